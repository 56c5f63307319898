// Cross-check of the ARX least squares (dv_lsq_*, dv_arx_fit: sequential Givens QR) against
// Eigen's ColPivHouseholderQR on random problems, on problems with a prescribed condition number
// (1e0 .. 1e10, by SVD construction and by nearly collinear columns), and on ARX regressions;
// truly singular problems must return DV_ENUMERIC. Tolerances scale with the condition number
// (LS perturbation bound: eps (kappa + kappa^2 ||r|| / (||A|| ||x||))). Non-zero exit on failure.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Dense>

extern "C" {
#include "dynval/dv_arx.h"
}

using Mat = Eigen::MatrixXd;
using Vec = Eigen::VectorXd;

static int failures = 0;
static const double EPS = std::numeric_limits<dv_real_t>::epsilon();
static const bool DBL = sizeof(dv_real_t) == 8;

static void report(const char *what, double err, double tol)
{
    const bool ok = err <= tol;
    std::printf("%-62s rel err %.3g (tol %.2g) %s\n", what, err, tol, ok ? "ok" : "FAIL");
    if (!ok) failures++;
}

static double cond2(const Mat &a)
{
    Eigen::JacobiSVD<Mat> svd(a);
    const Vec s = svd.singularValues();
    return s(0) / s(s.size() - 1);
}

// Solve min ||A x - y|| with dv_lsq (rows folded one at a time). Returns the status.
static dv_status_t dv_solve(const Mat &a, const Vec &y, Vec &x, double *rcond)
{
    const uint32_t q = (uint32_t)a.cols();
    std::vector<dv_real_t> buf(DV_LSQ_BUF_LEN(q)), row(q), th(q);
    dv_lsq_t s;
    if (dv_lsq_init(&s, q, buf.data(), buf.size()) != DV_OK) return DV_EINVAL;
    for (Eigen::Index i = 0; i < a.rows(); i++) {
        for (uint32_t j = 0; j < q; j++) row[j] = (dv_real_t)a(i, j);
        if (dv_lsq_update(&s, row.data(), (dv_real_t)y(i)) != DV_OK) return DV_ENUMERIC;
    }
    dv_real_t rss = 0, rc = 0;
    const dv_status_t st = dv_lsq_get(&s, th.data(), &rss, &rc);
    if (st == DV_OK) {
        x.resize(q);
        for (uint32_t j = 0; j < q; j++) x(j) = (double)th[j];
        if (rcond != nullptr) *rcond = (double)rc;
    }
    return st;
}

// Compare dv_lsq with Eigen on one problem; y = A x0 + noise_rel ||A x0|| / sqrt(m) * N(0,1).
static void check_problem(const char *name, const Mat &a, std::mt19937_64 &rng, double noise_rel)
{
    std::normal_distribution<double> nd;
    const Eigen::Index m = a.rows(), q = a.cols();
    // round the matrix to the library's type first, so both solvers see the same problem
    Mat ar = a.unaryExpr([](double v) { return (double)(dv_real_t)v; });
    Vec x0(q);
    for (Eigen::Index j = 0; j < q; j++) x0(j) = nd(rng);
    Vec y = ar * x0;
    const double ynorm = y.norm();
    for (Eigen::Index i = 0; i < m; i++)
        y(i) = (double)(dv_real_t)(y(i) + noise_rel * ynorm / std::sqrt((double)m) * nd(rng));
    const double kappa = cond2(ar);
    Eigen::ColPivHouseholderQR<Mat> qr(ar);
    const Vec xe = qr.solve(y);
    const Vec r = y - ar * xe;
    const double rrel = r.norm() / (ar.norm() * xe.norm()); // Frobenius >= 2-norm: a lower bound
    const double bound = EPS * (kappa + kappa * kappa * rrel) * std::sqrt((double)q);
    Vec xd;
    double rcond = 0;
    const dv_status_t st = dv_solve(ar, y, xd, &rcond);
    char what[160];
    std::snprintf(what, sizeof what, "%s m=%ld q=%ld kappa=%.1e rcond=%.1e", name, (long)m,
                  (long)q, kappa, rcond);
    if (st != DV_OK) {
        std::printf("%-62s status %d FAIL\n", what, (int)st);
        failures++;
        return;
    }
    // dv vs Eigen (both backward stable: they agree to the perturbation bound of the problem)
    report(what, (xd - xe).norm() / xe.norm(), 100.0 * bound + 10.0 * EPS);
    // residual norms: the LS residual moves by ~eps kappa ||y|| under backward-stable errors
    if (noise_rel > 0) {
        const double rd = (y - ar * xd).norm(), re = r.norm();
        std::snprintf(what, sizeof what, "  residual norm %.6g vs Eigen %.6g", rd, re);
        report(what, std::fabs(rd - re) / re, 10.0 * std::sqrt((double)q) * EPS * (1.0 + kappa * ynorm / re));
    }
    // rcond is a cheap estimate of the condition of the column-scaled matrix: within a factor
    // of a few q of 1/kappa_s
    const Vec cn = ar.colwise().norm();
    const double ks = cond2(ar * cn.cwiseInverse().asDiagonal());
    if (ks < 0.1 / EPS) {
        const double ratio = rcond * ks;
        std::snprintf(what, sizeof what, "  rcond*kappa(scaled) = %.3g within [1/q, 4q]", ratio);
        const bool ok = ratio >= 1.0 / (double)q && ratio <= 4.0 * (double)q;
        std::printf("%-62s %s\n", what, ok ? "ok" : "FAIL");
        if (!ok) failures++;
    }
}

// A with singular values logspaced from 1 to 1/kappa (random orthogonal factors).
static Mat with_condition(Eigen::Index m, Eigen::Index q, double kappa, std::mt19937_64 &rng)
{
    std::normal_distribution<double> nd;
    Mat g1(m, q), g2(q, q);
    for (Eigen::Index i = 0; i < m; i++)
        for (Eigen::Index j = 0; j < q; j++) g1(i, j) = nd(rng);
    for (Eigen::Index i = 0; i < q; i++)
        for (Eigen::Index j = 0; j < q; j++) g2(i, j) = nd(rng);
    Mat u = Eigen::HouseholderQR<Mat>(g1).householderQ() * Mat::Identity(m, q);
    Mat v = Eigen::HouseholderQR<Mat>(g2).householderQ() * Mat::Identity(q, q);
    Vec s(q);
    for (Eigen::Index j = 0; j < q; j++)
        s(j) = std::pow(kappa, -(double)j / (double)std::max<Eigen::Index>(q - 1, 1));
    return u * s.asDiagonal() * v.transpose();
}

static void check_singular(const char *name, const Mat &a, const Vec &y)
{
    Vec x;
    const dv_status_t st = dv_solve(a, y, x, nullptr);
    const bool ok = st == DV_ENUMERIC;
    std::printf("%-62s status %d (want DV_ENUMERIC %d) %s\n", name, (int)st, (int)DV_ENUMERIC,
                ok ? "ok" : "FAIL");
    if (!ok) failures++;
}

static void check_arx(const char *name, const dv_arx_cfg_t &cfg, const std::vector<dv_real_t> &x,
                      const std::vector<dv_real_t> &f)
{
    const size_t n = x.size();
    const size_t lf = cfg.nb > 0 ? cfg.nk + cfg.nb - 1 : 0, i0 = std::max<size_t>(cfg.na, lf);
    const Eigen::Index rows = (Eigen::Index)(n - i0), q = cfg.na + cfg.nb;
    Mat a(rows, q);
    Vec y(rows);
    for (size_t i = i0; i < n; i++) {
        const Eigen::Index r = (Eigen::Index)(i - i0);
        for (uint32_t j = 0; j < cfg.na; j++) a(r, j) = x[i - 1 - j];
        for (uint32_t t = 0; t < cfg.nb; t++) a(r, cfg.na + t) = f[i - cfg.nk - t];
        y(r) = x[i];
    }
    const Vec xe = Eigen::ColPivHouseholderQR<Mat>(a).solve(y);
    const double kappa = cond2(a);
    const double rrel = (y - a * xe).norm() / (a.norm() * xe.norm());
    std::vector<dv_real_t> work(DV_ARX_WORK_LEN(cfg.na, cfg.nb));
    dv_arx_model_t m;
    char what[160];
    std::snprintf(what, sizeof what, "%s na=%u nb=%u nk=%u kappa=%.1e", name, cfg.na, cfg.nb,
                  cfg.nk, kappa);
    const dv_status_t st = dv_arx_fit(&m, &cfg, x.data(), f.data(), n, work.data(), work.size());
    if (st != DV_OK) {
        std::printf("%-62s status %d FAIL\n", what, (int)st);
        failures++;
        return;
    }
    Vec xd(q);
    for (uint32_t j = 0; j < cfg.na; j++) xd(j) = m.alpha[j];
    for (uint32_t t = 0; t < cfg.nb; t++) xd(cfg.na + t) = m.beta[t];
    const double bound = EPS * (kappa + kappa * kappa * rrel) * std::sqrt((double)q);
    report(what, (xd - xe).norm() / xe.norm(), 100.0 * bound + 10.0 * EPS);
    const double s2 = (y - a * xe).squaredNorm() / (double)rows;
    std::snprintf(what, sizeof what, "  sigma2 %.6g vs Eigen %.6g", (double)m.sigma2, s2);
    report(what, std::fabs((double)m.sigma2 - s2) / s2, DBL ? 1e-8 : 1e-2);
}

int main()
{
    std::mt19937_64 rng(20261121);
    std::normal_distribution<double> nd;
    std::uniform_int_distribution<int> qd(1, 40), md(0, 400);

    std::printf("-- random Gaussian problems (well conditioned), noisy right-hand side\n");
    for (int t = 0; t < 12; t++) {
        const Eigen::Index q = qd(rng), m = q + 5 + md(rng);
        Mat a(m, q);
        for (Eigen::Index i = 0; i < m; i++)
            for (Eigen::Index j = 0; j < q; j++) a(i, j) = nd(rng) * std::pow(10.0, (double)(j % 5) - 2);
        check_problem("gaussian, column scales 1e-2..1e2", a, rng, 0.1);
    }

    std::printf("-- prescribed condition numbers (SVD construction)\n");
    const double kmax = DBL ? 1e10 : 1e4;
    for (double kappa = 1.0; kappa <= kmax * 1.01; kappa *= 100.0) {
        for (double noise : {0.0, 1e-3}) {
            char name[64];
            std::snprintf(name, sizeof name, "svd kappa %.0e noise %.0e", kappa, noise);
            check_problem(name, with_condition(300, 12, kappa, rng), rng, noise);
        }
    }

    std::printf("-- nearly collinear columns: col 3 = col 1 + delta * N(0,1)\n");
    for (double delta = 1e-2; delta >= (DBL ? 1e-10 : 1e-4) * 0.99; delta *= 1e-2) {
        Mat a(500, 8);
        for (Eigen::Index i = 0; i < a.rows(); i++)
            for (Eigen::Index j = 0; j < a.cols(); j++) a(i, j) = nd(rng);
        for (Eigen::Index i = 0; i < a.rows(); i++) a(i, 3) = a(i, 1) + delta * nd(rng);
        char name[64];
        std::snprintf(name, sizeof name, "collinear delta %.0e", delta);
        check_problem(name, a, rng, 1e-2);
    }

    std::printf("-- ARX regressions (dv_arx_fit) vs Eigen on the same regression matrix\n");
    {
        const size_t n = 3000;
        std::vector<dv_real_t> x(n), f(n), fs(n);
        double x1 = 0, x2 = 0, s = 0;
        for (size_t i = 0; i < n; i++) {
            f[i] = (dv_real_t)nd(rng);
            s = 0.999 * s + 0.05 * nd(rng); // slowly varying input: nearly collinear lags
            fs[i] = (dv_real_t)s;
        }
        for (size_t i = 0; i < n; i++) {
            const double fi1 = i >= 1 ? (double)f[i - 1] : 0.0, fi2 = i >= 2 ? (double)f[i - 2] : 0.0;
            const double xi = 1.6 * x1 - 0.8 * x2 + 0.5 * fi1 - 0.2 * fi2 + 0.05 * nd(rng);
            x2 = x1;
            x1 = xi;
            x[i] = (dv_real_t)xi;
        }
        check_arx("white input", dv_arx_cfg_t{4, 3, 1}, x, f);
        check_arx("white input, nk=0", dv_arx_cfg_t{6, 5, 0}, x, f);
        check_arx("AR only", dv_arx_cfg_t{8, 0, 0}, x, f);
        check_arx("slow (ill-conditioned) input", dv_arx_cfg_t{2, 6, 1}, x, fs);
    }

    std::printf("-- singular problems must fail with DV_ENUMERIC\n");
    {
        Mat a(100, 5);
        for (Eigen::Index i = 0; i < a.rows(); i++)
            for (Eigen::Index j = 0; j < a.cols(); j++) a(i, j) = nd(rng);
        Vec y = a * Vec::Ones(5);
        Mat b = a;
        b.col(4) = b.col(1);
        check_singular("repeated column", b, y);
        b = a;
        b.col(2).setZero();
        check_singular("zero column", b, y);
        b = a;
        b.col(3) = 2.0 * b.col(0) - 0.5 * b.col(2); // exactly representable combination
        check_singular("column = 2 col0 - 0.5 col2", b, y);
        Mat c = with_condition(200, 6, 1.0 / EPS * 1e3, rng);
        check_singular("kappa = 1e3/eps (numerically singular)", c, c * Vec::Ones(6));
        // ARX with a constant input and two input taps: identical columns
        std::vector<dv_real_t> x(400), f(400, (dv_real_t)3.0);
        for (size_t i = 0; i < x.size(); i++) x[i] = (dv_real_t)nd(rng);
        std::vector<dv_real_t> work(DV_ARX_WORK_LEN(2, 2));
        dv_arx_model_t m;
        const dv_arx_cfg_t cfg{2, 2, 1};
        const dv_status_t st = dv_arx_fit(&m, &cfg, x.data(), f.data(), x.size(), work.data(), work.size());
        std::printf("%-62s status %d %s\n", "ARX, constant input, 2 taps", (int)st,
                    st == DV_ENUMERIC ? "ok" : "FAIL");
        if (st != DV_ENUMERIC) failures++;
    }
    std::printf("%s\n", failures == 0 ? "xcheck_ar: all ok" : "xcheck_ar: FAILED");
    return failures == 0 ? 0 : 1;
}

// Cross-check of dv_model against Eigen: the generalised eigen-solution (K, M), the matrix
// exponential (unsupported MatrixFunctions), and the first-order-hold matrices computed here
// independently from Eigen's exponential of the augmented matrix. Returns non-zero on failure.
#include <cmath>
#include <complex>
#include <algorithm>
#include <cstdio>
#include <vector>

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>

extern "C" {
#include "dynval/dv_mat.h"
#include "dynval/dv_model.h"
}

using Mat = Eigen::MatrixXd;

static int failures = 0;

static Mat view(const dv_model_t &m, dv_model_mat_id_t id)
{
    dv_mat_t v;
    if (dv_model_get_mat(&m, id, &v) != DV_OK) {
        std::printf("FAIL get_mat %d\n", (int)id);
        failures++;
        return Mat();
    }
    Mat r(v.rows, v.cols);
    for (int i = 0; i < v.rows; i++)
        for (int j = 0; j < v.cols; j++) r(i, j) = (double)v.data[i * v.cols + j];
    return r;
}

static void check(const char *what, double err, double tol)
{
    const bool ok = err <= tol;
    std::printf("%-48s rel err %.3g (tol %.1g) %s\n", what, err, tol, ok ? "ok" : "FAIL");
    if (!ok) failures++;
}

static double rel(const Mat &a, const Mat &b)
{
    return (a - b).cwiseAbs().maxCoeff() / std::max(b.cwiseAbs().maxCoeff(), 1e-300);
}

static void check_model(const char *name, dv_model_desc_t &d, double dt, double tol)
{
    std::printf("-- %s\n", name);
    std::vector<dv_real_t> buf(dv_model_buf_len(&d));
    dv_model_t m;
    if (dv_model_init(&m, &d, (dv_real_t)dt, buf.data(), buf.size()) != DV_OK) {
        std::printf("FAIL init\n");
        failures++;
        return;
    }
    const int n = d.n_dof, ns = 2 * n;
    Mat mm = Mat::Zero(n, n);
    for (int i = 0; i < n; i++) mm(i, i) = d.mass_kg[i];
    Mat k = view(m, DV_MODEL_MAT_K);
    // generalised symmetric eigenproblem K phi = lambda M phi
    Eigen::GeneralizedSelfAdjointEigenSolver<Mat> ges(k, mm);
    Eigen::VectorXd f = ges.eigenvalues().cwiseMax(0.0).cwiseSqrt() / (2 * M_PI);
    Mat phi_e = ges.eigenvectors();
    Eigen::VectorXd fd(n);
    for (int i = 0; i < n; i++) fd(i) = (double)m.freq_hz[i];
    double ef = 0;
    for (int i = 0; i < n; i++)
        if (f(i) > 1.0) ef = std::max(ef, std::fabs(fd(i) - f(i)) / f(i));
    check("natural frequencies (> 1 Hz)", ef, tol);
    Mat phi = view(m, DV_MODEL_MAT_MODES);
    double ep = 0;
    for (int j = 0; j < n; j++) {
        if (f(j) <= 1.0) continue;
        double s = phi.col(j).dot(phi_e.col(j)) < 0 ? -1 : 1; // sign is a convention
        ep = std::max(ep, (phi.col(j) - s * phi_e.col(j)).cwiseAbs().maxCoeff() /
                              phi_e.col(j).cwiseAbs().maxCoeff());
    }
    check("mass-normalised mode shapes", ep, 100 * tol);
    // matrix exponential of A dt
    Mat a = view(m, DV_MODEL_MAT_A);
    Mat ad_e = (a * dt).exp();
    check("Ad = exp(A dt) vs Eigen MatrixFunctions", rel(view(m, DV_MODEL_MAT_AD), ad_e), tol);
    // dv_mat_expm on a general non-normal matrix with a large norm (many squarings)
    {
        const int q = 7;
        Mat g(q, q);
        for (int i = 0; i < q; i++)
            for (int j = 0; j < q; j++) g(i, j) = std::sin(1.0 + i * 3.1 + j * 1.7) * (j >= i ? 3.0 : 0.7);
        std::vector<dv_real_t> gd(q * q), ed(q * q), w(DV_MAT_EXPM_WORK_LEN(q));
        for (int i = 0; i < q; i++)
            for (int j = 0; j < q; j++) gd[i * q + j] = (dv_real_t)g(i, j);
        dv_mat_t gm = {(uint16_t)q, (uint16_t)q, gd.data()}, em = {(uint16_t)q, (uint16_t)q, ed.data()};
        if (dv_mat_expm(&gm, &em, w.data(), w.size()) != DV_OK) failures++;
        Mat e(q, q);
        for (int i = 0; i < q; i++)
            for (int j = 0; j < q; j++) e(i, j) = (double)ed[i * q + j];
        check("dv_mat_expm (7x7, norm ~ 20) vs Eigen", rel(e, g.exp()), 1000 * tol);
    }
    // first-order hold, independently: Gamma0 = int_0^T e^{As} ds B, Gamma1 = int_0^T e^{As}(1 -
    // s/T) ds B from exp([[A T, B T, 0], [0, 0, I], [0, 0, 0]]) in Eigen.
    Mat b = view(m, DV_MODEL_MAT_B);
    Mat big = Mat::Zero(ns + 4, ns + 4);
    big.topLeftCorner(ns, ns) = a * dt;
    big.block(0, ns, ns, 2) = b.leftCols(2) * dt;
    big.block(ns, ns + 2, 2, 2) = Mat::Identity(2, 2);
    Mat eb = big.exp();
    Mat g0 = eb.block(0, ns, ns, 2), g1 = eb.block(0, ns + 2, ns, 2);
    Mat pa_e = g0.col(0) - g1.col(0) - g0.col(1) / dt;
    Mat pb_e = g1.col(0) + g0.col(1) / dt;
    check("FOH Pa (coefficient of u[k])", rel(view(m, DV_MODEL_MAT_PA), pa_e), 10 * tol);
    check("FOH Pb (coefficient of u[k+1])", rel(view(m, DV_MODEL_MAT_PB), pb_e), 10 * tol);
    // the FOH recursion against a fine-step integral for a ramp input (independent again):
    // x(T) for x(0) = 0, u(t) = t / T must be Pb (u[k] = 0, u[k+1] = 1); B col 1 takes u'
    {
        const int steps = 4096;
        const double h = dt / steps;
        Mat eh = (a * h).exp();
        Eigen::VectorXd x = Eigen::VectorXd::Zero(ns);
        for (int s = 0; s < steps; s++) {
            // midpoint quadrature of int e^{A(h - t)} B u(t) dt over the small step
            double um = (s + 0.5) / steps;
            x = eh * x + (a * (0.5 * h)).exp() * (b.col(0) * um + b.col(1) / dt) * h; // u' = 1/T
        }
        check("FOH Pb vs a 4096-step quadrature of a ramp", rel(view(m, DV_MODEL_MAT_PB), x),
              1e-6);
    }
    // cubic hold (DV_HOLD_CUBIC): Pu column j is the response at T to the Lagrange basis
    // polynomial l_j(s) through s = -1, 0, 1, 2 (l_j(j - 1) = 1), u' = l_j'(s) / T.
    {
        dv_model_desc_t dc = d;
        dc.input_hold = DV_HOLD_CUBIC;
        std::vector<dv_real_t> bufc(dv_model_buf_len(&dc));
        dv_model_t mc;
        if (dv_model_init(&mc, &dc, (dv_real_t)dt, bufc.data(), bufc.size()) != DV_OK) {
            std::printf("FAIL init (cubic)\n");
            failures++;
            return;
        }
        Mat pu = view(mc, DV_MODEL_MAT_PU);
        // independent basis from the nodes, by Lagrange's formula
        auto lag = [](int j, double s) {
            double v = 1.0;
            for (int i = 0; i < 4; i++)
                if (i != j) v *= (s - (i - 1)) / double(j - i);
            return v;
        };
        auto dlag = [&](int j, double s) { // central difference of the cubic: exact to 1e-10
            const double e = 1e-4;
            return (lag(j, s + e) - lag(j, s - e)) / (2 * e);
        };
        const int steps = 4096;
        const double h = dt / steps;
        Mat eh = (a * h).exp(), em = (a * (0.5 * h)).exp();
        Mat pq = Mat::Zero(ns, 4);
        for (int j = 0; j < 4; j++) {
            Eigen::VectorXd x = Eigen::VectorXd::Zero(ns);
            for (int s = 0; s < steps; s++) {
                const double sm = (s + 0.5) / steps;
                x = eh * x + em * (b.col(0) * lag(j, sm) + b.col(1) * dlag(j, sm) / dt) * h;
            }
            pq.col(j) = x;
        }
        check("cubic Pu vs a 4096-step quadrature of the Lagrange basis", rel(pu, pq), 1e-6);
        // and the same from Eigen's exponential of the 4-block nilpotent augmentation
        Mat big4 = Mat::Zero(ns + 8, ns + 8);
        big4.topLeftCorner(ns, ns) = a * dt;
        big4.block(0, ns, ns, 2) = b.leftCols(2) * dt;
        for (int p = 0; p < 3; p++) big4.block(ns + 2 * p, ns + 2 * (p + 1), 2, 2) = Mat::Identity(2, 2);
        Mat e4 = big4.exp();
        const double c[4][4] = {{0, 1, 0, 0}, {-1.0 / 3, -0.5, 1, -1.0 / 6}, {0.5, -1, 0.5, 0},
                                {-1.0 / 6, 0.5, -0.5, 1.0 / 6}};
        const double fact[4] = {1, 1, 2, 6};
        Mat pe = Mat::Zero(ns, 4);
        for (int j = 0; j < 4; j++)
            for (int p = 0; p < 4; p++) {
                pe.col(j) += e4.block(0, ns + 2 * p, ns, 1) * fact[p] * c[p][j];
                if (p < 3) pe.col(j) += e4.block(0, ns + 2 * p + 1, ns, 1) * fact[p] * (p + 1) * c[p + 1][j] / dt;
            }
        check("cubic Pu vs Eigen exp of the 4-block augmentation", rel(pu, pe), 10 * tol);
        // Ad of the cubic model is the same matrix
        check("cubic model Ad", rel(view(mc, DV_MODEL_MAT_AD), ad_e), tol);
    }
}

// dv_mat_eig_real() against Eigen's EigenSolver: the discretised state matrix Ad of a model
// (eigenvalues on a circle near 1: the case the observer's modal form needs), a random
// matrix, and one with real and complex eigenvalues of very different sizes.
static void check_eig_real(const char *name, const Mat &a, double tol)
{
    const int n = (int)a.rows();
    std::vector<dv_real_t> ad(n * n), wr(n), wi(n), w(DV_MAT_EIGR_WORK_LEN(n));
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) ad[i * n + j] = (dv_real_t)a(i, j);
    dv_mat_t am = {(uint16_t)n, (uint16_t)n, ad.data()};
    if (dv_mat_eig_real(&am, wr.data(), wi.data(), w.data(), w.size()) != DV_OK) {
        std::printf("  %s: dv_mat_eig_real failed\n", name);
        failures++;
        return;
    }
    Eigen::EigenSolver<Mat> es(a, false);
    Eigen::VectorXcd ref = es.eigenvalues();
    std::vector<bool> used(n, false);
    double err = 0, scale = ref.cwiseAbs().maxCoeff();
    for (int i = 0; i < n; i++) {
        std::complex<double> z(wr[i], wi[i]);
        int best = -1;
        for (int k = 0; k < n; k++)
            if (!used[k] && (best < 0 || std::abs(ref(k) - z) < std::abs(ref(best) - z))) best = k;
        used[best] = true;
        err = std::max(err, std::abs(ref(best) - z));
    }
    check(name, err / scale, tol);
}

int main()
{
    dv_model_desc_t d;
    dv_model_desc_default(&d);
    const double mass[4] = {6.54, 6.66, 6.86, 6.80};
    const double kst[4] = {10.0, 399790.0, 399790.0, 399790.0};
    const double zeta[4] = {0.01, 0.05, 0.01, 0.01};
    d.n_dof = 4;
    for (int i = 0; i < 4; i++) {
        d.mass_kg[i] = (dv_real_t)mass[i];
        d.k_n_per_m[i] = (dv_real_t)kst[i];
        d.zeta[i] = (dv_real_t)zeta[i];
    }
    d.n_out = 4;
    for (int i = 0; i < 4; i++) {
        d.out[i].kind = DV_OUT_ACC;
        d.out[i].index = (uint16_t)i;
    }
    const bool dbl = sizeof(dv_real_t) == 8;
    const double tol = dbl ? 1e-10 : 2e-4;
    check_model("report 4-DOF, modal L2, force at base, 640 Hz", d, 1.0 / 640.0, tol);
    // 8 DOF, uneven masses, Rayleigh, ground displacement input, 2 kHz
    dv_model_desc_t e = d;
    e.n_dof = 8;
    for (int i = 0; i < 8; i++) {
        e.mass_kg[i] = (dv_real_t)(1.0 + 0.37 * i);
        e.k_n_per_m[i] = (dv_real_t)(2.0e5 * (1.0 + 0.11 * ((i * 5) % 7)));
    }
    e.damp_kind = DV_DAMP_RAYLEIGH;
    e.rayleigh_mode[0] = 0;
    e.rayleigh_mode[1] = 5;
    e.rayleigh_zeta[0] = (dv_real_t)0.02;
    e.rayleigh_zeta[1] = (dv_real_t)0.03;
    e.input_kind = DV_INPUT_GROUND_DISP;
    check_model("8-DOF, Rayleigh, ground displacement, 2 kHz", e, 1.0 / 2000.0, tol);
    {
        dv_model_t m;
        std::vector<dv_real_t> buf(dv_model_buf_len(&d));
        if (dv_model_init(&m, &d, (dv_real_t)(1.0 / 640.0), buf.data(), buf.size()) != DV_OK) {
            failures++;
        } else {
            // its first mode (k1 = 10 N/m, 0.1 Hz) is a pair at 1 +- 1e-3 i, 2e-3 apart: the
            // eigenvalue condition there is ~1/2e-3, so agreement is ~eps / 2e-3 per solver
            check_eig_real("eig_real: Ad of the report's 4-DOF model vs EigenSolver",
                           view(m, DV_MODEL_MAT_AD), dbl ? 1e-11 : 1e-4);
        }
        Mat r = Mat::Random(11, 11);
        check_eig_real("eig_real: random 11 x 11 vs EigenSolver", r, dbl ? 1e-12 : 1e-5);
        Mat g = Mat::Random(6, 6) * Mat(Eigen::VectorXd::LinSpaced(6, -3.0, 2.0).array().exp()
                                            .matrix().asDiagonal());
        check_eig_real("eig_real: graded 6 x 6 vs EigenSolver", g, dbl ? 1e-12 : 1e-5);
    }
    std::printf("%s\n", failures == 0 ? "xcheck_model: all ok" : "xcheck_model: FAILED");
    return failures == 0 ? 0 : 1;
}

// ARX / AR-ARX least squares and the ARX residual: numpy lstsq golden values (tests/gen/gen_ar.py),
// closed forms, singular problems, bad input.
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include "dv_test_util.h"
#include "dynval/dv_arx.h"

enum { NMAX = 8192 };
static double xin[NMAX], fin[NMAX];
static dv_real_t xr[NMAX], fr[NMAX];
static dv_real_t work[DV_ARARX_WORK_LEN(NMAX, 64, 64, 64)];
#define WL (sizeof work / sizeof *work)

#ifdef DV_REAL_DOUBLE
#define RTOL 1e-9
#else
#define RTOL 2e-3
#endif

static void test_arx_matches_lstsq(void **state)
{
    (void)state;
    size_t n = dv_test_load("ar_arx_x.csv", xin, NMAX);
    assert_int_equal(dv_test_load("ar_arx_f.csv", fin, NMAX), n);
    for (size_t i = 0; i < n; i++) { xr[i] = (dv_real_t)xin[i]; fr[i] = (dv_real_t)fin[i]; }
    const dv_arx_cfg_t cfgs[] = {{4, 3, 1}, {6, 5, 0}};
    for (int c = 0; c < 2; c++) {
        dv_arx_model_t m;
        assert_int_equal(dv_arx_fit(&m, &cfgs[c], xr, fr, n, work, WL), DV_OK);
        char feat[64];
        for (uint32_t j = 0; j < cfgs[c].na + cfgs[c].nb; j++) {
            snprintf(feat, sizeof feat, "arx_%u_%u_%u_%u", cfgs[c].na, cfgs[c].nb, cfgs[c].nk, j);
            double w = dv_test_expected("ar_expected.csv", "arx", feat);
            assert_false(isnan(w));
            double got = j < cfgs[c].na ? m.alpha[j] : m.beta[j - cfgs[c].na];
            assert_true(dv_test_close(got, w, RTOL, 1.0));
        }
        snprintf(feat, sizeof feat, "arx_%u_%u_%u_sigma2", cfgs[c].na, cfgs[c].nb, cfgs[c].nk);
        double s2 = dv_test_expected("ar_expected.csv", "arx", feat);
        assert_true(dv_test_close(m.sigma2, s2, RTOL * 100, 0));
        assert_true(m.rcond > 0 && m.rcond <= 1);
        // the streaming residual reproduces the fit's residual variance
        dv_arx_resid_t r;
        dv_real_t h[DV_ARX_RESID_BUF_LEN(64, 64, 64)];
        assert_int_equal(dv_arx_resid_init(&r, &m, h, sizeof h / sizeof *h), DV_OK);
        double ss = 0;
        size_t k = 0;
        for (size_t i = 0; i < n; i++) {
            dv_real_t e;
            dv_status_t st = dv_arx_resid_update(&r, xr[i], fr[i], &e);
            if (st == DV_OK) { ss += (double)e * e; k++; }
        }
        assert_int_equal(k, m.n_rows);
        assert_true(dv_test_close(ss / k, s2, RTOL * 1000, 0));
    }
}

static void test_arx_ararx_matches_two_stage_lstsq(void **state)
{
    (void)state;
    size_t n = dv_test_load("ar_struct.csv", xin, NMAX);
    for (size_t i = 0; i < n; i++) xr[i] = (dv_real_t)xin[i];
    dv_arx_cfg_t cfg = {5, 5, 0};
    dv_arx_model_t m;
    dv_ar_model_t ar;
    assert_int_equal(dv_ararx_fit(&m, &ar, &cfg, 30, xr, n, work, WL), DV_OK);
    assert_int_equal(ar.order, 30);
    double scale = 0;
    for (int j = 0; j < 10; j++) {
        char feat[32];
        snprintf(feat, sizeof feat, "theta_%d", j);
        scale = fmax(scale, fabs(dv_test_expected("ar_expected.csv", "ararx", feat)));
    }
    double err = 0;
    for (int j = 0; j < 10; j++) {
        char feat[32];
        snprintf(feat, sizeof feat, "theta_%d", j);
        double w = dv_test_expected("ar_expected.csv", "ararx", feat);
        assert_false(isnan(w));
        double got = j < 5 ? m.alpha[j] : m.beta[j - 5];
        err = fmax(err, fabs(got - w) / scale);
    }
    double s2 = dv_test_expected("ar_expected.csv", "ararx", "sigma2");
    double s2err = fabs(m.sigma2 - s2) / s2;
#ifdef DV_REAL_DOUBLE
    const double tol = 1e-7, s2tol = 1e-7;
#else
    // Float: stage 1 is a Yule-Walker AR(30) of a lightly damped structure, whose Toeplitz
    // matrix has condition number ~2.5e4 (ararx,toeplitz_cond): an autocorrelation known to
    // u = 2^-24 of r_0 gives AR(30) coefficients to ~kappa u ~ 1.5e-3, and stage 2 passes that
    // on. The floor no float build can beat is storing r_k in float: gen_ar.py rounds the exact
    // r_0..r_30 to float32, reruns both stages in double, and records the change
    // (ararx,f32_acf_theta_err ~2.9e-4 of max |theta|, f32_acf_sigma2_err ~1.8e-4). The
    // tolerance is 4x that floor; the library's own round-off (pairwise autocorrelation sums,
    // float Levinson, float Givens QR) must stay within 3x more. (With the autocorrelation
    // summed in 4 plain chains the error was 2.3e-3: this test failed.)
    const double tol = 4 * dv_test_expected("ar_expected.csv", "ararx", "f32_acf_theta_err");
    const double s2tol = 4 * dv_test_expected("ar_expected.csv", "ararx", "f32_acf_sigma2_err");
    assert_false(isnan(tol) || isnan(s2tol));
#endif
    printf("  ararx: max |theta - ref| = %.3g of max |theta| (tol %.3g), sigma2 rel err %.3g "
           "(tol %.3g)\n", err, tol, s2err, s2tol);
    assert_true(err <= tol);
    assert_true(s2err <= s2tol);
    cfg.na = 20; cfg.nb = 20; // p >= na + nb violated
    assert_int_equal(dv_ararx_fit(&m, NULL, &cfg, 30, xr, n, work, WL), DV_EINVAL);
}

static void test_arx_lsq_exact_and_singular(void **state)
{
    (void)state;
    dv_lsq_t s;
    dv_real_t buf[DV_LSQ_BUF_LEN(3)];
    assert_int_equal(dv_lsq_init(&s, 3, buf, DV_LSQ_BUF_LEN(3) - 1), DV_ESIZE);
    assert_int_equal(dv_lsq_init(&s, 0, buf, DV_LSQ_BUF_LEN(3)), DV_EINVAL);
    assert_int_equal(dv_lsq_init(&s, 3, buf, DV_LSQ_BUF_LEN(3)), DV_OK);
    dv_real_t th[3] = {-9, -9, -9}, rss = -1, rc = -1;
    assert_int_equal(dv_lsq_get(&s, th, &rss, &rc), DV_ENOTREADY);
    for (int i = 0; i < 20; i++) { // y = 2 a0 - 3 a1 + 0.5 a2, consistent: rss = 0
        dv_real_t a[3] = {(dv_real_t)i, (dv_real_t)(i * i % 7), DV_R(1.0)};
        assert_int_equal(dv_lsq_update(&s, a, 2 * a[0] - 3 * a[1] + DV_R(0.5)), DV_OK);
    }
    dv_real_t bad[3] = {DV_R(1.0), (dv_real_t)NAN, DV_R(1.0)};
    assert_int_equal(dv_lsq_update(&s, bad, DV_R(1.0)), DV_ENUMERIC);
    assert_int_equal(dv_lsq_get(&s, th, &rss, &rc), DV_OK);
    assert_true(dv_test_close(th[0], 2, 1e-5, 1) && dv_test_close(th[1], -3, 1e-5, 1) &&
                dv_test_close(th[2], 0.5, 1e-5, 1));
    assert_true(rss < 1e-6);
    // repeated column: singular, outputs untouched
    dv_lsq_reset(&s);
    for (int i = 0; i < 20; i++) {
        dv_real_t a[3] = {(dv_real_t)i, (dv_real_t)i, DV_R(1.0)};
        dv_lsq_update(&s, a, (dv_real_t)(i % 3));
    }
    th[0] = th[1] = th[2] = -9;
    assert_int_equal(dv_lsq_get(&s, th, NULL, NULL), DV_ENUMERIC);
    assert_true(th[0] == -9 && th[1] == -9 && th[2] == -9);
}

static void test_arx_bad_input(void **state)
{
    (void)state;
    for (int i = 0; i < 200; i++) { xr[i] = (dv_real_t)sin(0.37 * i * i); fr[i] = DV_R(0.0); }
    dv_arx_model_t m, keep;
    memset(&keep, 0x77, sizeof keep);
    m = keep;
    dv_arx_cfg_t cfg = {2, 2, 1};
    assert_int_equal(dv_arx_fit(&m, &cfg, xr, fr, 200, work, WL), DV_ENUMERIC); // zero input
    for (int i = 0; i < 200; i++) fr[i] = DV_R(3.0); // constant input: two identical columns
    assert_int_equal(dv_arx_fit(&m, &cfg, xr, fr, 200, work, WL), DV_ENUMERIC);
    assert_memory_equal(&m, &keep, sizeof m);
    for (int i = 0; i < 200; i++) fr[i] = (dv_real_t)cos(0.11 * i * i);
    assert_int_equal(dv_arx_fit(&m, &cfg, xr, fr, 4, work, WL), DV_EINVAL); // too short
    assert_int_equal(dv_arx_fit(&m, &cfg, xr, NULL, 200, work, WL), DV_EINVAL);
    assert_int_equal(dv_arx_fit(&m, &cfg, xr, fr, 200, work, 3), DV_ESIZE);
    dv_arx_cfg_t bad = {0, 0, 0};
    assert_int_equal(dv_arx_fit(&m, &bad, xr, fr, 200, work, WL), DV_EINVAL);
    xr[100] = (dv_real_t)NAN;
    assert_int_equal(dv_arx_fit(&m, &cfg, xr, fr, 200, work, WL), DV_ENUMERIC);
    xr[100] = DV_R(0.0);
    assert_int_equal(dv_arx_fit(&m, &cfg, xr, fr, 200, work, WL), DV_OK);
    dv_arx_resid_t r;
    dv_real_t h[DV_ARX_RESID_BUF_LEN(2, 2, 1)];
    assert_int_equal(dv_arx_resid_init(&r, &m, h, sizeof h / sizeof *h), DV_OK);
    dv_real_t e = -5;
    assert_int_equal(dv_arx_resid_update(&r, (dv_real_t)NAN, DV_R(1.0), &e), DV_ENUMERIC);
    assert_int_equal(dv_arx_resid_nonfinite(&r), 1);
    assert_int_equal(dv_arx_resid_update(&r, DV_R(1.0), DV_R(1.0), &e), DV_ENOTREADY);
    assert_true(e == -5);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_arx_matches_lstsq),
        cmocka_unit_test(test_arx_ararx_matches_two_stage_lstsq),
        cmocka_unit_test(test_arx_lsq_exact_and_singular),
        cmocka_unit_test(test_arx_bad_input),
    };
    return cmocka_run_group_tests_name("dv_arx", tests, NULL, NULL);
}

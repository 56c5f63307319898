// Cumulative statistics: golden vectors (numpy/scipy), closed forms, bad input.
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include "dv_test_util.h"
#include "dynval/dv_moments.h"

enum { NMAX = 8192 };
static double xin[NMAX];

static void check_case(const char *cas, int use_block)
{
    size_t n = dv_test_load(cas[0] == 'r' ? "features_random.csv"
                            : cas[0] == 'd' ? "features_decay.csv"
                            : cas[0] == 's' ? "features_skewed.csv"
                                            : "features_offset.csv",
                            xin, NMAX);
    assert_int_equal(n, 4096);
    dv_moments_t m;
    assert_int_equal(dv_moments_init(&m), DV_OK);
    static dv_real_t xr[NMAX];
    for (size_t i = 0; i < n; i++) xr[i] = (dv_real_t)xin[i];
    if (use_block) {
        // odd split so the block path meets an open block and a short tail
        assert_int_equal(dv_moments_update_block(&m, xr, 37), DV_OK);
        assert_int_equal(dv_moments_update_block(&m, xr + 37, n - 37), DV_OK);
    } else {
        for (size_t i = 0; i < n; i++) assert_int_equal(dv_moments_update(&m, xr[i]), DV_OK);
    }
    dv_stats_t st;
    assert_int_equal(dv_moments_get(&m, &st), DV_OK);
    assert_int_equal(st.count, n);
    const char *names[] = {"rec_mean", "rec_std", "rec_var", "rec_rms", "rec_skew", "rec_kurt",
                           "rec_peak", "rec_min", "rec_max", "rec_crest", "rec_kfactor"};
    double got[] = {st.mean, st.std, st.var, st.rms, st.skew, st.kurt,
                    st.peak, st.min, st.max, st.crest, st.kfactor};
    double std = dv_test_expected("features_expected.csv", cas, "rec_std");
#ifndef DV_REAL_DOUBLE
    double mean = dv_test_expected("features_expected.csv", cas, "rec_mean");
#endif
    for (int k = 0; k < 11; k++) {
        double want = dv_test_expected("features_expected.csv", cas, names[k]);
        assert_false(isnan(want));
        // mean is judged on the scale of the STD (a zero-mean signal has no relative error);
        // min/max/peak are the input samples themselves (float: one rounding of the input).
        double scale = k == 0 ? std : (k == 2 ? std * std : (k == 4 || k == 5 ? 1.0 : 1e-300));
        double rtol = DV_TEST_RTOL;
#ifndef DV_REAL_DOUBLE
        if (k == 2 || k == 1) rtol = fabs(mean) > 100 * std ? 5e-4 : DV_TEST_RTOL;
#endif
        assert_true(dv_test_close(got[k], want, rtol, scale));
    }
}

static void test_moments_golden_random(void **state) { (void)state; check_case("random", 0); }
static void test_moments_golden_decay(void **state) { (void)state; check_case("decay", 0); }
static void test_moments_golden_skewed(void **state) { (void)state; check_case("skewed", 0); }
static void test_moments_golden_offset(void **state) { (void)state; check_case("offset", 0); }
static void test_moments_block_matches_golden(void **state)
{
    (void)state;
    check_case("random", 1);
    check_case("skewed", 1);
    check_case("offset", 1);
}

static void test_moments_sine_crest_is_sqrt2(void **state)
{
    (void)state;
    dv_moments_t m;
    dv_moments_init(&m);
    const int n = 6400; // 100 whole periods of 64 samples, peak sampled exactly
    for (int i = 0; i < n; i++) {
        dv_moments_update(&m, (dv_real_t)(2.0 * sin(2.0 * M_PI * i / 64.0)));
    }
    dv_stats_t st;
    assert_int_equal(dv_moments_get(&m, &st), DV_OK);
    assert_true(dv_test_close(st.crest, sqrt(2.0), 1e-5, 0));
    assert_true(dv_test_close(st.rms, sqrt(2.0), 1e-5, 0));
    assert_true(dv_test_close(st.kurt, 1.5, 1e-4, 0)); // sine: kurtosis 3/2
    assert_true(fabs(st.skew) < 1e-4);
    assert_true(dv_test_close(st.kfactor, 2.0 * sqrt(2.0), 1e-5, 0));
}

static void test_moments_not_ready_leaves_output(void **state)
{
    (void)state;
    dv_moments_t m;
    dv_moments_init(&m);
    dv_stats_t st;
    st.mean = DV_R(-7.0);
    assert_int_equal(dv_moments_get(&m, &st), DV_ENOTREADY);
    assert_true(st.mean == DV_R(-7.0));
}

static void test_moments_nan_sample_is_dropped(void **state)
{
    (void)state;
    dv_moments_t a, b;
    dv_moments_init(&a);
    dv_moments_init(&b);
    for (int i = 0; i < 100; i++) {
        dv_real_t x = (dv_real_t)(i % 7) - DV_R(3.0);
        dv_moments_update(&a, x);
        dv_moments_update(&b, x);
        if (i == 50) {
            assert_int_equal(dv_moments_update(&b, (dv_real_t)NAN), DV_ENUMERIC);
            assert_int_equal(dv_moments_update(&b, (dv_real_t)INFINITY), DV_ENUMERIC);
        }
    }
    dv_stats_t sa, sb;
    dv_moments_get(&a, &sa);
    dv_moments_get(&b, &sb);
    assert_int_equal(dv_moments_nonfinite(&b), 2);
    assert_int_equal(sb.count, 100);
    assert_memory_equal(&sa.mean, &sb.mean, sizeof sa.mean);
    assert_memory_equal(&sa.var, &sb.var, sizeof sa.var);
    // the block path counts them too and keeps the others
    dv_moments_t c;
    dv_moments_init(&c);
    dv_real_t blk[200];
    for (int i = 0; i < 200; i++) blk[i] = (dv_real_t)(i % 5);
    blk[70] = (dv_real_t)NAN;
    blk[150] = -(dv_real_t)INFINITY;
    assert_int_equal(dv_moments_update_block(&c, blk, 200), DV_ENUMERIC);
    assert_int_equal(dv_moments_nonfinite(&c), 2);
    dv_stats_t sc;
    dv_moments_get(&c, &sc);
    assert_int_equal(sc.count, 198);
    assert_true(isfinite(sc.mean) && isfinite(sc.var) && isfinite(sc.kurt));
}

static void test_moments_constant_and_zero_signals_flag(void **state)
{
    (void)state;
    dv_moments_t m;
    dv_moments_init(&m);
    for (int i = 0; i < 300; i++) dv_moments_update(&m, DV_R(0.0));
    dv_stats_t st;
    assert_int_equal(dv_moments_get(&m, &st), DV_OK);
    assert_true(st.flags & DV_STATS_NO_SHAPE);
    assert_true(st.flags & DV_STATS_NO_CREST);
    assert_true(st.crest == 0 && st.skew == 0 && st.kurt == 0);
    dv_real_t c = DV_R(5.0);
    assert_int_equal(dv_crest_factor(DV_R(0.0), DV_R(0.0), &c), DV_ENUMERIC);
    assert_true(c == DV_R(5.0));
    assert_int_equal(dv_crest_factor(DV_R(1.0), (dv_real_t)NAN, &c), DV_ENUMERIC);
    assert_int_equal(dv_k_factor(DV_REAL_MAX, DV_REAL_MAX, &c), DV_ENUMERIC);
    assert_int_equal(dv_crest_factor(DV_R(3.0), DV_R(2.0), &c), DV_OK);
    assert_true(c == DV_R(1.5));
    // a large constant: variance at round-off level is still "no shape"
    dv_moments_init(&m);
    for (int i = 0; i < 300; i++) dv_moments_update(&m, DV_R(12345.678));
    dv_moments_get(&m, &st);
    assert_true(st.flags & DV_STATS_NO_SHAPE);
    assert_false(st.flags & DV_STATS_NO_CREST);
    assert_true(dv_test_close(st.crest, 1.0, 1e-6, 0));
}

static void test_moments_null_arguments(void **state)
{
    (void)state;
    dv_stats_t st;
    dv_moments_t m;
    assert_int_equal(dv_moments_init(NULL), DV_EINVAL);
    dv_moments_init(&m);
    assert_int_equal(dv_moments_get(NULL, &st), DV_EINVAL);
    assert_int_equal(dv_moments_get(&m, NULL), DV_EINVAL);
    assert_int_equal(dv_moments_update_block(&m, NULL, 3), DV_EINVAL);
    assert_int_equal(dv_moments_update_block(&m, NULL, 0), DV_OK);
    assert_string_equal(dv_status_str(DV_ENOTREADY), "DV_ENOTREADY");
    assert_int_equal(dv_real_size(), sizeof(dv_real_t));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_moments_golden_random),
        cmocka_unit_test(test_moments_golden_decay),
        cmocka_unit_test(test_moments_golden_skewed),
        cmocka_unit_test(test_moments_golden_offset),
        cmocka_unit_test(test_moments_block_matches_golden),
        cmocka_unit_test(test_moments_sine_crest_is_sqrt2),
        cmocka_unit_test(test_moments_not_ready_leaves_output),
        cmocka_unit_test(test_moments_nan_sample_is_dropped),
        cmocka_unit_test(test_moments_constant_and_zero_signals_flag),
        cmocka_unit_test(test_moments_null_arguments),
    };
    return cmocka_run_group_tests_name("dv_moments", tests, NULL, NULL);
}

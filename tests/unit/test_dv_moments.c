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

// ---- finite in, finite out -------------------------------------------------------------------

#include "dynval/dv_config.h"

// A sample far beyond DV_FEAT_MAX but finite: 1e10 (float) / 1e80 (double) made the kurtosis
// NaN before.
#ifdef DV_REAL_DOUBLE
#define HUGE_SAMPLE 1e80
#else
#define HUGE_SAMPLE 1e10f
#endif

static void moments_of(const dv_real_t *x, size_t n, int block, dv_stats_t *st, dv_moments_t *m)
{
    assert_int_equal(dv_moments_init(m), DV_OK);
    if (block) {
        (void)dv_moments_update_block(m, x, n);
    } else {
        for (size_t i = 0; i < n; i++) (void)dv_moments_update(m, x[i]);
    }
    assert_int_equal(dv_moments_get(m, st), DV_OK);
}

static int stats_finite(const dv_stats_t *s)
{
    const dv_real_t v[] = {s->mean, s->var, s->std, s->rms, s->skew, s->kurt,
                           s->peak, s->min, s->max, s->crest, s->kfactor};
    for (size_t i = 0; i < sizeof v / sizeof v[0]; i++) {
        if (!isfinite(v[i])) return 0;
    }
    return 1;
}

static void test_moments_full_scale_closed_form(void **state)
{
    (void)state;
    // +-DV_FEAT_MAX alternating: mean 0, std = rms = peak = L, skew 0, kurt 1, exactly
    static dv_real_t x[4096];
    const dv_real_t L = DV_FEAT_MAX;
    for (int i = 0; i < 4096; i++) x[i] = (i & 1) ? -L : L;
    for (int block = 0; block < 2; block++) {
        dv_moments_t m;
        dv_stats_t st;
        moments_of(x, 4096, block, &st, &m);
        assert_true(stats_finite(&st));
        assert_true(st.mean == 0 && st.std == L && st.rms == L && st.peak == L);
        assert_true(st.skew == 0 && st.kurt == 1 && st.crest == 1);
        assert_true(st.kfactor == L * L && st.flags == 0u);
        assert_int_equal(m.n_nonfinite, 0);
    }
}

static void test_moments_beyond_range_is_dropped_and_counted(void **state)
{
    (void)state;
    static dv_real_t x[1000], y[1000];
    size_t ny = 0;
    for (int i = 0; i < 1000; i++) {
        x[i] = (dv_real_t)sin(0.1 * i);
        if (i % 97 == 5) {
            x[i] = (i & 2) ? HUGE_SAMPLE : -DV_REAL_MAX;
        } else if (i % 101 == 7) {
            x[i] = DV_FEAT_MAX * (1 + DV_REAL_EPS); // the first value beyond the range
        } else {
            y[ny++] = x[i];
        }
    }
    for (int block = 0; block < 2; block++) {
        dv_moments_t m, m2;
        dv_stats_t st, want;
        moments_of(y, ny, block, &want, &m2);
        assert_int_equal(dv_moments_init(&m), DV_OK);
        if (block) {
            assert_int_equal(dv_moments_update_block(&m, x, 1000), DV_ENUMERIC);
        } else {
            for (int i = 0; i < 1000; i++) {
                const dv_status_t r = dv_moments_update(&m, x[i]);
                assert_int_equal(r, (i % 97 == 5 || i % 101 == 7) ? DV_ENUMERIC : DV_OK);
            }
        }
        assert_int_equal(dv_moments_nonfinite(&m), 1000 - ny);
        assert_int_equal(dv_moments_get(&m, &st), DV_OK);
        assert_true(stats_finite(&st));
        // the dropped samples left no trace: the statistics of the rest (bit for bit sample by
        // sample; the block path's blocks fall elsewhere around a dropped sample: round-off)
        if (!block) {
            const dv_real_t a[] = {st.mean, st.var, st.std, st.rms, st.skew, st.kurt, st.peak,
                                   st.min, st.max, st.crest, st.kfactor};
            const dv_real_t b[] = {want.mean, want.var, want.std, want.rms, want.skew, want.kurt,
                                   want.peak, want.min, want.max, want.crest, want.kfactor};
            assert_memory_equal(a, b, sizeof a);
            assert_true(st.count == want.count && st.flags == want.flags);
        } else {
            assert_true(dv_test_close(st.mean, want.mean, DV_TEST_RTOL, want.std) &&
                        dv_test_close(st.std, want.std, DV_TEST_RTOL, 0) &&
                        dv_test_close(st.kurt, want.kurt, DV_TEST_RTOL, 0) &&
                        st.peak == want.peak && st.count == want.count);
        }
    }
    // one huge sample alone never reaches a result
    dv_moments_t m;
    dv_stats_t st;
    dv_moments_init(&m);
    assert_int_equal(dv_moments_update(&m, HUGE_SAMPLE), DV_ENUMERIC);
    assert_int_equal(dv_moments_get(&m, &st), DV_ENOTREADY);
}

static void test_moments_scaled_shape_is_identical(void **state)
{
    (void)state;
    // Scaling by a power of two is exact: skewness and kurtosis of x 2^k are those of x bit for
    // bit and the STD scales exactly, from the top of the range (|x| <= 2 here, 2^k <= DV_FEAT_MAX
    // / 2) down to where the fourth powers of the smallest deviations leave the normal numbers;
    // below that, and down to the variance's underflow, every result is finite (no shape when
    // the variance is below 2^-60 / 2^-500), never NaN.
    static dv_real_t x[3000], y[3000];
    for (int i = 0; i < 3000; i++) {
        x[i] = (dv_real_t)(sin(0.07 * i) + 0.5 * sin(0.31 * i) * sin(0.31 * i));
    }
    dv_moments_t m;
    dv_stats_t ref, st;
    moments_of(x, 3000, 0, &ref, &m);
#ifdef DV_REAL_DOUBLE
    const int kmin = -240, kmax = 199;
#else
    const int kmin = -20, kmax = 23;
#endif
    for (int k = 2 * kmin - 100; k <= kmax; k++) {
        for (int i = 0; i < 3000; i++) y[i] = (dv_real_t)ldexp((double)x[i], k);
        for (int block = 0; block < 2; block++) {
            moments_of(y, 3000, block, &st, &m);
            assert_true(stats_finite(&st));
            assert_true(st.peak == (dv_real_t)ldexp((double)ref.peak, k) || k < kmin);
            if (k < kmin) {
                continue; // round-off of subnormals: finite is what is promised
            }
            if (!block) {
                assert_true(st.kurt == ref.kurt && st.skew == ref.skew);
                assert_true(st.std == (dv_real_t)ldexp((double)ref.std, k));
            } else {
                dv_stats_t rb;
                moments_of(x, 3000, 1, &rb, &m);
                assert_true(st.kurt == rb.kurt && st.skew == rb.skew);
                assert_true(st.std == (dv_real_t)ldexp((double)rb.std, k));
            }
        }
    }
}

static void test_moments_tiny_variance_has_no_shape(void **state)
{
    (void)state;
    // the float kurtosis of +-1e-20 was 0/0 = NaN: now no shape, the rest exact and finite
    dv_moments_t m;
    dv_stats_t st;
    dv_moments_init(&m);
    for (int i = 0; i < 256; i++) dv_moments_update(&m, (i & 1) ? DV_R(-1e-20) : DV_R(1e-20));
    assert_int_equal(dv_moments_get(&m, &st), DV_OK);
    assert_true(stats_finite(&st));
#ifndef DV_REAL_DOUBLE
    assert_true(st.flags & DV_STATS_NO_SHAPE);
#else
    assert_true(dv_test_close(st.kurt, 1.0, 1e-12, 0));
#endif
    assert_true(dv_test_close(st.std, 1e-20, 1e-4, 0)); // float: a subnormal variance
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
        cmocka_unit_test(test_moments_full_scale_closed_form),
        cmocka_unit_test(test_moments_beyond_range_is_dropped_and_counted),
        cmocka_unit_test(test_moments_scaled_shape_is_identical),
        cmocka_unit_test(test_moments_tiny_variance_has_no_shape),
    };
    return cmocka_run_group_tests_name("dv_moments", tests, NULL, NULL);
}

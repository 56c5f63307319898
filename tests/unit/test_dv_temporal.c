// Temporal moments: golden (numpy two-pass), closed forms, long records, bad input.
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include "dv_test_util.h"
#include "dynval/dv_temporal.h"

enum { NMAX = 4096 };
static double xin[NMAX];
static dv_real_t xr[NMAX];

static void check(const char *cas, int block)
{
    char file[64];
    snprintf(file, sizeof file, "features_%s.csv", cas);
    assert_int_equal(dv_test_load(file, xin, NMAX), NMAX);
    for (int i = 0; i < NMAX; i++) xr[i] = (dv_real_t)xin[i];
    dv_temporal_t s;
    assert_int_equal(dv_temporal_init(&s, (dv_real_t)(1.0 / 640.0)), DV_OK);
    if (block) {
        assert_int_equal(dv_temporal_update_block(&s, xr, 5), DV_OK);
        assert_int_equal(dv_temporal_update_block(&s, xr + 5, NMAX - 5), DV_OK);
    } else {
        for (int i = 0; i < NMAX; i++) assert_int_equal(dv_temporal_update(&s, xr[i]), DV_OK);
    }
    dv_temporal_out_t o;
    assert_int_equal(dv_temporal_get(&s, &o), DV_OK);
    assert_int_equal(o.count, NMAX);
    const char *names[] = {"tm_energy", "tm_time", "tm_duration", "tm_skew", "tm_kurt", "tm_amp"};
    double got[] = {o.energy, o.central_time, o.rms_duration, o.central_skew, o.central_kurt,
                    o.root_energy_amp};
    double dur = dv_test_expected("features_expected.csv", cas, "tm_duration");
    for (int k = 0; k < 6; k++) {
        double want = dv_test_expected("features_expected.csv", cas, names[k]);
        assert_false(isnan(want));
        // time-like moments are judged on the record's RMS duration (S can be near 0)
        double scale = (k >= 1 && k <= 4) ? dur : 0;
        assert_true(dv_test_close(got[k], want, DV_TEST_RTOL, scale));
    }
}

static void test_temporal_golden(void **state)
{
    (void)state;
    check("random", 0);
    check("decay", 0);
    check("skewed", 0);
    check("offset", 0);
}

static void test_temporal_block_golden(void **state)
{
    (void)state;
    check("random", 1);
    check("decay", 1);
}

// A rectangular pulse of height h over samples a..b (dt = 1): E = h^2 (b-a+1),
// T = (a+b)/2, D^2 = ((b-a+1)^2 - 1)/12, S = 0, K^4 = (3 m^4 - ... ) -> check E, T, D, S.
static void test_temporal_rectangle_closed_form(void **state)
{
    (void)state;
    dv_temporal_t s;
    dv_temporal_init(&s, DV_R(1.0));
    const int a = 1000, b = 1999, n = 3000;
    for (int i = 0; i < n; i++) dv_temporal_update(&s, (i >= a && i <= b) ? DV_R(2.0) : DV_R(0.0));
    dv_temporal_out_t o;
    assert_int_equal(dv_temporal_get(&s, &o), DV_OK);
    const double m = b - a + 1;
    assert_true(dv_test_close(o.energy, 4.0 * m, 1e-6, 0));
    assert_true(dv_test_close(o.central_time, 0.5 * (a + b), 1e-6, 0));
    assert_true(dv_test_close(o.rms_duration, sqrt((m * m - 1.0) / 12.0), 1e-5, 0));
    assert_true(fabs(o.central_skew) < 1e-3 * o.rms_duration);
    // discrete uniform: fourth central moment (m^2-1)(3m^2-7)/240
    assert_true(dv_test_close(o.central_kurt, pow((m * m - 1) * (3 * m * m - 7) / 240.0, 0.25), 1e-5, 0));
}

// A long record: a burst at the end of 2e6 samples keeps T and D exact (no t^4 blow-up).
static void test_temporal_long_record_is_stable(void **state)
{
    (void)state;
    dv_temporal_t s;
    dv_temporal_init(&s, DV_R(1.0));
    const long n = 2000000;
    for (long i = 0; i < n; i++) {
        dv_real_t x = (i >= n - 100) ? DV_R(1.0) : DV_R(0.0);
        dv_temporal_update(&s, x);
    }
    dv_temporal_out_t o;
    assert_int_equal(dv_temporal_get(&s, &o), DV_OK);
    assert_true(dv_test_close(o.central_time, (double)(n - 100 + n - 1) / 2.0, 1e-6, 0));
    assert_true(dv_test_close(o.rms_duration, sqrt((100.0 * 100.0 - 1.0) / 12.0),
                              sizeof(dv_real_t) == 8 ? 1e-9 : 1e-3, 0));
}

static void test_temporal_bad_input(void **state)
{
    (void)state;
    dv_temporal_t s;
    assert_int_equal(dv_temporal_init(NULL, DV_R(1.0)), DV_EINVAL);
    assert_int_equal(dv_temporal_init(&s, DV_R(0.0)), DV_EINVAL);
    assert_int_equal(dv_temporal_init(&s, (dv_real_t)NAN), DV_EINVAL);
    assert_int_equal(dv_temporal_init(&s, DV_R(0.5)), DV_OK);
    dv_temporal_out_t o;
    o.energy = -1;
    assert_int_equal(dv_temporal_get(&s, &o), DV_ENOTREADY);
    dv_temporal_update(&s, DV_R(0.0));
    assert_int_equal(dv_temporal_get(&s, &o), DV_ENUMERIC); // zero energy
    assert_true(o.energy == -1);
    // NaN keeps its time slot: a pulse at sample 2 after a NaN at 1 is still at t = 1 s
    assert_int_equal(dv_temporal_update(&s, (dv_real_t)NAN), DV_ENUMERIC);
    dv_temporal_update(&s, DV_R(3.0));
    assert_int_equal(dv_temporal_get(&s, &o), DV_OK);
    assert_true(dv_test_close(o.central_time, 1.0, 1e-6, 0));
    assert_true(dv_test_close(o.energy, 4.5, 1e-6, 0));
    assert_int_equal(s.n_nonfinite, 1);
}

// ---- finite in, finite out -------------------------------------------------------------------

#include "dynval/dv_config.h"

static dv_status_t temporal_of(const dv_real_t *x, size_t n, int block, dv_temporal_out_t *o)
{
    dv_temporal_t t;
    assert_int_equal(dv_temporal_init(&t, DV_R(1.0) / DV_R(640.0)), DV_OK);
    if (block) {
        (void)dv_temporal_update_block(&t, x, n);
    } else {
        for (size_t i = 0; i < n; i++) (void)dv_temporal_update(&t, x[i]);
    }
    return dv_temporal_get(&t, o);
}

static int tm_finite(const dv_temporal_out_t *o)
{
    return isfinite(o->energy) && isfinite(o->central_time) && isfinite(o->rms_duration) &&
           isfinite(o->central_skew) && isfinite(o->central_kurt) &&
           isfinite(o->root_energy_amp);
}

static void test_temporal_scaled_is_identical(void **state)
{
    (void)state;
    // The weights x^2 are kept scaled by exact powers of two: T, D, S, K of x 2^k are those of
    // x bit for bit, and E scales by 2^2k exactly, from full scale down to where x^2 tau^4 of the
    // smallest samples leaves the normal numbers. In float this overflowed to K = inf from
    // |x| ~ 6e4 over 4096 samples, and gave NaN at 1e-10.
    enum { N = 4096 };
    static dv_real_t x[N], y[N];
    for (int i = 0; i < N; i++) {
        x[i] = (dv_real_t)((1.0 + 0.5 * sin(0.013 * i)) * sin(0.2 * i + 0.1)) * DV_R(2.0);
    }
#ifdef DV_REAL_DOUBLE
    const int kmin = -200, kmax = 198;
#else
    const int kmin = -20, kmax = 21;
#endif
    for (int block = 0; block < 2; block++) {
        dv_temporal_out_t ref, o;
        assert_int_equal(temporal_of(x, N, block, &ref), DV_OK);
        for (int k = 2 * kmin - 100; k <= kmax + 1; k++) {
            for (int i = 0; i < N; i++) y[i] = (dv_real_t)ldexp((double)x[i], k);
            const dv_status_t st = temporal_of(y, N, block, &o);
            assert_true(st == DV_OK || st == DV_ENUMERIC); // ENUMERIC: every x^2 underflowed
            if (st == DV_OK) {
                assert_true(tm_finite(&o));
            }
            // the block path takes a block whose sum of x^2 exceeds DV_FEAT_MAX^2 sample by
            // sample (same values, other round-off): float blocks with rms > 2^21
            if (k < kmin || k > (block ? kmax - 3 : kmax)) {
                continue;
            }
            assert_int_equal(st, DV_OK);
            assert_true(o.central_time == ref.central_time && o.rms_duration == ref.rms_duration &&
                        o.central_skew == ref.central_skew && o.central_kurt == ref.central_kurt);
            assert_true(o.energy == (dv_real_t)ldexp((double)ref.energy, 2 * k));
        }
    }
}

static void test_temporal_full_scale_closed_form(void **state)
{
    (void)state;
    // a constant record at +-DV_FEAT_MAX, n samples: E = n L^2 dt, T = (n - 1) dt / 2,
    // D^2 = (n^2 - 1) dt^2 / 12, S = 0, K^4 = (n^2 - 1)(3 n^2 - 7) dt^4 / 240
    enum { N = 1 << 14 };
    static dv_real_t x[N];
    const double L = (double)DV_FEAT_MAX, n = N;
    for (int i = 0; i < N; i++) x[i] = (i & 1) ? -DV_FEAT_MAX : DV_FEAT_MAX;
    for (int block = 0; block < 2; block++) {
        dv_temporal_t t;
        dv_temporal_out_t o;
        assert_int_equal(dv_temporal_init(&t, DV_R(1.0)), DV_OK);
        if (block) {
            assert_int_equal(dv_temporal_update_block(&t, x, N), DV_OK);
        } else {
            for (int i = 0; i < N; i++) assert_int_equal(dv_temporal_update(&t, x[i]), DV_OK);
        }
        assert_int_equal(dv_temporal_get(&t, &o), DV_OK);
        assert_true(tm_finite(&o));
        assert_true(dv_test_close(o.energy, n * L * L, 1e-6, 0));
        assert_true(dv_test_close(o.central_time, (n - 1) / 2, 1e-6, 0));
        assert_true(dv_test_close(o.rms_duration, sqrt((n * n - 1) / 12), 1e-5, 0));
        assert_true(dv_test_close(o.central_kurt, pow((n * n - 1) * (3 * n * n - 7) / 240, 0.25),
                                  1e-4, 0));
        assert_true(fabs((double)o.central_skew) < 1e-2 * n);
    }
    // beyond the range: dropped and counted, its time slot kept
    dv_temporal_t t;
    dv_temporal_init(&t, DV_R(1.0));
    assert_int_equal(dv_temporal_update(&t, DV_FEAT_MAX * DV_R(2.0)), DV_ENUMERIC);
    assert_int_equal(dv_temporal_update(&t, DV_R(1.0)), DV_OK);
    dv_temporal_out_t o;
    assert_int_equal(dv_temporal_get(&t, &o), DV_OK);
    assert_true(o.central_time == 1 && o.energy == 1 && t.n_nonfinite == 1);
}

static void test_temporal_dt_range(void **state)
{
    (void)state;
    dv_temporal_t t;
    assert_int_equal(dv_temporal_init(&t, DV_TEMPORAL_MAX_DT_S), DV_OK);
    assert_int_equal(dv_temporal_init(&t, DV_TEMPORAL_MAX_DT_S * DV_R(2.0)), DV_EINVAL);
    assert_int_equal(dv_temporal_init(&t, (dv_real_t)INFINITY), DV_EINVAL);
    assert_int_equal(dv_temporal_init(&t, (dv_real_t)NAN), DV_EINVAL);
    // the longest period with full-scale samples: every result finite
    dv_temporal_init(&t, DV_TEMPORAL_MAX_DT_S);
    for (int i = 0; i < 5000; i++) (void)dv_temporal_update(&t, (i % 3) ? DV_FEAT_MAX : DV_R(0.0));
    dv_temporal_out_t o;
    assert_int_equal(dv_temporal_get(&t, &o), DV_OK);
    assert_true(tm_finite(&o));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_temporal_golden),
        cmocka_unit_test(test_temporal_block_golden),
        cmocka_unit_test(test_temporal_rectangle_closed_form),
        cmocka_unit_test(test_temporal_long_record_is_stable),
        cmocka_unit_test(test_temporal_bad_input),
        cmocka_unit_test(test_temporal_scaled_is_identical),
        cmocka_unit_test(test_temporal_full_scale_closed_form),
        cmocka_unit_test(test_temporal_dt_range),
    };
    return cmocka_run_group_tests_name("dv_temporal", tests, NULL, NULL);
}

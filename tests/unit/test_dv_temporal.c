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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_temporal_golden),
        cmocka_unit_test(test_temporal_block_golden),
        cmocka_unit_test(test_temporal_rectangle_closed_form),
        cmocka_unit_test(test_temporal_long_record_is_stable),
        cmocka_unit_test(test_temporal_bad_input),
    };
    return cmocka_run_group_tests_name("dv_temporal", tests, NULL, NULL);
}

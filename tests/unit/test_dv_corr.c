// Correlation coefficient: golden (numpy corrcoef), closed forms, offsets, bad input.
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include "dv_test_util.h"
#include "dynval/dv_corr.h"

enum { NMAX = 4096 };
static double xs[NMAX], ys[NMAX];

static void test_corr_golden(void **state)
{
    (void)state;
    assert_int_equal(dv_test_load("features_random.csv", xs, NMAX), NMAX);
    assert_int_equal(dv_test_load("features_corr_y.csv", ys, NMAX), NMAX);
    dv_corr_t c;
    assert_int_equal(dv_corr_init(&c), DV_OK);
    for (int i = 0; i < NMAX; i++) dv_corr_update(&c, (dv_real_t)xs[i], (dv_real_t)ys[i]);
    dv_real_t r;
    assert_int_equal(dv_corr_get(&c, &r), DV_OK);
    double want = dv_test_expected("features_expected.csv", "random", "corr_y");
    assert_true(dv_test_close(r, want, DV_TEST_RTOL, 0));
}

static void test_corr_linear_relations_are_plus_minus_one(void **state)
{
    (void)state;
    dv_corr_t a, b;
    dv_corr_init(&a);
    dv_corr_init(&b);
    for (int i = 0; i < 1000; i++) {
        dv_real_t x = (dv_real_t)sin(0.1 * i) + DV_R(5000.0); // large offset on x
        dv_corr_update(&a, x, DV_R(3.0) * x - DV_R(1.0));
        dv_corr_update(&b, x, DV_R(-0.5) * x);
    }
    dv_real_t r;
    dv_corr_get(&a, &r);
    assert_true(dv_test_close(r, 1.0, 1e-4, 0));
    dv_corr_get(&b, &r);
    assert_true(dv_test_close(r, -1.0, 1e-4, 0));
    // sine and cosine over whole periods are uncorrelated
    dv_corr_t q;
    dv_corr_init(&q);
    for (int i = 0; i < 6400; i++) {
        double ph = 2.0 * M_PI * i / 64.0;
        dv_corr_update(&q, (dv_real_t)sin(ph), (dv_real_t)cos(ph));
    }
    dv_corr_get(&q, &r);
    assert_true(fabs(r) < 1e-4);
}

static void test_corr_bad_input(void **state)
{
    (void)state;
    dv_corr_t c;
    assert_int_equal(dv_corr_init(NULL), DV_EINVAL);
    dv_corr_init(&c);
    dv_real_t r = 7;
    dv_corr_update(&c, 1, 2);
    assert_int_equal(dv_corr_get(&c, &r), DV_ENOTREADY);
    assert_int_equal(dv_corr_update(&c, (dv_real_t)NAN, 2), DV_ENUMERIC);
    assert_int_equal(dv_corr_update(&c, 1, (dv_real_t)INFINITY), DV_ENUMERIC);
    dv_corr_update(&c, 1, 3);
    assert_int_equal(dv_corr_get(&c, &r), DV_ENUMERIC); // x constant
    assert_true(r == 7);
    assert_int_equal(c.n_nonfinite, 2);
    assert_int_equal(c.count, 2);
    assert_int_equal(dv_corr_get(&c, NULL), DV_EINVAL);
}

// ---- finite in, finite out -------------------------------------------------------------------

#include "dynval/dv_config.h"

static void test_corr_full_scale_is_finite(void **state)
{
    (void)state;
    dv_corr_t c;
    dv_corr_init(&c);
    for (int i = 0; i < 1000; i++) {
        const dv_real_t x = (i & 1) ? DV_FEAT_MAX : -DV_FEAT_MAX;
        assert_int_equal(dv_corr_update(&c, x, -x), DV_OK);
    }
    assert_int_equal(dv_corr_update(&c, DV_REAL_MAX, DV_R(1.0)), DV_ENUMERIC);
    dv_real_t r;
    assert_int_equal(dv_corr_get(&c, &r), DV_OK);
    assert_true(r == DV_R(-1.0));
    assert_int_equal(c.n_nonfinite, 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_corr_golden),
        cmocka_unit_test(test_corr_linear_relations_are_plus_minus_one),
        cmocka_unit_test(test_corr_bad_input),
        cmocka_unit_test(test_corr_full_scale_is_finite),
    };
    return cmocka_run_group_tests_name("dv_corr", tests, NULL, NULL);
}

// FFT: complex and real transforms against a direct DFT (long double) for every length
// 4..1024, bad input.
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include "dv_test_util.h"
#include "dynval/dv_fft.h"

enum { NMAX = 1024 };

#ifdef DV_REAL_DOUBLE
#define FFT_TOL 1e-13 // max |X - DFT| / max |DFT|
#else
#define FFT_TOL 2e-6
#endif

static void test_fft_matches_direct_dft(void **state)
{
    (void)state;
    static dv_real_t tw[DV_FFT_BUF_LEN(NMAX)], x[2 * NMAX];
    static double x0[2 * NMAX];
    uint32_t r = 99u;
    for (size_t n = 4; n <= NMAX; n *= 2) {
        dv_fft_t f;
        assert_int_equal(dv_fft_init(&f, n, tw, DV_FFT_BUF_LEN(n)), DV_OK);
        for (size_t i = 0; i < 2 * n; i++) {
            r = r * 1664525u + 1013904223u;
            x[i] = (dv_real_t)((double)(r >> 8) / 16777216.0 - 0.5);
            x0[i] = (double)x[i];
        }
        dv_fft_forward(&f, x);
        double emax = 0, xmax = 0;
        for (size_t k = 0; k < n; k++) {
            long double re = 0, im = 0;
            for (size_t m = 0; m < n; m++) {
                long double a = -2.0L * 3.14159265358979323846264338327950288L *
                                (long double)((k * m) % n) / (long double)n;
                re += x0[2 * m] * cosl(a) - x0[2 * m + 1] * sinl(a);
                im += x0[2 * m] * sinl(a) + x0[2 * m + 1] * cosl(a);
            }
            emax = fmax(emax, hypot(x[2 * k] - (double)re, x[2 * k + 1] - (double)im));
            xmax = fmax(xmax, hypot((double)re, (double)im));
        }
        if (!(emax <= FFT_TOL * xmax)) fprintf(stderr, "  n %zu: err %.3g\n", n, emax / xmax);
        assert_true(emax <= FFT_TOL * xmax);
    }
}

static void test_fft_real_matches_direct_dft(void **state)
{
    (void)state;
    static dv_real_t tw[DV_FFT_BUF_LEN(NMAX)], x[NMAX];
    static double x0[NMAX];
    uint32_t r = 7u;
    for (size_t n = 4; n <= NMAX; n *= 2) {
        dv_fft_t f;
        assert_int_equal(dv_fft_init(&f, n, tw, DV_FFT_BUF_LEN(n)), DV_OK);
        for (size_t i = 0; i < n; i++) {
            r = r * 1664525u + 1013904223u;
            x[i] = (dv_real_t)((double)(r >> 8) / 16777216.0 - 0.5);
            x0[i] = (double)x[i];
        }
        dv_fft_forward_real(&f, x);
        double emax = 0, xmax = 0;
        for (size_t k = 0; k <= n / 2; k++) {
            long double re = 0, im = 0;
            for (size_t m = 0; m < n; m++) {
                long double a = -2.0L * 3.14159265358979323846264338327950288L *
                                (long double)((k * m) % n) / (long double)n;
                re += x0[m] * cosl(a);
                im += x0[m] * sinl(a);
            }
            double gr, gi;
            if (k == 0 || k == n / 2) {
                gr = x[k == 0 ? 0 : 1];
                gi = 0;
                assert_true(fabsl(im) < 1e-12L); // the packing's real bins
            } else {
                gr = x[2 * k];
                gi = x[2 * k + 1];
            }
            emax = fmax(emax, hypot(gr - (double)re, gi - (double)im));
            xmax = fmax(xmax, hypot((double)re, (double)im));
        }
        if (!(emax <= FFT_TOL * xmax)) fprintf(stderr, "  n %zu: err %.3g\n", n, emax / xmax);
        assert_true(emax <= FFT_TOL * xmax);
    }
}

static void test_fft_bad_input(void **state)
{
    (void)state;
    static dv_real_t tw[64];
    dv_fft_t f;
    assert_int_equal(dv_fft_init(NULL, 16, tw, 64), DV_EINVAL);
    assert_int_equal(dv_fft_init(&f, 16, NULL, 64), DV_EINVAL);
    assert_int_equal(dv_fft_init(&f, 2, tw, 64), DV_EINVAL);
    assert_int_equal(dv_fft_init(&f, 24, tw, 64), DV_EINVAL);
    assert_int_equal(dv_fft_init(&f, 0, tw, 64), DV_EINVAL);
    assert_int_equal(dv_fft_init(&f, 128, tw, 64), DV_ESIZE);
    assert_int_equal(dv_fft_init(&f, 64, tw, 64), DV_OK);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fft_matches_direct_dft),
        cmocka_unit_test(test_fft_real_matches_direct_dft),
        cmocka_unit_test(test_fft_bad_input),
    };
    return cmocka_run_group_tests_name("dv_fft", tests, NULL, NULL);
}

// Streaming Welch FRF: golden spectra, H1 and coherence from scipy (tests/gen/gen_frf.py), the
// resonance's frequency and damping, closed forms (pure gain, zero channels, exponential
// averaging), bad input.
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include "dv_test_util.h"
#include "dynval/dv_frf.h"

enum { SEG = 512, NB = SEG / 2 + 1, NMAX = 16384 };

// Agreement with scipy (float64) as measured (double: H1 3.7e-15, coherence 1.6e-15, spectra
// 3.4e-15; float: H1 2.2e-6, coherence 1.1e-6, spectra 2.2e-6), with about 10x margin in float.
#ifdef DV_REAL_DOUBLE
#define H1_RTOL 1e-12  // |H1 - H1_scipy| / |H1_scipy|, every bin
#define COH_ATOL 1e-12 // |coh - coh_scipy|
#define G_RTOL 1e-12   // auto- and cross-spectra, relative to max(|G|, 1e-6 max G)
#else
#define H1_RTOL 2e-5
#define COH_ATOL 1e-5
#define G_RTOL 2e-5
#endif

static double us[NMAX], ys[NMAX];
static double ref[NB * 5];
static dv_real_t buf[DV_FRF_BUF_LEN(SEG)];

static size_t load_record(void)
{
    size_t n = dv_test_load("frf_u.csv", us, NMAX);
    assert_int_equal(dv_test_load("frf_y.csv", ys, NMAX), n);
    assert_int_equal((double)n, dv_test_expected("frf_expected.csv", "all", "n"));
    return n;
}

static void check_golden(const char *cas, bool block)
{
    size_t n = load_record();
    char name[64];
    snprintf(name, sizeof name, "frf_ref_%s.csv", cas);
    assert_int_equal(dv_test_load(name, ref, NB * 5), NB * 5);
    dv_frf_config_t cfg = {SEG, (uint32_t)dv_test_expected("frf_expected.csv", cas, "hop"), 0u,
                           (dv_real_t)dv_test_expected("frf_expected.csv", "all", "fs_hz")};
    dv_frf_t s;
    assert_int_equal(dv_frf_buffer_size(&cfg), DV_FRF_BUF_LEN(SEG));
    assert_int_equal(dv_frf_init(&s, &cfg, buf, DV_FRF_BUF_LEN(SEG)), DV_OK);
    if (block) {
        static dv_real_t ub[NMAX], yb[NMAX];
        for (size_t i = 0; i < n; i++) {
            ub[i] = (dv_real_t)us[i];
            yb[i] = (dv_real_t)ys[i];
        }
        assert_int_equal(dv_frf_update_block(&s, ub, yb, 100), DV_OK); // no segment yet
        assert_int_equal(dv_frf_update_block(&s, ub + 100, yb + 100, n - 100), DV_DONE);
    } else {
        for (size_t i = 0; i < n; i++) {
            dv_status_t st = dv_frf_update(&s, (dv_real_t)us[i], (dv_real_t)ys[i]);
            assert_true(st == DV_OK || st == DV_DONE);
        }
    }
    assert_int_equal(dv_frf_segments(&s),
                     (uint64_t)dv_test_expected("frf_expected.csv", cas, "n_seg"));

    double gmax = 0;
    for (int k = 0; k < NB; k++) gmax = fmax(gmax, fmax(ref[5 * k], ref[5 * k + 1]));
    double e_h1 = 0, e_coh = 0, e_g = 0, e_ph = 0;
    int bad = 0;
    for (int k = 0; k < NB; k++) {
        const double *r = &ref[5 * k];
        dv_frf_bin_t b;
        assert_int_equal(dv_frf_get_bin(&s, k, &b), DV_OK);
        assert_true(fabs(b.f_hz - k * 1024.0 / SEG) < 1e-9);
        const double g[4] = {b.guu, b.gyy, b.guy_re, b.guy_im};
        const double gscale = hypot(r[2], r[3]) > 1e-6 * gmax ? hypot(r[2], r[3]) : 1e-6 * gmax;
        for (int q = 0; q < 4; q++) {
            double sc = q < 2 ? fmax(fabs(r[q]), 1e-6 * gmax) : gscale;
            e_g = fmax(e_g, fabs(g[q] - r[q]) / sc);
        }
        const double hr = r[2] / r[0], hi = r[3] / r[0];
        const double eh = hypot(b.h1_re - hr, b.h1_im - hi) / hypot(hr, hi);
        e_h1 = fmax(e_h1, eh);
        double dph = atan2(b.h1_im, b.h1_re) - atan2(hi, hr);
        dph = fabs(remainder(dph, 2 * M_PI));
        e_ph = fmax(e_ph, dph);
        e_coh = fmax(e_coh, fabs(b.coh - r[4]));
        if (!(eh <= H1_RTOL) || !(fabs(b.coh - r[4]) <= COH_ATOL)) {
            if (bad++ < 5) {
                fprintf(stderr, "  bin %d: H1 rel err %.3g, coh %.9g want %.9g\n", k, eh, b.coh,
                        r[4]);
            }
        }
        // H2 = Gyy / conj(Guy)
        const double m2 = r[2] * r[2] + r[3] * r[3], h2m = r[1] / sqrt(m2);
        assert_true(dv_test_close(b.h2_re, r[1] * r[2] / m2, H1_RTOL, h2m));
        assert_true(dv_test_close(b.h2_im, r[1] * r[3] / m2, H1_RTOL, h2m));
    }
    fprintf(stderr, "[ %s %s ] max H1 rel err %.3g (phase %.3g rad), max coherence abs err %.3g, "
            "max spectra rel err %.3g\n", cas, sizeof(dv_real_t) == 8 ? "double" : "float", e_h1,
            e_ph, e_coh, e_g);
    assert_int_equal(bad, 0);
    assert_true(e_g <= G_RTOL);

    // the vector getters agree with the bin getter
    dv_real_t re[NB], im[NB], coh[NB];
    assert_int_equal(dv_frf_get_h1(&s, re, im, NB), DV_OK);
    assert_int_equal(dv_frf_get_coherence(&s, coh, NB), DV_OK);
    for (int k = 0; k < NB; k++) {
        dv_frf_bin_t b;
        dv_frf_get_bin(&s, k, &b);
        assert_true(re[k] == b.h1_re && im[k] == b.h1_im && coh[k] == b.coh);
    }
    assert_int_equal(dv_frf_get_h2(&s, re, im, NB), DV_OK);
}

static void test_frf_golden_scipy_50pct_overlap(void **state)
{
    (void)state;
    check_golden("ov50", false);
}

static void test_frf_golden_scipy_no_overlap_block(void **state)
{
    (void)state;
    check_golden("ov0", true);
}

static void test_frf_resonance_peak(void **state)
{
    (void)state;
    size_t n = load_record();
    const double fn = dv_test_expected("frf_expected.csv", "all", "fn_hz");
    const double zeta = dv_test_expected("frf_expected.csv", "all", "zeta");
    dv_frf_config_t cfg = {SEG, SEG / 2, 0u, DV_R(1024.0)};
    dv_frf_t s;
    assert_int_equal(dv_frf_init(&s, &cfg, buf, DV_FRF_BUF_LEN(SEG)), DV_OK);
    dv_frf_peak_t pk[3];
    size_t np = 99;
    assert_int_equal(dv_frf_get_peaks(&s, pk, 3, &np), DV_ENOTREADY);
    assert_int_equal(np, 99);
    for (size_t i = 0; i < n; i++) dv_frf_update(&s, (dv_real_t)us[i], (dv_real_t)ys[i]);
    assert_int_equal(dv_frf_get_peaks(&s, pk, 3, &np), DV_OK);
    assert_true(np >= 1 && np <= 3);
    for (size_t i = 1; i < np; i++) assert_true(pk[i].mag <= pk[i - 1].mag);
    fprintf(stderr, "[ peak ] f %.4f Hz (true %.1f), |H1| %.4f (1/(2 zeta) = %.2f), zeta %.5f "
            "(true %.3f); %zu peaks, next |H1| %.3g\n", (double)pk[0].f_hz, fn, (double)pk[0].mag,
            0.5 / zeta, (double)pk[0].zeta, zeta, np, np > 1 ? (double)pk[1].mag : 0.0);
    // The same half-power points on scipy's H1 (gen_frf.py): the C peak search and interpolation,
    // checked to 1e-3 of the band in either real type.
    const double bw_ref = dv_test_expected("frf_expected.csv", "ov50", "hp_f2_hz") -
                          dv_test_expected("frf_expected.csv", "ov50", "hp_f1_hz");
    const double bw = 2.0 * pk[0].zeta * pk[0].f_hz;
    fprintf(stderr, "[ peak ] half-power band %.5f Hz, from scipy's H1 %.5f Hz (rel err %.3g)\n",
            bw, bw_ref, fabs(bw - bw_ref) / bw_ref);
    assert_true(fabs(bw - bw_ref) < 1e-3 * bw_ref);
    const double fp_ref = dv_test_expected("frf_expected.csv", "ov50", "peak_hz");
    assert_true(dv_test_close(pk[0].f_hz, fp_ref, 1e-5, 1)); // 1 mHz at 100 Hz
    // Against the true system: frequency within a quarter bin (0.5 Hz, 0.5 %); damping within
    // 15 %: a 5-bin half-power band is widened by the Hann window (scipy's H1 gives 0.0558 for
    // the true 0.050 as well); peak |H1| within 10 %.
    assert_true(fabs(pk[0].f_hz - fn) < 0.5);
    assert_true(fabs(pk[0].zeta - zeta) < 0.15 * zeta);
    assert_true(fabs(pk[0].mag - 0.5 / zeta) < 0.1 * 0.5 / zeta);
    if (np > 1) assert_true(pk[1].mag < 0.2 * pk[0].mag); // only one mode: the rest is noise
}

// y = 2 u exactly: H1 = H2 = 2, coherence 1 in every bin with input power.
static void test_frf_pure_gain(void **state)
{
    (void)state;
    enum { S = 64 };
    static dv_real_t b[DV_FRF_BUF_LEN(S)];
    dv_frf_config_t cfg = {S, 16, 0u, DV_R(100.0)};
    dv_frf_t s;
    assert_int_equal(dv_frf_init(&s, &cfg, b, DV_FRF_BUF_LEN(S)), DV_OK);
    uint32_t x = 12345u;
    for (int i = 0; i < 40 * S; i++) {
        x = x * 1664525u + 1013904223u;
        dv_real_t u = (dv_real_t)((double)(x >> 8) / 16777216.0 - 0.5);
        dv_frf_update(&s, u, DV_R(2.0) * u);
    }
    for (int k = 0; k < S / 2 + 1; k++) {
        dv_frf_bin_t o;
        assert_int_equal(dv_frf_get_bin(&s, k, &o), DV_OK);
        assert_true(dv_test_close(o.h1_re, 2.0, 1e-4, 1) && fabs(o.h1_im) < 1e-4);
        assert_true(dv_test_close(o.h2_re, 2.0, 1e-4, 1) && fabs(o.h2_im) < 1e-4);
        assert_true(o.coh > 1.0 - 1e-4 && o.coh <= 1.0);
    }
}

// Zero-power channels: results are defined (0), finite, and DV_OK.
static void test_frf_zero_channel_gives_zero_not_nan(void **state)
{
    (void)state;
    enum { S = 32 };
    static dv_real_t b[DV_FRF_BUF_LEN(S)];
    dv_frf_config_t cfg = {S, S / 2, 0u, DV_R(1.0)};
    for (int which = 0; which < 3; which++) { // 0: u = 0, 1: y = 0, 2: both 0
        dv_frf_t s;
        assert_int_equal(dv_frf_init(&s, &cfg, b, DV_FRF_BUF_LEN(S)), DV_OK);
        for (int i = 0; i < 4 * S; i++) {
            dv_real_t v = (dv_real_t)sin(0.37 * i) + DV_R(0.1) * (dv_real_t)(i % 7);
            dv_frf_update(&s, which == 1 ? v : DV_R(0.0), which == 0 ? v : DV_R(0.0));
        }
        for (int k = 0; k < S / 2 + 1; k++) {
            dv_frf_bin_t o;
            assert_int_equal(dv_frf_get_bin(&s, k, &o), DV_OK);
            assert_true(o.h1_re == 0 && o.h1_im == 0 && o.h2_re == 0 && o.h2_im == 0);
            assert_true(o.coh == 0);
            assert_true(isfinite(o.guu) && isfinite(o.gyy));
        }
        dv_frf_peak_t pk[2];
        size_t np = 9;
        assert_int_equal(dv_frf_get_peaks(&s, pk, 2, &np), DV_OK);
        assert_int_equal(np, 0);
    }
}

// n_avg > 0: after the first n_avg segments the average forgets exponentially.
static void test_frf_exponential_average_tracks_change(void **state)
{
    (void)state;
    enum { S = 64 };
    static dv_real_t b[DV_FRF_BUF_LEN(S)];
    for (uint32_t navg = 0; navg <= 4; navg += 4) {
        dv_frf_config_t cfg = {S, S, navg, DV_R(100.0)};
        dv_frf_t s;
        assert_int_equal(dv_frf_init(&s, &cfg, b, DV_FRF_BUF_LEN(S)), DV_OK);
        uint32_t x = 777u;
        for (int i = 0; i < 200 * S; i++) {
            x = x * 1664525u + 1013904223u;
            dv_real_t u = (dv_real_t)((double)(x >> 8) / 16777216.0 - 0.5);
            dv_frf_update(&s, u, (i < 100 * S ? DV_R(2.0) : DV_R(3.0)) * u);
        }
        dv_frf_bin_t o;
        assert_int_equal(dv_frf_get_bin(&s, 10, &o), DV_OK);
        if (navg == 0) {
            assert_true(o.h1_re > 2.2 && o.h1_re < 2.8); // the mean of both halves
            assert_true(o.coh < 0.999);
        } else {
            assert_true(dv_test_close(o.h1_re, 3.0, 1e-4, 1)); // (3/4)^100 of the old gain left
        }
    }
}

static void test_frf_bad_input(void **state)
{
    (void)state;
    enum { S = 64 };
    static dv_real_t b[DV_FRF_BUF_LEN(S)];
    dv_frf_t s;
    dv_frf_config_t cfg = {S, S / 2, 0u, DV_R(1000.0)};
    assert_int_equal(dv_frf_init(NULL, &cfg, b, DV_FRF_BUF_LEN(S)), DV_EINVAL);
    assert_int_equal(dv_frf_init(&s, NULL, b, DV_FRF_BUF_LEN(S)), DV_EINVAL);
    assert_int_equal(dv_frf_init(&s, &cfg, NULL, DV_FRF_BUF_LEN(S)), DV_EINVAL);
    assert_int_equal(dv_frf_init(&s, &cfg, b, DV_FRF_BUF_LEN(S) - 1), DV_ESIZE);
    assert_int_equal(dv_frf_buffer_size(NULL), 0);
    const dv_frf_config_t bad[] = {
        {96, 48, 0u, DV_R(1000.0)},                  // not a power of two
        {8, 4, 0u, DV_R(1000.0)},                    // below DV_FRF_MIN_SEG
        {2 * DV_FRF_MAX_SEG, 64, 0u, DV_R(1000.0)},  // above DV_FRF_MAX_SEG
        {S, 0, 0u, DV_R(1000.0)},                    // hop 0
        {S, S + 1, 0u, DV_R(1000.0)},                // hop > seg_len
        {S, S / 2, 0u, DV_R(0.0)},                   // fs 0
        {S, S / 2, 0u, (dv_real_t)NAN},              // fs NaN
        {S, S / 2, 0u, DV_R(1e8)},                   // fs too high
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(dv_frf_buffer_size(&bad[i]), 0);
        assert_int_equal(dv_frf_init(&s, &bad[i], b, DV_FRF_BUF_LEN(S)), DV_EINVAL);
    }

    assert_int_equal(dv_frf_init(&s, &cfg, b, DV_FRF_BUF_LEN(S)), DV_OK);
    dv_frf_bin_t o = {.coh = -7};
    dv_real_t re[S / 2 + 1] = {-7}, im[S / 2 + 1];
    dv_frf_peak_t pk[1];
    size_t np;
    assert_int_equal(dv_frf_get_bin(&s, 0, &o), DV_ENOTREADY);
    assert_true(o.coh == -7);
    assert_int_equal(dv_frf_get_h1(&s, re, im, S / 2 + 1), DV_ENOTREADY);
    assert_true(re[0] == -7);
    for (int i = 0; i < S - 1; i++) {
        assert_int_equal(dv_frf_update(&s, (dv_real_t)(i % 5), DV_R(0.5)), DV_OK);
    }

    // NaN/Inf/out-of-range samples: dropped, counted, state unchanged
    dv_frf_t before = s;
    static dv_real_t bcopy[DV_FRF_BUF_LEN(S)];
    memcpy(bcopy, b, sizeof b);
    assert_int_equal(dv_frf_update(&s, (dv_real_t)NAN, DV_R(1.0)), DV_ENUMERIC);
    assert_int_equal(dv_frf_update(&s, DV_R(1.0), (dv_real_t)INFINITY), DV_ENUMERIC);
    assert_int_equal(dv_frf_update(&s, DV_R(1.0), (dv_real_t)(-2.0 * DV_FEAT_MAX)), DV_ENUMERIC);
    assert_int_equal(dv_frf_nonfinite(&s), 3);
    s.n_nonfinite = before.n_nonfinite;
    assert_memory_equal(&s, &before, sizeof s);
    assert_memory_equal(b, bcopy, sizeof b);
    dv_real_t bu[2] = {DV_R(1.0), (dv_real_t)NAN}, by[2] = {DV_R(1.0), DV_R(1.0)};
    assert_int_equal(dv_frf_update_block(&s, bu, by, 2), DV_ENUMERIC); // first completes a segment
    assert_int_equal(dv_frf_segments(&s), 1);
    assert_int_equal(dv_frf_update_block(NULL, bu, by, 2), DV_EINVAL);
    assert_int_equal(dv_frf_update_block(&s, NULL, by, 2), DV_EINVAL);
    assert_int_equal(dv_frf_update_block(&s, NULL, NULL, 0), DV_OK);

    assert_int_equal(dv_frf_get_bin(&s, S / 2 + 1, &o), DV_ERANGE);
    assert_int_equal(dv_frf_get_bin(&s, 0, NULL), DV_EINVAL);
    assert_int_equal(dv_frf_get_bin(NULL, 0, &o), DV_EINVAL);
    assert_int_equal(dv_frf_get_h1(&s, re, im, S / 2), DV_ESIZE);
    assert_int_equal(dv_frf_get_h1(&s, re, NULL, S / 2 + 1), DV_EINVAL);
    assert_int_equal(dv_frf_get_h2(&s, NULL, im, S / 2 + 1), DV_EINVAL);
    assert_int_equal(dv_frf_get_coherence(&s, re, S / 2), DV_ESIZE);
    assert_int_equal(dv_frf_get_peaks(&s, pk, 0, &np), DV_EINVAL);
    assert_int_equal(dv_frf_get_peaks(&s, NULL, 1, &np), DV_EINVAL);
    assert_int_equal(dv_frf_get_peaks(&s, pk, 1, NULL), DV_EINVAL);
    assert_int_equal(dv_frf_segments(NULL), 0);
    assert_int_equal(dv_frf_nonfinite(NULL), 0);

    dv_frf_reset(&s);
    assert_int_equal(dv_frf_segments(&s), 0);
    assert_int_equal(dv_frf_nonfinite(&s), 0);
    assert_int_equal(dv_frf_get_bin(&s, 0, &o), DV_ENOTREADY);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_frf_golden_scipy_50pct_overlap),
        cmocka_unit_test(test_frf_golden_scipy_no_overlap_block),
        cmocka_unit_test(test_frf_resonance_peak),
        cmocka_unit_test(test_frf_pure_gain),
        cmocka_unit_test(test_frf_zero_channel_gives_zero_not_nan),
        cmocka_unit_test(test_frf_exponential_average_tracks_change),
        cmocka_unit_test(test_frf_bad_input),
    };
    return cmocka_run_group_tests_name("dv_frf", tests, NULL, NULL);
}

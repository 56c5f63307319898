// Residual statistics and the k-sigma outlier detector: closed forms, bounded buffers, bad input,
// and the impact record of tests/gen/gen_ar.py (4-DOF chain with a bumper gap).
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include "dv_test_util.h"
#include "dynval/dv_ar.h"
#include "dynval/dv_arstats.h"

enum { NMAX = 8192 };
static double xin[NMAX], cin[256], epi[256], endi[256];
static dv_real_t xr[NMAX], e[NMAX];
static dv_real_t work[DV_AR_WORK_LEN(NMAX, 64)];

// +-1 alternating (mean 0, std 1) with two spikes: closed-form moments and outliers.
static size_t spiky(dv_real_t *x)
{
    const size_t n = 1000;
    for (size_t i = 0; i < n; i++) x[i] = (i & 1) ? DV_R(1.0) : DV_R(-1.0);
    x[100] = DV_R(20.0);
    x[700] = DV_R(-30.0);
    return n;
}

static void test_arstats_record_closed_form(void **state)
{
    (void)state;
    size_t n = spiky(e);
    // mean = (20 - 30 - 1 + 1... ) / n: x[100] replaced a -1, x[700] replaced a -1
    double sum = 0, s2 = 0;
    for (size_t i = 0; i < n; i++) sum += e[i];
    double mean = sum / n;
    for (size_t i = 0; i < n; i++) s2 += (e[i] - mean) * (e[i] - mean);
    double sd = sqrt(s2 / n);
    uint32_t idx[4];
    dv_real_t size[4];
    dv_arstats_out_t o;
    assert_int_equal(dv_arstats_record(&o, DV_R(5.0), e, n, idx, size, 4), DV_OK);
    assert_int_equal(o.n_outliers, 2);
    assert_int_equal(o.n_stored, 2);
    assert_int_equal(o.n_overflow, 0);
    assert_int_equal(idx[0], 100);
    assert_int_equal(idx[1], 700);
    assert_true(dv_test_close(size[0], (20 - mean) / sd, 1e-5, 0));
    assert_true(dv_test_close(size[1], (-30 - mean) / sd, 1e-5, 0));
    assert_true(dv_test_close(o.rec.std, sd, 1e-5, 0));
    assert_true(dv_test_close(o.rec.rms, sqrt(mean * mean + sd * sd), 1e-5, 0));
    assert_true(o.rec.kurt > 50); // two spikes: heavy tails
    // capacity 1: the second outlier is counted, not stored
    idx[1] = 12345;
    assert_int_equal(dv_arstats_record(&o, DV_R(5.0), e, n, idx, NULL, 1), DV_OK);
    assert_int_equal(o.n_outliers, 2);
    assert_int_equal(o.n_stored, 1);
    assert_int_equal(o.n_overflow, 1);
    assert_int_equal(idx[1], 12345);
    // capacity 0: counting only
    assert_int_equal(dv_arstats_record(&o, DV_R(5.0), e, n, NULL, NULL, 0), DV_OK);
    assert_int_equal(o.n_outliers, 2);
    // k = 15 sigma finds only the larger spike (std ~1.5: 13.2 and 19.8 sigma)
    assert_int_equal(dv_arstats_record(&o, DV_R(15.0), e, n, idx, size, 4), DV_OK);
    assert_int_equal(o.n_outliers, 1);
    assert_int_equal(idx[0], 700);
}

static void test_arstats_nan_dropped_and_bad_input(void **state)
{
    (void)state;
    size_t n = spiky(e);
    e[5] = (dv_real_t)NAN;
    e[6] = (dv_real_t)INFINITY;
    uint32_t idx[4];
    dv_arstats_out_t o, keep;
    memset(&keep, 0x33, sizeof keep);
    o = keep;
    assert_int_equal(dv_arstats_record(&o, DV_R(5.0), e, n, idx, NULL, 4), DV_ENUMERIC);
    assert_int_equal(o.n_nonfinite, 2);
    assert_int_equal(o.rec.count, n - 2);
    assert_int_equal(o.n_outliers, 2);
    o = keep;
    assert_int_equal(dv_arstats_record(&o, DV_R(0.0), e, n, idx, NULL, 4), DV_EINVAL);
    assert_int_equal(dv_arstats_record(&o, DV_R(3.0), e, n, NULL, NULL, 4), DV_EINVAL);
    assert_int_equal(dv_arstats_record(&o, DV_R(3.0), NULL, n, idx, NULL, 4), DV_EINVAL);
    for (int i = 0; i < 10; i++) e[i] = DV_R(2.0);
    assert_int_equal(dv_arstats_record(&o, DV_R(3.0), e, 10, idx, NULL, 4), DV_ENOTREADY);
    assert_memory_equal(&o, &keep, sizeof o);
}

static void test_arstats_stream_flags_spikes(void **state)
{
    (void)state;
    size_t n = spiky(e);
    e[300] = (dv_real_t)NAN; // consumes a position
    dv_arstats_t s;
    dv_real_t buf[DV_ARSTATS_BUF_LEN(64)];
    uint32_t idx[1];
    dv_real_t size[1];
    assert_int_equal(dv_arstats_init(&s, DV_R(5.0), 64, buf, 10, idx, size, 1), DV_ESIZE);
    assert_int_equal(dv_arstats_init(&s, DV_R(-1.0), 64, buf, sizeof buf / sizeof *buf, idx, size, 1),
                     DV_EINVAL);
    dv_arstats_out_t o;
    assert_int_equal(dv_arstats_init(&s, DV_R(5.0), 64, buf, sizeof buf / sizeof *buf, idx, size, 1),
                     DV_OK);
    assert_int_equal(dv_arstats_get(&s, &o), DV_ENOTREADY);
    int flagged = 0;
    for (size_t i = 0; i < n; i++) {
        dv_status_t st = dv_arstats_update(&s, e[i]);
        if (i == 300) assert_int_equal(st, DV_ENUMERIC);
        if (st == DV_DONE) flagged++;
        if (i == 100 || i == 700) assert_int_equal(st, DV_DONE);
    }
    assert_int_equal(flagged, 2);
    assert_int_equal(dv_arstats_get(&s, &o), DV_OK);
    assert_int_equal(o.n_outliers, 2);
    assert_int_equal(o.n_stored, 1);
    assert_int_equal(o.n_overflow, 1);
    assert_int_equal(o.n_nonfinite, 1);
    assert_int_equal(idx[0], 100);
    assert_true(dv_test_close(size[0], 20.0, 1e-5, 0)); // window of +-1: mean 0, std 1
    assert_int_equal(o.win_ready, 1);
    assert_true(dv_test_close(o.win.rms, 1.0, 1e-5, 0));
    assert_int_equal(o.rec.count, n - 1);
}

// The report's Fig. 63: AR residual outliers line up with the bumper contacts.
static void test_arstats_impacts_line_up_with_contacts(void **state)
{
    (void)state;
    // Float builds too, same criteria: measured AR(40) float and double alike, 18/20 contacts hit
    // (0.90, at the bound), 4/48 outliers false (0.083), kurtosis 334.
    size_t n = dv_test_load("ar_impact.csv", xin, NMAX);
    size_t nc = dv_test_load("ar_impact_contacts.csv", cin, 256);
    size_t ne = dv_test_load("ar_impact_episodes.csv", epi, 256);
    assert_int_equal(dv_test_load("ar_impact_ends.csv", endi, 256), ne);
    assert_int_equal(n, NMAX);
    assert_true(nc >= 10);
    const uint32_t p = (uint32_t)dv_test_expected("ar_expected.csv", "impact", "p");
    const double k = dv_test_expected("ar_expected.csv", "impact", "k_sigma");
    for (size_t i = 0; i < n; i++) xr[i] = (dv_real_t)xin[i];
    dv_ar_model_t m;
    assert_int_equal(dv_ar_fit(&m, DV_AR_YULE_WALKER, p, xr, n, work, sizeof work / sizeof *work),
                     DV_OK);
    dv_ar_resid_t r;
    dv_real_t hist[DV_AR_RESID_BUF_LEN(64)];
    assert_int_equal(dv_ar_resid_init(&r, &m, hist, sizeof hist / sizeof *hist), DV_OK);
    size_t ne_out = 0;
    assert_int_equal(dv_ar_resid_update_block(&r, xr, n, e, &ne_out), DV_OK);
    assert_int_equal(ne_out, n - p);
    static uint32_t idx[512];
    dv_arstats_out_t o;
    assert_int_equal(dv_arstats_record(&o, (dv_real_t)k, e, ne_out, idx, NULL, 512), DV_OK);
    assert_int_equal(o.n_overflow, 0);
    int hit = 0, counted = 0, fals = 0;
    for (size_t c = 0; c < nc; c++) {
        if (cin[c] < p) continue;
        counted++;
        for (size_t j = 0; j < o.n_stored; j++) {
            if (fabs((double)(idx[j] + p) - cin[c]) <= 2) { hit++; break; }
        }
    }
    for (size_t j = 0; j < o.n_stored; j++) {
        double t = idx[j] + p; // residual index -> sample index
        int near = 0;
        for (size_t c = 0; c < ne; c++) near |= t >= epi[c] - 2 && t <= endi[c] + 2;
        fals += !near;
    }
    double hit_rate = (double)hit / counted, false_rate = (double)fals / o.n_stored;
    fprintf(stderr, "  %d/%d contacts hit (%.3f), %d/%d outliers false (%.3f), kurtosis %.1f\n",
            hit, counted, hit_rate, fals, (int)o.n_stored, false_rate, (double)o.rec.kurt);
    assert_true(hit_rate >= 0.9);
    assert_true(false_rate < 0.1);
    assert_true(o.rec.kurt > 5); // impacts make the residual heavy-tailed (Fig. 64)
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_arstats_record_closed_form),
        cmocka_unit_test(test_arstats_nan_dropped_and_bad_input),
        cmocka_unit_test(test_arstats_stream_flags_spikes),
        cmocka_unit_test(test_arstats_impacts_line_up_with_contacts),
    };
    return cmocka_run_group_tests_name("dv_arstats", tests, NULL, NULL);
}

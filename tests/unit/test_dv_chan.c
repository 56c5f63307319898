// The per-channel bundle: each feature equals its own module, records roll over, block API
// agrees with the per-sample API, NaN handling.
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include "dynval/dv_chan.h"
#include "dv_test_util.h"

enum { NMAX = 4096, WIN = 256, L = 64, NS = 64 };
static double xin[NMAX];
static dv_real_t xr[3 * NMAX];
static dv_real_t buf[DV_CHAN_BUF_LEN(WIN, NS)], buf2[DV_CHAN_BUF_LEN(WIN, NS)];
static const dv_chan_config_t CFG = {WIN, L, NS, DV_R(1.0) / DV_R(640.0), false};

static void load(void)
{
    assert_int_equal(dv_test_load("features_random.csv", xin, NMAX), NMAX);
    for (int r = 0; r < 3; r++)
        for (int i = 0; i < NMAX; i++) xr[r * NMAX + i] = (dv_real_t)xin[i] * (dv_real_t)(r + 1);
}

static void test_chan_record_features_match_golden(void **state)
{
    (void)state;
    load();
    dv_chan_t c;
    assert_int_equal(dv_chan_init(&c, &CFG, buf, DV_CHAN_BUF_LEN(WIN, NS)), DV_OK);
    int records = 0, segs = 0;
    for (int i = 0; i < NMAX; i++) {
        dv_status_t st = dv_chan_update(&c, xr[i]);
        records += st == DV_RECORD;
        segs += st == DV_DONE;
    }
    assert_int_equal(records, 1);
    assert_int_equal(segs, NS - 1);
    dv_stats_t st;
    dv_temporal_out_t tm;
    assert_int_equal(dv_chan_get_record(&c, &st, &tm), DV_OK);
    assert_true(dv_test_close(st.std, dv_test_expected("features_expected.csv", "random", "rec_std"), DV_TEST_RTOL, 0));
    assert_true(dv_test_close(st.kurt, dv_test_expected("features_expected.csv", "random", "rec_kurt"), DV_TEST_RTOL, 0));
    assert_true(dv_test_close(tm.central_time, dv_test_expected("features_expected.csv", "random", "tm_time"), DV_TEST_RTOL, 0));
    assert_true(dv_test_close(tm.energy, dv_test_expected("features_expected.csv", "random", "tm_energy"), DV_TEST_RTOL, 0));
    assert_int_equal(dv_chan_get_window(&c, &st), DV_OK);
    assert_true(dv_test_close(st.rms, dv_test_expected("features_expected.csv", "random", "win_rms"), DV_TEST_RTOL, 0));
    dv_real_t v[NS];
    assert_int_equal(dv_segstd_get(&c.seg, v, NS), DV_OK);
    assert_true(dv_test_close(v[17], dv_test_expected("features_expected.csv", "random", "segstd_17"), DV_TEST_RTOL, 0));
}

static void test_chan_block_agrees_with_per_sample(void **state)
{
    (void)state;
    load();
    dv_chan_t a, b;
    dv_chan_init(&a, &CFG, buf, DV_CHAN_BUF_LEN(WIN, NS));
    dv_chan_init(&b, &CFG, buf2, DV_CHAN_BUF_LEN(WIN, NS));
    const size_t n = 3 * NMAX - 100; // two whole records and most of a third
    for (size_t i = 0; i < n; i++) dv_chan_update(&a, xr[i]);
    size_t off = 0, used = 0;
    int records = 0;
    while (off < n) {
        size_t chunk = n - off < 1000 ? n - off : 1000; // chunks straddle record ends
        dv_status_t st = dv_chan_update_block(&b, xr + off, chunk, &used);
        assert_true(used >= 1 && used <= chunk);
        records += st == DV_RECORD;
        off += used;
    }
    assert_int_equal(records, 2);
    assert_int_equal(b.records, 2);
    dv_stats_t sa, sb;
    dv_temporal_out_t ta, tb;
    dv_chan_get_record(&a, &sa, &ta);
    dv_chan_get_record(&b, &sb, &tb);
    // record 2 is 2x the golden signal: exact merges keep both paths within round-off
    assert_true(dv_test_close(sb.std, sa.std, DV_TEST_RTOL, 0));
    assert_true(dv_test_close(sb.skew, sa.skew, DV_TEST_RTOL, 1));
    assert_true(dv_test_close(sb.kurt, sa.kurt, DV_TEST_RTOL, 0));
    assert_true(sb.peak == sa.peak && sb.count == sa.count);
    assert_true(dv_test_close(tb.rms_duration, ta.rms_duration, DV_TEST_RTOL, 0));
    assert_true(dv_test_close(sa.std, 2.0 * dv_test_expected("features_expected.csv", "random", "rec_std"), DV_TEST_RTOL, 0));
    dv_chan_get_window(&a, &sa);
    dv_chan_get_window(&b, &sb);
    assert_true(dv_test_stats_close(&sa, &sb, DV_TEST_RTOL));
}

static void test_chan_nan_is_dropped_everywhere(void **state)
{
    (void)state;
    dv_chan_t c;
    static dv_real_t small[DV_CHAN_BUF_LEN(4, 2)];
    const dv_chan_config_t cfg = {4, 4, 2, DV_R(0.01), false};
    assert_int_equal(dv_chan_init(&c, &cfg, small, DV_CHAN_BUF_LEN(4, 2)), DV_OK);
    for (int i = 0; i < 7; i++) {
        assert_true(dv_chan_update(&c, (dv_real_t)i) >= DV_OK);
        assert_int_equal(dv_chan_update(&c, (dv_real_t)NAN), DV_ENUMERIC);
    }
    assert_int_equal(dv_chan_update(&c, DV_R(7.0)), DV_RECORD);
    assert_int_equal(c.n_nonfinite, 7);
    dv_stats_t st;
    assert_int_equal(dv_chan_get_record(&c, &st, NULL), DV_OK);
    assert_int_equal(st.count, 8);
    assert_true(dv_test_close(st.mean, 3.5, 1e-6, 0));
    dv_real_t blk[10] = {1, 2, (dv_real_t)NAN, 3, 4, 5, 6, 7, 8, 9};
    size_t used = 0;
    assert_int_equal(dv_chan_update_block(&c, blk, 10, &used), DV_RECORD);
    assert_int_equal(used, 9);
    assert_int_equal(c.n_nonfinite, 8);
    assert_int_equal(dv_chan_get_record(&c, &st, NULL), DV_OK);
    assert_true(dv_test_close(st.mean, 4.5, 1e-6, 0));
}

// NaN/Inf inside whole 64-sample blocks of the block API (the fused kernel finds them after
// the fact): the block falls back to the per-sample path, nothing of it is half-applied, and
// the result equals the per-sample API's with the same samples dropped.
static void test_chan_block_nan_in_whole_blocks(void **state)
{
    (void)state;
    load();
    static dv_real_t xn[2 * NMAX];
    for (size_t i = 0; i < 2 * NMAX; i++) xn[i] = xr[i];
    const size_t bad[] = {0, 700, 701, 1000, 2047, 4096 + 63, 4096 + 64, 6000};
    for (size_t j = 0; j < sizeof bad / sizeof bad[0]; j++)
        xn[bad[j]] = (j % 2) ? (dv_real_t)NAN : (dv_real_t)((j % 4) == 0 ? INFINITY : -INFINITY);
    dv_chan_t a, b;
    dv_chan_init(&a, &CFG, buf, DV_CHAN_BUF_LEN(WIN, NS));
    dv_chan_init(&b, &CFG, buf2, DV_CHAN_BUF_LEN(WIN, NS));
    const size_t n = 2 * NMAX;
    int ra = 0, rb = 0;
    for (size_t i = 0; i < n; i++) ra += dv_chan_update(&a, xn[i]) == DV_RECORD;
    size_t off = 0, used = 0;
    while (off < n) {
        dv_status_t st = dv_chan_update_block(&b, xn + off, n - off, &used);
        assert_true(used >= 1 && used <= n - off);
        rb += st == DV_RECORD;
        off += used;
    }
    assert_int_equal(ra, 1);
    assert_int_equal(rb, 1);
    assert_int_equal(a.n_nonfinite, 8);
    assert_int_equal(b.n_nonfinite, 8);
    assert_true(a.tm.count == b.tm.count && a.rec.count == b.rec.count);
    dv_stats_t sa, sb;
    dv_temporal_out_t ta, tb;
    assert_int_equal(dv_chan_get_record(&a, &sa, &ta), DV_OK);
    assert_int_equal(dv_chan_get_record(&b, &sb, &tb), DV_OK);
    assert_true(dv_test_stats_close(&sa, &sb, DV_TEST_RTOL));
    assert_true(dv_test_close(tb.energy, ta.energy, DV_TEST_RTOL, 0));
    assert_true(dv_test_close(tb.rms_duration, ta.rms_duration, DV_TEST_RTOL, 0));
    assert_int_equal(dv_chan_get_window(&a, &sa), DV_OK);
    assert_int_equal(dv_chan_get_window(&b, &sb), DV_OK);
    assert_true(dv_test_stats_close(&sa, &sb, DV_TEST_RTOL));
    dv_real_t va[NS], vb[NS];
    assert_int_equal(dv_segstd_get(&a.seg, va, NS), DV_OK);
    assert_int_equal(dv_segstd_get(&b.seg, vb, NS), DV_OK);
    for (int i = 0; i < NS; i++) assert_true(dv_test_close(vb[i], va[i], DV_TEST_RTOL, 1e-12));
}

// no_seg_vectors: a buffer without the segment vectors, the same features bit for bit
// (each segment's STD read as it completes), and no vector to copy.
static void test_chan_without_segment_vectors(void **state)
{
    (void)state;
    load();
    static dv_real_t small[DV_CHAN_BUF_LEN(WIN, 0)];
    dv_chan_config_t cfg = CFG;
    cfg.no_seg_vectors = true;
    dv_chan_t a, b;
    assert_int_equal(dv_chan_init(&a, &CFG, buf, DV_CHAN_BUF_LEN(WIN, NS)), DV_OK);
    assert_int_equal(dv_chan_buf_len(&CFG), DV_CHAN_BUF_LEN(WIN, NS));
    assert_int_equal(dv_chan_buf_len(&cfg), DV_CHAN_BUF_LEN(WIN, 0));
    assert_int_equal(dv_chan_buf_len(NULL), 0);
    assert_int_equal(dv_chan_init(&b, &cfg, small, DV_CHAN_BUF_LEN(WIN, 0) - 1), DV_ESIZE);
    assert_int_equal(dv_chan_init(&b, &cfg, small, DV_CHAN_BUF_LEN(WIN, 0)), DV_OK);
    int segs = 0;
    for (int i = 0; i < 2 * NMAX; i++) {
        const dv_status_t sa = dv_chan_update(&a, xr[i]);
        assert_int_equal(dv_chan_update(&b, xr[i]), sa);
        if (sa == DV_DONE || sa == DV_RECORD) {
            dv_real_t va, vb;
            uint32_t ia, ib;
            assert_int_equal(dv_segstd_last(&a.seg, &va, &ia), DV_OK);
            assert_int_equal(dv_segstd_last(&b.seg, &vb, &ib), DV_OK);
            assert_true(va == vb && ia == ib);
            if (i < NMAX && ia == 17) {
                assert_true(dv_test_close(vb, dv_test_expected("features_expected.csv", "random", "segstd_17"), DV_TEST_RTOL, 0));
            }
            segs++;
        }
    }
    assert_int_equal(segs, 2 * NS);
    dv_stats_t sa, sb;
    assert_int_equal(dv_chan_get_window(&a, &sa), DV_OK);
    assert_int_equal(dv_chan_get_window(&b, &sb), DV_OK);
    assert_true(sa.rms == sb.rms && sa.peak == sb.peak && sa.kurt == sb.kurt);
    assert_int_equal(dv_chan_get_record(&a, &sa, NULL), DV_OK);
    assert_int_equal(dv_chan_get_record(&b, &sb, NULL), DV_OK);
    assert_true(sa.std == sb.std && sa.max == sb.max);
    dv_real_t v[NS];
    assert_int_equal(dv_segstd_get(&b.seg, v, NS), DV_EINVAL);
}

static void test_chan_bad_config(void **state)
{
    (void)state;
    dv_chan_t c;
    dv_chan_config_t cfg = CFG;
    assert_int_equal(dv_chan_init(NULL, &cfg, buf, DV_CHAN_BUF_LEN(WIN, NS)), DV_EINVAL);
    assert_int_equal(dv_chan_init(&c, NULL, buf, DV_CHAN_BUF_LEN(WIN, NS)), DV_EINVAL);
    assert_int_equal(dv_chan_init(&c, &cfg, buf, DV_CHAN_BUF_LEN(WIN, NS) - 1), DV_ESIZE);
    cfg.dt_s = DV_R(0.0);
    assert_int_equal(dv_chan_init(&c, &cfg, buf, DV_CHAN_BUF_LEN(WIN, NS)), DV_EINVAL);
    cfg = CFG;
    cfg.n_seg = 0;
    assert_int_equal(dv_chan_init(&c, &cfg, buf, DV_CHAN_BUF_LEN(WIN, NS)), DV_EINVAL);
    cfg = CFG;
    assert_int_equal(dv_chan_init(&c, &cfg, buf, DV_CHAN_BUF_LEN(WIN, NS)), DV_OK);
    dv_stats_t st;
    st.mean = 42;
    assert_int_equal(dv_chan_get_record(&c, &st, NULL), DV_ENOTREADY);
    assert_true(st.mean == 42);
    size_t used = 5;
    assert_int_equal(dv_chan_update_block(&c, NULL, 3, &used), DV_EINVAL);
}

// ---- finite in, finite out -------------------------------------------------------------------

#include "dynval/dv_config.h"

static int chan_stats_finite(const dv_stats_t *s)
{
    return isfinite(s->mean) && isfinite(s->std) && isfinite(s->rms) && isfinite(s->skew) &&
           isfinite(s->kurt) && isfinite(s->peak) && isfinite(s->crest) && isfinite(s->kfactor);
}

static void test_chan_full_scale_and_beyond_range(void **state)
{
    (void)state;
    // full-scale noise with +-DV_FEAT_MAX spikes, and samples beyond the range (1e10 float /
    // 1e80 double made NaN kurtosis and Inf RMS before) that both APIs drop and count alike
    enum { W = 64, S = 64, NS = 8, N = 3 * S * NS + 100 };
    static dv_real_t x[N], bufa[DV_CHAN_BUF_LEN(W, NS)], bufb[DV_CHAN_BUF_LEN(W, NS)];
    uint64_t seed = 3;
    size_t bad = 0;
    for (int i = 0; i < N; i++) {
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        x[i] = (dv_real_t)(((double)(seed >> 11) / 9007199254740992.0 - 0.5) * (double)DV_FEAT_MAX);
        if (i % 37 == 0) x[i] = (i & 1) ? DV_FEAT_MAX : -DV_FEAT_MAX;
        if (i % 101 == 50) {
            x[i] = (i & 2) ? (dv_real_t)1e10 * DV_FEAT_MAX : -DV_REAL_MAX;
            bad++;
        }
    }
    const dv_chan_config_t cfg = {W, S, NS, DV_R(1.0) / DV_R(640.0), false};
    dv_chan_t a, b;
    assert_int_equal(dv_chan_init(&a, &cfg, bufa, DV_CHAN_BUF_LEN(W, NS)), DV_OK);
    assert_int_equal(dv_chan_init(&b, &cfg, bufb, DV_CHAN_BUF_LEN(W, NS)), DV_OK);
    int records = 0;
    for (int i = 0; i < N; i++) {
        const dv_status_t st = dv_chan_update(&a, x[i]);
        assert_int_equal(st == DV_ENUMERIC, i % 101 == 50);
        if (st == DV_RECORD) {
            dv_stats_t r, w;
            dv_temporal_out_t t;
            assert_int_equal(dv_chan_get_record(&a, &r, &t), DV_OK);
            assert_int_equal(dv_chan_get_window(&a, &w), DV_OK);
            assert_true(chan_stats_finite(&r) && chan_stats_finite(&w));
            assert_true(isfinite(t.energy) && isfinite(t.central_kurt) &&
                        isfinite(t.root_energy_amp));
            assert_true(r.peak == DV_FEAT_MAX && (r.flags & DV_STATS_NO_SHAPE) == 0u);
            records++;
        }
    }
    assert_int_equal(records, 3);
    assert_int_equal(a.n_nonfinite, bad);
    size_t off = 0, used;
    while (off < N) {
        assert_true(dv_chan_update_block(&b, x + off, N - off, &used) >= DV_OK);
        off += used;
    }
    assert_int_equal(b.n_nonfinite, bad);
    dv_stats_t ra, rb;
    assert_int_equal(dv_chan_get_record(&a, &ra, NULL), DV_OK);
    assert_int_equal(dv_chan_get_record(&b, &rb, NULL), DV_OK);
    assert_true(dv_test_close(ra.kurt, rb.kurt, DV_TEST_RTOL, 0) && ra.peak == rb.peak);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_chan_record_features_match_golden),
        cmocka_unit_test(test_chan_block_agrees_with_per_sample),
        cmocka_unit_test(test_chan_nan_is_dropped_everywhere),
        cmocka_unit_test(test_chan_block_nan_in_whole_blocks),
        cmocka_unit_test(test_chan_without_segment_vectors),
        cmocka_unit_test(test_chan_bad_config),
        cmocka_unit_test(test_chan_full_scale_and_beyond_range),
    };
    return cmocka_run_group_tests_name("dv_chan", tests, NULL, NULL);
}

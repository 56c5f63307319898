/* libFuzzer target for the waveform features with the finiteness oracle: any sample stream
 * (every bit pattern of dv_real_t: NaN, Inf, subnormals, 1e300, values at and around
 * DV_FEAT_MAX) fed to dv_chan (per-sample and block APIs, which must agree on what they
 * drop), dv_moments, dv_sliding, dv_segstd, dv_temporal and dv_corr; every result returned
 * with DV_OK must be finite, and the counts must add up. Input: byte 0 picks the shapes and a
 * scale, then raw dv_real_t values (sizeof(dv_real_t) bytes each, native order), each scaled
 * by a power of two chosen per sample from the byte before it, so both huge and tiny values
 * are reached often. Built for float and double by tests/fuzz/run_fuzz.sh. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "dynval/dv.h"

#define CHECK(c)                                                                                  \
    do {                                                                                          \
        if (!(c)) {                                                                               \
            __builtin_trap();                                                                     \
        }                                                                                         \
    } while (0)

#define MAXN 4096
#define WIN 16
#define SEG 8
#define NSEG 4

static int fin(dv_real_t x)
{
    return (x - x) == (dv_real_t)0; /* no isfinite(): -ffast-math proof and no promotion */
}

static void check_stats(dv_status_t st, const dv_stats_t *s)
{
    if (st != DV_OK) {
        CHECK(st == DV_ENOTREADY || st == DV_ERANGE);
        return;
    }
    CHECK(fin(s->mean) && fin(s->var) && fin(s->std) && fin(s->rms) && fin(s->skew) &&
          fin(s->kurt) && fin(s->peak) && fin(s->min) && fin(s->max) && fin(s->crest) &&
          fin(s->kfactor));
    CHECK(s->var >= (dv_real_t)0 && s->min <= s->max);
}

static void check_tm(dv_status_t st, const dv_temporal_out_t *t)
{
    if (st != DV_OK) {
        CHECK(st == DV_ENOTREADY || st == DV_ENUMERIC || st == DV_ERANGE);
        return;
    }
    CHECK(fin(t->energy) && fin(t->central_time) && fin(t->rms_duration) &&
          fin(t->central_skew) && fin(t->central_kurt) && fin(t->root_energy_amp));
}

static dv_real_t xs[MAXN];
static dv_real_t chan_buf_a[DV_CHAN_BUF_LEN(WIN, NSEG)], chan_buf_b[DV_CHAN_BUF_LEN(WIN, NSEG)];
static dv_real_t slide_buf[DV_SLIDING_BUF_LEN(WIN)], seg_buf[DV_SEGSTD_BUF_LEN(NSEG)];

int LLVMFuzzerTestOneInput(const uint8_t *in, size_t n)
{
    if (n < 1u) {
        return 0;
    }
    const size_t w = sizeof(dv_real_t);
    size_t cnt = 0;
    for (size_t off = 1; off + w + 1u <= n && cnt < MAXN; off += w + 1u) {
        dv_real_t v;
        memcpy(&v, in + off + 1u, w);
        /* 2^(k - 64), k = 0..127: the values themselves are often modest bit patterns */
        const int k = in[off] & 0x7F;
        dv_real_t sc = (dv_real_t)1;
        for (int j = 0; j < (k < 64 ? 64 - k : k - 64); j++) {
            sc *= k < 64 ? (dv_real_t)0.5 : (dv_real_t)2;
        }
        xs[cnt++] = (in[off] & 0x80u) != 0u ? v : v * sc;
    }
    const dv_chan_config_t cfg = {WIN, SEG, NSEG, (dv_real_t)1 / (dv_real_t)640, (in[0] & 1u) != 0};
    dv_chan_t a, b;
    CHECK(dv_chan_init(&a, &cfg, chan_buf_a, DV_CHAN_BUF_LEN(WIN, NSEG)) == DV_OK);
    CHECK(dv_chan_init(&b, &cfg, chan_buf_b, DV_CHAN_BUF_LEN(WIN, NSEG)) == DV_OK);
    dv_moments_t mo, mob;
    dv_sliding_t sl;
    dv_segstd_t sg;
    dv_temporal_t tm;
    dv_corr_t co;
    CHECK(dv_moments_init(&mo) == DV_OK && dv_moments_init(&mob) == DV_OK);
    CHECK(dv_sliding_init(&sl, WIN, slide_buf, DV_SLIDING_BUF_LEN(WIN)) == DV_OK);
    CHECK(dv_segstd_init(&sg, SEG, NSEG, seg_buf, DV_SEGSTD_BUF_LEN(NSEG)) == DV_OK);
    CHECK(dv_temporal_init(&tm, (dv_real_t)1 / (dv_real_t)640) == DV_OK);
    CHECK(dv_corr_init(&co) == DV_OK);
    dv_stats_t s;
    dv_temporal_out_t t;
    uint64_t accepted = 0;
    for (size_t i = 0; i < cnt; i++) {
        const dv_status_t st = dv_chan_update(&a, xs[i]);
        accepted += st != DV_ENUMERIC;
        if (st == DV_DONE || st == DV_RECORD) {
            dv_real_t sd;
            uint32_t idx;
            CHECK(dv_segstd_last(&a.seg, &sd, &idx) == DV_OK && fin(sd) && sd >= (dv_real_t)0);
            check_stats(dv_chan_get_window(&a, &s), &s);
        }
        if (st == DV_RECORD) {
            const dv_status_t rs = dv_chan_get_record(&a, &s, &t);
            CHECK(rs == DV_OK || rs == DV_ENUMERIC || rs == DV_ERANGE);
            if (rs != DV_ERANGE) {
                check_stats(DV_OK, &s);
            }
            check_tm(rs, &t);
        }
        (void)dv_moments_update(&mo, xs[i]);
        (void)dv_sliding_update(&sl, xs[i]);
        const dv_status_t gs = dv_segstd_update(&sg, xs[i]);
        if (gs == DV_DONE || gs == DV_RECORD) {
            dv_real_t sd;
            uint32_t idx;
            CHECK(dv_segstd_last(&sg, &sd, &idx) == DV_OK && fin(sd));
        }
        (void)dv_temporal_update(&tm, xs[i]);
        (void)dv_corr_update(&co, xs[i], i > 0 ? xs[i - 1] : (dv_real_t)0);
        if ((in[0] & 2u) != 0u && (i & 31u) == 31u) {
            check_stats(dv_moments_get(&mo, &s), &s);
            check_stats(dv_sliding_get(&sl, &s), &s);
            check_tm(dv_temporal_get(&tm, &t), &t);
        }
    }
    /* the block APIs drop the same samples */
    size_t off = 0;
    while (off < cnt) {
        size_t used = 0;
        const dv_status_t st = dv_chan_update_block(&b, xs + off, cnt - off, &used);
        CHECK(st == DV_OK || st == DV_RECORD);
        CHECK(used > 0u && used <= cnt - off);
        off += used;
    }
    CHECK(a.n_nonfinite == b.n_nonfinite && a.n_nonfinite + accepted == cnt);
    CHECK(a.records == b.records);
    (void)dv_moments_update_block(&mob, xs, cnt);
    CHECK(mob.n_nonfinite == mo.n_nonfinite && mob.count == mo.count);
    CHECK(mo.n_nonfinite == a.n_nonfinite && sl.n_nonfinite == a.n_nonfinite &&
          sg.n_nonfinite == a.n_nonfinite && tm.n_nonfinite == a.n_nonfinite);
    check_stats(dv_moments_get(&mo, &s), &s);
    check_stats(dv_moments_get(&mob, &s), &s);
    check_stats(dv_sliding_get(&sl, &s), &s);
    check_stats(dv_chan_get_window(&b, &s), &s);
    check_tm(dv_temporal_get(&tm, &t), &t);
    dv_real_t r;
    const dv_status_t cs = dv_corr_get(&co, &r);
    CHECK(cs != DV_OK || (fin(r) && r >= (dv_real_t)-1 && r <= (dv_real_t)1));
    return 0;
}

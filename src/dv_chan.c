/* The per-channel feature bundle. Per sample: one NaN check and the sliding window's inlined
 * kernel, which keeps the sample in its ring. Every block (<= DV_BLOCK_LEN samples, never more
 * than the ring holds) the other features take the block from the ring in tight loops: power
 * sums about the segment's first sample feed the record moments and the segmented STD, and
 * the temporal moments run their block kernel. Same results, far fewer loads and stores. */
#include "dynval/dv_chan.h"
#include "dynval/dv_config.h"
#include "dv_feat_core.h"
#include "dv_priv.h"

/* The block close stays out of line so the per-sample path is a leaf with a tail call. */
#if defined(__GNUC__) || defined(__clang__)
#define DV_COLD __attribute__((noinline))
#else
#define DV_COLD
#endif

size_t dv_chan_buf_len(const dv_chan_config_t *cfg)
{
    if (cfg == NULL || dv_sliding_buf_len(cfg->win_len) == 0u) {
        return 0u;
    }
    return DV_CHAN_BUF_LEN(cfg->win_len, cfg->no_seg_vectors ? 0u : cfg->n_seg);
}

dv_status_t dv_chan_init(dv_chan_t *s, const dv_chan_config_t *cfg, dv_real_t *buf,
                         size_t buf_len)
{
    if (s == NULL || cfg == NULL || buf == NULL) {
        return DV_EINVAL;
    }
    /* dt_s is checked by dv_temporal_init() */
    if (cfg->win_len < 2u || cfg->win_len > DV_SLIDING_MAX_LEN || cfg->seg_len < 2u ||
        cfg->n_seg == 0u) {
        return DV_EINVAL;
    }
    if (buf_len < dv_chan_buf_len(cfg)) {
        return DV_ESIZE;
    }
    const size_t wl = DV_SLIDING_BUF_LEN(cfg->win_len);
    dv_status_t st = dv_sliding_init(&s->win, cfg->win_len, buf, wl);
    if (st == DV_OK) {
        st = cfg->no_seg_vectors
                 ? dv_segstd_init(&s->seg, cfg->seg_len, cfg->n_seg, NULL, 0u)
                 : dv_segstd_init(&s->seg, cfg->seg_len, cfg->n_seg, buf + wl, buf_len - wl);
    }
    if (st == DV_OK) {
        st = dv_temporal_init(&s->tm, cfg->dt_s);
    }
    if (st == DV_OK) {
        st = dv_moments_init(&s->rec);
    }
    if (st != DV_OK) {
        return st;
    }
    s->cfg = *cfg;
    s->blk_max = cfg->win_len < DV_BLOCK_LEN ? cfg->win_len : DV_BLOCK_LEN;
    dv_chan_reset(s);
    return DV_OK;
}

/* Length of the next block when seg_pos samples of the segment are in. */
static uint32_t block_len(const dv_chan_t *s, uint32_t seg_pos)
{
    const uint32_t seg_left = s->cfg.seg_len - seg_pos;
    return s->blk_max < seg_left ? s->blk_max : seg_left;
}

/* Samples in the open block. */
static uint32_t open_len(const dv_chan_t *s)
{
    return block_len(s, s->seg_pos) - s->left;
}

/* Power sums p[k] = sum (x - shift)^(k+1) and extremes {min, max} of the block being closed. */
typedef struct {
    dv_real_t p[4];
    dv_real_t mm[2];
} blk_acc_t;

static void acc_clear(blk_acc_t *a)
{
    a->p[0] = a->p[1] = a->p[2] = a->p[3] = DV_R(0.0);
    a->mm[0] = DV_REAL_MAX;
    a->mm[1] = -DV_REAL_MAX;
}

void dv_chan_reset(dv_chan_t *s)
{
    DV_ASSERT(s != NULL);
    dv_moments_reset(&s->rec);
    dv_sliding_reset(&s->win);
    dv_segstd_reset(&s->seg);
    dv_temporal_reset(&s->tm);
    s->records = 0u;
    s->n_nonfinite = 0u;
    s->last_tm_st = DV_ENOTREADY;
    s->shift = s->seg1 = s->seg2 = DV_R(0.0);
    s->seg_pos = 0u;
    s->left = block_len(s, 0u);
}

static void close_record(dv_chan_t *s)
{
    /* never empty here; DV_ERANGE only for a record too long for the type */
    s->last_st = dv_moments_get(&s->rec, &s->last_stats);
    s->last_tm_st = dv_temporal_get(&s->tm, &s->last_tm);
    dv_moments_reset(&s->rec);
    dv_temporal_reset(&s->tm);
    s->records++;
}

/* Hand the n-sample block to the record moments; at a segment end also to the segmented STD. */
static dv_status_t close_block(dv_chan_t *s, uint32_t n, const blk_acc_t *a)
{
    dv_priv_moments_push_block(&s->rec, s->shift, n, a->p, a->mm[0], a->mm[1]);
    s->seg1 += a->p[0];
    s->seg2 += a->p[1];
    s->seg_pos += n;
    if (s->seg_pos < s->cfg.seg_len) {
        s->left = block_len(s, s->seg_pos);
        return DV_OK;
    }
    const dv_status_t st = dv_priv_segstd_push(&s->seg, s->seg1, s->seg2);
    s->seg1 = s->seg2 = DV_R(0.0);
    s->seg_pos = 0u;
    s->left = block_len(s, 0u);
    if (st == DV_RECORD) {
        close_record(s);
    }
    return st;
}

/* Power sums, extremes and temporal moments of n consecutive finite samples of the block. The
 * common case, a whole block that is also a whole block of the temporal moments, is one fused
 * kernel pass (src/dv_featkern.c); other spans (a short segment end, a block that wraps around
 * the ring) are rare and take the plain loops. */
static void add_span(dv_chan_t *s, uint32_t kern, blk_acc_t *acc, const dv_real_t *restrict x,
                     size_t n, bool starts_segment)
{
    if (starts_segment) {
        s->shift = x[0]; /* power sums about the segment's first sample */
    }
    const dv_real_t k = s->shift;
    if (n == DV_BLOCK_LEN && s->tm.blk == 0u) {
        dv_real_t w[5];
        dv_priv_feat_block(kern, x, k, acc->p, acc->mm, w); /* acc is clear here */
        dv_priv_temporal_push_block(&s->tm, w);
        return;
    }
    /* what dv_temporal_update_block() does for a span that is not one whole temporal block,
     * without linking its block path into a firmware that needs only this */
    for (size_t i = 0u; i < n; i++) {
        dv_priv_temporal_push(&s->tm, x[i]);
    }
    dv_real_t p1 = DV_R(0.0), p2 = DV_R(0.0), p3 = DV_R(0.0), p4 = DV_R(0.0);
    dv_real_t mn = acc->mm[0], mx = acc->mm[1];
    for (size_t i = 0u; i < n; i++) {
        const dv_real_t u = x[i] - k, u2 = u * u;
        p1 += u;
        p2 += u2;
        p3 += u2 * u;
        p4 += u2 * u2;
        mn = x[i] < mn ? x[i] : mn;
        mx = x[i] > mx ? x[i] : mx;
    }
    acc->p[0] += p1;
    acc->p[1] += p2;
    acc->p[2] += p3;
    acc->p[3] += p4;
    acc->mm[0] = mn;
    acc->mm[1] = mx;
}

/* A whole block of m samples straight from the caller's array, when they are all finite:
 * the fused kernel runs first and its energy sum tells (NaN/Inf make it non-finite), so a
 * bad block changes no state and returns false. */
static bool caller_block(dv_chan_t *s, uint32_t kern, blk_acc_t *acc, const dv_real_t *x,
                         uint32_t m)
{
    acc_clear(acc);
    if (m == DV_BLOCK_LEN && s->tm.blk == 0u) {
        const dv_real_t k = s->seg_pos == 0u ? x[0] : s->shift;
        dv_real_t w[5];
        dv_priv_feat_block(kern, x, k, acc->p, acc->mm, w);
        /* NaN/Inf fail the test, and so does a sample beyond DV_FEAT_MAX (x^2 <= sum x^2); a
         * block of in-range samples that fails it (rms > DV_FEAT_MAX / 8) takes the per-sample
         * path, which ends in this same kernel: same result */
        if (!(w[0] <= DV_FEAT_MAX * DV_FEAT_MAX)) {
            return false;
        }
        s->shift = k;
        dv_priv_temporal_push_block(&s->tm, w);
        return true;
    }
    if (!dv_priv_all_in_range(x, m)) {
        return false;
    }
    add_span(s, kern, acc, x, m, s->seg_pos == 0u);
    return true;
}

/* The open block's samples sit in the sliding ring, ending just before its head. */
DV_COLD static dv_status_t close_ring_block(dv_chan_t *s)
{
    const uint32_t len = s->win.len, n = block_len(s, s->seg_pos);
    const uint32_t end = s->win.head == 0u ? len : s->win.head;
    const bool starts = s->seg_pos == 0u;
    blk_acc_t acc;
    acc_clear(&acc);
    const uint32_t kern = s->win.kern; /* chosen at init (dv_sliding_init()) */
    if (end >= n) {
        add_span(s, kern, &acc, s->win.ring + (end - n), n, starts);
    } else { /* the block wraps around the ring's end */
        add_span(s, kern, &acc, s->win.ring + (len - (n - end)), n - end, starts);
        add_span(s, kern, &acc, s->win.ring, end, false);
    }
    return close_block(s, n, &acc);
}

dv_status_t dv_chan_update(dv_chan_t *s, dv_real_t x)
{
    DV_ASSERT(s != NULL);
    if (!dv_priv_in_range(x)) {
        s->n_nonfinite++;
        return DV_ENUMERIC;
    }
    dv_priv_sliding_push(&s->win, x);
    if (--s->left != 0u) {
        return DV_OK;
    }
    return close_ring_block(s); /* a tail call: the hot path saves no registers */
}

dv_status_t dv_chan_update_block(dv_chan_t *s, const dv_real_t *x, size_t n, size_t *n_used)
{
    DV_ASSERT(s != NULL);
    if (n_used == NULL || (x == NULL && n > 0u)) {
        return DV_EINVAL;
    }
    size_t used = 0u;
    const uint32_t kern = s->win.kern; /* chosen at init (dv_sliding_init()) */
    while (used < n) {
        /* Whole blocks from here to the record's end (or the input's end) go straight from the
         * caller's array, up to the first block with a NaN/Inf; an open block, a short tail or
         * a block with NaN/Inf goes through the per-sample path, which keeps its pending
         * samples in the ring. */
        size_t whole = 0u;
        if (open_len(s) == 0u) {
            const size_t rec_left = (size_t)(s->cfg.n_seg - s->seg.seg) * s->cfg.seg_len -
                                    s->seg_pos;
            const size_t stretch = n - used < rec_left ? n - used : rec_left;
            uint32_t sp = s->seg_pos;
            for (;;) {
                const uint32_t m = block_len(s, sp);
                if (whole + m > stretch) {
                    break;
                }
                whole += m;
                sp = sp + m == s->cfg.seg_len ? 0u : sp + m;
            }
        }
        const dv_real_t *p = x + used;
        size_t done = 0u;
        dv_status_t st = DV_OK;
        while (done < whole) {
            const uint32_t m = block_len(s, s->seg_pos);
            blk_acc_t acc;
            if (!caller_block(s, kern, &acc, p + done, m)) {
                break;
            }
            st = close_block(s, m, &acc);
            done += m;
        }
        if (done == 0u) {
            st = dv_chan_update(s, x[used]);
            used++;
            if (st == DV_RECORD) {
                *n_used = used;
                return DV_RECORD;
            }
            continue;
        }
        dv_priv_sliding_push_finite(&s->win, p, done);
        used += done;
        if (st == DV_RECORD) { /* only at the stretch's end: it stops at the record's end */
            *n_used = used;
            return DV_RECORD;
        }
    }
    *n_used = used;
    return DV_OK;
}

dv_status_t dv_chan_get_record(const dv_chan_t *s, dv_stats_t *st, dv_temporal_out_t *tm)
{
    if (s == NULL || st == NULL) {
        return DV_EINVAL;
    }
    if (s->records == 0u) {
        return DV_ENOTREADY;
    }
    if (s->last_st != DV_OK) {
        return s->last_st;
    }
    *st = s->last_stats;
    if (tm == NULL) {
        return DV_OK;
    }
    if (s->last_tm_st != DV_OK) {
        return s->last_tm_st;
    }
    *tm = s->last_tm;
    return DV_OK;
}

dv_status_t dv_chan_get_window(const dv_chan_t *s, dv_stats_t *out)
{
    if (s == NULL) {
        return DV_EINVAL;
    }
    return dv_sliding_get(&s->win, out);
}

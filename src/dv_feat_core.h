/* Per-sample kernels shared by a feature module and the channel bundle (dv_chan.c), inlined
 * so that the bundle pays one NaN check and no calls per sample. Callers pass finite x. */
#ifndef DV_FEAT_CORE_H
#define DV_FEAT_CORE_H

#include "dynval/dv_config.h"
#include "dynval/dv_moments.h"
#include "dynval/dv_segstd.h"
#include "dynval/dv_sliding.h"
#include "dynval/dv_temporal.h"

/* The ring has turned over: recompute its sums. src is the ring itself, or the window's
 * len samples to copy into the ring (one pass: the copy rides on the turn-over's loads). */
void dv_priv_sliding_turn_over(dv_sliding_t *s, const dv_real_t *src);

/* ---- block kernels (src/dv_featkern.c): portable C, and on x86-64 double builds AVX2/FMA and
 * AVX-512F versions picked at run time. ---- */

/* One block of DV_BLOCK_LEN samples: p[k] = sum (x - k0)^(k+1), mm = {min, max} folded
 * into the given {min, max}, w[k] = sum x^2 tau^k with tau = 0, 1, ... kern is
 * dv_priv_simd_kern(), asked once at init (dv_sliding_t.kern). A NaN/Inf sample makes w[0] non-finite (so
 * does a finite |x| > ~1e154: callers treat both as "take the per-sample path"). */
void dv_priv_feat_block(uint32_t kern, const dv_real_t *x, dv_real_t k0, dv_real_t p[4],
                        dv_real_t mm[2], dv_real_t w[5]);

/* ring[0..n) = src[0..n) (src may be ring), s[k] = sum (ring - k0)^(k+1), bmax[b] / bmin[b] =
 * extremes of ring[b DV_SLIDING_BLK .. (b + 1) DV_SLIDING_BLK) (the last block may be short).
 * kern as for dv_priv_feat_block(). */
void dv_priv_feat_turn(uint32_t kern, const dv_real_t *src, dv_real_t *ring, uint32_t n, dv_real_t k0,
                       dv_real_t *bmax, dv_real_t *bmin, dv_real_t s[4]);

/* dv_sliding_update_block() for samples known to be finite (the caller checked). */
void dv_priv_sliding_push_finite(dv_sliding_t *s, const dv_real_t *x, size_t n);
void dv_priv_temporal_flush(dv_temporal_t *s);

/* A whole block of DV_BLOCK_LEN samples given as its sums w[k] = sum x^2 tau^k (tau = 0..),
 * added to the record; the open block must be empty (s->blk == 0). */
void dv_priv_temporal_push_block(dv_temporal_t *s, const dv_real_t w[5]);

/* Merge a complete block of n samples, given as power sums p[k] = sum (x - shift)^(k+1) and
 * its extremes, into the record totals. The moments' own open block must be empty. */
void dv_priv_moments_push_block(dv_moments_t *m, dv_real_t shift, uint32_t n, const dv_real_t p[4],
                                dv_real_t min, dv_real_t max);

/* Store the STD of a complete segment from s1 = sum (x - shift), s2 = sum (x - shift)^2.
 * Returns DV_DONE, or DV_RECORD when it was the record's last segment. */
dv_status_t dv_priv_segstd_push(dv_segstd_t *s, dv_real_t s1, dv_real_t s2);

/* One sample in, the oldest out. No warm-up branch: while the window fills, the slot left is
 * one the reset cleared and the sums are throw-away (dv_sliding_get() reports DV_ENOTREADY);
 * the first turn-over recomputes them from the full ring. */
static inline void dv_priv_sliding_push(dv_sliding_t *s, dv_real_t x)
{
    const uint32_t h = s->head;
    dv_real_t *slot = s->ring + h;
    const dv_real_t k = s->shift;
    const dv_real_t d = x - k, e = *slot - k;
    const dv_real_t d2 = d * d, e2 = e * e;
    s->s[0] += d - e;
    s->s[1] += d2 - e2;
    s->s[2] += d2 * d - e2 * e;
    s->s[3] += d2 * d2 - e2 * e2;
    s->premax = x > s->premax ? x : s->premax;
    s->premin = x < s->premin ? x : s->premin;
    *slot = x;
    s->head = h + 1u;
    if (h + 1u == s->len) {
        dv_priv_sliding_turn_over(s, s->ring);
    }
}

static inline void dv_priv_temporal_push(dv_temporal_t *s, dv_real_t x)
{
    const dv_real_t w = x * x;
    const dv_real_t t = s->tau;
    const dv_real_t w1 = w * t, w2 = w1 * t;
    s->s0 += w;
    s->s1 += w1;
    s->s2 += w2;
    s->s3 += w2 * t;
    s->s4 += w2 * (t * t);
    s->count++;
    s->tau += DV_R(1.0);
    if (++s->blk == DV_BLOCK_LEN) {
        dv_priv_temporal_flush(s);
    }
}

#endif /* DV_FEAT_CORE_H */

/* Cumulative basic statistics: shifted power sums per block, merged exactly per block. */
#include "dynval/dv_moments.h"
#include "dynval/dv_config.h"
#include "dv_feat_core.h"
#include "dv_priv.h"

dv_status_t dv_moments_init(dv_moments_t *s)
{
    if (s == NULL) {
        return DV_EINVAL;
    }
    dv_moments_reset(s);
    return DV_OK;
}

void dv_moments_reset(dv_moments_t *s)
{
    DV_ASSERT(s != NULL);
    s->n = s->mean = s->m2 = s->m3 = s->m4 = DV_R(0.0);
    s->shift = s->s1 = s->s2 = s->s3 = s->s4 = DV_R(0.0);
    s->min = DV_REAL_MAX;
    s->max = -DV_REAL_MAX;
    s->blk = 0u;
    s->count = 0u;
    s->n_nonfinite = 0u;
}

static void merge_sums(dv_moments_t *s, dv_real_t shift, dv_real_t n, const dv_real_t p[4])
{
    dv_priv_cm_t a = {s->n, s->mean, s->m2, s->m3, s->m4};
    dv_priv_cm_t b;
    dv_priv_cm_from_sums(&b, shift, n, p[0], p[1], p[2], p[3]);
    dv_priv_cm_merge(&a, &b);
    s->n = a.n;
    s->mean = a.mean;
    s->m2 = a.m2;
    s->m3 = a.m3;
    s->m4 = a.m4;
}

void dv_priv_moments_push_block(dv_moments_t *m, dv_real_t shift, uint32_t n, const dv_real_t p[4],
                                dv_real_t min, dv_real_t max)
{
    merge_sums(m, shift, (dv_real_t)n, p);
    m->min = min < m->min ? min : m->min;
    m->max = max > m->max ? max : m->max;
    m->count += n;
    m->shift = m->mean;
}

static void open_block_moments(const dv_moments_t *s, dv_priv_cm_t *b)
{
    dv_priv_cm_from_sums(b, s->shift, (dv_real_t)s->blk, s->s1, s->s2, s->s3, s->s4);
}

/* Merge the open block into the totals and re-centre the next block on the new mean. */
static void flush_block(dv_moments_t *s)
{
    const dv_real_t p[4] = {s->s1, s->s2, s->s3, s->s4};
    merge_sums(s, s->shift, (dv_real_t)s->blk, p);
    s->shift = s->mean;
    s->s1 = s->s2 = s->s3 = s->s4 = DV_R(0.0);
    s->blk = 0u;
}

dv_status_t dv_moments_update(dv_moments_t *s, dv_real_t x)
{
    DV_ASSERT(s != NULL);
    if (!dv_priv_in_range(x)) {
        s->n_nonfinite++;
        return DV_ENUMERIC;
    }
    if (s->count == 0u) {
        s->shift = x; /* first block: centre on the first sample */
    }
    const dv_real_t d = x - s->shift;
    const dv_real_t d2 = d * d;
    s->s1 += d;
    s->s2 += d2;
    s->s3 += d2 * d;
    s->s4 += d2 * d2;
    s->min = x < s->min ? x : s->min;
    s->max = x > s->max ? x : s->max;
    s->count++;
    if (++s->blk == DV_BLOCK_LEN) {
        flush_block(s);
    }
    return DV_OK;
}

dv_status_t dv_moments_update_block(dv_moments_t *s, const dv_real_t *x, size_t n)
{
    DV_ASSERT(s != NULL);
    if (x == NULL) {
        return n == 0u ? DV_OK : DV_EINVAL;
    }
    dv_status_t st = DV_OK;
    size_t i = 0u;
    while (i < n) {
        /* Finish the open block sample by sample, then take whole blocks in one sweep. */
        if (s->blk != 0u || s->count == 0u || n - i < DV_BLOCK_LEN) {
            if (dv_moments_update(s, x[i]) != DV_OK) {
                st = DV_ENUMERIC;
            }
            i++;
            continue;
        }
        const dv_real_t *p = x + i;
        const dv_real_t k = s->shift;
        /* Two interleaved accumulator sets: halves the add latency chain. */
        dv_real_t a1 = DV_R(0.0), a2 = DV_R(0.0), a3 = DV_R(0.0), a4 = DV_R(0.0);
        dv_real_t b1 = DV_R(0.0), b2 = DV_R(0.0), b3 = DV_R(0.0), b4 = DV_R(0.0);
        dv_real_t mn = s->min, mx = s->max;
        bool finite = true;
        for (size_t j = 0u; j < DV_BLOCK_LEN; j += 2u) {
            const dv_real_t u = p[j] - k, v = p[j + 1u] - k;
            const dv_real_t u2 = u * u, v2 = v * v;
            a1 += u;
            b1 += v;
            a2 += u2;
            b2 += v2;
            a3 += u2 * u;
            b3 += v2 * v;
            a4 += u2 * u2;
            b4 += v2 * v2;
            mn = p[j] < mn ? p[j] : mn;
            mx = p[j] > mx ? p[j] : mx;
            mn = p[j + 1u] < mn ? p[j + 1u] : mn;
            mx = p[j + 1u] > mx ? p[j + 1u] : mx;
        }
        /* A NaN/Inf anywhere poisons the fourth-power sum, a sample beyond DV_FEAT_MAX shows in
         * the extremes (the running ones are in range): then redo this block per sample. */
        finite = dv_priv_finite(a4 + b4) && dv_priv_finite(a1 + b1) && mn >= -DV_FEAT_MAX &&
                 mx <= DV_FEAT_MAX;
        if (!finite) {
            for (size_t j = 0u; j < DV_BLOCK_LEN; j++) {
                if (dv_moments_update(s, p[j]) != DV_OK) {
                    st = DV_ENUMERIC;
                }
            }
        } else {
            s->s1 = a1 + b1;
            s->s2 = a2 + b2;
            s->s3 = a3 + b3;
            s->s4 = a4 + b4;
            s->min = mn;
            s->max = mx;
            s->count += DV_BLOCK_LEN;
            s->blk = DV_BLOCK_LEN;
            flush_block(s);
        }
        i += DV_BLOCK_LEN;
    }
    return st;
}

void dv_priv_stats_fill(dv_stats_t *out, const dv_priv_cm_t *cm, uint64_t count, dv_real_t min,
                        dv_real_t max)
{
    const dv_real_t var = cm->m2 / cm->n;
    out->count = count;
    out->mean = cm->mean;
    out->var = var;
    out->std = DV_SQRT(var);
    out->rms = DV_SQRT(cm->mean * cm->mean + var);
    out->min = min;
    out->max = max;
    out->peak = DV_FABS(min) > DV_FABS(max) ? DV_FABS(min) : DV_FABS(max);
    out->flags = 0u;
    /* Relative to the scale of the data, a variance at round-off level is a constant signal;
     * and below DV_PRIV_VAR_MIN var * var and var * std would underflow (the fourth-power
     * sums already have): no shape either, rather than 0/0. */
    const dv_real_t scale2 = out->peak * out->peak;
    bool shape = var > DV_PRIV_VAR_MIN && var > scale2 * DV_REAL_EPS * DV_REAL_EPS;
    if (shape) {
        out->skew = (cm->m3 / cm->n) / (var * out->std);
        out->kurt = (cm->m4 / cm->n) / (var * var);
        /* n values have kurt < n and skew^2 < n: beyond (or NaN) the sums are round-off, e.g.
         * a sliding window's shortly after a sample far larger than the window's */
        shape = out->kurt <= cm->n && out->skew * out->skew <= cm->n;
    }
    if (!shape) {
        out->skew = DV_R(0.0);
        out->kurt = DV_R(0.0);
        out->flags |= DV_STATS_NO_SHAPE;
    }
    if (dv_crest_factor(out->peak, out->rms, &out->crest) != DV_OK) {
        out->crest = DV_R(0.0);
        out->flags |= DV_STATS_NO_CREST;
    }
    out->kfactor = out->peak * out->rms;
}

dv_status_t dv_moments_get(const dv_moments_t *s, dv_stats_t *out)
{
    if (s == NULL || out == NULL) {
        return DV_EINVAL;
    }
    if (s->count == 0u) {
        return DV_ENOTREADY;
    }
    dv_priv_cm_t a = {s->n, s->mean, s->m2, s->m3, s->m4};
    if (s->blk > 0u) {
        dv_priv_cm_t b;
        open_block_moments(s, &b);
        dv_priv_cm_merge(&a, &b);
    }
    if (!(a.m4 <= DV_REAL_MAX)) {
        return DV_ERANGE; /* the central sums of a very long record overflowed (Inf or NaN) */
    }
    dv_priv_stats_fill(out, &a, s->count, s->min, s->max);
    return DV_OK;
}

uint64_t dv_moments_nonfinite(const dv_moments_t *s)
{
    return s == NULL ? 0u : s->n_nonfinite;
}

dv_status_t dv_crest_factor(dv_real_t peak, dv_real_t rms, dv_real_t *out)
{
    if (out == NULL) {
        return DV_EINVAL;
    }
    if (!dv_priv_finite(peak) || !dv_priv_finite(rms) || !(rms > DV_R(0.0))) {
        return DV_ENUMERIC;
    }
    const dv_real_t c = peak / rms;
    if (!dv_priv_finite(c)) {
        return DV_ENUMERIC; /* rms subnormal */
    }
    *out = c;
    return DV_OK;
}

dv_status_t dv_k_factor(dv_real_t peak, dv_real_t rms, dv_real_t *out)
{
    if (out == NULL) {
        return DV_EINVAL;
    }
    const dv_real_t k = peak * rms;
    if (!dv_priv_finite(peak) || !dv_priv_finite(rms) || !dv_priv_finite(k)) {
        return DV_ENUMERIC;
    }
    *out = k;
    return DV_OK;
}

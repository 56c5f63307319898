/* Sliding-window statistics: add/subtract power sums, refreshed exactly once per window;
 * extremes from the current turn's running (prefix) extremes and the previous turn's suffix
 * extremes, kept per block of DV_SLIDING_BLK samples (the rest of the block the window starts
 * in is scanned when the extremes are read): O(1) per sample, 2 / DV_SLIDING_BLK extra
 * elements per window sample. */
#include "dynval/dv_sliding.h"
#include "dynval/dv_config.h"
#include "dv_feat_core.h"
#include "dv_priv.h"

size_t dv_sliding_buf_len(size_t len)
{
    return len < 2u || len > DV_SLIDING_MAX_LEN ? 0u : DV_SLIDING_BUF_LEN(len);
}

dv_status_t dv_sliding_init(dv_sliding_t *s, size_t len, dv_real_t *buf, size_t buf_len)
{
    if (s == NULL || buf == NULL || len < 2u || len > DV_SLIDING_MAX_LEN) {
        return DV_EINVAL;
    }
    if (buf_len < DV_SLIDING_BUF_LEN(len)) {
        return DV_ESIZE;
    }
    const size_t nb = (len + DV_SLIDING_BLK - 1u) / DV_SLIDING_BLK;
    s->ring = buf;
    s->sufmax = buf + len;
    s->sufmin = buf + len + nb;
    s->len = (uint32_t)len;
    s->kern = dv_priv_simd_kern(); /* asked once here, not per turn-over */
    dv_sliding_reset(s);
    return DV_OK;
}

void dv_sliding_reset(dv_sliding_t *s)
{
    DV_ASSERT(s != NULL);
    s->head = s->fill = 0u;
    for (uint32_t i = 0u; i < s->len; i++) {
        s->ring[i] = DV_R(0.0); /* finite slots for the per-sample path's first turn */
    }
    s->premax = -DV_REAL_MAX;
    s->premin = DV_REAL_MAX;
    s->shift = DV_R(0.0);
    for (int k = 0; k < 4; k++) {
        s->s[k] = DV_R(0.0);
    }
    s->n_nonfinite = 0u;
}

/* Block extremes (from the turn-over kernel) to suffix extremes over the blocks, in place. */
static void block_suffix_extremes(dv_sliding_t *s)
{
    uint32_t b = (s->len + DV_SLIDING_BLK - 1u) / DV_SLIDING_BLK - 1u;
    while (b-- > 0u) {
        s->sufmax[b] = s->sufmax[b + 1u] > s->sufmax[b] ? s->sufmax[b + 1u] : s->sufmax[b];
        s->sufmin[b] = s->sufmin[b + 1u] < s->sufmin[b] ? s->sufmin[b + 1u] : s->sufmin[b];
    }
}

/* The ring has turned over and holds exactly the window. Recompute its power sums from scratch
 * (no add/subtract round-off survives a turn) and the block suffix extremes for the next turn,
 * then re-centre the sums on the window mean (exact algebra; the old shift is within a few STDs
 * of it, so this is well conditioned) so a drifting signal keeps small deviations. */
void dv_priv_sliding_turn_over(dv_sliding_t *s, const dv_real_t *src)
{
    const uint32_t n = s->len;
    /* the first turn's sums were about an arbitrary shift: centre on a sample of the window */
    const dv_real_t k = s->fill == n ? s->shift : src[0];
    s->fill = n;
    dv_priv_feat_turn(s->kern, src, s->ring, n, k, s->sufmax, s->sufmin, s->s);
    block_suffix_extremes(s);
    const dv_real_t delta = s->s[0] / (dv_real_t)n; /* window mean - shift */
    dv_priv_sums_shift(s->s, (dv_real_t)n, -delta);
    s->shift = k + delta;
    s->premax = -DV_REAL_MAX;
    s->premin = DV_REAL_MAX;
    s->head = 0u;
}

dv_status_t dv_sliding_update(dv_sliding_t *s, dv_real_t x)
{
    DV_ASSERT(s != NULL);
    if (!dv_priv_in_range(x)) {
        s->n_nonfinite++;
        return DV_ENUMERIC;
    }
    dv_priv_sliding_push(s, x);
    return DV_OK;
}

dv_status_t dv_sliding_update_block(dv_sliding_t *s, const dv_real_t *x, size_t n)
{
    DV_ASSERT(s != NULL);
    if (x == NULL) {
        return n == 0u ? DV_OK : DV_EINVAL;
    }
    if (dv_priv_all_in_range(x, n)) {
        dv_priv_sliding_push_finite(s, x, n);
        return DV_OK;
    }
    for (size_t i = 0u; i < n; i++) { /* rare: drop and count the bad samples one by one */
        (void)dv_sliding_update(s, x[i]);
    }
    return DV_ENUMERIC;
}

void dv_priv_sliding_push_finite(dv_sliding_t *s, const dv_real_t *x, size_t n)
{
    size_t i = 0u;
    while (i < n) {
        /* Stretches up to the next turn; the window must be full for add/subtract. */
        size_t m = s->len - s->head;
        m = m < n - i ? m : n - i;
        const dv_real_t *restrict p = x + i;
        if (s->fill < s->len || m < 8u) {
            dv_priv_sliding_push(s, x[i]);
            i++;
            continue;
        }
        if (m == s->len) {
            /* A whole turn replaces the window: the turn-over recomputes everything from it. */
            dv_priv_sliding_turn_over(s, p);
            i += m;
            continue;
        }
        /* Sums of the entering minus the leaving samples, two interleaved lanes. */
        const dv_real_t k = s->shift;
        dv_real_t *restrict old = s->ring + s->head;
        dv_real_t a[4] = {0}, b[4] = {0}, oa[4] = {0}, ob[4] = {0};
        dv_real_t mx = s->premax, mn = s->premin;
        size_t j = 0u;
        for (; j + 1u < m; j += 2u) {
            const dv_real_t u = p[j] - k, v = p[j + 1u] - k;
            const dv_real_t e = old[j] - k, g = old[j + 1u] - k;
            const dv_real_t u2 = u * u, v2 = v * v, e2 = e * e, g2 = g * g;
            a[0] += u;
            b[0] += v;
            a[1] += u2;
            b[1] += v2;
            a[2] += u2 * u;
            b[2] += v2 * v;
            a[3] += u2 * u2;
            b[3] += v2 * v2;
            oa[0] += e;
            ob[0] += g;
            oa[1] += e2;
            ob[1] += g2;
            oa[2] += e2 * e;
            ob[2] += g2 * g;
            oa[3] += e2 * e2;
            ob[3] += g2 * g2;
            mx = p[j] > mx ? p[j] : mx;
            mn = p[j] < mn ? p[j] : mn;
            mx = p[j + 1u] > mx ? p[j + 1u] : mx;
            mn = p[j + 1u] < mn ? p[j + 1u] : mn;
        }
        for (; j < m; j++) {
            const dv_real_t u = p[j] - k, e = old[j] - k;
            const dv_real_t u2 = u * u, e2 = e * e;
            a[0] += u;
            a[1] += u2;
            a[2] += u2 * u;
            a[3] += u2 * u2;
            oa[0] += e;
            oa[1] += e2;
            oa[2] += e2 * e;
            oa[3] += e2 * e2;
            mx = p[j] > mx ? p[j] : mx;
            mn = p[j] < mn ? p[j] : mn;
        }
        for (int q = 0; q < 4; q++) {
            s->s[q] += (a[q] + b[q]) - (oa[q] + ob[q]);
        }
        for (j = 0u; j < m; j++) {
            old[j] = p[j];
        }
        s->premax = mx;
        s->premin = mn;
        s->head += (uint32_t)m;
        if (s->head == s->len) {
            dv_priv_sliding_turn_over(s, s->ring);
        }
        i += m;
    }
}

dv_status_t dv_sliding_get(const dv_sliding_t *s, dv_stats_t *out)
{
    if (s == NULL || out == NULL) {
        return DV_EINVAL;
    }
    if (s->fill < s->len) {
        return DV_ENOTREADY;
    }
    /* window = previous turn from head on + current turn before head; the previous turn's
     * part: the rest of head's block, then the blocks after it */
    const uint32_t h = s->head, b = h / DV_SLIDING_BLK;
    const uint32_t end = (b + 1u) * DV_SLIDING_BLK;
    dv_real_t mx = s->premax, mn = s->premin;
    if (end < s->len) {
        mx = s->sufmax[b + 1u] > mx ? s->sufmax[b + 1u] : mx;
        mn = s->sufmin[b + 1u] < mn ? s->sufmin[b + 1u] : mn;
    }
    for (uint32_t i = h; i < end && i < s->len; i++) {
        const dv_real_t v = s->ring[i];
        mx = v > mx ? v : mx;
        mn = v < mn ? v : mn;
    }
    dv_priv_cm_t cm;
    dv_priv_cm_from_sums(&cm, s->shift, (dv_real_t)s->len, s->s[0], s->s[1], s->s[2], s->s[3]);
    dv_priv_stats_fill(out, &cm, s->len, mn, mx);
    return DV_OK;
}

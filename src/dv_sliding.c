/* Sliding-window statistics: add/subtract power sums, refreshed exactly once per window;
 * extremes from suffix (previous turn) and prefix (current turn) maxima. */
#include "dynval/dv_sliding.h"
#include "dynval/dv_config.h"
#include "dv_feat_core.h"
#include "dv_priv.h"

dv_status_t dv_sliding_init(dv_sliding_t *s, size_t len, dv_real_t *buf, size_t buf_len)
{
    if (s == NULL || buf == NULL || len < 2u || len > DV_SLIDING_MAX_LEN) {
        return DV_EINVAL;
    }
    if (buf_len < DV_SLIDING_BUF_LEN(len)) {
        return DV_ESIZE;
    }
    s->ring = buf;
    s->sufmax = buf + len;
    s->sufmin = buf + 2u * len;
    s->len = (uint32_t)len;
    dv_sliding_reset(s);
    return DV_OK;
}

void dv_sliding_reset(dv_sliding_t *s)
{
    DV_ASSERT(s != NULL);
    s->head = s->fill = 0u;
    s->premax = -DV_REAL_MAX;
    s->premin = DV_REAL_MAX;
    s->shift = DV_R(0.0);
    for (int k = 0; k < 4; k++) {
        s->s[k] = DV_R(0.0);
    }
    s->n_nonfinite = 0u;
}

/* The ring has turned over and holds exactly the window. Recompute its sums from scratch about
 * its own mean (no add/subtract round-off survives a turn, and a drifting signal keeps small
 * d), and take the suffix extremes of this turn for the next one. */
void dv_priv_sliding_turn_over(dv_sliding_t *s)
{
    const dv_real_t *restrict r = s->ring;
    const uint32_t n = s->len;
    dv_real_t *restrict smax = s->sufmax;
    dv_real_t *restrict smin = s->sufmin;
    dv_real_t mx = -DV_REAL_MAX, mn = DV_REAL_MAX;
    dv_real_t a = DV_R(0.0), b = DV_R(0.0); /* two lanes: sum of x - shift */
    const dv_real_t k0 = s->shift;
    uint32_t i = n;
    for (; i >= 2u; i -= 2u) {
        const dv_real_t v = r[i - 1u], w = r[i - 2u];
        a += v - k0;
        b += w - k0;
        mx = v > mx ? v : mx;
        mn = v < mn ? v : mn;
        smax[i - 1u] = mx;
        smin[i - 1u] = mn;
        mx = w > mx ? w : mx;
        mn = w < mn ? w : mn;
        smax[i - 2u] = mx;
        smin[i - 2u] = mn;
    }
    if (i == 1u) {
        const dv_real_t v = r[0];
        a += v - k0;
        mx = v > mx ? v : mx;
        mn = v < mn ? v : mn;
        smax[0] = mx;
        smin[0] = mn;
    }
    const dv_real_t k = k0 + (a + b) / (dv_real_t)n; /* the window mean, to round-off */
    dv_real_t p1[2] = {0}, p2[2] = {0}, p3[2] = {0}, p4[2] = {0};
    for (i = 0u; i + 1u < n; i += 2u) {
        const dv_real_t u = r[i] - k, v = r[i + 1u] - k;
        const dv_real_t u2 = u * u, v2 = v * v;
        p1[0] += u;
        p1[1] += v;
        p2[0] += u2;
        p2[1] += v2;
        p3[0] += u2 * u;
        p3[1] += v2 * v;
        p4[0] += u2 * u2;
        p4[1] += v2 * v2;
    }
    if (i < n) {
        const dv_real_t u = r[i] - k, u2 = u * u;
        p1[0] += u;
        p2[0] += u2;
        p3[0] += u2 * u;
        p4[0] += u2 * u2;
    }
    s->shift = k;
    s->s[0] = p1[0] + p1[1]; /* ~0, but k is the mean only to round-off */
    s->s[1] = p2[0] + p2[1];
    s->s[2] = p3[0] + p3[1];
    s->s[3] = p4[0] + p4[1];
    s->premax = -DV_REAL_MAX;
    s->premin = DV_REAL_MAX;
    s->head = 0u;
}

dv_status_t dv_sliding_update(dv_sliding_t *s, dv_real_t x)
{
    DV_ASSERT(s != NULL);
    if (!dv_priv_finite(x)) {
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
    dv_status_t st = DV_OK;
    size_t i = 0u;
    while (i < n) {
        /* The fast path needs a full window, finite samples and a stretch up to the turn. */
        size_t m = s->len - s->head;
        m = m < n - i ? m : n - i;
        bool fast = s->fill == s->len && m >= 8u;
        const dv_real_t *restrict p = x + i;
        for (size_t j = 0u; fast && j < m; j++) {
            fast = dv_priv_finite(p[j]);
        }
        if (!fast) {
            if (dv_sliding_update(s, x[i]) != DV_OK) {
                st = DV_ENUMERIC;
            }
            i++;
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
            dv_priv_sliding_turn_over(s);
        }
        i += m;
    }
    return st;
}

dv_status_t dv_sliding_get(const dv_sliding_t *s, dv_stats_t *out)
{
    if (s == NULL || out == NULL) {
        return DV_EINVAL;
    }
    if (s->fill < s->len) {
        return DV_ENOTREADY;
    }
    /* window = previous turn from head on + current turn before head */
    dv_real_t mx = s->sufmax[s->head], mn = s->sufmin[s->head];
    mx = s->premax > mx ? s->premax : mx;
    mn = s->premin < mn ? s->premin : mn;
    dv_priv_cm_t cm;
    dv_priv_cm_from_sums(&cm, s->shift, (dv_real_t)s->len, s->s[0], s->s[1], s->s[2], s->s[3]);
    dv_priv_stats_fill(out, &cm, s->len, mn, mx);
    return DV_OK;
}

/* Sliding-window statistics: add/subtract power sums, refreshed exactly once per window. */
#include "dynval/dv_sliding.h"
#include "dynval/dv_config.h"
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
    s->qmax = buf + len;
    s->qmin = buf + 2u * len;
    s->len = (uint32_t)len;
    dv_sliding_reset(s);
    return DV_OK;
}

void dv_sliding_reset(dv_sliding_t *s)
{
    DV_ASSERT(s != NULL);
    s->head = s->fill = 0u;
    s->qmax_h = s->qmax_n = s->qmin_h = s->qmin_n = 0u;
    s->shift = DV_R(0.0);
    for (int k = 0; k < 4; k++) {
        s->s[k] = s->f[k] = DV_R(0.0);
    }
    s->count = 0u;
    s->n_nonfinite = 0u;
}

/* Deque slot i positions after head h, in a ring of n. */
static inline uint32_t slot(uint32_t h, uint32_t i, uint32_t n)
{
    const uint32_t j = h + i;
    return j >= n ? j - n : j;
}

static inline void push_max(dv_sliding_t *s, dv_real_t x)
{
    while (s->qmax_n > 0u && s->qmax[slot(s->qmax_h, s->qmax_n - 1u, s->len)] < x) {
        s->qmax_n--;
    }
    s->qmax[slot(s->qmax_h, s->qmax_n, s->len)] = x;
    s->qmax_n++;
}

static inline void push_min(dv_sliding_t *s, dv_real_t x)
{
    while (s->qmin_n > 0u && s->qmin[slot(s->qmin_h, s->qmin_n - 1u, s->len)] > x) {
        s->qmin_n--;
    }
    s->qmin[slot(s->qmin_h, s->qmin_n, s->len)] = x;
    s->qmin_n++;
}

/* The leaving sample is the deque front exactly when it is the window's extreme. */
static inline void expire(dv_sliding_t *s, dv_real_t old)
{
    if (s->qmax[s->qmax_h] == old) {
        s->qmax_h = slot(s->qmax_h, 1u, s->len);
        s->qmax_n--;
    }
    if (s->qmin[s->qmin_h] == old) {
        s->qmin_h = slot(s->qmin_h, 1u, s->len);
        s->qmin_n--;
    }
}

dv_status_t dv_sliding_update(dv_sliding_t *s, dv_real_t x)
{
    DV_ASSERT(s != NULL);
    if (!dv_priv_finite(x)) {
        s->n_nonfinite++;
        return DV_ENUMERIC;
    }
    if (s->count == 0u) {
        s->shift = x;
    }
    const dv_real_t d = x - s->shift;
    const dv_real_t d2 = d * d;
    const dv_real_t d3 = d2 * d, d4 = d2 * d2;
    if (s->fill == s->len) {
        const dv_real_t old = s->ring[s->head];
        const dv_real_t e = old - s->shift;
        const dv_real_t e2 = e * e;
        s->s[0] += d - e;
        s->s[1] += d2 - e2;
        s->s[2] += d3 - e2 * e;
        s->s[3] += d4 - e2 * e2;
        expire(s, old);
    } else {
        s->s[0] += d;
        s->s[1] += d2;
        s->s[2] += d3;
        s->s[3] += d4;
        s->fill++;
    }
    s->f[0] += d;
    s->f[1] += d2;
    s->f[2] += d3;
    s->f[3] += d4;
    push_max(s, x);
    push_min(s, x);
    s->ring[s->head] = x;
    s->count++;
    if (++s->head == s->len) {
        s->head = 0u;
        /* f now holds exactly the window's sums, free of add/subtract round-off. Adopt them,
         * and re-centre on the window mean so a drifting signal keeps small d. */
        const dv_real_t n = (dv_real_t)s->len;
        const dv_real_t delta = s->f[0] / n; /* window mean - shift */
        for (int k = 0; k < 4; k++) {
            s->s[k] = s->f[k];
            s->f[k] = DV_R(0.0);
        }
        dv_priv_sums_shift(s->s, n, -delta);
        s->s[0] = DV_R(0.0); /* the sum of deviations from the mean is 0 by definition */
        s->shift += delta;
    }
    return DV_OK;
}

dv_status_t dv_sliding_update_block(dv_sliding_t *s, const dv_real_t *x, size_t n)
{
    DV_ASSERT(s != NULL);
    if (x == NULL) {
        return n == 0u ? DV_OK : DV_EINVAL;
    }
    dv_status_t st = DV_OK;
    for (size_t i = 0u; i < n; i++) {
        if (dv_sliding_update(s, x[i]) != DV_OK) {
            st = DV_ENUMERIC;
        }
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
    dv_priv_cm_t cm;
    dv_priv_cm_from_sums(&cm, s->shift, (dv_real_t)s->len, s->s[0], s->s[1], s->s[2], s->s[3]);
    dv_priv_stats_fill(out, &cm, s->len, s->qmin[s->qmin_h], s->qmax[s->qmax_h]);
    return DV_OK;
}

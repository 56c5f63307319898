/* Segmented STD: per segment, sums of (x - first sample) and its square. */
#include "dynval/dv_segstd.h"
#include "dv_feat_core.h"
#include "dv_priv.h"

dv_status_t dv_segstd_init(dv_segstd_t *s, size_t seg_len, size_t n_seg, dv_real_t *buf,
                           size_t buf_len)
{
    if (s == NULL || (buf == NULL && buf_len != 0u) || seg_len < 2u || n_seg == 0u ||
        seg_len > UINT32_MAX || n_seg > UINT32_MAX / 2u) {
        return DV_EINVAL;
    }
    if (buf != NULL && buf_len < DV_SEGSTD_BUF_LEN(n_seg)) {
        return DV_ESIZE;
    }
    s->cur = buf;
    s->done = buf == NULL ? NULL : buf + n_seg;
    s->seg_len = (uint32_t)seg_len;
    s->n_seg = (uint32_t)n_seg;
    dv_segstd_reset(s);
    return DV_OK;
}

void dv_segstd_reset(dv_segstd_t *s)
{
    DV_ASSERT(s != NULL);
    s->pos = s->seg = s->records = 0u;
    s->shift = s->s1 = s->s2 = s->last = DV_R(0.0);
    s->n_nonfinite = 0u;
}

dv_status_t dv_segstd_update(dv_segstd_t *s, dv_real_t x)
{
    DV_ASSERT(s != NULL);
    if (!dv_priv_in_range(x)) {
        s->n_nonfinite++;
        return DV_ENUMERIC;
    }
    if (s->pos == 0u) {
        s->shift = x;
    }
    const dv_real_t d = x - s->shift;
    s->s1 += d;
    s->s2 += d * d;
    if (++s->pos < s->seg_len) {
        return DV_OK;
    }
    const dv_status_t st = dv_priv_segstd_push(s, s->s1, s->s2);
    s->pos = 0u;
    s->s1 = s->s2 = DV_R(0.0);
    return st;
}

dv_status_t dv_priv_segstd_push(dv_segstd_t *s, dv_real_t s1, dv_real_t s2)
{
    const dv_real_t n = (dv_real_t)s->seg_len;
    dv_real_t var = (s2 - s1 * s1 / n) / n;
    var = var > DV_R(0.0) ? var : DV_R(0.0);
    s->last = DV_SQRT(var);
    if (s->cur != NULL) {
        s->cur[s->seg] = s->last;
    }
    if (++s->seg < s->n_seg) {
        return DV_DONE;
    }
    /* Record complete: swap buffers so the finished vector stays readable. */
    dv_real_t *t = s->done;
    s->done = s->cur;
    s->cur = t;
    s->seg = 0u;
    s->records++;
    return DV_RECORD;
}

dv_status_t dv_segstd_last(const dv_segstd_t *s, dv_real_t *std, uint32_t *seg_index)
{
    if (s == NULL || std == NULL || seg_index == NULL) {
        return DV_EINVAL;
    }
    if (s->seg == 0u && s->records == 0u) {
        return DV_ENOTREADY;
    }
    *std = s->last;
    *seg_index = (s->seg == 0u ? s->n_seg : s->seg) - 1u;
    return DV_OK;
}

dv_status_t dv_segstd_get(const dv_segstd_t *s, dv_real_t *out, size_t out_len)
{
    if (s == NULL || out == NULL || s->done == NULL) {
        return DV_EINVAL;
    }
    if (out_len < s->n_seg) {
        return DV_ESIZE;
    }
    if (s->records == 0u) {
        return DV_ENOTREADY;
    }
    for (uint32_t i = 0u; i < s->n_seg; i++) {
        out[i] = s->done[i];
    }
    return DV_OK;
}

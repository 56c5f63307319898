/* Residual statistics: dv_moments / dv_sliding for the moments, k-sigma outlier tally. */
#include "dynval/dv_arstats.h"
#include "dynval/dv_config.h"
#include "dv_priv.h"

static void tally(uint64_t *n_out, uint64_t *n_stored, uint32_t *idx, dv_real_t *size,
                  size_t cap, uint64_t pos, dv_real_t z)
{
    if (*n_stored < (uint64_t)cap) {
        idx[*n_stored] = (uint32_t)pos;
        if (size != NULL) {
            size[*n_stored] = z;
        }
        (*n_stored)++;
    }
    (*n_out)++;
}

dv_status_t dv_arstats_record(dv_arstats_out_t *out, dv_real_t k_sigma, const dv_real_t *e,
                              size_t n, uint32_t *idx, dv_real_t *size, size_t cap)
{
    if (out == NULL || e == NULL || n == 0u || !(k_sigma > DV_R(0.0)) ||
        !dv_priv_finite(k_sigma) || (idx == NULL && cap > 0u)) {
        return DV_EINVAL;
    }
    dv_moments_t mo;
    (void)dv_moments_init(&mo);
    (void)dv_moments_update_block(&mo, e, n);
    dv_stats_t st;
    if (dv_moments_get(&mo, &st) != DV_OK || st.count < 2u ||
        (st.flags & DV_STATS_NO_SHAPE) != 0u) {
        return DV_ENOTREADY;
    }
    const dv_real_t thr = k_sigma * st.std;
    uint64_t n_out = 0u, n_stored = 0u;
    for (size_t i = 0u; i < n; i++) {
        const dv_real_t d = e[i] - st.mean;
        if (dv_priv_finite(d) && DV_FABS(d) > thr) {
            tally(&n_out, &n_stored, idx, size, cap, (uint64_t)i, d / st.std);
        }
    }
    out->rec = st;
    out->win = (dv_stats_t){0};
    out->win_ready = 0u;
    out->k_sigma = k_sigma;
    out->n_outliers = n_out;
    out->n_stored = n_stored;
    out->n_overflow = n_out - n_stored;
    out->n_nonfinite = dv_moments_nonfinite(&mo);
    return out->n_nonfinite > 0u ? DV_ENUMERIC : DV_OK;
}

dv_status_t dv_arstats_init(dv_arstats_t *s, dv_real_t k_sigma, size_t win_len, dv_real_t *buf,
                            size_t buf_len, uint32_t *idx, dv_real_t *size, size_t cap)
{
    if (s == NULL || buf == NULL || !(k_sigma > DV_R(0.0)) || !dv_priv_finite(k_sigma) ||
        (idx == NULL && cap > 0u)) {
        return DV_EINVAL;
    }
    const dv_status_t st = dv_sliding_init(&s->win, win_len, buf, buf_len);
    if (st != DV_OK) {
        return st;
    }
    s->k_sigma = k_sigma;
    s->idx = idx;
    s->size = size;
    s->cap = cap;
    dv_arstats_reset(s);
    return DV_OK;
}

void dv_arstats_reset(dv_arstats_t *s)
{
    DV_ASSERT(s != NULL);
    dv_moments_reset(&s->rec);
    dv_sliding_reset(&s->win);
    s->n_outliers = 0u;
    s->n_stored = 0u;
    s->pos = 0u;
}

dv_status_t dv_arstats_update(dv_arstats_t *s, dv_real_t e)
{
    DV_ASSERT(s != NULL);
    const uint64_t pos = s->pos++;
    if (!dv_priv_finite(e)) {
        (void)dv_moments_update(&s->rec, e); /* counts it */
        return DV_ENUMERIC;
    }
    dv_status_t ret = DV_OK;
    dv_stats_t w;
    if (dv_sliding_get(&s->win, &w) == DV_OK && (w.flags & DV_STATS_NO_SHAPE) == 0u) {
        const dv_real_t d = e - w.mean;
        if (DV_FABS(d) > s->k_sigma * w.std) {
            tally(&s->n_outliers, &s->n_stored, s->idx, s->size, s->cap, pos, d / w.std);
            ret = DV_DONE;
        }
    }
    (void)dv_moments_update(&s->rec, e);
    (void)dv_sliding_update(&s->win, e);
    return ret;
}

dv_status_t dv_arstats_get(const dv_arstats_t *s, dv_arstats_out_t *out)
{
    if (s == NULL || out == NULL) {
        return DV_EINVAL;
    }
    dv_stats_t rec;
    if (dv_moments_get(&s->rec, &rec) != DV_OK) {
        return DV_ENOTREADY;
    }
    out->rec = rec;
    out->win_ready = dv_sliding_get(&s->win, &out->win) == DV_OK ? 1u : 0u;
    if (out->win_ready == 0u) {
        out->win = (dv_stats_t){0};
    }
    out->k_sigma = s->k_sigma;
    out->n_outliers = s->n_outliers;
    out->n_stored = s->n_stored;
    out->n_overflow = s->n_outliers - s->n_stored;
    out->n_nonfinite = dv_moments_nonfinite(&s->rec);
    return DV_OK;
}

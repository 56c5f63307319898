/* The per-channel feature bundle: one NaN check, then every feature module. */
#include "dynval/dv_chan.h"
#include "dynval/dv_config.h"
#include "dv_priv.h"

dv_status_t dv_chan_init(dv_chan_t *s, const dv_chan_config_t *cfg, dv_real_t *buf,
                         size_t buf_len)
{
    if (s == NULL || cfg == NULL || buf == NULL) {
        return DV_EINVAL;
    }
    if (cfg->win_len < 2u || cfg->win_len > DV_SLIDING_MAX_LEN || cfg->seg_len < 2u ||
        cfg->n_seg == 0u || !dv_priv_finite(cfg->dt_s) || !(cfg->dt_s > DV_R(0.0))) {
        return DV_EINVAL;
    }
    if (buf_len < DV_CHAN_BUF_LEN(cfg->win_len, cfg->n_seg)) {
        return DV_ESIZE;
    }
    const size_t wl = DV_SLIDING_BUF_LEN(cfg->win_len);
    dv_status_t st = dv_sliding_init(&s->win, cfg->win_len, buf, wl);
    if (st == DV_OK) {
        st = dv_segstd_init(&s->seg, cfg->seg_len, cfg->n_seg, buf + wl, buf_len - wl);
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
    s->records = 0u;
    s->n_nonfinite = 0u;
    s->last_tm_st = DV_ENOTREADY;
    return DV_OK;
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
}

static void close_record(dv_chan_t *s)
{
    (void)dv_moments_get(&s->rec, &s->last_stats); /* a record is never empty here */
    s->last_tm_st = dv_temporal_get(&s->tm, &s->last_tm);
    dv_moments_reset(&s->rec);
    dv_temporal_reset(&s->tm);
    s->records++;
}

dv_status_t dv_chan_update(dv_chan_t *s, dv_real_t x)
{
    DV_ASSERT(s != NULL);
    if (!dv_priv_finite(x)) {
        s->n_nonfinite++;
        return DV_ENUMERIC;
    }
    (void)dv_moments_update(&s->rec, x);
    (void)dv_sliding_update(&s->win, x);
    (void)dv_temporal_update(&s->tm, x);
    const dv_status_t st = dv_segstd_update(&s->seg, x);
    if (st == DV_RECORD) {
        close_record(s);
    }
    return st;
}

dv_status_t dv_chan_update_block(dv_chan_t *s, const dv_real_t *x, size_t n, size_t *n_used)
{
    DV_ASSERT(s != NULL);
    if (n_used == NULL || (x == NULL && n > 0u)) {
        return DV_EINVAL;
    }
    /* Samples left in this record (NaN-free case): the modules take that chunk in one go. */
    const size_t rec_len = (size_t)s->cfg.seg_len * s->cfg.n_seg;
    size_t used = 0u;
    while (used < n) {
        size_t left = rec_len - (size_t)(s->rec.count % rec_len);
        size_t chunk = n - used < left ? n - used : left;
        const dv_real_t *p = x + used;
        /* Any NaN/Inf: take the chunk sample by sample (rare; keeps the bookkeeping simple). */
        bool finite = true;
        for (size_t i = 0u; i < chunk; i++) {
            finite = finite && dv_priv_finite(p[i]);
        }
        if (!finite) {
            for (size_t i = 0u; i < chunk; i++) {
                if (dv_chan_update(s, p[i]) == DV_RECORD) {
                    *n_used = used + i + 1u;
                    return DV_RECORD;
                }
            }
            used += chunk;
            continue;
        }
        (void)dv_moments_update_block(&s->rec, p, chunk);
        (void)dv_sliding_update_block(&s->win, p, chunk);
        (void)dv_temporal_update_block(&s->tm, p, chunk);
        dv_status_t st = DV_OK;
        for (size_t i = 0u; i < chunk; i++) {
            st = dv_segstd_update(&s->seg, p[i]);
        }
        used += chunk;
        if (st == DV_RECORD) {
            close_record(s);
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

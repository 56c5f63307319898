/* Correlation coefficient: Welford co-moments, one divide per pair. */
#include "dynval/dv_corr.h"
#include "dv_priv.h"

dv_status_t dv_corr_init(dv_corr_t *s)
{
    if (s == NULL) {
        return DV_EINVAL;
    }
    dv_corr_reset(s);
    return DV_OK;
}

void dv_corr_reset(dv_corr_t *s)
{
    DV_ASSERT(s != NULL);
    s->mx = s->my = s->cxx = s->cyy = s->cxy = DV_R(0.0);
    s->count = 0u;
    s->n_nonfinite = 0u;
}

dv_status_t dv_corr_update(dv_corr_t *s, dv_real_t x, dv_real_t y)
{
    DV_ASSERT(s != NULL);
    if (!dv_priv_in_range(x) || !dv_priv_in_range(y)) {
        s->n_nonfinite++;
        return DV_ENUMERIC;
    }
    s->count++;
    const dv_real_t inv_n = DV_R(1.0) / (dv_real_t)s->count;
    const dv_real_t dx = x - s->mx;
    const dv_real_t dy = y - s->my;
    s->mx += dx * inv_n;
    s->my += dy * inv_n;
    const dv_real_t ex = x - s->mx, ey = y - s->my;
    s->cxx += dx * ex;
    s->cyy += dy * ey;
    s->cxy += dx * ey;
    return DV_OK;
}

dv_status_t dv_corr_get(const dv_corr_t *s, dv_real_t *r)
{
    if (s == NULL || r == NULL) {
        return DV_EINVAL;
    }
    if (s->count < 2u) {
        return DV_ENOTREADY;
    }
    if (!(s->cxx > DV_R(0.0)) || !(s->cyy > DV_R(0.0))) {
        return DV_ENUMERIC;
    }
    dv_real_t v = s->cxy / (DV_SQRT(s->cxx) * DV_SQRT(s->cyy)); /* no overflow of cxx*cyy */
    v = v > DV_R(1.0) ? DV_R(1.0) : (v < DV_R(-1.0) ? DV_R(-1.0) : v);
    *r = v;
    return DV_OK;
}

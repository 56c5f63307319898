/* Temporal moments: x^2-weighted time moments, per block in local time, merged exactly. */
#include "dynval/dv_temporal.h"
#include "dynval/dv_config.h"
#include "dv_feat_core.h"
#include "dv_priv.h"

dv_status_t dv_temporal_init(dv_temporal_t *s, dv_real_t dt_s)
{
    if (s == NULL || !dv_priv_finite(dt_s) || !(dt_s > DV_R(0.0))) {
        return DV_EINVAL;
    }
    s->dt_s = dt_s;
    dv_temporal_reset(s);
    return DV_OK;
}

void dv_temporal_reset(dv_temporal_t *s)
{
    DV_ASSERT(s != NULL);
    s->w = s->mean = s->m2 = s->m3 = s->m4 = DV_R(0.0);
    s->t0 = s->tau = DV_R(0.0);
    s->s0 = s->s1 = s->s2 = s->s3 = s->s4 = DV_R(0.0);
    s->blk = 0u;
    s->count = 0u;
    s->n_nonfinite = 0u;
}

static void open_block(const dv_temporal_t *s, dv_priv_cm_t *b)
{
    dv_priv_cm_from_sums(b, s->t0, s->s0, s->s1, s->s2, s->s3, s->s4);
}

void dv_priv_temporal_flush(dv_temporal_t *s)
{
    if (s->s0 > DV_R(0.0)) {
        dv_priv_cm_t a = {s->w, s->mean, s->m2, s->m3, s->m4};
        dv_priv_cm_t b;
        open_block(s, &b);
        dv_priv_cm_merge(&a, &b);
        s->w = a.n;
        s->mean = a.mean;
        s->m2 = a.m2;
        s->m3 = a.m3;
        s->m4 = a.m4;
    }
    s->t0 += s->tau;
    s->tau = DV_R(0.0);
    s->s0 = s->s1 = s->s2 = s->s3 = s->s4 = DV_R(0.0);
    s->blk = 0u;
}

void dv_priv_temporal_push_block(dv_temporal_t *s, const dv_real_t w[5])
{
    DV_ASSERT(s->blk == 0u);
    s->s0 = w[0];
    s->s1 = w[1];
    s->s2 = w[2];
    s->s3 = w[3];
    s->s4 = w[4];
    s->tau = (dv_real_t)DV_BLOCK_LEN;
    s->count += DV_BLOCK_LEN;
    dv_priv_temporal_flush(s);
}

dv_status_t dv_temporal_update(dv_temporal_t *s, dv_real_t x)
{
    DV_ASSERT(s != NULL);
    if (dv_priv_finite(x)) {
        dv_priv_temporal_push(s, x);
        return DV_OK;
    }
    /* The sample clock ticked: keep the time slot, add no energy. */
    s->n_nonfinite++;
    s->tau += DV_R(1.0);
    if (++s->blk == DV_BLOCK_LEN) {
        dv_priv_temporal_flush(s);
    }
    return DV_ENUMERIC;
}

dv_status_t dv_temporal_update_block(dv_temporal_t *s, const dv_real_t *x, size_t n)
{
    DV_ASSERT(s != NULL);
    if (x == NULL) {
        return n == 0u ? DV_OK : DV_EINVAL;
    }
    dv_status_t st = DV_OK;
    size_t i = 0u;
    while (i < n) {
        if (s->blk != 0u || n - i < DV_BLOCK_LEN) {
            if (dv_temporal_update(s, x[i]) != DV_OK) {
                st = DV_ENUMERIC;
            }
            i++;
            continue;
        }
        const dv_real_t *p = x + i;
        dv_real_t a0 = DV_R(0.0), a1 = DV_R(0.0), a2 = DV_R(0.0), a3 = DV_R(0.0), a4 = DV_R(0.0);
        dv_real_t b0 = DV_R(0.0), b1 = DV_R(0.0), b2 = DV_R(0.0), b3 = DV_R(0.0), b4 = DV_R(0.0);
        dv_real_t t = DV_R(0.0);
        for (size_t j = 0u; j < DV_BLOCK_LEN; j += 2u) {
            const dv_real_t u = t + DV_R(1.0);
            const dv_real_t w = p[j] * p[j], v = p[j + 1u] * p[j + 1u];
            const dv_real_t w1 = w * t, w2 = w1 * t;
            const dv_real_t v1 = v * u, v2 = v1 * u;
            a0 += w;
            b0 += v;
            a1 += w1;
            b1 += v1;
            a2 += w2;
            b2 += v2;
            const dv_real_t w3 = w2 * t, v3 = v2 * u;
            a3 += w3;
            b3 += v3;
            a4 += w3 * t;
            b4 += v3 * u;
            t += DV_R(2.0);
        }
        if (!dv_priv_finite(a4 + b4 + a0 + b0)) {
            for (size_t j = 0u; j < DV_BLOCK_LEN; j++) {
                if (dv_temporal_update(s, p[j]) != DV_OK) {
                    st = DV_ENUMERIC;
                }
            }
        } else {
            s->s0 = a0 + b0;
            s->s1 = a1 + b1;
            s->s2 = a2 + b2;
            s->s3 = a3 + b3;
            s->s4 = a4 + b4;
            s->tau = (dv_real_t)DV_BLOCK_LEN;
            s->count += DV_BLOCK_LEN;
            dv_priv_temporal_flush(s);
        }
        i += DV_BLOCK_LEN;
    }
    return st;
}

dv_status_t dv_temporal_get(const dv_temporal_t *s, dv_temporal_out_t *out)
{
    if (s == NULL || out == NULL) {
        return DV_EINVAL;
    }
    if (s->count == 0u) {
        return DV_ENOTREADY;
    }
    dv_priv_cm_t a = {s->w, s->mean, s->m2, s->m3, s->m4};
    if (s->s0 > DV_R(0.0)) {
        dv_priv_cm_t b;
        open_block(s, &b);
        dv_priv_cm_merge(&a, &b);
    }
    if (!(a.n > DV_R(0.0))) {
        return DV_ENUMERIC;
    }
    const dv_real_t dt = s->dt_s;
    const dv_real_t m3 = a.m3 / a.n;
    out->energy = a.n * dt;
    out->central_time = a.mean * dt;
    out->rms_duration = DV_SQRT(a.m2 / a.n) * dt;
    out->central_skew = DV_CBRT(m3) * dt;
    out->central_kurt = DV_SQRT(DV_SQRT(a.m4 / a.n)) * dt;
    out->root_energy_amp =
        out->rms_duration > DV_R(0.0) ? DV_SQRT(out->energy / out->rms_duration) : DV_R(0.0);
    out->count = s->count;
    return DV_OK;
}

/* Temporal moments: x^2-weighted time moments, per block in local time, merged exactly. */
#include "dynval/dv_temporal.h"
#include "dynval/dv_config.h"
#include "dv_feat_core.h"
#include "dv_priv.h"

dv_status_t dv_temporal_init(dv_temporal_t *s, dv_real_t dt_s)
{
    if (s == NULL || !(dt_s > DV_R(0.0)) || !(dt_s <= DV_TEMPORAL_MAX_DT_S)) {
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
    s->wsc = DV_R(1.0);
    s->s0 = s->s1 = s->s2 = s->s3 = s->s4 = DV_R(0.0);
    s->blk = 0u;
    s->count = 0u;
    s->n_nonfinite = 0u;
}

/* The weights (x^2) are kept scaled by *wsc, a power of two, so that the merged weight stays
 * within [TM_W_LO, TM_W_HI]: then neither the merge's products of weights (na^2 m2 and the like)
 * nor the central sums overflow or underflow, whatever the amplitude of x (up to DV_FEAT_MAX)
 * and for records up to 2^28 samples (float) / 2^64 (double). Scaling by a power of two is
 * exact and every term of the merge has the weight's dimension, so the result is the unscaled
 * one bit for bit wherever that one stayed in range; only the energy carries the scale, and
 * dv_temporal_get() takes it out. */
#ifdef DV_REAL_DOUBLE
#define TM_W_HI 3.402823669209385e38 /* 2^128 */
#define TM_W_LO 2.938735877055719e-39 /* 2^-128 */
#else
#define TM_W_HI 65536.0f /* 2^16 */
#define TM_W_LO 1.5258789e-05f /* 2^-16 */
#endif
/* tiny weights: scaled up to 2^112 / 2^896, so that a record's weight of any normal size is
 * brought to TM_W_LO and even a subnormal one keeps the merge's mean shift d / n finite */
#define TM_WSC_MAX (TM_W_HI * TM_W_HI * TM_W_HI * TM_W_HI * TM_W_HI * TM_W_HI * TM_W_HI)

static void cm_scale(dv_priv_cm_t *a, dv_real_t f)
{
    a->n *= f;
    a->m2 *= f;
    a->m3 *= f;
    a->m4 *= f;
}

/* a (scaled by *wsc) <- a (+) the open block (unscaled sums). First a and *wsc are rescaled (by
 * TM_W_LO or TM_W_HI at a time, rarely) until the block's scaled weight is at most TM_W_HI and
 * a's weight within [TM_W_LO, TM_W_HI] unless the block's is already above TM_W_LO. */
static void merge_open_block(const dv_temporal_t *s, dv_priv_cm_t *a, dv_real_t *wsc)
{
    dv_priv_cm_t b;
    dv_priv_cm_from_sums(&b, s->t0, s->s0, s->s1, s->s2, s->s3, s->s4);
    for (;;) {
        const dv_real_t bn = b.n * *wsc;
        dv_real_t f;
        if (a->n > TM_W_HI || !(bn <= TM_W_HI)) {
            f = TM_W_LO;
        } else if (a->n < TM_W_LO && bn < TM_W_LO && *wsc < TM_WSC_MAX) {
            f = TM_W_HI;
        } else {
            break;
        }
        cm_scale(a, f);
        *wsc *= f;
    }
    cm_scale(&b, *wsc);
    dv_priv_cm_merge(a, &b);
}

void dv_priv_temporal_flush(dv_temporal_t *s)
{
    if (s->s0 > DV_R(0.0)) {
        dv_priv_cm_t a = {s->w, s->mean, s->m2, s->m3, s->m4};
        merge_open_block(s, &a, &s->wsc);
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
    if (dv_priv_in_range(x)) {
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
        /* NaN/Inf fail the test, and so does a sample beyond DV_FEAT_MAX (x^2 <= sum x^2; with
         * every x in range the other sums are finite); an in-range block that fails it (rms >
         * DV_FEAT_MAX / 8) is merely taken sample by sample */
        if (!(a0 + b0 <= DV_FEAT_MAX * DV_FEAT_MAX)) {
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
    dv_real_t wsc = s->wsc;
    if (s->s0 > DV_R(0.0)) {
        merge_open_block(s, &a, &wsc);
    }
    if (!(a.n > DV_R(0.0))) {
        return DV_ENUMERIC;
    }
    const dv_real_t dt = s->dt_s;
    const dv_real_t m3 = a.m3 / a.n;
    const dv_real_t m4 = a.m4 > DV_R(0.0) ? a.m4 : DV_R(0.0); /* round-off on tiny weights */
    const dv_real_t e = a.n / wsc * dt;
    const dv_real_t d = DV_SQRT(a.m2 / a.n) * dt;
    const dv_real_t ae = d > DV_R(0.0) ? DV_SQRT(e / d) : DV_R(0.0);
    /* With dt_s <= DV_TEMPORAL_MAX_DT_S and the weights in range, only a record too long for
     * the type (its fourth central sum, the largest; NaN fails too) or a huge energy over a
     * vanishing duration (ae) can overflow. */
    if (!(a.m4 <= DV_REAL_MAX) || !(ae <= DV_REAL_MAX)) {
        return DV_ERANGE;
    }
    out->energy = e;
    out->central_time = a.mean * dt;
    out->rms_duration = d;
    out->central_skew = DV_CBRT(m3) * dt;
    out->central_kurt = DV_SQRT(DV_SQRT(m4 / a.n)) * dt;
    out->root_energy_amp = ae;
    out->count = s->count;
    return DV_OK;
}

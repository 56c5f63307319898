/* The firmware loop's observer stage (sim_core.c stage 3): dv_model + dv_obs built from
 * the configuration's model registers, driven by the force channel, one step per time
 * index; each channel's samples wait in a queue until every channel of the step is in. */
#include "sim_core.h"
#include "sim_priv.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void sim_obs_free(struct sim_obs *o)
{
    free(o->mbuf);
    free(o->obuf);
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        free(o->q[i]);
        o->q[i] = NULL;
    }
    o->mbuf = o->obuf = NULL;
    o->on = 0;
}

void sim_obs_restart(struct sim_obs *o)
{
    if (o->on) {
        dv_obs_reset(&o->obs);
    }
    memset(o->qh, 0, sizeof o->qh);
    memset(o->qn, 0, sizeof o->qn);
    o->steps = 0;
}

/* (Re)build model and observer from the configuration; status says how it went. */
void sim_obs_setup(struct sim_core *c)
{
    struct sim_obs *o = &c->obs;
    const struct sim_config *cfg = &c->cfg;
    sim_obs_free(o);
    sim_obs_restart(o);
    o->overrun = 0;
    const float *p = cfg->model;
    const unsigned n_dof = (unsigned)p[SIM_MODEL_N_DOF];
    if (n_dof == 0) {
        c->obs_status = SIM_STAGE_NOT_CONFIGURED;
        return;
    }
    c->obs_status = SIM_STAGE_ERROR;
    dv_model_desc_t d;
    dv_model_desc_default(&d);
    d.n_dof = (uint16_t)n_dof;
    for (unsigned i = 0; i < n_dof; i++) {
        d.mass_kg[i] = (dv_real_t)p[SIM_MODEL_MASS + i];
        d.k_n_per_m[i] = (dv_real_t)p[SIM_MODEL_K + i];
        d.zeta[i] = (dv_real_t)p[SIM_MODEL_ZETA + i];
    }
    d.damp_kind = DV_DAMP_MODAL;
    d.input_kind = DV_INPUT_FORCE;
    d.input_dof = (uint16_t)p[SIM_MODEL_INPUT_DOF];
    d.input_hold = p[SIM_MODEL_HOLD] == (float)DV_HOLD_CUBIC ? DV_HOLD_CUBIC : DV_HOLD_FOH;
    d.n_elem = 0;
    /* measured channels: every channel but the force channel, in order, = acc of DOF 0.. */
    uint16_t n_out = 0;
    for (unsigned ch = 0; ch < cfg->n_chan && n_out < n_dof && n_out < DV_MAX_OUT; ch++) {
        if (ch != cfg->force_chan) {
            d.out[n_out].kind = DV_OUT_ACC;
            d.out[n_out].index = n_out;
            o->meas_ch[n_out] = (uint16_t)ch;
            n_out++;
        }
    }
    if (n_out == 0) {
        return;
    }
    d.n_out = n_out;
    o->n_out = n_out;
    const dv_real_t dt = (dv_real_t)1 / (dv_real_t)cfg->fs_hz[cfg->force_chan];
    const size_t ml = dv_model_buf_len(&d);
    o->mbuf = ml ? malloc(ml * sizeof *o->mbuf) : NULL;
    if (o->mbuf == NULL || dv_model_init(&o->model, &d, dt, o->mbuf, ml) != DV_OK) {
        sim_obs_free(o);
        return;
    }
    dv_obs_noise_t nz;
    memset(&nz, 0, sizeof nz);
    for (unsigned i = 0; i < DV_MAX_DOF; i++) {
        nz.q_force_n2[i] = (dv_real_t)p[SIM_MODEL_Q];
    }
    for (unsigned i = 0; i < DV_MAX_OUT; i++) {
        nz.r_meas[i] = (dv_real_t)p[SIM_MODEL_R];
    }
    const size_t ol = dv_obs_buf_len(&o->model);
    o->obuf = malloc(ol * sizeof *o->obuf);
    if (o->obuf == NULL ||
        dv_obs_init(&o->obs, &o->model, p[SIM_MODEL_Q] > 0.0f ? &nz : NULL, o->obuf, ol) !=
            DV_OK) {
        sim_obs_free(o);
        return;
    }
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        o->q[i] = malloc(SIM_OBS_QCAP * sizeof *o->q[i]);
        if (o->q[i] == NULL) {
            sim_obs_free(o);
            return;
        }
    }
    o->on = 1;
    c->obs_status = SIM_STAGE_RUNNING;
}

static int obs_uses(const struct sim_core *c, unsigned ch)
{
    if (ch == c->cfg.force_chan) {
        return 1;
    }
    for (unsigned j = 0; j < c->obs.n_out; j++) {
        if (c->obs.meas_ch[j] == ch) {
            return 1;
        }
    }
    return 0;
}

static void obs_push(struct sim_obs *o, unsigned ch, dv_real_t x)
{
    if (o->qn[ch] == SIM_OBS_QCAP) { /* this channel ran far ahead: lose its oldest */
        o->qh[ch] = (o->qh[ch] + 1u) % SIM_OBS_QCAP;
        o->qn[ch]--;
        o->overrun++;
    }
    o->q[ch][(o->qh[ch] + o->qn[ch]) % SIM_OBS_QCAP] = x;
    o->qn[ch]++;
}

static dv_real_t obs_pop(struct sim_obs *o, unsigned ch)
{
    const dv_real_t x = o->q[ch][o->qh[ch]];
    o->qh[ch] = (o->qh[ch] + 1u) % SIM_OBS_QCAP;
    o->qn[ch]--;
    return x;
}

/* Stage 3: queue the sample (NaN included: it holds its time slot); step the observer for
 * every time index all its channels have delivered; residual frames every resid_decim steps. */
void sim_obs_stage(struct sim_core *c, unsigned ch, dv_real_t x, dv_can_frame_t *out,
                           size_t *n)
{
    struct sim_obs *o = &c->obs;
    if (!o->on || !obs_uses(c, ch)) {
        return;
    }
    obs_push(o, ch, x);
    const unsigned fc = c->cfg.force_chan;
    for (;;) {
        if (o->qn[fc] == 0) {
            return;
        }
        for (unsigned j = 0; j < o->n_out; j++) {
            if (o->qn[o->meas_ch[j]] == 0) {
                return;
            }
        }
        dv_real_t y[DV_MAX_OUT], r[DV_MAX_OUT];
        const dv_real_t u = obs_pop(o, fc);
        for (unsigned j = 0; j < o->n_out; j++) {
            y[j] = obs_pop(o, o->meas_ch[j]);
        }
        const uint64_t n_pred = o->obs.n_pred;
        (void)dv_obs_step(&o->obs, u, y); /* NaN u: held; NaN y: predicted only */
        uint32_t step = o->steps++;
        if (dv_obs_latency(&o->obs) > 0u) {
            /* cubic hold: this call completes the previous accepted sample, whose residual
             * goes out now, labelled with that sample's own step; nothing new when the input
             * was refused (NaN) or on the first sample */
            if ((o->obs.flags & DV_OBS_FLAG_BAD_INPUT) != 0u) {
                continue;
            }
            const uint32_t done = o->pend_step;
            o->pend_step = step;
            if (o->obs.n_pred == n_pred) {
                continue;
            }
            step = done;
        }
        if (dv_obs_get(&o->obs, NULL, r, DV_MAX_OUT) != DV_OK) {
            continue;
        }
        const int emit = c->cfg.resid_decim != 0 && step % c->cfg.resid_decim == 0;
        for (unsigned j = 0; j < o->n_out; j++) {
            const unsigned mc = o->meas_ch[j];
            if (!isfinite((float)r[j])) { /* a diverging model: counted, never sent */
                c->n.nonfinite++;
                continue;
            }
            c->ch[mc].last.obs_resid = (float)r[j];
            if (!emit) {
                continue;
            }
            if (*n >= SIM_CORE_MAX_OUT) {
                c->n.tx_errors++;
                continue;
            }
            dv_msg_t m;
            m.kind = DV_MSG_RESID;
            m.u.resid.channel = (uint8_t)mc;
            m.u.resid.flags = o->obs.has_gain ? 1u : 0u;
            m.u.resid.step = (uint16_t)(step & 0xFFFFu);
            m.u.resid.value = (float)r[j];
            dv_codec_encode(&m, &out[(*n)++]);
        }
    }
}

/* A sequence gap of @p lost frames: NaN placeholders keep the observer's channels aligned. */
void sim_obs_stage_gap(struct sim_core *c, unsigned ch, uint32_t lost,
                               dv_can_frame_t *out, size_t *n)
{
    for (uint32_t i = 0; i < lost * DV_CODEC_SAMPLES_PER_FRAME; i++) {
        sim_obs_stage(c, ch, (dv_real_t)NAN, out, n);
    }
}

/* struct sim_config: its defaults, its check (the first bad holding register), and its
 * image in the Modbus holding registers (sim_regmap.h). */
#include "sim_core.h"
#include "sim_priv.h"

#include <math.h>
#include <string.h>

void sim_config_default(struct sim_config *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    cfg->n_chan = 5;
    cfg->win_len = 256;
    cfg->seg_len = 64;
    cfg->n_seg = 64;
    cfg->ar_order = 0;
    cfg->outlier_x100 = 600;
    cfg->resid_decim = 1;
    cfg->force_chan = 0;
    cfg->heartbeat_ms = 1000;
    cfg->recording = 1;
    cfg->model[SIM_MODEL_HOLD] = (float)DV_HOLD_CUBIC; /* the better hold, by default */
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        cfg->fs_hz[i] = 640;
        cfg->lsb[i] = DV_CODEC_DEFAULT_LSB;
    }
}

int sim_config_check(const struct sim_config *cfg)
{
    if (cfg->n_chan < 1 || cfg->n_chan > SIM_MAX_CHAN) {
        return SIM_HR_N_CHAN;
    }
    if (cfg->win_len < 2) {
        return SIM_HR_WIN_LEN;
    }
    if (cfg->seg_len < 2) {
        return SIM_HR_SEG_LEN;
    }
    if (cfg->n_seg < 1 || cfg->n_seg > 4096) {
        return SIM_HR_N_SEG;
    }
    if (cfg->ar_order > 32) {
        return SIM_HR_AR_ORDER;
    }
    if (cfg->force_chan >= cfg->n_chan) {
        return SIM_HR_FORCE_CHAN;
    }
    if (cfg->recording > 1) {
        return SIM_HR_RECORDING;
    }
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        if (!(cfg->lsb[i] > 0.0f) || !(cfg->lsb[i] <= SIM_LSB_MAX)) { /* NaN fails both */
            return SIM_HR_LSB + 2 * i;
        }
        if (cfg->fs_hz[i] == 0) {
            return SIM_HR_FS_CH + i;
        }
    }
    for (int i = 0; i < SIM_N_MODEL; i++) {
        if (!isfinite(cfg->model[i])) {
            return SIM_HR_MODEL + 2 * i;
        }
    }
    const float *m = cfg->model;
    const float nd = m[SIM_MODEL_N_DOF];
    if (nd < 0.0f || nd > (float)DV_MAX_DOF || nd != floorf(nd)) {
        return SIM_HR_MODEL + 2 * SIM_MODEL_N_DOF;
    }
    const int n = (int)nd;
    for (int i = 0; i < n; i++) {
        if (!(m[SIM_MODEL_MASS + i] > 0.0f)) {
            return SIM_HR_MODEL + 2 * (SIM_MODEL_MASS + i);
        }
        if (m[SIM_MODEL_K + i] < 0.0f) {
            return SIM_HR_MODEL + 2 * (SIM_MODEL_K + i);
        }
        if (m[SIM_MODEL_ZETA + i] < 0.0f) {
            return SIM_HR_MODEL + 2 * (SIM_MODEL_ZETA + i);
        }
    }
    if (m[SIM_MODEL_Q] < 0.0f) {
        return SIM_HR_MODEL + 2 * SIM_MODEL_Q;
    }
    if (m[SIM_MODEL_Q] > 0.0f && !(m[SIM_MODEL_R] > 0.0f)) {
        return SIM_HR_MODEL + 2 * SIM_MODEL_R;
    }
    const float in = m[SIM_MODEL_INPUT_DOF];
    if (in < 0.0f || in != floorf(in) || (n > 0 && in >= nd)) {
        return SIM_HR_MODEL + 2 * SIM_MODEL_INPUT_DOF;
    }
    const float hold = m[SIM_MODEL_HOLD];
    if (hold != (float)DV_HOLD_FOH && hold != (float)DV_HOLD_CUBIC) {
        return SIM_HR_MODEL + 2 * SIM_MODEL_HOLD;
    }
    return -1;
}

void sim_config_to_regs(const struct sim_config *cfg, uint16_t *hr)
{
    memset(hr, 0, SIM_N_HOLDING * sizeof *hr);
    hr[SIM_HR_N_CHAN] = cfg->n_chan;
    hr[SIM_HR_WIN_LEN] = cfg->win_len;
    hr[SIM_HR_SEG_LEN] = cfg->seg_len;
    hr[SIM_HR_N_SEG] = cfg->n_seg;
    hr[SIM_HR_AR_ORDER] = cfg->ar_order;
    hr[SIM_HR_OUTLIER_X100] = cfg->outlier_x100;
    hr[SIM_HR_RESID_DECIM] = cfg->resid_decim;
    hr[SIM_HR_FORCE_CHAN] = cfg->force_chan;
    hr[SIM_HR_HEARTBEAT_MS] = cfg->heartbeat_ms;
    hr[SIM_HR_RECORDING] = cfg->recording;
    for (int i = 0; i < SIM_N_MODEL; i++) {
        sim_put_f32(hr, SIM_HR_MODEL + 2 * i, cfg->model[i]);
    }
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        sim_put_f32(hr, SIM_HR_LSB + 2 * i, cfg->lsb[i]);
        hr[SIM_HR_FS_CH + i] = cfg->fs_hz[i];
    }
}

void sim_config_from_regs(struct sim_config *cfg, const uint16_t *hr)
{
    cfg->n_chan = hr[SIM_HR_N_CHAN];
    cfg->win_len = hr[SIM_HR_WIN_LEN];
    cfg->seg_len = hr[SIM_HR_SEG_LEN];
    cfg->n_seg = hr[SIM_HR_N_SEG];
    cfg->ar_order = hr[SIM_HR_AR_ORDER];
    cfg->outlier_x100 = hr[SIM_HR_OUTLIER_X100];
    cfg->resid_decim = hr[SIM_HR_RESID_DECIM];
    cfg->force_chan = hr[SIM_HR_FORCE_CHAN];
    cfg->heartbeat_ms = hr[SIM_HR_HEARTBEAT_MS];
    cfg->recording = hr[SIM_HR_RECORDING];
    for (int i = 0; i < SIM_N_MODEL; i++) {
        cfg->model[i] = sim_get_f32(hr, SIM_HR_MODEL + 2 * i);
    }
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        cfg->lsb[i] = sim_get_f32(hr, SIM_HR_LSB + 2 * i);
        cfg->fs_hz[i] = hr[SIM_HR_FS_CH + i];
    }
}

/* The firmware loop without sockets. See sim_core.h. Stages per accepted sample:
 * features (dv_chan), AR residual, observer; each stage returns the frames it produced. */
#include "sim_core.h"

#include <math.h>
#include <stdlib.h>
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
        if (!(cfg->lsb[i] > 0.0f) || !isfinite(cfg->lsb[i])) {
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
    return -1;
}

static uint32_t sat_add(uint32_t a, uint32_t b)
{
    return a + b < a ? UINT32_MAX : a + b;
}

static void nan_latest(struct sim_latest *l)
{
    float *f = (float *)l;
    for (size_t i = 0; i < sizeof *l / sizeof(float); i++) {
        f[i] = NAN;
    }
}

/* Fold the counts of the current sequence tracker into the channel's totals, then resync. */
static void seq_restart(struct sim_chan *sc)
{
    dv_seq_counts_t k;
    dv_seq_get(&sc->seq, &k);
    sc->seq_base.ok += k.ok;
    sc->seq_base.lost += k.lost;
    sc->seq_base.dup += k.dup;
    sc->seq_base.late += k.late;
    sc->seq_base.stale += k.stale;
    dv_seq_reset(&sc->seq);
}

static void chan_counts(const struct sim_chan *sc, dv_seq_counts_t *k)
{
    dv_seq_get(&sc->seq, k);
    k->ok += sc->seq_base.ok;
    k->lost += sc->seq_base.lost;
    k->dup += sc->seq_base.dup;
    k->late += sc->seq_base.late;
    k->stale += sc->seq_base.stale;
}

static uint32_t chan_nan(const struct sim_chan *sc)
{
    return sc->nan_base + (uint32_t)sc->feat.n_nonfinite;
}

/* (Re)initialise channel @p i's features with a fresh buffer; counters are kept. */
static int chan_setup(struct sim_core *c, const struct sim_config *cfg, int i, dv_real_t **buf_out)
{
    dv_chan_config_t cc;
    cc.win_len = cfg->win_len;
    cc.seg_len = cfg->seg_len;
    cc.n_seg = cfg->n_seg;
    cc.dt_s = (dv_real_t)1 / (dv_real_t)cfg->fs_hz[i];
    const size_t len = DV_CHAN_BUF_LEN(cc.win_len, cc.n_seg);
    dv_real_t *buf = malloc(len * sizeof *buf);
    if (buf == NULL) {
        return -1;
    }
    dv_chan_t tmp;
    if (dv_chan_init(&tmp, &cc, buf, len) != DV_OK) {
        free(buf);
        return -1;
    }
    struct sim_chan *sc = &c->ch[i];
    sc->nan_base += sc->buf != NULL ? (uint32_t)sc->feat.n_nonfinite : 0u;
    sc->feat = tmp;
    *buf_out = buf;
    sc->segments = 0;
    sc->records = 0;
    nan_latest(&sc->last);
    return 0;
}

int sim_core_configure(struct sim_core *c, const struct sim_config *cfg)
{
    if (sim_config_check(cfg) >= 0) {
        return -1;
    }
    int same = c->ch[0].buf != NULL && cfg->win_len == c->cfg.win_len &&
               cfg->seg_len == c->cfg.seg_len && cfg->n_seg == c->cfg.n_seg;
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        same = same && cfg->fs_hz[i] == c->cfg.fs_hz[i];
    }
    if (same) { /* nothing the features depend on changed: no re-init */
        c->cfg = *cfg;
        c->n.cfg_writes++;
        return 0;
    }
    dv_real_t *bufs[SIM_MAX_CHAN] = {0};
    struct sim_chan save[SIM_MAX_CHAN];
    memcpy(save, c->ch, sizeof save);
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        if (chan_setup(c, cfg, i, &bufs[i]) != 0) {
            for (int j = 0; j < i; j++) {
                free(bufs[j]);
            }
            memcpy(c->ch, save, sizeof save);
            return -1;
        }
    }
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        free(save[i].buf);
        c->ch[i].buf = bufs[i];
    }
    c->cfg = *cfg;
    c->ar_status = SIM_STAGE_NOT_CONFIGURED;  /* TODO(dv_ar): SIM_STAGE_RUNNING when ar_order>0 */
    c->obs_status = SIM_STAGE_NOT_CONFIGURED; /* TODO(dv_obs): build the model from cfg->model */
    c->n.cfg_writes++;
    return 0;
}

int sim_core_init(struct sim_core *c, const struct sim_config *cfg)
{
    memset(c, 0, sizeof *c);
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        dv_seq_init(&c->ch[i].seq);
        c->ch[i].enabled = 1;
    }
    if (sim_core_configure(c, cfg) != 0) {
        return -1;
    }
    c->n.cfg_writes = 0;
    return 0;
}

void sim_core_free(struct sim_core *c)
{
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        free(c->ch[i].buf);
        c->ch[i].buf = NULL;
    }
}

static void put_feature(dv_can_frame_t *out, size_t *n, uint8_t id, unsigned ch, uint32_t index,
                        dv_real_t value, float *latest)
{
    dv_msg_t m;
    m.kind = DV_MSG_FEATURE;
    m.u.feature.feat_id = id;
    m.u.feature.channel = (uint8_t)ch;
    m.u.feature.index = (uint16_t)(index & 0xFFFFu);
    m.u.feature.value = (float)value;
    if (latest != NULL) {
        *latest = m.u.feature.value;
    }
    dv_codec_encode(&m, &out[*n]);
    (*n)++;
}

/* Stage 1: the dv_chan feature set. Segment ends send the segment STD and the window
 * statistics; record ends also send the record statistics and temporal moments. Values that
 * are undefined for the data (flags, zero energy) are not sent. */
static size_t stage_features(struct sim_core *c, unsigned ch, dv_real_t x, dv_status_t *st_out,
                             dv_can_frame_t *out)
{
    struct sim_chan *sc = &c->ch[ch];
    struct sim_latest *l = &sc->last;
    size_t n = 0;
    const dv_status_t st = dv_chan_update(&sc->feat, x);
    *st_out = st;
    if (st == DV_ENUMERIC) {
        return 0;
    }
    sc->samples++;
    c->n.samples++;
    if (st != DV_DONE && st != DV_RECORD) {
        return 0;
    }
    const uint32_t seg = sc->segments++;
    dv_real_t std;
    uint32_t idx;
    if (dv_segstd_last(&sc->feat.seg, &std, &idx) == DV_OK) {
        put_feature(out, &n, DV_FEAT_SEG_STD, ch, seg, std, &l->seg_std);
    }
    dv_stats_t w;
    if (dv_chan_get_window(&sc->feat, &w) == DV_OK) {
        put_feature(out, &n, DV_FEAT_WIN_MEAN, ch, seg, w.mean, &l->win_mean);
        put_feature(out, &n, DV_FEAT_WIN_STD, ch, seg, w.std, &l->win_std);
        put_feature(out, &n, DV_FEAT_WIN_RMS, ch, seg, w.rms, &l->win_rms);
        put_feature(out, &n, DV_FEAT_WIN_PEAK, ch, seg, w.peak, &l->win_peak);
    }
    if (st != DV_RECORD) {
        return n;
    }
    const uint32_t rec = sc->records++;
    dv_stats_t r;
    dv_temporal_out_t tm;
    const dv_status_t rs = dv_chan_get_record(&sc->feat, &r, &tm);
    if (rs != DV_OK && rs != DV_ENUMERIC) {
        return n;
    }
    put_feature(out, &n, DV_FEAT_REC_MEAN, ch, rec, r.mean, &l->rec_mean);
    put_feature(out, &n, DV_FEAT_REC_STD, ch, rec, r.std, &l->rec_std);
    put_feature(out, &n, DV_FEAT_REC_RMS, ch, rec, r.rms, &l->rec_rms);
    if ((r.flags & DV_STATS_NO_SHAPE) == 0u) {
        put_feature(out, &n, DV_FEAT_REC_SKEW, ch, rec, r.skew, &l->rec_skew);
        put_feature(out, &n, DV_FEAT_REC_KURT, ch, rec, r.kurt, &l->rec_kurt);
    }
    put_feature(out, &n, DV_FEAT_REC_PEAK, ch, rec, r.peak, &l->rec_peak);
    put_feature(out, &n, DV_FEAT_REC_MIN, ch, rec, r.min, NULL);
    put_feature(out, &n, DV_FEAT_REC_MAX, ch, rec, r.max, NULL);
    if ((r.flags & DV_STATS_NO_CREST) == 0u) {
        put_feature(out, &n, DV_FEAT_REC_CREST, ch, rec, r.crest, &l->rec_crest);
    }
    put_feature(out, &n, DV_FEAT_REC_KFACTOR, ch, rec, r.kfactor, NULL);
    if (rs == DV_OK) {
        put_feature(out, &n, DV_FEAT_TM_ENERGY, ch, rec, tm.energy, &l->tm_energy);
        put_feature(out, &n, DV_FEAT_TM_CTIME, ch, rec, tm.central_time, &l->tm_ctime);
        put_feature(out, &n, DV_FEAT_TM_RMSDUR, ch, rec, tm.rms_duration, &l->tm_rmsdur);
        put_feature(out, &n, DV_FEAT_TM_CSKEW, ch, rec, tm.central_skew, NULL);
        put_feature(out, &n, DV_FEAT_TM_CKURT, ch, rec, tm.central_kurt, NULL);
        put_feature(out, &n, DV_FEAT_TM_AE, ch, rec, tm.root_energy_amp, NULL);
    }
    return n;
}

/* Stage 2: AR one-step residual per channel (DV_FEAT_AR_RESID_RMS at record ends).
 * TODO(dv_ar): the AR module (include/dynval/dv_ar*.h) had not landed when this was written;
 * wire it here: fit/update on accepted samples when cfg.ar_order > 0, send the record's
 * residual RMS when feat_st == DV_RECORD, set c->ar_status. Until then: not configured. */
static size_t stage_ar(struct sim_core *c, unsigned ch, dv_real_t x, dv_status_t feat_st,
                       dv_can_frame_t *out)
{
    (void)ch;
    (void)x;
    (void)feat_st;
    (void)out;
    c->ar_status = SIM_STAGE_NOT_CONFIGURED;
    return 0;
}

/* Stage 3: the observer, driven by the force channel, residual per measured channel sent
 * every cfg.resid_decim steps (DV_RESID).
 * TODO(dv_obs): the model/observer modules (dv_model.h, dv_obs.h) had not landed when this
 * was written. An observer step needs u and every y of the same time step, so this stage
 * will buffer one step across channels (samples arrive per channel, 3 per frame) and call
 * dv_obs_step() when all n_chan channels have delivered sample k. Until then: not configured. */
static size_t stage_observer(struct sim_core *c, unsigned ch, dv_real_t x, dv_can_frame_t *out)
{
    (void)ch;
    (void)x;
    (void)out;
    c->obs_status = SIM_STAGE_NOT_CONFIGURED;
    return 0;
}

static void start_record(struct sim_core *c)
{
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        struct sim_chan *sc = &c->ch[i];
        sc->nan_base += (uint32_t)sc->feat.n_nonfinite;
        dv_chan_reset(&sc->feat);
        seq_restart(sc);
        sc->segments = 0;
        sc->records = 0;
        nan_latest(&sc->last);
    }
}

static void clear_counters(struct sim_core *c)
{
    memset(&c->n, 0, sizeof c->n);
    c->overflowed = 0;
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        struct sim_chan *sc = &c->ch[i];
        dv_seq_counts_t k;
        dv_seq_get(&sc->seq, &k);
        /* keep the tracker's position, zero what it reports */
        sc->seq.n_ok = sc->seq.n_lost = sc->seq.n_dup = sc->seq.n_late = sc->seq.n_stale = 0;
        memset(&sc->seq_base, 0, sizeof sc->seq_base);
        sc->nan_base = 0u - (uint32_t)sc->feat.n_nonfinite; /* so chan_nan() reads 0 */
        sc->samples = 0;
    }
}

static size_t handle_samples(struct sim_core *c, const dv_msg_samples_t *s, dv_can_frame_t *out)
{
    if (s->channel >= c->cfg.n_chan) {
        c->n.bad_chan++;
        return 0;
    }
    struct sim_chan *sc = &c->ch[s->channel];
    if (!c->cfg.recording || !sc->enabled) {
        c->n.ignored++;
        return 0;
    }
    const dv_seq_verdict_t v = dv_seq_update(&sc->seq, s->seq);
    if (v != DV_SEQ_OK && v != DV_SEQ_GAP) {
        return 0;
    }
    size_t n = 0;
    for (unsigned i = 0; i < DV_CODEC_SAMPLES_PER_FRAME; i++) {
        const dv_real_t x = dv_codec_sample_value(s->raw[i], c->cfg.lsb[s->channel]);
        dv_status_t st;
        n += stage_features(c, s->channel, x, &st, out + n);
        n += stage_ar(c, s->channel, x, st, out + n);
        n += stage_observer(c, s->channel, x, out + n);
    }
    return n;
}

size_t sim_core_handle(struct sim_core *c, const dv_can_frame_t *in, dv_can_frame_t *out)
{
    c->n.rx_frames++;
    dv_msg_t m;
    const dv_status_t st = dv_codec_decode(in, &m);
    switch (st) {
    case DV_OK:
        break;
    case DV_ESIZE:
    case DV_EINVAL:
        c->n.bad_dlc++;
        return 0;
    case DV_ENUMERIC:
        c->n.bad_cfg++;
        return 0;
    default:
        c->n.unknown_id++;
        return 0;
    }
    switch (m.kind) {
    case DV_MSG_SAMPLES:
        return handle_samples(c, &m.u.samples, out);
    case DV_MSG_CTRL:
        switch (m.u.ctrl.cmd) {
        case DV_CTRL_START:
            start_record(c);
            c->cfg.recording = 1;
            return 0;
        case DV_CTRL_STOP:
            c->cfg.recording = 0;
            return 0;
        case DV_CTRL_CLEAR:
            clear_counters(c);
            return 0;
        default:
            sim_core_status_frame(c, out);
            return 1;
        }
    case DV_MSG_CHCFG: {
        const unsigned ch = m.u.chcfg.channel;
        if (ch >= SIM_MAX_CHAN) {
            c->n.bad_cfg++;
            return 0;
        }
        struct sim_config cfg = c->cfg;
        cfg.lsb[ch] = m.u.chcfg.lsb;
        cfg.fs_hz[ch] = m.u.chcfg.fs_hz;
        dv_real_t *buf;
        if (chan_setup(c, &cfg, (int)ch, &buf) != 0) {
            c->n.bad_cfg++;
            return 0;
        }
        free(c->ch[ch].buf);
        c->ch[ch].buf = buf;
        c->ch[ch].enabled = (m.u.chcfg.flags & 1u) != 0u;
        c->cfg = cfg;
        c->n.cfg_writes++;
        return 0;
    }
    default: /* a message this node sends, not consumes */
        c->n.unknown_id++;
        return 0;
    }
}

static uint8_t sat8(uint32_t v)
{
    return v > 255u ? 255u : (uint8_t)v;
}

static uint8_t state_bits(const struct sim_core *c)
{
    uint8_t s = 0;
    if (c->cfg.recording) {
        s |= DV_STATE_RECORDING;
    }
    if (c->obs_status == SIM_STAGE_RUNNING) {
        s |= DV_STATE_OBS_ON;
    }
    if (c->ar_status == SIM_STAGE_RUNNING) {
        s |= DV_STATE_AR_ON;
    }
    if (c->overflowed) {
        s |= DV_STATE_OVERFLOW;
    }
    return s;
}

static void total_counts(const struct sim_core *c, dv_seq_counts_t *t)
{
    memset(t, 0, sizeof *t);
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        dv_seq_counts_t k;
        chan_counts(&c->ch[i], &k);
        t->ok = sat_add(t->ok, k.ok);
        t->lost = sat_add(t->lost, k.lost);
        t->dup = sat_add(t->dup, k.dup);
        t->late = sat_add(t->late, k.late);
        t->stale = sat_add(t->stale, k.stale);
    }
}

void sim_core_status_frame(struct sim_core *c, dv_can_frame_t *out)
{
    dv_seq_counts_t t;
    total_counts(c, &t);
    dv_msg_t m;
    m.kind = DV_MSG_STATUS;
    m.u.status.state = state_bits(c);
    m.u.status.beat = c->beat++;
    m.u.status.lost = t.lost > 65535u ? 65535u : (uint16_t)t.lost;
    m.u.status.dup = sat8(t.dup);
    m.u.status.late = sat8(t.late);
    m.u.status.bad_dlc = sat8(c->n.bad_dlc);
    m.u.status.unknown = sat8(c->n.unknown_id);
    dv_codec_encode(&m, out);
}

size_t sim_core_tick(struct sim_core *c, uint64_t now_ns, dv_can_frame_t *out)
{
    if (c->cfg.heartbeat_ms == 0) {
        return 0;
    }
    const uint64_t period = (uint64_t)c->cfg.heartbeat_ms * 1000000u;
    if (c->next_beat_ns == 0 || now_ns + period < c->next_beat_ns) {
        c->next_beat_ns = now_ns + period; /* first tick, or the clock went back */
        return 0;
    }
    if (now_ns < c->next_beat_ns) {
        return 0;
    }
    c->next_beat_ns += period;
    if (c->next_beat_ns <= now_ns) {
        c->next_beat_ns = now_ns + period; /* missed beats are not sent in a burst */
    }
    sim_core_status_frame(c, out);
    return 1;
}

static void ir_u32(uint16_t *ir, int addr, uint32_t v)
{
    ir[addr] = (uint16_t)(v >> 16);
    ir[addr + 1] = (uint16_t)(v & 0xFFFFu);
}

static void ir_f32(uint16_t *ir, int addr, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    ir_u32(ir, addr, u);
}

static float hr_f32(const uint16_t *hr, int addr)
{
    const uint32_t u = ((uint32_t)hr[addr] << 16) | hr[addr + 1];
    float f;
    memcpy(&f, &u, 4);
    return f;
}

void sim_core_input_regs(const struct sim_core *c, uint16_t *ir)
{
    memset(ir, 0, SIM_N_INPUT * sizeof *ir);
    ir[SIM_IR_VERSION] = SIM_REGMAP_VERSION;
    ir[SIM_IR_STATE] = state_bits(c);
    ir[SIM_IR_N_CHAN] = c->cfg.n_chan;
    ir[SIM_IR_OBS_STATUS] = (uint16_t)c->obs_status;
    ir[SIM_IR_AR_STATUS] = (uint16_t)c->ar_status;
    ir[SIM_IR_REAL_SIZE] = (uint16_t)dv_real_size();
    dv_seq_counts_t t;
    total_counts(c, &t);
    uint32_t nan = 0;
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        nan = sat_add(nan, chan_nan(&c->ch[i]));
    }
    ir_u32(ir, SIM_IR_RX_FRAMES, c->n.rx_frames);
    ir_u32(ir, SIM_IR_TX_FRAMES, c->n.tx_frames);
    ir_u32(ir, SIM_IR_DROPPED, c->n.dropped);
    ir_u32(ir, SIM_IR_LOST, t.lost);
    ir_u32(ir, SIM_IR_DUP, t.dup);
    ir_u32(ir, SIM_IR_LATE, t.late);
    ir_u32(ir, SIM_IR_STALE, t.stale);
    ir_u32(ir, SIM_IR_BAD_DLC, c->n.bad_dlc);
    ir_u32(ir, SIM_IR_UNKNOWN_ID, c->n.unknown_id);
    ir_u32(ir, SIM_IR_NAN_SAMPLES, nan);
    ir_u32(ir, SIM_IR_BAD_CHAN, c->n.bad_chan);
    ir_u32(ir, SIM_IR_IGNORED, c->n.ignored);
    ir_u32(ir, SIM_IR_BAD_CFG, c->n.bad_cfg);
    ir_u32(ir, SIM_IR_SAMPLES, c->n.samples);
    ir_u32(ir, SIM_IR_TX_ERRORS, c->n.tx_errors);
    ir_u32(ir, SIM_IR_CFG_WRITES, c->n.cfg_writes);
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        const struct sim_chan *sc = &c->ch[i];
        const struct sim_latest *l = &sc->last;
        const int b = SIM_IR_CH(i);
        dv_seq_counts_t k;
        chan_counts(sc, &k);
        ir_u32(ir, b + SIM_IR_CH_LOST, k.lost);
        ir_u32(ir, b + SIM_IR_CH_DUP, k.dup);
        ir_u32(ir, b + SIM_IR_CH_LATE, k.late);
        ir_u32(ir, b + SIM_IR_CH_NAN, chan_nan(sc));
        ir_u32(ir, b + SIM_IR_CH_SAMPLES, sc->samples);
        ir_u32(ir, b + SIM_IR_CH_SEGMENTS, sc->segments);
        ir_u32(ir, b + SIM_IR_CH_RECORDS, sc->records);
        ir_f32(ir, b + SIM_IR_CH_SEG_STD, l->seg_std);
        ir_f32(ir, b + SIM_IR_CH_WIN_MEAN, l->win_mean);
        ir_f32(ir, b + SIM_IR_CH_WIN_STD, l->win_std);
        ir_f32(ir, b + SIM_IR_CH_WIN_RMS, l->win_rms);
        ir_f32(ir, b + SIM_IR_CH_WIN_PEAK, l->win_peak);
        ir_f32(ir, b + SIM_IR_CH_REC_MEAN, l->rec_mean);
        ir_f32(ir, b + SIM_IR_CH_REC_STD, l->rec_std);
        ir_f32(ir, b + SIM_IR_CH_REC_RMS, l->rec_rms);
        ir_f32(ir, b + SIM_IR_CH_REC_SKEW, l->rec_skew);
        ir_f32(ir, b + SIM_IR_CH_REC_KURT, l->rec_kurt);
        ir_f32(ir, b + SIM_IR_CH_REC_PEAK, l->rec_peak);
        ir_f32(ir, b + SIM_IR_CH_REC_CREST, l->rec_crest);
        ir_f32(ir, b + SIM_IR_CH_TM_ENERGY, l->tm_energy);
        ir_f32(ir, b + SIM_IR_CH_TM_CTIME, l->tm_ctime);
        ir_f32(ir, b + SIM_IR_CH_TM_RMSDUR, l->tm_rmsdur);
        ir_f32(ir, b + SIM_IR_CH_AR_RESID, l->ar_resid);
        ir_f32(ir, b + SIM_IR_CH_OBS_RESID, l->obs_resid);
    }
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
        ir_f32(hr, SIM_HR_MODEL + 2 * i, cfg->model[i]);
    }
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        ir_f32(hr, SIM_HR_LSB + 2 * i, cfg->lsb[i]);
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
        cfg->model[i] = hr_f32(hr, SIM_HR_MODEL + 2 * i);
    }
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        cfg->lsb[i] = hr_f32(hr, SIM_HR_LSB + 2 * i);
        cfg->fs_hz[i] = hr[SIM_HR_FS_CH + i];
    }
}

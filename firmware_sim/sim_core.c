/* The firmware loop without sockets. See sim_core.h. Stages per accepted sample, each
 * appending its frames to the output: features (dv_chan), AR residual (dv_ar, baseline fit),
 * observer (dv_model + dv_obs, driven by the force channel, one step per time index: in
 * sim_obs_stage.c). Here also the frame handling, the status frame and the input registers;
 * the configuration and its holding registers are in sim_config.c. */
#include "sim_core.h"
#include "sim_priv.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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
    /* each segment's STD is published as it completes: no vectors kept */
    cc.no_seg_vectors = true;
    const size_t len = DV_CHAN_BUF_LEN(cc.win_len, 0u);
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

/* ---- AR stage ------------------------------------------------------------------------- */

static void ar_clear(struct sim_ar *a)
{
    free(a->rec);
    a->rec = NULL;
    a->n = 0;
    a->phase = 0;
    a->outliers = 0;
    a->last_outliers = 0;
}

/* START: a fitted model is kept (it is the reference state); its filter restarts. */
static void ar_restart(struct sim_ar *a)
{
    a->n = 0;
    a->outliers = 0;
    if (a->phase == 1) {
        dv_ar_resid_reset(&a->res);
    }
    dv_moments_reset(&a->mom);
}

static void put_feature(struct sim_core *c, dv_can_frame_t *out, size_t *n, uint8_t id,
                        unsigned ch, uint32_t index, dv_real_t value, float *latest)
{
    dv_msg_t m;
    m.kind = DV_MSG_FEATURE;
    m.u.feature.feat_id = id;
    m.u.feature.channel = (uint8_t)ch;
    m.u.feature.index = (uint16_t)(index & 0xFFFFu);
    m.u.feature.value = (float)value;
    if (!isfinite(m.u.feature.value)) { /* a double beyond float32, or a library bug */
        c->n.nonfinite++;
        return;
    }
    if (latest != NULL) {
        *latest = m.u.feature.value;
    }
    if (*n >= SIM_CORE_MAX_OUT) {
        c->n.tx_errors++;
        return;
    }
    dv_codec_encode(&m, &out[*n]);
    (*n)++;
}

/* Stage 2: AR residual. Baseline record -> Burg fit of order cfg.ar_order; afterwards the
 * one-step residual of every accepted sample, and at each record end its RMS and the number
 * of residuals beyond (outlier_x100 / 100) x sigma of the fit. */
static void stage_ar(struct sim_core *c, unsigned ch, dv_real_t x, dv_status_t feat_st,
                     dv_can_frame_t *out, size_t *n)
{
    struct sim_chan *sc = &c->ch[ch];
    struct sim_ar *a = &sc->ar;
    const uint32_t p = c->cfg.ar_order;
    if (p == 0 || feat_st == DV_ENUMERIC || a->phase < 0) {
        return;
    }
    const uint32_t rec_len = (uint32_t)c->cfg.seg_len * c->cfg.n_seg;
    if (a->phase == 0) {
        if (a->rec == NULL) {
            a->rec = malloc((size_t)rec_len * sizeof *a->rec);
            if (a->rec == NULL) {
                a->phase = -1;
                c->ar_status = SIM_STAGE_ERROR;
                return;
            }
        }
        /* the baseline starts at a record boundary, like the records it is compared with */
        if (a->n < rec_len) {
            a->rec[a->n++] = x;
        }
        if (feat_st != DV_RECORD) {
            return;
        }
        if (a->n < rec_len) { /* joined mid-record: wait for a whole one */
            a->n = 0;
            return;
        }
        const size_t wl = DV_AR_WORK_LEN(rec_len, p);
        dv_real_t *work = malloc(wl * sizeof *work);
        dv_status_t st = work == NULL ? DV_ESIZE
                                      : dv_ar_fit(&a->model, DV_AR_BURG, p, a->rec, rec_len,
                                                  work, wl);
        free(work);
        if (st == DV_OK) {
            st = dv_ar_resid_init(&a->res, &a->model, a->hist, DV_AR_RESID_BUF_LEN(p));
        }
        free(a->rec);
        a->rec = NULL;
        a->n = 0;
        if (st != DV_OK) {
            a->phase = -1;
            c->ar_status = SIM_STAGE_ERROR;
            return;
        }
        a->phase = 1;
        dv_moments_reset(&a->mom);
        a->outliers = 0;
        if (c->ar_status != SIM_STAGE_ERROR) {
            c->ar_status = SIM_STAGE_RUNNING;
        }
        return;
    }
    dv_real_t e;
    if (dv_ar_resid_update(&a->res, x, &e) == DV_OK) {
        (void)dv_moments_update(&a->mom, e);
        const dv_real_t k = (dv_real_t)c->cfg.outlier_x100 / (dv_real_t)100;
        if (c->cfg.outlier_x100 != 0 && e * e > k * k * a->model.sigma2) {
            a->outliers++;
        }
    }
    if (feat_st != DV_RECORD) {
        return;
    }
    dv_stats_t rs;
    const uint32_t rec = sc->records - 1u; /* stage_features has counted this record */
    if (dv_moments_get(&a->mom, &rs) == DV_OK) {
        put_feature(c, out, n, DV_FEAT_AR_RESID_RMS, ch, rec, rs.rms, &sc->last.ar_resid);
        if (c->cfg.outlier_x100 != 0) {
            put_feature(c, out, n, DV_FEAT_AR_OUTLIERS, ch, rec, (dv_real_t)a->outliers, NULL);
        }
    }
    a->last_outliers = a->outliers;
    a->outliers = 0;
    dv_moments_reset(&a->mom);
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
    const int ar_same = cfg->ar_order == c->cfg.ar_order;
    if (same) { /* nothing the features depend on changed: no re-init */
        c->cfg = *cfg;
        if (!ar_same) {
            for (int i = 0; i < SIM_MAX_CHAN; i++) {
                ar_clear(&c->ch[i].ar);
            }
        }
        c->ar_status = SIM_STAGE_NOT_CONFIGURED;
        sim_obs_setup(c);
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
        ar_clear(&c->ch[i].ar); /* new record length: a new baseline */
    }
    c->cfg = *cfg;
    c->ar_status = SIM_STAGE_NOT_CONFIGURED; /* RUNNING once a baseline is fitted */
    sim_obs_setup(c);
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

struct sim_core *sim_core_new(const struct sim_config *cfg)
{
    struct sim_config def;
    if (cfg == NULL) {
        sim_config_default(&def);
        cfg = &def;
    }
    struct sim_core *c = malloc(sizeof *c);
    if (c != NULL && sim_core_init(c, cfg) != 0) {
        sim_core_free(c);
        free(c);
        c = NULL;
    }
    return c;
}

void sim_core_delete(struct sim_core *c)
{
    if (c != NULL) {
        sim_core_free(c);
        free(c);
    }
}

void sim_core_free(struct sim_core *c)
{
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        free(c->ch[i].buf);
        c->ch[i].buf = NULL;
        ar_clear(&c->ch[i].ar);
    }
    sim_obs_free(&c->obs);
}

/* Stage 1: the dv_chan feature set. Segment ends send the segment STD and the window
 * statistics; record ends also send the record statistics and temporal moments. Values that
 * are undefined for the data (flags, zero energy) are not sent. */
static dv_status_t stage_features(struct sim_core *c, unsigned ch, dv_real_t x,
                                  dv_can_frame_t *out, size_t *np)
{
    struct sim_chan *sc = &c->ch[ch];
    struct sim_latest *l = &sc->last;
    const dv_status_t st = dv_chan_update(&sc->feat, x);
    if (st == DV_ENUMERIC) {
        return st;
    }
    sc->samples++;
    c->n.samples++;
    if (st != DV_DONE && st != DV_RECORD) {
        return st;
    }
    const uint32_t seg = sc->segments++;
    dv_real_t std;
    uint32_t idx;
    if (dv_segstd_last(&sc->feat.seg, &std, &idx) == DV_OK) {
        put_feature(c, out, np, DV_FEAT_SEG_STD, ch, seg, std, &l->seg_std);
    }
    dv_stats_t w;
    if (dv_chan_get_window(&sc->feat, &w) == DV_OK) {
        put_feature(c, out, np, DV_FEAT_WIN_MEAN, ch, seg, w.mean, &l->win_mean);
        put_feature(c, out, np, DV_FEAT_WIN_STD, ch, seg, w.std, &l->win_std);
        put_feature(c, out, np, DV_FEAT_WIN_RMS, ch, seg, w.rms, &l->win_rms);
        put_feature(c, out, np, DV_FEAT_WIN_PEAK, ch, seg, w.peak, &l->win_peak);
    }
    if (st != DV_RECORD) {
        return st;
    }
    const uint32_t rec = sc->records++;
    dv_stats_t r;
    dv_temporal_out_t tm;
    const dv_status_t rs = dv_chan_get_record(&sc->feat, &r, &tm);
    if (rs != DV_OK && rs != DV_ENUMERIC) {
        c->n.nonfinite++; /* DV_ERANGE: the record overflowed the real type, nothing sent */
        return st;
    }
    put_feature(c, out, np, DV_FEAT_REC_MEAN, ch, rec, r.mean, &l->rec_mean);
    put_feature(c, out, np, DV_FEAT_REC_STD, ch, rec, r.std, &l->rec_std);
    put_feature(c, out, np, DV_FEAT_REC_RMS, ch, rec, r.rms, &l->rec_rms);
    if ((r.flags & DV_STATS_NO_SHAPE) == 0u) {
        put_feature(c, out, np, DV_FEAT_REC_SKEW, ch, rec, r.skew, &l->rec_skew);
        put_feature(c, out, np, DV_FEAT_REC_KURT, ch, rec, r.kurt, &l->rec_kurt);
    }
    put_feature(c, out, np, DV_FEAT_REC_PEAK, ch, rec, r.peak, &l->rec_peak);
    put_feature(c, out, np, DV_FEAT_REC_MIN, ch, rec, r.min, NULL);
    put_feature(c, out, np, DV_FEAT_REC_MAX, ch, rec, r.max, NULL);
    if ((r.flags & DV_STATS_NO_CREST) == 0u) {
        put_feature(c, out, np, DV_FEAT_REC_CREST, ch, rec, r.crest, &l->rec_crest);
    }
    put_feature(c, out, np, DV_FEAT_REC_KFACTOR, ch, rec, r.kfactor, NULL);
    if (rs == DV_OK) {
        put_feature(c, out, np, DV_FEAT_TM_ENERGY, ch, rec, tm.energy, &l->tm_energy);
        put_feature(c, out, np, DV_FEAT_TM_CTIME, ch, rec, tm.central_time, &l->tm_ctime);
        put_feature(c, out, np, DV_FEAT_TM_RMSDUR, ch, rec, tm.rms_duration, &l->tm_rmsdur);
        put_feature(c, out, np, DV_FEAT_TM_CSKEW, ch, rec, tm.central_skew, NULL);
        put_feature(c, out, np, DV_FEAT_TM_CKURT, ch, rec, tm.central_kurt, NULL);
        put_feature(c, out, np, DV_FEAT_TM_AE, ch, rec, tm.root_energy_amp, NULL);
    }
    return st;
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
        ar_restart(&sc->ar);
    }
    sim_obs_restart(&c->obs);
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
    dv_seq_counts_t before, after;
    dv_seq_get(&sc->seq, &before);
    const dv_seq_verdict_t v = dv_seq_update(&sc->seq, s->seq);
    if (v != DV_SEQ_OK && v != DV_SEQ_GAP) {
        return 0;
    }
    size_t n = 0;
    if (v == DV_SEQ_GAP) {
        dv_seq_get(&sc->seq, &after);
        sim_obs_stage_gap(c, s->channel, after.lost - before.lost, out, &n);
    }
    for (unsigned i = 0; i < DV_CODEC_SAMPLES_PER_FRAME; i++) {
        const dv_real_t x = dv_codec_sample_value(s->raw[i], c->cfg.lsb[s->channel]);
        const dv_status_t st = stage_features(c, s->channel, x, out, &n);
        stage_ar(c, s->channel, x, st, out, &n);
        sim_obs_stage(c, s->channel, x, out, &n);
    }
    return n;
}

int sim_refused_counter(dv_status_t st)
{
    switch (st) {
    case DV_ESIZE:
    case DV_EINVAL:
        return SIM_IR_BAD_DLC;
    case DV_ENUMERIC:
        return SIM_IR_BAD_CFG;
    default:
        return SIM_IR_UNKNOWN_ID;
    }
}

size_t sim_core_handle(struct sim_core *c, const dv_can_frame_t *in, dv_can_frame_t *out)
{
    c->n.rx_frames++;
    dv_msg_t m;
    const dv_status_t st = dv_codec_decode(in, &m);
    if (st != DV_OK) {
        const int reg = sim_refused_counter(st);
        uint32_t *n = reg == SIM_IR_BAD_DLC ? &c->n.bad_dlc
                      : reg == SIM_IR_BAD_CFG ? &c->n.bad_cfg : &c->n.unknown_id;
        (*n)++;
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
        /* the same checks as a Modbus write (lsb range above all) */
        if (sim_config_check(&cfg) >= 0 || chan_setup(c, &cfg, (int)ch, &buf) != 0) {
            c->n.bad_cfg++;
            return 0;
        }
        free(c->ch[ch].buf);
        c->ch[ch].buf = buf;
        c->ch[ch].enabled = (m.u.chcfg.flags & 1u) != 0u;
        ar_clear(&c->ch[ch].ar); /* new scaling: a new baseline */
        c->cfg = cfg;
        sim_obs_setup(c);
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
    sim_put_u32(ir, SIM_IR_RX_FRAMES, c->n.rx_frames);
    sim_put_u32(ir, SIM_IR_TX_FRAMES, c->n.tx_frames);
    sim_put_u32(ir, SIM_IR_DROPPED, c->n.dropped);
    sim_put_u32(ir, SIM_IR_LOST, t.lost);
    sim_put_u32(ir, SIM_IR_DUP, t.dup);
    sim_put_u32(ir, SIM_IR_LATE, t.late);
    sim_put_u32(ir, SIM_IR_STALE, t.stale);
    sim_put_u32(ir, SIM_IR_BAD_DLC, c->n.bad_dlc);
    sim_put_u32(ir, SIM_IR_UNKNOWN_ID, c->n.unknown_id);
    sim_put_u32(ir, SIM_IR_NAN_SAMPLES, nan);
    sim_put_u32(ir, SIM_IR_BAD_CHAN, c->n.bad_chan);
    sim_put_u32(ir, SIM_IR_IGNORED, c->n.ignored);
    sim_put_u32(ir, SIM_IR_BAD_CFG, c->n.bad_cfg);
    sim_put_u32(ir, SIM_IR_SAMPLES, c->n.samples);
    sim_put_u32(ir, SIM_IR_TX_ERRORS, c->n.tx_errors);
    sim_put_u32(ir, SIM_IR_CFG_WRITES, c->n.cfg_writes);
    sim_put_u32(ir, SIM_IR_OBS_STEPS, c->obs.steps);
    sim_put_u32(ir, SIM_IR_OBS_OVERRUN, c->obs.overrun);
    sim_put_u32(ir, SIM_IR_NONFINITE, c->n.nonfinite);
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        const struct sim_chan *sc = &c->ch[i];
        const struct sim_latest *l = &sc->last;
        const int b = SIM_IR_CH(i);
        dv_seq_counts_t k;
        chan_counts(sc, &k);
        sim_put_u32(ir, b + SIM_IR_CH_LOST, k.lost);
        sim_put_u32(ir, b + SIM_IR_CH_DUP, k.dup);
        sim_put_u32(ir, b + SIM_IR_CH_LATE, k.late);
        sim_put_u32(ir, b + SIM_IR_CH_NAN, chan_nan(sc));
        sim_put_u32(ir, b + SIM_IR_CH_SAMPLES, sc->samples);
        sim_put_u32(ir, b + SIM_IR_CH_SEGMENTS, sc->segments);
        sim_put_u32(ir, b + SIM_IR_CH_RECORDS, sc->records);
        sim_put_f32(ir, b + SIM_IR_CH_SEG_STD, l->seg_std);
        sim_put_f32(ir, b + SIM_IR_CH_WIN_MEAN, l->win_mean);
        sim_put_f32(ir, b + SIM_IR_CH_WIN_STD, l->win_std);
        sim_put_f32(ir, b + SIM_IR_CH_WIN_RMS, l->win_rms);
        sim_put_f32(ir, b + SIM_IR_CH_WIN_PEAK, l->win_peak);
        sim_put_f32(ir, b + SIM_IR_CH_REC_MEAN, l->rec_mean);
        sim_put_f32(ir, b + SIM_IR_CH_REC_STD, l->rec_std);
        sim_put_f32(ir, b + SIM_IR_CH_REC_RMS, l->rec_rms);
        sim_put_f32(ir, b + SIM_IR_CH_REC_SKEW, l->rec_skew);
        sim_put_f32(ir, b + SIM_IR_CH_REC_KURT, l->rec_kurt);
        sim_put_f32(ir, b + SIM_IR_CH_REC_PEAK, l->rec_peak);
        sim_put_f32(ir, b + SIM_IR_CH_REC_CREST, l->rec_crest);
        sim_put_f32(ir, b + SIM_IR_CH_TM_ENERGY, l->tm_energy);
        sim_put_f32(ir, b + SIM_IR_CH_TM_CTIME, l->tm_ctime);
        sim_put_f32(ir, b + SIM_IR_CH_TM_RMSDUR, l->tm_rmsdur);
        sim_put_f32(ir, b + SIM_IR_CH_AR_RESID, l->ar_resid);
        sim_put_f32(ir, b + SIM_IR_CH_OBS_RESID, l->obs_resid);
        sim_put_u32(ir, b + SIM_IR_CH_AR_OUTLIERS, sc->ar.last_outliers);
    }
}

/* The dynval CAN protocol: byte layouts of can/dynval.dbc and the sequence-gap tracker.
 * Byte order is spelled out with shifts so the code is the same on any host endianness. */
#include "dynval/dv_codec.h"
#include "dv_priv.h"

DV_STATIC_ASSERT(sizeof(float) == 4u, float_is_binary32);

static uint16_t get_u16(const uint8_t *p)
{
    return (uint16_t)((uint16_t)p[0] | (uint16_t)((uint16_t)p[1] << 8));
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

static void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)(v >> 8);
}

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)((v >> 8) & 0xFFu);
    p[2] = (uint8_t)((v >> 16) & 0xFFu);
    p[3] = (uint8_t)(v >> 24);
}

/* Union punning is defined in C99 (TC3, 6.5.2.3 footnote 82), and needs no memcpy. */
typedef union {
    float f;
    uint32_t u;
} f32_bits_t;

static float get_f32(const uint8_t *p)
{
    f32_bits_t b;
    b.u = get_u32(p);
    return b.f;
}

static void put_f32(uint8_t *p, float v)
{
    f32_bits_t b;
    b.f = v;
    put_u32(p, b.u);
}

static int16_t get_i16(const uint8_t *p)
{
    const uint16_t u = get_u16(p);
    /* two's complement without implementation-defined conversion */
    return u < 0x8000u ? (int16_t)u : (int16_t)(-(int32_t)(0x10000u - (uint32_t)u));
}

static bool id_is_ours(uint32_t id)
{
    return id == DV_CAN_ID_STATUS || id == DV_CAN_ID_CTRL || id == DV_CAN_ID_CHCFG ||
           id == DV_CAN_ID_SAMPLES || id == DV_CAN_ID_FEATURE || id == DV_CAN_ID_RESID;
}

dv_status_t dv_codec_decode(const dv_can_frame_t *f, dv_msg_t *out)
{
    if (f == NULL || out == NULL || f->dlc > 8u) {
        return DV_EINVAL;
    }
    if ((f->id & (DV_CAN_EFF_FLAG | DV_CAN_RTR_FLAG | DV_CAN_ERR_FLAG)) != 0u ||
        f->id > DV_CAN_SFF_MASK || !id_is_ours(f->id)) {
        return DV_ERANGE;
    }
    if (f->dlc != DV_CAN_DLC) {
        return DV_ESIZE;
    }
    const uint8_t *d = f->data;
    dv_msg_t m;
    switch (f->id) {
    case DV_CAN_ID_STATUS:
        m.kind = DV_MSG_STATUS;
        m.u.status.state = d[0];
        m.u.status.beat = d[1];
        m.u.status.lost = get_u16(d + 2);
        m.u.status.dup = d[4];
        m.u.status.late = d[5];
        m.u.status.bad_dlc = d[6];
        m.u.status.unknown = d[7];
        break;
    case DV_CAN_ID_CTRL:
        if (d[0] < DV_CTRL_START || d[0] > DV_CTRL_STATUS) {
            return DV_ERANGE;
        }
        m.kind = DV_MSG_CTRL;
        m.u.ctrl.cmd = d[0];
        m.u.ctrl.record_id = get_u32(d + 2);
        break;
    case DV_CAN_ID_CHCFG: {
        const float lsb = get_f32(d + 4);
        const uint16_t fs = get_u16(d + 2);
        /* !(lsb > 0) also rejects NaN; lsb - lsb is NaN for Inf */
        if (!(lsb > 0.0f) || (lsb - lsb) != 0.0f || fs == 0u) {
            return DV_ENUMERIC;
        }
        m.kind = DV_MSG_CHCFG;
        m.u.chcfg.channel = d[0];
        m.u.chcfg.flags = d[1];
        m.u.chcfg.fs_hz = fs;
        m.u.chcfg.lsb = lsb;
        break;
    }
    case DV_CAN_ID_SAMPLES:
        m.kind = DV_MSG_SAMPLES;
        m.u.samples.channel = d[0];
        m.u.samples.seq = d[1];
        for (uint32_t i = 0u; i < DV_CODEC_SAMPLES_PER_FRAME; i++) {
            m.u.samples.raw[i] = get_i16(d + 2u + 2u * i);
        }
        break;
    case DV_CAN_ID_FEATURE:
        m.kind = DV_MSG_FEATURE;
        m.u.feature.feat_id = d[0];
        m.u.feature.channel = d[1];
        m.u.feature.index = get_u16(d + 2);
        m.u.feature.value = get_f32(d + 4);
        break;
    default: /* DV_CAN_ID_RESID: id_is_ours() admitted nothing else */
        m.kind = DV_MSG_RESID;
        m.u.resid.channel = d[0];
        m.u.resid.flags = d[1];
        m.u.resid.step = get_u16(d + 2);
        m.u.resid.value = get_f32(d + 4);
        break;
    }
    *out = m;
    return DV_OK;
}

size_t dv_codec_decode_n(const dv_can_frame_t *f, size_t n, dv_msg_t *out, dv_status_t *status)
{
    if (f == NULL || out == NULL || status == NULL) {
        return 0u;
    }
    size_t ok = 0u;
    for (size_t i = 0; i < n; i++) {
        status[i] = dv_codec_decode(&f[i], &out[i]);
        ok += status[i] == DV_OK;
    }
    return ok;
}

dv_status_t dv_codec_encode(const dv_msg_t *m, dv_can_frame_t *f)
{
    if (m == NULL || f == NULL) {
        return DV_EINVAL;
    }
    uint8_t d[8] = {0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u};
    uint32_t id;
    switch (m->kind) {
    case DV_MSG_STATUS:
        id = DV_CAN_ID_STATUS;
        d[0] = m->u.status.state;
        d[1] = m->u.status.beat;
        put_u16(d + 2, m->u.status.lost);
        d[4] = m->u.status.dup;
        d[5] = m->u.status.late;
        d[6] = m->u.status.bad_dlc;
        d[7] = m->u.status.unknown;
        break;
    case DV_MSG_CTRL:
        id = DV_CAN_ID_CTRL;
        d[0] = m->u.ctrl.cmd;
        put_u32(d + 2, m->u.ctrl.record_id);
        break;
    case DV_MSG_CHCFG:
        id = DV_CAN_ID_CHCFG;
        d[0] = m->u.chcfg.channel;
        d[1] = m->u.chcfg.flags;
        put_u16(d + 2, m->u.chcfg.fs_hz);
        put_f32(d + 4, m->u.chcfg.lsb);
        break;
    case DV_MSG_SAMPLES:
        id = DV_CAN_ID_SAMPLES;
        d[0] = m->u.samples.channel;
        d[1] = m->u.samples.seq;
        for (uint32_t i = 0u; i < DV_CODEC_SAMPLES_PER_FRAME; i++) {
            /* the uint16 of a negative int16 is its two's complement (modulo 2^16) */
            put_u16(d + 2u + 2u * i, (uint16_t)m->u.samples.raw[i]);
        }
        break;
    case DV_MSG_FEATURE:
        id = DV_CAN_ID_FEATURE;
        d[0] = m->u.feature.feat_id;
        d[1] = m->u.feature.channel;
        put_u16(d + 2, m->u.feature.index);
        put_f32(d + 4, m->u.feature.value);
        break;
    case DV_MSG_RESID:
        id = DV_CAN_ID_RESID;
        d[0] = m->u.resid.channel;
        d[1] = m->u.resid.flags;
        put_u16(d + 2, m->u.resid.step);
        put_f32(d + 4, m->u.resid.value);
        break;
    default:
        return DV_EINVAL;
    }
    f->id = id;
    f->dlc = (uint8_t)DV_CAN_DLC;
    for (uint32_t i = 0u; i < 8u; i++) {
        f->data[i] = d[i];
    }
    return DV_OK;
}

dv_real_t dv_codec_sample_value(int16_t raw, float lsb)
{
    if (raw == DV_CODEC_RAW_MISSING) {
        return (dv_real_t)NAN;
    }
    return (dv_real_t)raw * (dv_real_t)lsb;
}

void dv_codec_sample_values(const int16_t *raw, const float *lsb, size_t n, dv_real_t *out)
{
    DV_ASSERT(n == 0u || (raw != NULL && lsb != NULL && out != NULL));
    for (size_t i = 0; i < n; i++) {
        out[i] = dv_codec_sample_value(raw[i], lsb[i]);
    }
}

int16_t dv_codec_sample_raw(dv_real_t x, float lsb)
{
    if (!dv_priv_finite(x) || !(lsb > 0.0f)) {
        return (int16_t)DV_CODEC_RAW_MISSING;
    }
    const dv_real_t v = x / (dv_real_t)lsb;
    if (!dv_priv_finite(v)) {
        return (int16_t)DV_CODEC_RAW_MISSING;
    }
    if (v >= DV_R(32766.5)) {
        return (int16_t)32767;
    }
    if (v <= DV_R(-32766.5)) {
        return (int16_t)-32767;
    }
    const dv_real_t r = v >= DV_R(0.0) ? DV_FLOOR(v + DV_R(0.5)) : -DV_FLOOR(-v + DV_R(0.5));
    return (int16_t)r;
}

dv_status_t dv_seq_init(dv_seq_t *s)
{
    if (s == NULL) {
        return DV_EINVAL;
    }
    dv_seq_reset(s);
    return DV_OK;
}

void dv_seq_reset(dv_seq_t *s)
{
    DV_ASSERT(s != NULL);
    s->seen = 0u;
    s->last = 0u;
    s->span = 0u;
    s->synced = false;
    s->n_ok = 0u;
    s->n_lost = 0u;
    s->n_dup = 0u;
    s->n_late = 0u;
    s->n_stale = 0u;
}

dv_seq_verdict_t dv_seq_update(dv_seq_t *s, uint8_t seq)
{
    DV_ASSERT(s != NULL);
    if (!s->synced) {
        s->synced = true;
        s->last = seq;
        s->seen = 1u;
        s->span = 1u;
        s->n_ok++;
        return DV_SEQ_OK;
    }
    const uint32_t ahead = ((uint32_t)seq - (uint32_t)s->last) & 0xFFu;
    if (ahead >= 1u && ahead <= 127u) {
        s->seen = ahead >= DV_SEQ_WINDOW ? 1u : ((s->seen << ahead) | 1u);
        s->span = s->span + ahead >= DV_SEQ_WINDOW ? DV_SEQ_WINDOW : s->span + ahead;
        s->last = seq;
        s->n_ok++;
        s->n_lost += ahead - 1u;
        return ahead == 1u ? DV_SEQ_OK : DV_SEQ_GAP;
    }
    const uint32_t behind = (256u - ahead) & 0xFFu; /* 0..128 */
    /* behind the window, or from before the first frame: nothing is known about it */
    if (behind >= s->span) {
        s->n_stale++;
        return DV_SEQ_STALE;
    }
    const uint64_t bit = (uint64_t)1u << behind;
    if ((s->seen & bit) != 0u) {
        s->n_dup++;
        return DV_SEQ_DUP;
    }
    s->seen |= bit;
    if (s->n_lost > 0u) {
        s->n_lost--;
    }
    s->n_late++;
    return DV_SEQ_LATE;
}

void dv_seq_track_n(dv_seq_t *s, int64_t *last, const uint8_t *chan, const uint8_t *seq,
                    size_t n, uint8_t *verdict, int64_t *frame_no)
{
    DV_ASSERT(s != NULL && last != NULL &&
              (n == 0u || (chan != NULL && seq != NULL && verdict != NULL && frame_no != NULL)));
    for (size_t i = 0; i < n; i++) {
        const uint8_t c = chan[i];
        const dv_seq_verdict_t v = dv_seq_update(&s[c], seq[i]);
        const int64_t prev = last[c];
        int64_t k;
        if (v == DV_SEQ_OK || v == DV_SEQ_GAP) {
            k = prev < 0 ? (int64_t)seq[i]
                         : prev + (int64_t)(((uint32_t)seq[i] - (uint32_t)prev) & 0xFFu);
            last[c] = k;
        } else {
            k = prev - (int64_t)(((uint32_t)prev - (uint32_t)seq[i]) & 0xFFu);
        }
        verdict[i] = (uint8_t)v;
        frame_no[i] = k;
    }
}

dv_status_t dv_seq_get(const dv_seq_t *s, dv_seq_counts_t *out)
{
    if (s == NULL || out == NULL) {
        return DV_EINVAL;
    }
    out->ok = s->n_ok;
    out->lost = s->n_lost;
    out->dup = s->n_dup;
    out->late = s->n_late;
    out->stale = s->n_stale;
    return DV_OK;
}

// Unit tests of the CAN codec and the sequence tracker. Expected bytes are written out by hand
// from the layout in can/dynval.dbc (little-endian, IEEE-754 binary32), not produced by the
// encoder under test.
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <string.h>

#include "dynval/dv_codec.h"

static dv_can_frame_t frame(uint32_t id, uint8_t dlc, const uint8_t *d)
{
    dv_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.dlc = dlc;
    memcpy(f.data, d, 8);
    return f;
}

static void assert_frame(const dv_can_frame_t *f, uint32_t id, const uint8_t *d)
{
    assert_int_equal(f->id, id);
    assert_int_equal(f->dlc, 8);
    assert_memory_equal(f->data, d, 8);
}

static void test_codec_samples_layout(void **state)
{
    (void)state;
    const uint8_t bytes[8] = {0x02, 0xFE, 0x01, 0x00, 0xFE, 0xFF, 0x00, 0x80};
    dv_msg_t m;
    memset(&m, 0, sizeof m);
    m.kind = DV_MSG_SAMPLES;
    m.u.samples.channel = 2;
    m.u.samples.seq = 0xFE;
    m.u.samples.raw[0] = 1;
    m.u.samples.raw[1] = -2;
    m.u.samples.raw[2] = -32768;
    dv_can_frame_t f;
    assert_int_equal(dv_codec_encode(&m, &f), DV_OK);
    assert_frame(&f, 0x200, bytes);

    dv_msg_t back;
    assert_int_equal(dv_codec_decode(&f, &back), DV_OK);
    assert_int_equal(back.kind, DV_MSG_SAMPLES);
    assert_int_equal(back.u.samples.channel, 2);
    assert_int_equal(back.u.samples.seq, 0xFE);
    assert_int_equal(back.u.samples.raw[0], 1);
    assert_int_equal(back.u.samples.raw[1], -2);
    assert_int_equal(back.u.samples.raw[2], -32768);
}

static void test_codec_feature_float_layout(void **state)
{
    (void)state;
    // 1.0f = 0x3F800000, -2.5f = 0xC0200000
    const uint8_t one[8] = {0x11, 0x04, 0x34, 0x12, 0x00, 0x00, 0x80, 0x3F};
    const uint8_t neg[8] = {0x07, 0x01, 0x00, 0x00, 0x00, 0x00, 0x20, 0xC0};
    dv_msg_t m;
    m.kind = DV_MSG_FEATURE;
    m.u.feature.feat_id = DV_FEAT_REC_STD;
    m.u.feature.channel = 4;
    m.u.feature.index = 0x1234;
    m.u.feature.value = 1.0f;
    dv_can_frame_t f;
    assert_int_equal(dv_codec_encode(&m, &f), DV_OK);
    assert_frame(&f, 0x300, one);

    dv_can_frame_t r = frame(0x380, 8, neg);
    dv_msg_t d;
    assert_int_equal(dv_codec_decode(&r, &d), DV_OK);
    assert_int_equal(d.kind, DV_MSG_RESID);
    assert_int_equal(d.u.resid.channel, 7);
    assert_int_equal(d.u.resid.flags, 1);
    assert_int_equal(d.u.resid.step, 0);
    assert_true(d.u.resid.value == -2.5f);
}

static void test_codec_ctrl_chcfg_status_layout(void **state)
{
    (void)state;
    // record_id 0xA1B2C3D4, lsb 2^-10 = 0x3A800000, fs 2560 = 0x0A00
    const uint8_t ctrl[8] = {0x01, 0x00, 0xD4, 0xC3, 0xB2, 0xA1, 0x00, 0x00};
    const uint8_t cfg[8] = {0x03, 0x01, 0x00, 0x0A, 0x00, 0x00, 0x80, 0x3A};
    const uint8_t st[8] = {0x05, 0x09, 0x02, 0x01, 0x03, 0x04, 0xFF, 0x06};
    dv_msg_t m;
    dv_can_frame_t f;

    m.kind = DV_MSG_CTRL;
    m.u.ctrl.cmd = DV_CTRL_START;
    m.u.ctrl.record_id = 0xA1B2C3D4u;
    assert_int_equal(dv_codec_encode(&m, &f), DV_OK);
    assert_frame(&f, 0x100, ctrl);

    m.kind = DV_MSG_CHCFG;
    m.u.chcfg.channel = 3;
    m.u.chcfg.flags = 1;
    m.u.chcfg.fs_hz = 2560;
    m.u.chcfg.lsb = 0.0009765625f;
    assert_int_equal(dv_codec_encode(&m, &f), DV_OK);
    assert_frame(&f, 0x101, cfg);

    dv_can_frame_t in = frame(0x080, 8, st);
    assert_int_equal(dv_codec_decode(&in, &m), DV_OK);
    assert_int_equal(m.kind, DV_MSG_STATUS);
    assert_int_equal(m.u.status.state, 5);
    assert_int_equal(m.u.status.beat, 9);
    assert_int_equal(m.u.status.lost, 0x0102);
    assert_int_equal(m.u.status.dup, 3);
    assert_int_equal(m.u.status.late, 4);
    assert_int_equal(m.u.status.bad_dlc, 255);
    assert_int_equal(m.u.status.unknown, 6);
    assert_int_equal(dv_codec_encode(&m, &f), DV_OK);
    assert_frame(&f, 0x080, st);
}

static void test_codec_bad_frames_are_rejected_untouched(void **state)
{
    (void)state;
    const uint8_t z[8] = {1, 0, 0, 0, 0, 0, 0, 0};
    dv_msg_t m;
    memset(&m, 0xA5, sizeof m);
    const dv_msg_t before = m;
    dv_can_frame_t f = frame(0x200, 7, z);
    assert_int_equal(dv_codec_decode(&f, &m), DV_ESIZE);
    f = frame(0x200, 0, z);
    assert_int_equal(dv_codec_decode(&f, &m), DV_ESIZE);
    f = frame(0x201, 8, z);
    assert_int_equal(dv_codec_decode(&f, &m), DV_ERANGE);
    f = frame(0x7FF, 3, z); // unknown id wins over a bad DLC
    assert_int_equal(dv_codec_decode(&f, &m), DV_ERANGE);
    f = frame(0x200u | DV_CAN_EFF_FLAG, 8, z);
    assert_int_equal(dv_codec_decode(&f, &m), DV_ERANGE);
    f = frame(0x200u | DV_CAN_RTR_FLAG, 8, z);
    assert_int_equal(dv_codec_decode(&f, &m), DV_ERANGE);
    f = frame(0x200, 9, z);
    assert_int_equal(dv_codec_decode(&f, &m), DV_EINVAL);
    assert_int_equal(dv_codec_decode(NULL, &m), DV_EINVAL);
    assert_int_equal(dv_codec_decode(&f, NULL), DV_EINVAL);
    const uint8_t badcmd[8] = {5, 0, 0, 0, 0, 0, 0, 0};
    f = frame(0x100, 8, badcmd);
    assert_int_equal(dv_codec_decode(&f, &m), DV_ERANGE);
    assert_memory_equal(&m, &before, sizeof m);
}

static void test_codec_chcfg_bad_scale(void **state)
{
    (void)state;
    // lsb: 0, -1.0f (0xBF800000), NaN (0x7FC00000), +Inf (0x7F800000); then fs 0
    const uint8_t lsbs[4][4] = {{0, 0, 0, 0}, {0, 0, 0x80, 0xBF}, {0, 0, 0xC0, 0x7F},
                                {0, 0, 0x80, 0x7F}};
    dv_msg_t m;
    for (int i = 0; i < 4; i++) {
        uint8_t d[8] = {0, 1, 0x80, 0x02, 0, 0, 0, 0};
        memcpy(d + 4, lsbs[i], 4);
        dv_can_frame_t f = frame(0x101, 8, d);
        assert_int_equal(dv_codec_decode(&f, &m), DV_ENUMERIC);
    }
    const uint8_t fs0[8] = {0, 1, 0, 0, 0, 0, 0x80, 0x3A};
    dv_can_frame_t f = frame(0x101, 8, fs0);
    assert_int_equal(dv_codec_decode(&f, &m), DV_ENUMERIC);
    dv_msg_t bad;
    bad.kind = (dv_msg_kind_t)99;
    assert_int_equal(dv_codec_encode(&bad, &f), DV_EINVAL);
}

static void test_codec_sample_scaling(void **state)
{
    (void)state;
    const float lsb = 0.0009765625f;
    assert_true(dv_codec_sample_value(1024, lsb) == DV_R(1.0));
    assert_true(dv_codec_sample_value(-3, 0.5f) == DV_R(-1.5));
    assert_true(isnan(dv_codec_sample_value(-32768, lsb)));
    assert_int_equal(dv_codec_sample_raw(DV_R(1.0), lsb), 1024);
    assert_int_equal(dv_codec_sample_raw(DV_R(0.25), 0.5f), 1);   // 0.5 rounds away from 0
    assert_int_equal(dv_codec_sample_raw(DV_R(-0.25), 0.5f), -1);
    assert_int_equal(dv_codec_sample_raw(DV_R(0.2), 0.5f), 0);
    assert_int_equal(dv_codec_sample_raw(DV_R(1e9), lsb), 32767); // clamped, never -32768
    assert_int_equal(dv_codec_sample_raw(DV_R(-1e9), lsb), -32767);
    assert_int_equal(dv_codec_sample_raw((dv_real_t)NAN, lsb), -32768);
    assert_int_equal(dv_codec_sample_raw((dv_real_t)INFINITY, lsb), -32768);
    // round trip of every representable count
    for (int r = -32767; r <= 32767; r += 7) {
        assert_int_equal(dv_codec_sample_raw(dv_codec_sample_value((int16_t)r, lsb), lsb), r);
    }
}

static void counts(const dv_seq_t *s, uint32_t ok, uint32_t lost, uint32_t dup, uint32_t late,
                   uint32_t stale)
{
    dv_seq_counts_t c;
    assert_int_equal(dv_seq_get(s, &c), DV_OK);
    assert_int_equal(c.ok, ok);
    assert_int_equal(c.lost, lost);
    assert_int_equal(c.dup, dup);
    assert_int_equal(c.late, late);
    assert_int_equal(c.stale, stale);
}

static void test_codec_seq_in_order_wraps(void **state)
{
    (void)state;
    dv_seq_t s;
    assert_int_equal(dv_seq_init(&s), DV_OK);
    assert_int_equal(dv_seq_init(NULL), DV_EINVAL);
    for (int i = 0; i < 600; i++) {
        assert_int_equal(dv_seq_update(&s, (uint8_t)(i + 250)), DV_SEQ_OK);
    }
    counts(&s, 600, 0, 0, 0, 0);
}

static void test_codec_seq_gap_dup_late(void **state)
{
    (void)state;
    dv_seq_t s;
    dv_seq_init(&s);
    assert_int_equal(dv_seq_update(&s, 10), DV_SEQ_OK);
    assert_int_equal(dv_seq_update(&s, 11), DV_SEQ_OK);
    assert_int_equal(dv_seq_update(&s, 11), DV_SEQ_DUP);
    assert_int_equal(dv_seq_update(&s, 14), DV_SEQ_GAP); // 12, 13 missing
    counts(&s, 3, 2, 1, 0, 0);
    assert_int_equal(dv_seq_update(&s, 12), DV_SEQ_LATE);
    counts(&s, 3, 1, 1, 1, 0);
    assert_int_equal(dv_seq_update(&s, 12), DV_SEQ_DUP); // late frame seen twice
    assert_int_equal(dv_seq_update(&s, 10), DV_SEQ_DUP);
    assert_int_equal(dv_seq_update(&s, 9), DV_SEQ_STALE); // before the first frame
    counts(&s, 3, 1, 3, 1, 1);
    // the largest forward jump accepted is 127 (14 + 127 = 141)
    assert_int_equal(dv_seq_update(&s, 141), DV_SEQ_GAP); // 126 lost
    counts(&s, 4, 127, 3, 1, 1);
    assert_int_equal(dv_seq_update(&s, 141 - 70), DV_SEQ_STALE); // outside the 64 window
    assert_int_equal(dv_seq_update(&s, 141 - 63), DV_SEQ_LATE);
    counts(&s, 4, 126, 3, 2, 2);
}

// Property: a stream damaged by known drops, duplicates and adjacent swaps (never touching the
// same frame twice) gives exactly those counts.
static void test_codec_seq_counts_match_injection(void **state)
{
    (void)state;
    uint32_t lcg = 12345u;
    dv_seq_t s;
    dv_seq_init(&s);
    uint32_t drops = 0, dups = 0, swaps = 0, sent = 0;
    uint32_t i = 0;
    assert_int_equal(dv_seq_update(&s, 0), DV_SEQ_OK);
    sent++;
    i = 1;
    while (i < 20000u) {
        lcg = lcg * 1103515245u + 12345u;
        uint32_t r = (lcg >> 16) % 100u;
        if (r < 3u && i + 3u < 20000u) { // drop frame i
            drops++;
            assert_int_not_equal(dv_seq_update(&s, (uint8_t)(i + 1u)), DV_SEQ_LATE);
            sent++;
            i += 2u;
        } else if (r < 6u) { // duplicate frame i
            dv_seq_update(&s, (uint8_t)i);
            assert_int_equal(dv_seq_update(&s, (uint8_t)i), DV_SEQ_DUP);
            dups++;
            sent++;
            i += 1u;
        } else if (r < 9u && i + 2u < 20000u) { // swap i and i+1
            assert_int_equal(dv_seq_update(&s, (uint8_t)(i + 1u)), DV_SEQ_GAP);
            assert_int_equal(dv_seq_update(&s, (uint8_t)i), DV_SEQ_LATE);
            swaps++;
            sent++;
            i += 2u;
        } else {
            assert_int_equal(dv_seq_update(&s, (uint8_t)i), DV_SEQ_OK);
            sent++;
            i += 1u;
        }
    }
    assert_true(drops > 100 && dups > 100 && swaps > 100);
    counts(&s, sent, drops, dups, swaps, 0);
}

// The block functions are the single-frame ones applied in order: a mixed block (samples,
// feature, an unknown id, a short frame, a bad DV_CHCFG) decodes to the same messages and
// statuses; untouched outputs stay untouched; sequence verdicts over a block with a gap, a
// duplicate and a late frame equal frame-by-frame ones, and so do the tracker's counters;
// frame numbers unwrap the counter per channel.
static void test_codec_block_functions_equal_single_calls(void **state)
{
    (void)state;
    const uint8_t smp[8] = {0x01, 0x07, 0x10, 0x00, 0xF0, 0xFF, 0x00, 0x80};
    const uint8_t fea[8] = {0x12, 0x01, 0x05, 0x00, 0x00, 0x00, 0x80, 0x3F};
    const uint8_t cfg_bad[8] = {0x00, 0x01, 0x00, 0x0A, 0x00, 0x00, 0x00, 0x00}; /* lsb 0 */
    dv_can_frame_t f[5] = {frame(0x200, 8, smp), frame(0x300, 8, fea), frame(0x123, 8, smp),
                           frame(0x200, 6, smp), frame(0x101, 8, cfg_bad)};
    dv_msg_t out[5];
    dv_status_t st[5];
    memset(out, 0xAB, sizeof out);
    assert_int_equal(dv_codec_decode_n(f, 5, out, st), 2);
    const dv_status_t want[5] = {DV_OK, DV_OK, DV_ERANGE, DV_ESIZE, DV_ENUMERIC};
    for (size_t i = 0; i < 5; i++) {
        dv_msg_t one;
        memset(&one, 0xAB, sizeof one);
        assert_int_equal(st[i], want[i]);
        assert_int_equal(dv_codec_decode(&f[i], &one), want[i]);
        assert_memory_equal(&out[i], &one, sizeof one);
    }
    assert_int_equal(out[0].u.samples.raw[0], 16);
    assert_int_equal(out[0].u.samples.raw[1], -16);
    assert_int_equal(out[0].u.samples.raw[2], DV_CODEC_RAW_MISSING);
    assert_true(out[1].u.feature.value == 1.0f);
    assert_int_equal(dv_codec_decode_n(NULL, 5, out, st), 0);

    const int16_t raw[4] = {3, -32768, -4, 32767};
    const float lsb[4] = {0.25f, 0.25f, 0.5f, 0.25f};
    dv_real_t v[4];
    dv_codec_sample_values(raw, lsb, 4, v);
    assert_true(v[0] == 0.75 && isnan(v[1]) && v[2] == -2.0 && v[3] == 8191.75);

    /* channel 1: a gap (252 lost), a duplicate, the late 252, the counter wrapping past 255;
       channel 0 interleaved, in order from 7 */
    const uint8_t chan[10] = {1, 1, 0, 1, 1, 0, 1, 1, 1, 1};
    const uint8_t seq[10] = {250, 251, 7, 253, 253, 8, 252, 254, 255, 0};
    const uint8_t want_v[10] = {DV_SEQ_OK, DV_SEQ_OK, DV_SEQ_OK, DV_SEQ_GAP, DV_SEQ_DUP,
                                DV_SEQ_OK, DV_SEQ_LATE, DV_SEQ_OK, DV_SEQ_OK, DV_SEQ_OK};
    const int64_t want_k[10] = {250, 251, 7, 253, 253, 8, 252, 254, 255, 256};
    uint8_t verdict[10];
    int64_t k[10];
    int64_t last[2] = {-1, -1};
    dv_seq_t a[2], b;
    dv_seq_init(&a[0]);
    dv_seq_init(&a[1]);
    dv_seq_init(&b);
    dv_seq_track_n(a, last, chan, seq, 10, verdict, k);
    for (size_t i = 0; i < 10; i++) {
        assert_int_equal(verdict[i], want_v[i]);
        assert_int_equal(k[i], want_k[i]);
        if (chan[i] == 1) {
            assert_int_equal(dv_seq_update(&b, seq[i]), want_v[i]);
        }
    }
    assert_int_equal(last[0], 8);
    assert_int_equal(last[1], 256);
    dv_seq_counts_t ca, cb;
    dv_seq_get(&a[1], &ca);
    dv_seq_get(&b, &cb);
    assert_memory_equal(&ca, &cb, sizeof ca);
    assert_int_equal(ca.ok, 6);
    assert_int_equal(ca.lost, 0);
    assert_int_equal(ca.dup, 1);
    assert_int_equal(ca.late, 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_codec_samples_layout),
        cmocka_unit_test(test_codec_block_functions_equal_single_calls),
        cmocka_unit_test(test_codec_feature_float_layout),
        cmocka_unit_test(test_codec_ctrl_chcfg_status_layout),
        cmocka_unit_test(test_codec_bad_frames_are_rejected_untouched),
        cmocka_unit_test(test_codec_chcfg_bad_scale),
        cmocka_unit_test(test_codec_sample_scaling),
        cmocka_unit_test(test_codec_seq_in_order_wraps),
        cmocka_unit_test(test_codec_seq_gap_dup_late),
        cmocka_unit_test(test_codec_seq_counts_match_injection),
    };
    return cmocka_run_group_tests_name("dv_codec", tests, NULL, NULL);
}

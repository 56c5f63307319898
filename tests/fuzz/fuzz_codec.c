/* libFuzzer target for the CAN frame decoder and the sequence tracker.
 * Input: a stream of 13-byte records {id u32 LE, dlc u8, data[8]}. Every record is decoded;
 * a decoded message must re-encode to a frame that decodes to the same message, and the
 * tracker's counters must add up. Built and run by tests/fuzz/run_fuzz.sh. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "dynval/dv_codec.h"

#define CHECK(c)                                                                                  \
    do {                                                                                          \
        if (!(c)) {                                                                               \
            __builtin_trap();                                                                     \
        }                                                                                         \
    } while (0)

static int same_msg(const dv_msg_t *a, const dv_msg_t *b)
{
    dv_can_frame_t fa, fb;
    /* compare through the wire form: union padding and floats (NaN) compare as bytes */
    if (a->kind != b->kind || dv_codec_encode(a, &fa) != DV_OK || dv_codec_encode(b, &fb) != DV_OK) {
        return 0;
    }
    return fa.id == fb.id && fa.dlc == fb.dlc && memcmp(fa.data, fb.data, 8) == 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *in, size_t n)
{
    dv_seq_t seq[4];
    uint32_t n_samples[4] = {0, 0, 0, 0};
    for (int c = 0; c < 4; c++) {
        CHECK(dv_seq_init(&seq[c]) == DV_OK);
    }
    for (size_t off = 0; off + 13u <= n; off += 13u) {
        dv_can_frame_t f;
        f.id = (uint32_t)in[off] | ((uint32_t)in[off + 1] << 8) | ((uint32_t)in[off + 2] << 16) |
               ((uint32_t)in[off + 3] << 24);
        /* bias towards our ids so the fuzzer reaches the payload decoders */
        if ((in[off + 3] & 0x80u) == 0u) {
            static const uint32_t ids[8] = {0x080, 0x100, 0x101, 0x200, 0x300, 0x380, 0x200, 0x7FF};
            f.id = ids[in[off] & 7u];
        }
        f.dlc = in[off + 4];
        memcpy(f.data, in + off + 5, 8);
        dv_msg_t m;
        memset(&m, 0, sizeof m);
        const dv_status_t st = dv_codec_decode(&f, &m);
        CHECK(st == DV_OK || st == DV_ERANGE || st == DV_ESIZE || st == DV_ENUMERIC ||
              st == DV_EINVAL);
        if (st != DV_OK) {
            continue;
        }
        dv_can_frame_t g;
        CHECK(dv_codec_encode(&m, &g) == DV_OK);
        CHECK(g.id == f.id && g.dlc == 8u);
        dv_msg_t m2;
        memset(&m2, 0, sizeof m2);
        CHECK(dv_codec_decode(&g, &m2) == DV_OK);
        CHECK(same_msg(&m, &m2));
        if (m.kind == DV_MSG_SAMPLES) {
            const unsigned c = m.u.samples.channel & 3u;
            const dv_seq_verdict_t v = dv_seq_update(&seq[c], m.u.samples.seq);
            CHECK(v <= DV_SEQ_STALE);
            n_samples[c]++;
            for (unsigned i = 0; i < DV_CODEC_SAMPLES_PER_FRAME; i++) {
                const dv_real_t x = dv_codec_sample_value(m.u.samples.raw[i], 0.001f);
                CHECK(m.u.samples.raw[i] == DV_CODEC_RAW_MISSING ||
                      dv_codec_sample_raw(x, 0.001f) == m.u.samples.raw[i]);
            }
        }
    }
    for (int c = 0; c < 4; c++) {
        dv_seq_counts_t k;
        CHECK(dv_seq_get(&seq[c], &k) == DV_OK);
        CHECK(k.ok + k.dup + k.late + k.stale == n_samples[c]);
    }
    return 0;
}

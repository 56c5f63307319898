/* libFuzzer target for firmware_sim's loop without sockets (firmware_sim/sim_core.c): any frame
 * sequence must be handled without a crash, out-of-bounds access or undefined behaviour, with
 * every stage on (features on short records, AR order 2, the LANL 4-DOF observer) and the
 * counters consistent. Input: 13-byte records {id u32 LE, dlc u8, data[8]}, ids biased towards
 * the dynval set. The finiteness oracle: every feature and residual value sent is finite
 * (a DV_CHCFG may set any lsb, the samples are any counts). Built and run by
 * tests/fuzz/run_fuzz.sh. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sim_core.h"

#define CHECK(c)                                                                                  \
    do {                                                                                          \
        if (!(c)) {                                                                               \
            __builtin_trap();                                                                     \
        }                                                                                         \
    } while (0)

static struct sim_core g_core; /* built once: the observer's DARE solve is slow */
static dv_can_frame_t g_out[SIM_CORE_MAX_OUT];

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    struct sim_config cfg;
    sim_config_default(&cfg);
    cfg.win_len = 4;
    cfg.seg_len = 4;
    cfg.n_seg = 3;
    cfg.ar_order = 2;
    cfg.outlier_x100 = 200;
    cfg.heartbeat_ms = 0;
    static const float m[28] = {4, 6.54f, 6.66f, 6.86f, 6.8f, 0, 0, 0, 0, 10, 399790, 399790,
                                399790, 0, 0, 0, 0, 0.01f, 0.05f, 0.01f, 0.01f, 0, 0, 0, 0,
                                1.0f, 0.04f, 0};
    memcpy(cfg.model, m, sizeof m);
    if (sim_core_init(&g_core, &cfg) != 0 || g_core.obs_status != SIM_STAGE_RUNNING) {
        abort();
    }
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *in, size_t n)
{
    static const uint32_t ids[8] = {0x200, 0x200, 0x200, 0x200, 0x100, 0x101, 0x300, 0x7FF};
    dv_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = 0x100;
    f.dlc = 8;
    f.data[0] = DV_CTRL_START; /* every input starts a fresh record */
    (void)sim_core_handle(&g_core, &f, g_out);
    for (size_t off = 0; off + 13u <= n; off += 13u) {
        f.id = (uint32_t)in[off] | ((uint32_t)in[off + 1] << 8) | ((uint32_t)in[off + 2] << 16) |
               ((uint32_t)in[off + 3] << 24);
        if ((in[off + 3] & 0x80u) == 0u) {
            f.id = ids[in[off] & 7u];
        }
        f.dlc = in[off + 4];
        memcpy(f.data, in + off + 5, 8);
        if (f.id == 0x200 && (in[off + 1] & 1u) == 0u) {
            f.data[0] &= 7u; /* mostly valid channels */
        }
        const size_t k = sim_core_handle(&g_core, &f, g_out);
        CHECK(k <= SIM_CORE_MAX_OUT);
        for (size_t i = 0; i < k; i++) {
            dv_msg_t m;
            CHECK(dv_codec_decode(&g_out[i], &m) == DV_OK); /* we only send valid frames */
            CHECK(m.kind != DV_MSG_FEATURE || isfinite(m.u.feature.value));
            CHECK(m.kind != DV_MSG_RESID || isfinite(m.u.resid.value));
        }
    }
    uint16_t ir[SIM_N_INPUT];
    sim_core_input_regs(&g_core, ir);
    CHECK(ir[SIM_IR_VERSION] == SIM_REGMAP_VERSION);
    return 0;
}

/* What the firmware loop's own files share and nothing else sees: the observer stage
 * (sim_obs_stage.c, called by sim_core.c) and the 32-bit register words (big-endian word
 * order, as sim_regmap.h documents) that the input registers (sim_core.c) and the holding
 * registers (sim_config.c) are written in. */
#ifndef SIM_PRIV_H
#define SIM_PRIV_H

#include <string.h>

#include "sim_core.h"

/* Observer stage: (re)build model and observer from c->cfg (c->obs_status says how it went);
 * release; restart at START (a built observer is kept); one sample of channel @p ch, or
 * @p lost frames of NaN placeholders after a sequence gap. Residual frames go to out[*n..]. */
void sim_obs_setup(struct sim_core *c);
void sim_obs_free(struct sim_obs *o);
void sim_obs_restart(struct sim_obs *o);
void sim_obs_stage(struct sim_core *c, unsigned ch, dv_real_t x, dv_can_frame_t *out,
                   size_t *n);
void sim_obs_stage_gap(struct sim_core *c, unsigned ch, uint32_t lost, dv_can_frame_t *out,
                       size_t *n);

static inline void sim_put_u32(uint16_t *reg, int addr, uint32_t v)
{
    reg[addr] = (uint16_t)(v >> 16);
    reg[addr + 1] = (uint16_t)(v & 0xFFFFu);
}

static inline void sim_put_f32(uint16_t *reg, int addr, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    sim_put_u32(reg, addr, u);
}

static inline float sim_get_f32(const uint16_t *reg, int addr)
{
    const uint32_t u = ((uint32_t)reg[addr] << 16) | reg[addr + 1];
    float f;
    memcpy(&f, &u, 4);
    return f;
}

#endif /* SIM_PRIV_H */

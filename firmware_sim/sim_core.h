/* The firmware loop without sockets: one CAN frame in, the frames to send out.
 * sim_main.c drives it from SocketCAN and Modbus; tests and the Python gateway can drive it
 * in-process (it is also built as the shared library libdv_simcore). All state is in
 * struct sim_core; the only heap use is the channel buffers, allocated on (re)configuration. */
#ifndef SIM_CORE_H
#define SIM_CORE_H

#include <stddef.h>
#include <stdint.h>

#include "dynval/dv.h"
#include "sim_regmap.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Room for the frames one input frame can produce: 3 samples x (segment: 1 + 4 window
 * frames, record: 16 record/temporal + 2 AR frames), plus the observer residuals of every
 * step the frame completes: up to 3 x 127 steps after a gap (NaN placeholders), 7 residual
 * frames each. Frames beyond it are counted in tx_errors, never written out of bounds. */
#define SIM_CORE_MAX_OUT 3072

/* Samples one channel may run ahead of the slowest observer channel before its oldest are
 * discarded (counted in obs.overrun). */
#define SIM_OBS_QCAP 4096

struct sim_config {
    uint16_t n_chan;       /* 1..SIM_MAX_CHAN */
    uint16_t win_len;      /* sliding window, samples */
    uint16_t seg_len;      /* samples per segment */
    uint16_t n_seg;        /* segments per record */
    uint16_t ar_order;     /* 0 = AR stage off */
    uint16_t outlier_x100; /* outlier threshold, sigma x 100 */
    uint16_t resid_decim;  /* residual frame every N observer steps, 0 = none */
    uint16_t force_chan;   /* observer input channel */
    uint16_t heartbeat_ms; /* DV_STATUS period, 0 = off */
    uint16_t recording;    /* 1 = accept samples */
    uint16_t fs_hz[SIM_MAX_CHAN]; /* sample rate per channel */
    float lsb[SIM_MAX_CHAN];      /* units per count per channel */
    float model[SIM_N_MODEL];     /* observer model parameters */
};

struct sim_counters {
    uint32_t rx_frames, tx_frames, dropped, bad_dlc, unknown_id, bad_chan, ignored, bad_cfg;
    uint32_t samples, tx_errors, cfg_writes;
    uint32_t nonfinite; /* results not sent because non-finite as float32 (SIM_IR_NONFINITE) */
};

#ifndef DV_CDEF /* the Python binding's cdef (CMakeLists.txt) sees struct sim_core opaque */
/* The latest features of one channel, as floats (the wire type). NaN = not yet computed. */
struct sim_latest {
    float seg_std, win_mean, win_std, win_rms, win_peak;
    float rec_mean, rec_std, rec_rms, rec_skew, rec_kurt, rec_peak, rec_crest;
    float tm_energy, tm_ctime, tm_rmsdur, ar_resid, obs_resid;
};

/* AR stage of one channel: the first complete record after configuration is the baseline
 * the AR(p) model is fitted to (Burg); later records get its one-step residual. */
struct sim_ar {
    int phase;             /* 0 collecting the baseline, 1 fitted, -1 fit failed */
    dv_real_t *rec;        /* baseline record (heap), seg_len * n_seg samples */
    uint32_t n;            /* samples in rec */
    dv_ar_model_t model;   /* fitted model */
    dv_ar_resid_t res;     /* streaming residual */
    dv_real_t hist[DV_AR_RESID_BUF_LEN(DV_AR_MAX_ORDER)]; /* residual coefficients + history */
    dv_moments_t mom;      /* residuals of the open record */
    uint32_t outliers;     /* |e| > k sigma in the open record */
    uint32_t last_outliers; /* in the last complete record */
};

/* Observer stage: one step per time index across the force channel and the measured ones. */
struct sim_obs {
    int on;                 /* model and observer built */
    dv_model_t model;
    dv_obs_t obs;
    dv_real_t *mbuf, *obuf; /* model and observer storage (heap) */
    uint16_t n_out;         /* measured channels = model outputs */
    uint16_t meas_ch[DV_MAX_OUT]; /* channel of output j */
    dv_real_t *q[SIM_MAX_CHAN]; /* per-channel sample queues (heap, SIM_OBS_QCAP) */
    uint32_t qh[SIM_MAX_CHAN], qn[SIM_MAX_CHAN]; /* queue heads and fill */
    uint32_t steps;         /* steps since the last START */
    uint32_t pend_step;     /* cubic hold: step of the sample the observer still holds */
    uint32_t overrun;       /* samples discarded from full queues */
};

struct sim_chan {
    dv_chan_t feat;        /* features */
    dv_real_t *buf;        /* DV_CHAN_BUF_LEN(win_len, n_seg) elements (heap) */
    dv_seq_t seq;          /* sequence tracking of DV_SAMPLES.seq since the last START */
    dv_seq_counts_t seq_base; /* counts of earlier trackers (folded in at START) */
    int enabled;           /* DV_CHCFG flags bit 0 */
    uint32_t segments;     /* segments completed since the last (re)start */
    uint32_t records;      /* records completed since the last (re)start */
    uint32_t nan_base;     /* NaN count of earlier feature instances (kept across re-init) */
    uint32_t samples;      /* samples accepted */
    struct sim_latest last;
    struct sim_ar ar;      /* AR stage */
};

struct sim_core {
    struct sim_config cfg;
    struct sim_chan ch[SIM_MAX_CHAN];
    struct sim_counters n;
    struct sim_obs obs;
    int obs_status;       /* SIM_STAGE_* */
    int ar_status;        /* SIM_STAGE_* */
    uint8_t beat;         /* heartbeat counter */
    uint8_t overflowed;   /* the receive queue overflowed at least once */
    uint64_t next_beat_ns; /* time of the next heartbeat */
};
#else
struct sim_core;
#endif

/* Defaults: 5 channels, window 256, 64 x 64 records, 640 Hz, lsb 2^-10, heartbeat 1 s. */
void sim_config_default(struct sim_config *cfg);

/* -1 if @p cfg is acceptable, else the holding register address of the first bad value. */
int sim_config_check(const struct sim_config *cfg);

/* Set up (allocates the channel buffers). 0 on success, -1 on a bad config or no memory. */
int sim_core_init(struct sim_core *c, const struct sim_config *cfg);

/* Apply a new configuration: channels re-initialised, counters and sequence tracking kept.
 * On failure the old configuration stays. 0 / -1. */
int sim_core_configure(struct sim_core *c, const struct sim_config *cfg);

void sim_core_free(struct sim_core *c);

/* For bindings (ctypes/cffi) that should not depend on the struct layout: a heap instance,
 * with the defaults when @p cfg is NULL. NULL on a bad config or no memory. */
struct sim_core *sim_core_new(const struct sim_config *cfg);
void sim_core_delete(struct sim_core *c);

/* The counter (its input register: SIM_IR_BAD_DLC, SIM_IR_BAD_CFG or SIM_IR_UNKNOWN_ID) of a
 * frame dv_codec_decode() refused with @p st (< 0): the one table of refusal names, which the
 * gateway's logger also uses for its events. */
int sim_refused_counter(dv_status_t st);

/* Handle one received frame; writes up to SIM_CORE_MAX_OUT frames to @p out and returns how
 * many. Never fails: bad frames are counted. */
size_t sim_core_handle(struct sim_core *c, const dv_can_frame_t *in, dv_can_frame_t *out);

/* Heartbeat: returns 1 and a DV_STATUS frame in @p out when one is due at @p now_ns. */
size_t sim_core_tick(struct sim_core *c, uint64_t now_ns, dv_can_frame_t *out);

/* The DV_STATUS frame for the current counters. */
void sim_core_status_frame(struct sim_core *c, dv_can_frame_t *out);

/* Fill input registers 0..SIM_N_INPUT-1 from the state. */
void sim_core_input_regs(const struct sim_core *c, uint16_t *ir);

/* Holding registers <-> configuration. */
void sim_config_to_regs(const struct sim_config *cfg, uint16_t *hr);
void sim_config_from_regs(struct sim_config *cfg, const uint16_t *hr);

#ifdef __cplusplus
}
#endif

#endif /* SIM_CORE_H */

/* firmware_sim Modbus register map: the one place it is defined (the table in README.md is
 * the same map in prose; the Python gateway reads it from the build's macro dump of
 * sim_core.h, dynval.contract, and never restates a number).
 *
 * Conventions: unit id ignored (TCP), register addresses are 0-based protocol addresses.
 * 32-bit values take two registers, high word first (the common "big-endian word order");
 * floats are IEEE-754 binary32 in that layout. Counters are uint32 and wrap.
 * Input registers (function 0x04) are read-only results; holding registers (0x03, 0x06,
 * 0x10, 0x16 mask write, 0x17) are configuration; a write takes effect at once and
 * re-initialises every channel's features (sequence tracking and counters are kept). A write
 * with a value out of range is refused with exception 0x03 (illegal data value), a write to a
 * holding register that is not below (4, 11..39, 56..59, 68..99) with exception 0x02; either
 * changes nothing. Coils and discrete inputs do not exist (exception 0x02).
 */
#ifndef SIM_REGMAP_H
#define SIM_REGMAP_H

#define SIM_REGMAP_VERSION 1

#define SIM_MAX_CHAN 8 /* channels a node serves; DV_SAMPLES.channel >= n_chan is counted */
#define SIM_N_MODEL 32 /* model parameters (float32) of the observer stage, see SIM_MODEL_* */

/* ---- input registers (read-only) ---------------------------------------------------------- */
#define SIM_IR_VERSION 0   /* SIM_REGMAP_VERSION */
#define SIM_IR_STATE 1     /* DV_STATE_* bits of dv_codec.h (recording, obs on, ar on, overflow) */
#define SIM_IR_N_CHAN 2    /* channels in use */
#define SIM_IR_OBS_STATUS 3 /* SIM_STAGE_* of the observer stage */
#define SIM_IR_AR_STATUS 4  /* SIM_STAGE_* of the AR stage */
#define SIM_IR_REAL_SIZE 5  /* sizeof(dv_real_t) of the linked library: 4 or 8 */

/* global counters, uint32 (2 registers each) */
#define SIM_IR_RX_FRAMES 10   /* frames read from the bus */
#define SIM_IR_TX_FRAMES 12   /* frames written to the bus */
#define SIM_IR_DROPPED 14     /* frames the kernel dropped on a full receive queue */
#define SIM_IR_LOST 16        /* sample frames missing by sequence (gaps not filled later) */
#define SIM_IR_DUP 18         /* duplicate sample frames discarded */
#define SIM_IR_LATE 20        /* late (reordered) sample frames discarded */
#define SIM_IR_STALE 22       /* sample frames too far behind to classify, discarded */
#define SIM_IR_BAD_DLC 24     /* frames with a dynval id and DLC != 8 */
#define SIM_IR_UNKNOWN_ID 26  /* frames with an id the node does not consume */
#define SIM_IR_NAN_SAMPLES 28 /* missing samples (raw -32768) dropped by the features */
#define SIM_IR_BAD_CHAN 30    /* sample frames for a channel >= n_chan */
#define SIM_IR_IGNORED 32     /* sample frames received while not recording */
#define SIM_IR_BAD_CFG 34     /* DV_CHCFG/DV_CTRL frames refused (bad value or channel) */
#define SIM_IR_SAMPLES 36     /* samples fed to the features, all channels */
#define SIM_IR_TX_ERRORS 38   /* frames that could not be written */
#define SIM_IR_CFG_WRITES 40  /* configuration changes applied (Modbus or DV_CHCFG) */
#define SIM_IR_OBS_STEPS 42   /* observer steps taken since the last START */
#define SIM_IR_OBS_OVERRUN 44 /* observer input samples discarded (a channel stalled) */
#define SIM_IR_NONFINITE 46   /* results not sent: non-finite as float32 (never on the bus) */

/* per-channel block: SIM_IR_CH(ch) + offset, ch < SIM_MAX_CHAN */
#define SIM_IR_CH_BASE 100
#define SIM_IR_CH_STRIDE 50
#define SIM_IR_CH(ch) (SIM_IR_CH_BASE + SIM_IR_CH_STRIDE * (ch))
#define SIM_IR_CH_LOST 0        /* u32 sequence gaps of this channel */
#define SIM_IR_CH_DUP 2         /* u32 */
#define SIM_IR_CH_LATE 4        /* u32 */
#define SIM_IR_CH_NAN 6         /* u32 missing samples dropped */
#define SIM_IR_CH_SAMPLES 8     /* u32 samples accepted */
#define SIM_IR_CH_SEGMENTS 10   /* u32 segments completed */
#define SIM_IR_CH_RECORDS 12    /* u32 records completed */
#define SIM_IR_CH_SEG_STD 14    /* f32 STD of the last segment */
#define SIM_IR_CH_WIN_MEAN 16   /* f32 sliding-window mean at the last segment end */
#define SIM_IR_CH_WIN_STD 18    /* f32 */
#define SIM_IR_CH_WIN_RMS 20    /* f32 */
#define SIM_IR_CH_WIN_PEAK 22   /* f32 */
#define SIM_IR_CH_REC_MEAN 24   /* f32 last complete record */
#define SIM_IR_CH_REC_STD 26    /* f32 */
#define SIM_IR_CH_REC_RMS 28    /* f32 */
#define SIM_IR_CH_REC_SKEW 30   /* f32 */
#define SIM_IR_CH_REC_KURT 32   /* f32 */
#define SIM_IR_CH_REC_PEAK 34   /* f32 */
#define SIM_IR_CH_REC_CREST 36  /* f32 */
#define SIM_IR_CH_TM_ENERGY 38  /* f32 temporal moment E */
#define SIM_IR_CH_TM_CTIME 40   /* f32 central time T, s */
#define SIM_IR_CH_TM_RMSDUR 42  /* f32 RMS duration D, s */
#define SIM_IR_CH_AR_RESID 44   /* f32 RMS of the AR residual over the last record */
#define SIM_IR_CH_OBS_RESID 46  /* f32 last observer residual (measured channels) */
#define SIM_IR_CH_AR_OUTLIERS 48 /* u32 AR residual outliers in the last record */
/* features not yet computed read as NaN (0x7FC0 0x0000) */
#define SIM_N_INPUT (SIM_IR_CH_BASE + SIM_IR_CH_STRIDE * SIM_MAX_CHAN)

/* SIM_IR_OBS_STATUS / SIM_IR_AR_STATUS */
#define SIM_STAGE_NOT_CONFIGURED 0 /* not configured (or not built into this firmware) */
#define SIM_STAGE_RUNNING 1        /* configured and updating */
#define SIM_STAGE_ERROR 2          /* configured, last update failed (e.g. unstable model) */

/* ---- holding registers (read/write configuration) ----------------------------------------- */
#define SIM_HR_N_CHAN 0       /* channels in use, 1..SIM_MAX_CHAN (default 5) */
#define SIM_HR_WIN_LEN 1      /* sliding window, samples, 2..65535 (default 256) */
#define SIM_HR_SEG_LEN 2      /* segment, samples, 2..65535 (default 64) */
#define SIM_HR_N_SEG 3        /* segments per record, 1..4096 (default 64) */
/* 4: reserved (sample rates are per channel, SIM_HR_FS_CH) */
#define SIM_HR_AR_ORDER 5     /* AR order, 0 (off)..32 (default 0) */
#define SIM_HR_OUTLIER_X100 6 /* outlier threshold, sigma x 100, 0 (off)..65535 (default 600) */
#define SIM_HR_RESID_DECIM 7  /* send one residual frame every N observer steps, 0 = none (1) */
#define SIM_HR_FORCE_CHAN 8   /* input (force) channel of the observer, < n_chan (default 0) */
#define SIM_HR_HEARTBEAT_MS 9 /* DV_STATUS period, ms, 0 = off (default 1000) */
#define SIM_HR_RECORDING 10   /* 1 = accept samples, 0 = ignore them (default 1) */
#define SIM_HR_LSB 40         /* f32 lsb of channel ch (units/count): SIM_HR_LSB + 2 ch,
                               * 0 < lsb <= SIM_LSB_MAX */
#define SIM_HR_FS_CH 60       /* u16 sample rate of channel ch, Hz: SIM_HR_FS_CH + ch, 1..65535 */
#define SIM_HR_MODEL 100      /* SIM_N_MODEL f32 model parameters: SIM_HR_MODEL + 2 i */
#define SIM_N_HOLDING (SIM_HR_MODEL + 2 * SIM_N_MODEL)

/* Largest lsb (units/count) a channel accepts (Modbus exception 3, DV_CHCFG counted in BAD_CFG):
 * 2^24 / 32768, so that every count is a sample the features take (DV_FEAT_MAX of a float build,
 * 2^24) and every feature of a record fits a float32 frame. */
#define SIM_LSB_MAX 512.0f

/* Model parameter i (f32 at SIM_HR_MODEL + 2 i): a lumped-mass chain, modal damping, force
 * input, the measured (non-force) channels in order = accelerations of DOF 0, 1, ...
 * Observer off while n_dof is 0. Any write re-builds the model and the observer. */
#define SIM_MODEL_N_DOF 0   /* 0 (off) or 1..8, integral */
#define SIM_MODEL_MASS 1    /* 1..8: mass of DOF i, kg, > 0 */
#define SIM_MODEL_K 9       /* 9..16: k[0] ground-DOF0, k[i] DOF i-1..i, N/m, >= 0 */
#define SIM_MODEL_ZETA 17   /* 17..24: modal damping ratio of mode i (ascending), >= 0 */
#define SIM_MODEL_Q 25      /* white force variance at each DOF, N^2, >= 0; 0 = open loop */
#define SIM_MODEL_R 26      /* measurement noise variance per channel, > 0 when Q > 0 */
#define SIM_MODEL_INPUT_DOF 27 /* DOF the force channel loads, < n_dof, integral */
#define SIM_MODEL_HOLD 28   /* input hold: 0 first-order (linear), 1 cubic (DV_HOLD_CUBIC, one
                             * sample of latency: the residual frame of sample k leaves with
                             * sample k + 1, labelled k). Power-on default 1; a model list that
                             * does not set it (-m, a whole-block write) leaves 0 = first-order */

#endif /* SIM_REGMAP_H */

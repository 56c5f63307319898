/**
 * @file dv_codec.h
 * @brief The dynval CAN protocol (can/dynval.dbc): pure encode/decode of classic 8-byte
 *        frames, and per-channel sequence tracking (gaps, duplicates, late frames).
 *
 * Every message is a classic CAN 2.0A frame (11-bit id), DLC exactly 8, signals little-endian
 * (Intel byte order), floats are IEEE-754 binary32. The table (also in firmware_sim/README.md):
 *
 * | id    | name        | dir      | bytes 0..7                                                |
 * |-------|-------------|----------|-----------------------------------------------------------|
 * | 0x080 | DV_STATUS   | node->bus| state u8, beat u8, lost u16, dup u8, late u8, bad_dlc u8, unknown u8 |
 * | 0x100 | DV_CTRL     | bus->node| cmd u8, rsv u8, record_id u32, rsv u16                     |
 * | 0x101 | DV_CHCFG    | bus->node| channel u8, flags u8, fs_hz u16, lsb f32 (units per count)|
 * | 0x200 | DV_SAMPLES  | bus->node| channel u8, seq u8, s0 i16, s1 i16, s2 i16                 |
 * | 0x300 | DV_FEATURE  | node->bus| feat_id u8, channel u8, index u16, value f32               |
 * | 0x380 | DV_RESID    | node->bus| channel u8, flags u8, step u16, value f32                  |
 *
 * A sample is raw * lsb in the channel's units; raw = -32768 (DV_CODEC_RAW_MISSING) marks a
 * missing sample, decoded as NaN (the feature modules drop and count it). The sequence counter
 * of DV_SAMPLES counts frames per channel modulo 256.
 */
#ifndef DV_CODEC_H
#define DV_CODEC_H

#include "dynval/dv_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Flags in dv_can_frame_t.id: the SocketCAN layout (linux/can.h), so frames pass unchanged. */
#define DV_CAN_EFF_FLAG 0x80000000u /**< extended 29-bit identifier */
#define DV_CAN_RTR_FLAG 0x40000000u /**< remote transmission request */
#define DV_CAN_ERR_FLAG 0x20000000u /**< error frame */
#define DV_CAN_SFF_MASK 0x000007FFu /**< 11-bit identifier */

#define DV_CAN_ID_STATUS 0x080u  /**< heartbeat with error counters, node -> bus */
#define DV_CAN_ID_CTRL 0x100u    /**< record start/stop, counter reset, node <- bus */
#define DV_CAN_ID_CHCFG 0x101u   /**< per-channel scaling and rate, node <- bus */
#define DV_CAN_ID_SAMPLES 0x200u /**< DV_CODEC_SAMPLES_PER_FRAME int16 samples, node <- bus */
#define DV_CAN_ID_FEATURE 0x300u /**< one feature value, node -> bus */
#define DV_CAN_ID_RESID 0x380u   /**< one observer residual, node -> bus */

#define DV_CAN_DLC 8u                   /**< every dynval message is 8 bytes */
#define DV_CODEC_SAMPLES_PER_FRAME 3u   /**< int16 samples per DV_SAMPLES frame (6 of 8 bytes) */
#define DV_CODEC_RAW_MISSING (-32768)   /**< raw value of a missing sample (decodes to NaN) */
#define DV_CODEC_DEFAULT_LSB 0.0009765625f/**< lsb until DV_CHCFG arrives: 2^-10 units/count */

/* DV_CTRL commands */
#define DV_CTRL_START 1u  /**< reset features and sequence tracking, start accepting samples */
#define DV_CTRL_STOP 2u   /**< stop accepting samples (they are counted as ignored) */
#define DV_CTRL_CLEAR 3u  /**< zero every error counter */
#define DV_CTRL_STATUS 4u /**< send DV_STATUS now */

/* DV_STATUS.state bits */
#define DV_STATE_RECORDING 0x01u /**< samples are accepted */
#define DV_STATE_OBS_ON 0x02u    /**< an observer is configured and running */
#define DV_STATE_AR_ON 0x04u     /**< an AR model is configured and running */
#define DV_STATE_OVERFLOW 0x08u  /**< the receive queue overflowed at least once */

/* DV_FEATURE.feat_id: segment features (index = segment number since record start, mod 2^16) */
#define DV_FEAT_SEG_STD 0x01u /**< STD of the segment just completed */
#define DV_FEAT_WIN_MEAN 0x08u /**< sliding-window mean at the segment end */
#define DV_FEAT_WIN_STD 0x09u  /**< sliding-window STD */
#define DV_FEAT_WIN_RMS 0x0Au  /**< sliding-window RMS */
#define DV_FEAT_WIN_PEAK 0x0Bu /**< sliding-window max |x| */
/* record features (index = record number, mod 2^16) */
#define DV_FEAT_REC_MEAN 0x10u  /**< record mean */
#define DV_FEAT_REC_STD 0x11u   /**< record population STD */
#define DV_FEAT_REC_RMS 0x12u   /**< record RMS */
#define DV_FEAT_REC_SKEW 0x13u  /**< record skewness */
#define DV_FEAT_REC_KURT 0x14u  /**< record kurtosis */
#define DV_FEAT_REC_PEAK 0x15u  /**< record max |x| */
#define DV_FEAT_REC_MIN 0x16u   /**< record minimum */
#define DV_FEAT_REC_MAX 0x17u   /**< record maximum */
#define DV_FEAT_REC_CREST 0x18u /**< record crest factor */
#define DV_FEAT_REC_KFACTOR 0x19u /**< record K-factor */
#define DV_FEAT_TM_ENERGY 0x20u   /**< temporal moment: energy E */
#define DV_FEAT_TM_CTIME 0x21u    /**< central time T, s */
#define DV_FEAT_TM_RMSDUR 0x22u   /**< RMS duration D, s */
#define DV_FEAT_TM_CSKEW 0x23u    /**< central skewness S, s */
#define DV_FEAT_TM_CKURT 0x24u    /**< central kurtosis K, s */
#define DV_FEAT_TM_AE 0x25u       /**< root energy amplitude A_e */
#define DV_FEAT_AR_RESID_RMS 0x40u /**< RMS of the AR one-step residual over the record */
#define DV_FEAT_AR_OUTLIERS 0x41u  /**< AR residuals beyond k sigma in the record (a count) */

/** @brief One classic CAN frame as SocketCAN has it. */
typedef struct {
    uint32_t id;     /**< identifier | DV_CAN_*_FLAG */
    uint8_t dlc;     /**< data length code, 0..8 */
    uint8_t data[8]; /**< payload, dlc bytes valid */
} dv_can_frame_t;

/** @brief The message kinds. */
typedef enum {
    DV_MSG_NONE = 0,
    DV_MSG_STATUS = 1,
    DV_MSG_CTRL = 2,
    DV_MSG_CHCFG = 3,
    DV_MSG_SAMPLES = 4,
    DV_MSG_FEATURE = 5,
    DV_MSG_RESID = 6
} dv_msg_kind_t;

/** @brief DV_STATUS: heartbeat; 8-bit counters saturate at 255, lost at 65535. */
typedef struct {
    uint8_t state;   /**< DV_STATE_* bits */
    uint8_t beat;    /**< heartbeat counter, mod 256 */
    uint16_t lost;   /**< sample frames missing (sequence gaps not filled later) */
    uint8_t dup;     /**< duplicate sample frames */
    uint8_t late;    /**< sample frames that arrived late (reordered) */
    uint8_t bad_dlc; /**< frames with a known id and DLC != 8 */
    uint8_t unknown; /**< frames with an id the node does not consume */
} dv_msg_status_t;

/** @brief DV_CTRL: record control. */
typedef struct {
    uint8_t cmd;        /**< DV_CTRL_* */
    uint32_t record_id; /**< caller's label of the record (echoed nowhere, logged) */
} dv_msg_ctrl_t;

/** @brief DV_CHCFG: channel configuration. */
typedef struct {
    uint8_t channel; /**< channel number */
    uint8_t flags;   /**< bit 0: channel enabled */
    uint16_t fs_hz;  /**< sample rate, Hz (sets dt of the temporal moments) */
    float lsb;       /**< units per count, finite and > 0 */
} dv_msg_chcfg_t;

/** @brief DV_SAMPLES: consecutive samples of one channel. */
typedef struct {
    uint8_t channel; /**< channel number */
    uint8_t seq;     /**< frame counter of this channel, mod 256 */
    int16_t raw[DV_CODEC_SAMPLES_PER_FRAME]; /**< samples in counts; DV_CODEC_RAW_MISSING = none */
} dv_msg_samples_t;

/** @brief DV_FEATURE: one feature value. */
typedef struct {
    uint8_t feat_id; /**< DV_FEAT_* */
    uint8_t channel; /**< channel number */
    uint16_t index;  /**< segment number (segment features) or record number, mod 2^16 */
    float value;     /**< value in the feature's units */
} dv_msg_feature_t;

/** @brief DV_RESID: one observer residual. */
typedef struct {
    uint8_t channel; /**< measured channel the residual belongs to */
    uint8_t flags;   /**< bit 0: observer converged */
    uint16_t step;   /**< observer step, mod 2^16 */
    float value;     /**< y_meas - y_pred, channel units */
} dv_msg_resid_t;

/** @brief Payload of a decoded message; the member named by dv_msg_t.kind is valid. */
typedef union {
    dv_msg_status_t status;   /**< DV_MSG_STATUS */
    dv_msg_ctrl_t ctrl;       /**< DV_MSG_CTRL */
    dv_msg_chcfg_t chcfg;     /**< DV_MSG_CHCFG */
    dv_msg_samples_t samples; /**< DV_MSG_SAMPLES */
    dv_msg_feature_t feature; /**< DV_MSG_FEATURE */
    dv_msg_resid_t resid;     /**< DV_MSG_RESID */
} dv_msg_body_t;

/** @brief A decoded message. */
typedef struct {
    dv_msg_kind_t kind; /**< which member of @c u is valid */
    dv_msg_body_t u;    /**< payload */
} dv_msg_t;

/**
 * @brief Decode a frame.
 * @param[in]  f   frame as received
 * @param[out] out decoded message; untouched unless DV_OK
 * @retval DV_OK      decoded
 * @retval DV_ERANGE  unknown id, an extended/RTR/error frame, or a DV_CTRL command not defined
 * @retval DV_ESIZE   a dynval id with a DLC other than 8 (the payload is not read)
 * @retval DV_ENUMERIC DV_CHCFG with an lsb that is not finite and > 0, or fs_hz 0
 * @retval DV_EINVAL  NULL argument, or dlc > 8
 */
dv_status_t dv_codec_decode(const dv_can_frame_t *f, dv_msg_t *out);

/**
 * @brief Decode a block of frames: dv_codec_decode() of each, for callers that handle frames
 *        in arrays (a logger at bus rate) rather than one call per frame.
 * @param[in]  f      @p n frames
 * @param[in]  n      number of frames
 * @param[out] out    @p n messages; out[i] is valid where status[i] is DV_OK (else untouched)
 * @param[out] status @p n statuses, as dv_codec_decode() returns them
 * @return the number of frames decoded DV_OK (0 when an argument is NULL)
 */
size_t dv_codec_decode_n(const dv_can_frame_t *f, size_t n, dv_msg_t *out, dv_status_t *status);

/**
 * @brief Encode a message (all bytes of the frame are written; reserved bytes are 0).
 * @param[in]  m   message; m->kind selects the layout
 * @param[out] f   frame with id, dlc 8 and data
 * @retval DV_OK     encoded
 * @retval DV_EINVAL NULL argument or unknown kind
 */
dv_status_t dv_codec_encode(const dv_msg_t *m, dv_can_frame_t *f);

/**
 * @brief Value of one raw sample in channel units: raw * lsb in dv_real_t, NaN for missing.
 *        Every consumer (firmware, offline reference) converts through this one function so
 *        results agree bit for bit.
 * @param[in] raw counts
 * @param[in] lsb units per count
 * @return raw * lsb, or a quiet NaN when raw is DV_CODEC_RAW_MISSING
 */
dv_real_t dv_codec_sample_value(int16_t raw, float lsb);

/**
 * @brief dv_codec_sample_value() of @p n raw samples, each with its own lsb (a block of
 *        frames of several channels).
 * @param[in]  raw @p n counts
 * @param[in]  lsb @p n units per count
 * @param[in]  n   number of samples
 * @param[out] out @p n values (NaN for missing samples)
 */
void dv_codec_sample_values(const int16_t *raw, const float *lsb, size_t n, dv_real_t *out);

/**
 * @brief Counts for a value in channel units, rounded to nearest (ties away from zero) and
 *        clamped to -32767..32767; NaN/Inf give DV_CODEC_RAW_MISSING.
 * @param[in] x   value, channel units
 * @param[in] lsb units per count, > 0
 * @return raw counts
 */
int16_t dv_codec_sample_raw(dv_real_t x, float lsb);

/** @brief Verdict of dv_seq_update() on one frame. */
typedef enum {
    DV_SEQ_OK = 0,    /**< the next frame in order (or the first one): use it */
    DV_SEQ_GAP = 1,   /**< ahead of the next expected: use it; the skipped ones count as lost */
    DV_SEQ_DUP = 2,   /**< already received: discard */
    DV_SEQ_LATE = 3,  /**< a frame counted lost that arrived late (reordered): discard */
    DV_SEQ_STALE = 4  /**< further behind than the tracking window: discard */
} dv_seq_verdict_t;

/** Frames behind the newest that are still told apart as late or duplicate. */
#define DV_SEQ_WINDOW 64u

/** @brief Sequence tracking of one channel's 8-bit frame counter. Fields are private. */
typedef struct {
    uint64_t seen;    /**< bit i: frame (last - i) mod 256 received */
    uint32_t span;    /**< counter positions covered since the first frame, <= DV_SEQ_WINDOW */
    uint8_t last;     /**< newest counter accepted */
    bool synced;      /**< a first frame has been seen */
    uint32_t n_ok;    /**< frames accepted (OK or GAP) */
    uint32_t n_lost;  /**< frames skipped and not (yet) arrived */
    uint32_t n_dup;   /**< duplicates */
    uint32_t n_late;  /**< late (reordered) frames */
    uint32_t n_stale; /**< frames behind the window */
} dv_seq_t;

/** @brief Counters of a dv_seq_t. */
typedef struct {
    uint32_t ok;    /**< frames accepted */
    uint32_t lost;  /**< frames missing */
    uint32_t dup;   /**< duplicates discarded */
    uint32_t late;  /**< late frames discarded (they are no longer counted as lost) */
    uint32_t stale; /**< frames behind the window discarded */
} dv_seq_counts_t;

/**
 * @brief Clear the tracker; the next frame is accepted as the first.
 * @retval DV_OK / DV_EINVAL (@p s NULL)
 */
dv_status_t dv_seq_init(dv_seq_t *s);

/** @brief Same as dv_seq_init() on a valid instance (counters zeroed, resynchronise). */
void dv_seq_reset(dv_seq_t *s);

/**
 * @brief Classify one received counter value and update the counters.
 * A jump forward of 1..127 is accepted (1..127 - 1 frames counted lost); a counter 0..128
 * behind the newest is a duplicate if it was received, late if it was counted lost and is
 * within DV_SEQ_WINDOW, else stale (also a frame from before the first one seen).
 * @param[in,out] s instance
 * @param[in] seq the frame's counter
 * @return the verdict (only OK and GAP frames should be used)
 */
dv_seq_verdict_t dv_seq_update(dv_seq_t *s, uint8_t seq);

/**
 * @brief Sequence tracking of a block of frames of several channels, in the order received:
 *        dv_seq_update() of each frame on its channel's tracker, and the frame's number since
 *        DV_CTRL START (the 8-bit counter unwrapped: frame k carries k mod 256). An accepted
 *        frame (OK, GAP) is numbered forward from the channel's last accepted one (the first
 *        one by its counter); a discarded one (DUP, LATE, STALE) behind it.
 * @param[in,out] s        trackers, indexed by channel number (at least max(chan) + 1)
 * @param[in,out] last     per channel: number of its last accepted frame, -1 before the first
 * @param[in]     chan     @p n channel numbers
 * @param[in]     seq      @p n frame counters
 * @param[in]     n        number of frames
 * @param[out]    verdict  @p n verdicts (dv_seq_verdict_t values)
 * @param[out]    frame_no @p n frame numbers
 */
void dv_seq_track_n(dv_seq_t *s, int64_t *last, const uint8_t *chan, const uint8_t *seq,
                    size_t n, uint8_t *verdict, int64_t *frame_no);

/**
 * @brief Read the counters.
 * @retval DV_OK / DV_EINVAL (NULL)
 */
dv_status_t dv_seq_get(const dv_seq_t *s, dv_seq_counts_t *out);

#ifdef __cplusplus
}
#endif

#endif /* DV_CODEC_H */

/**
 * @file dv_chan.h
 * @brief The per-channel feature set a DAQ runs on every sample: record statistics,
 *        sliding-window statistics, segmented STD and temporal moments, in one call.
 *
 * A record is n_seg * seg_len accepted samples. When a record completes, its statistics and
 * temporal moments are kept for dv_chan_get_record() and the record accumulators restart.
 * The sliding window runs continuously across records. NaN/Inf samples and samples with
 * |x| > DV_FEAT_MAX (dv_config.h) are dropped and counted (they do not enter any feature), so
 * every result is finite: a result that would not be is reported as an error, never as DV_OK.
 */
#ifndef DV_CHAN_H
#define DV_CHAN_H

#include "dynval/dv_types.h"
#include "dynval/dv_moments.h"
#include "dynval/dv_sliding.h"
#include "dynval/dv_segstd.h"
#include "dynval/dv_temporal.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Storage needed by dv_chan_init(), in elements (n_seg 0 with no_seg_vectors). */
#define DV_CHAN_BUF_LEN(win_len, n_seg) (DV_SLIDING_BUF_LEN(win_len) + DV_SEGSTD_BUF_LEN(n_seg))

/** @brief Configuration of one channel's feature set. */
typedef struct {
    uint32_t win_len; /**< sliding window, samples, 2..DV_SLIDING_MAX_LEN (e.g. 256) */
    uint32_t seg_len; /**< samples per STD segment, >= 2 (e.g. 64) */
    uint32_t n_seg;   /**< segments per record, >= 1 (e.g. 64: a 4096-sample record) */
    dv_real_t dt_s;   /**< sample period, s, 0 < dt_s <= DV_TEMPORAL_MAX_DT_S */
    bool no_seg_vectors; /**< true: keep no segmented-STD vector, each STD is read as its segment
                              completes (dv_segstd_last()); the buffer is DV_CHAN_BUF_LEN(win_len, 0) */
} dv_chan_config_t;

/** @brief One channel's features. Fields are private. */
typedef struct {
    dv_chan_config_t cfg;   /**< configuration */
    dv_moments_t rec;       /**< statistics of the open record */
    dv_sliding_t win;       /**< sliding window */
    dv_segstd_t seg;        /**< segmented STD */
    dv_temporal_t tm;       /**< temporal moments of the open record */
    dv_stats_t last_stats;  /**< statistics of the last complete record */
    dv_temporal_out_t last_tm; /**< temporal moments of the last complete record */
    dv_status_t last_st;    /**< status of last_stats (DV_ERANGE: the record overflowed) */
    dv_status_t last_tm_st; /**< status of last_tm (DV_ENUMERIC for an all-zero record) */
    dv_real_t shift;        /**< first sample of the open segment */
    dv_real_t seg1; /**< sums of (x - shift), (x - shift)^2 of earlier blocks of the segment (seg1) */
    dv_real_t seg2; /**< sums of (x - shift), (x - shift)^2 of earlier blocks of the segment (seg2) */
    uint32_t left;          /**< samples until the open block closes */
    uint32_t blk_max;       /**< block length: min(DV_BLOCK_LEN, win_len), so a block is in the ring */
    uint32_t seg_pos;       /**< samples of the open segment in closed blocks */
    uint32_t records;       /**< complete records */
    uint64_t n_nonfinite;   /**< samples dropped: NaN/Inf or |x| > DV_FEAT_MAX */
} dv_chan_t;

/** @brief Storage dv_chan_init() needs for @p cfg, in elements (DV_CHAN_BUF_LEN(), n_seg 0 with
 *         no_seg_vectors), at run time for bindings; 0 for NULL or a window length out of range. */
size_t dv_chan_buf_len(const dv_chan_config_t *cfg);

/**
 * @brief Bind storage and clear state.
 * @param[out] s instance
 * @param[in] cfg window, segment and record lengths, sample period (copied)
 * @param[in] buf DV_CHAN_BUF_LEN(cfg->win_len, cfg->n_seg) elements (n_seg 0 with
 *                cfg->no_seg_vectors), must outlive @p s
 * @param[in] buf_len elements in @p buf
 * @retval DV_OK / DV_EINVAL (NULL or a config value out of range) / DV_ESIZE (buffer too small)
 */
dv_status_t dv_chan_init(dv_chan_t *s, const dv_chan_config_t *cfg, dv_real_t *buf,
                         size_t buf_len);

/** @brief Clear every feature and counter (storage and config kept). */
void dv_chan_reset(dv_chan_t *s);

/**
 * @brief Add one sample to every feature.
 * @retval DV_OK       added
 * @retval DV_DONE     added; it completed a segment (dv_segstd_last(&s->seg, ...))
 * @retval DV_RECORD   added; it completed a record (dv_chan_get_record())
 * @retval DV_ENUMERIC NaN/Inf or |x| > DV_FEAT_MAX: dropped and counted, no feature changed
 */
dv_status_t dv_chan_update(dv_chan_t *s, dv_real_t x);

/**
 * @brief Add up to @p n samples, stopping right after a sample that completes a record.
 * @param[in,out] s instance
 * @param[in] x samples
 * @param[in] n samples in @p x
 * @param[out] n_used samples consumed (<= n); call again with the rest
 * @retval DV_RECORD a record completed at x[*n_used - 1]
 * @retval DV_OK     all @p n consumed, no record completed (NaN/Inf and samples beyond
 *                   DV_FEAT_MAX dropped and counted)
 * @retval DV_EINVAL NULL argument with n > 0
 */
dv_status_t dv_chan_update_block(dv_chan_t *s, const dv_real_t *x, size_t n, size_t *n_used);

/**
 * @brief Statistics and temporal moments of the last complete record.
 * @param[in] s instance
 * @param[out] st statistics of the record
 * @param[out] tm may be NULL; otherwise filled, or left untouched when the record's energy
 *                was zero (then DV_ENUMERIC is returned after @p st is filled)
 * @retval DV_OK        both filled, every value finite
 * @retval DV_ENOTREADY no complete record; outputs untouched
 * @retval DV_ERANGE    the record statistics overflowed (a float record of more than ~2^28
 *                      samples near DV_FEAT_MAX; see dv_moments_get()): outputs untouched; or
 *                      the temporal moments did (see dv_temporal_get()): @p st filled
 * @retval DV_ENUMERIC  zero energy: @p st filled, @p tm untouched
 * @retval DV_EINVAL    NULL @p s or @p st
 */
dv_status_t dv_chan_get_record(const dv_chan_t *s, dv_stats_t *st, dv_temporal_out_t *tm);

/** @brief Sliding-window statistics; see dv_sliding_get(). */
dv_status_t dv_chan_get_window(const dv_chan_t *s, dv_stats_t *out);

#ifdef __cplusplus
}
#endif

#endif /* DV_CHAN_H */

/**
 * @file dv_arstats.h
 * @brief Statistics of an AR/ARX residual (report Section 5.4.1, Fig. 63-64): RMS, skewness,
 *        kurtosis over the record and over a sliding window, and the outliers beyond k sigma
 *        (the impact detector).
 *
 * The moments come from dv_moments (record) and dv_sliding (window). An outlier is a sample
 * with |e_i - mean| > k sigma, where mean and sigma are the population mean and STD of the
 * record (dv_arstats_record()) or of the window of the preceding samples (streaming). Its size
 * is reported in sigmas, signed: (e_i - mean) / sigma. Indices go into a caller buffer of
 * bounded length; outliers beyond it are counted, not stored.
 */
#ifndef DV_ARSTATS_H
#define DV_ARSTATS_H

#include "dynval/dv_types.h"
#include "dynval/dv_moments.h"
#include "dynval/dv_sliding.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Storage for dv_arstats_init(), in elements, for a window of @p win samples. */
#define DV_ARSTATS_BUF_LEN(win) DV_SLIDING_BUF_LEN(win)

/** @brief Residual statistics and outlier tally. */
typedef struct {
    dv_stats_t rec;          /**< record (or stream-so-far) statistics: rms, skew, kurt, ... */
    dv_stats_t win;          /**< window statistics (streaming only; zero for a record) */
    uint32_t win_ready;      /**< 1 when @c win is valid */
    dv_real_t k_sigma;       /**< threshold in sigmas */
    uint64_t n_outliers;     /**< outliers found */
    uint64_t n_stored;       /**< of which index/size were stored (<= capacity) */
    uint64_t n_overflow;     /**< outliers that did not fit the caller buffers */
    uint64_t n_nonfinite;    /**< NaN/Inf samples dropped */
} dv_arstats_out_t;

/**
 * @brief Statistics and outliers of a residual record.
 * @param[out] out     filled on DV_OK and on DV_ENUMERIC (then NaN/Inf samples were skipped)
 * @param[in]  k_sigma threshold, > 0 (3 to 5 is usual)
 * @param[in]  e       residual record
 * @param[in]  n       samples
 * @param[out] idx     indices into @p e of the first @p cap outliers, ascending; may be NULL
 *                     when @p cap is 0
 * @param[out] size    their signed sizes in sigmas, same order; may be NULL
 * @param[in]  cap     room in @p idx (and in @p size if given)
 * @retval DV_OK        done
 * @retval DV_ENUMERIC  some samples were NaN/Inf: skipped and counted; the rest evaluated
 * @retval DV_ENOTREADY fewer than 2 finite samples, or zero spread; @p out untouched
 * @retval DV_EINVAL    NULL @p out/@p e, n == 0, k_sigma not > 0, or NULL @p idx with cap > 0
 */
dv_status_t dv_arstats_record(dv_arstats_out_t *out, dv_real_t k_sigma, const dv_real_t *e,
                              size_t n, uint32_t *idx, dv_real_t *size, size_t cap);

/** @brief Streaming residual statistics with a windowed outlier test. Fields are private. */
typedef struct {
    dv_moments_t rec;     /**< whole stream */
    dv_sliding_t win;     /**< last win_len accepted samples */
    dv_real_t k_sigma;    /**< threshold in sigmas */
    uint32_t *idx;        /**< caller buffer of outlier indices (stream position), @c cap */
    dv_real_t *size;      /**< caller buffer of outlier sizes in sigmas, @c cap, or NULL */
    size_t cap;           /**< room in idx/size */
    uint64_t n_outliers;  /**< outliers found */
    uint64_t n_stored;    /**< outliers stored */
    uint64_t pos;         /**< stream position of the next sample (dropped samples count) */
} dv_arstats_t;

/**
 * @brief Bind storage and clear.
 *
 * A sample is tested against the mean and STD of the @p win_len samples before it, once that
 * window is full; it then enters the window. Indices are stream positions counted from 0 at
 * init/reset, including dropped NaN/Inf samples (so they line up with the caller's clock).
 *
 * @param[out] s       instance
 * @param[in]  k_sigma threshold, > 0
 * @param[in]  win_len window length in samples, 2..DV_SLIDING_MAX_LEN
 * @param[in]  buf     DV_ARSTATS_BUF_LEN(win_len) elements; outlives @p s
 * @param[in]  buf_len elements in @p buf
 * @param[out] idx     outlier index buffer, @p cap elements (NULL if cap == 0)
 * @param[out] size    outlier size buffer, @p cap elements, or NULL
 * @param[in]  cap     capacity of @p idx / @p size
 * @retval DV_OK / DV_EINVAL (NULL, bad k_sigma or win_len) / DV_ESIZE (@p buf_len too small)
 */
dv_status_t dv_arstats_init(dv_arstats_t *s, dv_real_t k_sigma, size_t win_len, dv_real_t *buf,
                            size_t buf_len, uint32_t *idx, dv_real_t *size, size_t cap);

/** @brief Start a new stream (storage kept, outliers forgotten). */
void dv_arstats_reset(dv_arstats_t *s);

/**
 * @brief Push one residual sample.
 * @retval DV_OK       accepted, not an outlier (or the window is not full yet)
 * @retval DV_DONE     accepted and flagged as an outlier
 * @retval DV_ENUMERIC NaN/Inf: dropped and counted (its position is still consumed)
 */
dv_status_t dv_arstats_update(dv_arstats_t *s, dv_real_t e);

/**
 * @brief Current statistics and outlier tally (state unchanged).
 * @retval DV_OK        @p out filled (out->win_ready says whether out->win is valid)
 * @retval DV_ENOTREADY no sample accepted yet; @p out untouched
 * @retval DV_EINVAL    NULL argument
 */
dv_status_t dv_arstats_get(const dv_arstats_t *s, dv_arstats_out_t *out);

#ifdef __cplusplus
}
#endif

#endif /* DV_ARSTATS_H */

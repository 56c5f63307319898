/**
 * @file dv_moments.h
 * @brief Cumulative basic statistics of a record (report Table 15, eq. 11-12), O(1) per sample.
 *
 * Population moments (1/N): skewness = m3 / m2^1.5, kurtosis = m4 / m2^2 (3 for a Gaussian).
 * Samples are summed as shifted powers in blocks of DV_BLOCK_LEN and each block is merged
 * exactly into the running central moments (Pebay), so long records stay accurate in float.
 */
#ifndef DV_MOMENTS_H
#define DV_MOMENTS_H

#include "dynval/dv_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Flags in dv_stats_t.flags for results that are undefined for this data. */
#define DV_STATS_NO_SHAPE 0x1u /**< variance is 0, at round-off level for the data's peak, or
                                    below 2^-60 (float) / 2^-500 (double), or skew^2 or kurt beyond
                                    the count (round-off): skew and kurt set to 0 */
#define DV_STATS_NO_CREST 0x2u /**< RMS is 0: crest is set to 0 */

/** @brief Basic statistics of a set of samples (units of x unless stated). */
typedef struct {
    uint64_t count;  /**< samples in the set */
    dv_real_t mean;  /**< arithmetic mean */
    dv_real_t var;   /**< population variance (1/N), units of x^2 */
    dv_real_t std;   /**< population standard deviation */
    dv_real_t rms;   /**< root mean square */
    dv_real_t skew;  /**< m3 / m2^1.5, dimensionless */
    dv_real_t kurt;  /**< m4 / m2^2, dimensionless, 3 for a Gaussian */
    dv_real_t peak;  /**< max |x| */
    dv_real_t min;   /**< smallest sample */
    dv_real_t max;   /**< largest sample */
    dv_real_t crest; /**< peak / rms (eq. 11), dimensionless */
    dv_real_t kfactor; /**< peak * rms (eq. 12), units of x^2 */
    uint32_t flags;  /**< DV_STATS_NO_SHAPE, DV_STATS_NO_CREST */
} dv_stats_t;

/** @brief Running statistics of a record. Fields are private. */
typedef struct {
    dv_real_t n;        /**< merged samples */
    dv_real_t mean;     /**< merged mean */
    dv_real_t m2; /**< merged central sums (m2) */
    dv_real_t m3; /**< merged central sums (m3) */
    dv_real_t m4; /**< merged central sums (m4) */
    dv_real_t shift;    /**< shift of the open block (the running mean) */
    dv_real_t s1; /**< shifted power sums of the open block (s1) */
    dv_real_t s2; /**< shifted power sums of the open block (s2) */
    dv_real_t s3; /**< shifted power sums of the open block (s3) */
    dv_real_t s4; /**< shifted power sums of the open block (s4) */
    dv_real_t min; /**< extremes so far (min) */
    dv_real_t max; /**< extremes so far (max) */
    uint32_t blk;       /**< samples in the open block, < DV_BLOCK_LEN */
    uint64_t count;     /**< accepted samples */
    uint64_t n_nonfinite; /**< samples dropped: NaN/Inf or |x| > DV_FEAT_MAX */
} dv_moments_t;

/**
 * @brief Clear the statistics.
 * @retval DV_OK     ready
 * @retval DV_EINVAL @p s is NULL
 */
dv_status_t dv_moments_init(dv_moments_t *s);

/** @brief Start a new record (same as init). */
void dv_moments_reset(dv_moments_t *s);

/**
 * @brief Add one sample.
 * @param[in,out] s instance
 * @param[in] x sample, |x| <= DV_FEAT_MAX (dv_config.h: 2^24 float, 2^200 double), units of x
 * @retval DV_OK       added
 * @retval DV_ENUMERIC @p x is NaN/Inf or |x| > DV_FEAT_MAX: dropped, counted in n_nonfinite,
 *                     state unchanged
 */
dv_status_t dv_moments_update(dv_moments_t *s, dv_real_t x);

/**
 * @brief Add @p n samples; same result as n updates up to round-off (partial sums merged exactly).
 * NaN/Inf samples and samples beyond DV_FEAT_MAX are dropped and counted.
 * @retval DV_OK       all added
 * @retval DV_ENUMERIC at least one sample was dropped (the others were added)
 * @retval DV_EINVAL   @p x is NULL with @p n > 0
 */
dv_status_t dv_moments_update_block(dv_moments_t *s, const dv_real_t *x, size_t n);

/**
 * @brief Statistics of all samples so far (the state is not changed).
 * @retval DV_OK        @p out filled, every field finite; check out->flags for undefined
 *                      shape/crest
 * @retval DV_ENOTREADY no sample yet; @p out untouched
 * @retval DV_ERANGE    the fourth central sum overflowed the real type (float: possible after
 *                      ~2^28 samples near DV_FEAT_MAX); @p out untouched, start a new record
 * @retval DV_EINVAL    NULL argument
 */
dv_status_t dv_moments_get(const dv_moments_t *s, dv_stats_t *out);

/** @brief Samples dropped since init (NaN/Inf or beyond DV_FEAT_MAX); 0 for NULL. */
uint64_t dv_moments_nonfinite(const dv_moments_t *s);

/**
 * @brief Crest factor peak/rms (eq. 11).
 * @retval DV_OK       @p out = peak / rms
 * @retval DV_ENUMERIC rms <= 0 or a non-finite argument; @p out untouched
 */
dv_status_t dv_crest_factor(dv_real_t peak, dv_real_t rms, dv_real_t *out);

/**
 * @brief K-factor peak*rms (eq. 12).
 * @retval DV_OK       @p out = peak * rms
 * @retval DV_ENUMERIC a non-finite argument or an overflowing product; @p out untouched
 */
dv_status_t dv_k_factor(dv_real_t peak, dv_real_t rms, dv_real_t *out);

#ifdef __cplusplus
}
#endif

#endif /* DV_MOMENTS_H */

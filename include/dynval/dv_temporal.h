/**
 * @file dv_temporal.h
 * @brief Temporal moments of a record in one pass (report eq. 14-16, Table 16).
 *
 * With t_i = i * dt (i = 0 for the first sample of the record) and weights w_i = x_i^2:
 * E = dt * sum w (the energy integral), T = sum w t / sum w (central time),
 * D^2 = M2(T)/M0 (RMS duration), S^3 = M3(T)/M0 (central skewness, signed),
 * K^4 = M4(T)/M0 (central kurtosis), A_e = sqrt(E / D) (root energy amplitude).
 * Note: the report prints A_e = E/D (eq. 16); the name and Smallwood's definition take the
 * root, which has the units of x. Weighted moments are accumulated per block of local time
 * and merged exactly, so records of any length keep full precision.
 */
#ifndef DV_TEMPORAL_H
#define DV_TEMPORAL_H

#include "dynval/dv_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Longest sample period dv_temporal_init() accepts, s (2^32 s, 136 years): with it every
 *  time-scaled result of an in-range record stays finite. */
#define DV_TEMPORAL_MAX_DT_S DV_R(4294967296.0)

/** @brief Temporal moments of a record. */
typedef struct {
    dv_real_t energy;   /**< E, units of x^2 s */
    dv_real_t central_time; /**< T, s from the first sample */
    dv_real_t rms_duration; /**< D, s */
    dv_real_t central_skew; /**< S, s (signed cube root) */
    dv_real_t central_kurt; /**< K, s */
    dv_real_t root_energy_amp; /**< A_e = sqrt(E/D), units of x */
    uint64_t count;     /**< samples in the record */
} dv_temporal_out_t;

/** @brief Temporal-moment accumulator. Fields are private. */
typedef struct {
    dv_real_t dt_s;       /**< sample period, s */
    dv_real_t w;          /**< merged weight (sum x^2) times wsc */
    dv_real_t mean;       /**< merged centroid, samples from record start */
    dv_real_t m2;         /**< merged weighted central sum, samples^2, times wsc */
    dv_real_t m3;         /**< merged weighted central sum, samples^3, times wsc */
    dv_real_t m4;         /**< merged weighted central sum, samples^4, times wsc */
    dv_real_t wsc;        /**< scale of the merged weights, a power of two (1 unless large or
                               small weights needed it) */
    dv_real_t t0;         /**< start of the open block, samples */
    dv_real_t tau;        /**< local time of the next sample in the open block */
    dv_real_t s0; /**< sums of w tau^k in the open block (s0) */
    dv_real_t s1; /**< sums of w tau^k in the open block (s1) */
    dv_real_t s2; /**< sums of w tau^k in the open block (s2) */
    dv_real_t s3; /**< sums of w tau^k in the open block (s3) */
    dv_real_t s4; /**< sums of w tau^k in the open block (s4) */
    uint32_t blk;         /**< samples in the open block */
    uint64_t count;       /**< accepted samples */
    uint64_t n_nonfinite; /**< samples dropped: NaN/Inf or |x| > DV_FEAT_MAX */
} dv_temporal_t;

/**
 * @brief Clear state.
 * @param[out] s instance
 * @param[in] dt_s sample period in seconds, 0 < dt_s <= DV_TEMPORAL_MAX_DT_S
 * @retval DV_OK / DV_EINVAL (NULL @p s, @p dt_s NaN or out of range)
 */
dv_status_t dv_temporal_init(dv_temporal_t *s, dv_real_t dt_s);

/** @brief Start a new record (t = 0 at its next sample). */
void dv_temporal_reset(dv_temporal_t *s);

/**
 * @brief Add the next sample of the record.
 * @retval DV_OK / DV_ENUMERIC (NaN/Inf or |x| > DV_FEAT_MAX: dropped and counted; its time slot
 *         still advances, since the sample clock did)
 */
dv_status_t dv_temporal_update(dv_temporal_t *s, dv_real_t x);

/** @brief Add @p n consecutive samples; identical to n updates. DV_EINVAL for NULL @p x. */
dv_status_t dv_temporal_update_block(dv_temporal_t *s, const dv_real_t *x, size_t n);

/**
 * @brief Temporal moments of the record so far (state unchanged).
 * @retval DV_OK        @p out filled, every field finite
 * @retval DV_ENOTREADY no sample yet; @p out untouched
 * @retval DV_ENUMERIC  zero energy (all samples 0): T, D undefined; @p out untouched
 * @retval DV_ERANGE    a result is beyond the real type (a float record of more than ~2^28
 *                      samples at full scale, a huge energy over a vanishing RMS duration);
 *                      @p out untouched
 * @retval DV_EINVAL    NULL argument
 */
dv_status_t dv_temporal_get(const dv_temporal_t *s, dv_temporal_out_t *out);

#ifdef __cplusplus
}
#endif

#endif /* DV_TEMPORAL_H */

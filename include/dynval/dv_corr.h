/**
 * @file dv_corr.h
 * @brief Streaming correlation coefficient of two channels (report eq. 21).
 *
 * r = sum (x - mx)(y - my) / sqrt(sum (x - mx)^2 sum (y - my)^2), the same as eq. 21 with
 * sample STDs. Co-moments are updated with Welford's recurrence (stable for any offset).
 */
#ifndef DV_CORR_H
#define DV_CORR_H

#include "dynval/dv_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** @brief Correlation state. Fields are private. */
typedef struct {
    dv_real_t mx; /**< running means (mx) */
    dv_real_t my; /**< running means (my) */
    dv_real_t cxx; /**< running central co-moments (cxx) */
    dv_real_t cyy; /**< running central co-moments (cyy) */
    dv_real_t cxy; /**< running central co-moments (cxy) */
    uint64_t count;       /**< accepted sample pairs */
    uint64_t n_nonfinite; /**< pairs dropped: x or y NaN/Inf or beyond DV_FEAT_MAX */
} dv_corr_t;

/** @brief Clear state. @retval DV_OK / DV_EINVAL (NULL). */
dv_status_t dv_corr_init(dv_corr_t *s);

/** @brief Clear state (same as init). */
void dv_corr_reset(dv_corr_t *s);

/**
 * @brief Add one pair of simultaneous samples.
 * @retval DV_OK / DV_ENUMERIC (x or y NaN/Inf or |v| > DV_FEAT_MAX: the pair is dropped and
 *         counted)
 */
dv_status_t dv_corr_update(dv_corr_t *s, dv_real_t x, dv_real_t y);

/**
 * @brief Correlation coefficient in [-1, 1] of the pairs so far.
 * @retval DV_OK        @p r filled
 * @retval DV_ENOTREADY fewer than 2 pairs; @p r untouched
 * @retval DV_ENUMERIC  a channel is constant (zero variance); @p r untouched
 * @retval DV_EINVAL    NULL argument
 */
dv_status_t dv_corr_get(const dv_corr_t *s, dv_real_t *r);

#ifdef __cplusplus
}
#endif

#endif /* DV_CORR_H */

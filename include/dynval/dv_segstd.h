/**
 * @file dv_segstd.h
 * @brief Segmented STD: a record cut into n_seg consecutive segments of seg_len samples,
 *        the population STD of each (the report uses 64 x 64 over a 4096-point record).
 *
 * Each completed record's vector is kept (double-buffered) while the next record fills, or,
 * initialised without storage, no vector is kept at all: firmware that publishes each STD as its
 * segment completes (dv_segstd_last()) needs no RAM per segment.
 */
#ifndef DV_SEGSTD_H
#define DV_SEGSTD_H

#include "dynval/dv_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Storage needed by dv_segstd_init(), in elements, for @p n_seg segments per record. */
#define DV_SEGSTD_BUF_LEN(n_seg) (2u * (size_t)(n_seg))

/** @brief Segmented-STD state. Fields are private. */
typedef struct {
    dv_real_t *cur;       /**< STDs of the record being filled, length n_seg (NULL: none kept) */
    dv_real_t *done;      /**< STDs of the last complete record, length n_seg (NULL: none kept) */
    uint32_t seg_len;     /**< samples per segment */
    uint32_t n_seg;       /**< segments per record */
    uint32_t pos;         /**< samples in the open segment */
    uint32_t seg;         /**< index of the open segment in its record */
    uint32_t records;     /**< complete records so far */
    dv_real_t shift;      /**< first sample of the open segment */
    dv_real_t s1; /**< shifted sums of the open segment (s1) */
    dv_real_t s2; /**< shifted sums of the open segment (s2) */
    dv_real_t last;       /**< STD of the last completed segment */
    uint64_t n_nonfinite; /**< samples dropped: NaN/Inf or |x| > DV_FEAT_MAX */
} dv_segstd_t;

/**
 * @brief Bind storage and clear state.
 * @param[out] s instance
 * @param[in] seg_len samples per segment, >= 2
 * @param[in] n_seg   segments per record, >= 1
 * @param[in] buf     DV_SEGSTD_BUF_LEN(n_seg) elements, must outlive @p s; or NULL with
 *                    @p buf_len 0: keep no vectors (dv_segstd_get() then returns DV_EINVAL)
 * @param[in] buf_len elements in @p buf
 * @retval DV_OK / DV_EINVAL (NULL @p s, seg_len < 2, n_seg 0, NULL @p buf with @p buf_len > 0) /
 *         DV_ESIZE (@p buf_len too small)
 */
dv_status_t dv_segstd_init(dv_segstd_t *s, size_t seg_len, size_t n_seg, dv_real_t *buf,
                           size_t buf_len);

/** @brief Restart at segment 0 of a new record; the last complete vector is forgotten. */
void dv_segstd_reset(dv_segstd_t *s);

/**
 * @brief Add one sample.
 * @retval DV_OK       added
 * @retval DV_DONE     added, and it completed a segment (dv_segstd_last() has its STD)
 * @retval DV_RECORD   added, and it completed the last segment of a record
 * @retval DV_ENUMERIC NaN/Inf or |x| > DV_FEAT_MAX: dropped, counted, state unchanged (so every
 *                     STD is finite)
 */
dv_status_t dv_segstd_update(dv_segstd_t *s, dv_real_t x);

/**
 * @brief STD of the last completed segment and its index within its record.
 * @retval DV_OK / DV_ENOTREADY (no segment yet, outputs untouched) / DV_EINVAL (NULL)
 */
dv_status_t dv_segstd_last(const dv_segstd_t *s, dv_real_t *std, uint32_t *seg_index);

/**
 * @brief Copy the STD vector of the last complete record.
 * @param[in] s instance
 * @param[out] out  n_seg elements
 * @param[in] out_len elements in @p out
 * @retval DV_OK / DV_ENOTREADY (no complete record yet, @p out untouched) /
 *         DV_EINVAL (NULL, or @p s keeps no vectors) / DV_ESIZE (@p out_len < n_seg)
 */
dv_status_t dv_segstd_get(const dv_segstd_t *s, dv_real_t *out, size_t out_len);

#ifdef __cplusplus
}
#endif

#endif /* DV_SEGSTD_H */

/**
 * @file dv_sliding.h
 * @brief Basic statistics over a sliding window of the last N samples, O(1) per sample.
 *
 * Mean, STD, RMS, skewness, kurtosis from shifted power sums with add/subtract; each time the
 * ring turns over, the sums are recomputed exactly from the ring (O(1) amortised), so
 * round-off cannot drift however long the stream. Min/max/peak are exact and branch-free: the
 * window is the tail of the previous turn of the ring (its suffix extremes, computed once per
 * turn) plus the head of the current turn (running extremes) (van Herk / Gil-Werman).
 */
#ifndef DV_SLIDING_H
#define DV_SLIDING_H

#include "dynval/dv_types.h"
#include "dynval/dv_moments.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Ring blocks whose suffix extremes the window keeps (the rest of a block is scanned when
 *  the window's extremes are read). */
#define DV_SLIDING_BLK 16u
/** Storage needed by dv_sliding_init(), in elements, for a window of @p n samples: the ring
 *  and two extremes per DV_SLIDING_BLK samples. */
#define DV_SLIDING_BUF_LEN(n)                                                                    \
    ((size_t)(n) + 2u * (((size_t)(n) + DV_SLIDING_BLK - 1u) / DV_SLIDING_BLK))

/** @brief Sliding-window statistics. Fields are private. */
typedef struct {
    dv_real_t *ring;      /**< last @c len samples, length @c len */
    dv_real_t *sufmax;    /**< [b]: max of ring[b * DV_SLIDING_BLK .. len-1] over the previous
                               turn, ceil(len / DV_SLIDING_BLK) of them */
    dv_real_t *sufmin;    /**< [b]: min of the same */
    uint32_t len;         /**< window length in samples */
    uint32_t head;        /**< next ring slot to write */
    uint32_t fill;        /**< @c len once the ring has turned over (window full), else 0 */
    uint32_t kern;        /**< vector kernel of the turn-over and of dv_chan_t's blocks, chosen
                               at init (0 portable C, 1 AVX2 + FMA, 2 AVX-512) */
    dv_real_t premax;     /**< max of ring[0..head-1] in the current turn */
    dv_real_t premin;     /**< min of ring[0..head-1] in the current turn */
    dv_real_t shift;      /**< shift of the power sums */
    dv_real_t s[4];       /**< window sums of d, d^2, d^3, d^4, d = x - shift */
    uint64_t n_nonfinite; /**< samples dropped: NaN/Inf or |x| > DV_FEAT_MAX */
} dv_sliding_t;

/** @brief DV_SLIDING_BUF_LEN(len) at run time (bindings); 0 for @p len out of 2..DV_SLIDING_MAX_LEN. */
size_t dv_sliding_buf_len(size_t len);

/**
 * @brief Bind storage and clear state.
 * @param[out] s   instance
 * @param[in]  len window length in samples, 2..DV_SLIDING_MAX_LEN
 * @param[in]  buf storage of DV_SLIDING_BUF_LEN(len) elements; must outlive @p s
 * @param[in]  buf_len elements in @p buf
 * @retval DV_OK     ready
 * @retval DV_EINVAL NULL pointer, or @p len out of range
 * @retval DV_ESIZE  @p buf_len < DV_SLIDING_BUF_LEN(len)
 */
dv_status_t dv_sliding_init(dv_sliding_t *s, size_t len, dv_real_t *buf, size_t buf_len);

/** @brief Empty the window (storage and length kept). */
void dv_sliding_reset(dv_sliding_t *s);

/**
 * @brief Push one sample (the oldest leaves once the window is full).
 * @retval DV_OK       added
 * @retval DV_ENUMERIC @p x is NaN/Inf or |x| > DV_FEAT_MAX: dropped, counted, state unchanged
 */
dv_status_t dv_sliding_update(dv_sliding_t *s, dv_real_t x);

/**
 * @brief Push @p n samples; identical to n calls of dv_sliding_update().
 * @retval DV_OK / DV_ENUMERIC (some samples NaN/Inf or beyond DV_FEAT_MAX: dropped and
 *         counted) / DV_EINVAL (NULL @p x, n > 0)
 */
dv_status_t dv_sliding_update_block(dv_sliding_t *s, const dv_real_t *x, size_t n);

/**
 * @brief Statistics of the current window; count is the window length.
 * @retval DV_OK        @p out filled, every field finite (check out->flags)
 * @retval DV_ENOTREADY fewer than @c len samples so far; @p out untouched
 * @retval DV_EINVAL    NULL argument
 */
dv_status_t dv_sliding_get(const dv_sliding_t *s, dv_stats_t *out);

#ifdef __cplusplus
}
#endif

#endif /* DV_SLIDING_H */

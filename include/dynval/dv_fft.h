/**
 * @file dv_fft.h
 * @brief Small in-place radix-4 complex FFT with caller-owned twiddles (kissfft's lenmem idea).
 *
 * X[k] = sum_m x[m] exp(-2 pi i k m / n), unscaled, for n a power of two. Data are interleaved
 * complex: x[2m] real part, x[2m + 1] imaginary part. A real n-point transform runs as an
 * n/2-point complex one plus a split pass, in the n elements of its input (CMSIS/kissfft
 * packing). The bit reversal is done on the fly, so the only storage is the twiddle table of
 * DV_FFT_BUF_LEN(n) elements, shared by both transforms of length n.
 */
#ifndef DV_FFT_H
#define DV_FFT_H

#include "dynval/dv_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Shortest transform: the butterflies assume n >= 4. */
#define DV_FFT_MIN_LEN 4u
/** Longest transform: indices are 32-bit and 2^20 points already need 8 MB of float data. */
#define DV_FFT_MAX_LEN 1048576u

/** Twiddle storage needed by dv_fft_init(), in elements, for an @p n -point transform. */
#define DV_FFT_BUF_LEN(n) ((size_t)(n))

/** @brief FFT plan: the length and its twiddle table. Fields are private. */
typedef struct {
    const dv_real_t *tw; /**< cos, -sin of 2 pi k / n for k < n/2, interleaved, length n */
    uint32_t n;          /**< transform length, a power of two */
} dv_fft_t;

/**
 * @brief Fill the twiddle table for an @p n -point transform.
 * @param[out] f   plan
 * @param[in]  n   transform length: a power of two in [DV_FFT_MIN_LEN, DV_FFT_MAX_LEN]
 * @param[out] buf DV_FFT_BUF_LEN(n) elements, must outlive @p f
 * @param[in]  len elements in @p buf
 * @retval DV_OK     ready for dv_fft_forward()
 * @retval DV_EINVAL NULL @p f or @p buf, or @p n not a power of two in range
 * @retval DV_ESIZE  @p len < DV_FFT_BUF_LEN(n)
 */
dv_status_t dv_fft_init(dv_fft_t *f, size_t n, dv_real_t *buf, size_t len);

/**
 * @brief Forward transform in place, unscaled (cannot fail; NaN/Inf in @p x propagate).
 * @param[in]     f plan from dv_fft_init()
 * @param[in,out] x 2 n elements: interleaved complex input, replaced by its transform
 */
void dv_fft_forward(const dv_fft_t *f, dv_real_t *x);

/**
 * @brief Forward transform of @p n real samples in place, unscaled (cannot fail).
 * @param[in]     f plan from dv_fft_init() for n points
 * @param[in,out] x n elements: real input, replaced by the half spectrum packed as
 *                  x[0] = X[0], x[1] = X[n/2] (both real), x[2k] + i x[2k+1] = X[k] for
 *                  0 < k < n/2 (X[n-k] = conj X[k])
 */
void dv_fft_forward_real(const dv_fft_t *f, dv_real_t *x);

#ifdef __cplusplus
}
#endif

#endif /* DV_FFT_H */

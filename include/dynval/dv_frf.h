/**
 * @file dv_frf.h
 * @brief Streaming Welch estimate of the FRF and coherence between one input u and one output y,
 *        in fixed caller-owned memory: live H1, H2, coherence and a peak summary for a DAQ.
 *
 * Samples arrive one pair at a time (or in blocks). Every @c hop samples, once @c seg_len have
 * arrived, the last @c seg_len pairs are Hann-windowed (periodic Hann, as scipy's 'hann'), each
 * transformed by a real FFT (dv_fft.h), and their one-sided auto- and cross-spectra averaged in:
 *
 *   Guu = E|U|^2,  Gyy = E|Y|^2,  Guy = E[conj(U) Y]    (scipy.signal.csd(u, y) convention)
 *   H1 = Guy / Guu,  H2 = Gyy / conj(Guy),  coherence = |Guy|^2 / (Guu Gyy)
 *
 * Spectra are power spectral densities in units^2/Hz, one-sided (doubled except at DC and
 * Nyquist), no detrending: the same numbers as scipy.signal.welch/csd(window='hann',
 * nperseg=seg_len, noverlap=seg_len-hop, detrend=False) with the default mean averaging.
 * Bin k is at k fs_hz / seg_len, k = 0 .. seg_len/2.
 *
 * Undefined ratios are defined, never NaN/Inf: a bin where Guu is 0 (no input power), or so small
 * that H1 would overflow, has H1 = 0 and coherence 0; where Guy is 0 (or H2 would overflow),
 * H2 = 0; coherence is clamped to [0, 1].
 */
#ifndef DV_FRF_H
#define DV_FRF_H

#include "dynval/dv_types.h"
#include "dynval/dv_config.h"
#include "dynval/dv_fft.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Shortest segment: fewer than 16 points give a spectrum too coarse to hold a peak. */
#define DV_FRF_MIN_SEG 16u

/** Frequency bins of a @p seg_len -point segment (DC to Nyquist). */
#define DV_FRF_N_BINS(seg_len) ((size_t)(seg_len) / 2u + 1u)

/** Storage needed by dv_frf_init(), in elements, for segments of @p seg_len samples: twiddles
 * (seg_len), the u and y history (2 seg_len), the FFT work area (2 seg_len) and four spectra
 * (Guu, Gyy, Re and Im Guy) of DV_FRF_N_BINS(seg_len) bins. */
#define DV_FRF_BUF_LEN(seg_len) (5u * (size_t)(seg_len) + 4u * DV_FRF_N_BINS(seg_len))

/** @brief Estimator configuration. */
typedef struct {
    uint32_t seg_len; /**< samples per segment (FFT length): a power of two in
                           [DV_FRF_MIN_SEG, DV_FRF_MAX_SEG] */
    uint32_t hop;     /**< samples between segment starts, 1 .. seg_len (seg_len/2: 50 % overlap,
                           seg_len: none) */
    uint32_t n_avg;   /**< 0: plain mean of every segment so far (scipy's Welch); N > 0: plain
                           mean of the first N segments, then exponential averaging with weight
                           1/N, so that a live estimate follows slow changes */
    dv_real_t fs_hz;  /**< sample rate in Hz, in [1e-3, 1e7] */
} dv_frf_config_t;

/** @brief One frequency bin of the estimate (see the file comment for definitions). */
typedef struct {
    dv_real_t f_hz;   /**< bin frequency, Hz */
    dv_real_t guu;    /**< input auto-spectrum, units_u^2/Hz */
    dv_real_t gyy;    /**< output auto-spectrum, units_y^2/Hz */
    dv_real_t guy_re; /**< cross-spectrum E[conj(U) Y], real part, units_u units_y/Hz */
    dv_real_t guy_im; /**< cross-spectrum, imaginary part */
    dv_real_t h1_re;  /**< H1 = Guy/Guu, real part, units_y/units_u */
    dv_real_t h1_im;  /**< H1, imaginary part */
    dv_real_t h2_re;  /**< H2 = Gyy/conj(Guy), real part, units_y/units_u */
    dv_real_t h2_im;  /**< H2, imaginary part */
    dv_real_t coh;    /**< coherence, in [0, 1] */
} dv_frf_bin_t;

/** @brief One resonance peak of |H1|: what firmware publishes. */
typedef struct {
    dv_real_t f_hz; /**< peak frequency, Hz (parabolic interpolation of |H1| over 3 bins) */
    dv_real_t mag;  /**< interpolated peak |H1|, units_y/units_u */
    dv_real_t zeta; /**< half-power damping ratio (f2 - f1) / (2 f_hz) (one side doubled when the
                         other is not found before a valley or the band edge); 0 when neither
                         half-power point is found. Biased high when the half-power band is
                         narrower than ~4 bins (the Hann window's resolution) */
} dv_frf_peak_t;

/** @brief Estimator state. Fields are private. */
typedef struct {
    dv_fft_t fft;           /**< plan over the first seg_len elements of the storage */
    dv_real_t *hist_u;      /**< ring of the last seg_len inputs */
    dv_real_t *hist_y;      /**< ring of the last seg_len outputs */
    dv_real_t *work;        /**< FFT work area, 2 seg_len */
    dv_real_t *guu;         /**< averaged |U|^2, unscaled, DV_FRF_N_BINS(seg_len) */
    dv_real_t *gyy;         /**< averaged |Y|^2, unscaled */
    dv_real_t *guy_re;      /**< averaged Re conj(U) Y, unscaled */
    dv_real_t *guy_im;      /**< averaged Im conj(U) Y, unscaled */
    dv_frf_config_t cfg;    /**< configuration */
    dv_real_t scale;        /**< unscaled average -> one-sided density: 2 / (fs sum w^2) */
    uint32_t head;          /**< next write index of the rings (the oldest sample) */
    uint32_t to_next;       /**< samples until the next segment completes */
    uint64_t n_seg;         /**< segments averaged */
    uint64_t n_nonfinite;   /**< pairs dropped: u or y NaN/Inf or beyond DV_FEAT_MAX */
} dv_frf_t;

/**
 * @brief Storage a configuration needs, in elements (DV_FRF_BUF_LEN(cfg->seg_len)).
 * @param[in] cfg configuration
 * @return elements for dv_frf_init(), or 0 when @p cfg is NULL or invalid (see dv_frf_init())
 */
size_t dv_frf_buffer_size(const dv_frf_config_t *cfg);

/**
 * @brief Check the configuration, bind storage, compute twiddles and clear state.
 * @param[out] s   instance
 * @param[in]  cfg configuration (copied)
 * @param[in]  buf dv_frf_buffer_size(cfg) elements, must outlive @p s
 * @param[in]  len elements in @p buf
 * @retval DV_OK     ready for dv_frf_update()
 * @retval DV_EINVAL NULL argument; seg_len not a power of two in [DV_FRF_MIN_SEG,
 *                   DV_FRF_MAX_SEG]; hop 0 or > seg_len; fs_hz not in [1e-3, 1e7] (or NaN)
 * @retval DV_ESIZE  @p len < dv_frf_buffer_size(cfg)
 */
dv_status_t dv_frf_init(dv_frf_t *s, const dv_frf_config_t *cfg, dv_real_t *buf, size_t len);

/** @brief Forget every sample and average (configuration and twiddles kept). */
void dv_frf_reset(dv_frf_t *s);

/**
 * @brief Add one pair of simultaneous input and output samples.
 * @param[in,out] s instance
 * @param[in] u input sample (e.g. force)
 * @param[in] y output sample (e.g. acceleration)
 * @retval DV_OK       added
 * @retval DV_DONE     added, and it completed a segment: the averages now include it
 * @retval DV_ENUMERIC u or y NaN/Inf or |value| > DV_FEAT_MAX: the pair is dropped and counted,
 *                     the state is unchanged (the segment is not broken, it closes a sample late)
 */
dv_status_t dv_frf_update(dv_frf_t *s, dv_real_t u, dv_real_t y);

/**
 * @brief Add @p n pairs; the same as @p n calls of dv_frf_update().
 * @param[in,out] s instance
 * @param[in] u @p n input samples
 * @param[in] y @p n output samples
 * @param[in] n pairs
 * @retval DV_DONE     at least one segment completed (no pair dropped)
 * @retval DV_OK       all added, no segment completed
 * @retval DV_ENUMERIC at least one pair was dropped and counted (the others were added)
 * @retval DV_EINVAL   NULL @p s, or NULL @p u or @p y with @p n > 0
 */
dv_status_t dv_frf_update_block(dv_frf_t *s, const dv_real_t *u, const dv_real_t *y, size_t n);

/** @brief Segments averaged so far (0 for NULL). */
uint64_t dv_frf_segments(const dv_frf_t *s);

/** @brief Pairs dropped (NaN/Inf or beyond DV_FEAT_MAX) since init/reset (0 for NULL). */
uint64_t dv_frf_nonfinite(const dv_frf_t *s);

/**
 * @brief One bin of the current estimate.
 * @param[in] s instance
 * @param[in] k bin index, 0 .. seg_len/2
 * @param[out] out spectra, H1, H2 and coherence of bin @p k, all finite
 * @retval DV_OK / DV_ENOTREADY (no segment yet; @p out untouched) / DV_ERANGE (k > seg_len/2) /
 *         DV_EINVAL (NULL)
 */
dv_status_t dv_frf_get_bin(const dv_frf_t *s, size_t k, dv_frf_bin_t *out);

/**
 * @brief H1 = Guy/Guu of every bin.
 * @param[in] s instance
 * @param[out] re real parts, DV_FRF_N_BINS(seg_len) elements
 * @param[out] im imaginary parts, same length
 * @param[in] len elements in each of @p re and @p im
 * @retval DV_OK / DV_ENOTREADY (no segment yet; outputs untouched) /
 *         DV_ESIZE (@p len < DV_FRF_N_BINS(seg_len)) / DV_EINVAL (NULL)
 */
dv_status_t dv_frf_get_h1(const dv_frf_t *s, dv_real_t *re, dv_real_t *im, size_t len);

/**
 * @brief H2 = Gyy/conj(Guy) of every bin (0 where Guy is 0).
 * @param[in] s instance
 * @param[out] re real parts, DV_FRF_N_BINS(seg_len) elements
 * @param[out] im imaginary parts, same length
 * @param[in] len elements in each of @p re and @p im
 * @retval DV_OK / DV_ENOTREADY / DV_ESIZE / DV_EINVAL, as dv_frf_get_h1()
 */
dv_status_t dv_frf_get_h2(const dv_frf_t *s, dv_real_t *re, dv_real_t *im, size_t len);

/**
 * @brief Coherence |Guy|^2/(Guu Gyy) in [0, 1] of every bin (0 where Guu or Gyy is 0).
 * @param[in] s instance
 * @param[out] coh DV_FRF_N_BINS(seg_len) elements
 * @param[in] len elements in @p coh
 * @retval DV_OK / DV_ENOTREADY / DV_ESIZE / DV_EINVAL, as dv_frf_get_h1()
 */
dv_status_t dv_frf_get_coherence(const dv_frf_t *s, dv_real_t *coh, size_t len);

/**
 * @brief The strongest local maxima of |H1| (bins 1 .. seg_len/2 - 1), strongest first.
 * A bin is a peak when its |H1| is above its left neighbour's and not below its right one's.
 * @param[in] s instance
 * @param[out] peaks @p max_peaks elements; the first @p *n_found are filled
 * @param[in] max_peaks peaks wanted, >= 1
 * @param[out] n_found peaks found, 0 .. @p max_peaks (0 for a flat or all-zero |H1|)
 * @retval DV_OK / DV_ENOTREADY (no segment yet; outputs untouched) /
 *         DV_EINVAL (NULL, or @p max_peaks 0)
 */
dv_status_t dv_frf_get_peaks(const dv_frf_t *s, dv_frf_peak_t *peaks, size_t max_peaks,
                             size_t *n_found);

#ifdef __cplusplus
}
#endif

#endif /* DV_FRF_H */

/**
 * @file dv_ar.h
 * @brief AR(p) models (report Section 5.4.1): Yule-Walker and Burg fits, order selection by AIC
 *        and by the partial-autocorrelation band, and the streaming AR residual.
 *
 * Sign convention (report eq. 27, 29, 31), used by every function here:
 *
 *     x_hat_i = sum_{j=1..p} a_j (x_{i-j} - mean),    e_i = (x_i - mean) - x_hat_i
 *
 * a[j-1] holds a_j. The fits remove the record mean first and store it in the model; the
 * residual filter subtracts the same mean, so e_i is exactly eq. 31 on the centred signal.
 * The reflection coefficients are stored with the same sign as a: refl[m-1] = a_m of the
 * order-m fit = the partial autocorrelation phi_mm (eq. 29-30; statsmodels pacf_yw sign).
 *
 * Fits run on a caller record and caller workspace (DV_AR_WORK_LEN); nothing is kept between
 * calls. On x86-64 double builds the O(n p) loops use AVX2/FMA or AVX-512 kernels chosen at
 * run time (results differ from the portable C loops only by round-off).
 *
 * Burg in double builds forms each order's sums from the autocorrelation plus corrections at
 * the record's ends (one O(n p) pass, then O(p) per order) when n >= 6p and its estimated
 * round-off stays below a few 1e-10 relative (~4e-12 for a lightly damped structure at AR(60));
 * otherwise (nearly deterministic records), and always in float builds, by the forward/backward
 * error lattice (round-off ~1e-14 in double). Both give the same quantities.
 */
#ifndef DV_AR_H
#define DV_AR_H

#include "dynval/dv_types.h"
#include "dynval/dv_config.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Workspace for dv_ar_fit() / dv_ar_order(), in elements, for @p n samples and order @p p. */
#define DV_AR_WORK_LEN(n, p) (2u * (size_t)(n) + 4u * ((size_t)(p) + 1u))

/** Extra elements of the streaming residual's storage: zero padding around the coefficients
 *  (aligned to 64 bytes) and before the history, for the x86-64 double kernels, which read
 *  whole vectors of 8. 0 in float builds. */
#ifdef DV_REAL_DOUBLE
#define DV_AR_RESID_PAD 24u
#else
#define DV_AR_RESID_PAD 0u
#endif

/** History of the streaming residual, in elements, for order @p p: double-length (2p: every
 *  window of p contiguous, for the x86-64 double kernels' vector loads) in double builds, a
 *  ring of p in float builds (firmware RAM). */
#ifdef DV_REAL_DOUBLE
#define DV_AR_RESID_HIST_LEN(p) (2u * (size_t)(p))
#else
#define DV_AR_RESID_HIST_LEN(p) ((size_t)(p))
#endif

/** Storage for dv_ar_resid_init(), in elements, for order @p p: the p coefficients and the
 *  history (+ DV_AR_RESID_PAD). Sized by the order, so an AR(32) float instance needs 64
 *  elements here; see also dv_ar_resid_buf_len(). */
#define DV_AR_RESID_BUF_LEN(p)                                                                  \
    ((size_t)(p) + DV_AR_RESID_HIST_LEN(p) + (size_t)DV_AR_RESID_PAD)

/** Estimator for dv_ar_fit() and dv_ar_order(). */
typedef enum {
    DV_AR_YULE_WALKER = 0, /**< Levinson-Durbin on the biased autocorrelation (eq. 27) */
    DV_AR_BURG = 1         /**< Burg: forward/backward lattice, harmonic-mean reflection */
} dv_ar_method_t;

/** @brief A fitted AR(p) model (see the sign convention above). */
typedef struct {
    uint32_t order;                   /**< p, 1..DV_AR_MAX_ORDER */
    uint32_t n;                       /**< samples in the fitted record */
    dv_real_t mean;                   /**< record mean removed before the fit, units of x */
    dv_real_t sigma2;                 /**< residual (innovation) variance, units of x^2 */
    dv_real_t a[DV_AR_MAX_ORDER];     /**< a_1..a_p in a[0..p-1]; the rest are 0 */
    dv_real_t refl[DV_AR_MAX_ORDER];  /**< reflection coefficients = PACF phi_11..phi_pp */
} dv_ar_model_t;

/** @brief Order-selection curves and the chosen orders (dv_ar_order()). */
typedef struct {
    uint32_t pmax;                     /**< orders examined: 1..pmax */
    uint32_t n;                        /**< samples in the record */
    uint32_t p_aic;                    /**< order with the smallest AIC */
    uint32_t p_pacf;                   /**< largest m with |phi_mm| >= band; 0 if none */
    dv_real_t band;                    /**< PACF band 2/sqrt(n) (eq. 30, ~95 %) */
    dv_real_t aic[DV_AR_MAX_ORDER];    /**< aic[m-1] = n ln(sigma2_m) + 2m (eq. 28) */
    dv_real_t pacf[DV_AR_MAX_ORDER];   /**< pacf[m-1] = phi_mm */
    dv_real_t sigma2[DV_AR_MAX_ORDER]; /**< sigma2[m-1] = residual variance of order m */
} dv_ar_order_t;

/**
 * @brief Fit AR(p) to a record.
 *
 * Yule-Walker: r_k = (1/n) sum_{i=0}^{n-1-k} (x_i - mean)(x_{i+k} - mean), then Levinson-Durbin;
 * sigma2 = r_0 prod (1 - phi_mm^2). Burg: the same recursion with reflection coefficients
 * 2 sum f b / sum (f^2 + b^2) from the forward/backward errors; sigma2 likewise from
 * r_0 = (1/n) sum (x_i - mean)^2.
 *
 * @param[out] m        model; written only on DV_OK
 * @param[in]  method   DV_AR_YULE_WALKER or DV_AR_BURG
 * @param[in]  p        order, 1..DV_AR_MAX_ORDER, < n
 * @param[in]  x        record, @p n samples, all finite
 * @param[in]  n        samples, >= 2, < 2^32
 * @param[in]  work     scratch of @p work_len elements (contents destroyed)
 * @param[in]  work_len elements in @p work, >= DV_AR_WORK_LEN(n, p)
 * @retval DV_OK       @p m filled; coefficients finite, every |phi_mm| < 1
 * @retval DV_EINVAL   NULL pointer, bad @p method, p == 0, p > DV_AR_MAX_ORDER, n < 2, p >= n
 * @retval DV_ESIZE    @p work_len too small
 * @retval DV_ENUMERIC a NaN/Inf sample, a constant record (variance 0 at round-off), or a
 *                     recursion that reaches |phi_mm| >= 1 / a zero error (a deterministic
 *                     record); @p m untouched
 */
dv_status_t dv_ar_fit(dv_ar_model_t *m, dv_ar_method_t method, uint32_t p, const dv_real_t *x,
                      size_t n, dv_real_t *work, size_t work_len);

/**
 * @brief AIC and PACF curves for orders 1..pmax from one recursion, and the chosen orders.
 *
 * AIC_m = n ln(sigma2_m) + 2m (eq. 28 with -2 L_m = n ln(2 pi sigma2_m) + n; the constant
 * n (1 + ln 2 pi) is dropped, it moves every order alike). PACF rule (eq. 30): p_pacf is the
 * largest m with |phi_mm| >= 2/sqrt(n), i.e. every higher coefficient up to pmax lies inside the
 * band. If the recursion stops early (a deterministic record) the curves are cut at the last
 * valid order and pmax says so.
 *
 * @param[out] o        curves and orders; written only on DV_OK
 * @param[in]  method   DV_AR_YULE_WALKER or DV_AR_BURG
 * @param[in]  pmax     highest order examined, 1..DV_AR_MAX_ORDER, < n
 * @param[in]  x        record, @p n finite samples
 * @param[in]  n        samples, >= 2
 * @param[in]  work     scratch, DV_AR_WORK_LEN(n, pmax) elements
 * @param[in]  work_len elements in @p work
 * @retval DV_OK       @p o filled
 * @retval DV_EINVAL   NULL pointer, bad method, pmax == 0, pmax > DV_AR_MAX_ORDER, pmax >= n
 * @retval DV_ESIZE    @p work_len too small
 * @retval DV_ENUMERIC NaN/Inf sample, constant record, or not even order 1 is valid
 */
dv_status_t dv_ar_order(dv_ar_order_t *o, dv_ar_method_t method, uint32_t pmax,
                        const dv_real_t *x, size_t n, dv_real_t *work, size_t work_len);

/**
 * @brief Biased autocorrelation r_k = (1/n) sum_{i=0}^{n-1-k} x_i x_{i+k}, k = 0..maxlag,
 *        of the record as given (no mean removed).
 * @param[in]  x      @p n samples
 * @param[in]  n      samples, >= 1
 * @param[in]  maxlag highest lag, < n
 * @param[out] r      @p maxlag + 1 values
 * @retval DV_OK       @p r filled
 * @retval DV_EINVAL   NULL pointer, n == 0 or maxlag >= n
 * @retval DV_ENUMERIC a NaN/Inf sample (or an overflowing sum); @p r is then unspecified
 */
dv_status_t dv_ar_autocorr(const dv_real_t *x, size_t n, size_t maxlag, dv_real_t *r);

/** @brief Streaming AR residual (eq. 31), O(p) per sample. Fields are private; the coefficients
 *  and the history live in the caller's buffer (DV_AR_RESID_BUF_LEN). */
typedef struct {
    const dv_real_t *c;  /**< a_p..a_1 (reversed) after `off` zeros, in the caller buffer */
    dv_real_t *hist;     /**< history (DV_AR_RESID_HIST_LEN): double: 2p, hist[j] == hist[j + p];
                              float: a ring of p */
    dv_real_t mean;      /**< subtracted from every input */
    dv_real_t c0;        /**< mean (1 - sum a_j): the mean folded out of the block kernel */
    uint32_t p;          /**< order */
    uint32_t head;       /**< oldest history slot, 0..p-1 */
    uint32_t kern;       /**< kernel chosen at init (0 portable, 1 AVX2, 2 AVX-512) */
    uint32_t nb;         /**< vector kernels: blocks of 8 taps before the newest 4 */
    uint32_t off;        /**< vector kernels: zero taps in front, 8 nb + 4 - p */
    uint32_t step;       /**< vector kernels: per-sample step for (kern, nb), 9 (kern - 1) + nb */
    uint64_t count;      /**< samples accepted since init/reset */
    uint64_t n_nonfinite; /**< NaN/Inf samples dropped */
} dv_ar_resid_t;

/** @brief DV_AR_RESID_BUF_LEN(p) as a function (for bindings); 0 for p == 0 or
 *  p > DV_AR_MAX_ORDER. */
size_t dv_ar_resid_buf_len(uint32_t p);

/**
 * @brief Copy the model's coefficients into @p buf, bind its history part, clear the history.
 * @param[out] r       instance
 * @param[in]  m       fitted model (copied into @p buf; need not outlive @p r); order
 *                     1..DV_AR_MAX_ORDER
 * @param[in]  buf     storage for the coefficients and the history,
 *                     DV_AR_RESID_BUF_LEN(m->order) elements; outlives @p r, not shared
 * @param[in]  buf_len elements in @p buf
 * @retval DV_OK       ready
 * @retval DV_EINVAL   NULL pointer, or order 0 / > DV_AR_MAX_ORDER
 * @retval DV_ESIZE    @p buf_len too small
 * @retval DV_ENUMERIC a non-finite coefficient or mean in @p m
 */
dv_status_t dv_ar_resid_init(dv_ar_resid_t *r, const dv_ar_model_t *m, dv_real_t *buf,
                             size_t buf_len);

/** @brief Forget the history (model and storage kept); counters cleared. */
void dv_ar_resid_reset(dv_ar_resid_t *r);

/**
 * @brief Push one sample; the residual e_i of eq. 31 once p samples precede it.
 * @param[in,out] r instance
 * @param[in]     x sample, units of the fitted record
 * @param[out]    e residual, written only on DV_OK
 * @retval DV_OK        @p e written
 * @retval DV_ENOTREADY fewer than p samples before this one: sample stored, @p e untouched
 * @retval DV_ENUMERIC  @p x NaN/Inf: dropped and counted, state unchanged, @p e untouched
 */
dv_status_t dv_ar_resid_update(dv_ar_resid_t *r, dv_real_t x, dv_real_t *e);

/**
 * @brief Push @p n samples; residuals of the accepted, ready samples are packed into @p e.
 *
 * Equivalent to n calls of dv_ar_resid_update() keeping the DV_OK outputs, up to round-off
 * (the block kernel sums taps in a different order). Finite blocks run a multi-output kernel
 * straight from @p x (about 3x faster per sample than single updates).
 *
 * @param[in,out] r     instance
 * @param[in]     x     @p n samples
 * @param[in]     n     samples
 * @param[out]    e     room for @p n residuals; the first *n_out are written
 * @param[out]    n_out residuals written (n minus dropped minus not-ready samples)
 * @retval DV_OK       all samples accepted
 * @retval DV_ENUMERIC some samples were NaN/Inf: dropped and counted, the rest processed
 * @retval DV_EINVAL   NULL @p x, @p e or @p n_out with n > 0 (nothing done)
 */
dv_status_t dv_ar_resid_update_block(dv_ar_resid_t *r, const dv_real_t *x, size_t n,
                                     dv_real_t *e, size_t *n_out);

/** @brief NaN/Inf samples dropped since init/reset (0 for NULL). */
uint64_t dv_ar_resid_nonfinite(const dv_ar_resid_t *r);

#ifdef __cplusplus
}
#endif

#endif /* DV_AR_H */

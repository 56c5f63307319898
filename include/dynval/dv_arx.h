/**
 * @file dv_arx.h
 * @brief ARX(na, nb, nk) and AR-ARX models (report eq. 32, 37-38): least squares by Givens QR
 *        in O(q^2) fixed memory, and the streaming ARX residual.
 *
 * Model (sign convention as dv_ar.h, eq. 32):
 *
 *     x_hat_i = sum_{j=1..na} alpha_j x_{i-j} + sum_{t=0..nb-1} beta_t f_{i-nk-t},
 *     e_i     = x_i - x_hat_i
 *
 * alpha[j-1] holds alpha_j; beta[t] multiplies the input at lag nk + t. Eq. 32 (lags 0..b) is
 * nk = 0, nb = b + 1; eq. 34 / 37 (lags 1..b) is nk = 1, nb = b. No mean is removed: remove it
 * upstream if the record has one.
 *
 * Least squares: rows are folded one at a time into an upper-triangular R with Givens
 * rotations (the QR factorisation of the regression matrix without storing it), so memory is
 * O(q^2) whatever the record length, and the conditioning is that of the data, not of the normal
 * equations. A column whose R diagonal is at round-off level of its own norm makes the problem
 * singular: DV_ENUMERIC, never NaN coefficients.
 */
#ifndef DV_ARX_H
#define DV_ARX_H

#include "dynval/dv_types.h"
#include "dynval/dv_config.h"
#include "dynval/dv_ar.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Most unknowns in one least-squares problem (na + nb). */
#define DV_LSQ_MAX_PARAMS (2u * DV_AR_MAX_ORDER)

/** Storage for dv_lsq_init(), in elements, for @p q unknowns. */
#define DV_LSQ_BUF_LEN(q) ((size_t)(q) * (size_t)(q) + 3u * (size_t)(q) + 1u)

/** Workspace for dv_arx_fit(), in elements. */
#define DV_ARX_WORK_LEN(na, nb) (DV_LSQ_BUF_LEN((size_t)(na) + (size_t)(nb)) + (size_t)(na) + (size_t)(nb))

/** Workspace for dv_ararx_fit(), in elements, for @p n samples and stage-1 order @p p. */
#define DV_ARARX_WORK_LEN(n, p, na, nb)                                                        \
    (2u * (size_t)(n) + 4u * ((size_t)(p) + 1u) + DV_ARX_WORK_LEN(na, nb))

/** Storage for dv_arx_resid_init(), in elements. */
#define DV_ARX_RESID_BUF_LEN(na, nb, nk) (2u * (size_t)(na) + 2u * ((size_t)(nb) + (size_t)(nk)))

/** @brief Sequential least squares min ||A theta - y||_2 (Givens QR). Fields are private. */
typedef struct {
    dv_real_t *R;         /**< q x q, row-major, upper triangle used */
    dv_real_t *z;         /**< q: Q^T y */
    dv_real_t *w;         /**< q + 1: the row being folded in */
    dv_real_t *cn;        /**< q: column sums of squares of A */
    dv_real_t rss;        /**< residual sum of squares so far */
    uint32_t q;           /**< unknowns */
    uint64_t rows;        /**< rows accepted */
    uint64_t n_nonfinite; /**< rows dropped for a NaN/Inf entry */
} dv_lsq_t;

/**
 * @brief Bind storage and clear.
 * @param[out] s       instance
 * @param[in]  q       unknowns, 1..DV_LSQ_MAX_PARAMS
 * @param[in]  buf     DV_LSQ_BUF_LEN(q) elements; outlives @p s
 * @param[in]  buf_len elements in @p buf
 * @retval DV_OK / DV_EINVAL (NULL, q out of range) / DV_ESIZE (@p buf_len too small)
 */
dv_status_t dv_lsq_init(dv_lsq_t *s, uint32_t q, dv_real_t *buf, size_t buf_len);

/** @brief Drop all rows (storage and q kept). */
void dv_lsq_reset(dv_lsq_t *s);

/**
 * @brief Fold in one row: a . theta ~ y. O(q^2).
 * @param[in,out] s instance
 * @param[in] a q regressors
 * @param[in] y target
 * @retval DV_OK       row added
 * @retval DV_ENUMERIC a NaN/Inf in @p a or @p y: row dropped and counted, state unchanged
 */
dv_status_t dv_lsq_update(dv_lsq_t *s, const dv_real_t *a, dv_real_t y);

/**
 * @brief Solve R theta = Q^T y.
 * @param[in] s instance
 * @param[out] theta q unknowns, written only on DV_OK
 * @param[out] rss   residual sum of squares, may be NULL
 * @param[out] rcond min/max of |R_jj| / ||A_j|| (columns scaled to unit norm), a cheap
 *                   reciprocal-condition estimate in (0, 1]; may be NULL
 * @retval DV_OK        solved, theta finite
 * @retval DV_ENOTREADY fewer rows than unknowns
 * @retval DV_ENUMERIC  rank deficient: some |R_jj| <= 10 q eps ||A_j||, or a non-finite
 *                      solution; outputs untouched
 * @retval DV_EINVAL    NULL @p s or @p theta
 */
dv_status_t dv_lsq_get(const dv_lsq_t *s, dv_real_t *theta, dv_real_t *rss, dv_real_t *rcond);

/** @brief ARX orders. */
typedef struct {
    uint32_t na; /**< AR order, 0..DV_AR_MAX_ORDER */
    uint32_t nb; /**< number of input taps, 0..DV_AR_MAX_ORDER (na + nb >= 1) */
    uint32_t nk; /**< input delay of the first tap in samples, 0..DV_AR_MAX_ORDER */
} dv_arx_cfg_t;

/** @brief A fitted ARX model. */
typedef struct {
    uint32_t na; /**< orders, as in dv_arx_cfg_t (na) */
    uint32_t nb; /**< orders, as in dv_arx_cfg_t (nb) */
    uint32_t nk; /**< orders, as in dv_arx_cfg_t (nk) */
    uint32_t n_rows;                   /**< regression rows used */
    dv_real_t alpha[DV_AR_MAX_ORDER];  /**< alpha_1..alpha_na */
    dv_real_t beta[DV_AR_MAX_ORDER];   /**< beta_0..beta_{nb-1} (input lags nk..nk+nb-1) */
    dv_real_t sigma2;                  /**< residual variance rss / n_rows, units of x^2 */
    dv_real_t rcond;                   /**< dv_lsq_get() reciprocal-condition estimate */
} dv_arx_model_t;

/**
 * @brief Fit ARX by least squares (eq. 32) over rows i = max(na, nk + nb - 1) .. n-1.
 * @param[out] m        model, written only on DV_OK
 * @param[in]  cfg      orders
 * @param[in]  x        output record, @p n samples
 * @param[in]  f        input record, @p n samples (may be NULL when nb == 0)
 * @param[in]  n        samples
 * @param[in]  work     DV_ARX_WORK_LEN(na, nb) elements of scratch
 * @param[in]  work_len elements in @p work
 * @retval DV_OK       fitted
 * @retval DV_EINVAL   NULL pointer, orders out of range, or fewer rows than na + nb
 * @retval DV_ESIZE    @p work_len too small
 * @retval DV_ENUMERIC a NaN/Inf sample, or a singular problem (e.g. a zero or repeated input);
 *                     @p m untouched
 */
dv_status_t dv_arx_fit(dv_arx_model_t *m, const dv_arx_cfg_t *cfg, const dv_real_t *x,
                       const dv_real_t *f, size_t n, dv_real_t *work, size_t work_len);

/**
 * @brief AR-ARX two-stage ARMA estimate (eq. 37-38, Mayne-Firoozan / Hannan-Rissanen).
 *
 * Stage 1: AR(p) by Yule-Walker on x; its residuals e_i (eq. 31), i >= p, stand in for the
 * white-noise input. Stage 2: ARX of the centred record x_i - mean on e, over i >= p, with the
 * orders in @p cfg (eq. 38 is nk = 0, nb = b + 1).
 *
 * @param[out] m        stage-2 ARX model (input channel = e), written only on DV_OK
 * @param[out] ar       stage-1 AR model, may be NULL; written only on DV_OK
 * @param[in]  cfg      stage-2 orders; requires p >= na + nb (report: p >= a + b)
 * @param[in]  p        stage-1 order, 1..DV_AR_MAX_ORDER, < n
 * @param[in]  x        record, @p n samples
 * @param[in]  n        samples
 * @param[in]  work     DV_ARARX_WORK_LEN(n, p, na, nb) elements of scratch
 * @param[in]  work_len elements in @p work
 * @retval DV_OK / DV_EINVAL / DV_ESIZE / DV_ENUMERIC as dv_ar_fit() and dv_arx_fit()
 */
dv_status_t dv_ararx_fit(dv_arx_model_t *m, dv_ar_model_t *ar, const dv_arx_cfg_t *cfg,
                         uint32_t p, const dv_real_t *x, size_t n, dv_real_t *work,
                         size_t work_len);

/** @brief Streaming ARX residual given the input channel. Fields are private. */
typedef struct {
    dv_real_t ca[DV_AR_MAX_ORDER]; /**< alpha_na..alpha_1 (reversed) */
    dv_real_t cb[DV_AR_MAX_ORDER]; /**< beta_{nb-1}..beta_0 (reversed) */
    dv_real_t *hx;                 /**< double-length output history, 2 na */
    dv_real_t *hf;                 /**< double-length input history, 2 (nb + nk) */
    uint32_t na; /**< orders; lf = nb + nk input samples kept (na) */
    uint32_t nb; /**< orders; lf = nb + nk input samples kept (nb) */
    uint32_t lf; /**< orders; lf = nb + nk input samples kept (lf) */
    uint32_t hx_head; /**< oldest slots (hx_head) */
    uint32_t hf_head; /**< oldest slots (hf_head) */
    uint32_t kern;                 /**< dot-product kernel */
    uint64_t count;                /**< sample pairs accepted */
    uint64_t n_nonfinite;          /**< pairs dropped for NaN/Inf */
} dv_arx_resid_t;

/**
 * @brief Bind a model and storage, clear the history.
 * @param[out] r instance
 * @param[in] m fitted model (copied)
 * @param[in] buf DV_ARX_RESID_BUF_LEN(na, nb, nk) elements; outlives @p r
 * @param[in] buf_len elements in @p buf
 * @retval DV_OK / DV_EINVAL (NULL, orders out of range) / DV_ESIZE / DV_ENUMERIC (non-finite
 *         coefficient)
 */
dv_status_t dv_arx_resid_init(dv_arx_resid_t *r, const dv_arx_model_t *m, dv_real_t *buf,
                              size_t buf_len);

/** @brief Forget the history and counters. */
void dv_arx_resid_reset(dv_arx_resid_t *r);

/**
 * @brief Push one (output, input) pair; e_i once max(na, nk + nb - 1) pairs precede it.
 * @param[in,out] r instance
 * @param[in] x output sample
 * @param[in] f input sample
 * @param[out] e residual, written only on DV_OK
 * @retval DV_OK        @p e written
 * @retval DV_ENOTREADY history not full yet: pair stored, @p e untouched
 * @retval DV_ENUMERIC  @p x or @p f NaN/Inf: pair dropped and counted, state unchanged
 */
dv_status_t dv_arx_resid_update(dv_arx_resid_t *r, dv_real_t x, dv_real_t f, dv_real_t *e);

/** @brief Pairs dropped since init/reset (0 for NULL). */
uint64_t dv_arx_resid_nonfinite(const dv_arx_resid_t *r);

#ifdef __cplusplus
}
#endif

#endif /* DV_ARX_H */

/**
 * @file dv_obs.h
 * @brief Fixed-step observer of a dv_model_t: open-loop prediction, optional constant
 *        (steady-state Kalman) correction, and the residual measured - predicted per channel.
 *
 * One call per sample k with the input u[k] and the measured outputs y[k]:
 *   x-[k]  = Ad x[k-1] + Pa u[k-1] + Pb u[k] + V g[k]      (exact first-order hold, contacts
 *                                                         through sub-node forces g[k])
 *   yhat[k] = Cy x-[k] + D0 u[k] + D1 u[k-1] + Ey g_end[k]  (prediction)
 *   r[k]   = y[k] - yhat[k]                               (residual / innovation)
 *   x[k]   = x-[k] + L r[k]                               (L = 0: open loop)
 * All of it is one column-major matrix-vector product over [x, u[k-1], u[k], g, y] with the
 * gain folded in, so the cost per step is fixed. The first sample only evaluates the output
 * (the structure is at rest at t = 0, x = 0). L is the steady-state Kalman gain of the linear
 * part for a white force of variance q at each DOF (held over a sample) and white measurement
 * noise of variance r per channel, from the filter DARE solved by the structure-preserving
 * doubling algorithm at init, or set by the caller.
 *
 * On x86-64 double builds the step uses AVX2/AVX-512 kernels picked at init; with AVX-512 the
 * linear 4-DOF, 4-output first-order-hold step keeps its state in modal coordinates q = T^-1 x
 * (the folded state block in real 2 x 2 block-diagonal form, src/dv_obs_modal.c), which halves
 * it.
 * dv_obs_get_state() returns x in every case; results agree with the portable code to rounding.
 *
 * Cubic input hold (model built with DV_HOLD_CUBIC, dv_model.h): the step from t_k-1 to t_k
 * needs u[k-2..k+1], so the observer runs ONE SAMPLE LATE (dv_obs_latency() = 1). The call
 * with u[j], y[j] keeps y[j] and completes sample k = j - 1: x-[k], yhat[k], the residual
 * r[k] = y[k] - yhat[k] against the measurement y[k] of the PREVIOUS call, and the correction.
 * dv_obs_get() after that call therefore returns sample j - 1 (DV_ENOTREADY after the first
 * call). The residual stays paired with the measured sample it belongs to; only its delivery is
 * one call late. dv_obs_update_block() writes, per call, what dv_obs_get() returns after it
 * (row j holds sample j - 1); dv_obs_simulate() realigns (row k holds sample k) and completes
 * the last sample with dv_obs_flush(). The input is 0 before the first sample.
 */
#ifndef DV_OBS_H
#define DV_OBS_H

#include "dynval/dv_types.h"
#include "dynval/dv_config.h"
#include "dynval/dv_model.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Largest number of doubling steps of the DARE solver (each doubles the horizon). */
#define DV_OBS_DARE_MAX_ITER 80u

/** Bits of dv_obs_t.flags after a step. */
#define DV_OBS_FLAG_BAD_INPUT 0x1u /**< u was NaN/Inf: nothing changed */
#define DV_OBS_FLAG_BAD_MEAS 0x2u  /**< a measured channel was NaN/Inf: predicted, not corrected */
#define DV_OBS_FLAG_NO_MEAS 0x4u   /**< no measurement given: predicted only */

/** @brief Noise model for the steady-state Kalman gain. */
typedef struct {
    dv_real_t q_force_n2[DV_MAX_DOF]; /**< variance of a white force at each DOF, N^2, >= 0 */
    dv_real_t r_meas[DV_MAX_OUT];     /**< measurement noise variance per output, > 0 */
} dv_obs_noise_t;

/** The modal form of the AVX-512 step applies to this model: 4 DOFs, at most one contact
 *  element with at most 24 sub-nodes, 4 outputs, first-order hold (@p nin 2). */
#define DV_OBS_MODAL_FITS(n, nc, nsub, nout, nin)                                              \
    ((n) == 4u && (nc) <= 1u && DV_MODEL_NF(nc, nsub) <= 24u && (nout) == 4u && (nin) == 2u)

/** Storage of the modal form of the 4-DOF, 4-output step, in elements: T and the step's blocks
 *  and prediction rows (112), with a contact element its sub-node X rows in modal coordinates
 *  (10 columns of 8 per block of 8 sub-nodes), and 28 of slack to put the step's vectors on
 *  64-byte lines (layout: struct dv_obs_modal, src/dv_obs_priv.h). Only the AVX-512 step of
 *  x86-64 builds uses it, a choice the library makes at run time; every double build reserves
 *  it whatever the compiler, CPU or DV_NO_SIMD, so the size depends on nothing but dv_real_t
 *  (which must match the library's anyway). Float builds never use it and reserve nothing. */
#ifdef DV_REAL_DOUBLE
#define DV_OBS_MODAL_LEN(n, nc, nsub, nout, nin)                                                \
    (DV_OBS_MODAL_FITS(n, nc, nsub, nout, nin)                                                \
         ? 140u + (DV_MODEL_NS(n) + 2u) * ((DV_MODEL_NF(nc, nsub) + 7u) / 8u * 8u)            \
         : 0u)
#else
#define DV_OBS_MODAL_LEN(n, nc, nsub, nout, nin) 0u
#endif

/** Persistent storage of an observer with @p nin input samples per step
 *  (DV_MODEL_HOLD_NIN()), in elements: state vector, prediction, residual, the folded step
 *  matrix, the gain and (cubic) the kept measurement. Only this much of the caller's storage
 *  is used after dv_obs_init()/dv_obs_init_ex() returns. */
#define DV_OBS_PERSIST_LEN_HOLD(n, nc, nsub, nout, nin)                                         \
    ((DV_MODEL_NS(n) + (nout)) *                                                              \
         ((DV_MODEL_NS(n) + (nin) + DV_MODEL_NF(nc, nsub)) + (nout) + 1u) +                   \
     DV_MODEL_NS(n) + (nin) + DV_MODEL_NF(nc, nsub) + 2u * (nout) +                           \
     DV_MODEL_NS(n) * (nout) + ((nin) - 2u) / 2u * (nout) +                                   \
     DV_OBS_MODAL_LEN(n, nc, nsub, nout, nin))

/** Init-time scratch of dv_obs_init_ex() with a noise model (the exponential for the process
 *  noise and the DARE), in elements; dead once init returns (see DV_MODEL_SCRATCH_LEN_HOLD()).
 *  Only @p n and @p nout matter; the other arguments keep the family's signature. */
#define DV_OBS_SCRATCH_LEN_HOLD(n, nc, nsub, nout, nin)                                         \
    (7u * (DV_MODEL_NS(n) + (n)) * (DV_MODEL_NS(n) + (n)) +                                   \
     (nout) * (DV_MODEL_NS(n) + (nout)) + 64u)

/** Storage for dv_obs_init() (one buffer: the persistent part first, then the init scratch)
 *  with @p nin input samples per step, in elements. */
#define DV_OBS_BUF_LEN_HOLD(n, nc, nsub, nout, nin)                                             \
    (DV_OBS_PERSIST_LEN_HOLD(n, nc, nsub, nout, nin) +                                         \
     DV_OBS_SCRATCH_LEN_HOLD(n, nc, nsub, nout, nin))

/** Storage for dv_obs_init() with the default first-order hold, in elements. */
#define DV_OBS_BUF_LEN(n, nc, nsub, nout) DV_OBS_BUF_LEN_HOLD(n, nc, nsub, nout, 2u)
/** Persistent storage with the default first-order hold, in elements. */
#define DV_OBS_PERSIST_LEN(n, nc, nsub, nout) DV_OBS_PERSIST_LEN_HOLD(n, nc, nsub, nout, 2u)
/** Init scratch (either hold), in elements. */
#define DV_OBS_SCRATCH_LEN(n, nc, nsub, nout) DV_OBS_SCRATCH_LEN_HOLD(n, nc, nsub, nout, 2u)

/** @brief Vector kernel of the observer's step, chosen at init from the CPU (dv_obs_t.kern). */
typedef enum {
    DV_OBS_KERN_C = 0,     /**< portable C */
    DV_OBS_KERN_AVX2 = 1,  /**< AVX2 + FMA (x86-64 double builds) */
    DV_OBS_KERN_AVX512 = 2 /**< AVX-512: the modal step where it applies (DV_OBS_MODAL_FITS()) */
} dv_obs_kern_t;

/** @brief What dv_obs_step() runs for a regular sample (dv_obs_t.path). */
typedef enum {
    DV_OBS_PATH_GENERAL = 0,  /**< any sizes, the first sample, the cubic hold */
    DV_OBS_PATH_DIRECT,       /**< 8 states, 4 outputs, first-order hold, past the first sample */
    DV_OBS_PATH_MODAL,        /**< the AVX-512 modal step, linear */
    DV_OBS_PATH_MODAL_CONTACT /**< the AVX-512 modal step with one gap element */
} dv_obs_path_t;

struct dv_obs_modal; /* the modal form's layout: src/dv_obs_priv.h */

/** @brief Observer instance. Fields are private; arrays point into the caller's buffer. */
typedef struct {
    const dv_model_t *m; /**< the model (must outlive the observer) */
    uint16_t ns;         /**< states */
    uint16_t no;         /**< outputs */
    uint16_t nf;         /**< sub-node element forces */
    uint16_t nrows;      /**< ns + no: rows of the folded matrix */
    uint16_t nin;        /**< input samples in the state vector: 2 (FOH) or 4 (cubic) */
    uint16_t ncol_open;  /**< ns + nin + nf */
    uint16_t ncol_gain;  /**< ns + nin + nf + no */
    bool has_gain;       /**< L != 0 */
    bool started;        /**< the first sample has been seen */
    bool modal;          /**< the state is kept as q = T^-1 x, the folded rows in that basis */
    bool contact_hot;    /**< the last direct-path contact step engaged: the next measured
                              step skips the AVX-512 open check (dv_obskern.c) */
    dv_obs_kern_t kern;  /**< the 8 x 4 step's kernel (AVX-512 only where the modal form
                              fits; AVX2 otherwise) */
    dv_obs_path_t path;  /**< dv_obs_step()'s dispatch, from the sizes, kern, modal, started */
    uint32_t flags;      /**< DV_OBS_FLAG_* of the last step */
    uint64_t n_steps;    /**< accepted steps */
    uint64_t n_bad_input; /**< steps refused for a NaN/Inf input */
    uint64_t n_bad_meas;  /**< steps with a NaN/Inf measured channel */
    uint64_t n_pred;      /**< predictions produced (n_steps, or n_steps - 1 with latency) */
    uint32_t pend_flags;  /**< cubic: DV_OBS_FLAG_* of the kept measurement */
    dv_real_t *sv;       /**< [x (ns), u window (nin), g (nf), y (no)] */
    dv_real_t *ypend;    /**< cubic: the kept measurement (no), else NULL */
    dv_real_t *z;        /**< [x (ns), yhat (no)] product */
    dv_real_t *resid;    /**< no residuals of the last step */
    dv_real_t *f;        /**< folded step: ns x ncol_gain state rows (gain folded in, y columns
                              L; zeros in open loop), then no x ncol_open output rows, each
                              column-major */
    dv_real_t *gain;     /**< L, ns x no row-major */
    struct dv_obs_modal *modal_form; /**< T, Lam's blocks, C T and (with a contact) its sub-node
                                          rows over q; NULL where it never applies */
    dv_real_t elem_x[DV_MAX_ELEM]; /**< stick-slip elements: X at the last sub-node, m */
    dv_real_t elem_g[DV_MAX_ELEM]; /**< stick-slip elements: force at the last sub-node, N */
} dv_obs_t;

/**
 * @brief Storage dv_obs_init() needs for model @p m, in elements
 *        (dv_obs_persistent_len() + dv_obs_scratch_len()).
 * @return DV_OBS_BUF_LEN_HOLD() for the model's sizes, or 0 when @p m is NULL or not built
 */
size_t dv_obs_buf_len(const dv_model_t *m);

/**
 * @brief Elements of storage the observer keeps for its lifetime
 *        (DV_OBS_PERSIST_LEN_HOLD()): after dv_obs_init() returns, only the first
 *        dv_obs_persistent_len(m) elements of its buffer are used; the caller may reuse the rest.
 * @return the length, or 0 when @p m is NULL or not built
 */
size_t dv_obs_persistent_len(const dv_model_t *m);

/**
 * @brief Elements of init-time scratch dv_obs_init_ex() needs with a noise model
 *        (DV_OBS_SCRATCH_LEN_HOLD()).
 * @return the length, or 0 when @p m is NULL or not built
 */
size_t dv_obs_scratch_len(const dv_model_t *m);

/**
 * @brief Bind an observer to a built model; with @p noise, solve for the Kalman gain.
 * @param[out] o      observer
 * @param[in]  m      built model (dv_model_init()); must outlive @p o
 * @param[in]  noise  noise model for the gain, or NULL for open loop (L = 0)
 * @param[in]  buf    storage of dv_obs_buf_len(m) elements: the first dv_obs_persistent_len(m)
 *                    must outlive @p o; the rest is init-time scratch, free for the caller
 *                    again when this returns
 * @param[in]  len    elements in @p buf
 * @retval DV_OK        ready; state at rest
 * @retval DV_EINVAL    NULL @p o, @p m or @p buf, model not built or kept for steps only
 *                      (dv_model_keep_step_only()), a negative or non-finite q, or an r <= 0
 *                      or non-finite
 * @retval DV_ESIZE     @p len too small
 * @retval DV_EUNSTABLE the DARE did not converge or is singular, or the gain it gave does not
 *                      hold the filter: an eigenvalue of (I - L Cy) Ad outside the unit disc
 *                      by more than 16 sqrt(eps). A mode the outputs do not see (a free
 *                      rigid-body mode seen only through accelerations) keeps its eigenvalue
 *                      1 whatever the gain: such a gain is returned when it holds the rest,
 *                      and the estimate drifts along that mode as the open loop would; the
 *                      doubling may also refuse it (no stabilising DARE solution exists)
 */
dv_status_t dv_obs_init(dv_obs_t *o, const dv_model_t *m, const dv_obs_noise_t *noise,
                        dv_real_t *buf, size_t len);

/**
 * @brief dv_obs_init() with the init-time scratch apart from the observer's storage: @p buf
 *        only needs the persistent part, and @p scratch is free again when this returns (it
 *        may be the same area given to dv_model_init_ex()).
 * @param[out] o            observer
 * @param[in]  m            built model; must outlive @p o
 * @param[in]  noise        noise model for the gain, or NULL for open loop (L = 0)
 * @param[in]  buf          dv_obs_persistent_len(m) elements; must outlive @p o
 * @param[in]  len          elements in @p buf
 * @param[in]  scratch      dv_obs_scratch_len(m) elements, not overlapping @p buf (may be NULL
 *                          when @p noise is NULL); contents destroyed, not used after the call
 * @param[in]  scratch_len  elements in @p scratch
 * @retval DV_OK        ready; state at rest
 * @retval DV_EINVAL    as dv_obs_init(), or @p scratch NULL with @p noise given
 * @retval DV_ESIZE     @p len or (with @p noise) @p scratch_len too small
 * @retval DV_EUNSTABLE as dv_obs_init()
 */
dv_status_t dv_obs_init_ex(dv_obs_t *o, const dv_model_t *m, const dv_obs_noise_t *noise,
                           dv_real_t *buf, size_t len, dv_real_t *scratch,
                           size_t scratch_len);

/**
 * @brief Set the correction gain L (or remove it) and refold the step matrix.
 * @param[in,out] o     observer
 * @param[in]     gain  L, ns x no row-major (x += L r), or NULL for open loop
 * @param[in]     len   elements in @p gain (>= ns * no unless NULL)
 * @retval DV_OK       set; the state is kept
 * @retval DV_EINVAL   @p o NULL or not initialised, a non-finite gain element, or the model kept
 *                     for steps only (dv_model_keep_step_only())
 * @retval DV_ESIZE    @p len too small
 */
dv_status_t dv_obs_set_gain(dv_obs_t *o, const dv_real_t *gain, size_t len);

/**
 * @brief Copy the gain L (zeros in open loop).
 * @retval DV_OK     copied, ns * no elements
 * @retval DV_EINVAL NULL argument
 * @retval DV_ESIZE  @p len < ns * no
 */
dv_status_t dv_obs_get_gain(const dv_obs_t *o, dv_real_t *gain, size_t len);

/** @brief Back to rest: x = 0, no previous input, counters cleared; the gain is kept. */
void dv_obs_reset(dv_obs_t *o);

/**
 * @brief Set the state x = [displacements (m); velocities (m/s)] at the next sample given:
 *        after dv_obs_reset(), the start of a record that does not start at rest (a segment
 *        cut from a running test). Relative to the ground for a ground-motion input, as
 *        dv_obs_get_state(), which after a sample gives the state at that sample (so a run
 *        goes on from it bit for bit with that sample given again). The input window and the
 *        stick-slip elements' internal state are kept (at rest after a reset).
 * @param[in,out] o    observer
 * @param[in]     x    2n elements, finite
 * @param[in]     len  elements in @p x (>= 2n)
 * @retval DV_OK       set
 * @retval DV_EINVAL   @p o or @p x NULL, a non-finite element, or a model kept for steps only
 *                     (dv_model_keep_step_only()) whose state is kept in modal coordinates
 * @retval DV_ESIZE    @p len < 2n
 */
dv_status_t dv_obs_set_state(dv_obs_t *o, const dv_real_t *x, size_t len);

/**
 * @brief One sample: predict, form the residual, correct (see the file comment).
 * @param[in,out] o       observer
 * @param[in]     u       input at this sample (N, m/s^2 or m, per the model)
 * @param[in]     y_meas  no measured outputs, or NULL to predict only
 * @retval DV_OK       done; dv_obs_get() gives the prediction and residual
 * @retval DV_ENUMERIC @p u is NaN/Inf: state, prediction and residual held (flag
 *                     DV_OBS_FLAG_BAD_INPUT); or a measured channel is NaN/Inf: predicted
 *                     without correction, that channel's residual set to 0 (flag
 *                     DV_OBS_FLAG_BAD_MEAS)
 * @retval DV_EUNSTABLE the model has elements and its state is no longer finite: it ran away
 *                     (a softening cubic spring driven past its peak force, an element too
 *                     stiff for the sub-steps); the predictions from here on are not finite
 *                     until dv_obs_reset()
 */
dv_status_t dv_obs_step(dv_obs_t *o, dv_real_t u, const dv_real_t *y_meas);

/**
 * @brief Samples of delay between an input and its prediction: 0 (first-order hold) or 1
 *        (cubic hold: the call with u[j] completes sample j - 1).
 * @return the latency; 0 when @p o is NULL
 */
uint32_t dv_obs_latency(const dv_obs_t *o);

/**
 * @brief Cubic hold: complete the pending sample (the last one given to dv_obs_step()) now,
 *        with the next input extrapolated (u[j+1] = 3 u[j] - 3 u[j-1] + u[j-2], the quadratic
 *        through the last three samples) and its kept measurement. Only the prediction and the
 *        residual change (dv_obs_get()); the state is not advanced, so steps may continue and
 *        the sample is predicted again, exactly, when its real next input arrives.
 * @retval DV_OK        done
 * @retval DV_ENOTREADY no sample pending (first-order hold, or no step since the reset)
 * @retval DV_EINVAL    @p o NULL
 */
dv_status_t dv_obs_flush(dv_obs_t *o);

/**
 * @brief Prediction and residual of the last step.
 * @param[in] o observer
 * @param[out] y_pred  no predicted outputs, or NULL
 * @param[out] resid   no residuals (0 where no finite measurement), or NULL
 * @param[in]  len     elements available in each non-NULL array
 * @retval DV_OK        copied
 * @retval DV_ENOTREADY no step yet; outputs untouched
 * @retval DV_EINVAL    @p o NULL
 * @retval DV_ESIZE     @p len < no
 */
dv_status_t dv_obs_get(const dv_obs_t *o, dv_real_t *y_pred, dv_real_t *resid, size_t len);

/**
 * @brief The state estimate x = [displacements; velocities] (2n elements).
 * @retval DV_OK / DV_EINVAL (NULL) / DV_ESIZE (len < 2n)
 */
dv_status_t dv_obs_get_state(const dv_obs_t *o, dv_real_t *x, size_t len);

/**
 * @brief Run @p n samples through dv_obs_step(), continuing from the current state (the same
 *        results bit for bit; x86-64 with AVX-512 runs the linear 4-DOF steps in one loop).
 * @param[in,out] o       observer
 * @param[in]     u       n inputs
 * @param[in]     y_meas  n x no measured outputs, row-major, or NULL (prediction only)
 * @param[in]     n       samples
 * @param[out]    y_pred  n x no predictions, row-major, or NULL; a refused sample (NaN
 *                        input) repeats the previous row (0 before the first). With the
 *                        cubic hold row j is what dv_obs_get() gives after the call with
 *                        u[j]: the prediction of sample j - 1 (see the file comment)
 * @param[out]    resid   n x no residuals, row-major, or NULL
 * @retval DV_OK       all samples accepted
 * @retval DV_ENUMERIC at least one sample had a NaN/Inf input or measurement (see
 *                     dv_obs_step(); the others were processed)
 * @retval DV_EUNSTABLE the state is not finite at the end of the block: the model ran away
 *                     (see dv_obs_step()); the rows from there on are not finite
 * @retval DV_EINVAL   @p o or @p u NULL with @p n > 0
 */
dv_status_t dv_obs_update_block(dv_obs_t *o, const dv_real_t *u, const dv_real_t *y_meas,
                                size_t n, dv_real_t *y_pred, dv_real_t *resid);

/**
 * @brief Simulate a record from rest, open loop (the gain is ignored): reset, then the
 *        same step code as dv_obs_step() for each sample. Row k is sample k for either hold
 *        (cubic: the outputs are realigned and the last sample is completed as
 *        dv_obs_flush() does).
 * @param[in,out] o       observer (its state is left at the end of the record)
 * @param[in]     u       n inputs
 * @param[in]     n       samples
 * @param[out]    y       n x no outputs, row-major
 * @retval DV_OK / DV_ENUMERIC / DV_EUNSTABLE / DV_EINVAL as dv_obs_update_block() (@p y NULL
 *         is DV_EINVAL)
 */
dv_status_t dv_obs_simulate(dv_obs_t *o, const dv_real_t *u, size_t n, dv_real_t *y);

#ifdef __cplusplus
}
#endif

#endif /* DV_OBS_H */

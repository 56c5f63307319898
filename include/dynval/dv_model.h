/**
 * @file dv_model.h
 * @brief n-DOF lumped-mass chain with nonlinear elements (report Section 4.1, eq. 1-7, 45-46),
 *        built at init: eigen-solution, damping, and an exact first-order-hold discretisation.
 *
 * Equations of motion (eq. 1-2): M x'' + C x' + K x = f(t) + f_elem(x, x').
 * - Chain: DOF i (0-based) has mass m_i > 0. Story spring k_0 ties DOF 0 to the ground
 *   (k_0 = 0 leaves the chain free, with a rigid-body mode), k_i (i >= 1) ties DOF i-1 to
 *   DOF i. K is the tridiagonal matrix of eq. 2.
 * - Links (off the chain): a linear spring k and dashpot c between any two DOFs a != b (not
 *   the ground), added to K and to C after the declared damping is formed (modal and Rayleigh
 *   damping are built on the modes of K with the links): an appendage on its own DOF (its
 *   story spring 0, a link to the DOF it hangs from), a coupling of DOFs that are not
 *   neighbours. They act on relative motion, so every input kind sees them alike.
 * - Damping: DV_DAMP_MODAL: C = M Phi diag(2 zeta_k w_k) Phi^T M with mass-normalised modes
 *   (Phi^T M Phi = I), which is eq. 5 since Phi^-1 = Phi^T M; DV_DAMP_RAYLEIGH: C = a M + b K
 *   with a, b from two modal ratios (eq. 45-46: zeta_k = a / (2 w_k) + b w_k / 2);
 *   DV_DAMP_MATRIX: C given (symmetric, N s/m). Damping acts on velocities relative to the
 *   ground frame.
 * - Input (one scalar per sample, u):
 *   DV_INPUT_FORCE: a force u (N) at DOF input_dof; states are absolute.
 *   DV_INPUT_GROUND_ACC: ground acceleration u (m/s^2); states are relative to the ground
 *   (z = x - x_g), M z'' + C z' + K z = -M 1 u. Acceleration outputs are absolute; velocity and
 *   displacement outputs are relative to the ground.
 *   DV_INPUT_GROUND_DISP: ground displacement u (m), e.g. an actuator stroke; states are
 *   absolute and the ground elements see x - x_g: f = K 1 u + C 1 u'. u' is the slope of the
 *   first-order-hold interpolant (exact for it); outputs that depend on u' use the slope of the
 *   interval that ends at the sample.
 * - Elements (dv_elem.h: the laws and their parameters) between DOF a and DOF b or the ground
 *   (a = DV_GROUND), on X = x_b - x_a or V = v_b - v_a, with x_ground = 0 (or u, and
 *   v_ground = u', for DV_INPUT_GROUND_DISP; 0 in the relative coordinates of
 *   DV_INPUT_GROUND_ACC). Each pushes DOF a by +g and DOF b by -g. init checks the sub-step
 *   against the stiffest element: with every element at its dv_elem_stiffness_bound() (contact
 *   kB, stick-slip F / z) the highest natural frequency w must keep w h <= DV_MODEL_ELEM_MAX_WH
 *   (h = T / n_sub); a friction element's slope F / eps (dv_elem_damping_bound()) must keep
 *   F / eps h (1/m_a + 1/m_b) under the same bound (the fixed-point iterations contract). The
 *   cubic law's tangent stiffness 3 k3 X^2 is not checked: keep it of the order of that limit.
 *   The observer keeps the stick-slip law's history (dv_obs_t; zero after reset).
 *
 * Discretisation, sample period T: the linear part is exact for an input linear between
 * samples (first-order hold), from the exponential of the augmented matrix
 * [[A T, B T, 0], [0, 0, I], [0, 0, 0]] = [[Ad, G0, G1], ...], giving
 * x[k+1] = Ad x[k] + (G0 - G1) u[k] + G1 u[k+1]. The element forces are extra inputs with
 * the same hold on n_sub sub-intervals of h = T / n_sub: at each sub-node the relative
 * displacements are predicted exactly from the state, the input and the earlier sub-node
 * forces, and the implicit force at the node is resolved by fixed-point iterations, a fixed
 * number, so a step always costs the same: DV_MODEL_FP_ITERS at the step's second node (started
 * from the first node's force), one at each later node, started from the line through the two
 * previous nodes' forces (that start is already O(h^2) close, the order of the scheme; a second
 * iteration changes the error by a few per cent). The end state adds all sub-node forces through
 * precomputed columns. Error: O((w_c h)^2) in the element force's effect, w_c the element
 * stiffened frequency; init refuses w_max h > DV_MODEL_ELEM_MAX_WH.
 *
 * Input hold (desc.input_hold). DV_HOLD_FOH (default): u linear between samples, as above.
 * DV_HOLD_CUBIC: over the interval [t_k, t_k+1] u is the cubic (Lagrange) interpolant through
 * u[k-1], u[k], u[k+1], u[k+2]; with s = (t - t_k) / T,
 *     u(s) = u[k] + s (-u[k-1]/3 - u[k]/2 + u[k+1] - u[k+2]/6)
 *                 + s^2 (u[k-1]/2 - u[k] + u[k+1]/2) + s^3 (-u[k-1] + 3 u[k] - 3 u[k+1] + u[k+2])/6,
 * exact for an input that is a cubic polynomial, and for a band-limited (sampled) force far
 * closer to the continuous signal than the linear interpolant (which attenuates a component at
 * frequency f by about sinc^2(f T)). It is discretised exactly, from the exponential of
 * [[A T, B T, 0, 0, 0], [0, 0, I, 0, 0], [0, 0, 0, I, 0], [0, 0, 0, 0, I], [0, 0, 0, 0, 0]]
 * (top row: Ad and G_p = int_0^1 e^{A T (1 - s)} B T s^p / p! ds, p = 0..3), giving
 * x[k+1] = Ad x[k] + sum_{j=0..3} Pu_j u[k-1+j]. u' (ground displacement) is the derivative
 * of the cubic; outputs that need u' at t_k use the interval that ends at t_k. The sub-step
 * element scheme sees the same cubic input. The input is 0 before the first sample (the
 * structure at rest). The price is one sample of latency in the observer (dv_obs.h): the
 * state at t_k and the prediction of y[k] need u[k+1].
 */
#ifndef DV_MODEL_H
#define DV_MODEL_H

#include "dynval/dv_types.h"
#include "dynval/dv_elem.h"
#include "dynval/dv_config.h"
#include "dynval/dv_mat.h"

#ifdef __cplusplus
extern "C" {
#endif

/** DOF index that stands for the ground in an element. */
enum { DV_GROUND = 65535 };

/** Fixed-point iterations that resolve the implicit element force at a step's second sub-node
 *  (the later nodes take one, from an extrapolated start: see the file comment). */
#define DV_MODEL_FP_ITERS 2u

/** Largest (highest natural frequency with every element at its stiffness bound, rad/s) x (dt / n_sub). */
#define DV_MODEL_ELEM_MAX_WH 1.0

/** How the damping matrix is given. */
typedef enum {
    DV_DAMP_MODAL = 0,    /**< modal ratios zeta[k] per mode, ascending frequency (eq. 3-5) */
    DV_DAMP_RAYLEIGH = 1, /**< C = a M + b K from two modal ratios (eq. 45-46) */
    DV_DAMP_MATRIX = 2    /**< explicit symmetric matrix c_n_s_per_m */
} dv_damp_kind_t;

/** What the scalar input u is. */
typedef enum {
    DV_INPUT_FORCE = 0,      /**< force at input_dof, N */
    DV_INPUT_GROUND_ACC = 1, /**< ground acceleration, m/s^2 */
    DV_INPUT_GROUND_DISP = 2 /**< ground displacement, m */
} dv_input_kind_t;

/** How the input is interpolated between samples (see the file comment). */
typedef enum {
    DV_HOLD_FOH = 0,  /**< linear between samples (first-order hold); no latency */
    DV_HOLD_CUBIC = 1 /**< cubic through 4 samples (Lagrange); one sample of latency */
} dv_input_hold_t;

/** Output channel kinds. */
typedef enum {
    DV_OUT_ACC = 0,       /**< acceleration of DOF index, m/s^2 (absolute) */
    DV_OUT_VEL = 1,       /**< velocity of DOF index, m/s */
    DV_OUT_DISP = 2,      /**< displacement of DOF index, m */
    DV_OUT_SPRING_FORCE = 3, /**< story spring index: k_i (x_i - x_{i-1}), N (x_{-1} = ground) */
    DV_OUT_ELEM_FORCE = 4, /**< element index: its force g, N (dv_elem.h) */
    DV_OUT_REACTION = 5   /**< force of the structure on the ground, N (index ignored) */
} dv_out_kind_t;

/** @brief One output channel. */
typedef struct {
    dv_out_kind_t kind; /**< what */
    uint16_t index;     /**< DOF, story or element index (0-based) */
} dv_out_desc_t;

/** @brief A linear spring and dashpot between two DOFs, off the chain (see the file comment):
 *         force k (x_b - x_a) + c (v_b - v_a) on DOF a, its opposite on DOF b. */
typedef struct {
    uint16_t dof_a;        /**< first DOF (0-based), < n_dof (not the ground) */
    uint16_t dof_b;        /**< second DOF (0-based), < n_dof, != dof_a */
    dv_real_t k_n_per_m;   /**< stiffness, N/m, finite, >= 0 */
    dv_real_t c_n_s_per_m; /**< viscous damping, N s/m, finite, >= 0 */
} dv_link_desc_t;

/** @brief Declarative model description (plain data; fill it, then dv_model_init()). */
typedef struct {
    uint16_t n_dof;                          /**< 1..DV_MAX_DOF */
    dv_real_t mass_kg[DV_MAX_DOF];           /**< masses, kg, > 0 */
    dv_real_t k_n_per_m[DV_MAX_DOF];         /**< k[0]: ground-DOF0 (>= 0); k[i]: DOF i-1..i */
    dv_damp_kind_t damp_kind;                /**< how damping is given */
    dv_real_t zeta[DV_MAX_DOF];              /**< DV_DAMP_MODAL: ratio per mode, >= 0 */
    uint16_t rayleigh_mode[2];               /**< DV_DAMP_RAYLEIGH: two mode indices (0-based) */
    dv_real_t rayleigh_zeta[2];              /**< DV_DAMP_RAYLEIGH: their ratios */
    dv_real_t c_n_s_per_m[DV_MAX_DOF * DV_MAX_DOF]; /**< DV_DAMP_MATRIX: n x n, stride n */
    dv_input_kind_t input_kind;              /**< what u is */
    uint16_t input_dof;                      /**< DV_INPUT_FORCE: the loaded DOF */
    uint16_t n_elem;                      /**< 0..DV_MAX_ELEM */
    dv_elem_desc_t elem[DV_MAX_ELEM];   /**< nonlinear elements */
    uint16_t n_sub;                          /**< element sub-steps per sample, 1..DV_MAX_SUB */
    uint16_t n_out;                          /**< 1..DV_MAX_OUT */
    dv_out_desc_t out[DV_MAX_OUT];           /**< output channels, in order */
    dv_input_hold_t input_hold;              /**< DV_HOLD_FOH (default) or DV_HOLD_CUBIC */
    uint16_t n_link;                         /**< 0..DV_MAX_LINK (0 by default) */
    dv_link_desc_t link[DV_MAX_LINK];        /**< linear links off the chain */
} dv_model_desc_t;

/** State size (2 n: displacements then velocities). */
#define DV_MODEL_NS(n) (2u * (n))
/** Sub-node element forces per step. */
#define DV_MODEL_NF(nc, nsub) (((nsub) + 1u) * (nc))
/** Size of the augmented matrix exponentiated at init (first-order hold). */
#define DV_MODEL_NAUG(n, nc) (2u * (n) + 4u + 2u * (nc))
/** Input samples per step of a hold: 2 (DV_HOLD_FOH) or 4 (DV_HOLD_CUBIC). */
#define DV_MODEL_HOLD_NIN(hold) ((hold) == 1 ? 4u : 2u)
/** Size of the augmented matrix exponentiated at init, for @p nin input samples per step. */
#define DV_MODEL_NAUG_HOLD(n, nc, nin) (2u * (n) + (nin) * (2u + (nc)))

/**
 * Persistent storage of a model with @p nin input samples per step (DV_MODEL_HOLD_NIN()), in
 * elements: the matrices the model keeps for its lifetime (K, C, modes, A, Ad, B, the hold,
 * output and element sub-node matrices), for @p n DOF, @p nc elements, @p nsub sub-steps and
 * @p nout outputs (nc = 0 needs no sub-step storage). Only this much of the caller's storage
 * is used after dv_model_init()/dv_model_init_ex() returns.
 */
#define DV_MODEL_PERSIST_LEN_HOLD(n, nc, nsub, nout, nin)                                       \
    (3u * (n) * (n) + 2u * DV_MODEL_NS(n) * DV_MODEL_NS(n) +                                  \
     DV_MODEL_NS(n) * (4u + (nc)) + (nout) * (DV_MODEL_NS(n) + 2u + (nc)) +                   \
     DV_MODEL_NF(nc, nsub) * (2u * DV_MODEL_NS(n) + 2u + DV_MODEL_NF(nc, nsub)) +             \
     ((nin) - 2u) * (DV_MODEL_NS(n) + (nout) + DV_MODEL_NF(nc, nsub)) * 2u)

/**
 * The part of the persistent storage a bound observer's steps still read (output, element
 * sub-node and, cubic, hold matrices), in elements: the first this many elements of the
 * model's storage. After dv_model_keep_step_only() only these stay in use.
 */
#define DV_MODEL_STEP_LEN_HOLD(n, nc, nsub, nout, nin)                                          \
    ((nout) * (DV_MODEL_NS(n) + 2u + (nc)) +                                                  \
     DV_MODEL_NF(nc, nsub) * (DV_MODEL_NS(n) + 2u + DV_MODEL_NF(nc, nsub)) +                  \
     ((nin) - 2u) * 2u * ((nout) + DV_MODEL_NF(nc, nsub)))
/** DV_MODEL_STEP_LEN_HOLD() with the default first-order hold. */
#define DV_MODEL_STEP_LEN(n, nc, nsub, nout) DV_MODEL_STEP_LEN_HOLD(n, nc, nsub, nout, 2u)

/**
 * Init-time scratch of dv_model_init_ex(), in elements (eigen-solutions, the exponential of the
 * augmented matrix and the sub-step response): dead once init returns, so one scratch area can
 * serve several inits (e.g. dv_model_init_ex() then dv_obs_init_ex()) and be reused after.
 */
#define DV_MODEL_SCRATCH_LEN_HOLD(n, nc, nsub, nout, nin)                                       \
    (7u * DV_MODEL_NAUG_HOLD(n, nc, nin) * DV_MODEL_NAUG_HOLD(n, nc, nin) +                   \
     DV_MODEL_NS(n) * (2u * DV_MODEL_NS(n) + 2u * (2u + (nc)) + 7u) + 64u)

/**
 * Storage for dv_model_init() (one buffer: the persistent part first, then the init scratch),
 * with @p nin input samples per step, in elements.
 */
#define DV_MODEL_BUF_LEN_HOLD(n, nc, nsub, nout, nin)                                           \
    (DV_MODEL_PERSIST_LEN_HOLD(n, nc, nsub, nout, nin) +                                       \
     DV_MODEL_SCRATCH_LEN_HOLD(n, nc, nsub, nout, nin))

/** Storage for dv_model_init() with the default first-order hold, in elements. */
#define DV_MODEL_BUF_LEN(n, nc, nsub, nout) DV_MODEL_BUF_LEN_HOLD(n, nc, nsub, nout, 2u)
/** Persistent storage with the default first-order hold, in elements. */
#define DV_MODEL_PERSIST_LEN(n, nc, nsub, nout) DV_MODEL_PERSIST_LEN_HOLD(n, nc, nsub, nout, 2u)
/** Init scratch with the default first-order hold, in elements. */
#define DV_MODEL_SCRATCH_LEN(n, nc, nsub, nout) DV_MODEL_SCRATCH_LEN_HOLD(n, nc, nsub, nout, 2u)

/** @brief A built model. Fields are private; the arrays point into the caller's buffer. */
typedef struct {
    uint16_t n_dof;       /**< n */
    uint16_t n_state;     /**< 2 n */
    uint16_t n_out;       /**< outputs */
    uint16_t n_elem;   /**< elements */
    uint16_t n_sub;       /**< sub-steps (1 without elements) */
    uint16_t n_f;         /**< sub-node element forces per step, (n_sub + 1) n_elem */
    dv_input_kind_t input_kind; /**< input */
    dv_input_hold_t input_hold; /**< input hold */
    uint16_t n_in;        /**< input samples per step: 2 (FOH) or 4 (cubic) */
    dv_real_t dt_s;       /**< sample period, s */
    dv_real_t mass_kg[DV_MAX_DOF];  /**< masses */
    dv_real_t freq_hz[DV_MAX_DOF];  /**< undamped natural frequencies, ascending, Hz */
    dv_real_t zeta[DV_MAX_DOF];     /**< modal damping ratios of C (diagonal of Phi^T C Phi) */
    dv_real_t rayleigh_a;           /**< Rayleigh a, 1/s (DV_DAMP_RAYLEIGH, else 0) */
    dv_real_t rayleigh_b;           /**< Rayleigh b, s (DV_DAMP_RAYLEIGH, else 0) */
    dv_real_t w_elem_max;        /**< highest natural frequency, elements at their stiffness bound, rad/s */
    dv_elem_desc_t elem[DV_MAX_ELEM];   /**< copies of the elements */
    dv_real_t elem_dx[DV_MAX_ELEM];      /**< dX/du, or dV/du' for the velocity laws
                                                    (-1: ground end follows u) */
    dv_real_t *kmat;  /**< K, n x n */
    dv_real_t *cmat;  /**< C, n x n */
    dv_real_t *modes; /**< Phi, n x n, mass-normalised, column k = mode k */
    dv_real_t *ac;    /**< continuous A, 2n x 2n */
    dv_real_t *bc;    /**< continuous B, 2n x (2 + nc): u, u' (ground disp), element forces */
    dv_real_t *ad;    /**< Ad = exp(A T), 2n x 2n */
    dv_real_t *pa;    /**< 2n: coefficient of u[k] in x[k+1] */
    dv_real_t *pb;    /**< 2n: coefficient of u[k+1] in x[k+1] */
    dv_real_t *cy;    /**< nout x 2n output matrix */
    dv_real_t *d0;    /**< nout: coefficient of u[k] in y[k] */
    dv_real_t *d1;    /**< nout: coefficient of u[k-1] in y[k] */
    dv_real_t *ey;    /**< nout x nc: coefficient of the element forces in y[k] */
    dv_real_t *rx;    /**< nf x 2n, column-major (followed by rxa, rxb: the columns of
                           [x[k], u[k], u[k+1]]): sub-node X from x[k] */
    dv_real_t *rxa;   /**< nf: sub-node X from u[k] */
    dv_real_t *rxb;   /**< nf: sub-node X from u[k+1] */
    dv_real_t *smat;  /**< nf x nf: sub-node X from sub-node forces (block lower triangular) */
    dv_real_t *vmat;  /**< 2n x nf: x[k+1] from sub-node forces */
    dv_real_t *pu;    /**< cubic: 2n x 4, coefficient of u[k-1+j] in x[k+1] (else NULL) */
    dv_real_t *du;    /**< cubic: nout x 4, coefficient of u[k-2+j] in y[k] (else NULL) */
    dv_real_t *rxu;   /**< cubic: nf x 4, sub-node X of step k from u[k-1+j] (else NULL) */
} dv_model_t;

/** @brief Read-only views of a model's matrices (for checks and bindings). */
typedef enum {
    DV_MODEL_MAT_K = 0,  /**< n x n */
    DV_MODEL_MAT_C = 1,  /**< n x n */
    DV_MODEL_MAT_MODES = 2, /**< n x n */
    DV_MODEL_MAT_A = 3,  /**< 2n x 2n */
    DV_MODEL_MAT_B = 4,  /**< 2n x (2 + nc) */
    DV_MODEL_MAT_AD = 5, /**< 2n x 2n */
    DV_MODEL_MAT_PA = 6, /**< 2n x 1 */
    DV_MODEL_MAT_PB = 7, /**< 2n x 1 */
    DV_MODEL_MAT_CY = 8, /**< nout x 2n */
    DV_MODEL_MAT_D0 = 9, /**< nout x 1 */
    DV_MODEL_MAT_D1 = 10, /**< nout x 1 */
    DV_MODEL_MAT_PU = 11, /**< 2n x 4 (DV_HOLD_CUBIC only) */
    DV_MODEL_MAT_DU = 12  /**< nout x 4 (DV_HOLD_CUBIC only) */
} dv_model_mat_id_t;

/**
 * @brief Fill @p d with a neutral description: zeros, n_sub = 8, DV_SIDE_POS sides,
 *        DV_DAMP_MODAL, DV_INPUT_FORCE at DOF 0, DV_HOLD_FOH. The caller then sets n_dof,
 *        masses, ...
 * @retval DV_OK     done
 * @retval DV_EINVAL @p d is NULL
 */
dv_status_t dv_model_desc_default(dv_model_desc_t *d);

/**
 * @brief Storage dv_model_init() needs for @p d, in elements (DV_MODEL_BUF_LEN_HOLD():
 *        dv_model_persistent_len() + dv_model_scratch_len()).
 * @return the length, or 0 when @p d is NULL or its sizes are out of range
 */
size_t dv_model_buf_len(const dv_model_desc_t *d);

/**
 * @brief Elements of storage the model keeps for its lifetime (DV_MODEL_PERSIST_LEN_HOLD()):
 *        after dv_model_init() returns, only the first dv_model_persistent_len(d) elements of
 *        its buffer are used; the caller may reuse the rest.
 * @return the length, or 0 when @p d is NULL or its sizes are out of range
 */
size_t dv_model_persistent_len(const dv_model_desc_t *d);

/**
 * @brief Elements of init-time scratch dv_model_init_ex() needs (DV_MODEL_SCRATCH_LEN_HOLD()).
 * @return the length, or 0 when @p d is NULL or its sizes are out of range
 */
size_t dv_model_scratch_len(const dv_model_desc_t *d);

/**
 * @brief Build the model: eigen-solution, damping, state space, discretisation at @p dt_s.
 * @param[out] m     model
 * @param[in]  d     description (copied; need not outlive @p m)
 * @param[in]  dt_s  sample period, s, > 0
 * @param[in]  buf   storage of dv_model_buf_len(d) elements: the first
 *                   dv_model_persistent_len(d) must outlive @p m; the rest is init-time
 *                   scratch, free for the caller again when this returns
 * @param[in]  len   elements in @p buf
 * @retval DV_OK        built
 * @retval DV_EINVAL    NULL pointer; n_dof, n_out, n_elem or n_sub out of range; an
 *                      unknown input_hold; a mass
 *                      <= 0; a negative stiffness, gap, delta or kB; a negative modal ratio;
 *                      a non-finite number; a bad DOF/story/element index; Rayleigh modes
 *                      equal or with zero frequency; an asymmetric damping matrix; dt_s <= 0
 * @retval DV_ESIZE     @p len too small
 * @retval DV_EUNSTABLE the damping matrix is not positive semi-definite (e.g. a negative
 *                      Rayleigh b that makes a mode's ratio negative), the discretisation is
 *                      not finite, or the sample period is too long for the element stiffness
 *                      (w_elem_max * dt_s / n_sub > DV_MODEL_ELEM_MAX_WH)
 */
dv_status_t dv_model_init(dv_model_t *m, const dv_model_desc_t *d, dv_real_t dt_s,
                          dv_real_t *buf, size_t len);

/**
 * @brief dv_model_init() with the init-time scratch apart from the model's storage: @p buf
 *        only needs the persistent part, and @p scratch is free again when this returns
 *        (firmware: one shared scratch area, or the stack, for every init).
 * @param[out] m            model
 * @param[in]  d            description (copied)
 * @param[in]  dt_s         sample period, s, > 0
 * @param[in]  buf          dv_model_persistent_len(d) elements; must outlive @p m
 * @param[in]  len          elements in @p buf
 * @param[in]  scratch      dv_model_scratch_len(d) elements, not overlapping @p buf; its
 *                          contents are destroyed and not used after the call
 * @param[in]  scratch_len  elements in @p scratch
 * @retval DV_OK        built
 * @retval DV_EINVAL    as dv_model_init(), or @p scratch NULL
 * @retval DV_ESIZE     @p len or @p scratch_len too small
 * @retval DV_EUNSTABLE as dv_model_init()
 */
dv_status_t dv_model_init_ex(dv_model_t *m, const dv_model_desc_t *d, dv_real_t dt_s,
                             dv_real_t *buf, size_t len, dv_real_t *scratch,
                             size_t scratch_len);

/**
 * @brief Keep only what the observers bound to @p m read in their steps (firmware RAM), in
 *        @p buf: the model's own storage (then only its first DV_MODEL_STEP_LEN_HOLD() elements
 *        stay in use) or a buffer apart from it (then none of the old storage does: build the
 *        model in a transient area, bind the observers, move the step part out). Bound observers
 *        step on bit for bit; what needs the build matrices (dv_obs_init(), dv_obs_set_gain(),
 *        dv_model_get_mat(), the mode shapes of dv_model_get_modes()) returns DV_EINVAL after.
 * @param[in,out] m built model
 * @param[in] buf DV_MODEL_STEP_LEN_HOLD() elements, the model's storage or not overlapping it;
 *                must outlive @p m
 * @param[in] len elements in @p buf
 * @retval DV_OK / DV_EINVAL (NULL, or @p m not built) / DV_ESIZE (@p len too small)
 */
dv_status_t dv_model_keep_step_only(dv_model_t *m, dv_real_t *buf, size_t len);

/**
 * @brief Natural frequencies (Hz, ascending) and mass-normalised mode shapes.
 * @param[in]  m        built model
 * @param[out] freq_hz  n frequencies, or NULL
 * @param[out] modes    n x n row-major, column k = mode k, or NULL
 * @param[in]  len      elements available in @p modes (>= n * n when modes is given)
 * @retval DV_OK     done
 * @retval DV_EINVAL @p m is NULL or not built, or @p modes given after dv_model_keep_step_only()
 * @retval DV_ESIZE  @p len < n * n with @p modes given
 */
dv_status_t dv_model_get_modes(const dv_model_t *m, dv_real_t *freq_hz, dv_real_t *modes,
                               size_t len);

/**
 * @brief A read-only view of one of the model's matrices.
 * @retval DV_OK     @p view set (data points into the model's storage; do not write)
 * @retval DV_EINVAL NULL argument, model not built or kept for steps only
 *                   (dv_model_keep_step_only()), or unknown @p which (DV_MODEL_MAT_PU and
 *                   DV_MODEL_MAT_DU exist with DV_HOLD_CUBIC only)
 */
dv_status_t dv_model_get_mat(const dv_model_t *m, dv_model_mat_id_t which, dv_mat_t *view);

/**
 * @brief Rayleigh coefficients from two modes (eq. 45-46): zeta = a / (2 w) + b w / 2.
 * @param[in]  w_r, w_s   the two circular frequencies, rad/s, > 0 and different
 * @param[in]  zeta_r, zeta_s  their damping ratios
 * @param[out] a  mass coefficient, 1/s
 * @param[out] b  stiffness coefficient, s
 * @retval DV_OK     done
 * @retval DV_EINVAL NULL output, a frequency <= 0 or non-finite, or w_r == w_s
 */
dv_status_t dv_model_rayleigh(dv_real_t w_r, dv_real_t zeta_r, dv_real_t w_s, dv_real_t zeta_s,
                              dv_real_t *a, dv_real_t *b);


#ifdef __cplusplus
}
#endif

#endif /* DV_MODEL_H */

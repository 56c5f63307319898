/**
 * @file dv_elem.h
 * @brief Nonlinear elements of the lumped-mass model: the force laws, their description and
 *        its validation (the one home of the element concept; dv_model and dv_obs use it).
 *
 * An element e acts between DOF a and DOF b (or the ground, a = DV_GROUND) on the relative
 * displacement X = x_b - x_a or the relative velocity V = v_b - v_a (which one: the law's
 * argument, dv_elem_on_velocity()). It pushes DOF a by +g and DOF b by -g. The laws
 * (parameters in the description's fields, whose names come from the gap law):
 *
 * - DV_ELEM_CONTACT, the report's bumper (eq. 6-7) on X, side DV_SIDE_POS, s = X - gap:
 *       g = 0 (s <= 0),  kB s^2 / (2 delta) (0 < s < delta),  kB (s - delta / 2) (s >= delta)
 *   so the tangent stiffness rises linearly from 0 to kB over delta; force and stiffness are
 *   continuous; delta = 0 is a plain bilinear spring kB max(s, 0). DV_SIDE_NEG mirrors it
 *   (g = -g_pos(-X), engages for X < -gap); DV_SIDE_BOTH is the sum.
 *   gap = gap_m (m, >= 0), delta = delta_m (m, >= 0), kB = kb_n_per_m (N/m, >= 0).
 * - DV_ELEM_FRICTION, regularised Coulomb friction on V: g = F V / sqrt(V^2 + eps^2),
 *   F = kb_n_per_m (slip force, N, >= 0), eps = delta_m (m/s, > 0): g -> F sign(V).
 * - DV_ELEM_CUBIC, cubic spring on X: g = k3 X^3, k3 = kb_n_per_m (N/m^3, any sign: k3 < 0
 *   is a softening spring, whose restoring force with the linear stiffness k between the same
 *   DOFs peaks at X^2 = k / (3 |k3|); driven past it the motion runs away, which the observer
 *   reports as DV_EUNSTABLE).
 * - DV_ELEM_VV, quadratic damper on V: g = c2 V |V|, c2 = kb_n_per_m (N s^2/m^2, >= 0).
 * - DV_ELEM_STICKSLIP, elasto-plastic (Jenkins) friction on X with history: a stick spring of
 *   stiffness F / z in series with a slider at F = kb_n_per_m (N, >= 0), z = delta_m (m, > 0):
 *   g = clip(g_prev + (F / z) (X - X_prev), -F, F) from the previous evaluation's (X, g).
 *   Without history (dv_elem_force()) its virgin curve clip((F / z) X, -F, F).
 * - DV_ELEM_CONSTANT, a constant force whatever the motion: g = -F, F = kb_n_per_m (N, any
 *   sign), so it pushes DOF b by +F (towards +x) and DOF a by -F. Between the ground and DOF b:
 *   a force offset at DOF b (a preload, a weight component on an incline, a force
 *   transducer's bias at the input).
 *
 * gap_m and side matter only for the contact law (side must still be a valid value).
 * Adding a law: docs/adding-an-element-law.md.
 */
#ifndef DV_ELEM_H
#define DV_ELEM_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "dynval/dv_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Force law of an element (see the file comment). */
typedef enum {
    DV_ELEM_CONTACT = 0,  /**< gap/bumper on X (the default, zero-initialised) */
    DV_ELEM_FRICTION = 1, /**< regularised Coulomb friction on V */
    DV_ELEM_CUBIC = 2,    /**< cubic spring on X */
    DV_ELEM_VV = 3,       /**< velocity-squared damper on V */
    DV_ELEM_STICKSLIP = 4, /**< elasto-plastic (Jenkins) friction on X, with history */
    DV_ELEM_CONSTANT = 5   /**< constant force (reads neither X nor V) */
} dv_elem_law_t;

/** Number of element laws (one past the last dv_elem_law_t value). */
#define DV_ELEM_N_LAWS 6u

/** Which side(s) of a contact engage (bit 1: positive, bit 2: negative). */
typedef enum {
    DV_SIDE_POS = 1, /**< engages for X > gap */
    DV_SIDE_NEG = 2, /**< engages for X < -gap */
    DV_SIDE_BOTH = 3 /**< both */
} dv_elem_side_t;

/** @brief One element: where it acts and its law's parameters (see the file comment). */
typedef struct {
    uint16_t dof_a;         /**< first DOF (0-based), or DV_GROUND */
    uint16_t dof_b;         /**< second DOF (0-based), X = x_b - x_a; not the ground */
    dv_elem_side_t side;    /**< DV_SIDE_POS / NEG / BOTH (contact law) */
    dv_real_t gap_m;        /**< contact gap, m, >= 0 */
    dv_real_t delta_m;      /**< contact transition width m (>= 0); friction eps m/s, stick-slip
                                 slip displacement m (> 0) */
    dv_real_t kb_n_per_m;   /**< contact kB N/m; friction / stick-slip F N; cubic k3 N/m^3;
                                 v|v| c2 N s^2/m^2; constant F N */
    dv_elem_law_t law;      /**< DV_ELEM_CONTACT (0) unless set */
} dv_elem_desc_t;

/**
 * @brief Whether the law acts on the relative velocity V (friction, v|v|) rather than on the
 *        relative displacement X (contact, cubic, stick-slip).
 * @return true for DV_ELEM_FRICTION and DV_ELEM_VV; false otherwise (also for an invalid law)
 */
bool dv_elem_on_velocity(dv_elem_law_t law);

/**
 * @brief Check an element's law and parameters (not its DOFs: the model checks those).
 * @param[in] e  element
 * @retval DV_OK     valid
 * @retval DV_EINVAL NULL @p e, an unknown law or side, a non-finite parameter, gap_m,
 *                   delta_m < 0, kb_n_per_m < 0 (except for the constant force and the
 *                   cubic spring, of any sign), or delta_m <= 0 for friction and stick-slip
 */
dv_status_t dv_elem_check(const dv_elem_desc_t *e);

/**
 * @brief The largest stiffness the element adds, N/m: kB for a contact, F / z for stick-slip
 *        (its stick spring), 0 for the laws whose stiffness is unbounded or zero (cubic) or
 *        that act on V. The model's sub-step check uses it.
 * @return the bound; 0 for NULL
 */
dv_real_t dv_elem_stiffness_bound(const dv_elem_desc_t *e);

/**
 * @brief The largest damping the element adds, N s/m: F / eps for friction (the slope of its
 *        regularised law at V = 0), 0 for the laws whose slope is unbounded (v|v|) or that act
 *        on X. The model's sub-step check uses it beside dv_elem_stiffness_bound().
 * @return the bound; 0 for NULL
 */
dv_real_t dv_elem_damping_bound(const dv_elem_desc_t *e);

/**
 * @brief The element's force law g (N) without history: g(X) for the contact, cubic and
 *        stick-slip (virgin curve) laws, g(V) for friction and the v|v| damper (@p x is then
 *        the relative velocity V, m/s), -F for the constant force (x is not read).
 * @return g; 0 when @p e is NULL
 */
dv_real_t dv_elem_force(const dv_elem_desc_t *e, dv_real_t x);

/**
 * @brief The element force for a record of relative motions, as the model evaluates it
 *        (for bindings, trace views and tests).
 * @param[in]     e           element (dv_elem_check() must accept it)
 * @param[in]     x_m         n relative displacements X = x_b - x_a, m (read by the laws on X)
 * @param[in]     v_m_per_s   n relative velocities V = v_b - v_a, m/s (read by the laws on V);
 *                            either array may be NULL when the law does not read it
 * @param[in]     n           samples
 * @param[in,out] hist        stick-slip: 2 values, the previous (X, g) (zeros: the virgin
 *                            state), advanced to the last sample; ignored (may be NULL) for
 *                            the laws without history
 * @param[out]    f_n         n forces g, N
 * @retval DV_OK       done
 * @retval DV_EINVAL   invalid @p e, NULL @p f_n with n > 0, NULL array the law reads, or NULL
 *                     @p hist for stick-slip
 * @retval DV_ENUMERIC a non-finite sample: its force is 0 and the history is not advanced by
 *                     it; the others are evaluated
 */
dv_status_t dv_elem_force_block(const dv_elem_desc_t *e, const dv_real_t *x_m,
                                const dv_real_t *v_m_per_s, size_t n, dv_real_t *hist,
                                dv_real_t *f_n);

#ifdef __cplusplus
}
#endif

#endif /* DV_ELEM_H */

/* The element laws of dv_elem.h as inline functions: the one definition the model, the observer's
 * steps and the public dv_elem functions evaluate (the AVX-512 modal step's open test,
 * shut_lanes() in dv_obskern.c, is the vector form of dv_priv_gap_open()). A new law is a case
 * in dv_priv_elem_on_velocity(), dv_priv_elem_g() and, if it keeps history or adds a bounded
 * stiffness, in dv_priv_elem_force() and dv_elem_stiffness_bound() (docs/adding-an-element-law.md). */
#ifndef DV_ELEM_LAW_H
#define DV_ELEM_LAW_H

#include "dynval/dv_elem.h"
#include "dynval/dv_model.h" /* DV_GROUND */
#include "dv_priv.h"

/* The law sits in the observer's per-step loop: forced inline (-Os would call it). */
#if defined(__GNUC__)
#define DV_ELEM_FORCE_INLINE static inline __attribute__((always_inline))
#else
#define DV_ELEM_FORCE_INLINE static inline
#endif
#define DV_ELEM_INLINE static inline

/* The contact (gap) law, one side: s = X - gap; 0, then kB s^2 / (2 delta) on the
 * transition, then kB (s - delta / 2). Continuous force and tangent stiffness. Written without
 * branches, kh = kB / (2 delta) given (callers evaluating the law many times compute it once):
 * kh min(max(s, 0), delta)^2 + kB max(s - delta, 0). */
DV_ELEM_FORCE_INLINE dv_real_t dv_priv_gap_g1k(dv_real_t s, dv_real_t delta, dv_real_t kb,
                                            dv_real_t kh)
{
    const dv_real_t pos = s > DV_R(0.0) ? s : DV_R(0.0);
    const dv_real_t sc = pos < delta ? pos : delta;
    const dv_real_t over = s - delta > DV_R(0.0) ? s - delta : DV_R(0.0);
    return kh * sc * sc + kb * over;
}

/* Both sides: side bit 1 = positive (X > gap), bit 2 = negative (X < -gap, mirrored). */
DV_ELEM_FORCE_INLINE dv_real_t dv_priv_gap_gk(int side, dv_real_t gap, dv_real_t delta,
                                           dv_real_t kb, dv_real_t kh, dv_real_t x)
{
    dv_real_t g = DV_R(0.0);
    if ((side & 1) != 0) {
        g += dv_priv_gap_g1k(x - gap, delta, kb, kh);
    }
    if ((side & 2) != 0) {
        g -= dv_priv_gap_g1k(-x - gap, delta, kb, kh);
    }
    return g;
}

/* dv_priv_gap_gk() is exactly 0 for every X in [xmin, xmax] (no side engaged). */
DV_ELEM_INLINE bool dv_priv_gap_open(int side, dv_real_t gap, dv_real_t xmin, dv_real_t xmax)
{
    return ((side & 1) == 0 || xmax <= gap) && ((side & 2) == 0 || xmin >= -gap);
}

/* kh of dv_priv_gap_g1k(): kB / (2 delta); 0 for delta = 0 (plain bilinear: no transition,
 * and no 0 x Inf). */
DV_ELEM_INLINE dv_real_t dv_priv_gap_kh(dv_real_t kb, dv_real_t delta)
{
    return delta > DV_R(0.0) ? kb / (DV_R(2.0) * delta) : DV_R(0.0);
}

/* dv_priv_gap_gk() with kh formed here. */
DV_ELEM_INLINE dv_real_t dv_priv_gap_g(int side, dv_real_t gap, dv_real_t delta,
                                          dv_real_t kb, dv_real_t x)
{
    return dv_priv_gap_gk(side, gap, delta, kb, dv_priv_gap_kh(kb, delta), x);
}

/* Whether the law reads V (friction, v|v|) rather than X. */
DV_ELEM_INLINE bool dv_priv_elem_on_velocity(dv_elem_law_t law)
{
    return law == DV_ELEM_FRICTION || law == DV_ELEM_VV;
}

/* Where an element's argument starts in a state-like vector (2 n: displacements, then
 * velocities): X = x_b - x_a, or V = v_b - v_a for the velocity laws (rows n..2n). */
DV_ELEM_INLINE size_t dv_priv_elem_arg_off(const dv_elem_desc_t *c, size_t n)
{
    return dv_priv_elem_on_velocity(c->law) ? n : 0u;
}

/* The element's argument from z: x_b - x_a (or v_b - v_a); the ground's entry is 0. */
DV_ELEM_INLINE dv_real_t dv_priv_elem_arg(const dv_elem_desc_t *c, const dv_real_t *z, size_t n)
{
    const size_t o = dv_priv_elem_arg_off(c, n);
    const dv_real_t za = c->dof_a == (uint16_t)DV_GROUND ? DV_R(0.0) : z[o + c->dof_a];
    return z[o + c->dof_b] - za;
}

/* The memoryless law g(x) (stick-slip: its virgin curve; x is V for the velocity laws). */
DV_ELEM_INLINE dv_real_t dv_priv_elem_g(const dv_elem_desc_t *c, dv_real_t x)
{
    const dv_real_t delta = c->delta_m, kb = c->kb_n_per_m;
    switch (c->law) {
    case DV_ELEM_FRICTION:
        return kb * x / DV_SQRT(x * x + delta * delta);
    case DV_ELEM_CUBIC:
        return kb * x * x * x;
    case DV_ELEM_VV:
        return kb * x * DV_FABS(x);
    case DV_ELEM_STICKSLIP: {
        const dv_real_t g = kb / delta * x;
        return g > kb ? kb : (g < -kb ? -kb : g);
    }
    case DV_ELEM_CONSTANT:
        return -kb;
    default:
        return dv_priv_gap_g((int)c->side, c->gap_m, delta, kb, x);
    }
}

/* Stick-slip (Jenkins) force at X = x from the previous evaluation's (X, g) = (xp, gp). */
DV_ELEM_INLINE dv_real_t dv_priv_stickslip_g(const dv_elem_desc_t *c, dv_real_t xp, dv_real_t gp,
                                             dv_real_t x)
{
    const dv_real_t f = c->kb_n_per_m;
    const dv_real_t g = gp + f / c->delta_m * (x - xp);
    return g > f ? f : (g < -f ? -f : g);
}

/* kB / (2 delta) of a gap element (the constant of its transition), 0 for the other laws. */
DV_ELEM_INLINE dv_real_t dv_priv_elem_kh(const dv_elem_desc_t *c)
{
    return c->law == DV_ELEM_CONTACT ? dv_priv_gap_kh(c->kb_n_per_m, c->delta_m) : DV_R(0.0);
}

/* The force of element c at x with history: every law evaluation of the observer goes through
 * here. (xp, gp): the element's argument and force at the previous evaluation (stick-slip
 * history); kh from dv_priv_elem_kh(). */
DV_ELEM_FORCE_INLINE dv_real_t dv_priv_elem_force(const dv_elem_desc_t *c, dv_real_t kh,
                                                  dv_real_t xp, dv_real_t gp, dv_real_t x)
{
    if (c->law == DV_ELEM_CONTACT) {
        return dv_priv_gap_gk((int)c->side, c->gap_m, c->delta_m, c->kb_n_per_m, kh, x);
    }
    if (c->law == DV_ELEM_STICKSLIP) {
        return dv_priv_stickslip_g(c, xp, gp, x);
    }
    return dv_priv_elem_g(c, x);
}

#endif /* DV_ELEM_LAW_H */

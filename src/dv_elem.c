/* Nonlinear elements: validation, stiffness bound and the laws for bindings and tests (the laws
 * themselves are inline in dv_elem_law.h, shared with the model and the observer's steps). */
#include "dynval/dv_elem.h"
#include "dv_elem_law.h"
#include "dv_priv.h"

bool dv_elem_on_velocity(dv_elem_law_t law)
{
    return dv_priv_elem_on_velocity(law);
}

dv_status_t dv_elem_check(const dv_elem_desc_t *e)
{
    if (e == NULL || !dv_priv_finite(e->gap_m) || !dv_priv_finite(e->delta_m) ||
        !dv_priv_finite(e->kb_n_per_m) || e->gap_m < DV_R(0.0) || e->delta_m < DV_R(0.0) ||
        (e->kb_n_per_m < DV_R(0.0) && e->law != DV_ELEM_CONSTANT && e->law != DV_ELEM_CUBIC) ||
        (e->side != DV_SIDE_POS && e->side != DV_SIDE_NEG && e->side != DV_SIDE_BOTH) ||
        (unsigned)e->law >= DV_ELEM_N_LAWS) {
        return DV_EINVAL;
    }
    /* the laws that divide by delta: friction's eps and stick-slip's slip displacement */
    if ((e->law == DV_ELEM_FRICTION || e->law == DV_ELEM_STICKSLIP) && !(e->delta_m > DV_R(0.0))) {
        return DV_EINVAL;
    }
    return DV_OK;
}

dv_real_t dv_elem_stiffness_bound(const dv_elem_desc_t *e)
{
    if (e == NULL) {
        return DV_R(0.0);
    }
    switch (e->law) {
    case DV_ELEM_CONTACT:
        return e->kb_n_per_m;
    case DV_ELEM_STICKSLIP:
        return e->kb_n_per_m / e->delta_m;
    default:
        return DV_R(0.0);
    }
}

dv_real_t dv_elem_damping_bound(const dv_elem_desc_t *e)
{
    if (e == NULL || e->law != DV_ELEM_FRICTION) {
        return DV_R(0.0);
    }
    return e->kb_n_per_m / e->delta_m;
}

dv_real_t dv_elem_force(const dv_elem_desc_t *e, dv_real_t x)
{
    return e == NULL ? DV_R(0.0) : dv_priv_elem_g(e, x);
}

dv_status_t dv_elem_force_block(const dv_elem_desc_t *e, const dv_real_t *x_m,
                                const dv_real_t *v_m_per_s, size_t n, dv_real_t *hist,
                                dv_real_t *f_n)
{
    if (dv_elem_check(e) != DV_OK) {
        return DV_EINVAL;
    }
    if (n == 0u) {
        return DV_OK;
    }
    const bool vel = dv_priv_elem_on_velocity(e->law);
    const dv_real_t *arg = vel ? v_m_per_s : x_m;
    if (f_n == NULL || arg == NULL || (e->law == DV_ELEM_STICKSLIP && hist == NULL)) {
        return DV_EINVAL;
    }
    const dv_real_t kh = dv_priv_elem_kh(e);
    dv_real_t xp = hist != NULL ? hist[0] : DV_R(0.0);
    dv_real_t gp = hist != NULL ? hist[1] : DV_R(0.0);
    dv_status_t st = DV_OK;
    for (size_t i = 0; i < n; i++) {
        const dv_real_t x = arg[i];
        if (!dv_priv_finite(x)) {
            f_n[i] = DV_R(0.0);
            st = DV_ENUMERIC;
            continue;
        }
        const dv_real_t g = dv_priv_elem_force(e, kh, xp, gp, x);
        f_n[i] = g;
        xp = x;
        gp = g;
    }
    if (e->law == DV_ELEM_STICKSLIP) {
        hist[0] = xp;
        hist[1] = gp;
    }
    return st;
}

/* Lumped-mass chain model: the description, its checks, the model's storage (sizes, header,
 * layout) and the getters. The build itself (eigen-solution, damping, the discretisation, all
 * computed once at init into the caller's buffer) is dv_model_init_ex() in dv_model_build.c,
 * with its numerical pieces in dv_model_math.c; the equations are in dv_model.h. */
#include "dynval/dv_model.h"
#include "dv_model_priv.h"
#include "dv_priv.h"

dv_status_t dv_model_desc_default(dv_model_desc_t *d)
{
    if (d == NULL) {
        return DV_EINVAL;
    }
    const dv_model_desc_t zero = {0};
    *d = zero;
    d->damp_kind = DV_DAMP_MODAL;
    d->input_kind = DV_INPUT_FORCE;
    d->n_sub = 8u;
    d->input_hold = DV_HOLD_FOH;
    for (size_t c = 0; c < DV_MAX_ELEM; c++) {
        d->elem[c].side = DV_SIDE_POS;
    }
    return DV_OK;
}

static bool desc_sizes_ok(const dv_model_desc_t *d)
{
    return d != NULL && d->n_dof >= 1u && d->n_dof <= DV_MAX_DOF && d->n_out >= 1u &&
           d->n_out <= DV_MAX_OUT && d->n_elem <= DV_MAX_ELEM && d->n_link <= DV_MAX_LINK &&
           (d->n_elem == 0u || (d->n_sub >= 1u && d->n_sub <= DV_MAX_SUB)) &&
           (d->input_hold == DV_HOLD_FOH || d->input_hold == DV_HOLD_CUBIC);
}

/* 0: persistent, 1: scratch, 2: both (one buffer) */
static size_t model_len(const dv_model_desc_t *d, int which)
{
    if (!desc_sizes_ok(d)) {
        return 0u;
    }
    const size_t n = d->n_dof;
    const size_t nc = d->n_elem;
    const size_t nsub = nc > 0u ? d->n_sub : 1u;
    const size_t no = d->n_out;
    const size_t nin = DV_MODEL_HOLD_NIN((int)d->input_hold);
    const size_t per = DV_MODEL_PERSIST_LEN_HOLD(n, nc, nsub, no, nin);
    const size_t scr = DV_MODEL_SCRATCH_LEN_HOLD(n, nc, nsub, no, nin);
    return which == 0 ? per : (which == 1 ? scr : per + scr);
}

size_t dv_model_buf_len(const dv_model_desc_t *d)
{
    return model_len(d, 2);
}

size_t dv_model_persistent_len(const dv_model_desc_t *d)
{
    return model_len(d, 0);
}

size_t dv_model_scratch_len(const dv_model_desc_t *d)
{
    return model_len(d, 1);
}

dv_status_t dv_model_rayleigh(dv_real_t w_r, dv_real_t zeta_r, dv_real_t w_s, dv_real_t zeta_s,
                              dv_real_t *a, dv_real_t *b)
{
    if (a == NULL || b == NULL || !dv_priv_finite(w_r) || !dv_priv_finite(w_s) ||
        !dv_priv_finite(zeta_r) || !dv_priv_finite(zeta_s) || !(w_r > DV_R(0.0)) ||
        !(w_s > DV_R(0.0)) || w_r == w_s) {
        return DV_EINVAL;
    }
    /* eq. 45-46: [1/(2 w_r)  w_r/2; 1/(2 w_s)  w_s/2] [a; b] = [zeta_r; zeta_s] */
    const dv_real_t den = w_s * w_s - w_r * w_r;
    *a = DV_R(2.0) * w_r * w_s * (zeta_r * w_s - zeta_s * w_r) / den;
    *b = DV_R(2.0) * (zeta_s * w_s - zeta_r * w_r) / den;
    return DV_OK;
}

static bool fin(dv_real_t x)
{
    return dv_priv_finite(x);
}

dv_status_t dv_priv_model_validate(const dv_model_desc_t *d, dv_real_t dt_s)
{
    if (!desc_sizes_ok(d) || !fin(dt_s) || !(dt_s > DV_R(0.0))) {
        return DV_EINVAL;
    }
    const size_t n = d->n_dof;
    for (size_t i = 0; i < n; i++) {
        if (!fin(d->mass_kg[i]) || !(d->mass_kg[i] > DV_R(0.0)) || !fin(d->k_n_per_m[i]) ||
            d->k_n_per_m[i] < DV_R(0.0)) {
            return DV_EINVAL;
        }
    }
    switch (d->damp_kind) {
    case DV_DAMP_MODAL:
        for (size_t i = 0; i < n; i++) {
            if (!fin(d->zeta[i]) || d->zeta[i] < DV_R(0.0)) {
                return DV_EINVAL;
            }
        }
        break;
    case DV_DAMP_RAYLEIGH:
        if (d->rayleigh_mode[0] >= n || d->rayleigh_mode[1] >= n ||
            d->rayleigh_mode[0] == d->rayleigh_mode[1] || !fin(d->rayleigh_zeta[0]) ||
            !fin(d->rayleigh_zeta[1]) || d->rayleigh_zeta[0] < DV_R(0.0) ||
            d->rayleigh_zeta[1] < DV_R(0.0)) {
            return DV_EINVAL;
        }
        break;
    case DV_DAMP_MATRIX: {
        dv_real_t cmax = DV_R(0.0);
        for (size_t i = 0; i < n * n; i++) {
            if (!fin(d->c_n_s_per_m[i])) {
                return DV_EINVAL;
            }
            cmax = DV_FABS(d->c_n_s_per_m[i]) > cmax ? DV_FABS(d->c_n_s_per_m[i]) : cmax;
        }
        for (size_t i = 0; i < n; i++) {
            for (size_t j = i + 1; j < n; j++) {
                const dv_real_t diff = d->c_n_s_per_m[i * n + j] - d->c_n_s_per_m[j * n + i];
                if (DV_FABS(diff) > DV_R(1e-5) * cmax) {
                    return DV_EINVAL;
                }
            }
        }
        break;
    }
    default:
        return DV_EINVAL;
    }
    if (d->input_kind != DV_INPUT_FORCE && d->input_kind != DV_INPUT_GROUND_ACC &&
        d->input_kind != DV_INPUT_GROUND_DISP) {
        return DV_EINVAL;
    }
    if (d->input_kind == DV_INPUT_FORCE && d->input_dof >= n) {
        return DV_EINVAL;
    }
    for (size_t c = 0; c < d->n_elem; c++) {
        const dv_elem_desc_t *e = &d->elem[c];
        if ((e->dof_a >= n && e->dof_a != (uint16_t)DV_GROUND) || e->dof_b >= n ||
            e->dof_a == e->dof_b || dv_elem_check(e) != DV_OK) {
            return DV_EINVAL;
        }
    }
    for (size_t l = 0; l < d->n_link; l++) {
        const dv_link_desc_t *k = &d->link[l];
        if (k->dof_a >= n || k->dof_b >= n || k->dof_a == k->dof_b || !fin(k->k_n_per_m) ||
            !fin(k->c_n_s_per_m) || k->k_n_per_m < DV_R(0.0) || k->c_n_s_per_m < DV_R(0.0)) {
            return DV_EINVAL;
        }
    }
    for (size_t o = 0; o < d->n_out; o++) {
        const dv_out_desc_t *y = &d->out[o];
        switch (y->kind) {
        case DV_OUT_ACC:
        case DV_OUT_VEL:
        case DV_OUT_DISP:
        case DV_OUT_SPRING_FORCE:
            if (y->index >= n) {
                return DV_EINVAL;
            }
            break;
        case DV_OUT_ELEM_FORCE:
            if (y->index >= d->n_elem) {
                return DV_EINVAL;
            }
            break;
        case DV_OUT_REACTION:
            break;
        default:
            return DV_EINVAL;
        }
    }
    return DV_OK;
}

dv_status_t dv_model_init(dv_model_t *m, const dv_model_desc_t *d, dv_real_t dt_s,
                          dv_real_t *buf, size_t len)
{
    if (m == NULL || d == NULL || buf == NULL) {
        return DV_EINVAL;
    }
    const dv_status_t st = dv_priv_model_validate(d, dt_s);
    if (st != DV_OK) {
        return st;
    }
    const size_t per = dv_model_persistent_len(d);
    if (len < dv_model_buf_len(d)) {
        return DV_ESIZE;
    }
    return dv_model_init_ex(m, d, dt_s, buf, per, buf + per, len - per);
}

/* ---- storage layout ----------------------------------------------------------------------- */

/* Carve @p count elements off the front of the remaining buffer. */
static dv_real_t *take(dv_real_t **p, size_t count)
{
    dv_real_t *r = *p;
    *p += count;
    return r;
}

/* take() for an array that may already hold data (old, not NULL): copied unless in place. */
static dv_real_t *take_from(dv_real_t **p, dv_real_t *old, size_t count)
{
    dv_real_t *r = take(p, count);
    if (old != NULL && old != r) {
        for (size_t i = 0; i < count; i++) {
            r[i] = old[i];
        }
    }
    return r;
}

/* The arrays the observers' steps read, laid out from *p (DV_MODEL_STEP_LEN_HOLD elements):
 * the start of the model's storage at init, a caller's buffer in dv_model_keep_step_only(). */
static void lay_step_part(dv_model_t *m, dv_real_t **p)
{
    const size_t ns = m->n_state, no = m->n_out, nc = m->n_elem, nf = m->n_f;
    m->cy = take_from(p, m->cy, no * ns);
    m->d0 = take_from(p, m->d0, no);
    m->d1 = take_from(p, m->d1, no);
    m->ey = take_from(p, m->ey, no * nc);
    m->rx = take_from(p, m->rx, nf * ns);
    m->rxa = take_from(p, m->rxa, nf);
    m->rxb = take_from(p, m->rxb, nf);
    m->smat = take_from(p, m->smat, nf * nf);
    if (m->input_hold == DV_HOLD_CUBIC) {
        m->du = take_from(p, m->du, no * DV_PRIV_CUBIC_NIN);
        m->rxu = take_from(p, m->rxu, nf * DV_PRIV_CUBIC_NIN);
    }
}

void dv_priv_model_lay_out(dv_model_t *m, const dv_model_desc_t *d, dv_real_t dt_s,
                           dv_real_t *buf, size_t len)
{
    const size_t n = d->n_dof, ns = DV_MODEL_NS(n), nc = d->n_elem, no = d->n_out;
    const size_t nsub = nc > 0u ? d->n_sub : 1u;
    const size_t nf = DV_MODEL_NF(nc, nsub);
    const dv_model_t zero = {0};
    *m = zero; /* the arrays a hold does not use stay NULL */
    m->n_dof = (uint16_t)n;
    m->n_state = (uint16_t)ns;
    m->n_out = (uint16_t)no;
    m->n_elem = (uint16_t)nc;
    m->n_sub = (uint16_t)nsub;
    m->n_f = (uint16_t)nf;
    m->input_kind = d->input_kind;
    m->input_hold = d->input_hold;
    m->n_in = (uint16_t)DV_MODEL_HOLD_NIN((int)d->input_hold);
    m->dt_s = dt_s;
    for (size_t i = 0; i < n; i++) {
        m->mass_kg[i] = d->mass_kg[i];
    }

    dv_real_t *p = buf;
    lay_step_part(m, &p);
    DV_ASSERT((size_t)(p - buf) == DV_MODEL_STEP_LEN_HOLD(n, nc, nsub, no, (size_t)m->n_in));
    m->kmat = take(&p, n * n);
    m->cmat = take(&p, n * n);
    m->modes = take(&p, n * n);
    m->ac = take(&p, ns * ns);
    m->ad = take(&p, ns * ns);
    m->bc = take(&p, ns * (DV_PRIV_U_COLS + nc));
    m->pa = take(&p, ns);
    m->pb = take(&p, ns);
    m->vmat = take(&p, ns * nf);
    if (m->input_hold == DV_HOLD_CUBIC) {
        m->pu = take(&p, ns * DV_PRIV_CUBIC_NIN);
    }
    DV_ASSERT((size_t)(p - buf) <= len);
    (void)len; /* only asserted */
}

dv_status_t dv_model_keep_step_only(dv_model_t *m, dv_real_t *buf, size_t len)
{
    if (m == NULL || m->cy == NULL || buf == NULL) {
        return DV_EINVAL;
    }
    if (len < DV_MODEL_STEP_LEN_HOLD((size_t)m->n_dof, (size_t)m->n_elem, (size_t)m->n_sub,
                                     (size_t)m->n_out, (size_t)m->n_in)) {
        return DV_ESIZE;
    }
    dv_real_t *p = buf;
    lay_step_part(m, &p);
    m->kmat = m->cmat = m->modes = m->ac = m->ad = m->bc = NULL;
    m->pa = m->pb = m->vmat = m->pu = NULL;
    return DV_OK;
}

/* ---- getters ------------------------------------------------------------------------------ */

dv_status_t dv_model_get_modes(const dv_model_t *m, dv_real_t *freq_hz, dv_real_t *modes,
                               size_t len)
{
    if (m == NULL || m->cy == NULL || (modes != NULL && m->modes == NULL)) {
        return DV_EINVAL;
    }
    const size_t n = m->n_dof;
    if (modes != NULL && len < n * n) {
        return DV_ESIZE;
    }
    for (size_t i = 0; i < n; i++) {
        if (freq_hz != NULL) {
            freq_hz[i] = m->freq_hz[i];
        }
    }
    if (modes != NULL) {
        for (size_t i = 0; i < n * n; i++) {
            modes[i] = m->modes[i];
        }
    }
    return DV_OK;
}

dv_status_t dv_model_get_mat(const dv_model_t *m, dv_model_mat_id_t which, dv_mat_t *view)
{
    if (m == NULL || view == NULL || m->kmat == NULL) {
        return DV_EINVAL;
    }
    const uint16_t n = m->n_dof;
    const uint16_t ns = m->n_state;
    const uint16_t no = m->n_out;
    switch (which) {
    case DV_MODEL_MAT_K: *view = (dv_mat_t){n, n, m->kmat}; break;
    case DV_MODEL_MAT_C: *view = (dv_mat_t){n, n, m->cmat}; break;
    case DV_MODEL_MAT_MODES: *view = (dv_mat_t){n, n, m->modes}; break;
    case DV_MODEL_MAT_A: *view = (dv_mat_t){ns, ns, m->ac}; break;
    case DV_MODEL_MAT_B: *view = (dv_mat_t){ns, (uint16_t)(2u + m->n_elem), m->bc}; break;
    case DV_MODEL_MAT_AD: *view = (dv_mat_t){ns, ns, m->ad}; break;
    case DV_MODEL_MAT_PA: *view = (dv_mat_t){ns, 1u, m->pa}; break;
    case DV_MODEL_MAT_PB: *view = (dv_mat_t){ns, 1u, m->pb}; break;
    case DV_MODEL_MAT_CY: *view = (dv_mat_t){no, ns, m->cy}; break;
    case DV_MODEL_MAT_D0: *view = (dv_mat_t){no, 1u, m->d0}; break;
    case DV_MODEL_MAT_D1: *view = (dv_mat_t){no, 1u, m->d1}; break;
    case DV_MODEL_MAT_PU:
        if (m->pu == NULL) {
            return DV_EINVAL;
        }
        *view = (dv_mat_t){ns, 4u, m->pu};
        break;
    case DV_MODEL_MAT_DU:
        if (m->du == NULL) {
            return DV_EINVAL;
        }
        *view = (dv_mat_t){no, 4u, m->du};
        break;
    default: return DV_EINVAL;
    }
    return DV_OK;
}

/* Lumped-mass chain model: eigen-solution, damping and the first-order-hold discretisation,
 * all built once at init into the caller's buffer. See dv_model.h for the equations. */
#include "dynval/dv_model.h"
#include "dv_elem_law.h"
#include "dv_priv.h"

#define TWO_PI_R DV_R(6.283185307179586)

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
           d->n_out <= DV_MAX_OUT && d->n_elem <= DV_MAX_ELEM &&
           (d->n_elem == 0u || (d->n_sub >= 1u && d->n_sub <= DV_MAX_SUB)) &&
           (d->input_hold == DV_HOLD_FOH || d->input_hold == DV_HOLD_CUBIC);
}

/* Lagrange cubic through u[k-1], u[k], u[k+1], u[k+2] (nodes s = -1, 0, 1, 2): coefficient of
 * s^p (row p) of sample u[k-1+j] (column j) over s in [0, 1]. */
static const dv_real_t LAG3[4][4] = {
    {DV_R(0.0), DV_R(1.0), DV_R(0.0), DV_R(0.0)},
    {DV_R(-1.0) / DV_R(3.0), DV_R(-0.5), DV_R(1.0), DV_R(-1.0) / DV_R(6.0)},
    {DV_R(0.5), DV_R(-1.0), DV_R(0.5), DV_R(0.0)},
    {DV_R(-1.0) / DV_R(6.0), DV_R(0.5), DV_R(-0.5), DV_R(1.0) / DV_R(6.0)}};

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
        m->du = take_from(p, m->du, no * 4u);
        m->rxu = take_from(p, m->rxu, nf * 4u);
    }
}

static dv_status_t validate(const dv_model_desc_t *d, dv_real_t dt_s)
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

/* Eigenvalues of M^-1/2 S M^-1/2 (S symmetric n x n): w ascending, v its eigenvectors. */
static dv_status_t eig_mass_scaled(size_t n, const dv_real_t *mass, const dv_real_t *s,
                                   dv_real_t *w, dv_real_t *v, dv_real_t *tmp,
                                   dv_real_t *work)
{
    for (size_t i = 0; i < n; i++) {
        for (size_t j = 0; j < n; j++) {
            tmp[i * n + j] = s[i * n + j] / DV_SQRT(mass[i] * mass[j]);
        }
    }
    dv_mat_t sm = {(uint16_t)n, (uint16_t)n, tmp};
    dv_mat_t vm = {(uint16_t)n, (uint16_t)n, v};
    return dv_mat_eig_sym(&sm, w, &vm, work, n * n);
}

/* exp of [[A h, B h, 0, ..], [0, 0, I, ..], .., [0, .., 0]] with q >= 2 input blocks (B: ns x
 * nb, row-major with stride nb): a chain of integrators whose block p is s^p / p! for unit
 * initial value. Writes Ad (ns x ns) and gp[p] = p! G_p = int_0^1 e^{A h (1 - s)} B h s^p ds
 * for p < q (each ns x nb, stride nb; gp[0], gp[1] may be G0, G1 of the first-order hold). */
static dv_status_t poly_expm(size_t ns, size_t nb, size_t q, const dv_real_t *a,
                             const dv_real_t *b, dv_real_t h, dv_real_t *ad,
                             dv_real_t *const *gp, dv_real_t *scratch)
{
    const size_t na = ns + q * nb;
    dv_real_t *e = scratch;
    dv_real_t *r = e + na * na;
    dv_real_t *work = r + na * na;
    for (size_t i = 0; i < na * na; i++) {
        e[i] = DV_R(0.0);
    }
    for (size_t i = 0; i < ns; i++) {
        for (size_t j = 0; j < ns; j++) {
            e[i * na + j] = a[i * ns + j] * h;
        }
        for (size_t j = 0; j < nb; j++) {
            e[i * na + ns + j] = b[i * nb + j] * h;
        }
    }
    for (size_t p = 0; p + 1u < q; p++) {
        for (size_t j = 0; j < nb; j++) {
            e[(ns + p * nb + j) * na + ns + (p + 1u) * nb + j] = DV_R(1.0);
        }
    }
    dv_mat_t em = {(uint16_t)na, (uint16_t)na, e};
    dv_mat_t rm = {(uint16_t)na, (uint16_t)na, r};
    const dv_status_t st = dv_mat_expm(&em, &rm, work, DV_MAT_EXPM_WORK_LEN(na));
    if (st != DV_OK) {
        return st == DV_ENUMERIC ? DV_EUNSTABLE : st;
    }
    for (size_t i = 0; i < ns; i++) {
        for (size_t j = 0; j < ns; j++) {
            ad[i * ns + j] = r[i * na + j];
        }
    }
    dv_real_t fact = DV_R(1.0);
    for (size_t p = 0; p < q; p++) {
        if (p > 1u) {
            fact *= (dv_real_t)p;
        }
        for (size_t i = 0; i < ns; i++) {
            for (size_t j = 0; j < nb; j++) {
                gp[p][i * nb + j] = p > 1u ? r[i * na + ns + p * nb + j] * fact
                                           : r[i * na + ns + p * nb + j];
            }
        }
    }
    return DV_OK;
}

static dv_status_t foh_expm(size_t ns, size_t nb, const dv_real_t *a, const dv_real_t *b,
                            dv_real_t h, dv_real_t *ad, dv_real_t *g0, dv_real_t *g1,
                            dv_real_t *scratch)
{
    dv_real_t *const gp[2] = {g0, g1};
    return poly_expm(ns, nb, 2u, a, b, h, ad, gp, scratch);
}

/* Coefficients (in t, over sub-interval i of nsub: s = (i + t) / nsub) of the full-step
 * polynomial sum_p c[p] s^p, p < 4. */
static void poly_sub(const dv_real_t *c, size_t i, size_t nsub, dv_real_t *out)
{
    static const dv_real_t binom[4][4] = {{DV_R(1.0), DV_R(0.0), DV_R(0.0), DV_R(0.0)},
                                          {DV_R(1.0), DV_R(1.0), DV_R(0.0), DV_R(0.0)},
                                          {DV_R(1.0), DV_R(2.0), DV_R(1.0), DV_R(0.0)},
                                          {DV_R(1.0), DV_R(3.0), DV_R(3.0), DV_R(1.0)}};
    const dv_real_t fi = (dv_real_t)i;
    const dv_real_t inv = DV_R(1.0) / (dv_real_t)nsub;
    for (size_t q = 0; q < 4u; q++) {
        dv_real_t s = DV_R(0.0);
        for (size_t p = q; p < 4u; p++) {
            dv_real_t t = c[p] * binom[p][q];
            for (size_t r = 0; r < p - q; r++) {
                t *= fi;
            }
            for (size_t r = 0; r < p; r++) {
                t *= inv;
            }
            s += t;
        }
        out[q] = s;
    }
}

/* X of contact c for a state-sized vector z: z[b] - z[a]. */
/* The element's argument from a state-like vector z (2n): X = x_b - x_a, or V = v_b - v_a
 * for the velocity laws (rows n..2n). */
static size_t cx_off(const dv_elem_desc_t *e, size_t n)
{
    return dv_priv_elem_on_velocity(e->law) ? n : 0u;
}

static dv_real_t cx_dot(const dv_elem_desc_t *e, const dv_real_t *z, size_t n)
{
    const size_t o = cx_off(e, n);
    const dv_real_t za = e->dof_a == (uint16_t)DV_GROUND ? DV_R(0.0) : z[o + e->dof_a];
    return z[o + e->dof_b] - za;
}

dv_status_t dv_model_init(dv_model_t *m, const dv_model_desc_t *d, dv_real_t dt_s,
                          dv_real_t *buf, size_t len)
{
    if (m == NULL || d == NULL || buf == NULL) {
        return DV_EINVAL;
    }
    const dv_status_t st = validate(d, dt_s);
    if (st != DV_OK) {
        return st;
    }
    const size_t per = dv_model_persistent_len(d);
    if (len < dv_model_buf_len(d)) {
        return DV_ESIZE;
    }
    return dv_model_init_ex(m, d, dt_s, buf, per, buf + per, len - per);
}

dv_status_t dv_model_init_ex(dv_model_t *m, const dv_model_desc_t *d, dv_real_t dt_s,
                             dv_real_t *buf, size_t len, dv_real_t *scratch,
                             size_t scratch_len)
{
    if (m == NULL || d == NULL || buf == NULL || scratch == NULL) {
        return DV_EINVAL;
    }
    dv_status_t st = validate(d, dt_s);
    if (st != DV_OK) {
        return st;
    }
    if (len < dv_model_persistent_len(d) || scratch_len < dv_model_scratch_len(d)) {
        return DV_ESIZE;
    }
    const size_t n = d->n_dof;
    const size_t ns = 2u * n;
    const size_t nc = d->n_elem;
    const size_t nsub = nc > 0u ? d->n_sub : 1u;
    const size_t nf = (nsub + 1u) * nc;
    const size_t no = d->n_out;
    const size_t nb = 2u + nc;

    const dv_model_t zero = {0};
    *m = zero;
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

    /* what the observers' steps read first (DV_MODEL_STEP_LEN_HOLD), then what only the
     * builds of observers read: dv_model_keep_step_only() lets the caller reuse the tail */
    dv_real_t *p = buf;
    const bool cubic = d->input_hold == DV_HOLD_CUBIC;
    lay_step_part(m, &p);
    DV_ASSERT((size_t)(p - buf) ==
              DV_MODEL_STEP_LEN_HOLD(n, nc, nsub, no, (size_t)m->n_in));
    m->kmat = take(&p, n * n);
    m->cmat = take(&p, n * n);
    m->modes = take(&p, n * n);
    m->ac = take(&p, ns * ns);
    m->ad = take(&p, ns * ns);
    m->bc = take(&p, ns * nb);
    m->pa = take(&p, ns);
    m->pb = take(&p, ns);
    m->vmat = take(&p, ns * nf);
    if (cubic) {
        m->pu = take(&p, ns * 4u);
    }
    DV_ASSERT((size_t)(p - buf) <= len);
    dv_real_t *scr = scratch; /* init-only scratch, dead after init */

    for (size_t i = 0; i < n; i++) {
        m->mass_kg[i] = d->mass_kg[i];
    }
    /* K (eq. 2) */
    dv_real_t *k = m->kmat;
    for (size_t i = 0; i < n * n; i++) {
        k[i] = DV_R(0.0);
    }
    for (size_t i = 0; i < n; i++) {
        const dv_real_t ki = d->k_n_per_m[i];
        k[i * n + i] += ki;
        if (i > 0u) {
            k[(i - 1u) * n + (i - 1u)] += ki;
            k[i * n + (i - 1u)] -= ki;
            k[(i - 1u) * n + i] -= ki;
        }
    }
    /* generalised eigenproblem K phi = w^2 M phi via S = M^-1/2 K M^-1/2 (M diagonal) */
    dv_real_t lam[DV_MAX_DOF] = {DV_R(0.0)};
    dv_real_t w[DV_MAX_DOF] = {DV_R(0.0)};
    dv_real_t *v = scr;
    dv_real_t *tmp = v + n * n;
    dv_real_t *ework = tmp + n * n;
    st = eig_mass_scaled(n, m->mass_kg, k, lam, v, tmp, ework);
    if (st != DV_OK) {
        return st == DV_ENUMERIC ? DV_EINVAL : DV_EUNSTABLE;
    }
    for (size_t j = 0; j < n; j++) {
        w[j] = lam[j] > DV_R(0.0) ? DV_SQRT(lam[j]) : DV_R(0.0);
        m->freq_hz[j] = w[j] / TWO_PI_R;
        for (size_t i = 0; i < n; i++) {
            m->modes[i * n + j] = v[i * n + j] / DV_SQRT(m->mass_kg[i]);
        }
    }
    /* damping */
    dv_real_t *c = m->cmat;
    if (d->damp_kind == DV_DAMP_MODAL) {
        for (size_t i = 0; i < n; i++) {
            for (size_t j = 0; j < n; j++) {
                dv_real_t s = DV_R(0.0);
                for (size_t q = 0; q < n; q++) {
                    s += m->modes[i * n + q] * DV_R(2.0) * d->zeta[q] * w[q] *
                         m->modes[j * n + q];
                }
                c[i * n + j] = m->mass_kg[i] * m->mass_kg[j] * s;
            }
        }
    } else if (d->damp_kind == DV_DAMP_RAYLEIGH) {
        const size_t r = d->rayleigh_mode[0];
        const size_t s = d->rayleigh_mode[1];
        st = dv_model_rayleigh(w[r], d->rayleigh_zeta[0], w[s], d->rayleigh_zeta[1],
                               &m->rayleigh_a, &m->rayleigh_b);
        if (st != DV_OK) {
            return DV_EINVAL; /* a zero-frequency or repeated mode */
        }
        for (size_t i = 0; i < n * n; i++) {
            c[i] = m->rayleigh_b * k[i];
        }
        for (size_t i = 0; i < n; i++) {
            c[i * n + i] += m->rayleigh_a * m->mass_kg[i];
        }
    } else {
        for (size_t i = 0; i < n; i++) {
            for (size_t j = 0; j < n; j++) {
                c[i * n + j] = DV_R(0.5) * (d->c_n_s_per_m[i * n + j] + d->c_n_s_per_m[j * n + i]);
            }
        }
    }
    /* modal ratios actually in C, and positive semi-definiteness of C */
    for (size_t q = 0; q < n; q++) {
        dv_real_t s = DV_R(0.0);
        for (size_t i = 0; i < n; i++) {
            for (size_t j = 0; j < n; j++) {
                s += m->modes[i * n + q] * c[i * n + j] * m->modes[j * n + q];
            }
        }
        m->zeta[q] = w[q] > DV_R(0.0) ? s / (DV_R(2.0) * w[q]) : DV_R(0.0);
    }
    {
        dv_real_t cl[DV_MAX_DOF];
        st = eig_mass_scaled(n, m->mass_kg, c, cl, v, tmp, ework);
        if (st != DV_OK) {
            return DV_EUNSTABLE;
        }
        const dv_real_t big = DV_FABS(cl[n - 1u]) > DV_FABS(cl[0]) ? DV_FABS(cl[n - 1u])
                                                                   : DV_FABS(cl[0]);
        if (cl[0] < -DV_R(100.0) * DV_REAL_EPS * (dv_real_t)n * big) {
            return DV_EUNSTABLE;
        }
    }

    /* continuous state space, x = [q; v] */
    dv_real_t *a = m->ac;
    for (size_t i = 0; i < ns * ns; i++) {
        a[i] = DV_R(0.0);
    }
    for (size_t i = 0; i < n; i++) {
        a[i * ns + n + i] = DV_R(1.0);
        for (size_t j = 0; j < n; j++) {
            a[(n + i) * ns + j] = -k[i * n + j] / m->mass_kg[i];
            a[(n + i) * ns + n + j] = -c[i * n + j] / m->mass_kg[i];
        }
    }
    dv_real_t *b = m->bc;
    for (size_t i = 0; i < ns * nb; i++) {
        b[i] = DV_R(0.0);
    }
    dv_real_t k1sum = DV_R(0.0); /* 1^T K 1 and 1^T C 1 (ground displacement only) */
    dv_real_t c1sum = DV_R(0.0);
    for (size_t i = 0; i < n; i++) {
        dv_real_t kr = DV_R(0.0);
        dv_real_t cr = DV_R(0.0);
        for (size_t j = 0; j < n; j++) {
            kr += k[i * n + j];
            cr += c[i * n + j];
        }
        k1sum += kr;
        c1sum += cr;
        switch (d->input_kind) {
        case DV_INPUT_FORCE:
            b[(n + i) * nb] = i == d->input_dof ? DV_R(1.0) / m->mass_kg[i] : DV_R(0.0);
            break;
        case DV_INPUT_GROUND_ACC:
            b[(n + i) * nb] = DV_R(-1.0);
            break;
        default:
            b[(n + i) * nb] = kr / m->mass_kg[i];
            b[(n + i) * nb + 1u] = cr / m->mass_kg[i];
            break;
        }
    }
    for (size_t e = 0; e < nc; e++) {
        const dv_elem_desc_t *ce = &d->elem[e];
        m->elem[e] = *ce;
        m->elem_dx[e] = (ce->dof_a == (uint16_t)DV_GROUND &&
                            d->input_kind == DV_INPUT_GROUND_DISP)
                               ? DV_R(-1.0)
                               : DV_R(0.0);
        if (ce->dof_a != (uint16_t)DV_GROUND) {
            b[(n + ce->dof_a) * nb + 2u + e] = DV_R(1.0) / m->mass_kg[ce->dof_a];
        }
        b[(n + ce->dof_b) * nb + 2u + e] = DV_R(-1.0) / m->mass_kg[ce->dof_b];
    }

    /* full-step first-order hold on u (and the constant slope u' for ground displacement) */
    {
        dv_real_t bb[2u * DV_MAX_DOF * 2u] = {DV_R(0.0)};
        dv_real_t g0[2u * DV_MAX_DOF * 2u];
        dv_real_t g1[2u * DV_MAX_DOF * 2u];
        for (size_t i = 0; i < ns; i++) {
            bb[i * 2u] = b[i * nb];
            bb[i * 2u + 1u] = b[i * nb + 1u];
        }
        st = foh_expm(ns, 2u, a, bb, dt_s, m->ad, g0, g1, scr);
        if (st != DV_OK) {
            return st;
        }
        for (size_t i = 0; i < ns; i++) {
            m->pa[i] = g0[i * 2u] - g1[i * 2u] - g0[i * 2u + 1u] / dt_s;
            m->pb[i] = g1[i * 2u] + g0[i * 2u + 1u] / dt_s;
            if (!fin(m->pa[i]) || !fin(m->pb[i])) {
                return DV_EUNSTABLE;
            }
        }
        for (size_t i = 0; i < ns * ns; i++) {
            if (!fin(m->ad[i])) {
                return DV_EUNSTABLE;
            }
        }
    }

    /* outputs: y = Cy x + D0 u[k] + D1 u[k-1] + Ey g */
    for (size_t o = 0; o < no; o++) {
        dv_real_t *cy = m->cy + o * ns;
        dv_real_t *ey = m->ey + o * nc;
        for (size_t j = 0; j < ns; j++) {
            cy[j] = DV_R(0.0);
        }
        for (size_t e = 0; e < nc; e++) {
            ey[e] = DV_R(0.0);
        }
        m->d0[o] = DV_R(0.0);
        m->d1[o] = DV_R(0.0);
        const size_t idx = d->out[o].index;
        switch (d->out[o].kind) {
        case DV_OUT_ACC:
            for (size_t j = 0; j < ns; j++) {
                cy[j] = a[(n + idx) * ns + j];
            }
            for (size_t e = 0; e < nc; e++) {
                ey[e] = b[(n + idx) * nb + 2u + e];
            }
            if (d->input_kind == DV_INPUT_FORCE) {
                m->d0[o] = b[(n + idx) * nb];
            } else if (d->input_kind == DV_INPUT_GROUND_ACC) {
                m->d0[o] = DV_R(0.0); /* relative acceleration - u, plus u: absolute */
            } else {
                m->d0[o] = b[(n + idx) * nb] + b[(n + idx) * nb + 1u] / dt_s;
                m->d1[o] = -b[(n + idx) * nb + 1u] / dt_s;
            }
            break;
        case DV_OUT_VEL:
            cy[n + idx] = DV_R(1.0);
            break;
        case DV_OUT_DISP:
            cy[idx] = DV_R(1.0);
            break;
        case DV_OUT_SPRING_FORCE:
            cy[idx] = d->k_n_per_m[idx];
            if (idx > 0u) {
                cy[idx - 1u] = -d->k_n_per_m[idx];
            } else if (d->input_kind == DV_INPUT_GROUND_DISP) {
                m->d0[o] = -d->k_n_per_m[0];
            }
            break;
        case DV_OUT_ELEM_FORCE:
            ey[idx] = DV_R(1.0);
            break;
        default: /* DV_OUT_REACTION: 1^T K x_rel + 1^T C v_rel + ground contacts */
            for (size_t j = 0; j < n; j++) {
                dv_real_t ks = DV_R(0.0);
                dv_real_t cs = DV_R(0.0);
                for (size_t i = 0; i < n; i++) {
                    ks += k[i * n + j];
                    cs += c[i * n + j];
                }
                cy[j] = ks;
                cy[n + j] = cs;
            }
            for (size_t e = 0; e < nc; e++) {
                ey[e] = d->elem[e].dof_a == (uint16_t)DV_GROUND ? DV_R(1.0) : DV_R(0.0);
            }
            if (d->input_kind == DV_INPUT_GROUND_DISP) {
                m->d0[o] = -k1sum - c1sum / dt_s;
                m->d1[o] = c1sum / dt_s;
            }
            break;
        }
    }

    if (cubic) {
        /* full-step cubic hold: x[k+1] = Ad x[k] + sum_j Pu_j u[k-1+j], with u' = du/dt */
        dv_real_t bb[2u * DV_MAX_DOF * 2u] = {DV_R(0.0)};
        dv_real_t gq[4][2u * DV_MAX_DOF * 2u];
        dv_real_t *const gp[4] = {gq[0], gq[1], gq[2], gq[3]};
        dv_real_t *adc = scr;
        for (size_t i = 0; i < ns; i++) {
            bb[i * 2u] = b[i * nb];
            bb[i * 2u + 1u] = b[i * nb + 1u];
        }
        st = poly_expm(ns, 2u, 4u, a, bb, dt_s, adc, gp, scr + ns * ns);
        if (st != DV_OK) {
            return st;
        }
        for (size_t i = 0; i < ns; i++) {
            for (size_t j = 0; j < 4u; j++) {
                dv_real_t s = DV_R(0.0);
                for (size_t q = 0; q < 4u; q++) {
                    s += gq[q][i * 2u] * LAG3[q][j];
                    if (q < 3u) {
                        s += gq[q][i * 2u + 1u] * (dv_real_t)(q + 1u) * LAG3[q + 1u][j] / dt_s;
                    }
                }
                if (!fin(s)) {
                    return DV_EUNSTABLE;
                }
                m->pu[i * 4u + j] = s;
            }
        }
        /* y[k]: coefficient of u (d0 + d1) and of u' (-d1 dt), u' at the end of [t_k-1, t_k]
         * whose samples are u[k-2..k+1] */
        for (size_t o = 0; o < no; o++) {
            for (size_t j = 0; j < 4u; j++) {
                dv_real_t slope = DV_R(0.0);
                for (size_t q = 1; q < 4u; q++) {
                    slope += (dv_real_t)q * LAG3[q][j];
                }
                m->du[o * 4u + j] = (j == 2u ? m->d0[o] + m->d1[o] : DV_R(0.0)) - m->d1[o] * slope;
            }
        }
    }

    if (nc == 0u) {
        return DV_OK;
    }

    /* contact: highest frequency with every contact fully engaged vs the sub-step */
    {
        dv_real_t *ke = tmp + n * n; /* after v, tmp */
        dv_real_t *ework2 = ke + n * n;
        dv_real_t *tmp2 = ework2 + n * n;
        for (size_t i = 0; i < n * n; i++) {
            ke[i] = k[i];
        }
        for (size_t e = 0; e < nc; e++) {
            const dv_elem_desc_t *ce = &d->elem[e];
            if (ce->law != DV_ELEM_CONTACT && ce->law != DV_ELEM_STICKSLIP) {
                continue; /* only these laws add a bounded stiffness */
            }
            const dv_real_t kb = dv_elem_stiffness_bound(ce);
            ke[ce->dof_b * n + ce->dof_b] += kb;
            if (ce->dof_a != (uint16_t)DV_GROUND) {
                ke[ce->dof_a * n + ce->dof_a] += kb;
                ke[ce->dof_a * n + ce->dof_b] -= kb;
                ke[ce->dof_b * n + ce->dof_a] -= kb;
            }
        }
        dv_real_t le[DV_MAX_DOF];
        st = eig_mass_scaled(n, m->mass_kg, ke, le, v, tmp2, ework2);
        if (st != DV_OK) {
            return DV_EUNSTABLE;
        }
        m->w_elem_max = DV_SQRT(le[n - 1u] > DV_R(0.0) ? le[n - 1u] : DV_R(0.0));
        const dv_real_t h = dt_s / (dv_real_t)nsub;
        if (m->w_elem_max * h > (dv_real_t)DV_MODEL_ELEM_MAX_WH) {
            return DV_EUNSTABLE;
        }
        for (size_t e = 0; e < nc; e++) {
            const dv_elem_desc_t *ce = &d->elem[e];
            if (ce->law == DV_ELEM_FRICTION) {
                /* the regularised law's largest slope F / eps acts like a damper */
                dv_real_t inv_m = DV_R(1.0) / m->mass_kg[ce->dof_b];
                if (ce->dof_a != (uint16_t)DV_GROUND) {
                    inv_m += DV_R(1.0) / m->mass_kg[ce->dof_a];
                }
                if (ce->kb_n_per_m / ce->delta_m * h * inv_m >
                    (dv_real_t)DV_MODEL_ELEM_MAX_WH) {
                    return DV_EUNSTABLE;
                }
            }
        }
    }

    /* sub-step first-order hold on [u, u', contact forces] */
    const dv_real_t h = dt_s / (dv_real_t)nsub;
    dv_real_t *phih = scr;
    dv_real_t *g0 = phih + ns * ns;
    dv_real_t *g1 = g0 + ns * nb;
    dv_real_t *pah = g1 + ns * nb;
    dv_real_t *pbh = pah + ns;
    dv_real_t *za = pbh + ns;
    dv_real_t *zb = za + ns;
    dv_real_t *z = zb + ns;
    dv_real_t *zn = z + ns;
    dv_real_t *row = zn + ns;
    dv_real_t *rown = row + ns;
    dv_real_t *scr2 = rown + ns;
    st = foh_expm(ns, nb, a, b, h, phih, g0, g1, scr2);
    if (st != DV_OK) {
        return st;
    }
    for (size_t i = 0; i < ns; i++) {
        pah[i] = g0[i * nb] - g1[i * nb] - g0[i * nb + 1u] / h;
        pbh[i] = g1[i * nb] + g0[i * nb + 1u] / h;
    }
    /* X at node i from x[k]: cX Phih^i; from u[k], u[k+1]: through za/zb. */
    for (size_t e = 0; e < nc; e++) {
        for (size_t j = 0; j < ns; j++) {
            row[j] = DV_R(0.0);
        }
        const size_t off = cx_off(&m->elem[e], n);
        if (m->elem[e].dof_a != (uint16_t)DV_GROUND) {
            row[off + m->elem[e].dof_a] = DV_R(-1.0);
        }
        row[off + m->elem[e].dof_b] = DV_R(1.0);
        for (size_t i = 0; i <= nsub; i++) {
            const size_t f = i * nc + e;
            for (size_t j = 0; j < ns; j++) {
                m->rx[j * nf + f] = row[j]; /* column-major: see dv_model.h */
            }
            for (size_t j = 0; j < ns; j++) {
                dv_real_t s = DV_R(0.0);
                for (size_t q = 0; q < ns; q++) {
                    s += row[q] * phih[q * ns + j];
                }
                rown[j] = s;
            }
            for (size_t j = 0; j < ns; j++) {
                row[j] = rown[j];
            }
        }
    }
    for (size_t j = 0; j < ns; j++) {
        za[j] = DV_R(0.0);
        zb[j] = DV_R(0.0);
    }
    for (size_t i = 0; i <= nsub; i++) {
        const dv_real_t fi = (dv_real_t)i / (dv_real_t)nsub;
        for (size_t e = 0; e < nc; e++) {
            const size_t f = i * nc + e;
            if (dv_priv_elem_on_velocity(m->elem[e].law)) {
                /* V sees the ground velocity u' = (u[k+1] - u[k]) / T of the linear hold */
                m->rxa[f] = cx_dot(&m->elem[e], za, n) - m->elem_dx[e] / dt_s;
                m->rxb[f] = cx_dot(&m->elem[e], zb, n) + m->elem_dx[e] / dt_s;
            } else {
                m->rxa[f] = cx_dot(&m->elem[e], za, n) + m->elem_dx[e] * (DV_R(1.0) - fi);
                m->rxb[f] = cx_dot(&m->elem[e], zb, n) + m->elem_dx[e] * fi;
            }
        }
        if (i == nsub) {
            break;
        }
        /* sub-step i -> i+1 with u_i = (1 - i/N) u[k] + (i/N) u[k+1] */
        const dv_real_t f1 = (dv_real_t)(i + 1u) / (dv_real_t)nsub;
        for (size_t r = 0; r < ns; r++) {
            dv_real_t sa = DV_R(0.0);
            dv_real_t sb = DV_R(0.0);
            for (size_t q = 0; q < ns; q++) {
                sa += phih[r * ns + q] * za[q];
                sb += phih[r * ns + q] * zb[q];
            }
            zn[r] = sa + pah[r] * (DV_R(1.0) - fi) + pbh[r] * (DV_R(1.0) - f1);
            rown[r] = sb + pah[r] * fi + pbh[r] * f1;
        }
        for (size_t r = 0; r < ns; r++) {
            za[r] = zn[r];
            zb[r] = rown[r];
        }
    }
    if (cubic) {
        /* X at the sub-nodes from each sample of the cubic, through the exact sub-step
         * response to the cubic's pieces (u and u' columns only) */
        dv_real_t bb[2u * DV_MAX_DOF * 2u] = {DV_R(0.0)};
        dv_real_t gq[4][2u * DV_MAX_DOF * 2u];
        dv_real_t *const gp[4] = {gq[0], gq[1], gq[2], gq[3]};
        dv_real_t *phic = scr2;
        for (size_t i = 0; i < ns; i++) {
            bb[i * 2u] = b[i * nb];
            bb[i * 2u + 1u] = b[i * nb + 1u];
        }
        st = poly_expm(ns, 2u, 4u, a, bb, h, phic, gp, scr2 + ns * ns);
        if (st != DV_OK) {
            return st;
        }
        for (size_t j = 0; j < 4u; j++) {
            dv_real_t cu[4];
            dv_real_t cd[4];
            for (size_t q = 0; q < 4u; q++) {
                cu[q] = LAG3[q][j];
                cd[q] = q < 3u ? (dv_real_t)(q + 1u) * LAG3[q + 1u][j] / dt_s : DV_R(0.0);
            }
            for (size_t r = 0; r < ns; r++) {
                za[r] = DV_R(0.0);
            }
            for (size_t i = 0; i <= nsub; i++) {
                const dv_real_t si = (dv_real_t)i / (dv_real_t)nsub;
                const dv_real_t ui = cu[0] + si * (cu[1] + si * (cu[2] + si * cu[3]));
                for (size_t e = 0; e < nc; e++) {
                    const size_t f = i * nc + e;
                    const dv_real_t ud = (cu[1] + si * (DV_R(2.0) * cu[2] +
                                                        DV_R(3.0) * si * cu[3])) / dt_s;
                    m->rxu[f * 4u + j] =
                        cx_dot(&m->elem[e], za, n) +
                        m->elem_dx[e] *
                            (dv_priv_elem_on_velocity(m->elem[e].law) ? ud : ui);
                }
                if (i == nsub) {
                    break;
                }
                dv_real_t lu[4];
                dv_real_t ld[4];
                poly_sub(cu, i, nsub, lu);
                poly_sub(cd, i, nsub, ld);
                for (size_t r = 0; r < ns; r++) {
                    dv_real_t s = DV_R(0.0);
                    for (size_t q = 0; q < ns; q++) {
                        s += phih[r * ns + q] * za[q];
                    }
                    for (size_t q = 0; q < 4u; q++) {
                        s += gq[q][r * 2u] * lu[q] + gq[q][r * 2u + 1u] * ld[q];
                    }
                    zn[r] = s;
                }
                for (size_t r = 0; r < ns; r++) {
                    za[r] = zn[r];
                }
            }
        }
        for (size_t i = 0; i < nf * 4u; i++) {
            if (!fin(m->rxu[i])) {
                return DV_EUNSTABLE;
            }
        }
    }
    /* response to each sub-node force: X at later nodes (smat) and the end state (vmat) */
    for (size_t i = 0; i < nf * nf; i++) {
        m->smat[i] = DV_R(0.0);
    }
    for (size_t jn = 0; jn <= nsub; jn++) {
        for (size_t e2 = 0; e2 < nc; e2++) {
            const size_t col = jn * nc + e2;
            for (size_t r = 0; r < ns; r++) {
                z[r] = DV_R(0.0);
            }
            for (size_t i = 1; i <= nsub; i++) {
                for (size_t r = 0; r < ns; r++) {
                    dv_real_t s = DV_R(0.0);
                    for (size_t q = 0; q < ns; q++) {
                        s += phih[r * ns + q] * z[q];
                    }
                    if (jn == i - 1u) {
                        s += g0[r * nb + 2u + e2] - g1[r * nb + 2u + e2];
                    }
                    if (jn == i) {
                        s += g1[r * nb + 2u + e2];
                    }
                    zn[r] = s;
                }
                for (size_t r = 0; r < ns; r++) {
                    z[r] = zn[r];
                }
                for (size_t e = 0; e < nc; e++) {
                    m->smat[(i * nc + e) * nf + col] = cx_dot(&m->elem[e], z, n);
                }
            }
            for (size_t r = 0; r < ns; r++) {
                m->vmat[r * nf + col] = z[r];
            }
        }
    }
    for (size_t i = 0; i < nf * ns; i++) {
        if (!fin(m->rx[i]) || !fin(m->vmat[i])) {
            return DV_EUNSTABLE;
        }
    }
    return DV_OK;
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

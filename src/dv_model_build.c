/* Building a model, dv_model_init_ex(): from the description to the discretised matrices in
 * stages over one build context (struct build), in the order dv_model_init_ex() calls them: the
 * linear model and its input holds, then the elements' sub-step scheme. The equations are in
 * dv_model.h; dv_model_priv.h says what pins the results. */
#include "dynval/dv_model.h"
#include "dv_elem_law.h"
#include "dv_model_priv.h"
#include "dv_priv.h"

#define TWO_PI_R DV_R(6.283185307179586)

/* Lagrange cubic through u[k-1], u[k], u[k+1], u[k+2] (nodes s = -1, 0, 1, 2): coefficient of
 * s^p (row p) of sample u[k-1+j] (column j) over s in [0, 1]. */
static const dv_real_t LAG3[DV_PRIV_CUBIC_NIN][DV_PRIV_CUBIC_NIN] = {
    {DV_R(0.0), DV_R(1.0), DV_R(0.0), DV_R(0.0)},
    {DV_R(-1.0) / DV_R(3.0), DV_R(-0.5), DV_R(1.0), DV_R(-1.0) / DV_R(6.0)},
    {DV_R(0.5), DV_R(-1.0), DV_R(0.5), DV_R(0.0)},
    {DV_R(-1.0) / DV_R(6.0), DV_R(0.5), DV_R(-0.5), DV_R(1.0) / DV_R(6.0)}};

/* The sub-step stages' pieces of the init scratch (ns each unless said); the first five carry
 * results from one sub-step stage to the next. */
struct sub_scratch {
    dv_real_t *phih;     /* ns x ns: exp(A h), the state's map over one sub-step */
    dv_real_t *g0;       /* ns x nb: G0 of the sub-step's first-order hold, every input column */
    dv_real_t *g1;       /* ns x nb: its G1 */
    dv_real_t *pah;      /* state after one sub-step from the input at its start */
    dv_real_t *pbh;      /* state after one sub-step from the input at its end */
    dv_real_t *row;      /* a row of the map from x[k] to X at a sub-node */
    dv_real_t *row_next; /* that row at the next sub-node */
    dv_real_t *za;       /* a state response propagated node by node */
    dv_real_t *za_next;  /* za at the next sub-node */
    dv_real_t *zb;       /* a second one */
    dv_real_t *zb_next;  /* zb at the next sub-node */
    dv_real_t *rest;     /* the rest: the matrix exponentials' scratch */
};

/* What the build stages share: the description, the model being built, its sizes, what one
 * stage leaves for a later one, and the init scratch (dead when dv_model_init_ex() returns). */
struct build {
    const dv_model_desc_t *d; /* the description */
    dv_model_t *m;            /* the model being built */
    size_t n;                 /* DOF */
    size_t ns;                /* states, 2 n: displacements then velocities */
    size_t nc;                /* elements */
    size_t nsub;              /* element sub-steps per sample (1 without elements) */
    size_t nf;                /* sub-node element forces per step, (nsub + 1) nc */
    size_t no;                /* outputs */
    size_t nb;                /* columns of B: DV_PRIV_U_COLS, then one per element */
    bool cubic;               /* DV_HOLD_CUBIC */
    dv_real_t dt_s;           /* sample period T, s */
    dv_real_t h;              /* element sub-step T / nsub, s */
    dv_real_t w[DV_MAX_DOF];  /* undamped circular frequencies, rad/s, ascending */
    dv_real_t k1sum;          /* 1^T K 1 and 1^T C 1: the reaction output under ground */
    dv_real_t c1sum;          /* displacement */
    dv_real_t *scratch;       /* the init scratch, carved twice (begin_build()): */
    dv_priv_model_eig_scratch_t eig; /* the eigen-solutions' pieces, n x n each */
    dv_real_t *k_stiff;       /* n x n after them: K with every element at its stiffness bound */
    struct sub_scratch sub;   /* the sub-step stages' pieces, over the eigen-solutions' */
};

/* The build context of a model laid out by dv_priv_model_lay_out(), and the init scratch
 * carved twice: the eigen-solutions' pieces (and K stiffened) from its start, and the sub-step
 * stages' pieces over them, used once the eigen-solutions are dead. */
static void begin_build(struct build *bd, const dv_model_desc_t *d, dv_model_t *m,
                        dv_real_t *scratch)
{
    const struct build zero_build = {0};
    *bd = zero_build;
    bd->d = d;
    bd->m = m;
    bd->n = m->n_dof;
    bd->ns = m->n_state;
    bd->nc = m->n_elem;
    bd->nsub = m->n_sub;
    bd->nf = m->n_f;
    bd->no = m->n_out;
    bd->nb = DV_PRIV_U_COLS + bd->nc;
    bd->cubic = m->input_hold == DV_HOLD_CUBIC;
    bd->dt_s = m->dt_s;
    bd->h = bd->dt_s / (dv_real_t)bd->nsub;
    bd->scratch = scratch;
    const size_t nn = bd->n * bd->n;
    bd->eig.vec = scratch;
    bd->eig.scaled = bd->eig.vec + nn;
    bd->eig.work = bd->eig.scaled + nn;
    bd->k_stiff = bd->eig.work + nn;

    const size_t ns = bd->ns, nb = bd->nb;
    struct sub_scratch *s = &bd->sub;
    s->phih = scratch;
    s->g0 = s->phih + ns * ns;
    s->g1 = s->g0 + ns * nb;
    s->pah = s->g1 + ns * nb;
    s->pbh = s->pah + ns;
    s->row = s->pbh + ns;
    s->row_next = s->row + ns;
    s->za = s->row_next + ns;
    s->za_next = s->za + ns;
    s->zb = s->za_next + ns;
    s->zb_next = s->zb + ns;
    s->rest = s->zb_next + ns;
}

/* ---- the linear model and its input holds ------------------------------------------------ */

/* Adds a coupling v between DOFs a and b to the n x n matrix z (a spring or a dashpot). */
static void add_coupling(dv_real_t *z, size_t n, size_t a, size_t b, dv_real_t v)
{
    z[a * n + a] += v;
    z[b * n + b] += v;
    z[a * n + b] -= v;
    z[b * n + a] -= v;
}

/* K of the chain (eq. 2): story spring i ties DOF i-1 (the ground for i = 0) to DOF i; then
 * the links' springs. */
static void assemble_stiffness(const struct build *bd)
{
    const size_t n = bd->n;
    dv_real_t *k = bd->m->kmat;
    for (size_t i = 0; i < n * n; i++) {
        k[i] = DV_R(0.0);
    }
    for (size_t i = 0; i < n; i++) {
        const dv_real_t ki = bd->d->k_n_per_m[i];
        k[i * n + i] += ki;
        if (i > 0u) {
            k[(i - 1u) * n + (i - 1u)] += ki;
            k[i * n + (i - 1u)] -= ki;
            k[(i - 1u) * n + i] -= ki;
        }
    }
    for (size_t l = 0; l < bd->d->n_link; l++) {
        const dv_link_desc_t *lk = &bd->d->link[l];
        add_coupling(k, n, lk->dof_a, lk->dof_b, lk->k_n_per_m);
    }
}

/* Natural frequencies and mass-normalised modes: K phi = w^2 M phi solved as the symmetric
 * S = M^-1/2 K M^-1/2 (M diagonal), whose eigenvectors v give phi = M^-1/2 v. */
static dv_status_t solve_modes(struct build *bd)
{
    dv_model_t *m = bd->m;
    const size_t n = bd->n;
    const dv_real_t *v = bd->eig.vec;
    dv_real_t lam[DV_MAX_DOF] = {DV_R(0.0)};
    const dv_status_t st = dv_priv_model_eig(m, m->kmat, lam, bd->eig);
    if (st != DV_OK) {
        return st == DV_ENUMERIC ? DV_EINVAL : DV_EUNSTABLE;
    }
    for (size_t j = 0; j < n; j++) {
        bd->w[j] = lam[j] > DV_R(0.0) ? DV_SQRT(lam[j]) : DV_R(0.0);
        m->freq_hz[j] = bd->w[j] / TWO_PI_R;
        for (size_t i = 0; i < n; i++) {
            m->modes[i * n + j] = v[i * n + j] / DV_SQRT(m->mass_kg[i]);
        }
    }
    return DV_OK;
}

/* C as the description gives it (dv_model.h), then the links' dashpots; the Rayleigh
 * coefficients stay in the model. */
static dv_status_t assemble_damping(const struct build *bd)
{
    dv_model_t *m = bd->m;
    const dv_model_desc_t *d = bd->d;
    const size_t n = bd->n;
    const dv_real_t *k = m->kmat;
    dv_real_t *c = m->cmat;
    if (d->damp_kind == DV_DAMP_MODAL) {
        for (size_t i = 0; i < n; i++) {
            for (size_t j = 0; j < n; j++) {
                dv_real_t s = DV_R(0.0);
                for (size_t q = 0; q < n; q++) {
                    s += m->modes[i * n + q] * DV_R(2.0) * d->zeta[q] * bd->w[q] *
                         m->modes[j * n + q];
                }
                c[i * n + j] = m->mass_kg[i] * m->mass_kg[j] * s;
            }
        }
    } else if (d->damp_kind == DV_DAMP_RAYLEIGH) {
        const size_t r = d->rayleigh_mode[0];
        const size_t s = d->rayleigh_mode[1];
        const dv_status_t st = dv_model_rayleigh(bd->w[r], d->rayleigh_zeta[0], bd->w[s],
                                                 d->rayleigh_zeta[1], &m->rayleigh_a,
                                                 &m->rayleigh_b);
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
    for (size_t l = 0; l < d->n_link; l++) {
        add_coupling(c, n, d->link[l].dof_a, d->link[l].dof_b, d->link[l].c_n_s_per_m);
    }
    return DV_OK;
}

/* The modal ratios C really gives (whatever its kind), and C positive semi-definite: a
 * negative Rayleigh b, say, would make a mode grow. */
static dv_status_t check_damping(const struct build *bd)
{
    dv_model_t *m = bd->m;
    const size_t n = bd->n;
    const dv_real_t *c = m->cmat;
    for (size_t q = 0; q < n; q++) {
        dv_real_t s = DV_R(0.0);
        for (size_t i = 0; i < n; i++) {
            for (size_t j = 0; j < n; j++) {
                s += m->modes[i * n + q] * c[i * n + j] * m->modes[j * n + q];
            }
        }
        m->zeta[q] = bd->w[q] > DV_R(0.0) ? s / (DV_R(2.0) * bd->w[q]) : DV_R(0.0);
    }
    dv_real_t cl[DV_MAX_DOF];
    const dv_status_t st = dv_priv_model_eig(m, c, cl, bd->eig);
    if (st != DV_OK) {
        return DV_EUNSTABLE;
    }
    const dv_real_t big =
        DV_FABS(cl[n - 1u]) > DV_FABS(cl[0]) ? DV_FABS(cl[n - 1u]) : DV_FABS(cl[0]);
    if (cl[0] < -DV_R(100.0) * DV_REAL_EPS * (dv_real_t)n * big) {
        return DV_EUNSTABLE;
    }
    return DV_OK;
}

/* Continuous state space, x = [q; v]: A, and B's input columns (u; u' under ground
 * displacement, whose ground springs and dampers see x - x_g). Also 1^T K 1 and 1^T C 1 for the
 * reaction output under ground displacement. */
static void assemble_state_space(struct build *bd)
{
    dv_model_t *m = bd->m;
    const size_t n = bd->n, ns = bd->ns, nb = bd->nb;
    const dv_real_t *k = m->kmat;
    const dv_real_t *c = m->cmat;
    dv_real_t *a = m->ac;
    dv_real_t *b = m->bc;
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
    for (size_t i = 0; i < ns * nb; i++) {
        b[i] = DV_R(0.0);
    }
    dv_real_t k1sum = DV_R(0.0);
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
        switch (bd->d->input_kind) {
        case DV_INPUT_FORCE:
            b[(n + i) * nb] = i == bd->d->input_dof ? DV_R(1.0) / m->mass_kg[i] : DV_R(0.0);
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
    bd->k1sum = k1sum;
    bd->c1sum = c1sum;
}

/* The elements join the state space as extra inputs: the model's copies, how an element's
 * ground end follows the input (elem_dx), and B's force columns (+g on DOF a, -g on DOF b). */
static void attach_elements(const struct build *bd)
{
    dv_model_t *m = bd->m;
    const dv_model_desc_t *d = bd->d;
    const size_t n = bd->n, nb = bd->nb;
    dv_real_t *b = m->bc;
    for (size_t e = 0; e < bd->nc; e++) {
        const dv_elem_desc_t *ce = &d->elem[e];
        m->elem[e] = *ce;
        m->elem_dx[e] =
            (ce->dof_a == (uint16_t)DV_GROUND && d->input_kind == DV_INPUT_GROUND_DISP)
                ? DV_R(-1.0)
                : DV_R(0.0);
        if (ce->dof_a != (uint16_t)DV_GROUND) {
            b[(n + ce->dof_a) * nb + DV_PRIV_U_COLS + e] = DV_R(1.0) / m->mass_kg[ce->dof_a];
        }
        b[(n + ce->dof_b) * nb + DV_PRIV_U_COLS + e] = DV_R(-1.0) / m->mass_kg[ce->dof_b];
    }
}

/* The full-step first-order hold on u (and on its constant slope u' under ground displacement):
 * x[k+1] = Ad x[k] + pa u[k] + pb u[k+1]. */
static dv_status_t discretise_full_step(const struct build *bd)
{
    dv_model_t *m = bd->m;
    const size_t ns = bd->ns;
    const dv_real_t dt_s = bd->dt_s;
    dv_real_t gq[2][DV_PRIV_U_BLOCK_LEN];
    const dv_status_t st = dv_priv_model_input_hold_expm(m, 2u, dt_s, m->ad, gq, bd->scratch);
    if (st != DV_OK) {
        return st;
    }
    const dv_real_t *g0 = gq[0];
    const dv_real_t *g1 = gq[1];
    for (size_t i = 0; i < ns; i++) {
        m->pa[i] = g0[i * DV_PRIV_U_COLS] - g1[i * DV_PRIV_U_COLS] -
                   g0[i * DV_PRIV_U_COLS + 1u] / dt_s;
        m->pb[i] = g1[i * DV_PRIV_U_COLS] + g0[i * DV_PRIV_U_COLS + 1u] / dt_s;
        if (!dv_priv_finite(m->pa[i]) || !dv_priv_finite(m->pb[i])) {
            return DV_EUNSTABLE;
        }
    }
    for (size_t i = 0; i < ns * ns; i++) {
        if (!dv_priv_finite(m->ad[i])) {
            return DV_EUNSTABLE;
        }
    }
    return DV_OK;
}

/* Output row o: y = Cy x + D0 u[k] + D1 u[k-1] + Ey g. */
static void build_output(const struct build *bd, size_t o)
{
    dv_model_t *m = bd->m;
    const dv_model_desc_t *d = bd->d;
    const size_t n = bd->n, ns = bd->ns, nc = bd->nc, nb = bd->nb;
    const dv_real_t dt_s = bd->dt_s;
    const dv_real_t *a = m->ac;
    const dv_real_t *b = m->bc;
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
            ey[e] = b[(n + idx) * nb + DV_PRIV_U_COLS + e];
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
                ks += m->kmat[i * n + j];
                cs += m->cmat[i * n + j];
            }
            cy[j] = ks;
            cy[n + j] = cs;
        }
        for (size_t e = 0; e < nc; e++) {
            ey[e] = d->elem[e].dof_a == (uint16_t)DV_GROUND ? DV_R(1.0) : DV_R(0.0);
        }
        if (d->input_kind == DV_INPUT_GROUND_DISP) {
            m->d0[o] = -bd->k1sum - bd->c1sum / dt_s;
            m->d1[o] = bd->c1sum / dt_s;
        }
        break;
    }
}

/* The full-step cubic hold: x[k+1] = Ad x[k] + sum_j Pu_j u[k-1+j] (u' the cubic's derivative),
 * and the outputs' coefficients of the cubic's samples (du). */
static dv_status_t discretise_cubic(const struct build *bd)
{
    dv_model_t *m = bd->m;
    const size_t ns = bd->ns;
    const dv_real_t dt_s = bd->dt_s;
    dv_real_t gq[DV_PRIV_CUBIC_NIN][DV_PRIV_U_BLOCK_LEN];
    const dv_status_t st =
        dv_priv_model_input_hold_expm(m, DV_PRIV_CUBIC_NIN, dt_s, NULL, gq, bd->scratch);
    if (st != DV_OK) {
        return st;
    }
    for (size_t i = 0; i < ns; i++) {
        for (size_t j = 0; j < DV_PRIV_CUBIC_NIN; j++) {
            dv_real_t s = DV_R(0.0);
            for (size_t q = 0; q < DV_PRIV_CUBIC_NIN; q++) {
                s += gq[q][i * DV_PRIV_U_COLS] * LAG3[q][j];
                if (q < 3u) {
                    s += gq[q][i * DV_PRIV_U_COLS + 1u] * (dv_real_t)(q + 1u) *
                         LAG3[q + 1u][j] / dt_s;
                }
            }
            if (!dv_priv_finite(s)) {
                return DV_EUNSTABLE;
            }
            m->pu[i * DV_PRIV_CUBIC_NIN + j] = s;
        }
    }
    /* y[k]: coefficient of u (d0 + d1) and of u' (-d1 dt), u' at the end of [t_k-1, t_k]
     * whose samples are u[k-2..k+1] */
    for (size_t o = 0; o < bd->no; o++) {
        for (size_t j = 0; j < DV_PRIV_CUBIC_NIN; j++) {
            dv_real_t slope = DV_R(0.0);
            for (size_t q = 1; q < DV_PRIV_CUBIC_NIN; q++) {
                slope += (dv_real_t)q * LAG3[q][j];
            }
            m->du[o * DV_PRIV_CUBIC_NIN + j] =
                (j == 2u ? m->d0[o] + m->d1[o] : DV_R(0.0)) - m->d1[o] * slope;
        }
    }
    return DV_OK;
}

/* ---- the elements' sub-step scheme -------------------------------------------------------- */

/* The sub-step against the stiffest elements (dv_model.h): with every element at its
 * dv_elem_stiffness_bound() the highest natural frequency must keep w h <= DV_MODEL_ELEM_MAX_WH,
 * and an element's dv_elem_damping_bound() must keep bound h (1/m_a + 1/m_b) under the same
 * limit, or the steps' fixed-point iterations do not contract. */
static dv_status_t check_element_substep(const struct build *bd)
{
    dv_model_t *m = bd->m;
    const size_t n = bd->n;
    const dv_real_t h = bd->h;
    dv_real_t *ke = bd->k_stiff;
    for (size_t i = 0; i < n * n; i++) {
        ke[i] = m->kmat[i];
    }
    for (size_t e = 0; e < bd->nc; e++) {
        const dv_elem_desc_t *ce = &bd->d->elem[e];
        const dv_real_t kb = dv_elem_stiffness_bound(ce); /* 0 for the laws that add none */
        ke[ce->dof_b * n + ce->dof_b] += kb;
        if (ce->dof_a != (uint16_t)DV_GROUND) {
            ke[ce->dof_a * n + ce->dof_a] += kb;
            ke[ce->dof_a * n + ce->dof_b] -= kb;
            ke[ce->dof_b * n + ce->dof_a] -= kb;
        }
    }
    dv_real_t le[DV_MAX_DOF];
    const dv_status_t st = dv_priv_model_eig(m, ke, le, bd->eig);
    if (st != DV_OK) {
        return DV_EUNSTABLE;
    }
    m->w_elem_max = DV_SQRT(le[n - 1u] > DV_R(0.0) ? le[n - 1u] : DV_R(0.0));
    if (m->w_elem_max * h > (dv_real_t)DV_MODEL_ELEM_MAX_WH) {
        return DV_EUNSTABLE;
    }
    for (size_t e = 0; e < bd->nc; e++) {
        const dv_elem_desc_t *ce = &bd->d->elem[e];
        dv_real_t inv_m = DV_R(1.0) / m->mass_kg[ce->dof_b];
        if (ce->dof_a != (uint16_t)DV_GROUND) {
            inv_m += DV_R(1.0) / m->mass_kg[ce->dof_a];
        }
        if (dv_elem_damping_bound(ce) * h * inv_m > (dv_real_t)DV_MODEL_ELEM_MAX_WH) {
            return DV_EUNSTABLE;
        }
    }
    return DV_OK;
}

/* The first-order hold over one sub-step h on every input column [u, u', element forces]:
 * Phih, G0, G1, and the sub-step's maps pah, pbh from its start and end input. */
static dv_status_t discretise_sub_step(const struct build *bd)
{
    const struct sub_scratch *s = &bd->sub;
    const size_t ns = bd->ns, nb = bd->nb;
    const dv_real_t h = bd->h;
    dv_real_t *const gp[2] = {s->g0, s->g1};
    const dv_status_t st =
        dv_priv_model_poly_expm(ns, nb, 2u, bd->m->ac, bd->m->bc, h, s->phih, gp, s->rest);
    if (st != DV_OK) {
        return st;
    }
    for (size_t i = 0; i < ns; i++) {
        s->pah[i] = s->g0[i * nb] - s->g1[i * nb] - s->g0[i * nb + 1u] / h;
        s->pbh[i] = s->g1[i * nb] + s->g0[i * nb + 1u] / h;
    }
    return DV_OK;
}

/* X at sub-node i from x[k] (rx, column-major: dv_model.h): the element's row of the state,
 * times Phih^i. */
static void subnode_from_state(const struct build *bd)
{
    const struct sub_scratch *s = &bd->sub;
    dv_model_t *m = bd->m;
    const size_t n = bd->n, ns = bd->ns, nc = bd->nc, nf = bd->nf;
    dv_real_t *row = s->row;
    dv_real_t *row_next = s->row_next;
    for (size_t e = 0; e < nc; e++) {
        for (size_t j = 0; j < ns; j++) {
            row[j] = DV_R(0.0);
        }
        const size_t off = dv_priv_elem_arg_off(&m->elem[e], n);
        if (m->elem[e].dof_a != (uint16_t)DV_GROUND) {
            row[off + m->elem[e].dof_a] = DV_R(-1.0);
        }
        row[off + m->elem[e].dof_b] = DV_R(1.0);
        for (size_t i = 0; i <= bd->nsub; i++) {
            const size_t f = i * nc + e;
            for (size_t j = 0; j < ns; j++) {
                m->rx[j * nf + f] = row[j];
            }
            for (size_t j = 0; j < ns; j++) {
                dv_real_t sum = DV_R(0.0);
                for (size_t q = 0; q < ns; q++) {
                    sum += row[q] * s->phih[q * ns + j];
                }
                row_next[j] = sum;
            }
            for (size_t j = 0; j < ns; j++) {
                row[j] = row_next[j];
            }
        }
    }
}

/* X at each sub-node from u[k] (rxa) and u[k+1] (rxb) of the linear hold: the states za, zb
 * they drive through the sub-steps, plus the motion of a ground end that follows u. */
static void subnode_from_input(const struct build *bd)
{
    const struct sub_scratch *s = &bd->sub;
    dv_model_t *m = bd->m;
    const size_t n = bd->n, ns = bd->ns, nc = bd->nc, nsub = bd->nsub;
    const dv_real_t dt_s = bd->dt_s;
    dv_real_t *za = s->za;
    dv_real_t *zb = s->zb;
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
                m->rxa[f] = dv_priv_elem_arg(&m->elem[e], za, n) - m->elem_dx[e] / dt_s;
                m->rxb[f] = dv_priv_elem_arg(&m->elem[e], zb, n) + m->elem_dx[e] / dt_s;
            } else {
                m->rxa[f] = dv_priv_elem_arg(&m->elem[e], za, n) + m->elem_dx[e] * (DV_R(1.0) - fi);
                m->rxb[f] = dv_priv_elem_arg(&m->elem[e], zb, n) + m->elem_dx[e] * fi;
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
                sa += s->phih[r * ns + q] * za[q];
                sb += s->phih[r * ns + q] * zb[q];
            }
            s->za_next[r] = sa + s->pah[r] * (DV_R(1.0) - fi) + s->pbh[r] * (DV_R(1.0) - f1);
            s->zb_next[r] = sb + s->pah[r] * fi + s->pbh[r] * f1;
        }
        for (size_t r = 0; r < ns; r++) {
            za[r] = s->za_next[r];
            zb[r] = s->zb_next[r];
        }
    }
}

/* Cubic hold: X at the sub-nodes from each sample u[k-1+j] of the cubic (rxu), through the
 * exact sub-step response to the cubic's pieces (u and u' columns only). */
static dv_status_t subnode_from_cubic(const struct build *bd)
{
    const struct sub_scratch *s = &bd->sub;
    dv_model_t *m = bd->m;
    const size_t n = bd->n, ns = bd->ns, nc = bd->nc, nsub = bd->nsub;
    const dv_real_t dt_s = bd->dt_s;
    dv_real_t gq[DV_PRIV_CUBIC_NIN][DV_PRIV_U_BLOCK_LEN];
    const dv_status_t st =
        dv_priv_model_input_hold_expm(m, DV_PRIV_CUBIC_NIN, bd->h, NULL, gq, s->rest);
    if (st != DV_OK) {
        return st;
    }
    dv_real_t *za = s->za;
    for (size_t j = 0; j < DV_PRIV_CUBIC_NIN; j++) {
        dv_real_t cu[DV_PRIV_CUBIC_NIN]; /* sample j's share of u(s), and of u'(s), by power of s */
        dv_real_t cd[DV_PRIV_CUBIC_NIN];
        for (size_t q = 0; q < DV_PRIV_CUBIC_NIN; q++) {
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
                const dv_real_t ud =
                    (cu[1] + si * (DV_R(2.0) * cu[2] + DV_R(3.0) * si * cu[3])) / dt_s;
                m->rxu[f * DV_PRIV_CUBIC_NIN + j] =
                    dv_priv_elem_arg(&m->elem[e], za, n) +
                    m->elem_dx[e] * (dv_priv_elem_on_velocity(m->elem[e].law) ? ud : ui);
            }
            if (i == nsub) {
                break;
            }
            dv_real_t lu[DV_PRIV_CUBIC_NIN];
            dv_real_t ld[DV_PRIV_CUBIC_NIN];
            dv_priv_model_poly_sub(cu, i, nsub, lu);
            dv_priv_model_poly_sub(cd, i, nsub, ld);
            for (size_t r = 0; r < ns; r++) {
                dv_real_t sum = DV_R(0.0);
                for (size_t q = 0; q < ns; q++) {
                    sum += s->phih[r * ns + q] * za[q];
                }
                for (size_t q = 0; q < DV_PRIV_CUBIC_NIN; q++) {
                    sum += gq[q][r * DV_PRIV_U_COLS] * lu[q] +
                           gq[q][r * DV_PRIV_U_COLS + 1u] * ld[q];
                }
                s->za_next[r] = sum;
            }
            for (size_t r = 0; r < ns; r++) {
                za[r] = s->za_next[r];
            }
        }
    }
    for (size_t i = 0; i < bd->nf * DV_PRIV_CUBIC_NIN; i++) {
        if (!dv_priv_finite(m->rxu[i])) {
            return DV_EUNSTABLE;
        }
    }
    return DV_OK;
}

/* The response to each sub-node force (node jn of element e2, held linearly between its
 * neighbouring nodes): X at the later nodes (smat) and the end state x[k+1] (vmat). */
static void subnode_from_forces(const struct build *bd)
{
    const struct sub_scratch *s = &bd->sub;
    dv_model_t *m = bd->m;
    const size_t n = bd->n, ns = bd->ns, nc = bd->nc, nf = bd->nf, nb = bd->nb;
    dv_real_t *z = s->za;
    for (size_t i = 0; i < nf * nf; i++) {
        m->smat[i] = DV_R(0.0);
    }
    for (size_t jn = 0; jn <= bd->nsub; jn++) {
        for (size_t e2 = 0; e2 < nc; e2++) {
            const size_t col = jn * nc + e2;
            for (size_t r = 0; r < ns; r++) {
                z[r] = DV_R(0.0);
            }
            for (size_t i = 1; i <= bd->nsub; i++) {
                for (size_t r = 0; r < ns; r++) {
                    dv_real_t sum = DV_R(0.0);
                    for (size_t q = 0; q < ns; q++) {
                        sum += s->phih[r * ns + q] * z[q];
                    }
                    if (jn == i - 1u) {
                        sum += s->g0[r * nb + DV_PRIV_U_COLS + e2] -
                               s->g1[r * nb + DV_PRIV_U_COLS + e2];
                    }
                    if (jn == i) {
                        sum += s->g1[r * nb + DV_PRIV_U_COLS + e2];
                    }
                    s->za_next[r] = sum;
                }
                for (size_t r = 0; r < ns; r++) {
                    z[r] = s->za_next[r];
                }
                for (size_t e = 0; e < nc; e++) {
                    m->smat[(i * nc + e) * nf + col] = dv_priv_elem_arg(&m->elem[e], z, n);
                }
            }
            for (size_t r = 0; r < ns; r++) {
                m->vmat[r * nf + col] = z[r];
            }
        }
    }
}

dv_status_t dv_model_init_ex(dv_model_t *m, const dv_model_desc_t *d, dv_real_t dt_s,
                             dv_real_t *buf, size_t len, dv_real_t *scratch,
                             size_t scratch_len)
{
    if (m == NULL || d == NULL || buf == NULL || scratch == NULL) {
        return DV_EINVAL;
    }
    dv_status_t st = dv_priv_model_validate(d, dt_s);
    if (st != DV_OK) {
        return st;
    }
    if (len < dv_model_persistent_len(d) || scratch_len < dv_model_scratch_len(d)) {
        return DV_ESIZE;
    }
    dv_priv_model_lay_out(m, d, dt_s, buf, len);
    struct build bd;
    begin_build(&bd, d, m, scratch);

    /* the linear structure and its discretisation */
    assemble_stiffness(&bd);
    st = solve_modes(&bd);
    if (st != DV_OK) {
        return st;
    }
    st = assemble_damping(&bd);
    if (st != DV_OK) {
        return st;
    }
    st = check_damping(&bd);
    if (st != DV_OK) {
        return st;
    }
    assemble_state_space(&bd);
    attach_elements(&bd);
    st = discretise_full_step(&bd);
    if (st != DV_OK) {
        return st;
    }
    for (size_t o = 0; o < bd.no; o++) {
        build_output(&bd, o);
    }
    if (bd.cubic) {
        st = discretise_cubic(&bd);
        if (st != DV_OK) {
            return st;
        }
    }
    if (bd.nc == 0u) {
        return DV_OK;
    }

    /* the elements' sub-step scheme: the sub-node maps the observers' steps use */
    st = check_element_substep(&bd);
    if (st != DV_OK) {
        return st;
    }
    st = discretise_sub_step(&bd);
    if (st != DV_OK) {
        return st;
    }
    subnode_from_state(&bd);
    subnode_from_input(&bd);
    if (bd.cubic) {
        st = subnode_from_cubic(&bd);
        if (st != DV_OK) {
            return st;
        }
    }
    subnode_from_forces(&bd);
    for (size_t i = 0; i < bd.nf * bd.ns; i++) {
        if (!dv_priv_finite(m->rx[i]) || !dv_priv_finite(m->vmat[i])) {
            return DV_EUNSTABLE;
        }
    }
    return DV_OK;
}

/* Fixed-step observer: one folded column-major product per sample, contact forces resolved
 * at the sub-nodes with a fixed number of fixed-point iterations, DARE by doubling at init. */
#include "dynval/dv_obs.h"
#include "dv_elem_law.h"
#include "dv_priv.h"
#include "dv_obskern.h"

/* 0: persistent, 1: scratch, 2: both (one buffer) */
static size_t obs_len(const dv_model_t *m, int which)
{
    if (m == NULL || m->kmat == NULL) {
        return 0u;
    }
    const size_t n = m->n_dof;
    const size_t nc = m->n_elem;
    const size_t nsub = m->n_sub;
    const size_t no = m->n_out;
    const size_t nin = m->n_in == 4u ? 4u : 2u;
    const size_t per = DV_OBS_PERSIST_LEN_HOLD(n, nc, nsub, no, nin);
    const size_t scr = DV_OBS_SCRATCH_LEN_HOLD(n, nc, nsub, no, nin);
    return which == 0 ? per : (which == 1 ? scr : per + scr);
}

size_t dv_obs_buf_len(const dv_model_t *m)
{
    return obs_len(m, 2);
}

size_t dv_obs_persistent_len(const dv_model_t *m)
{
    return obs_len(m, 0);
}

size_t dv_obs_scratch_len(const dv_model_t *m)
{
    return obs_len(m, 1);
}

#if DV_SIMD_X86
static bool make_modal(dv_obs_t *o, dv_real_t *x);
#endif

/* dv_obs_step()'s dispatch from simd, modal and started (kept in one byte: the per-sample step
 * reads one flag). Called wherever one of them changes. */
static void set_ready(dv_obs_t *o)
{
    o->modal_ready = (o->simd == 2u && o->modal && o->started) ? (o->nf != 0u ? 2u : 1u) : 0u;
}

/* Fill the folded step matrix from the model and the gain (o->gain, used when has_gain).
 * Layout: the state rows first, column-major (ns rows, one column per entry of sv:
 * [x, u window, g, y]), then the output rows, column-major (no rows, columns
 * [x, u window, g] only: the prediction never depends on y). The u window is [u[k-1], u[k]]
 * (first-order hold) or [u[k-2], u[k-1], u[k], u[k+1]] (cubic) for the step to t_k. Keeping the two row sets
 * apart lets the step skip the zero y columns of the output rows and gives short columns
 * that fit vector registers. */
static void fold(dv_obs_t *o)
{
    const dv_model_t *m = o->m;
    const size_t ns = o->ns;
    const size_t no = o->no;
    const size_t nf = o->nf;
    const size_t nc = m->n_elem;
    const size_t nco = o->ncol_open;
    const size_t nin = o->nin;
    const bool cubic = nin == 4u;
    dv_real_t col[2u * DV_MAX_DOF + DV_MAX_OUT];
    dv_real_t *fxg = o->f;
    dv_real_t *fyg = o->f + ns * (size_t)o->ncol_gain;
    /* open loop: column j of [x+; yhat] for input column j of [x, u[k-1], u[k], g] */
    for (size_t j = 0; j < nco; j++) {
        for (size_t r = 0; r < ns; r++) {
            dv_real_t v;
            if (j < ns) {
                v = m->ad[r * ns + j];
            } else if (cubic && j < ns + nin) {
                v = m->pu[r * 4u + (j - ns)];
            } else if (j == ns) {
                v = m->pa[r];
            } else if (j == ns + 1u) {
                v = m->pb[r];
            } else {
                v = m->vmat[r * nf + (j - ns - nin)];
            }
            col[r] = v;
        }
        for (size_t q = 0; q < no; q++) {
            dv_real_t s = DV_R(0.0);
            for (size_t r = 0; r < ns; r++) {
                s += m->cy[q * ns + r] * col[r];
            }
            if (cubic && j >= ns && j < ns + nin) {
                s += m->du[q * 4u + (j - ns)];
            } else if (j == ns) {
                s += m->d1[q];
            } else if (j == ns + 1u) {
                s += m->d0[q];
            } else if (j >= ns + nin) {
                const size_t f = j - ns - nin;
                if (f >= nf - nc) { /* forces at the end node act on the output directly */
                    s += m->ey[q * nc + (f - (nf - nc))];
                }
            }
            col[ns + q] = s;
        }
        for (size_t q = 0; q < no; q++) {
            fyg[j * no + q] = col[ns + q];
        }
        /* x+ = x- + L (y - yhat): rows of x- minus L times rows of yhat */
        for (size_t r = 0; r < ns; r++) {
            dv_real_t s = col[r];
            if (o->has_gain) {
                for (size_t q = 0; q < no; q++) {
                    s -= o->gain[r * no + q] * col[ns + q];
                }
            }
            fxg[j * ns + r] = s;
        }
    }
    /* y columns of the gain rows carry L (zeros in open loop) */
    for (size_t q0 = 0; q0 < no; q0++) {
        for (size_t r = 0; r < ns; r++) {
            fxg[(nco + q0) * ns + r] = o->gain[r * no + q0];
        }
    }
    o->modal = false;
    o->rxq = NULL;
#if DV_SIMD_X86
    /* storage for the modal form: it may apply (see make_modal()); with a contact, only to
     * the gap law (the step that skips an open element) */
    if (o->tq != NULL && (nc == 0u || m->elem[0].law == DV_ELEM_CONTACT)) {
        o->modal = make_modal(o, o->sv);
    }
#endif
    set_ready(o);
}

/* ---- modal coordinates (x86-64 double, AVX-512: the 4-DOF step, linear or one gap element) --
 * The state block F of the folded state rows (x+ = F x + ...) of the 8-state observer is
 * brought to real block-diagonal form, F = T Lam T^-1 with 2 x 2 blocks (a complex pair of
 * eigenvalues or two real ones), and the observer runs on q = T^-1 x: the state rows become
 * [Lam | T^-1 (input and y columns)], the output rows' state columns C T. Every kernel works
 * unchanged on these dense rows; the AVX-512 step also uses the blocks directly (two fused
 * multiply-adds for the state instead of eight), which halves the step. With a gap element the
 * contact's sub-node X rows are rewritten over q too (o->rxq), and a step that finds the element
 * open at every node is the linear modal step (its force columns skipped, as in all_open());
 * a step that engages it runs the node chain and the dense product on the same q-coordinate
 * rows. x = T q is formed only
 * when asked for (dv_obs_get_state()). The eigenvalues come from dv_mat_eig_real(), each pair's
 * vectors from inverse iteration; F keeps the dense form when T is ill-conditioned (a repeated
 * or defective eigenvalue) or the blocks do not reproduce F to 1e-9 relative. */

/* x (ns) of the current state, whichever coordinates it is kept in. */
static void state_x(const dv_obs_t *o, dv_real_t *x)
{
    const size_t ns = o->ns;
    if (o->modal) {
        for (size_t i = 0; i < ns; i++) {
            dv_real_t s = DV_R(0.0);
            for (size_t j = 0; j < ns; j++) {
                s += o->tq[i * ns + j] * o->sv[j];
            }
            x[i] = s;
        }
    } else {
        for (size_t i = 0; i < ns; i++) {
            x[i] = o->sv[i];
        }
    }
}

#if DV_SIMD_X86
/* Inverse iteration: the real invariant subspace of the eigenvalue (re, im) of f (8 x 8
 * row-major) into columns c, c + 1 of t (8 x 8 row-major); im == 0: the real eigenvector into
 * column c only. The shift is moved by 1e-9 so the solve is not singular. */
static bool inv_iter(const double *f, double re, double im, double *t, size_t c)
{
    const size_t n = 8u;
    const size_t m = im != 0.0 ? 2u * n : n;
    double a[256];
    double z[16];
    for (size_t i = 0; i < m; i++) {
        z[i] = 1.0 + 0.1 * (double)i; /* not orthogonal to any eigenvector in practice */
    }
    const double sh = re + 1e-9 * (fabs(re) + fabs(im) + 1e-3);
    for (int it = 0; it < 3; it++) {
        for (size_t i = 0; i < m; i++) {
            for (size_t j = 0; j < m; j++) {
                const size_t bi = i / n, bj = j / n, ii = i % n, jj = j % n;
                double v = bi == bj ? f[ii * n + jj] - (ii == jj ? sh : 0.0) : 0.0;
                if (bi != bj && ii == jj) {
                    v = bi == 0u ? im : -im; /* [[F - re, im], [-im, F - re]] */
                }
                a[i * m + j] = v;
            }
        }
        dv_mat_t am = {(uint16_t)m, (uint16_t)m, a};
        dv_mat_t zm = {(uint16_t)m, 1u, z};
        if (dv_mat_solve(&am, &zm) != DV_OK) {
            return false;
        }
        double nrm = 0.0;
        for (size_t i = 0; i < m; i++) {
            nrm += z[i] * z[i];
        }
        nrm = sqrt(nrm);
        if (!(nrm > 0.0) || !dv_priv_finite(nrm)) {
            return false;
        }
        for (size_t i = 0; i < m; i++) {
            z[i] /= nrm;
        }
    }
    for (size_t i = 0; i < n; i++) {
        t[i * n + c] = z[i];
        if (im != 0.0) {
            t[i * n + c + 1u] = z[n + i];
        }
    }
    return true;
}

/* F (the folded state rows' state block, column-major in o->f) to modal form: fills o->tq and
 * o->fm (and after it the contact's X rows over q, o->rxq), rewrites o->f in q coordinates; x:
 * the current state in x coordinates, rewritten
 * as q. Returns false, with nothing changed, when F keeps the dense form. */
static bool make_modal(dv_obs_t *o, dv_real_t *x)
{
    const size_t n = 8u;
    const size_t no = 4u;
    const size_t ncg = o->ncol_gain;
    double *f = o->f;
    double *fy = o->f + n * ncg;
    double fr[64], t[64], ti[64], lam[64], wr[8], wi[8], work[DV_MAT_EIGR_WORK_LEN(8)];
    double fmax = 0.0;
    for (size_t r = 0; r < n; r++) {
        for (size_t j = 0; j < n; j++) {
            fr[r * n + j] = f[j * n + r];
            fmax = fmax > fabs(fr[r * n + j]) ? fmax : fabs(fr[r * n + j]);
        }
    }
    dv_mat_t fm = {8u, 8u, fr};
    if (dv_mat_eig_real(&fm, wr, wi, work, sizeof work / sizeof *work) != DV_OK) {
        return false;
    }
    /* blocks: complex pairs as they come (positive imaginary part first), real ones paired */
    size_t col = 0u;
    size_t pend = 8u; /* a real eigenvalue waiting for its partner */
    for (size_t i = 0; i < n; i++) {
        if (wi[i] > 0.0) {
            if (!inv_iter(fr, wr[i], wi[i], t, col)) {
                return false;
            }
            col += 2u;
            i++; /* its conjugate */
        } else if (wi[i] == 0.0) {
            if (!inv_iter(fr, wr[i], 0.0, t, pend == 8u ? col : col + 1u)) {
                return false;
            }
            if (pend == 8u) {
                pend = i;
            } else {
                pend = 8u;
                col += 2u;
            }
        } else {
            return false; /* a conjugate without its pair: not from dv_mat_eig_real() */
        }
    }
    if (col != n || pend != 8u) {
        return false;
    }
    /* T^-1, its condition number and the blocks Lam = T^-1 F T */
    double tc[64];
    for (size_t i = 0; i < 64u; i++) {
        tc[i] = t[i];
        ti[i] = (i / n) == (i % n) ? 1.0 : 0.0;
    }
    dv_mat_t tm = {8u, 8u, tc};
    dv_mat_t im = {8u, 8u, ti};
    if (dv_mat_solve(&tm, &im) != DV_OK) {
        return false;
    }
    double n1 = 0.0, n2 = 0.0;
    for (size_t j = 0; j < n; j++) {
        double s1 = 0.0, s2 = 0.0;
        for (size_t i = 0; i < n; i++) {
            s1 += fabs(t[i * n + j]);
            s2 += fabs(ti[i * n + j]);
        }
        n1 = n1 > s1 ? n1 : s1;
        n2 = n2 > s2 ? n2 : s2;
    }
    if (!(n1 * n2 < 1e6)) {
        return false;
    }
    double ft[64];
    dv_mat_t tv = {8u, 8u, t}, ftm = {8u, 8u, ft}, lm = {8u, 8u, lam};
    if (dv_mat_mul(&fm, &tv, &ftm) != DV_OK || dv_mat_mul(&im, &ftm, &lm) != DV_OK) {
        return false;
    }
    for (size_t i = 0; i < n; i++) {
        for (size_t j = 0; j < n; j++) {
            if (i / 2u != j / 2u && !(fabs(lam[i * n + j]) <= 1e-9 * fmax)) {
                return false;
            }
        }
    }
    /* rewrite the folded rows: state rows' state columns Lam, their other columns T^-1 col,
     * output rows' state columns (C T); then the step kernel's copy */
    for (size_t j = 0; j < n; j++) {
        for (size_t r = 0; r < n; r++) {
            f[j * n + r] = r / 2u == j / 2u ? lam[r * n + j] : 0.0;
        }
    }
    for (size_t j = n; j < ncg; j++) {
        double tc8[8];
        for (size_t r = 0; r < n; r++) {
            double s = 0.0;
            for (size_t k = 0; k < n; k++) {
                s += ti[r * n + k] * f[j * n + k];
            }
            tc8[r] = s;
        }
        for (size_t r = 0; r < n; r++) {
            f[j * n + r] = tc8[r];
        }
    }
    double ct[32];
    for (size_t q = 0; q < no; q++) {
        for (size_t j = 0; j < n; j++) {
            double s = 0.0;
            for (size_t k = 0; k < n; k++) {
                s += fy[k * no + q] * t[k * n + j];
            }
            ct[q * n + j] = s;
        }
    }
    for (size_t q = 0; q < no; q++) {
        for (size_t j = 0; j < n; j++) {
            fy[j * no + q] = ct[q * n + j];
        }
    }
    /* the prediction without lane sums: lane l of product k pairs output l % 4 with state
     * l ^ k (k < 4 keeps it in l's half), so the four products of q with its in-half
     * permutations sum, per half, to the prediction's first and last four columns */
    for (size_t k = 0; k < 4u; k++) {
        for (size_t l = 0; l < n; l++) {
            o->fm[16u + k * n + l] = ct[(l & 3u) * n + (l ^ k)];
        }
    }
    for (size_t b = 0; b < n; b += 2u) {
        o->fm[b] = lam[b * n + b];                         /* Lam diagonal */
        o->fm[b + 1u] = lam[(b + 1u) * n + b + 1u];
        o->fm[8u + b] = lam[b * n + b + 1u];               /* Lam off-diagonal of the block */
        o->fm[8u + b + 1u] = lam[(b + 1u) * n + b];
    }
    for (size_t i = 0; i < 64u; i++) {
        o->tq[i] = t[i];
    }
    /* a contact's sub-node X rows: state columns rx T, the input window's two as they are; in
     * blocks of 8 nodes (zero rows past nf: X = 0, open at any gap >= 0), each block 10
     * columns of 8, the layout of the AVX-512 open check */
    const size_t nf = o->nf;
    if (nf > 0u) {
        const double *rx = o->m->rx;
        double *rq = o->fm + 48;
        for (size_t b = 0; b < nf; b += 8u) {
            for (size_t j = 0; j < n + 2u; j++) {
                for (size_t l = 0; l < 8u; l++) {
                    const size_t r = b + l;
                    double s = 0.0;
                    if (r < nf && j < n) {
                        for (size_t k = 0; k < n; k++) {
                            s += rx[k * nf + r] * t[k * n + j];
                        }
                    } else if (r < nf) {
                        s = j == n ? o->m->rxa[r] : o->m->rxb[r];
                    }
                    rq[b * (n + 2u) + j * 8u + l] = s;
                }
            }
        }
        o->rxq = rq;
    }
    double q[8];
    for (size_t i = 0; i < n; i++) {
        double s = 0.0;
        for (size_t k = 0; k < n; k++) {
            s += ti[i * n + k] * x[k];
        }
        q[i] = s;
    }
    for (size_t i = 0; i < n; i++) {
        x[i] = q[i];
    }
    return true;
}
#endif

/* Fold again (a new gain) keeping the state: back to x coordinates, fold, then to modal
 * coordinates again if they apply. */
static void refold(dv_obs_t *o)
{
    dv_real_t x[2u * DV_MAX_DOF];
    state_x(o, x);
    for (size_t i = 0; i < o->ns; i++) {
        o->sv[i] = x[i];
    }
    fold(o);
}

/* ---- DARE by the structure-preserving doubling algorithm (Chu, Fan, Lin 2005) ---------- */

static void mm(size_t n, const dv_real_t *a, bool ta, const dv_real_t *b, bool tb, dv_real_t *c)
{
    for (size_t i = 0; i < n; i++) {
        for (size_t j = 0; j < n; j++) {
            dv_real_t s = DV_R(0.0);
            for (size_t k = 0; k < n; k++) {
                const dv_real_t aik = ta ? a[k * n + i] : a[i * n + k];
                const dv_real_t bkj = tb ? b[j * n + k] : b[k * n + j];
                s += aik * bkj;
            }
            c[i * n + j] = s;
        }
    }
}

/* X = A^T X (I + G X)^-1 A + H; returns X in h. A, G, H are n x n, overwritten. */
static dv_status_t sda(size_t n, dv_real_t *a, dv_real_t *g, dv_real_t *h, dv_real_t *w)
{
    dv_real_t *wm = w;               /* I + G H */
    dv_real_t *y = wm + n * n;       /* n x 2n: [W^-1 A, W^-1 G] */
    dv_real_t *t1 = y + 2u * n * n;
    dv_real_t *t2 = t1 + n * n;
    dv_real_t *t3 = t2 + n * n;
    dv_real_t *y1 = t3 + n * n;
    dv_real_t *y2 = y1 + n * n;
    const dv_real_t tol = DV_R(64.0) * DV_REAL_EPS;
    for (uint32_t it = 0; it < DV_OBS_DARE_MAX_ITER; it++) {
        mm(n, g, false, h, false, wm);
        for (size_t i = 0; i < n; i++) {
            wm[i * n + i] += DV_R(1.0);
            for (size_t j = 0; j < n; j++) {
                y[i * 2u * n + j] = a[i * n + j];
                y[i * 2u * n + n + j] = g[i * n + j];
            }
        }
        dv_mat_t wmat = {(uint16_t)n, (uint16_t)n, wm};
        dv_mat_t ymat = {(uint16_t)n, (uint16_t)(2u * n), y};
        if (dv_mat_solve(&wmat, &ymat) != DV_OK) {
            return DV_EUNSTABLE;
        }
        for (size_t i = 0; i < n; i++) {
            for (size_t j = 0; j < n; j++) {
                y1[i * n + j] = y[i * 2u * n + j];
                y2[i * n + j] = y[i * 2u * n + n + j];
            }
        }
        /* H += A^T H Y1 */
        mm(n, a, true, h, false, t1);
        mm(n, t1, false, y1, false, t2);
        dv_real_t dn = DV_R(0.0);
        dv_real_t hn = DV_R(0.0);
        for (size_t i = 0; i < n * n; i++) {
            dn += DV_FABS(t2[i]);
        }
        /* G += A Y2 A^T */
        mm(n, a, false, y2, false, t1);
        mm(n, t1, false, a, true, t3);
        /* A = A Y1 */
        mm(n, a, false, y1, false, t1);
        for (size_t i = 0; i < n; i++) {
            for (size_t j = 0; j < n; j++) {
                const size_t ij = i * n + j;
                h[ij] += t2[ij];
                g[ij] += t3[ij];
                a[ij] = t1[ij];
            }
        }
        for (size_t i = 0; i < n; i++) {
            for (size_t j = i + 1u; j < n; j++) {
                const dv_real_t hs = DV_R(0.5) * (h[i * n + j] + h[j * n + i]);
                const dv_real_t gs = DV_R(0.5) * (g[i * n + j] + g[j * n + i]);
                h[i * n + j] = h[j * n + i] = hs;
                g[i * n + j] = g[j * n + i] = gs;
            }
        }
        for (size_t i = 0; i < n * n; i++) {
            if (!dv_priv_finite(h[i])) {
                return DV_EUNSTABLE;
            }
            hn += DV_FABS(h[i]);
        }
        if (dn <= tol * hn) {
            return DV_OK;
        }
    }
    return DV_EUNSTABLE;
}

/* Steady-state Kalman gain L = P Cy^T (Cy P Cy^T + R)^-1 of the filter DARE. */
static dv_status_t kalman_gain(dv_obs_t *o, const dv_obs_noise_t *nz, dv_real_t *w)
{
    const dv_model_t *m = o->m;
    const size_t n = m->n_dof;
    const size_t ns = o->ns;
    const size_t no = o->no;
    /* process noise: Gw = int_0^T exp(A s) ds [0; M^-1] from exp([[A T, Bw T], [0, 0]]) */
    const size_t na = ns + n;
    dv_real_t *e = w;
    dv_real_t *r = e + na * na;
    dv_real_t *ew = r + na * na;
    for (size_t i = 0; i < na * na; i++) {
        e[i] = DV_R(0.0);
    }
    for (size_t i = 0; i < ns; i++) {
        for (size_t j = 0; j < ns; j++) {
            e[i * na + j] = m->ac[i * ns + j] * m->dt_s;
        }
    }
    for (size_t i = 0; i < n; i++) {
        e[(n + i) * na + ns + i] = m->dt_s / m->mass_kg[i];
    }
    dv_mat_t em = {(uint16_t)na, (uint16_t)na, e};
    dv_mat_t rm = {(uint16_t)na, (uint16_t)na, r};
    if (dv_mat_expm(&em, &rm, ew, DV_MAT_EXPM_WORK_LEN(na)) != DV_OK) {
        return DV_EUNSTABLE;
    }
    /* the DARE blocks live after the exponential's storage is no longer needed */
    dv_real_t *a = w + 0u;
    dv_real_t *g = a + ns * ns;
    dv_real_t *h = g + ns * ns;
    dv_real_t *sw = h + ns * ns;
    /* H = Q = Gw diag(q) Gw^T, computed from r before a/g/h overwrite it: use a temp copy */
    dv_real_t *gw = sw + 7u * ns * ns; /* ns x n */
    for (size_t i = 0; i < ns; i++) {
        for (size_t j = 0; j < n; j++) {
            gw[i * n + j] = r[i * na + ns + j];
        }
    }
    for (size_t i = 0; i < ns; i++) {
        for (size_t j = 0; j < ns; j++) {
            dv_real_t s = DV_R(0.0);
            for (size_t q = 0; q < n; q++) {
                s += gw[i * n + q] * nz->q_force_n2[q] * gw[j * n + q];
            }
            h[i * ns + j] = s;
        }
    }
    for (size_t i = 0; i < ns; i++) {
        for (size_t j = 0; j < ns; j++) {
            a[i * ns + j] = m->ad[j * ns + i]; /* A = Ad^T */
            dv_real_t s = DV_R(0.0);
            for (size_t q = 0; q < no; q++) {
                s += m->cy[q * ns + i] * m->cy[q * ns + j] / nz->r_meas[q];
            }
            g[i * ns + j] = s; /* G = Cy^T R^-1 Cy */
        }
    }
    dv_status_t st = sda(ns, a, g, h, sw);
    if (st != DV_OK) {
        return st;
    }
    /* S = Cy P Cy^T + R (no x no); solve S X = Cy P (no x ns); L = X^T */
    dv_real_t *cp = sw;            /* no x ns */
    dv_real_t *smat = cp + no * ns; /* no x no */
    for (size_t q = 0; q < no; q++) {
        for (size_t j = 0; j < ns; j++) {
            dv_real_t s = DV_R(0.0);
            for (size_t i = 0; i < ns; i++) {
                s += m->cy[q * ns + i] * h[i * ns + j];
            }
            cp[q * ns + j] = s;
        }
    }
    for (size_t q = 0; q < no; q++) {
        for (size_t p = 0; p < no; p++) {
            dv_real_t s = DV_R(0.0);
            for (size_t j = 0; j < ns; j++) {
                s += cp[q * ns + j] * m->cy[p * ns + j];
            }
            smat[q * no + p] = s + (q == p ? nz->r_meas[q] : DV_R(0.0));
        }
    }
    dv_mat_t sm = {(uint16_t)no, (uint16_t)no, smat};
    dv_mat_t xm = {(uint16_t)no, (uint16_t)ns, cp};
    if (dv_mat_solve(&sm, &xm) != DV_OK) {
        return DV_EUNSTABLE;
    }
    for (size_t i = 0; i < ns; i++) {
        for (size_t q = 0; q < no; q++) {
            o->gain[i * no + q] = cp[q * ns + i];
        }
    }
    return DV_OK;
}

/* q >= 0 and r > 0, all finite (NULL: open loop, fine) */
static bool noise_ok(const dv_model_t *m, const dv_obs_noise_t *noise)
{
    if (noise == NULL) {
        return true;
    }
    for (size_t i = 0; i < m->n_dof; i++) {
        if (!dv_priv_finite(noise->q_force_n2[i]) || noise->q_force_n2[i] < DV_R(0.0)) {
            return false;
        }
    }
    for (size_t q = 0; q < m->n_out; q++) {
        if (!dv_priv_finite(noise->r_meas[q]) || !(noise->r_meas[q] > DV_R(0.0))) {
            return false;
        }
    }
    return true;
}

/* p moved up to the next 64-byte boundary when al (at most 7 elements: the buffer holds doubles
 * at least), else p. */
static dv_real_t *align64(dv_real_t *p, bool al)
{
    const uintptr_t mis = (uintptr_t)p % 64u;
    return (al && mis != 0u) ? p + (64u - mis) / sizeof(dv_real_t) : p;
}

dv_status_t dv_obs_init(dv_obs_t *o, const dv_model_t *m, const dv_obs_noise_t *noise,
                        dv_real_t *buf, size_t len)
{
    if (o == NULL || m == NULL || buf == NULL || m->kmat == NULL) {
        return DV_EINVAL;
    }
    if (!noise_ok(m, noise)) {
        return DV_EINVAL;
    }
    const size_t per = dv_obs_persistent_len(m);
    if (len < dv_obs_buf_len(m)) {
        return DV_ESIZE;
    }
    return dv_obs_init_ex(o, m, noise, buf, per, buf + per, len - per);
}

dv_status_t dv_obs_init_ex(dv_obs_t *o, const dv_model_t *m, const dv_obs_noise_t *noise,
                           dv_real_t *buf, size_t len, dv_real_t *scratch,
                           size_t scratch_len)
{
    if (o == NULL || m == NULL || buf == NULL || m->kmat == NULL ||
        (noise != NULL && scratch == NULL)) {
        return DV_EINVAL;
    }
    const size_t ns = m->n_state;
    const size_t no = m->n_out;
    const size_t nf = m->n_f;
    if (!noise_ok(m, noise)) {
        return DV_EINVAL;
    }
    if (len < dv_obs_persistent_len(m) ||
        (noise != NULL && scratch_len < dv_obs_scratch_len(m))) {
        return DV_ESIZE;
    }
    const dv_obs_t zero = {0};
    *o = zero;
    o->m = m;
    o->ns = (uint16_t)ns;
    o->no = (uint16_t)no;
    o->nf = (uint16_t)nf;
    const size_t nin = m->n_in == 4u ? 4u : 2u;
    o->nrows = (uint16_t)(ns + no);
    o->nin = (uint16_t)nin;
    o->ncol_open = (uint16_t)(ns + nin + nf);
    o->ncol_gain = (uint16_t)(ns + nin + nf + no);
    o->fast = ns == 8u && no == 4u && nin == 2u;
    o->simd = (uint8_t)dv_priv_simd_kern();
    if (o->simd == 2u && DV_OBS_MODAL_LEN(m->n_dof, m->n_elem, m->n_sub, no, nin) == 0u) {
        o->simd = 1u; /* AVX-512 serves the 8 x 4 step in modal form; AVX2 kernel otherwise */
    }
    /* the modal step's vectors on 64-byte lines (its storage has the slack): a 64-byte load or
     * store across two lines costs two, and the step makes about twenty */
    const bool al = o->simd == 2u;
    dv_real_t *p = align64(buf, al);
    o->sv = p;
    p += o->ncol_gain;
    p = align64(p, al);
    o->z = p;
    p += o->nrows;
    o->resid = p;
    p += no;
    p = align64(p, al);
    o->f = p;
    p += ns * (size_t)o->ncol_gain + no * (size_t)o->ncol_open;
    o->gain = p;
    p += ns * no;
    if (nin == 4u) {
        o->ypend = p;
        p += no;
    }
    if (o->simd == 2u) {
        p = align64(p, true);
        o->tq = p;
        p += ns * ns;
        o->fm = p;
        p += 6u * ns + (ns + 2u) * ((nf + 7u) / 8u * 8u); /* then the modal X rows */
    }
    DV_ASSERT((size_t)(p - buf) <= len);
    for (size_t i = 0; i < ns * no; i++) {
        o->gain[i] = DV_R(0.0);
    }
    if (noise != NULL) {
        const dv_status_t st = kalman_gain(o, noise, scratch);
        if (st != DV_OK) {
            return st;
        }
        o->has_gain = true;
    }
    fold(o);
    dv_obs_reset(o);
    return DV_OK;
}

dv_status_t dv_obs_set_gain(dv_obs_t *o, const dv_real_t *gain, size_t len)
{
    if (o == NULL || o->m == NULL || o->m->ad == NULL) { /* dv_model_keep_step_only() */
        return DV_EINVAL;
    }
    const size_t nl = (size_t)o->ns * o->no;
    if (gain == NULL) {
        o->has_gain = false;
        for (size_t i = 0; i < nl; i++) {
            o->gain[i] = DV_R(0.0);
        }
        refold(o);
        return DV_OK;
    }
    if (len < nl) {
        return DV_ESIZE;
    }
    for (size_t i = 0; i < nl; i++) {
        if (!dv_priv_finite(gain[i])) {
            return DV_EINVAL;
        }
    }
    for (size_t i = 0; i < nl; i++) {
        o->gain[i] = gain[i];
    }
    o->has_gain = true;
    refold(o);
    return DV_OK;
}

dv_status_t dv_obs_get_gain(const dv_obs_t *o, dv_real_t *gain, size_t len)
{
    if (o == NULL || gain == NULL || o->m == NULL) {
        return DV_EINVAL;
    }
    const size_t nl = (size_t)o->ns * o->no;
    if (len < nl) {
        return DV_ESIZE;
    }
    for (size_t i = 0; i < nl; i++) {
        gain[i] = o->gain[i];
    }
    return DV_OK;
}

void dv_obs_reset(dv_obs_t *o)
{
    DV_ASSERT(o != NULL);
    for (size_t i = 0; i < o->ncol_gain; i++) {
        o->sv[i] = DV_R(0.0);
    }
    for (size_t i = 0; i < o->nrows; i++) {
        o->z[i] = DV_R(0.0);
    }
    for (size_t i = 0; i < o->no; i++) {
        o->resid[i] = DV_R(0.0);
        if (o->ypend != NULL) {
            o->ypend[i] = DV_R(0.0);
        }
    }
    o->n_pred = 0u;
    o->pend_flags = DV_OBS_FLAG_NO_MEAS;
    o->started = false;
    set_ready(o);
    o->flags = 0u;
    o->n_steps = 0u;
    o->contact_hot = false;
    o->n_bad_input = 0u;
    o->n_bad_meas = 0u;
    for (size_t e = 0; e < DV_MAX_ELEM; e++) {
        o->elem_x[e] = DV_R(0.0);
        o->elem_g[e] = DV_R(0.0);
    }
}

/* The force-free X at every sub-node (what X would be with no contact force at this or any
 * earlier node of the step), xl[f] = rx[f, :] x + the input window's share: column by column,
 * in each node the same order of operations as a row dot. The rows: the model's (column-major,
 * over x: node f of column j at rx[j nf + f]) or with the modal form o->rxq (over q, the
 * window's columns included, in blocks of 8 nodes: node f of column j at
 * rxq[(f / 8) 8 (ns + 2) + 8 j + f % 8]). */
static void nodes_x_free(const dv_obs_t *o, size_t ns, bool cubic, const dv_real_t *sv,
                         dv_real_t *xl)
{
    const dv_model_t *m = o->m;
    const size_t nf = m->n_f;
    const dv_real_t *win = sv + ns;
    const dv_real_t *rx = m->rx; /* the model's: read here, it may move */
#if DV_SIMD_X86
    const bool modal = o->rxq != NULL;
    if (modal) {
        rx = o->rxq;
    }
    if (!cubic && o->simd != 0u) {
        dv_priv_obs_xfree_avx2(rx, nf, ns, modal ? 8u * (ns + 2u) : 8u, modal ? 8u : nf, sv, xl);
        return;
    }
    if (modal) { /* the portable kernel on the modal rows (a test's comparison) */
        for (size_t f = 0; f < nf; f++) {
            const dv_real_t *r = rx + f / 8u * 8u * (ns + 2u) + f % 8u;
            dv_real_t a = r[ns * 8u] * win[0] + r[(ns + 1u) * 8u] * win[1];
            for (size_t j = 0; j < ns; j++) {
                a += r[j * 8u] * sv[j];
            }
            xl[f] = a;
        }
        return;
    }
#endif
    for (size_t f = 0; f < nf; f++) {
        if (cubic) {
            const dv_real_t *ru = m->rxu + f * 4u;
            xl[f] = ru[0] * win[0] + ru[1] * win[1] + ru[2] * win[2] + ru[3] * win[3];
        } else {
            xl[f] = m->rxa[f] * win[0] + m->rxb[f] * win[1];
        }
    }
    for (size_t j = 0; j < ns; j++) {
        const dv_real_t *col = rx + j * nf;
        const dv_real_t v = sv[j];
        for (size_t f = 0; f < nf; f++) {
            xl[f] += col[f] * v;
        }
    }
}

/* forced inline where speed is measured (x86 double); firmware builds keep the flash */
#if DV_SIMD_X86
#define DV_OBS_INLINE __attribute__((always_inline))
#else
#define DV_OBS_INLINE
#endif

/* Every element (nc of them; a constant 1 on the one-element path) a plain contact and open at
 * all its sub-nodes at the force-free X (xl, node f = i nc + e): then zero forces solve every
 * node (each law gives 0 at the force-free X, and each node's fixed-point start, from the
 * earlier nodes' zeros, is 0), and the node chain would only add zeros to reach them. Sets the
 * forces as the chain would, bit for bit (the gap law keeps no element history: elem_x, elem_g
 * are the stick-slip law's), and returns true; false (nothing written) otherwise. */
static inline DV_OBS_INLINE bool all_open(const dv_obs_t *o, dv_real_t *g, const dv_real_t *xl,
                                                size_t nc)
{
    const dv_model_t *m = o->m;
    const size_t nsub = m->n_sub;
    for (size_t e = 0; e < nc; e++) {
        const dv_elem_desc_t *c = &m->elem[e];
        dv_real_t lo = DV_REAL_MAX, hi = -DV_REAL_MAX;
        for (size_t i = 0; i <= nsub; i++) {
            const dv_real_t x = xl[i * nc + e];
            lo = x < lo ? x : lo;
            hi = x > hi ? x : hi;
        }
        if (c->law != DV_ELEM_CONTACT || !dv_priv_gap_open((int)c->side, c->gap_m, lo, hi)) {
            return false;
        }
    }
    for (size_t f = 0; f < m->n_f; f++) {
        g[f] = DV_R(0.0);
    }
    return true;
}

/* contact_forces() for one element (the common case), in the same order of operations: the
 * force-free part of X at every sub-node first (independent of the forces, so it leaves the
 * sequential chain through the nodes), then node by node the earlier forces and the implicit
 * force. */
static bool contact_forces_1(dv_obs_t *o, dv_real_t *sv, size_t ns)
{
    const dv_model_t *m = o->m;
    const size_t nf = m->n_f;
    const bool cubic = m->n_in == 4u;
    dv_real_t *g = sv + ns + (cubic ? 4u : 2u);
    const dv_elem_desc_t *c = &m->elem[0];
    dv_real_t xl[DV_MAX_SUB + 1u];
    nodes_x_free(o, ns, cubic, sv, xl);
    if (all_open(o, g, xl, 1u)) {
        return true;
    }
    const dv_real_t kh = dv_priv_elem_kh(c);
    dv_real_t xp = o->elem_x[0];
    dv_real_t gp = o->elem_g[0];
    /* the chain from one node's force to the next is the latency of the whole step: the last
     * two forces stay in registers (gp, g2), and X at the node is one multiply-add from the
     * previous force, X = lin + s gp: the first node X = xl (s = 0); the second lin = xl +
     * S_f,0 g_0, s = S_ff, with DV_MODEL_FP_ITERS fixed-point iterations from g_0; later nodes
     * one iteration from the line through the previous two forces, 2 gp - g2, folded into lin
     * and s (see dv_model.h) */
    dv_real_t g2 = DV_R(0.0);
    for (size_t f = 0; f < nf; f++) {
        const dv_real_t *srow = m->smat + f * nf;
        dv_real_t lin = xl[f];
        dv_real_t sl = DV_R(0.0);
        if (f == 1u) {
            lin += srow[0] * gp;
            sl = srow[1];
        } else if (f >= 2u) {
            for (size_t j = 0; j + 2u < f; j++) {
                lin += srow[j] * g[j];
            }
            lin += (srow[f - 2u] - srow[f]) * g2;
            sl = srow[f - 1u] + DV_R(2.0) * srow[f];
        }
        const uint32_t iters = f == 1u ? DV_MODEL_FP_ITERS : 1u;
        dv_real_t cur = gp;
        dv_real_t xr = lin;
        for (uint32_t it = 0; it < iters; it++) {
            xr = lin + sl * cur;
            cur = dv_priv_elem_force(c, kh, xp, gp, xr);
        }
        g[f] = cur;
        g2 = gp;
        xp = xr;
        gp = cur;
    }
    o->elem_x[0] = xp;
    o->elem_g[0] = gp;
    return false;
}

/* Sub-node contact forces g into sv[ns + nin ..], from x = sv[0..ns) and the input window
 * sv[ns .. ns + nin). Stick-slip elements read and advance the observer's element history.
 * True when every force is zero because every element stays open (all_open()). */
static bool contact_forces(dv_obs_t *o, dv_real_t *sv, size_t ns)
{
    const dv_model_t *m = o->m;
    const size_t nc = m->n_elem;
    if (nc == 1u) {
        return contact_forces_1(o, sv, ns);
    }
    const size_t nf = m->n_f;
    const size_t nsub = m->n_sub;
    const bool cubic = m->n_in == 4u;
    dv_real_t *g = sv + ns + (cubic ? 4u : 2u);
    dv_real_t lin[DV_MAX_ELEM];
    dv_real_t cur[DV_MAX_ELEM];
    dv_real_t xp[DV_MAX_ELEM];
    dv_real_t gp[DV_MAX_ELEM];
    dv_real_t xn[DV_MAX_ELEM];
    dv_real_t kh[DV_MAX_ELEM];
    dv_real_t xl[(DV_MAX_SUB + 1u) * DV_MAX_ELEM];
    nodes_x_free(o, ns, cubic, sv, xl);
    if (all_open(o, g, xl, nc)) {
        return true;
    }
    for (size_t e = 0; e < nc; e++) {
        kh[e] = dv_priv_elem_kh(&m->elem[e]);
        xp[e] = o->elem_x[e];
        gp[e] = o->elem_g[e];
        xn[e] = xp[e];
    }
    for (size_t i = 0; i <= nsub; i++) {
        const size_t f0 = i * nc;
        for (size_t e = 0; e < nc; e++) {
            const size_t f = f0 + e;
            const dv_real_t *srow = m->smat + f * nf;
            dv_real_t s = xl[f];
            for (size_t j = 0; j < f0; j++) {
                s += srow[j] * g[j];
            }
            lin[e] = s;
            /* start: as in contact_forces_1() */
            cur[e] = i == 0u ? DV_R(0.0)
                             : (i == 1u ? g[f0 - nc + e]
                                        : DV_R(2.0) * g[f0 - nc + e] - g[f0 - 2u * nc + e]);
        }
        /* implicit in the node's own force: fixed-point iterations, a fixed number */
        const uint32_t iters = i == 1u ? DV_MODEL_FP_ITERS : 1u;
        for (uint32_t it = 0; it < iters; it++) {
            for (size_t e = 0; e < nc; e++) {
                const dv_real_t *srow = m->smat + (f0 + e) * nf + f0;
                dv_real_t xr = lin[e];
                for (size_t e2 = 0; e2 < nc; e2++) {
                    xr += srow[e2] * cur[e2];
                }
                xn[e] = xr;
                g[f0 + e] = dv_priv_elem_force(&m->elem[e], kh[e], xp[e], gp[e], xr);
            }
            for (size_t e = 0; e < nc; e++) {
                cur[e] = g[f0 + e];
            }
        }
        for (size_t e = 0; e < nc; e++) {
            xp[e] = xn[e];
            gp[e] = g[f0 + e];
        }
    }
    for (size_t e = 0; e < nc; e++) {
        o->elem_x[e] = xp[e];
        o->elem_g[e] = gp[e];
    }
    return false;
}

/* The step product. State rows: x+ = sum over every column j of sv of fx[:, j] sv[j]
 * (columns [x, u[k-1], u[k], g, y], the last ny = no or 0 of them); output rows:
 * yhat = sum over [x, u[k-1], u[k], g] of fy[:, j] sv[j]. The input columns are summed first
 * and the state columns last in two interleaved partial sums, so the chain from the previous
 * state to the next is short. static inline with the sizes as arguments: the call with
 * constant ns and no gets fixed trip counts over the rows, unrolled and vectorised. xo and yo
 * must not alias sv (restrict). */
static void kernel(size_t ns, size_t no, size_t nin, size_t ny,
                          const dv_real_t *restrict fx, const dv_real_t *restrict fy,
                          const dv_real_t *restrict sv, dv_real_t *restrict xo,
                          dv_real_t *restrict yo)
{
    dv_real_t a[2u * DV_MAX_DOF];
    dv_real_t b[2u * DV_MAX_DOF];
    dv_real_t c[2u * DV_MAX_DOF];
    dv_real_t ya[DV_MAX_OUT];
    dv_real_t yb[DV_MAX_OUT];
    const dv_real_t *restrict in = sv + ns;
    const dv_real_t *restrict fxi = fx + ns * ns;
    const dv_real_t *restrict fyi = fy + no * ns;
    /* inputs (u[k-1], u[k], contact forces, measurements): off the state chain */
    for (size_t r = 0; r < ns; r++) {
        a[r] = fxi[r] * in[0];
    }
    for (size_t q = 0; q < no; q++) {
        ya[q] = fyi[q] * in[0];
    }
    for (size_t j = 1; j < nin; j++) {
        const dv_real_t sj = in[j];
        for (size_t r = 0; r < ns; r++) {
            a[r] += fxi[j * ns + r] * sj;
        }
        for (size_t q = 0; q < no; q++) {
            ya[q] += fyi[j * no + q] * sj;
        }
    }
    for (size_t j = nin; j < nin + ny; j++) {
        const dv_real_t sj = in[j];
        for (size_t r = 0; r < ns; r++) {
            a[r] += fxi[j * ns + r] * sj;
        }
    }
    /* the state columns, even and odd apart (ns is even) */
    for (size_t r = 0; r < ns; r++) {
        b[r] = fx[r] * sv[0];
        c[r] = fx[ns + r] * sv[1];
    }
    for (size_t q = 0; q < no; q++) {
        ya[q] += fy[q] * sv[0];
        yb[q] = fy[no + q] * sv[1];
    }
    for (size_t j = 2; j < ns; j += 2u) {
        const dv_real_t s0 = sv[j];
        const dv_real_t s1 = sv[j + 1u];
        for (size_t r = 0; r < ns; r++) {
            b[r] += fx[j * ns + r] * s0;
            c[r] += fx[(j + 1u) * ns + r] * s1;
        }
        for (size_t q = 0; q < no; q++) {
            ya[q] += fy[j * no + q] * s0;
            yb[q] += fy[(j + 1u) * no + q] * s1;
        }
    }
    for (size_t r = 0; r < ns; r++) {
        xo[r] = a[r] + (b[r] + c[r]);
    }
    for (size_t q = 0; q < no; q++) {
        yo[q] = ya[q] + yb[q];
    }
}

/* gcc's loop vectoriser turns the column loops below into two-columns-at-a-time code full of
 * shuffles (several times slower); its basic-block vectoriser alone gives the clean form (one
 * broadcast, then mul/add on register pairs per column). Other compilers: no effect. */
#if defined(__GNUC__) && !defined(__clang__)
#define OBS_NO_LOOP_VEC __attribute__((optimize("no-tree-loop-vectorize")))
#else
#define OBS_NO_LOOP_VEC
#endif

/* One partial sum of kernel() for 8 rows: acc = sum_{j < ncol} f[:, j] s[j] (ncol >= 1). The
 * rows live in eight scalars, so the compiler keeps them in (vector) registers. */
OBS_NO_LOOP_VEC
static void colsum8(size_t ncol, const dv_real_t *restrict f, const dv_real_t *restrict s,
                    dv_real_t *restrict acc)
{
    const dv_real_t s0 = s[0];
    dv_real_t a0 = f[0] * s0, a1 = f[1] * s0, a2 = f[2] * s0, a3 = f[3] * s0;
    dv_real_t a4 = f[4] * s0, a5 = f[5] * s0, a6 = f[6] * s0, a7 = f[7] * s0;
    for (size_t j = 1; j < ncol; j++) {
        const dv_real_t *restrict c = f + 8u * j;
        const dv_real_t sj = s[j];
        a0 += c[0] * sj;
        a1 += c[1] * sj;
        a2 += c[2] * sj;
        a3 += c[3] * sj;
        a4 += c[4] * sj;
        a5 += c[5] * sj;
        a6 += c[6] * sj;
        a7 += c[7] * sj;
    }
    acc[0] = a0;
    acc[1] = a1;
    acc[2] = a2;
    acc[3] = a3;
    acc[4] = a4;
    acc[5] = a5;
    acc[6] = a6;
    acc[7] = a7;
}

/* The same for 4 rows. */
OBS_NO_LOOP_VEC
static void colsum4(size_t ncol, const dv_real_t *restrict f, const dv_real_t *restrict s,
                    dv_real_t *restrict acc)
{
    const dv_real_t s0 = s[0];
    dv_real_t a0 = f[0] * s0, a1 = f[1] * s0, a2 = f[2] * s0, a3 = f[3] * s0;
    for (size_t j = 1; j < ncol; j++) {
        const dv_real_t *restrict c = f + 4u * j;
        const dv_real_t sj = s[j];
        a0 += c[0] * sj;
        a1 += c[1] * sj;
        a2 += c[2] * sj;
        a3 += c[3] * sj;
    }
    acc[0] = a0;
    acc[1] = a1;
    acc[2] = a2;
    acc[3] = a3;
}

/* kernel() for 8 states and 4 outputs (the 4-DOF chain, four channels), with the rest of a
 * regular step folded in: sv[0..8) is overwritten by the new state, yo gets the prediction and,
 * with y (4 finite measurements, used for the correction when ny = 4), resid = y - yo. The
 * first nin input columns are used; the measurement columns start at input column iy >= nin
 * (the contact-force columns between are skipped when every force is zero). */
OBS_NO_LOOP_VEC
static void kernel_8x4_c(size_t nin, size_t iy, size_t ny, const dv_real_t *restrict fx,
                       const dv_real_t *restrict fy, dv_real_t *restrict sv,
                       const dv_real_t *restrict y, dv_real_t *restrict yo,
                       dv_real_t *restrict resid)
{
    dv_real_t a[8], b[8], c[8], ya[4], yb[4];
    colsum8(nin, fx + 64, sv + 8, a); /* inputs, off the state chain */
    if (ny > 0u) {
        colsum8(ny, fx + 8u * (8u + iy), y, c);
    } else {
        for (size_t r = 0; r < 8u; r++) {
            c[r] = DV_R(0.0);
        }
    }
    colsum8(8u, fx, sv, b);
    colsum4(nin, fy + 32, sv + 8, ya);
    colsum4(8u, fy, sv, yb);
    for (size_t r = 0; r < 8u; r++) {
        sv[r] = (a[r] + c[r]) + b[r];
    }
    for (size_t q = 0; q < 4u; q++) {
        yo[q] = ya[q] + yb[q];
    }
    if (y != NULL) {
        for (size_t q = 0; q < 4u; q++) {
            resid[q] = y[q] - yo[q];
        }
    }
}

/* kernel_8x4_c(), or its AVX2 + FMA form when the CPU has it (chosen at init, o->simd). The
 * measurement columns start at input column iy: nin, or 2 + nf in a contact step whose forces
 * are all zero (nin = 2: the input window's columns only, the force columns skipped). */
static inline void kernel_8x4(const dv_obs_t *o, size_t nin, size_t iy, size_t ny,
                              const dv_real_t *fx, const dv_real_t *fy, dv_real_t *sv,
                              const dv_real_t *y, dv_real_t *yo, dv_real_t *resid)
{
#if DV_SIMD_X86
    if (o->simd != 0u) {
        if (iy == nin) {
            dv_priv_obs_kern8x4_avx2(nin, ny, fx, fy, sv, y, yo, resid);
        } else {
            dv_priv_obs_kern8x4_open_avx2(iy, ny, fx, fy, sv, y, yo, resid);
        }
        return;
    }
#else
    (void)o;
#endif
    kernel_8x4_c(nin, iy, ny, fx, fy, sv, y, yo, resid);
}

/* End of a first sample: residual against y (a NaN channel: predicted only), the gain's
 * correction of the state in sv, and the state copied out. yhat = o->z + ns is filled. */
static void finish_first(dv_obs_t *o, const dv_real_t *y, bool correct)
{
    const size_t ns = o->ns;
    const size_t no = o->no;
    dv_real_t *sv = o->sv;
    const dv_real_t *yhat = o->z + ns;
    for (size_t q = 0; q < no; q++) {
        const dv_real_t yq = (y != NULL && dv_priv_finite(y[q])) ? y[q] : yhat[q];
        o->resid[q] = yq - yhat[q];
    }
    if (correct) {
        /* the y columns of the folded state rows: L (T^-1 L in modal coordinates) */
        const dv_real_t *ly = o->f + (size_t)o->ncol_open * ns;
        for (size_t j = 0; j < ns; j++) {
            dv_real_t s = DV_R(0.0);
            for (size_t q = 0; q < no; q++) {
                s += ly[q * ns + j] * o->resid[q];
            }
            sv[j] += s;
        }
    }
    for (size_t j = 0; j < ns; j++) {
        o->z[j] = sv[j];
    }
    o->started = true;
    set_ready(o);
}

/* First sample (first-order hold): the state is at t0 already; output only, then correct. */
static void step_first(dv_obs_t *o, dv_real_t u, const dv_real_t *y, bool correct)
{
    const dv_model_t *m = o->m;
    const size_t ns = o->ns;
    const size_t no = o->no;
    const size_t nc = m->n_elem;
    dv_real_t *sv = o->sv;
    dv_real_t *yhat = o->z + ns;
    sv[ns] = u;
    if (o->nf > 0u) {
        contact_forces(o, sv, ns); /* every node sees the same state: use node 0 */
    }
    for (size_t q = 0; q < no; q++) {
        dv_real_t s = (m->d0[q] + m->d1[q]) * u;
        for (size_t j = 0; j < ns; j++) {
            s += m->cy[q * ns + j] * sv[j];
        }
        for (size_t e = 0; e < nc; e++) {
            s += m->ey[q * nc + e] * sv[ns + 2u + e];
        }
        yhat[q] = s;
    }
    finish_first(o, y, correct);
}

/* First sample (cubic hold): the state is at t0 (at rest); the window is [0, 0, u[0], u[1]].
 * Output only (contact forces from the state at t0 directly), then correct. */
static void step_first_cubic(dv_obs_t *o, const dv_real_t *y, bool correct)
{
    const dv_model_t *m = o->m;
    const size_t ns = o->ns;
    const size_t no = o->no;
    const size_t nc = m->n_elem;
    dv_real_t *sv = o->sv;
    const dv_real_t *win = sv + ns;
    dv_real_t *yhat = o->z + ns;
    dv_real_t g[DV_MAX_ELEM];
    for (size_t e = 0; e < nc; e++) {
        const dv_elem_desc_t *c = &m->elem[e];
        /* velocity laws: at rest, the ground's velocity at t0 is left out (first sample) */
        const bool vel = dv_priv_elem_on_velocity(c->law);
        const size_t off = vel ? (size_t)m->n_dof : 0u;
        const dv_real_t xa = c->dof_a == (uint16_t)DV_GROUND ? DV_R(0.0) : sv[off + c->dof_a];
        const dv_real_t x = sv[off + c->dof_b] - xa + (vel ? DV_R(0.0) : m->elem_dx[e] * win[2]);
        g[e] = dv_priv_elem_force(c, dv_priv_elem_kh(c), o->elem_x[e], o->elem_g[e], x); /* history: at rest */
    }
    for (size_t q = 0; q < no; q++) {
        dv_real_t s = DV_R(0.0);
        for (size_t i = 0; i < 4u; i++) {
            s += m->du[q * 4u + i] * win[i];
        }
        for (size_t j = 0; j < ns; j++) {
            s += m->cy[q * ns + j] * sv[j];
        }
        for (size_t e = 0; e < nc; e++) {
            s += m->ey[q * nc + e] * g[e];
        }
        yhat[q] = s;
    }
    finish_first(o, y, correct);
}

/* Prediction only: yhat = sum over the first ncol columns of sv of fy[:, j] sv[j] (the output
 * rows, column-major, no rows). */
static void outputs(size_t ncol, size_t no, const dv_real_t *fy, const dv_real_t *sv,
                    dv_real_t *yhat)
{
    for (size_t q = 0; q < no; q++) {
        yhat[q] = DV_R(0.0);
    }
    for (size_t j = 0; j < ncol; j++) {
        for (size_t q = 0; q < no; q++) {
            yhat[q] += fy[j * no + q] * sv[j];
        }
    }
}

/* Complete one sample from the state and input window in sv: predict, residual against y
 * (NULL: none; flags: its DV_OBS_FLAG_*), correct. first: the first sample of a record. */
static void produce(dv_obs_t *o, const dv_real_t *y, uint32_t flags, bool use_gain, bool first)
{
    const size_t ns = o->ns;
    const size_t no = o->no;
    const size_t nf = o->nf;
    const size_t nin = o->nin;
    dv_real_t *sv = o->sv;
    const bool correct = use_gain && o->has_gain && flags == 0u;
    dv_real_t *yhat = o->z + ns;
    const dv_real_t *fx = o->f;
    const dv_real_t *fy = o->f + ns * (size_t)o->ncol_gain;
    if (first) {
        if (nin == 4u) {
            step_first_cubic(o, y, correct);
        } else {
            step_first(o, sv[ns + 1u], y, correct);
        }
        o->n_pred++;
        return;
    }
    if (nf > 0u) {
        contact_forces(o, sv, ns);
    }
    /* the measurements the state rows see: y (correction), nothing (no gain folded), or the
     * prediction itself when a gain is folded but this step is open loop (x+ = x- + L (yhat -
     * yhat): the folded rows give back the open-loop ones) */
    const dv_real_t *ys = y;
    size_t ny = no;
    dv_real_t ypre[DV_MAX_OUT];
    if (!correct) {
        ys = NULL;
        ny = 0u;
        if (o->has_gain) {
            outputs(ns + nin + nf, no, fy, sv, ypre);
            ys = ypre;
            ny = no;
        }
    }
    if (ns == 8u && no == 4u) {
        /* the 4-DOF, 4-channel case: constant sizes, one call */
        kernel_8x4(o, nin + nf, nin + nf, ny, fx, fy, sv, ys, yhat, o->resid);
    } else {
        dv_real_t *yc = sv + ns + nin + nf;
        for (size_t q = 0; q < ny; q++) {
            yc[q] = ys[q];
        }
        dv_real_t xn[2u * DV_MAX_DOF];
        kernel(ns, no, nin + nf, ny, fx, fy, sv, xn, yhat);
        for (size_t j = 0; j < ns; j++) {
            sv[j] = xn[j];
        }
    }
    for (size_t q = 0; q < no; q++) {
        const dv_real_t yq = (y != NULL && (flags == 0u || dv_priv_finite(y[q]))) ? y[q] : yhat[q];
        o->resid[q] = yq - yhat[q];
    }
    o->n_pred++;
}

static dv_status_t step(dv_obs_t *o, dv_real_t u, const dv_real_t *y, bool use_gain)
{
    const size_t ns = o->ns;
    const size_t no = o->no;
    dv_real_t *sv = o->sv;
    if (!dv_priv_finite(u)) {
        o->flags = DV_OBS_FLAG_BAD_INPUT;
        o->n_bad_input++;
        return DV_ENUMERIC;
    }
    uint32_t flags = 0u;
    if (y == NULL) {
        flags = DV_OBS_FLAG_NO_MEAS;
    } else if (no == 4u ? !dv_priv_all_finite(y, 4u) : !dv_priv_all_finite(y, no)) {
        flags = DV_OBS_FLAG_BAD_MEAS;
    }
    if (o->nin == 2u) {
        sv[ns + 1u] = u;
        produce(o, y, flags, use_gain, !o->started);
        sv[ns] = u;
        o->flags = flags;
    } else {
        /* cubic: the window moves to [u[j-3], u[j-2], u[j-1], u[j]]; sample j - 1 completes
         * against the measurement kept from the previous call */
        sv[ns] = sv[ns + 1u];
        sv[ns + 1u] = sv[ns + 2u];
        sv[ns + 2u] = sv[ns + 3u];
        sv[ns + 3u] = u;
        if (o->n_steps > 0u) {
            const uint32_t pf = o->pend_flags;
            produce(o, (pf & DV_OBS_FLAG_NO_MEAS) != 0u ? NULL : o->ypend, pf, use_gain,
                    o->n_steps == 1u);
            o->flags = pf;
        } else {
            o->flags = flags;
        }
        if (y != NULL) {
            for (size_t q = 0; q < no; q++) {
                o->ypend[q] = y[q];
            }
        }
        o->pend_flags = flags;
    }
    o->n_steps++;
    if ((flags & DV_OBS_FLAG_BAD_MEAS) != 0u) {
        o->n_bad_meas++;
        return DV_ENUMERIC;
    }
    return DV_OK;
}

/* fast_step()'s product with contact elements: the forces, then the step with their columns,
 * or without them when every force is zero (the element open). Out of line: the linear fast
 * step then needs no saved registers. */
#if defined(__GNUC__) || defined(__clang__)
__attribute__((noinline))
#endif
static void contact_step_8x4(dv_obs_t *o, const dv_real_t *y)
{
    dv_real_t *sv = o->sv;
    const size_t ny = o->has_gain ? 4u : 0u;
    const dv_real_t *fy = o->f + 8u * (size_t)o->ncol_gain;
    const bool open = contact_forces(o, sv, 8u);
    const size_t nfc = open ? 0u : o->nf;
    o->contact_hot = !open;
    kernel_8x4(o, 2u + nfc, 2u + o->nf, ny, o->f, fy, sv, y, o->z + 8, o->resid);
}

/* The regular step of the 4-DOF, 4-channel case (first-order hold, vector kernel, past the
 * first sample, finite u and y, with the gain if there is one): step() for it, written out
 * without its general cases. Returns false, with nothing changed, for any other step. */
static inline bool fast_step(dv_obs_t *o, dv_real_t u, const dv_real_t *y)
{
    if (!(o->fast && o->started && y != NULL)) {
        return false;
    }
    const dv_real_t bad =
        ((u - u) + (y[0] - y[0])) + ((y[1] - y[1]) + ((y[2] - y[2]) + (y[3] - y[3])));
    if (bad != DV_R(0.0)) {
        return false;
    }
    dv_real_t *sv = o->sv;
    sv[9] = u;
    if (o->nf > 0u) {
        contact_step_8x4(o, y);
    } else {
        kernel_8x4(o, 2u, 2u, o->has_gain ? 4u : 0u, o->f, o->f + 8u * (size_t)o->ncol_gain, sv,
                   y, o->z + 8, o->resid);
    }
    sv[8] = u;
    o->flags = 0u;
    o->n_pred++;
    o->n_steps++;
    return true;
}

/* kept out of line: dv_obs_step() then needs no saved registers on its modal path */
#if defined(__GNUC__)
__attribute__((noinline))
#endif
dv_status_t dv_priv_obs_step_slow(dv_obs_t *o, dv_real_t u, const dv_real_t *y_meas)
{
    if (fast_step(o, u, y_meas)) {
        return DV_OK;
    }
    return step(o, u, y_meas, true);
}

dv_status_t dv_obs_step(dv_obs_t *o, dv_real_t u, const dv_real_t *y_meas)
{
    DV_ASSERT(o != NULL && o->m != NULL);
#if DV_SIMD_X86
    /* the modal steps, tail calls (they hand anything but a regular step to the slow path) */
    if (o->modal_ready == 1u) {
        return dv_priv_obs_step8x4_modal_avx512(o, u, y_meas);
    }
    if (o->modal_ready == 2u) {
        return dv_priv_obs_step8x4_modal_contact_avx512(o, u, y_meas);
    }
#endif
    return dv_priv_obs_step_slow(o, u, y_meas);
}

uint32_t dv_obs_latency(const dv_obs_t *o)
{
    return (o != NULL && o->nin == 4u) ? 1u : 0u;
}

/* Complete the pending sample (cubic) with an extrapolated next input; the state, window and
 * contact slots are restored afterwards. */
static dv_status_t flush(dv_obs_t *o, bool use_gain)
{
    if (o->nin != 4u || o->n_steps == 0u) {
        return DV_ENOTREADY;
    }
    const size_t ns = o->ns;
    const size_t keep = ns + 4u;
    dv_real_t save[2u * DV_MAX_DOF + 4u];
    dv_real_t *sv = o->sv;
    for (size_t i = 0; i < keep; i++) {
        save[i] = sv[i];
    }
    dv_real_t sx[DV_MAX_ELEM];
    dv_real_t sg[DV_MAX_ELEM];
    for (size_t e = 0; e < DV_MAX_ELEM; e++) {
        sx[e] = o->elem_x[e];
        sg[e] = o->elem_g[e];
    }
    const dv_real_t ux = DV_R(3.0) * sv[ns + 3u] - DV_R(3.0) * sv[ns + 2u] + sv[ns + 1u];
    sv[ns] = sv[ns + 1u];
    sv[ns + 1u] = sv[ns + 2u];
    sv[ns + 2u] = sv[ns + 3u];
    sv[ns + 3u] = ux;
    const uint32_t pf = o->pend_flags;
    const bool started = o->started;
    produce(o, (pf & DV_OBS_FLAG_NO_MEAS) != 0u ? NULL : o->ypend, pf, use_gain,
            o->n_steps == 1u);
    o->flags = pf;
    o->started = started;
    for (size_t i = 0; i < keep; i++) {
        sv[i] = save[i];
    }
    for (size_t e = 0; e < DV_MAX_ELEM; e++) {
        o->elem_x[e] = sx[e];
        o->elem_g[e] = sg[e];
    }
    return DV_OK;
}

dv_status_t dv_obs_flush(dv_obs_t *o)
{
    if (o == NULL || o->m == NULL) {
        return DV_EINVAL;
    }
    return flush(o, true);
}

dv_status_t dv_obs_get(const dv_obs_t *o, dv_real_t *y_pred, dv_real_t *resid, size_t len)
{
    if (o == NULL || o->m == NULL) {
        return DV_EINVAL;
    }
    if (o->n_pred == 0u) {
        return DV_ENOTREADY;
    }
    if (len < o->no) {
        return DV_ESIZE;
    }
    for (size_t q = 0; q < o->no; q++) {
        if (y_pred != NULL) {
            y_pred[q] = o->z[o->ns + q];
        }
        if (resid != NULL) {
            resid[q] = o->resid[q];
        }
    }
    return DV_OK;
}

dv_status_t dv_obs_get_state(const dv_obs_t *o, dv_real_t *x, size_t len)
{
    if (o == NULL || x == NULL || o->m == NULL) {
        return DV_EINVAL;
    }
    if (len < o->ns) {
        return DV_ESIZE;
    }
    state_x(o, x);
    return DV_OK;
}

static dv_status_t run_block(dv_obs_t *o, const dv_real_t *u, const dv_real_t *y_meas, size_t n,
                             dv_real_t *y_pred, dv_real_t *resid, bool use_gain)
{
    const size_t no = o->no;
    dv_status_t worst = DV_OK;
    for (size_t k = 0; k < n; k++) {
#if DV_SIMD_X86
        /* the modal steps with the state in registers, up to a non-finite sample (or the end);
         * open loop (y NULL) the same with or without use_gain */
        if (o->modal_ready != 0u && (use_gain || y_meas == NULL)) {
            k += dv_priv_obs_run8x4_modal_avx512(
                o, u + k, y_meas != NULL ? y_meas + k * no : NULL, n - k,
                y_pred != NULL ? y_pred + k * no : NULL, resid != NULL ? resid + k * no : NULL);
            if (k == n) {
                break;
            }
        }
#endif
        const dv_real_t *yk = y_meas != NULL ? y_meas + k * no : NULL;
        const dv_status_t st =
            (use_gain && fast_step(o, u[k], yk)) ? DV_OK : step(o, u[k], yk, use_gain);
        if (st != DV_OK) {
            worst = st;
        }
        const bool have = (o->flags & DV_OBS_FLAG_BAD_INPUT) == 0u && o->n_pred > 0u;
        const dv_real_t *yh = o->z + o->ns;
        for (size_t q = 0; q < no; q++) {
            if (y_pred != NULL) {
                y_pred[k * no + q] = yh[q];
            }
            if (resid != NULL) {
                resid[k * no + q] = have ? o->resid[q] : DV_R(0.0);
            }
        }
    }
    return worst;
}

dv_status_t dv_obs_update_block(dv_obs_t *o, const dv_real_t *u, const dv_real_t *y_meas,
                                size_t n, dv_real_t *y_pred, dv_real_t *resid)
{
    if (o == NULL || o->m == NULL || (u == NULL && n > 0u)) {
        return DV_EINVAL;
    }
    return run_block(o, u, y_meas, n, y_pred, resid, true);
}

/* dv_obs_simulate() with the cubic hold: the call with u[k] completes the last accepted sample
 * before it; its row gets the prediction. Refused samples repeat the row before them. */
static dv_status_t simulate_cubic(dv_obs_t *o, const dv_real_t *u, size_t n, dv_real_t *y)
{
    const size_t no = o->no;
    const dv_real_t *yh = o->z + o->ns;
    dv_status_t worst = DV_OK;
    size_t last = n; /* row of the pending sample; n: none */
    for (size_t k = 0; k < n; k++) {
        const uint64_t before = o->n_pred;
        const dv_status_t st = step(o, u[k], NULL, false);
        if (st != DV_OK) {
            worst = st;
            continue;
        }
        if (o->n_pred != before && last < n) {
            for (size_t q = 0; q < no; q++) {
                y[last * no + q] = yh[q];
            }
        }
        last = k;
    }
    if (last < n && flush(o, false) == DV_OK) {
        for (size_t q = 0; q < no; q++) {
            y[last * no + q] = yh[q];
        }
    }
    for (size_t k = 0; k < n; k++) {
        if (!dv_priv_finite(u[k])) {
            for (size_t q = 0; q < no; q++) {
                y[k * no + q] = k > 0u ? y[(k - 1u) * no + q] : DV_R(0.0);
            }
        }
    }
    return worst;
}

dv_status_t dv_obs_simulate(dv_obs_t *o, const dv_real_t *u, size_t n, dv_real_t *y)
{
    if (o == NULL || o->m == NULL || y == NULL || (u == NULL && n > 0u)) {
        return DV_EINVAL;
    }
    dv_obs_reset(o);
    if (o->nin == 4u) {
        return simulate_cubic(o, u, n, y);
    }
    return run_block(o, u, NULL, n, y, NULL, false);
}

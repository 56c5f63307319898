/* The modal form of the observer's 4-DOF, 4-output step (x86-64 double, AVX-512; the layout is
 * struct dv_obs_modal in dv_obs_priv.h, the step that uses it dv_obskern.c).
 *
 * The state block F of the folded state rows (x+ = F x + ...) of the 8-state observer is
 * brought to real block-diagonal form, F = T Lam T^-1 with 2 x 2 blocks (a complex pair of
 * eigenvalues or two real ones), and the observer runs on q = T^-1 x: the state rows become
 * [Lam | T^-1 (input and y columns)], the output rows' state columns C T. Every kernel works
 * unchanged on these dense rows; the AVX-512 step also uses the blocks directly (two fused
 * multiply-adds for the state instead of eight), which halves the step. With a gap element the
 * contact's sub-node X rows are rewritten over q too (struct dv_obs_modal rx), and a step that
 * finds the element open at every node is the linear modal step (its force columns skipped, as
 * in all_open(), dv_obs_elem.c); a step that engages it runs the node chain and the dense
 * product on the same q-coordinate rows. x = T q is formed only when asked for
 * (dv_obs_get_state()). The eigenvalues come from dv_mat_eig_real(), each pair's vectors from
 * inverse iteration; F keeps the dense form when T is ill-conditioned (a repeated
 * or defective eigenvalue) or the blocks do not reproduce F to 1e-9 relative. */
#include "dv_obs_priv.h"

#if DV_SIMD_X86
#include "dynval/dv_mat.h"

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


/* T of F (fr, 8 x 8 row-major): the eigenvalues, then each block's real basis by inverse
 * iteration, complex pairs as they come (positive imaginary part first), real ones paired. */
static bool modal_basis(double *fr, double *t)
{
    const size_t n = 8u;
    double wr[8], wi[8], work[DV_MAT_EIGR_WORK_LEN(8)];
    dv_mat_t fm = {8u, 8u, fr};
    if (dv_mat_eig_real(&fm, wr, wi, work, sizeof work / sizeof *work) != DV_OK) {
        return false;
    }
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
    return col == n && pend == 8u;
}

/* T^-1 (ti), its condition number and the blocks Lam = T^-1 F T; false when T is
 * ill-conditioned or Lam has more than rounding (1e-9 fmax) off its 2 x 2 blocks. */
static bool modal_blocks(double *fr, double *t, double *ti, double *lam, double fmax)
{
    const size_t n = 8u;
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
    dv_mat_t fm = {8u, 8u, fr};
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
    return true;
}

/* The folded rows in q coordinates: the state rows' state columns Lam, their other columns
 * T^-1 col, the output rows' state columns C T (also into ct, 4 x 8 row-major). */
static void modal_rows(dv_obs_t *o, const double *lam, const double *ti, const double *t,
                       double *ct)
{
    const size_t n = 8u;
    const size_t no = 4u;
    const size_t ncg = o->ncol_gain;
    double *f = o->f;
    double *fy = o->f + n * ncg;
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
}

/* The step's own copy: T, Lam's blocks, the prediction's lane-permuted products (see
 * struct dv_obs_modal). */
static void modal_fill(dv_obs_modal_t *mf, const double *lam, const double *ct, const double *t)
{
    const size_t n = 8u;
    for (size_t k = 0; k < 4u; k++) {
        for (size_t l = 0; l < n; l++) {
            mf->pred[k][l] = ct[(l & 3u) * n + (l ^ k)];
        }
    }
    for (size_t b = 0; b < n; b += 2u) {
        mf->lam_diag[b] = lam[b * n + b];
        mf->lam_diag[b + 1u] = lam[(b + 1u) * n + b + 1u];
        mf->lam_off[b] = lam[b * n + b + 1u];
        mf->lam_off[b + 1u] = lam[(b + 1u) * n + b];
    }
    for (size_t i = 0; i < 64u; i++) {
        mf->t[i] = t[i];
    }
}

/* A contact's sub-node X rows over q: state columns rx T, the input window's two as they are,
 * in blocks of 8 nodes (the layout of the AVX-512 open check). */
static void modal_contact_rows(dv_obs_t *o, const double *t)
{
    const size_t n = 8u;
    const size_t nf = o->nf;
    const double *rx = o->m->rx;
    for (size_t b = 0; b < nf; b += 8u) {
        double(*rb)[DV_OBS_MODAL_BLOCK] = o->modal_form->rx[b / 8u];
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
                rb[j][l] = s;
            }
        }
    }
}

bool dv_priv_obs_make_modal(dv_obs_t *o, dv_real_t *x)
{
    const size_t n = 8u;
    const double *f = o->f;
    double fr[64], t[64], ti[64], lam[64], ct[32];
    double fmax = 0.0;
    for (size_t r = 0; r < n; r++) {
        for (size_t j = 0; j < n; j++) {
            fr[r * n + j] = f[j * n + r];
            fmax = fmax > fabs(fr[r * n + j]) ? fmax : fabs(fr[r * n + j]);
        }
    }
    if (!modal_basis(fr, t) || !modal_blocks(fr, t, ti, lam, fmax)) {
        return false;
    }
    modal_rows(o, lam, ti, t, ct);
    modal_fill(o->modal_form, lam, ct, t);
    if (o->nf > 0u) {
        modal_contact_rows(o, t);
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

#else
/* ISO C wants at least one declaration in a translation unit. */
typedef int dv_obs_modal_unused_t;
#endif

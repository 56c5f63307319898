/* The observer's steady-state Kalman gain: the filter DARE of the linear part, solved by the
 * structure-preserving doubling algorithm at init (Chu, Fan, Lin 2005). */
#include "dv_obs_priv.h"

/* c = op(a) op(b), n x n row-major; ta, tb: the transpose of a, b. */
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

/* Does gain l (ns x no) hold the filter? The estimate's error follows e+ = (I - L Cy) Ad e, so
 * every eigenvalue of that matrix must lie in the unit disc. A mode the outputs do not see
 * (a free chain's rigid-body mode through accelerations) keeps its eigenvalue 1 whatever the
 * gain, and round-off puts a double eigenvalue there at 1 +- O(sqrt(eps)): hence the margin.
 * Without a stabilising DARE solution the doubling can stop on round-off at a gain that
 * makes the filter grow (largest modulus 2.3 on such a chain). w: 2 ns^2 + 3 ns elements. */
static bool gain_holds(const dv_model_t *m, const dv_real_t *l, size_t ns, size_t no,
                       dv_real_t *w)
{
    dv_real_t *cl = w;
    dv_real_t *wr = cl + ns * ns;
    dv_real_t *wi = wr + ns;
    dv_real_t *work = wi + ns;
    dv_real_t *t = work; /* I - L Cy, free again before the eigenvalues */
    for (size_t i = 0; i < ns; i++) {
        for (size_t k = 0; k < ns; k++) {
            dv_real_t lc = DV_R(0.0);
            for (size_t q = 0; q < no; q++) {
                lc += l[i * no + q] * m->cy[q * ns + k];
            }
            t[i * ns + k] = (i == k ? DV_R(1.0) : DV_R(0.0)) - lc;
        }
    }
    mm(ns, t, false, m->ad, false, cl);
    dv_mat_t cm = {(uint16_t)ns, (uint16_t)ns, cl};
    if (dv_mat_eig_real(&cm, wr, wi, work, DV_MAT_EIGR_WORK_LEN(ns)) != DV_OK) {
        return false;
    }
    const dv_real_t edge = DV_R(1.0) + DV_R(16.0) * DV_SQRT(DV_REAL_EPS);
    for (size_t i = 0; i < ns; i++) {
        if (!(wr[i] * wr[i] + wi[i] * wi[i] <= edge * edge)) {
            return false;
        }
    }
    return true;
}

/* Steady-state Kalman gain L = P Cy^T (Cy P Cy^T + R)^-1 of the filter DARE. */
dv_status_t dv_priv_obs_kalman_gain(dv_obs_t *o, const dv_obs_noise_t *nz, dv_real_t *w)
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
    return gain_holds(m, o->gain, ns, no, w) ? DV_OK : DV_EUNSTABLE;
}

bool dv_priv_obs_noise_ok(const dv_model_t *m, const dv_obs_noise_t *noise)
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

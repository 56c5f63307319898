/* The numerical pieces of a model build (dv_model_build.c) that several of its stages call: the
 * mass-scaled eigen-solution, the exponential of a hold's augmented matrix, and the cubic hold's
 * polynomial over a sub-interval. Declared, with what each computes, in dv_model_priv.h. */
#include "dynval/dv_model.h"
#include "dv_model_priv.h"
#include "dv_priv.h"

dv_status_t dv_priv_model_eig(const dv_model_t *m, const dv_real_t *s, dv_real_t *w,
                              dv_priv_model_eig_scratch_t sc)
{
    const size_t n = m->n_dof;
    const dv_real_t *mass = m->mass_kg;
    dv_real_t *tmp = sc.scaled;
    for (size_t i = 0; i < n; i++) {
        for (size_t j = 0; j < n; j++) {
            tmp[i * n + j] = s[i * n + j] / DV_SQRT(mass[i] * mass[j]);
        }
    }
    dv_mat_t sm = {(uint16_t)n, (uint16_t)n, tmp};
    dv_mat_t vm = {(uint16_t)n, (uint16_t)n, sc.vec};
    return dv_mat_eig_sym(&sm, w, &vm, sc.work, n * n);
}

dv_status_t dv_priv_model_poly_expm(size_t ns, size_t nb, size_t q, const dv_real_t *a,
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
    for (size_t i = 0; ad != NULL && i < ns; i++) {
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

dv_status_t dv_priv_model_input_hold_expm(const dv_model_t *m, size_t q, dv_real_t h,
                                          dv_real_t *ad, dv_real_t gq[][DV_PRIV_U_BLOCK_LEN],
                                          dv_real_t *scratch)
{
    const size_t ns = m->n_state, nb = DV_PRIV_U_COLS + (size_t)m->n_elem;
    const dv_real_t *b = m->bc;
    dv_real_t bu[DV_PRIV_U_BLOCK_LEN];
    dv_real_t *gp[DV_PRIV_CUBIC_NIN];
    for (size_t i = 0; i < ns; i++) {
        bu[i * DV_PRIV_U_COLS] = b[i * nb];
        bu[i * DV_PRIV_U_COLS + 1u] = b[i * nb + 1u];
    }
    for (size_t p = 0; p < q; p++) {
        gp[p] = gq[p];
    }
    return dv_priv_model_poly_expm(ns, DV_PRIV_U_COLS, q, m->ac, bu, h, ad, gp, scratch);
}

void dv_priv_model_poly_sub(const dv_real_t *c, size_t i, size_t nsub, dv_real_t *out)
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

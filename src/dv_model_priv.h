/* What the model's source files share. Not installed, not part of the API.
 * - dv_model.c: the description, its checks, the model's storage (sizes, layout), the getters;
 * - dv_model_build.c: dv_model_init_ex(), as stages over one build context;
 * - dv_model_math.c: the numerical pieces several stages call.
 * tests/scripts/golden_hashes.sh pins what a build computes bit for bit: keep each expression's
 * operations and the order of every sum unless a change of results is meant. */
#ifndef DV_MODEL_PRIV_H
#define DV_MODEL_PRIV_H

#include "dynval/dv_model.h"

/* B's input columns: u, and its slope u' (ground displacement); the element forces follow. */
#define DV_PRIV_U_COLS 2u
/* The largest ns x DV_PRIV_U_COLS block: B's input columns, or a hold's response to them. */
#define DV_PRIV_U_BLOCK_LEN (DV_MODEL_NS(DV_MAX_DOF) * DV_PRIV_U_COLS)
/* Samples of the cubic hold, u[k-1..k+2]; also the terms of its polynomial in s. */
#define DV_PRIV_CUBIC_NIN 4u

/* Scratch of dv_priv_model_eig(), n x n each. */
typedef struct {
    dv_real_t *vec;    /* out: the eigenvectors */
    dv_real_t *scaled; /* the mass-scaled matrix M^-1/2 S M^-1/2 */
    dv_real_t *work;   /* the eigen-solver's work */
} dv_priv_model_eig_scratch_t;

/* ---- dv_model.c ---- */

/* Every check dv_model_init() documents for DV_EINVAL on the description and the sample period,
 * before any storage is touched: DV_OK or DV_EINVAL. */
dv_status_t dv_priv_model_validate(const dv_model_desc_t *d, dv_real_t dt_s);

/* A model's shape before its build fills it: @p m zeroed, its sizes and header from @p d and
 * @p dt_s, and its arrays in @p buf (dv_model_persistent_len(d) elements): what the observers'
 * steps read first (DV_MODEL_STEP_LEN_HOLD), then what only the builds of observers read, so
 * that dv_model_keep_step_only() frees the tail. */
void dv_priv_model_lay_out(dv_model_t *m, const dv_model_desc_t *d, dv_real_t dt_s,
                           dv_real_t *buf, size_t len);

/* ---- dv_model_math.c ---- */

/* Eigenvalues @p w (ascending) of M^-1/2 S M^-1/2 for a symmetric n x n @p s and the model's
 * masses (n = m->n_dof), eigenvectors in sc.vec: dv_mat_eig_sym()'s status. @p sc comes by
 * value so that no pointer into the build context escapes its function: the compiler then keeps
 * the context in registers (a pointer cost about 300 B of Cortex-M4 flash at -Os). */
dv_status_t dv_priv_model_eig(const dv_model_t *m, const dv_real_t *s, dv_real_t *w,
                              dv_priv_model_eig_scratch_t sc);

/* exp of [[A h, B h, 0, ..], [0, 0, I, ..], .., [0, .., 0]] with q >= 2 input blocks (A: ns x
 * ns; B: ns x nb, row-major with stride nb): a chain of integrators whose block p is s^p / p!
 * for unit initial value. Writes Ad (ns x ns; skipped when @p ad is NULL) and
 * gp[p] = p! G_p = int_0^1 e^{A h (1 - s)} B h s^p ds for p < q (each ns x nb, stride nb;
 * gp[0], gp[1] are G0, G1 of the first-order hold). @p scratch: 7 (ns + q nb)^2 elements.
 * DV_EUNSTABLE when the exponential is not finite. */
dv_status_t dv_priv_model_poly_expm(size_t ns, size_t nb, size_t q, const dv_real_t *a,
                                    const dv_real_t *b, dv_real_t h, dv_real_t *ad,
                                    dv_real_t *const *gp, dv_real_t *scratch);

/* dv_priv_model_poly_expm() of the model's A and B's input columns only, the block each input
 * hold needs (the full-step first-order hold, q = 2; the full-step cubic and its sub-step
 * response, q = 4): over a step of @p h, gq[p] = p! G_p (ns x DV_PRIV_U_COLS), p < q, and Ad
 * when @p ad is not NULL. */
dv_status_t dv_priv_model_input_hold_expm(const dv_model_t *m, size_t q, dv_real_t h,
                                          dv_real_t *ad, dv_real_t gq[][DV_PRIV_U_BLOCK_LEN],
                                          dv_real_t *scratch);

/* Coefficients (in t, over sub-interval i of nsub: s = (i + t) / nsub) of the full-step
 * polynomial sum_p c[p] s^p, p < 4. */
void dv_priv_model_poly_sub(const dv_real_t *c, size_t i, size_t nsub, dv_real_t *out);

#endif /* DV_MODEL_PRIV_H */

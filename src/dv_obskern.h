/* Observer step kernels with wide vector units (x86-64, double), chosen at run time.
 * Internal; see dv_obs.c for the portable kernel they replace and its layout. */
#ifndef DV_OBSKERN_H
#define DV_OBSKERN_H

#include "dv_obs_priv.h"

#if DV_SIMD_X86
/* The 8-state, 4-output step product with AVX2 + FMA: the same contract as kernel_8x4() in
 * dv_obs_step.c (fx: 8-row column-major state rows over [x, inputs (nin), y (ny)], fy: 4-row
 * column-major output rows over [x, inputs]; sv[0..8) becomes the new state, yo the
 * prediction, and with y, resid = y - yo). Only call when dv_priv_simd_kern() != 0. */
void dv_priv_obs_kern8x4_avx2(size_t nin, size_t ny, const dv_real_t *fx, const dv_real_t *fy,
                              dv_real_t *sv, const dv_real_t *y, dv_real_t *yo,
                              dv_real_t *resid);

/* The same with only the input window's two columns used and y from input column iy on: a
 * contact step whose forces are all zero (their columns skipped). */
void dv_priv_obs_kern8x4_open_avx2(size_t iy, size_t ny, const dv_real_t *fx,
                                   const dv_real_t *fy, dv_real_t *sv, const dv_real_t *y,
                                   dv_real_t *yo, dv_real_t *resid);

/* The step product of any size with AVX2 + FMA: kernel() in dv_obs_step.c (fx: ns-row
 * column-major state rows over [x, inputs, y], fy: no-row column-major output rows over
 * [x, inputs]), even ns <= 2 DV_MAX_DOF, no <= DV_MAX_OUT. The first nin input columns are
 * used and the ny measurement columns start at input column iy >= nin (the element-force
 * columns between are skipped when every force is zero); sv[0..ns) becomes the new state and
 * yo the prediction. False (nothing done) above 16 states or 16 outputs. Only call when
 * dv_priv_simd_kern() != 0. */
bool dv_priv_obs_kern_avx2(size_t ns, size_t no, size_t nin, size_t iy, size_t ny,
                           const dv_real_t *fx, const dv_real_t *fy, dv_real_t *sv,
                           const dv_real_t *y, dv_real_t *yo);

/* The force-free X at every element sub-node (dv_obs_elem.c nodes_x_free(), first-order hold):
 * xl = R [x; u[k-1]; u[k]], the vector = sv[0 .. ns + 2), node f of column j of R at
 * rx[(f / 8) bs + j cs + f % 8]: the model's column-major rows (bs 8, cs nf) or the modal form's
 * blocks of 8 nodes (struct dv_obs_modal rx: bs 80, cs 8). */
void dv_priv_obs_xfree_avx2(const double *rx, size_t nf, size_t ns, size_t bs, size_t cs,
                            const double *sv, double *xl);

/* The same X with the cubic hold (nodes_x_free()): xl = R [x; window], the window sv[ns ..
 * ns + 4), node f of state column j at rx[j nf + f] and its window coefficients at rxu[4 f ..
 * 4 f + 4) (the model's rows), product then sum in the portable loops' order: their results,
 * bit for bit. */
void dv_priv_obs_xfree_cubic_avx2(const double *rx, const double *rxu, size_t nf, size_t ns,
                                  const double *sv, double *xl);

/* The same step in modal coordinates (o->modal, past the first sample): q+ = Lam q + inputs,
 * with Lam's 2 x 2 blocks and the prediction's C T rows from o->modal_form; y NULL:
 * open loop, as dv_obs_step(). A non-finite u or y goes to dv_priv_obs_step_slow(). Returns
 * dv_obs_step()'s status. With a contact element (the next entry) the step is taken here only
 * when the element stays open at every sub-node (then the forces are zero); a step that
 * engages it goes to dv_priv_obs_step_slow() too. */
dv_status_t dv_priv_obs_step8x4_modal_avx512(dv_obs_t *o, double u, const double *y);

/* The same for a model with one gap element (o->nf > 0, o->path DV_OBS_PATH_MODAL_CONTACT). */
dv_status_t dv_priv_obs_step8x4_modal_contact_avx512(dv_obs_t *o, double u, const double *y);

/* n such steps with the state in registers (the same arithmetic, bit for bit), predictions and
 * residuals to y_pred / resid (4 per step; either may be NULL), y NULL for open loop. Stops
 * at the first non-finite u[k] or y[k], or step that engages the contact; returns how many
 * steps it made. */
size_t dv_priv_obs_run8x4_modal_avx512(dv_obs_t *o, const double *u, const double *y, size_t n,
                                       double *y_pred, double *resid);
#endif

#endif /* DV_OBSKERN_H */

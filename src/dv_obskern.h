/* Observer step kernels with wide vector units (x86-64, double), chosen at run time.
 * Internal; see dv_obs.c for the portable kernel they replace and its layout. */
#ifndef DV_OBSKERN_H
#define DV_OBSKERN_H

#include "dynval/dv_types.h"
#include "dynval/dv_obs.h"

#include "dv_priv.h"

/* dv_obs_step() without the modal step: the direct path when it applies, else the general
 * one (dv_obs.c). */
dv_status_t dv_priv_obs_step_slow(dv_obs_t *o, dv_real_t u, const dv_real_t *y_meas);

#if DV_SIMD_X86
/* The 8-state, 4-output step product with AVX2 + FMA: the same contract as kernel_8x4() in
 * dv_obs.c (fx: 8-row column-major state rows over [x, inputs (nin), y (ny)], fy: 4-row
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

/* The force-free X at every contact sub-node (dv_obs.c nodes_x_free(), first-order hold):
 * xl = [rx | rxa | rxb] [x; u[k-1]; u[k]], rx column-major nf x ns followed by the columns rxa
 * and rxb (the model's layout), the vector [x; u window] = sv[0 .. ns + 2). */
void dv_priv_obs_xfree_avx2(const double *rx, size_t nf, size_t ns, const double *sv,
                            double *xl);

/* The same step in modal coordinates (o->modal, past the first sample): q+ = Lam q + inputs,
 * with Lam's 2 x 2 blocks from o->fm, and the prediction from the C T rows in o->fm; y NULL:
 * open loop, as dv_obs_step(). A non-finite u or y goes to dv_priv_obs_step_slow(); returns
 * dv_obs_step()'s status. */
dv_status_t dv_priv_obs_step8x4_modal_avx512(dv_obs_t *o, double u, const double *y);

/* n such steps with the state in registers (the same arithmetic, bit for bit), predictions and
 * residuals to y_pred / resid (4 per step; either may be NULL), y NULL for open loop. Stops
 * at the first non-finite u[k] or y[k]; returns how many steps it made. */
size_t dv_priv_obs_run8x4_modal_avx512(dv_obs_t *o, const double *u, const double *y, size_t n,
                                       double *y_pred, double *resid);
#endif

#endif /* DV_OBSKERN_H */

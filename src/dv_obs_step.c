/* The observer's portable step paths: the step product (kernel(), and kernel_8x4() for the
 * 4-DOF, 4-output case), the first sample, the general step of any size and hold (produce(),
 * step()), the direct 8 x 4 step (fast_step()), the cubic hold's flush and the block loops.
 * Every path agrees bit for bit with the others where they overlap (tests/unit/test_dv_obs.c). */
#include "dv_obs_priv.h"
#include "dv_obskern.h"

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
    /* inputs (u[k-1], u[k], element forces, measurements): off the state chain */
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
 * (the element-force columns between are skipped when every force is zero). */
OBS_NO_LOOP_VEC
static void kernel_8x4_c(size_t nin, size_t iy, size_t ny, const dv_real_t *restrict fx,
                       const dv_real_t *restrict fy, dv_real_t *restrict sv,
                       const dv_real_t *restrict y, dv_real_t *restrict yo,
                       dv_real_t *restrict resid)
{
    dv_real_t a[8], b[8], c[8], ya[4], yb[4];
    /* inputs, off the state chain */
    colsum8(nin, fx + DV_OBS8_NS * DV_OBS8_COL_UPREV, sv + DV_OBS8_COL_UPREV, a);
    if (ny > 0u) {
        colsum8(ny, fx + DV_OBS8_NS * (DV_OBS8_COL_UPREV + iy), y, c);
    } else {
        for (size_t r = 0; r < 8u; r++) {
            c[r] = DV_R(0.0);
        }
    }
    colsum8(8u, fx, sv, b);
    colsum4(nin, fy + DV_OBS8_NO * DV_OBS8_COL_UPREV, sv + DV_OBS8_COL_UPREV, ya);
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

/* kernel_8x4_c(), or its AVX2 + FMA form when the CPU has it (chosen at init, o->kern). The
 * measurement columns start at input column iy: nin, or 2 + nf in an element step whose forces
 * are all zero (nin = 2: the input window's columns only, the force columns skipped). */
static inline void kernel_8x4(const dv_obs_t *o, size_t nin, size_t iy, size_t ny,
                              const dv_real_t *fx, const dv_real_t *fy, dv_real_t *sv,
                              const dv_real_t *y, dv_real_t *yo, dv_real_t *resid)
{
#if DV_SIMD_X86
    if (o->kern != DV_OBS_KERN_C) {
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
    dv_priv_obs_set_path(o);
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
        dv_priv_obs_elem_forces(o, sv, ns); /* every node sees the same state: use node 0 */
    }
    dv_real_t x[2u * DV_MAX_DOF]; /* a state set away from rest may be in modal coordinates */
    dv_priv_obs_state_x(o, x);
    for (size_t q = 0; q < no; q++) {
        dv_real_t s = (m->d0[q] + m->d1[q]) * u;
        for (size_t j = 0; j < ns; j++) {
            s += m->cy[q * ns + j] * x[j];
        }
        for (size_t e = 0; e < nc; e++) {
            s += m->ey[q * nc + e] * sv[ns + 2u + e];
        }
        yhat[q] = s;
    }
    finish_first(o, y, correct);
}

/* First sample (cubic hold): the state is at t0 (at rest, or as set); the window is
 * [0, 0, u[0], u[1]].
 * Output only (element forces from the state at t0 directly), then correct. */
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
    dv_priv_obs_first_forces_cubic(o, g);
    dv_real_t x[2u * DV_MAX_DOF]; /* a state set away from rest may be in modal coordinates */
    dv_priv_obs_state_x(o, x);
    for (size_t q = 0; q < no; q++) {
        dv_real_t s = DV_R(0.0);
        for (size_t i = 0; i < 4u; i++) {
            s += m->du[q * 4u + i] * win[i];
        }
        for (size_t j = 0; j < ns; j++) {
            s += m->cy[q * ns + j] * x[j];
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
        return;
    }
    /* every element open: the forces are zero (the vector kernel skips their columns) */
    const bool open = nf > 0u && dv_priv_obs_elem_forces(o, sv, ns);
    (void)open;
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
#if DV_SIMD_X86
    } else if (o->kern != DV_OBS_KERN_C && dv_priv_obs_kern_avx2(ns, no, open ? nin : nin + nf,
                                                                 nin + nf, ny, fx, fy, sv, ys,
                                                                 yhat)) {
        /* any other size: the vector kernel */
#endif
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
}

static dv_status_t step(dv_obs_t *o, dv_real_t u, const dv_real_t *y, bool use_gain)
{
    const size_t ns = o->ns;
    const size_t no = o->no;
    dv_real_t *sv = o->sv;
    if (!dv_priv_finite(u)) {
        dv_priv_obs_tally(o, DV_OBS_FLAG_BAD_INPUT, DV_OBS_FLAG_BAD_INPUT, 0u, 0u);
        return DV_ENUMERIC;
    }
    uint32_t flags = 0u;
    if (y == NULL) {
        flags = DV_OBS_FLAG_NO_MEAS;
    } else if (no == 4u ? !dv_priv_all_finite(y, 4u) : !dv_priv_all_finite(y, no)) {
        flags = DV_OBS_FLAG_BAD_MEAS;
    }
    uint32_t shown = flags; /* the flags of the sample this call completes */
    size_t preds = 1u;
    if (o->nin == 2u) {
        sv[ns + 1u] = u;
        produce(o, y, flags, use_gain, !o->started);
        sv[ns] = u;
    } else {
        /* cubic: the window moves to [u[j-3], u[j-2], u[j-1], u[j]]; sample j - 1 completes
         * against the measurement kept from the previous call (none on the first call) */
        sv[ns] = sv[ns + 1u];
        sv[ns + 1u] = sv[ns + 2u];
        sv[ns + 2u] = sv[ns + 3u];
        sv[ns + 3u] = u;
        if (o->n_steps > 0u) {
            shown = o->pend_flags;
            produce(o, (shown & DV_OBS_FLAG_NO_MEAS) != 0u ? NULL : o->ypend, shown, use_gain,
                    o->n_steps == 1u);
        } else {
            preds = 0u;
        }
        if (y != NULL) {
            for (size_t q = 0; q < no; q++) {
                o->ypend[q] = y[q];
            }
        }
        o->pend_flags = flags;
    }
    dv_priv_obs_tally(o, shown, flags, 1u, preds);
    return (flags & DV_OBS_FLAG_BAD_MEAS) != 0u ? DV_ENUMERIC : DV_OK;
}

/* fast_step()'s product with elements: the forces, then the step with their columns,
 * or without them when every force is zero (the element open). Out of line: the linear fast
 * step then needs no saved registers. */
#if defined(__GNUC__) || defined(__clang__)
__attribute__((noinline))
#endif
static void elem_step_8x4(dv_obs_t *o, const dv_real_t *y)
{
    dv_real_t *sv = o->sv;
    const size_t ny = o->has_gain ? 4u : 0u;
    const dv_real_t *fy = o->f + DV_OBS8_NS * (size_t)o->ncol_gain;
    const bool open = dv_priv_obs_elem_forces(o, sv, 8u);
    const size_t nfc = open ? 0u : o->nf;
    o->contact_hot = !open;
    kernel_8x4(o, 2u + nfc, 2u + o->nf, ny, o->f, fy, sv, y, o->z + DV_OBS8_NS, o->resid);
}

/* The regular step of the 4-DOF, 4-channel case (first-order hold, vector kernel, past the
 * first sample, finite u and y, with the gain if there is one): step() for it, written out
 * without its general cases. Returns false, with nothing changed, for any other step. */
static inline bool fast_step(dv_obs_t *o, dv_real_t u, const dv_real_t *y)
{
    if (o->path == DV_OBS_PATH_GENERAL || y == NULL) {
        return false;
    }
    const dv_real_t bad =
        ((u - u) + (y[0] - y[0])) + ((y[1] - y[1]) + ((y[2] - y[2]) + (y[3] - y[3])));
    if (bad != DV_R(0.0)) {
        return false;
    }
    dv_real_t *sv = o->sv;
    sv[DV_OBS8_COL_UPREV + 1] = u; /* u[k] */
    if (o->nf > 0u) {
        elem_step_8x4(o, y);
    } else {
        kernel_8x4(o, 2u, 2u, o->has_gain ? 4u : 0u, o->f,
                   o->f + DV_OBS8_NS * (size_t)o->ncol_gain, sv, y, o->z + DV_OBS8_NS, o->resid);
    }
    sv[DV_OBS8_COL_UPREV] = u; /* u[k-1] of the next step */
    dv_priv_obs_tally(o, 0u, 0u, 1u, 1u);
    return true;
}

/* A model with elements can run away from a finite input (a softening spring driven past
 * its peak force, an element too stiff for the sub-steps): its state is then not finite. A
 * linear model the init accepted cannot. */
static bool ran_away(const dv_obs_t *o)
{
    return o->nf > 0u && !dv_priv_all_finite(o->sv, o->ns);
}

/* kept out of line: dv_obs_step() then needs no saved registers on its modal path */
#if defined(__GNUC__)
__attribute__((noinline))
#endif
dv_status_t dv_priv_obs_step_slow(dv_obs_t *o, dv_real_t u, const dv_real_t *y_meas)
{
    const dv_status_t st = fast_step(o, u, y_meas) ? DV_OK : step(o, u, y_meas, true);
    return ran_away(o) ? DV_EUNSTABLE : st;
}

/* Complete the pending sample (cubic) with an extrapolated next input; the state, window and
 * element-force slots are restored afterwards. */
dv_status_t dv_priv_obs_flush(dv_obs_t *o, bool use_gain)
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
    dv_priv_obs_tally(o, pf, 0u, 0u, 1u); /* a prediction, not a step */
    o->started = started;
    dv_priv_obs_set_path(o);
    for (size_t i = 0; i < keep; i++) {
        sv[i] = save[i];
    }
    for (size_t e = 0; e < DV_MAX_ELEM; e++) {
        o->elem_x[e] = sx[e];
        o->elem_g[e] = sg[e];
    }
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
        if ((o->path == DV_OBS_PATH_MODAL || o->path == DV_OBS_PATH_MODAL_CONTACT) &&
            (use_gain || y_meas == NULL)) {
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
    return ran_away(o) ? DV_EUNSTABLE : worst; /* a non-finite state stays so to the end */
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
    if (last < n && dv_priv_obs_flush(o, false) == DV_OK) {
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
    return ran_away(o) ? DV_EUNSTABLE : worst;
}

dv_status_t dv_obs_update_block(dv_obs_t *o, const dv_real_t *u, const dv_real_t *y_meas,
                                size_t n, dv_real_t *y_pred, dv_real_t *resid)
{
    if (o == NULL || o->m == NULL || (u == NULL && n > 0u)) {
        return DV_EINVAL;
    }
    return run_block(o, u, y_meas, n, y_pred, resid, true);
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

/* The observer's internals shared by its files. Not installed, not part of the API.
 *   dv_obs.c          the API: sizes, init, gain, reset, dispatch of a step, get
 *   dv_obs_step.c     the portable step paths (first sample, general, direct 8 x 4), the
 *                     block API (dv_obs_update_block(), dv_obs_simulate())
 *   dv_obs_elem.c     the elements' sub-node forces of a step
 *   dv_obs_gain.c     the steady-state Kalman gain (DARE)
 *   dv_obs_modal.c    the modal form of the 8 x 4 step (x86-64 double)
 *   dv_obskern.c      the AVX2 / AVX-512 step kernels (dv_obskern.h)
 * Every path that completes a step records it with dv_priv_obs_tally(), and dispatch reads
 * dv_obs_t.path, set only by dv_priv_obs_set_path(). */
#ifndef DV_OBS_PRIV_H
#define DV_OBS_PRIV_H

#include "dynval/dv_obs.h"
#include "dv_priv.h"

/* ---- the folded rows of the 8-state, 4-output first-order-hold step (fold(), dv_obs.c) ----
 * State rows: 8 per column, columns [x (8), u[k-1], u[k], g (nf), y (4)]; output rows, after
 * all ncol_gain state columns: 4 per column, columns [x (8), u[k-1], u[k], g (nf)]. Column j
 * of the state rows starts at f + DV_OBS8_NS j, of the output rows at fy + DV_OBS8_NO j. */
enum {
    DV_OBS8_NS = 8,        /* states: rows of a state-row column */
    DV_OBS8_NO = 4,        /* outputs: rows of an output-row column */
    DV_OBS8_COL_UPREV = 8, /* column of u[k-1]; u[k] is the next */
    DV_OBS8_COL_G = 10     /* first contact-force column; y's columns follow the nf forces */
};

/* ---- the modal form (x86-64 double with AVX-512; built by dv_obs_modal.c, stepped by
 * dv_obskern.c) ---- The 8 x 8 state block of the folded state rows is F = T Lam T^-1 with
 * 2 x 2 blocks; the state is kept as q = T^-1 x. Lives in the caller's buffer on a 64-byte
 * line (o->modal_form), dv_priv_obs_modal_len() elements. */
enum {
    DV_OBS_MODAL_BLOCK = 8,                 /* sub-nodes per block of contact rows */
    DV_OBS_MODAL_RX_COLS = DV_OBS8_NS + 2   /* a contact row's columns: q, u[k-1], u[k] */
};
struct dv_obs_modal {
    dv_real_t t[DV_OBS8_NS * DV_OBS8_NS]; /* T, row-major: x = T q */
    dv_real_t lam_diag[DV_OBS8_NS];       /* the blocks' diagonals: Lam[i][i] */
    dv_real_t lam_off[DV_OBS8_NS];        /* their other entries: Lam[i][i ^ 1] */
    /* the prediction C T q without lane sums: lane l of product k pairs output l % 4 with state
     * l ^ k, so the four products of q with its in-half permutations sum, per half, to the
     * prediction over the first and the last four state columns */
    dv_real_t pred[4][DV_OBS8_NS];
    /* a contact element's sub-node X rows over [q, u[k-1], u[k]]: node 8 b + l of column j at
     * rx[b][j][l] (rows past nf are zero: X = 0, open at any gap >= 0) */
    dv_real_t rx[][DV_OBS_MODAL_RX_COLS][DV_OBS_MODAL_BLOCK];
};
typedef struct dv_obs_modal dv_obs_modal_t;

/* The public DV_OBS_MODAL_LEN() reserves this layout (with 28 elements of alignment slack). */
DV_STATIC_ASSERT(sizeof(dv_obs_modal_t) == 112u * sizeof(dv_real_t), obs_modal_head_112);
DV_STATIC_ASSERT(sizeof(dv_obs_modal_t) % 64u == 0u, obs_modal_rows_on_lines);

/* Elements of the modal form with nf contact sub-nodes (the layout function). */
static inline size_t dv_priv_obs_modal_len(size_t nf)
{
    const size_t blocks = (nf + DV_OBS_MODAL_BLOCK - 1u) / DV_OBS_MODAL_BLOCK;
    return sizeof(dv_obs_modal_t) / sizeof(dv_real_t) +
           blocks * DV_OBS_MODAL_RX_COLS * DV_OBS_MODAL_BLOCK;
}

/* ---- dispatch and bookkeeping ---- */

/* dv_obs_step()'s path from the sizes, kern, modal and started; called wherever one of them
 * changes, so the per-sample step reads one field (dv_obs.c). */
void dv_priv_obs_set_path(dv_obs_t *o);

/* Forced inline: with the constant arguments of the step paths it is the few stores they made
 * before (no call in the per-sample step, also at -Os). */
#if defined(__GNUC__)
#define DV_OBS_TALLY_INLINE static inline __attribute__((always_inline))
#else
#define DV_OBS_TALLY_INLINE static inline
#endif

/* The one place a call's outcome is counted: dv_obs_t.flags becomes @p shown; @p steps steps
 * were accepted, each with the measurement flags @p meas (DV_OBS_FLAG_BAD_INPUT: the input was
 * refused, steps 0); @p preds predictions were made (with the cubic hold the call that keeps
 * the first sample makes none, dv_obs_flush() one without a step). */
DV_OBS_TALLY_INLINE void dv_priv_obs_tally(dv_obs_t *o, uint32_t shown, uint32_t meas,
                                            size_t steps, size_t preds)
{
    o->flags = shown;
    o->n_steps += steps;
    o->n_pred += preds;
    if ((meas & DV_OBS_FLAG_BAD_INPUT) != 0u) {
        o->n_bad_input++;
    }
    if ((meas & DV_OBS_FLAG_BAD_MEAS) != 0u) {
        o->n_bad_meas += steps;
    }
}

/* ---- cross-file functions ---- */

/* The steady-state Kalman gain into o->gain (dv_obs_gain.c); w: dv_obs_scratch_len() elements.
 * DV_EUNSTABLE when the DARE does not converge or is singular. */
dv_status_t dv_priv_obs_kalman_gain(dv_obs_t *o, const dv_obs_noise_t *nz, dv_real_t *w);

/* q >= 0 and r > 0, all finite; NULL (open loop) is fine (dv_obs_gain.c). */
bool dv_priv_obs_noise_ok(const dv_model_t *m, const dv_obs_noise_t *noise);

#if DV_SIMD_X86
/* The folded rows (o->f) to modal form: fills o->modal_form, rewrites o->f in q coordinates and
 * x (the state, ns) as q. False, with nothing changed, when F keeps the dense form
 * (dv_obs_modal.c). */
bool dv_priv_obs_make_modal(dv_obs_t *o, dv_real_t *x);
#endif

/* Sub-node element forces into sv[ns + nin ..] from the state and input window in sv; true when
 * every force is zero because every element stays open (dv_obs_elem.c). */
bool dv_priv_obs_elem_forces(dv_obs_t *o, dv_real_t *sv, size_t ns);

/* x (ns) of the observer's state, whichever coordinates it is kept in (dv_obs.c). */
void dv_priv_obs_state_x(const dv_obs_t *o, dv_real_t *x);

/* The first sample with the cubic hold: each element's force (n_elem into g) from the state at
 * t0 directly, the input window [0, 0, u[0], u[1]], the element history at rest
 * (dv_obs_elem.c). */
void dv_priv_obs_first_forces_cubic(const dv_obs_t *o, dv_real_t *g);

/* dv_obs_step() without the modal step: the direct path when it applies, else the general one
 * (dv_obs_step.c). */
dv_status_t dv_priv_obs_step_slow(dv_obs_t *o, dv_real_t u, const dv_real_t *y_meas);

/* Complete the pending sample of the cubic hold (dv_obs_flush(); dv_obs_step.c). */
dv_status_t dv_priv_obs_flush(dv_obs_t *o, bool use_gain);

#endif /* DV_OBS_PRIV_H */

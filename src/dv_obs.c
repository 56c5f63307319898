/* Fixed-step observer, the API: storage sizes, init (the layout of the caller's buffer),
 * the folded step matrix and gain, reset, a step's dispatch, and reading results. The steps
 * themselves are in dv_obs_step.c, the element forces in dv_obs_elem.c, the Kalman gain in
 * dv_obs_gain.c, the modal form in dv_obs_modal.c and the vector kernels in dv_obskern.c. */
#include "dv_obs_priv.h"
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

void dv_priv_obs_set_path(dv_obs_t *o)
{
    dv_obs_path_t p = DV_OBS_PATH_GENERAL;
    if (o->started && o->ns == DV_OBS8_NS && o->no == DV_OBS8_NO && o->nin == 2u) {
        p = DV_OBS_PATH_DIRECT;
        if (o->kern == DV_OBS_KERN_AVX512 && o->modal) {
            p = o->nf != 0u ? DV_OBS_PATH_MODAL_CONTACT : DV_OBS_PATH_MODAL;
        }
    }
    o->path = p;
}

/* Fill the folded step matrix from the model and the gain (o->gain, used when has_gain).
 * Layout: the state rows first, column-major (ns rows, one column per entry of sv:
 * [x, u window, g, y]), then the output rows, column-major (no rows, columns
 * [x, u window, g] only: the prediction never depends on y). The u window is [u[k-1], u[k]]
 * (first-order hold) or [u[k-2], u[k-1], u[k], u[k+1]] (cubic) for the step to t_k. Keeping
 * the two row sets apart lets the step skip the zero y columns of the output rows and gives short columns
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
#if DV_SIMD_X86
    /* storage for the modal form: it may apply (dv_obs_modal.c); with a contact, only to the
     * gap law (the step that skips an open element) */
    if (o->modal_form != NULL && (nc == 0u || m->elem[0].law == DV_ELEM_CONTACT)) {
        o->modal = dv_priv_obs_make_modal(o, o->sv);
    }
#endif
    dv_priv_obs_set_path(o);
}

/* x (ns) of the current state, whichever coordinates it is kept in. */
void dv_priv_obs_state_x(const dv_obs_t *o, dv_real_t *x)
{
    const size_t ns = o->ns;
    if (o->modal) {
        for (size_t i = 0; i < ns; i++) {
            dv_real_t s = DV_R(0.0);
            for (size_t j = 0; j < ns; j++) {
                s += o->modal_form->t[i * ns + j] * o->sv[j];
            }
            x[i] = s;
        }
    } else {
        for (size_t i = 0; i < ns; i++) {
            x[i] = o->sv[i];
        }
    }
}

/* Fold again (a new gain) keeping the state: back to x coordinates, fold, then to modal
 * coordinates again if they apply. */
static void refold(dv_obs_t *o)
{
    dv_real_t x[2u * DV_MAX_DOF];
    dv_priv_obs_state_x(o, x);
    for (size_t i = 0; i < o->ns; i++) {
        o->sv[i] = x[i];
    }
    fold(o);
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
    if (!dv_priv_obs_noise_ok(m, noise)) {
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
    if (!dv_priv_obs_noise_ok(m, noise)) {
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
    o->kern = (dv_obs_kern_t)dv_priv_simd_kern();
    if (o->kern == DV_OBS_KERN_AVX512 &&
        !DV_OBS_MODAL_FITS(m->n_dof, m->n_elem, m->n_sub, no, nin)) {
        o->kern = DV_OBS_KERN_AVX2; /* AVX-512 serves the 8 x 4 step in modal form only */
    }
    /* the modal step's vectors on 64-byte lines (its storage has the slack): a 64-byte load or
     * store across two lines costs two, and the step makes about twenty */
    const bool al = o->kern == DV_OBS_KERN_AVX512;
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
    if (o->kern == DV_OBS_KERN_AVX512) {
        p = align64(p, true);
        o->modal_form = (dv_obs_modal_t *)(void *)p;
        p += dv_priv_obs_modal_len(nf);
    }
    DV_ASSERT((size_t)(p - buf) <= len);
    for (size_t i = 0; i < ns * no; i++) {
        o->gain[i] = DV_R(0.0);
    }
    if (noise != NULL) {
        const dv_status_t st = dv_priv_obs_kalman_gain(o, noise, scratch);
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

dv_status_t dv_obs_set_state(dv_obs_t *o, const dv_real_t *x, size_t len)
{
    if (o == NULL || x == NULL || o->m == NULL || (o->modal && o->m->ad == NULL)) {
        return DV_EINVAL;
    }
    if (len < o->ns) {
        return DV_ESIZE;
    }
    for (size_t i = 0; i < o->ns; i++) {
        if (!dv_priv_finite(x[i])) {
            return DV_EINVAL;
        }
    }
    for (size_t i = 0; i < o->ns; i++) {
        o->sv[i] = x[i];
    }
    if (o->modal) {
        fold(o); /* back to modal coordinates: q = T^-1 x (refold's path) */
    }
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
    o->pend_flags = DV_OBS_FLAG_NO_MEAS;
    o->started = false;
    dv_priv_obs_set_path(o);
    o->flags = 0u;
    o->n_steps = 0u;
    o->n_pred = 0u;
    o->n_bad_input = 0u;
    o->n_bad_meas = 0u;
    o->contact_hot = false;
    for (size_t e = 0; e < DV_MAX_ELEM; e++) {
        o->elem_x[e] = DV_R(0.0);
        o->elem_g[e] = DV_R(0.0);
    }
}

dv_status_t dv_obs_step(dv_obs_t *o, dv_real_t u, const dv_real_t *y_meas)
{
    DV_ASSERT(o != NULL && o->m != NULL);
#if DV_SIMD_X86
    /* the modal steps, tail calls (they hand anything but a regular step to the slow path) */
    if (o->path == DV_OBS_PATH_MODAL) {
        return dv_priv_obs_step8x4_modal_avx512(o, u, y_meas);
    }
    if (o->path == DV_OBS_PATH_MODAL_CONTACT) {
        return dv_priv_obs_step8x4_modal_contact_avx512(o, u, y_meas);
    }
#endif
    return dv_priv_obs_step_slow(o, u, y_meas);
}

uint32_t dv_obs_latency(const dv_obs_t *o)
{
    return (o != NULL && o->nin == 4u) ? 1u : 0u;
}

dv_status_t dv_obs_flush(dv_obs_t *o)
{
    if (o == NULL || o->m == NULL) {
        return DV_EINVAL;
    }
    return dv_priv_obs_flush(o, true);
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
    dv_priv_obs_state_x(o, x);
    return DV_OK;
}

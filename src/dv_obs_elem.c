/* The elements' sub-node forces of one observer step: a fixed number of fixed-point
 * iterations per sub-node, the laws from dv_elem_law.h. */
#include "dv_obs_priv.h"
#include "dv_elem_law.h"
#include "dv_obskern.h"

/* The force-free X at every sub-node (what X would be with no element force at this or any
 * earlier node of the step), xl[f] = rx[f, :] x + the input window's share: column by column,
 * in each node the same order of operations as a row dot. The rows: the model's (column-major,
 * over x: node f of column j at rx[j nf + f]) or with the modal form its rows over q (the
 * window's columns included, in blocks of 8 nodes: struct dv_obs_modal rx). */
static void nodes_x_free(const dv_obs_t *o, size_t ns, bool cubic, const dv_real_t *sv,
                         dv_real_t *xl)
{
    const dv_model_t *m = o->m;
    const size_t nf = m->n_f;
    const dv_real_t *win = sv + ns;
    const dv_real_t *rx = m->rx; /* the model's: read here, it may move */
#if DV_SIMD_X86
    const bool modal = o->modal && nf > 0u; /* the rows over q of the modal form */
    if (modal) {
        rx = &o->modal_form->rx[0][0][0];
    }
    if (!cubic && o->kern != DV_OBS_KERN_C) {
        const size_t bs = DV_OBS_MODAL_RX_COLS * DV_OBS_MODAL_BLOCK; /* block stride */
        dv_priv_obs_xfree_avx2(rx, nf, ns, modal ? bs : 8u, modal ? DV_OBS_MODAL_BLOCK : nf, sv,
                               xl);
        return;
    }
    if (cubic && !modal && o->kern != DV_OBS_KERN_C) {
        dv_priv_obs_xfree_cubic_avx2(rx, m->rxu, nf, ns, sv, xl);
        return;
    }
    if (modal) { /* the portable kernel on the modal rows (a test's comparison) */
        for (size_t f = 0; f < nf; f++) {
            dv_real_t(*rb)[DV_OBS_MODAL_BLOCK] = o->modal_form->rx[f / DV_OBS_MODAL_BLOCK];
            const size_t l = f % DV_OBS_MODAL_BLOCK;
            dv_real_t a = rb[ns][l] * win[0] + rb[ns + 1u][l] * win[1];
            for (size_t j = 0; j < ns; j++) {
                a += rb[j][l] * sv[j];
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

/* gcc turns the short copy loops over the elements (nc <= DV_MAX_ELEM values) into memcpy and
 * memset calls, a call per node that cost a tenth of a two-contact simulation; kept as loops */
#if defined(__GNUC__) && !defined(__clang__)
#define DV_OBS_NO_LIBCALLS __attribute__((optimize("no-tree-loop-distribute-patterns")))
#else
#define DV_OBS_NO_LIBCALLS
#endif

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

/* dv_priv_obs_elem_forces() for one element (the common case), in the same order of
 * operations: the force-free part of X at every sub-node first (independent of the forces, so
 * it leaves the sequential chain through the nodes), then node by node the earlier forces and
 * the implicit force. */
DV_OBS_NO_LIBCALLS
static bool elem_forces_1(dv_obs_t *o, dv_real_t *sv, size_t ns)
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

/* Sub-node element forces g into sv[ns + nin ..], from x = sv[0..ns) and the input window
 * sv[ns .. ns + nin). Stick-slip elements read and advance the observer's element history.
 * True when every force is zero because every element stays open (all_open()). */
DV_OBS_NO_LIBCALLS
bool dv_priv_obs_elem_forces(dv_obs_t *o, dv_real_t *sv, size_t ns)
{
    const dv_model_t *m = o->m;
    const size_t nc = m->n_elem;
    if (nc == 1u) {
        return elem_forces_1(o, sv, ns);
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
            lin[e] = xl[f]; /* the earlier nodes' forces are in already (below) */
            /* start: as in elem_forces_1() */
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
        /* this node's forces into every later node's X, in the order a row dot from the first
         * node would add them (the same sums, bit for bit): the next node then waits for nc
         * products, not for a dot over every earlier node */
        for (size_t f = f0 + nc; f < nf; f++) {
            const dv_real_t *srow = m->smat + f * nf + f0;
            dv_real_t s = xl[f];
            for (size_t e = 0; e < nc; e++) {
                s += srow[e] * g[f0 + e];
            }
            xl[f] = s;
        }
    }
    for (size_t e = 0; e < nc; e++) {
        o->elem_x[e] = xp[e];
        o->elem_g[e] = gp[e];
    }
    return false;
}

void dv_priv_obs_first_forces_cubic(const dv_obs_t *o, dv_real_t *g)
{
    const dv_model_t *m = o->m;
    const size_t nc = m->n_elem;
    const dv_real_t *win = o->sv + o->ns;
    dv_real_t xs[2u * DV_MAX_DOF]; /* a state set away from rest may be in modal coordinates */
    dv_priv_obs_state_x(o, xs);
    for (size_t e = 0; e < nc; e++) {
        const dv_elem_desc_t *c = &m->elem[e];
        /* velocity laws: at rest, the ground's velocity at t0 is left out (first sample) */
        const bool vel = dv_priv_elem_on_velocity(c->law);
        const dv_real_t x = dv_priv_elem_arg(c, xs, m->n_dof) +
                            (vel ? DV_R(0.0) : m->elem_dx[e] * win[2]);
        /* history: at rest */
        g[e] = dv_priv_elem_force(c, dv_priv_elem_kh(c), o->elem_x[e], o->elem_g[e], x);
    }
}

/* AR(p): Yule-Walker (Levinson-Durbin) and Burg fits, order selection, streaming residual. */
#include "dynval/dv_ar.h"
#include "dv_priv.h"

/* ---- record preparation ---------------------------------------------------------------- */

/* y = x - mean. A non-finite sample shows up as a non-finite sum. */
static dv_status_t center(const dv_real_t *x, size_t n, dv_real_t *y, dv_real_t *mean,
                          uint32_t kern)
{
    const dv_real_t nn = (dv_real_t)n;
    dv_real_t mu = dv_priv_ar_sum(x, n, kern) / nn;
    if (!dv_priv_finite(mu)) {
        /* A sum can overflow with finite samples; look before blaming the data. */
        return DV_ENUMERIC;
    }
    dv_priv_ar_sub(x, n, mu, y, kern);
#ifndef DV_REAL_DOUBLE
    /* In float the first mean is off by ~n eps |mean|; one correction pass removes it. */
    const dv_real_t d = dv_priv_ar_sum(y, n, kern) / nn;
    for (size_t i = 0u; i < n; i++) {
        y[i] -= d;
    }
    mu += d;
#endif
    *mean = mu;
    return DV_OK;
}

/* A record whose spread is at round-off level of its offset carries no AR information. */
static bool is_constant(dv_real_t r0, dv_real_t mean)
{
    const dv_real_t floor2 = DV_R(16.0) * DV_REAL_EPS * DV_REAL_EPS * mean * mean;
    return !(r0 > DV_R(0.0)) || r0 <= floor2;
}

/* ---- the recursion shared by both estimators -------------------------------------------- */

/* Result of run(): coefficients of the highest valid order and per-order curves. */
typedef struct {
    uint32_t reached; /* highest valid order, 0..pmax */
    dv_real_t mean;
    dv_real_t r0;
} run_out_t;

/* v[0..n] <- v - k * reverse(v), in place: v[j] and v[n-j] are updated as a pair from their
 * old values (the step of every Levinson/Burg order update). */
static void reflect_update(dv_real_t *v, uint32_t n, dv_real_t k)
{
    uint32_t lo = 0u, hi = n;
    for (; lo < hi; lo++, hi--) {
        const dv_real_t vl = v[lo], vh = v[hi];
        v[lo] = vl - k * vh;
        v[hi] = vh - k * vl;
    }
    if (lo == hi) {
        v[lo] = v[lo] - k * v[lo];
    }
}

/* Order-update a <- [a - k * reverse(a), k] (m-1 -> m), in place. */
static void order_update(dv_real_t *a, uint32_t m, dv_real_t k)
{
    if (m >= 2u) {
        reflect_update(a, m - 2u, k);
    }
    a[m - 1u] = k;
}

/* Order m with reflection coefficient k, if valid (|k| < 1 and a positive error variance
 * err (1 - k^2)): the coefficients a order-updated, err, refl[m-1], sig[m-1] and ro->reached
 * set. False (nothing changed) otherwise: the recursion stops at the order before. */
static bool accept_order(dv_real_t k, uint32_t m, dv_real_t *err, dv_real_t *a, dv_real_t *refl,
                         dv_real_t *sig, run_out_t *ro)
{
    if (!(DV_FABS(k) < DV_R(1.0))) {
        return false;
    }
    const dv_real_t e2 = *err * (DV_R(1.0) - k * k);
    if (!(e2 > DV_R(0.0))) {
        return false;
    }
    order_update(a, m, k);
    *err = e2;
    refl[m - 1u] = k;
    sig[m - 1u] = e2;
    ro->reached = m;
    return true;
}

/* r[m] - sum_{j=1}^{m-1} a[j-1] r[m-j], four partial sums (one chain is latency-bound). */
static dv_real_t levinson_num(const dv_real_t *a, const dv_real_t *r, uint32_t m)
{
    dv_real_t s0 = DV_R(0.0), s1 = DV_R(0.0), s2 = DV_R(0.0), s3 = DV_R(0.0);
    uint32_t j = 1u;
    for (; j + 4u <= m; j += 4u) {
        s0 += a[j - 1u] * r[m - j];
        s1 += a[j] * r[m - j - 1u];
        s2 += a[j + 1u] * r[m - j - 2u];
        s3 += a[j + 2u] * r[m - j - 3u];
    }
    for (; j < m; j++) {
        s0 += a[j - 1u] * r[m - j];
    }
    return r[m] - ((s0 + s1) + (s2 + s3));
}

/* Burg by the lattice, two stages per sweep of the error arrays (they do not fit L1: the sweeps
 * are what costs). A sweep returns the new errors' lag-0 and lag-1 sums; stage m's reflection
 * coefficient comes from the lag-0 sums, stage m+1's from all seven through the one-stage update
 * written out (exact in exact arithmetic). y: the centred record, work[0..2n) (y first). */
static dv_status_t burg_lattice(uint32_t pmax, dv_real_t *work, size_t n, dv_real_t mean,
                                dv_real_t *ak, dv_real_t *refl, dv_real_t *sig, run_out_t *ro,
                                uint32_t kern)
{
    const dv_real_t nn = (dv_real_t)n;
    dv_real_t *y = work, *b = work + n;
    for (size_t i = 0u; i < n; i++) {
        b[i] = y[i];
    }
    const dv_real_t r0s = dv_priv_ar_dot(b, b, n, kern);
    const dv_real_t r0 = r0s / nn;
    ro->r0 = r0;
    ro->reached = 0u;
    if (!dv_priv_finite(r0) || is_constant(r0, mean)) {
        return DV_ENUMERIC;
    }
    const dv_real_t r1s = dv_priv_ar_dot(y, y + 1, n - 1u, kern);
    const dv_real_t r2s = n > 2u ? dv_priv_ar_dot(y, y + 2, n - 2u, kern) : DV_R(0.0);
    const dv_real_t y0 = b[0], y1 = b[1], yl = b[n - 1u], yl1 = b[n - 2u];
    /* order-0 errors: f[j] = y[j+1], b[j] = y[j], j < n-1; their seven sums from r0..r2 */
    dv_real_t sm[7];
    sm[0] = r0s - y0 * y0;
    sm[1] = r0s - yl * yl;
    sm[2] = r1s;
    sm[3] = r2s;
    sm[4] = r1s - y1 * y0;
    sm[5] = r1s - yl * yl1;
    sm[6] = r0s - y0 * y0 - yl * yl;
    dv_real_t *f = y;
    for (size_t i = 0u; i + 1u < n; i++) {
        f[i] = y[i + 1u];
    }
    size_t len = n - 1u;
    dv_real_t err = r0;
    for (uint32_t m = 1u; m <= pmax; m += 2u) {
        const dv_real_t den = sm[0] + sm[1];
        if (!(den > DV_R(0.0))) {
            break;
        }
        const dv_real_t k = DV_R(2.0) * sm[2] / den;
        if (!accept_order(k, m, &err, ak, refl, sig, ro) || m == pmax) {
            break;
        }
        /* stage m+1: sums of the stage-m errors f'[j] = f[j+1] - k b[j+1],
         * b'[j] = b[j] - k f[j], j < len-1, from the sums of f and b */
        const dv_real_t f0 = f[0], b0 = b[0], fl = f[len - 1u], bl = b[len - 1u];
        const dv_real_t num2 = sm[3] - k * (sm[4] + sm[5]) + k * k * sm[6];
        const dv_real_t den2 = (sm[0] - f0 * f0) - DV_R(2.0) * k * (sm[2] - f0 * b0) +
                               k * k * (sm[1] - b0 * b0) + (sm[1] - bl * bl) -
                               DV_R(2.0) * k * (sm[2] - bl * fl) + k * k * (sm[0] - fl * fl);
        if (!(den2 > DV_R(0.0))) {
            break;
        }
        const dv_real_t k2 = DV_R(2.0) * num2 / den2;
        if (!accept_order(k2, m + 1u, &err, ak, refl, sig, ro) || m + 1u == pmax) {
            break;
        }
        dv_priv_ar_burg2(f, b, len, k, k2, sm, kern);
        len -= 2u;
    }
    return DV_OK;
}

#ifdef DV_REAL_DOUBLE
/* Burg from the autocorrelation (the idea of K. Vos, "A fast implementation of Burg's method",
 * 2013; derived and written here as follows). Let y be zero outside 0..n-1 and c_0 = 1,
 * c_j = -a_j the order m-1 error filter; F(t) = sum_j c_j y(t-j) and B(t) = sum_j c_j
 * y(t-m+1+j) are its forward and backward errors at every t (zero far out). The lattice
 * F'(t) = F(t) - k B(t-1), B'(t) = B(t-1) - k F(t) holds at every t, and stage m sums over
 * t = m..n-1, so each of its sums is a sum over all t minus the edges t < m and t >= n:
 *   all t:  sum F(t)^2 = sum B(t-1)^2 = P = sum_j c_j u_j,  sum F(t) B(t-1) = X = sum_j c_j u_{m-j}
 * with u_i = sum_j c_j R_|i-j| (R: the autocorrelation sums). The order update c' = [c, 0] -
 * k [0, reverse(c)] gives u'_i = u_i - k u_{m-i}, i = 0..m, and u'_{m+1} = sum_j c_j R_{m+1-j}
 * - k sum_j c_j R_{j+1}: O(m) per stage. The edges are small lattices of their own: F(t), B(t-1)
 * for t < p on the record's head, and (time reversal swaps F and B) the same on the reversed
 * tail; O(p) per stage. So the O(n p) cost is one autocorrelation instead of p sweeps.
 *
 * The price is cancellation: P ~ den/2 comes out of terms of size (sum |c_j|)^2 R_0, so den
 * carries a relative error of about eps (sum |c_j|)^2 R_0 / den =: eps q_m, and so does k_m
 * (3-30 eps q_m, measured against a long-double lattice), and sigma2 = r_0 prod (1 - k_m^2) one
 * of about eps sum_m q_m 2 |k_m| / (1 - k_m^2) (0.5-6 eps times the sum, measured). For the
 * lightly damped structure at AR(60), q_m stays below ~1.1e4 and the sum below ~7e4 (errors
 * ~4e-12). The limits BURG_CORR_Q and BURG_CORR_QS2 keep both errors below ~3e-10; past them (a
 * nearly noise-free sinusoid, a mode with damping ratio ~3e-4 at AR(20)), or when a stage does not
 * give |k| < 1 and a positive error, the fit is handed to the lattice, which then decides.
 * Beyond 8192 samples both limits shrink like sqrt(8192 / n): the autocorrelation's round-off,
 * the larger part of these errors, grows about like that. */
#define BURG_CORR_Q DV_R(1e5)
#define BURG_CORR_QS2 DV_R(5e5)

/* Records shorter than this many samples per order go to the lattice (cheap there): the edge
 * lattices need 6 p - 2 elements of the workspace's second half. */
#define BURG_CORR_MIN_N_PER_P 6u

/* One lattice stage on an edge: f[t] = F(t), g[t] = B(t-1), t < len. */
static void edge_stage(dv_real_t *restrict f, dv_real_t *restrict g, uint32_t len, dv_real_t k)
{
    for (uint32_t t = 0u; t < len; t++) {
        const dv_real_t ft = f[t], gt = g[t];
        f[t] = ft - k * gt;
        g[t] = gt - k * ft;
    }
}

/* sq += sum f^2 + g^2, fg += sum f g over t < m */
static void edge_sums(const dv_real_t *f, const dv_real_t *g, uint32_t m, dv_real_t *sq,
                      dv_real_t *fg)
{
    dv_real_t s0 = DV_R(0.0), s1 = DV_R(0.0), c0 = DV_R(0.0), c1 = DV_R(0.0);
    uint32_t t = 0u;
    for (; t + 2u <= m; t += 2u) {
        s0 += f[t] * f[t] + g[t] * g[t];
        s1 += f[t + 1u] * f[t + 1u] + g[t + 1u] * g[t + 1u];
        c0 += f[t] * g[t];
        c1 += f[t + 1u] * g[t + 1u];
    }
    if (t < m) {
        s0 += f[t] * f[t] + g[t] * g[t];
        c0 += f[t] * g[t];
    }
    *sq += s0 + s1;
    *fg += c0 + c1;
}

/* Burg orders 1..p from the autocorrelation; false hands the fit to the lattice (nothing of it
 * is kept). small: 4 (p + 1) elements (R, c = ak, reverse(c), u); edge: 6 p - 2. */
static bool burg_corr(uint32_t p, const dv_real_t *y, size_t n, dv_real_t mean, dv_real_t *edge,
                      dv_real_t *small, dv_real_t *refl, dv_real_t *sig, run_out_t *ro,
                      uint32_t kern)
{
    dv_real_t *rs = small, *c = small + (p + 1u), *cr = small + 2u * (p + 1u);
    dv_real_t *u = small + 3u * (p + 1u);
    /* edges: F(t) at f[t], t < p; B(t-1) of order m-1 at g[t + p - m] (B(-1) = 0 at g[p-m]),
     * so that a stage updates f[t] and g[t + p - m] in place; g has 2p - 1 slots */
    dv_real_t *fy = edge, *gy = edge + p, *fz = gy + (2u * p - 1u), *gz = fz + p;
    dv_priv_ar_acf(y, n, p, rs, kern);
    const dv_real_t r0 = rs[0] / (dv_real_t)n;
    if (!dv_priv_finite(r0) || is_constant(r0, mean)) {
        return false;
    }
    for (uint32_t t = 0u; t < p; t++) {
        fy[t] = y[t];
        fz[t] = y[n - 1u - t];
        gy[t] = DV_R(0.0);
        gz[t] = DV_R(0.0);
    }
    for (uint32_t t = 0u; t + 1u < p; t++) {
        gy[p + t] = y[t];
        gz[p + t] = y[n - 1u - t];
    }
    c[0] = cr[0] = DV_R(1.0);
    u[0] = rs[0];
    u[1] = rs[1];
    const dv_real_t shrink = n > 8192u ? DV_SQRT(DV_R(8192.0) / (dv_real_t)n) : DV_R(1.0);
    const dv_real_t lim_q = BURG_CORR_Q * shrink, lim_qs2 = BURG_CORR_QS2 * shrink;
    dv_real_t sabs = DV_R(1.0), err = r0, qs2 = DV_R(0.0);
    for (uint32_t m = 1u; m <= p; m++) {
        const dv_real_t pq = dv_priv_ar_dot(c, u, m, kern);
        const dv_real_t xq = dv_priv_ar_dot(cr, u + 1, m, kern);
        dv_real_t esq = DV_R(0.0), efg = DV_R(0.0);
        edge_sums(fy, gy + (p - m), m, &esq, &efg);
        edge_sums(fz, gz + (p - m), m, &esq, &efg);
        const dv_real_t den = DV_R(2.0) * pq - esq, big = sabs * sabs * rs[0];
        if (!(den * lim_q > big)) {
            return false;
        }
        const dv_real_t k = DV_R(2.0) * (xq - efg) / den;
        if (!(DV_FABS(k) < DV_R(1.0))) {
            return false;
        }
        const dv_real_t omk2 = DV_R(1.0) - k * k, e2 = err * omk2;
        if (!(e2 > DV_R(0.0))) {
            return false;
        }
        qs2 += big * DV_R(2.0) * DV_FABS(k) / (den * omk2);
        if (!(qs2 < lim_qs2)) {
            return false;
        }
        err = e2;
        refl[m - 1u] = k;
        sig[m - 1u] = err;
        if (m < p) {
            const dv_real_t up = dv_priv_ar_dot(cr, rs + 2, m, kern);
            const dv_real_t um = dv_priv_ar_dot(c, rs + 1, m, kern);
            reflect_update(u, m, k);
            u[m + 1u] = up - k * um;
            edge_stage(fy, gy + (p - m), p, k);
            edge_stage(fz, gz + (p - m), p, k);
        }
        /* c' = [c, 0] - k [0, reverse(c)]: pairs (j, m-j) from their old values */
        c[m] = DV_R(0.0);
        reflect_update(c, m, k);
        sabs = DV_R(0.0);
        for (uint32_t j = 0u; j <= m; j++) {
            cr[j] = c[m - j];
            sabs += DV_FABS(c[j]);
        }
    }
    for (uint32_t j = 0u; j < p; j++) {
        c[j] = -c[j + 1u]; /* c becomes ak: a_j = -c_j */
    }
    ro->r0 = r0;
    ro->reached = p;
    return true;
}
#endif

/* Runs orders 1..pmax; stops at the first order whose reflection coefficient is not inside
 * (-1, 1) or whose error variance is not positive. a holds the last valid order's fit. */
static dv_status_t run(dv_ar_method_t method, uint32_t pmax, const dv_real_t *x, size_t n,
                       dv_real_t *work, dv_real_t *a, dv_real_t *refl, dv_real_t *sig,
                       run_out_t *ro)
{
    const uint32_t kern = dv_priv_simd_kern();
    const dv_real_t nn = (dv_real_t)n;
    dv_real_t *y = work;                 /* n: centred record (Burg: forward errors) */
    dv_real_t *small = work + 2u * n;    /* 4 (pmax + 1) */
    dv_real_t *r = small;                /* pmax + 1 autocorrelation values */
    dv_real_t *ak = small + (pmax + 1u); /* order-m coefficients in progress */
    dv_real_t mean;

    dv_status_t st = center(x, n, y, &mean, kern);
    if (st != DV_OK) {
        return st;
    }
    ro->mean = mean;
    ro->reached = 0u;

    if (method == DV_AR_YULE_WALKER) {
        dv_priv_ar_acf(y, n, pmax, r, kern);
        for (uint32_t k = 0u; k <= pmax; k++) {
            r[k] /= nn;
        }
        ro->r0 = r[0];
        if (!dv_priv_finite(r[0]) || !dv_priv_finite(r[pmax]) || is_constant(r[0], mean)) {
            return DV_ENUMERIC;
        }
        dv_real_t err = r[0];
        for (uint32_t m = 1u; m <= pmax; m++) {
            if (!accept_order(levinson_num(ak, r, m) / err, m, &err, ak, refl, sig, ro)) {
                break;
            }
        }
    } else {
        bool done = false;
#ifdef DV_REAL_DOUBLE
        /* float: burg_corr's cancellation would cost ~2e-4 on the structure at AR(60) (the
         * lattice: ~3e-6), so the lattice */
        if (n >= BURG_CORR_MIN_N_PER_P * (size_t)pmax) {
            done = burg_corr(pmax, y, n, mean, work + n, small, refl, sig, ro, kern);
        }
#endif
        if (!done) {
            st = burg_lattice(pmax, work, n, mean, ak, refl, sig, ro, kern);
            if (st != DV_OK) {
                return st;
            }
        }
    }
    for (uint32_t j = 0u; j < ro->reached; j++) {
        a[j] = ak[j];
    }
    return DV_OK;
}

static dv_status_t check_args(const void *out, dv_ar_method_t method, uint32_t p,
                              const dv_real_t *x, size_t n, const dv_real_t *work,
                              size_t work_len)
{
    if (out == NULL || x == NULL || work == NULL || p == 0u || p > DV_AR_MAX_ORDER || n < 2u ||
        (size_t)p >= n || n > (size_t)UINT32_MAX ||
        (method != DV_AR_YULE_WALKER && method != DV_AR_BURG)) {
        return DV_EINVAL;
    }
    if (work_len < DV_AR_WORK_LEN(n, p)) {
        return DV_ESIZE;
    }
    return DV_OK;
}

dv_status_t dv_ar_fit(dv_ar_model_t *m, dv_ar_method_t method, uint32_t p, const dv_real_t *x,
                      size_t n, dv_real_t *work, size_t work_len)
{
    dv_status_t st = check_args(m, method, p, x, n, work, work_len);
    if (st != DV_OK) {
        return st;
    }
    dv_real_t a[DV_AR_MAX_ORDER], refl[DV_AR_MAX_ORDER], sig[DV_AR_MAX_ORDER];
    run_out_t ro;
    st = run(method, p, x, n, work, a, refl, sig, &ro);
    if (st != DV_OK) {
        return st;
    }
    if (ro.reached < p) {
        return DV_ENUMERIC; /* deterministic (perfectly predictable) record at this order */
    }
    m->order = p;
    m->n = (uint32_t)n;
    m->mean = ro.mean;
    m->sigma2 = sig[p - 1u];
    for (uint32_t j = 0u; j < DV_AR_MAX_ORDER; j++) {
        m->a[j] = j < p ? a[j] : DV_R(0.0);
        m->refl[j] = j < p ? refl[j] : DV_R(0.0);
    }
    return DV_OK;
}

dv_status_t dv_ar_order(dv_ar_order_t *o, dv_ar_method_t method, uint32_t pmax,
                        const dv_real_t *x, size_t n, dv_real_t *work, size_t work_len)
{
    dv_status_t st = check_args(o, method, pmax, x, n, work, work_len);
    if (st != DV_OK) {
        return st;
    }
    dv_real_t a[DV_AR_MAX_ORDER], refl[DV_AR_MAX_ORDER], sig[DV_AR_MAX_ORDER];
    run_out_t ro;
    st = run(method, pmax, x, n, work, a, refl, sig, &ro);
    if (st != DV_OK) {
        return st;
    }
    if (ro.reached == 0u) {
        return DV_ENUMERIC;
    }
    const dv_real_t nn = (dv_real_t)n;
    const dv_real_t band = DV_R(2.0) / DV_SQRT(nn);
    o->pmax = ro.reached;
    o->n = (uint32_t)n;
    o->band = band;
    o->p_aic = 1u;
    o->p_pacf = 0u;
    for (uint32_t m = 1u; m <= DV_AR_MAX_ORDER; m++) {
        if (m > ro.reached) {
            o->aic[m - 1u] = o->pacf[m - 1u] = o->sigma2[m - 1u] = DV_R(0.0);
            continue;
        }
        const dv_real_t aic = nn * DV_LOG(sig[m - 1u]) + DV_R(2.0) * (dv_real_t)m;
        o->aic[m - 1u] = aic;
        o->pacf[m - 1u] = refl[m - 1u];
        o->sigma2[m - 1u] = sig[m - 1u];
        if (aic < o->aic[o->p_aic - 1u]) {
            o->p_aic = m;
        }
        if (DV_FABS(refl[m - 1u]) >= band) {
            o->p_pacf = m;
        }
    }
    return DV_OK;
}

dv_status_t dv_ar_autocorr(const dv_real_t *x, size_t n, size_t maxlag, dv_real_t *r)
{
    if (x == NULL || r == NULL || n == 0u || maxlag >= n) {
        return DV_EINVAL;
    }
    dv_priv_ar_acf(x, n, maxlag, r, dv_priv_simd_kern());
    const dv_real_t nn = (dv_real_t)n;
    dv_status_t st = DV_OK;
    for (size_t k = 0u; k <= maxlag; k++) {
        r[k] /= nn;
        if (!dv_priv_finite(r[k])) {
            st = DV_ENUMERIC;
        }
    }
    return st;
}

/* ---- streaming residual ------------------------------------------------------------------ */

/* Buffer layout (DV_AR_RESID_BUF_LEN): float [c: p][hist: p]; double [c part: p + 16][slack:
 * 8][hist: 2p], the coefficients a_p..a_1 after off zeros from a 64-byte boundary in the c
 * part, the slack zero (read by the vector kernels before hist[0]). The vector kernels
 * multiply the L = 8 nb + 4 coefficients ending at a_1 with the L samples ending at the newest:
 * the off = L - p extra taps are zero coefficients over older history or the slack. */

size_t dv_ar_resid_buf_len(uint32_t p)
{
    return p == 0u || p > DV_AR_MAX_ORDER ? 0u : DV_AR_RESID_BUF_LEN(p);
}

dv_status_t dv_ar_resid_init(dv_ar_resid_t *r, const dv_ar_model_t *m, dv_real_t *buf,
                             size_t buf_len)
{
    if (r == NULL || m == NULL || buf == NULL || m->order == 0u || m->order > DV_AR_MAX_ORDER) {
        return DV_EINVAL;
    }
    const uint32_t p = m->order;
    if (buf_len < DV_AR_RESID_BUF_LEN(p)) {
        return DV_ESIZE;
    }
    dv_real_t suma = DV_R(0.0);
    for (uint32_t j = 0u; j < p; j++) {
        if (!dv_priv_finite(m->a[j])) {
            return DV_ENUMERIC;
        }
        suma += m->a[j];
    }
    if (!dv_priv_finite(m->mean)) {
        return DV_ENUMERIC;
    }
    uint32_t nb = 0u, off = 0u, c_at = 0u;
    dv_real_t *hist = buf + p;
#if DV_AR_RESID_PAD > 0
    /* [c part: p + 16][slack: 8][hist: 2p]; c starts on a 64-byte boundary when buf allows */
    nb = p > 4u ? (p - 4u + 7u) / 8u : 0u;
    off = 8u * nb + 4u - p; /* 0..7 */
    c_at = (uint32_t)((64u - (uintptr_t)buf % 64u) % 64u / sizeof(dv_real_t)) % 8u;
    hist = buf + p + 24u;
#endif
    for (dv_real_t *z = buf; z < hist; z++) {
        *z = DV_R(0.0);
    }
    dv_real_t *c = buf + c_at; /* c[off + j] = a_{p-j}, j < p */
    for (uint32_t j = 0u; j < p; j++) {
        c[off + j] = m->a[p - 1u - j];
    }
    r->c = c;
    r->hist = hist;
    r->mean = m->mean;
    r->c0 = m->mean * (DV_R(1.0) - suma);
    r->p = p;
    r->nb = nb;
    r->off = off;
    r->kern = dv_priv_simd_kern();
    r->step = r->kern != 0u ? 9u * (r->kern - 1u) + nb : 0u;
    dv_ar_resid_reset(r);
    return DV_OK;
}

void dv_ar_resid_reset(dv_ar_resid_t *r)
{
    DV_ASSERT(r != NULL);
    for (size_t j = 0u; j < DV_AR_RESID_HIST_LEN(r->p); j++) {
        r->hist[j] = DV_R(0.0);
    }
    r->head = 0u;
    r->count = 0u;
    r->n_nonfinite = 0u;
}

/* The portable step (x finite); dv_priv_ar_rstep_* do the same around their vector kernels.
 * Kept out of line on x86 so that the dispatch below stays a few instructions + a tail jump. */
#if DV_SIMD_X86
__attribute__((noinline))
#endif
static dv_status_t rstep_c(dv_ar_resid_t *r, dv_real_t x, dv_real_t *e)
{
    const uint32_t p = r->p, head = r->head;
    dv_real_t *h = r->hist + head; /* the last p centred samples, oldest first from here */
    const dv_real_t y = x - r->mean;
    dv_status_t st = DV_ENOTREADY;
    if (r->count >= p) {
#ifdef DV_REAL_DOUBLE
        *e = y - dv_priv_ar_dot(r->c + r->off, h, p, 0u);
#else /* a ring: the oldest p - head samples, then the newest head */
        *e = y - (dv_priv_ar_dot(r->c, h, p - head, 0u) +
                  dv_priv_ar_dot(r->c + (p - head), r->hist, head, 0u));
#endif
        st = DV_OK;
    }
    h[0] = y;
#ifdef DV_REAL_DOUBLE
    h[p] = y;
#endif
    r->head = head + 1u == p ? 0u : head + 1u;
    r->count++;
    return st;
}

dv_status_t dv_ar_resid_update(dv_ar_resid_t *r, dv_real_t x, dv_real_t *e)
{
    DV_ASSERT(r != NULL && e != NULL);
    if (!dv_priv_finite(x)) {
        r->n_nonfinite++;
        return DV_ENUMERIC;
    }
#if DV_SIMD_X86
    if (r->kern != 0u) {
        return dv_priv_ar_rstep(r, x, e);
    }
#endif
    return rstep_c(r, x, e);
}

dv_status_t dv_ar_resid_update_block(dv_ar_resid_t *r, const dv_real_t *x, size_t n,
                                     dv_real_t *e, size_t *n_out)
{
    DV_ASSERT(r != NULL);
    if (n == 0u) {
        if (n_out != NULL) {
            *n_out = 0u;
        }
        return DV_OK;
    }
    if (x == NULL || e == NULL || n_out == NULL) {
        return DV_EINVAL;
    }
    const uint32_t p = r->p;
    bool finite = dv_priv_ar_all_finite(x, n, r->kern);
    size_t out = 0u, i = 0u;
    dv_status_t st = DV_OK;
    /* The block kernel folds the mean into c0 and filters the raw samples: exact enough in
     * double, but in float a large mean costs digits, so float with a mean goes sample-wise. */
#ifndef DV_REAL_DOUBLE
    finite = finite && r->mean == DV_R(0.0);
#endif
    if (!finite) {
        for (; i < n; i++) {
            const dv_status_t s1 = dv_ar_resid_update(r, x[i], e + out);
            if (s1 == DV_OK) {
                out++;
            } else if (s1 == DV_ENUMERIC) {
                st = DV_ENUMERIC;
            }
        }
        *n_out = out;
        return st;
    }
    /* Single updates until the block itself holds the p samples before each output. */
    for (; i < n && (i < p || r->count < p); i++) {
        if (dv_ar_resid_update(r, x[i], e + out) == DV_OK) {
            out++;
        }
    }
    if (i < n) {
        dv_priv_ar_fir(r->c + r->off, p, r->c0, x + i, n - i, e + out, r->kern);
        out += n - i;
        r->count += n - i;
        for (uint32_t j = 0u; j < p; j++) {
            const dv_real_t y = x[n - p + j] - r->mean;
            r->hist[j] = y;
#ifdef DV_REAL_DOUBLE
            r->hist[j + p] = y;
#endif
        }
        r->head = 0u;
    }
    *n_out = out;
    return st;
}

uint64_t dv_ar_resid_nonfinite(const dv_ar_resid_t *r)
{
    return r == NULL ? 0u : r->n_nonfinite;
}

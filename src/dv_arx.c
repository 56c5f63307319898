/* ARX / AR-ARX least squares (sequential Givens QR) and the streaming ARX residual. */
#include "dynval/dv_arx.h"
#include "dv_priv.h"

/* ---- sequential least squares ------------------------------------------------------------- */

dv_status_t dv_lsq_init(dv_lsq_t *s, uint32_t q, dv_real_t *buf, size_t buf_len)
{
    if (s == NULL || buf == NULL || q == 0u || q > DV_LSQ_MAX_PARAMS) {
        return DV_EINVAL;
    }
    if (buf_len < DV_LSQ_BUF_LEN(q)) {
        return DV_ESIZE;
    }
    s->q = q;
    s->R = buf;
    s->z = buf + (size_t)q * q;
    s->cn = s->z + q;
    s->w = s->cn + q;
    dv_lsq_reset(s);
    return DV_OK;
}

void dv_lsq_reset(dv_lsq_t *s)
{
    DV_ASSERT(s != NULL);
    const size_t q = s->q;
    for (size_t i = 0u; i < q * q; i++) {
        s->R[i] = DV_R(0.0);
    }
    for (size_t i = 0u; i < q; i++) {
        s->z[i] = DV_R(0.0);
        s->cn[i] = DV_R(0.0);
    }
    s->rss = DV_R(0.0);
    s->rows = 0u;
    s->n_nonfinite = 0u;
}

/* sqrt(a^2 + b^2) without overflow or underflow of the squares. */
static dv_real_t hyp(dv_real_t a, dv_real_t b)
{
    a = DV_FABS(a);
    b = DV_FABS(b);
    const dv_real_t big = a > b ? a : b;
    const dv_real_t sml = a > b ? b : a;
    if (big == DV_R(0.0)) {
        return DV_R(0.0);
    }
    const dv_real_t t = sml / big;
    return big * DV_SQRT(DV_R(1.0) + t * t);
}

dv_status_t dv_lsq_update(dv_lsq_t *s, const dv_real_t *a, dv_real_t y)
{
    DV_ASSERT(s != NULL && a != NULL);
    const uint32_t q = s->q;
    bool ok = dv_priv_finite(y);
    for (uint32_t j = 0u; j < q; j++) {
        ok = ok && dv_priv_finite(a[j]);
    }
    if (!ok) {
        s->n_nonfinite++;
        return DV_ENUMERIC;
    }
    dv_real_t *w = s->w;
    for (uint32_t j = 0u; j < q; j++) {
        w[j] = a[j];
        s->cn[j] += a[j] * a[j];
    }
    dv_real_t wy = y;
    for (uint32_t j = 0u; j < q; j++) {
        if (w[j] == DV_R(0.0)) {
            continue;
        }
        dv_real_t *Rj = s->R + (size_t)j * q;
        const dv_real_t rr = hyp(Rj[j], w[j]);
        const dv_real_t c = Rj[j] / rr, sn = w[j] / rr;
        Rj[j] = rr;
        for (uint32_t k = j + 1u; k < q; k++) {
            const dv_real_t t = Rj[k];
            Rj[k] = c * t + sn * w[k];
            w[k] = c * w[k] - sn * t;
        }
        const dv_real_t t = s->z[j];
        s->z[j] = c * t + sn * wy;
        wy = c * wy - sn * t;
    }
    s->rss += wy * wy;
    s->rows++;
    return DV_OK;
}

dv_status_t dv_lsq_get(const dv_lsq_t *s, dv_real_t *theta, dv_real_t *rss, dv_real_t *rcond)
{
    if (s == NULL || theta == NULL) {
        return DV_EINVAL;
    }
    const uint32_t q = s->q;
    if (s->rows < q) {
        return DV_ENOTREADY;
    }
    const dv_real_t tol = DV_R(10.0) * (dv_real_t)q * DV_REAL_EPS;
    dv_real_t dmin = DV_REAL_MAX, dmax = DV_R(0.0);
    for (uint32_t j = 0u; j < q; j++) {
        const dv_real_t d = DV_FABS(s->R[(size_t)j * q + j]);
        const dv_real_t cn = DV_SQRT(s->cn[j]);
        if (!(d > tol * cn)) {
            return DV_ENUMERIC;
        }
        const dv_real_t rel = d / cn;
        dmin = rel < dmin ? rel : dmin;
        dmax = rel > dmax ? rel : dmax;
    }
    /* Back substitution into w (scratch) first, so theta stays untouched on failure. */
    dv_real_t *t = s->w;
    for (uint32_t jj = q; jj-- > 0u;) {
        const dv_real_t *Rj = s->R + (size_t)jj * q;
        dv_real_t acc = s->z[jj];
        for (uint32_t k = jj + 1u; k < q; k++) {
            acc -= Rj[k] * t[k];
        }
        t[jj] = acc / Rj[jj];
        if (!dv_priv_finite(t[jj])) {
            return DV_ENUMERIC;
        }
    }
    for (uint32_t j = 0u; j < q; j++) {
        theta[j] = t[j];
    }
    if (rss != NULL) {
        *rss = s->rss;
    }
    if (rcond != NULL) {
        *rcond = dmin / dmax;
    }
    return DV_OK;
}

/* ---- ARX ---------------------------------------------------------------------------------- */

static bool cfg_ok(const dv_arx_cfg_t *c)
{
    return c->na <= DV_AR_MAX_ORDER && c->nb <= DV_AR_MAX_ORDER && c->nk <= DV_AR_MAX_ORDER &&
           c->na + c->nb >= 1u;
}

static size_t first_row(const dv_arx_cfg_t *c)
{
    const size_t lf = c->nb > 0u ? (size_t)c->nk + c->nb - 1u : 0u;
    return (size_t)c->na > lf ? (size_t)c->na : lf;
}

dv_status_t dv_arx_fit(dv_arx_model_t *m, const dv_arx_cfg_t *cfg, const dv_real_t *x,
                       const dv_real_t *f, size_t n, dv_real_t *work, size_t work_len)
{
    if (m == NULL || cfg == NULL || x == NULL || work == NULL || !cfg_ok(cfg) ||
        (cfg->nb > 0u && f == NULL)) {
        return DV_EINVAL;
    }
    const uint32_t na = cfg->na, nb = cfg->nb, nk = cfg->nk, q = na + nb;
    const size_t i0 = first_row(cfg);
    if (n <= i0 || n - i0 < q || n > (size_t)UINT32_MAX) {
        return DV_EINVAL;
    }
    if (work_len < DV_ARX_WORK_LEN(na, nb)) {
        return DV_ESIZE;
    }
    for (size_t i = 0u; i < n; i++) {
        if (!dv_priv_finite(x[i]) || (nb > 0u && !dv_priv_finite(f[i]))) {
            return DV_ENUMERIC;
        }
    }
    dv_lsq_t ls;
    (void)dv_lsq_init(&ls, q, work, DV_LSQ_BUF_LEN(q));
    dv_real_t *row = work + DV_LSQ_BUF_LEN(q);
    for (size_t i = i0; i < n; i++) {
        for (uint32_t j = 0u; j < na; j++) {
            row[j] = x[i - 1u - j];
        }
        for (uint32_t t = 0u; t < nb; t++) {
            row[na + t] = f[i - nk - t];
        }
        (void)dv_lsq_update(&ls, row, x[i]);
    }
    dv_real_t rss, rcond;
    const dv_status_t st = dv_lsq_get(&ls, row, &rss, &rcond);
    if (st != DV_OK) {
        return st == DV_ENOTREADY ? DV_EINVAL : st;
    }
    m->na = na;
    m->nb = nb;
    m->nk = nk;
    m->n_rows = (uint32_t)(n - i0);
    for (uint32_t j = 0u; j < DV_AR_MAX_ORDER; j++) {
        m->alpha[j] = j < na ? row[j] : DV_R(0.0);
        m->beta[j] = j < nb ? row[na + j] : DV_R(0.0);
    }
    m->sigma2 = rss / (dv_real_t)(n - i0);
    m->rcond = rcond;
    return DV_OK;
}

dv_status_t dv_ararx_fit(dv_arx_model_t *m, dv_ar_model_t *ar, const dv_arx_cfg_t *cfg,
                         uint32_t p, const dv_real_t *x, size_t n, dv_real_t *work,
                         size_t work_len)
{
    if (m == NULL || cfg == NULL || x == NULL || work == NULL || !cfg_ok(cfg) || p == 0u ||
        p > DV_AR_MAX_ORDER || (size_t)p >= n || p < cfg->na + cfg->nb) {
        return DV_EINVAL;
    }
    if (work_len < DV_ARARX_WORK_LEN(n, p, cfg->na, cfg->nb)) {
        return DV_ESIZE;
    }
    dv_ar_model_t a1;
    dv_status_t st = dv_ar_fit(&a1, DV_AR_YULE_WALKER, p, x, n, work, work_len);
    if (st != DV_OK) {
        return st;
    }
    /* e[i] (i >= p) from the raw record with the mean folded into c0; xc = centred record. */
    dv_real_t *e = work, *xc = work + n;
    dv_real_t suma = DV_R(0.0), crev[DV_AR_MAX_ORDER];
    for (uint32_t j = 0u; j < p; j++) {
        suma += a1.a[j];
        crev[p - 1u - j] = a1.a[j];
    }
    dv_priv_ar_fir(crev, p, a1.mean * (DV_R(1.0) - suma), x + p, n - p, e + p,
                   dv_priv_simd_kern());
    for (size_t i = 0u; i < n; i++) {
        xc[i] = x[i] - a1.mean;
    }
    dv_arx_model_t m2;
    st = dv_arx_fit(&m2, cfg, xc + p, e + p, n - p, work + 2u * n, work_len - 2u * n);
    if (st != DV_OK) {
        return st;
    }
    *m = m2;
    if (ar != NULL) {
        *ar = a1;
    }
    return DV_OK;
}

/* ---- streaming ARX residual --------------------------------------------------------------- */

dv_status_t dv_arx_resid_init(dv_arx_resid_t *r, const dv_arx_model_t *m, dv_real_t *buf,
                              size_t buf_len)
{
    if (r == NULL || m == NULL || buf == NULL) {
        return DV_EINVAL;
    }
    const dv_arx_cfg_t c = {m->na, m->nb, m->nk};
    if (!cfg_ok(&c)) {
        return DV_EINVAL;
    }
    if (buf_len < DV_ARX_RESID_BUF_LEN(m->na, m->nb, m->nk)) {
        return DV_ESIZE;
    }
    for (uint32_t j = 0u; j < DV_AR_MAX_ORDER; j++) {
        if ((j < m->na && !dv_priv_finite(m->alpha[j])) ||
            (j < m->nb && !dv_priv_finite(m->beta[j]))) {
            return DV_ENUMERIC;
        }
    }
    for (uint32_t j = 0u; j < DV_AR_MAX_ORDER; j++) {
        r->ca[j] = j < m->na ? m->alpha[m->na - 1u - j] : DV_R(0.0);
        r->cb[j] = j < m->nb ? m->beta[m->nb - 1u - j] : DV_R(0.0);
    }
    r->na = m->na;
    r->nb = m->nb;
    r->lf = m->nb + m->nk;
    r->hx = buf;
    r->hf = buf + 2u * (size_t)m->na;
    r->kern = dv_priv_simd_kern();
    dv_arx_resid_reset(r);
    return DV_OK;
}

void dv_arx_resid_reset(dv_arx_resid_t *r)
{
    DV_ASSERT(r != NULL);
    for (uint32_t j = 0u; j < 2u * r->na; j++) {
        r->hx[j] = DV_R(0.0);
    }
    for (uint32_t j = 0u; j < 2u * r->lf; j++) {
        r->hf[j] = DV_R(0.0);
    }
    r->hx_head = r->hf_head = 0u;
    r->count = 0u;
    r->n_nonfinite = 0u;
}

dv_status_t dv_arx_resid_update(dv_arx_resid_t *r, dv_real_t x, dv_real_t f, dv_real_t *e)
{
    DV_ASSERT(r != NULL && e != NULL);
    if (!dv_priv_finite(x) || !dv_priv_finite(f)) {
        r->n_nonfinite++;
        return DV_ENUMERIC;
    }
    const uint32_t na = r->na, lf = r->lf;
    if (lf > 0u) {
        r->hf[r->hf_head] = f;
        r->hf[r->hf_head + lf] = f;
        r->hf_head = r->hf_head + 1u == lf ? 0u : r->hf_head + 1u;
    }
    const uint64_t need = na > (lf > 0u ? lf - 1u : 0u) ? na : (lf > 0u ? lf - 1u : 0u);
    dv_status_t st = DV_ENOTREADY;
    if (r->count >= need) {
        /* hf[head .. head+lf-1]: f_{i-lf+1} .. f_i; the first nb carry lags nk+nb-1 .. nk. */
        dv_real_t pred = DV_R(0.0);
        if (na > 0u) {
            pred += dv_priv_ar_dot(r->ca, r->hx + r->hx_head, na, r->kern);
        }
        if (r->nb > 0u) {
            pred += dv_priv_ar_dot(r->cb, r->hf + r->hf_head, r->nb, r->kern);
        }
        *e = x - pred;
        st = DV_OK;
    }
    if (na > 0u) {
        r->hx[r->hx_head] = x;
        r->hx[r->hx_head + na] = x;
        r->hx_head = r->hx_head + 1u == na ? 0u : r->hx_head + 1u;
    }
    r->count++;
    return st;
}

uint64_t dv_arx_resid_nonfinite(const dv_arx_resid_t *r)
{
    return r == NULL ? 0u : r->n_nonfinite;
}

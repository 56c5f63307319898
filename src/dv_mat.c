/* Small dense matrix kernels used at init by the model and the observer. */
#include "dynval/dv_mat.h"
#include "dv_priv.h"

#define EL(m, i, j) ((m)->data[(size_t)(i) * (m)->cols + (size_t)(j)])

static bool mat_ok(const dv_mat_t *a)
{
    return a != NULL && a->data != NULL && a->rows > 0u && a->cols > 0u;
}

dv_status_t dv_mat_mul(const dv_mat_t *a, const dv_mat_t *b, dv_mat_t *c)
{
    if (!mat_ok(a) || !mat_ok(b) || !mat_ok(c) || a->cols != b->rows || c->rows != a->rows ||
        c->cols != b->cols) {
        return DV_EINVAL;
    }
    for (size_t i = 0; i < a->rows; i++) {
        for (size_t j = 0; j < b->cols; j++) {
            EL(c, i, j) = DV_R(0.0);
        }
        for (size_t k = 0; k < a->cols; k++) {
            const dv_real_t aik = EL(a, i, k);
            for (size_t j = 0; j < b->cols; j++) {
                EL(c, i, j) += aik * EL(b, k, j);
            }
        }
    }
    return DV_OK;
}

dv_status_t dv_mat_solve(dv_mat_t *a, dv_mat_t *b)
{
    if (!mat_ok(a) || !mat_ok(b) || a->rows != a->cols || b->rows != a->rows) {
        return DV_EINVAL;
    }
    const size_t n = a->rows;
    const size_t m = b->cols;
    dv_real_t amax = DV_R(0.0);
    for (size_t i = 0; i < n * n; i++) {
        const dv_real_t v = DV_FABS(a->data[i]);
        amax = v > amax ? v : amax;
    }
    const dv_real_t tiny = (dv_real_t)n * DV_REAL_EPS * amax;
    if (!(amax > DV_R(0.0))) {
        return DV_EUNSTABLE;
    }
    for (size_t k = 0; k < n; k++) {
        size_t p = k;
        dv_real_t best = DV_FABS(EL(a, k, k));
        for (size_t i = k + 1; i < n; i++) {
            const dv_real_t v = DV_FABS(EL(a, i, k));
            if (v > best) {
                best = v;
                p = i;
            }
        }
        if (!(best > tiny)) {
            return DV_EUNSTABLE;
        }
        if (p != k) {
            for (size_t j = 0; j < n; j++) {
                const dv_real_t t = EL(a, k, j);
                EL(a, k, j) = EL(a, p, j);
                EL(a, p, j) = t;
            }
            for (size_t j = 0; j < m; j++) {
                const dv_real_t t = EL(b, k, j);
                EL(b, k, j) = EL(b, p, j);
                EL(b, p, j) = t;
            }
        }
        const dv_real_t inv = DV_R(1.0) / EL(a, k, k);
        for (size_t i = k + 1; i < n; i++) {
            const dv_real_t f = EL(a, i, k) * inv;
            if (f == DV_R(0.0)) {
                continue;
            }
            for (size_t j = k; j < n; j++) {
                EL(a, i, j) -= f * EL(a, k, j);
            }
            for (size_t j = 0; j < m; j++) {
                EL(b, i, j) -= f * EL(b, k, j);
            }
        }
    }
    for (size_t kk = n; kk-- > 0;) {
        const dv_real_t inv = DV_R(1.0) / EL(a, kk, kk);
        for (size_t j = 0; j < m; j++) {
            dv_real_t s = EL(b, kk, j);
            for (size_t i = kk + 1; i < n; i++) {
                s -= EL(a, kk, i) * EL(b, i, j);
            }
            EL(b, kk, j) = s * inv;
        }
    }
    return DV_OK;
}

/* ---- eigenvalues of a general matrix ------------------------------------------------- */

/* Householder vector of x[0..m): P = I - beta v v^T with P x = alpha e1, v written over x.
 * Returns beta (0 when x is 0: P = I). */
static dv_real_t house(dv_real_t *x, size_t m)
{
    dv_real_t sc = DV_R(0.0);
    for (size_t i = 0; i < m; i++) {
        sc += DV_FABS(x[i]);
    }
    if (sc == DV_R(0.0)) {
        return DV_R(0.0);
    }
    dv_real_t nrm2 = DV_R(0.0);
    for (size_t i = 0; i < m; i++) {
        x[i] /= sc; /* scaled: no overflow or underflow in the squares */
        nrm2 += x[i] * x[i];
    }
    const dv_real_t nrm = DV_SQRT(nrm2);
    const dv_real_t alpha = x[0] >= DV_R(0.0) ? -nrm : nrm;
    const dv_real_t vv = nrm2 - alpha * x[0]; /* |x - alpha e1|^2 / 2, alpha^2 = |x|^2 */
    x[0] -= alpha;
    return vv > DV_R(0.0) ? DV_R(1.0) / vv : DV_R(0.0);
}

/* H = P H on rows r0..r0+m-1, columns c0..c1 (inclusive); H = H P on columns r0..r0+m-1,
 * rows q0..q1. P = I - beta v v^T. h is n x n row-major. */
static void reflect_rows(dv_real_t *h, size_t n, const dv_real_t *v, size_t m, dv_real_t beta,
                         size_t r0, size_t c0, size_t c1)
{
    for (size_t j = c0; j <= c1; j++) {
        dv_real_t d = DV_R(0.0);
        for (size_t i = 0; i < m; i++) {
            d += v[i] * h[(r0 + i) * n + j];
        }
        d *= beta;
        for (size_t i = 0; i < m; i++) {
            h[(r0 + i) * n + j] -= d * v[i];
        }
    }
}

static void reflect_cols(dv_real_t *h, size_t n, const dv_real_t *v, size_t m, dv_real_t beta,
                         size_t r0, size_t q0, size_t q1)
{
    for (size_t i = q0; i <= q1; i++) {
        dv_real_t d = DV_R(0.0);
        for (size_t k = 0; k < m; k++) {
            d += h[i * n + r0 + k] * v[k];
        }
        d *= beta;
        for (size_t k = 0; k < m; k++) {
            h[i * n + r0 + k] -= d * v[k];
        }
    }
}

/* Eigenvalues of [[a, b], [c, d]]. */
static void eig2(dv_real_t a, dv_real_t b, dv_real_t c, dv_real_t d, dv_real_t *wr, dv_real_t *wi)
{
    const dv_real_t mid = DV_R(0.5) * (a + d);
    const dv_real_t p = DV_R(0.5) * (a - d);
    const dv_real_t disc = p * p + b * c;
    if (disc >= DV_R(0.0)) {
        const dv_real_t sq = DV_SQRT(disc);
        wr[0] = mid + sq;
        wr[1] = mid - sq;
        wi[0] = wi[1] = DV_R(0.0);
    } else {
        wr[0] = wr[1] = mid;
        wi[0] = DV_SQRT(-disc);
        wi[1] = -wi[0];
    }
}

/* One Francis double-shift step on the unreduced window [l, hi] of the Hessenberg h
 * (hi >= l + 2); only the window is updated (all the eigenvalues need). its: iterations on
 * this window so far (an exceptional shift at 10 and 20). */
static void francis(dv_real_t *h, size_t n, size_t l, size_t hi, uint32_t its)
{
#define H(i, j) h[(size_t)(i) * n + (size_t)(j)]
    const size_t m = hi - 1u;
    dv_real_t s = H(m, m) + H(hi, hi);
    dv_real_t t = H(m, m) * H(hi, hi) - H(m, hi) * H(hi, m);
    if (its == 10u || its == 20u) {
        const dv_real_t e = DV_FABS(H(hi, m)) + DV_FABS(H(m, m - 1u));
        s = DV_R(1.5) * e;
        t = e * e;
    }
    dv_real_t v[3];
    v[0] = H(l, l) * H(l, l) + H(l, l + 1u) * H(l + 1u, l) - s * H(l, l) + t;
    v[1] = H(l + 1u, l) * (H(l, l) + H(l + 1u, l + 1u) - s);
    v[2] = H(l + 1u, l) * H(l + 2u, l + 1u);
    for (size_t k = l; k + 2u <= hi; k++) {
        const dv_real_t beta = house(v, 3u);
        const size_t q = k > l ? k - 1u : l;
        reflect_rows(h, n, v, 3u, beta, k, q, hi);
        reflect_cols(h, n, v, 3u, beta, k, l, k + 3u < hi ? k + 3u : hi);
        v[0] = H(k + 1u, k);
        v[1] = H(k + 2u, k);
        v[2] = k + 3u <= hi ? H(k + 3u, k) : DV_R(0.0);
    }
    const dv_real_t beta = house(v, 2u);
    reflect_rows(h, n, v, 2u, beta, m, m - 1u, hi);
    reflect_cols(h, n, v, 2u, beta, m, l, hi);
#undef H
}

dv_status_t dv_mat_eig_real(const dv_mat_t *a, dv_real_t *wr, dv_real_t *wi, dv_real_t *work,
                            size_t len)
{
    if (!mat_ok(a) || a->rows != a->cols || wr == NULL || wi == NULL || work == NULL) {
        return DV_EINVAL;
    }
    const size_t n = a->rows;
    if (len < DV_MAT_EIGR_WORK_LEN(n)) {
        return DV_ESIZE;
    }
    dv_real_t *h = work;
    dv_real_t *v = work + n * n;
    dv_real_t norm = DV_R(0.0);
    for (size_t i = 0; i < n * n; i++) {
        if (!dv_priv_finite(a->data[i])) {
            return DV_ENUMERIC;
        }
        h[i] = a->data[i];
        norm += DV_FABS(h[i]);
    }
    /* upper Hessenberg form: zeros below the first subdiagonal, column by column */
    for (size_t k = 0; k + 2u < n; k++) {
        const size_t m = n - k - 1u;
        for (size_t i = 0; i < m; i++) {
            v[i] = h[(k + 1u + i) * n + k];
        }
        const dv_real_t beta = house(v, m);
        if (beta != DV_R(0.0)) {
            reflect_rows(h, n, v, m, beta, k + 1u, k, n - 1u);
            reflect_cols(h, n, v, m, beta, k + 1u, 0u, n - 1u);
        }
        for (size_t i = k + 2u; i < n; i++) {
            h[i * n + k] = DV_R(0.0);
        }
    }
    /* QR iteration on the trailing unreduced window, deflating 1 x 1 and 2 x 2 blocks */
    size_t hi = n - 1u;
    uint32_t its = 0u;
    for (;;) {
        size_t l = hi;
        while (l > 0u) {
            dv_real_t sd = DV_FABS(h[(l - 1u) * n + l - 1u]) + DV_FABS(h[l * n + l]);
            if (sd == DV_R(0.0)) {
                sd = norm;
            }
            if (DV_FABS(h[l * n + l - 1u]) <= DV_REAL_EPS * sd) {
                h[l * n + l - 1u] = DV_R(0.0);
                break;
            }
            l--;
        }
        if (l == hi) {
            wr[hi] = h[hi * n + hi];
            wi[hi] = DV_R(0.0);
        } else if (l + 1u == hi) {
            eig2(h[l * n + l], h[l * n + hi], h[hi * n + l], h[hi * n + hi], wr + l, wi + l);
        } else {
            if (++its > DV_MAT_QR_MAX_ITER) {
                return DV_EUNSTABLE;
            }
            francis(h, n, l, hi, its);
            continue;
        }
        its = 0u;
        if (l == 0u) {
            return DV_OK;
        }
        hi = l - 1u;
    }
}

/* ---- eigen-solution of a symmetric matrix (cyclic Jacobi) -------------------------- */

/* Sum of squares of the strict upper triangle of a: what the Jacobi sweeps drive to zero. */
static dv_real_t off_diag_sq(const dv_mat_t *a)
{
    const size_t n = a->rows;
    dv_real_t off = DV_R(0.0);
    for (size_t p = 0; p < n; p++) {
        for (size_t q = p + 1; q < n; q++) {
            off += EL(a, p, q) * EL(a, p, q);
        }
    }
    return off;
}

/* One Jacobi rotation in the (p, q) plane: a = J^T a J zeroes a[p][q] (a no-op if it is
 * zero already), and the eigenvector estimate v = v J. */
static void jacobi_rotate(dv_mat_t *a, dv_mat_t *v, size_t p, size_t q)
{
    const size_t n = a->rows;
    const dv_real_t apq = EL(a, p, q);
    if (apq == DV_R(0.0)) {
        return;
    }
    /* Rutishauser's stable rotation: t = sgn(theta) / (|theta| + sqrt(theta^2+1)) */
    const dv_real_t theta = (EL(a, q, q) - EL(a, p, p)) / (DV_R(2.0) * apq);
    dv_real_t t = DV_R(1.0) / (DV_FABS(theta) + DV_SQRT(theta * theta + DV_R(1.0)));
    if (theta < DV_R(0.0)) {
        t = -t;
    }
    const dv_real_t c = DV_R(1.0) / DV_SQRT(t * t + DV_R(1.0));
    const dv_real_t sn = t * c;
    for (size_t k = 0; k < n; k++) {
        const dv_real_t akp = EL(a, k, p);
        const dv_real_t akq = EL(a, k, q);
        EL(a, k, p) = c * akp - sn * akq;
        EL(a, k, q) = sn * akp + c * akq;
    }
    for (size_t k = 0; k < n; k++) {
        const dv_real_t apk = EL(a, p, k);
        const dv_real_t aqk = EL(a, q, k);
        EL(a, p, k) = c * apk - sn * aqk;
        EL(a, q, k) = sn * apk + c * aqk;
    }
    EL(a, p, q) = DV_R(0.0);
    EL(a, q, p) = DV_R(0.0);
    for (size_t k = 0; k < n; k++) {
        const dv_real_t vkp = EL(v, k, p);
        const dv_real_t vkq = EL(v, k, q);
        EL(v, k, p) = c * vkp - sn * vkq;
        EL(v, k, q) = sn * vkp + c * vkq;
    }
}

dv_status_t dv_mat_eig_sym(const dv_mat_t *s, dv_real_t *w, dv_mat_t *v, dv_real_t *work,
                           size_t len)
{
    if (!mat_ok(s) || w == NULL || !mat_ok(v) || work == NULL || s->rows != s->cols ||
        v->rows != s->rows || v->cols != s->cols) {
        return DV_EINVAL;
    }
    const size_t n = s->rows;
    if (len < DV_MAT_EIG_WORK_LEN(n)) {
        return DV_ESIZE;
    }
    dv_mat_t a = {s->rows, s->cols, work};
    dv_real_t scale = DV_R(0.0);
    for (size_t i = 0; i < n; i++) {
        for (size_t j = 0; j < n; j++) {
            const dv_real_t x = i <= j ? EL(s, i, j) : EL(s, j, i);
            if (!dv_priv_finite(x)) {
                return DV_ENUMERIC;
            }
            EL(&a, i, j) = x;
            EL(v, i, j) = i == j ? DV_R(1.0) : DV_R(0.0);
            scale = DV_FABS(x) > scale ? DV_FABS(x) : scale;
        }
    }
    bool converged = false;
    for (uint32_t sweep = 0; sweep < DV_MAT_JACOBI_MAX_SWEEPS && !converged; sweep++) {
        const dv_real_t off = off_diag_sq(&a);
        if (off <= DV_REAL_EPS * DV_REAL_EPS * scale * scale * DV_R(1e-4) || scale == DV_R(0.0)) {
            converged = true;
            break;
        }
        for (size_t p = 0; p < n; p++) {
            for (size_t q = p + 1; q < n; q++) {
                jacobi_rotate(&a, v, p, q);
            }
        }
    }
    if (!converged) {
        /* one more test after the last sweep */
        const dv_real_t off = off_diag_sq(&a);
        if (off > DV_REAL_EPS * scale * scale) {
            return DV_EUNSTABLE;
        }
    }
    for (size_t i = 0; i < n; i++) {
        w[i] = EL(&a, i, i);
    }
    /* selection sort, ascending, carrying the columns of v */
    for (size_t i = 0; i + 1 < n; i++) {
        size_t k = i;
        for (size_t j = i + 1; j < n; j++) {
            if (w[j] < w[k]) {
                k = j;
            }
        }
        if (k != i) {
            const dv_real_t t = w[i];
            w[i] = w[k];
            w[k] = t;
            for (size_t r = 0; r < n; r++) {
                const dv_real_t x = EL(v, r, i);
                EL(v, r, i) = EL(v, r, k);
                EL(v, r, k) = x;
            }
        }
    }
    for (size_t j = 0; j < n; j++) {
        size_t big = 0;
        for (size_t r = 1; r < n; r++) {
            if (DV_FABS(EL(v, r, j)) > DV_FABS(EL(v, big, j))) {
                big = r;
            }
        }
        if (EL(v, big, j) < DV_R(0.0)) {
            for (size_t r = 0; r < n; r++) {
                EL(v, r, j) = -EL(v, r, j);
            }
        }
    }
    return DV_OK;
}

/* c = a * b for n x n blocks of raw storage (no aliasing). */
static void sq_mul(size_t n, const dv_real_t *a, const dv_real_t *b, dv_real_t *c)
{
    for (size_t i = 0; i < n; i++) {
        dv_real_t *ci = c + i * n;
        for (size_t j = 0; j < n; j++) {
            ci[j] = DV_R(0.0);
        }
        for (size_t k = 0; k < n; k++) {
            const dv_real_t aik = a[i * n + k];
            const dv_real_t *bk = b + k * n;
            for (size_t j = 0; j < n; j++) {
                ci[j] += aik * bk[j];
            }
        }
    }
}

dv_status_t dv_mat_expm(const dv_mat_t *a, dv_mat_t *e, dv_real_t *work, size_t len)
{
    if (!mat_ok(a) || !mat_ok(e) || work == NULL || a->rows != a->cols || e->rows != a->rows ||
        e->cols != a->cols) {
        return DV_EINVAL;
    }
    const size_t n = a->rows;
    const size_t nn = n * n;
    if (len < DV_MAT_EXPM_WORK_LEN(n)) {
        return DV_ESIZE;
    }
    dv_real_t *as = work;      /* scaled a */
    dv_real_t *x = as + nn;    /* powers of as */
    dv_real_t *num = x + nn;   /* Pade numerator */
    dv_real_t *den = num + nn; /* Pade denominator */
    dv_real_t *tmp = den + nn;

    dv_real_t norm = DV_R(0.0);
    for (size_t i = 0; i < n; i++) {
        dv_real_t row = DV_R(0.0);
        for (size_t j = 0; j < n; j++) {
            const dv_real_t v = a->data[i * n + j];
            if (!dv_priv_finite(v)) {
                return DV_ENUMERIC;
            }
            row += DV_FABS(v);
        }
        norm = row > norm ? row : norm;
    }
    /* smallest s >= 0 with norm / 2^s <= 1/2 */
    int s = 0;
    dv_real_t sc = DV_R(1.0);
    while (norm * sc > DV_R(0.5)) {
        sc *= DV_R(0.5);
        if (++s > 64) {
            return DV_ENUMERIC;
        }
    }
    for (size_t i = 0; i < nn; i++) {
        as[i] = a->data[i] * sc;
        x[i] = as[i];
    }
    const int q = 6;
    dv_real_t c = DV_R(0.5);
    for (size_t i = 0; i < nn; i++) {
        const dv_real_t id = (i % (n + 1u)) == 0u ? DV_R(1.0) : DV_R(0.0);
        num[i] = id + c * as[i];
        den[i] = id - c * as[i];
    }
    for (int k = 2; k <= q; k++) {
        c = c * (dv_real_t)(q - k + 1) / (dv_real_t)(k * (2 * q - k + 1));
        sq_mul(n, as, x, tmp);
        for (size_t i = 0; i < nn; i++) {
            x[i] = tmp[i];
            num[i] += c * x[i];
            den[i] += ((k & 1) ? -c : c) * x[i];
        }
    }
    dv_mat_t dm = {a->rows, a->cols, den};
    dv_mat_t nm = {a->rows, a->cols, num};
    if (dv_mat_solve(&dm, &nm) != DV_OK) {
        return DV_EUNSTABLE;
    }
    for (int k = 0; k < s; k++) {
        sq_mul(n, num, num, tmp);
        for (size_t i = 0; i < nn; i++) {
            num[i] = tmp[i];
        }
    }
    for (size_t i = 0; i < nn; i++) {
        if (!dv_priv_finite(num[i])) {
            return DV_EUNSTABLE;
        }
        e->data[i] = num[i];
    }
    return DV_OK;
}

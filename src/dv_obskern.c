/* Observer step kernels with AVX2 + FMA (x86-64, double builds; see dv_obskern.h): the 8 x 4
 * one below, one for any other size (kern_any()), the elements' force-free node X, and the
 * AVX-512 modal step. The 8 x 4 product is the portable kernel_8x4()'s, column by column: one
 * broadcast of the column's entry of the step vector, then fused multiply-adds on the two
 * 4-row halves of the state rows and on the 4 output rows. The state columns, the only ones on
 * the chain from one step to the next, go in four independent partial sums of two columns
 * each, with the inputs' sum (ready early) as the first one's start, so the chain is two FMAs
 * and two additions long. */
#include "dv_obskern.h"

#if DV_SIMD_X86
#include <immintrin.h>

/* always inlined into the entry points below, so the common sizes get fixed trip counts */
/* The next step reads the state back one element at a time (broadcast loads); scalar stores
 * keep each of those loads served by store-to-load forwarding from one store of its own size
 * (a load from part of a wide store is not always forwarded, and stalls when it is not).
 * The empty asm statements stop the compiler from merging the stores again. */
DV_TGT_AVX2 static inline void store2(double *p, __m128d v)
{
    _mm_storel_pd(p, v);
    __asm__ volatile("" ::: "memory");
    _mm_storeh_pd(p + 1, v);
}

DV_TGT_AVX2 static inline void store4(double *p, __m256d v)
{
    store2(p, _mm256_castpd256_pd128(v));
    __asm__ volatile("" ::: "memory");
    store2(p + 2, _mm256_extractf128_pd(v, 1));
}

/* The lanes of a 4-vector whose index is below n (n <= 0: none, n >= 4: all): the mask of a
 * vector's rows that exist. */
DV_TGT_AVX2 static inline __m256i lanes_below(long long n)
{
    return _mm256_cmpgt_epi64(_mm256_set1_epi64x(n), _mm256_set_epi64x(3, 2, 1, 0));
}

DV_TGT_AVX2 static inline __attribute__((always_inline)) void
kern8x4(size_t nin, size_t iy, size_t ny, const double *fx, const double *fy, double *sv,
        const double *y, double *yo, double *resid)
{
    const double *in = sv + DV_OBS8_COL_UPREV;
    const double *fxi = fx + DV_OBS8_NS * DV_OBS8_COL_UPREV;
    const double *fyi = fy + DV_OBS8_NO * DV_OBS8_COL_UPREV;
    /* inputs (u window, contact forces) and measurements: off the state chain */
    __m256d s = _mm256_broadcast_sd(in);
    __m256d a0 = _mm256_mul_pd(_mm256_loadu_pd(fxi), s);
    __m256d a1 = _mm256_mul_pd(_mm256_loadu_pd(fxi + 4), s);
    __m256d ay = _mm256_mul_pd(_mm256_loadu_pd(fyi), s);
    for (size_t j = 1; j < nin; j++) {
        s = _mm256_broadcast_sd(in + j);
        a0 = _mm256_fmadd_pd(_mm256_loadu_pd(fxi + 8u * j), s, a0);
        a1 = _mm256_fmadd_pd(_mm256_loadu_pd(fxi + 8u * j + 4u), s, a1);
        ay = _mm256_fmadd_pd(_mm256_loadu_pd(fyi + 4u * j), s, ay);
    }
    const double *fxm = fxi + 8u * iy;
    for (size_t j = 0; j < ny; j++) {
        s = _mm256_broadcast_sd(y + j);
        a0 = _mm256_fmadd_pd(_mm256_loadu_pd(fxm + 8u * j), s, a0);
        a1 = _mm256_fmadd_pd(_mm256_loadu_pd(fxm + 8u * j + 4u), s, a1);
    }
    /* state columns c and c + 4 in partial sum c */
    __m256d p0[4], p1[4], py[4];
    for (size_t c = 0; c < 4u; c++) {
        const __m256d x0 = _mm256_broadcast_sd(sv + c);
        const __m256d x1 = _mm256_broadcast_sd(sv + c + 4u);
        if (c == 0u) {
            p0[c] = _mm256_fmadd_pd(_mm256_loadu_pd(fx), x0, a0);
            p1[c] = _mm256_fmadd_pd(_mm256_loadu_pd(fx + 4), x0, a1);
            py[c] = _mm256_fmadd_pd(_mm256_loadu_pd(fy), x0, ay);
        } else {
            p0[c] = _mm256_mul_pd(_mm256_loadu_pd(fx + 8u * c), x0);
            p1[c] = _mm256_mul_pd(_mm256_loadu_pd(fx + 8u * c + 4u), x0);
            py[c] = _mm256_mul_pd(_mm256_loadu_pd(fy + 4u * c), x0);
        }
        p0[c] = _mm256_fmadd_pd(_mm256_loadu_pd(fx + 8u * (c + 4u)), x1, p0[c]);
        p1[c] = _mm256_fmadd_pd(_mm256_loadu_pd(fx + 8u * (c + 4u) + 4u), x1, p1[c]);
        py[c] = _mm256_fmadd_pd(_mm256_loadu_pd(fy + 4u * (c + 4u)), x1, py[c]);
    }
    const __m256d x0n = _mm256_add_pd(_mm256_add_pd(p0[0], p0[1]), _mm256_add_pd(p0[2], p0[3]));
    const __m256d x1n = _mm256_add_pd(_mm256_add_pd(p1[0], p1[1]), _mm256_add_pd(p1[2], p1[3]));
    const __m256d yh = _mm256_add_pd(_mm256_add_pd(py[0], py[1]), _mm256_add_pd(py[2], py[3]));
    store4(sv, x0n);
    store4(sv + 4, x1n);
    _mm256_storeu_pd(yo, yh);
    if (y != NULL) {
        _mm256_storeu_pd(resid, _mm256_sub_pd(_mm256_loadu_pd(y), yh));
    }
}

DV_TGT_AVX2 void dv_priv_obs_kern8x4_avx2(size_t nin, size_t ny, const double *fx,
                                          const double *fy, double *sv, const double *y,
                                          double *yo, double *resid)
{
    /* the linear 4-DOF step (u[k-1], u[k]; with or without the gain's 4 measurement columns)
     * with constant sizes; anything else (contact forces) through the general form */
    if (nin == 2u && ny == 4u) {
        kern8x4(2u, 2u, 4u, fx, fy, sv, y, yo, resid);
    } else if (nin == 2u && ny == 0u) {
        kern8x4(2u, 2u, 0u, fx, fy, sv, y, yo, resid);
    } else {
        kern8x4(nin, nin, ny, fx, fy, sv, y, yo, resid);
    }
}

DV_TGT_AVX2 void dv_priv_obs_kern8x4_open_avx2(size_t iy, size_t ny, const double *fx,
                                               const double *fy, double *sv, const double *y,
                                               double *yo, double *resid)
{
    if (ny == 4u) {
        kern8x4(2u, iy, 4u, fx, fy, sv, y, yo, resid);
    } else {
        kern8x4(2u, iy, ny, fx, fy, sv, y, yo, resid);
    }
}

/* The loops over a kernel's vectors unrolled early, so each accumulator of the arrays below
 * gets a register of its own (left to the late unroller, gcc kept them on the stack and the
 * state's chain went through memory). */
#if defined(__GNUC__) && !defined(__clang__)
#define DV_UNROLL4 _Pragma("GCC unroll 4")
#else
#define DV_UNROLL4
#endif

/* Rows [4 v, 4 v + 4) of a column; the last vector (v = nv - 1) masked to the rows that exist,
 * so no read goes past the column's matrix. */
DV_TGT_AVX2 static inline __attribute__((always_inline)) __m256d
rows4(const double *col, size_t v, size_t nv, __m256i last)
{
    return v + 1u < nv ? _mm256_loadu_pd(col + 4u * v) : _mm256_maskload_pd(col + 4u * v, last);
}

/* The general step product: nv = ceil(ns / 4) state vectors, nyv = ceil(no / 4) output
 * vectors, constants where the entry point below calls it, so the accumulators stay in
 * registers. The inputs' sum (ready early) starts the even state columns' sum, the odd ones go
 * in a second, so the chain from one state to the next is ns / 2 FMAs and one addition. The
 * new state is stored lane by lane (store4(): the next step broadcasts it back). */
DV_TGT_AVX2 static inline __attribute__((always_inline)) void
kern_any(size_t nv, size_t nyv, size_t ns, size_t no, size_t nin, size_t iy, size_t ny,
         const double *fx, const double *fy, double *sv, const double *y, double *yo)
{
    const __m256i mx = lanes_below((long long)(ns - 4u * (nv - 1u)));
    const __m256i my = lanes_below((long long)(no - 4u * (nyv - 1u)));
    const double *in = sv + ns;
    const double *fxi = fx + ns * ns;
    const double *fyi = fy + no * ns;
    __m256d a[4], b[4], ay[4];
    DV_UNROLL4
    for (size_t v = 0; v < nv; v++) {
        a[v] = _mm256_setzero_pd();
        b[v] = _mm256_setzero_pd();
    }
    DV_UNROLL4
    for (size_t w = 0; w < nyv; w++) {
        ay[w] = _mm256_setzero_pd();
    }
    for (size_t j = 0; j < nin; j++) {
        const __m256d s = _mm256_broadcast_sd(in + j);
        DV_UNROLL4
        for (size_t v = 0; v < nv; v++) {
            a[v] = _mm256_fmadd_pd(rows4(fxi + j * ns, v, nv, mx), s, a[v]);
        }
        DV_UNROLL4
        for (size_t w = 0; w < nyv; w++) {
            ay[w] = _mm256_fmadd_pd(rows4(fyi + j * no, w, nyv, my), s, ay[w]);
        }
    }
    for (size_t j = 0; j < ny; j++) {
        const __m256d s = _mm256_broadcast_sd(y + j);
        DV_UNROLL4
        for (size_t v = 0; v < nv; v++) {
            a[v] = _mm256_fmadd_pd(rows4(fxi + (iy + j) * ns, v, nv, mx), s, a[v]);
        }
    }
    for (size_t j = 0; j < ns; j += 2u) {
        const __m256d s0 = _mm256_broadcast_sd(sv + j);
        const __m256d s1 = _mm256_broadcast_sd(sv + j + 1u);
        DV_UNROLL4
        for (size_t v = 0; v < nv; v++) {
            a[v] = _mm256_fmadd_pd(rows4(fx + j * ns, v, nv, mx), s0, a[v]);
            b[v] = _mm256_fmadd_pd(rows4(fx + (j + 1u) * ns, v, nv, mx), s1, b[v]);
        }
        DV_UNROLL4
        for (size_t w = 0; w < nyv; w++) {
            ay[w] = _mm256_fmadd_pd(rows4(fy + j * no, w, nyv, my), s0, ay[w]);
            ay[w] = _mm256_fmadd_pd(rows4(fy + (j + 1u) * no, w, nyv, my), s1, ay[w]);
        }
    }
    DV_UNROLL4
    for (size_t w = 0; w < nyv; w++) {
        _mm256_maskstore_pd(yo + 4u * w, w + 1u < nyv ? _mm256_set1_epi64x(-1) : my, ay[w]);
    }
    DV_UNROLL4
    for (size_t v = 0; v < nv; v++) {
        const __m256d x = _mm256_add_pd(a[v], b[v]);
        if (4u * v + 4u <= ns) {
            store4(sv + 4u * v, x);
        } else { /* ns is even: two rows left */
            store2(sv + 4u * v, _mm256_castpd256_pd128(x));
        }
    }
}

DV_TGT_AVX2 bool dv_priv_obs_kern_avx2(size_t ns, size_t no, size_t nin, size_t iy, size_t ny,
                                       const double *fx, const double *fy, double *sv,
                                       const double *y, double *yo)
{
    const size_t nv = (ns + 3u) / 4u;
    const size_t nyv = (no + 3u) / 4u;
    /* constant vector counts: each case its own unrolled loops */
#define DV_KERN_ANY(NV, NYV)                                                                    \
    case (NV) * 8u + (NYV):                                                                     \
        kern_any(NV, NYV, ns, no, nin, iy, ny, fx, fy, sv, y, yo);                             \
        return true
    switch (nv * 8u + nyv) {
        DV_KERN_ANY(1u, 1u);
        DV_KERN_ANY(1u, 2u);
        DV_KERN_ANY(1u, 3u);
        DV_KERN_ANY(1u, 4u);
        DV_KERN_ANY(2u, 1u);
        DV_KERN_ANY(2u, 2u);
        DV_KERN_ANY(2u, 3u);
        DV_KERN_ANY(2u, 4u);
        DV_KERN_ANY(3u, 1u);
        DV_KERN_ANY(3u, 2u);
        DV_KERN_ANY(3u, 3u);
        DV_KERN_ANY(3u, 4u);
        DV_KERN_ANY(4u, 1u);
        DV_KERN_ANY(4u, 2u);
        DV_KERN_ANY(4u, 3u);
        DV_KERN_ANY(4u, 4u);
    default: /* more than 16 states or outputs (DV_MAX_DOF, DV_MAX_OUT raised): not served */
        return false;
    }
#undef DV_KERN_ANY
}

/* The force-free X of nodes [f0, f0 + 12) (those < nf) in three vectors, column by column;
 * node f of column j at rx[(f / 8) bs + j cs + f % 8] (f0 a multiple of 4, so no vector
 * straddles a block of 8). */
DV_TGT_AVX2 static inline __attribute__((always_inline)) void
xfree12(const double *rx, size_t f0, size_t nf, size_t ns, size_t bs, size_t cs,
        const double *sv, double *xl)
{
    const long long left = (long long)(nf - f0);
    const __m256i m0 = lanes_below(left);
    const __m256i m1 = lanes_below(left - 4);
    const __m256i m2 = lanes_below(left - 8);
    const double *r0 = rx + f0 / 8u * bs + f0 % 8u;
    const double *r1 = rx + (f0 + 4u) / 8u * bs + (f0 + 4u) % 8u;
    const double *r2 = rx + (f0 + 8u) / 8u * bs + (f0 + 8u) % 8u;
    const __m256d w0 = _mm256_broadcast_sd(sv + ns), w1 = _mm256_broadcast_sd(sv + ns + 1u);
    const size_t ja = ns * cs, jb = (ns + 1u) * cs;
    __m256d a0 = _mm256_mul_pd(_mm256_maskload_pd(r0 + ja, m0), w0);
    __m256d a1 = _mm256_mul_pd(_mm256_maskload_pd(r1 + ja, m1), w0);
    __m256d a2 = _mm256_mul_pd(_mm256_maskload_pd(r2 + ja, m2), w0);
    a0 = _mm256_fmadd_pd(_mm256_maskload_pd(r0 + jb, m0), w1, a0);
    a1 = _mm256_fmadd_pd(_mm256_maskload_pd(r1 + jb, m1), w1, a1);
    a2 = _mm256_fmadd_pd(_mm256_maskload_pd(r2 + jb, m2), w1, a2);
    for (size_t j = 0; j < ns; j++) {
        const __m256d v = _mm256_broadcast_sd(sv + j);
        a0 = _mm256_fmadd_pd(_mm256_maskload_pd(r0 + j * cs, m0), v, a0);
        a1 = _mm256_fmadd_pd(_mm256_maskload_pd(r1 + j * cs, m1), v, a1);
        a2 = _mm256_fmadd_pd(_mm256_maskload_pd(r2 + j * cs, m2), v, a2);
    }
    _mm256_maskstore_pd(xl + f0, m0, a0);
    _mm256_maskstore_pd(xl + f0 + 4u, m1, a1);
    _mm256_maskstore_pd(xl + f0 + 8u, m2, a2);
}

/* Twelve nodes at a time. */
DV_TGT_AVX2 void dv_priv_obs_xfree_avx2(const double *rx, size_t nf, size_t ns, size_t bs,
                                        size_t cs, const double *sv, double *xl)
{
    for (size_t f0 = 0; f0 < nf; f0 += 12u) {
        xfree12(rx, f0, nf, ns, bs, cs, sv, xl);
    }
}

/* The cubic hold's force-free X of four nodes from f0 (those < nf): the input window's share
 * ((c0 w0 + c1 w1) + c2 w2) + c3 w3, node f's coefficients at rxu[4 f ..], then the state's
 * columns one by one, rx[j nf + f] x[j]; each product rounded and then added (no FMA): the
 * portable loops of nodes_x_free(), bit for bit. */
DV_TGT_AVX2 static inline __attribute__((always_inline)) __m256d
xcubic4(const double *rx, const double *rxu, size_t f0, size_t nf, size_t ns, const double *sv)
{
    const long long left = (long long)(nf - f0);
    const __m256i all = _mm256_set1_epi64x(-1), none = _mm256_setzero_si256();
    /* the window's coefficients of nodes f0..f0+3 (rows), transposed to one vector per input */
    const __m256d r0 = _mm256_maskload_pd(rxu + 4u * f0, left > 0 ? all : none);
    const __m256d r1 = _mm256_maskload_pd(rxu + 4u * f0 + 4u, left > 1 ? all : none);
    const __m256d r2 = _mm256_maskload_pd(rxu + 4u * f0 + 8u, left > 2 ? all : none);
    const __m256d r3 = _mm256_maskload_pd(rxu + 4u * f0 + 12u, left > 3 ? all : none);
    const __m256d t0 = _mm256_unpacklo_pd(r0, r1), t1 = _mm256_unpackhi_pd(r0, r1);
    const __m256d t2 = _mm256_unpacklo_pd(r2, r3), t3 = _mm256_unpackhi_pd(r2, r3);
    const __m256d c0 = _mm256_permute2f128_pd(t0, t2, 0x20);
    const __m256d c1 = _mm256_permute2f128_pd(t1, t3, 0x20);
    const __m256d c2 = _mm256_permute2f128_pd(t0, t2, 0x31);
    const __m256d c3 = _mm256_permute2f128_pd(t1, t3, 0x31);
    const double *win = sv + ns;
    __m256d a = _mm256_mul_pd(c0, _mm256_broadcast_sd(win));
    a = _mm256_add_pd(a, _mm256_mul_pd(c1, _mm256_broadcast_sd(win + 1u)));
    a = _mm256_add_pd(a, _mm256_mul_pd(c2, _mm256_broadcast_sd(win + 2u)));
    a = _mm256_add_pd(a, _mm256_mul_pd(c3, _mm256_broadcast_sd(win + 3u)));
    const __m256i m = lanes_below(left);
    for (size_t j = 0; j < ns; j++) {
        const __m256d col = _mm256_maskload_pd(rx + j * nf + f0, m);
        a = _mm256_add_pd(a, _mm256_mul_pd(col, _mm256_broadcast_sd(sv + j)));
    }
    return a;
}

/* Four nodes at a time, the last four's lanes beyond nf not stored. */
DV_TGT_AVX2 void dv_priv_obs_xfree_cubic_avx2(const double *rx, const double *rxu, size_t nf,
                                              size_t ns, const double *sv, double *xl)
{
    size_t f0 = 0;
    for (; f0 + 4u <= nf; f0 += 4u) {
        _mm256_storeu_pd(xl + f0, xcubic4(rx, rxu, f0, nf, ns, sv));
    }
    if (f0 < nf) {
        _mm256_maskstore_pd(xl + f0, lanes_below((long long)(nf - f0)),
                            xcubic4(rx, rxu, f0, nf, ns, sv));
    }
}

/* The modal prediction: C T q as sum_k pred[k] (q permuted by lane ^ k) (struct dv_obs_modal),
 * the low half holding the state columns 0-3, the high half 4-7, plus the input window's terms
 * (fyu: the output rows' u[k-1] column, u[k]'s after it). */
DV_TGT_AVX512 static inline __attribute__((always_inline)) __m256d
modal_pred(const double *fyu, const dv_obs_modal_t *mf, __m512d q, __m512d qs, __m512d up,
           __m512d uk)
{
    const __m512d q2 = _mm512_permutex_pd(q, 0x4E), q3 = _mm512_permutex_pd(q, 0x1B);
    __m512d ya = _mm512_mul_pd(_mm512_loadu_pd(mf->pred[0]), q);
    __m512d yb = _mm512_mul_pd(_mm512_loadu_pd(mf->pred[1]), qs);
    ya = _mm512_fmadd_pd(_mm512_loadu_pd(mf->pred[2]), q2, ya);
    yb = _mm512_fmadd_pd(_mm512_loadu_pd(mf->pred[3]), q3, yb);
    ya = _mm512_add_pd(ya, yb);
    __m256d yh = _mm256_add_pd(_mm512_castpd512_pd256(ya), _mm512_extractf64x4_pd(ya, 1));
    yh = _mm256_fmadd_pd(_mm256_loadu_pd(fyu), _mm512_castpd512_pd256(up), yh);
    return _mm256_fmadd_pd(_mm256_loadu_pd(fyu + DV_OBS8_NO), _mm512_castpd512_pd256(uk), yh);
}

/* The columns of the folded rows the modal step reads (dv_obs_priv.h): the state rows' u[k-1]
 * column (u[k]'s after it) and first y column (after the contact forces' columns, which an
 * open step skips), and the output rows' u[k-1] column. */
typedef struct {
    const double *fxu;
    const double *fxy;
    const double *fyu;
} modal_cols_t;

static inline __attribute__((always_inline)) modal_cols_t modal_cols(const dv_obs_t *o)
{
    const double *fy = o->f + DV_OBS8_NS * (size_t)o->ncol_gain;
    const modal_cols_t c = {o->f + DV_OBS8_NS * DV_OBS8_COL_UPREV,
                            o->f + DV_OBS8_NS * (DV_OBS8_COL_G + (size_t)o->nf),
                            fy + DV_OBS8_NO * DV_OBS8_COL_UPREV};
    return c;
}

/* One modal step's arithmetic (dv_priv_obs_step8x4_modal_avx512() and the block loop share it,
 * so both give the same bits): the prediction yh from q and the input window (up = u[k-1],
 * uk = u[k]), and the next state from q, the inputs and, with the gain, the measurements y,
 * or with y NULL the prediction itself (open loop: x+ = x- + L (yhat - yhat)). */
DV_TGT_AVX512 static inline __attribute__((always_inline)) __m512d
modal_core(modal_cols_t c, const dv_obs_modal_t *mf, bool gain, __m512d q, __m512d up,
           __m512d uk, const double *y, __m256d *yh_out)
{
    const __m512d qs = _mm512_permute_pd(q, 0x55);
    const bool open_gain = gain && y == NULL; /* the prediction feeds the state update */
    double yp[4];
    if (open_gain) {
        *yh_out = modal_pred(c.fyu, mf, q, qs, up, uk);
        _mm256_storeu_pd(yp, *yh_out);
        y = yp;
    }
    /* inputs and (with the gain) measurements */
    __m512d a = _mm512_mul_pd(_mm512_loadu_pd(c.fxu), up);
    a = _mm512_fmadd_pd(_mm512_loadu_pd(c.fxu + DV_OBS8_NS), uk, a);
    if (gain) {
        a = _mm512_fmadd_pd(_mm512_loadu_pd(c.fxy), _mm512_set1_pd(y[0]), a);
        a = _mm512_fmadd_pd(_mm512_loadu_pd(c.fxy + 8), _mm512_set1_pd(y[1]), a);
        a = _mm512_fmadd_pd(_mm512_loadu_pd(c.fxy + 16), _mm512_set1_pd(y[2]), a);
        a = _mm512_fmadd_pd(_mm512_loadu_pd(c.fxy + 24), _mm512_set1_pd(y[3]), a);
    }
    /* q+ = diag * q + off * (q with each pair swapped) + inputs */
    __m512d qn = _mm512_fmadd_pd(_mm512_loadu_pd(mf->lam_diag), q, a);
    qn = _mm512_fmadd_pd(_mm512_loadu_pd(mf->lam_off), qs, qn);
    if (!open_gain) {
        *yh_out = modal_pred(c.fyu, mf, q, qs, up, uk);
    }
    return qn;
}

/* u and, when given, the four measurements finite: one class test each (NaN or Inf). */
DV_TGT_AVX512 static inline __attribute__((always_inline)) bool modal_finite(double u,
                                                                          const double *y)
{
    enum { NAN_INF = 0x01 | 0x08 | 0x10 | 0x80 }; /* QNaN, +Inf, -Inf, SNaN */
    const __mmask8 bu = _mm_fpclass_sd_mask(_mm_set_sd(u), NAN_INF);
    if (y == NULL) {
        return bu == 0u;
    }
    return _kortestz_mask8_u8(bu, _mm256_fpclass_pd_mask(_mm256_loadu_pd(y), NAN_INF)) != 0u;
}

/* The contact element's X at 8 sub-nodes from a block of its modal rows (struct dv_obs_modal
 * rx: the columns q, then u[k-1], u[k]); two partial sums (the open check is off the state's
 * chain, but decides a branch). */
DV_TGT_AVX512 static inline __attribute__((always_inline)) __m512d
nodes_x(const double (*rb)[DV_OBS_MODAL_BLOCK], const double *q, __m512d up, __m512d uk)
{
    __m512d a = _mm512_mul_pd(_mm512_loadu_pd(rb[DV_OBS8_NS]), up);
    __m512d b = _mm512_mul_pd(_mm512_loadu_pd(rb[DV_OBS8_NS + 1]), uk);
    for (size_t j = 0; j < 8u; j += 2u) {
        a = _mm512_fmadd_pd(_mm512_loadu_pd(rb[j]), _mm512_set1_pd(q[j]), a);
        b = _mm512_fmadd_pd(_mm512_loadu_pd(rb[j + 1u]), _mm512_set1_pd(q[j + 1u]), b);
    }
    return _mm512_add_pd(a, b);
}

/* Lanes of x where the gap element is not open: the vector form of dv_priv_gap_open()
 * (dv_elem_law.h), X > gap on the positive side, X < -gap on the negative one, or NaN.
 * (The padding rows give X = 0: open at any gap >= 0.) */
DV_TGT_AVX512 static inline __attribute__((always_inline)) __mmask8
shut_lanes(const dv_elem_desc_t *c, __m512d x)
{
    __mmask8 shut = 0;
    if (((int)c->side & (int)DV_SIDE_POS) != 0) {
        shut |= _mm512_cmp_pd_mask(x, _mm512_set1_pd(c->gap_m), _CMP_NLE_UQ);
    }
    if (((int)c->side & (int)DV_SIDE_NEG) != 0) {
        shut |= _mm512_cmp_pd_mask(x, _mm512_set1_pd(-c->gap_m), _CMP_NGE_UQ);
    }
    return shut;
}

/* With the contact element (o->nf > 0, at most 24 nodes; a gap law, one element): its X at every
 * sub-node of the step from q and the input window (the modal form's rows) all on the open side of
 * the gap. Then the forces are all zero and the step is the linear one (dv_obs.c all_open():
 * the node chain would only add zeros; the gap law keeps no element history). False when any
 * node engages (or is NaN). */
DV_TGT_AVX512 static inline __attribute__((always_inline)) bool
modal_open(const dv_obs_t *o, const double *q, __m512d up, __m512d uk)
{
    const dv_elem_desc_t *c = &o->m->elem[0];
    const size_t nf = o->nf;
    const dv_obs_modal_t *mf = o->modal_form;
    __m512d x = nodes_x(mf->rx[0], q, up, uk);
    __mmask8 shut = shut_lanes(c, x);
    if (nf > 8u) {
        x = nodes_x(mf->rx[1], q, up, uk);
        shut |= shut_lanes(c, x);
        if (nf > 16u) {
            x = nodes_x(mf->rx[2], q, up, uk);
            shut |= shut_lanes(c, x);
        }
    }
    return shut == 0u;
}

/* dv_priv_obs_step8x4_modal_avx512() with its y (NULL: open loop) and u checked; with the
 * contact (a constant on each path, so the linear step keeps its straight code) only when the
 * element stays open: false, with nothing changed, for a step that engages it. */
DV_TGT_AVX512 static inline __attribute__((always_inline)) bool
modal_step(dv_obs_t *o, double u, const double *y, bool contact)
{
    double *sv = o->sv;
    const __m512d up = _mm512_set1_pd(sv[DV_OBS8_COL_UPREV]), uk = _mm512_set1_pd(u);
    if (contact && !modal_open(o, sv, up, uk)) {
        return false;
    }
    __m256d yh;
    const __m512d qn = modal_core(modal_cols(o), o->modal_form, o->has_gain, _mm512_loadu_pd(sv),
                                  up, uk, y, &yh);
    _mm512_storeu_pd(sv, qn);
    _mm256_storeu_pd(o->z + DV_OBS8_NS, yh);
    /* no measurement: the residual is the prediction's own, 0 */
    _mm256_storeu_pd(o->resid, y != NULL ? _mm256_sub_pd(_mm256_loadu_pd(y), yh)
                                         : _mm256_setzero_pd());
    sv[DV_OBS8_COL_UPREV] = u;
    const uint32_t flags = y != NULL ? 0u : DV_OBS_FLAG_NO_MEAS;
    dv_priv_obs_tally(o, flags, flags, 1u, 1u);
    return true;
}

/* The open-loop and the contact steps apart, so the linear measured one keeps its straight
 * code. The slow path takes a bad sample (flagged, counted there) and a step that engages the
 * contact. */
DV_TGT_AVX512 __attribute__((noinline)) static dv_status_t modal_step_open(dv_obs_t *o, double u)
{
    if (!modal_finite(u, NULL) || !modal_step(o, u, NULL, o->nf != 0u)) {
        return dv_priv_obs_step_slow(o, u, NULL);
    }
    return DV_OK;
}

/* While the contact stays engaged (o->contact_hot, kept by the direct path's contact step) the
 * measured steps go to the slow path without the open check: with its 512-bit work the
 * latency-bound node chain measured ~20 % slower on this host. */
DV_TGT_AVX512 dv_status_t dv_priv_obs_step8x4_modal_contact_avx512(dv_obs_t *o, double u,
                                                                  const double *y)
{
    if (y == NULL) {
        return modal_step_open(o, u);
    }
    if (o->contact_hot || !modal_finite(u, y) || !modal_step(o, u, y, true)) {
        return dv_priv_obs_step_slow(o, u, y);
    }
    return DV_OK;
}

DV_TGT_AVX512 dv_status_t dv_priv_obs_step8x4_modal_avx512(dv_obs_t *o, double u,
                                                          const double *y)
{
    if (y == NULL) {
        return modal_step_open(o, u);
    }
    if (!modal_finite(u, y)) {
        return dv_priv_obs_step_slow(o, u, y); /* flags and counts the bad sample */
    }
    modal_step(o, u, y, false);
    return DV_OK;
}

DV_TGT_AVX512 size_t dv_priv_obs_run8x4_modal_avx512(dv_obs_t *o, const double *u,
                                                     const double *y, size_t n, double *y_pred,
                                                     double *resid)
{
    double *sv = o->sv;
    const modal_cols_t cols = modal_cols(o);
    const dv_obs_modal_t *mf = o->modal_form;
    const bool gain = o->has_gain;
    const bool contact = o->nf != 0u;
    __m512d q = _mm512_loadu_pd(sv);
    double up = sv[DV_OBS8_COL_UPREV];
    __m256d yh = _mm256_loadu_pd(o->z + DV_OBS8_NS), r = _mm256_loadu_pd(o->resid);
    size_t k = 0;
    for (; k < n; k++) {
        const double *yk = y != NULL ? y + 4u * k : NULL;
        const __m512d upv = _mm512_set1_pd(up), ukv = _mm512_set1_pd(u[k]);
        if (!modal_finite(u[k], yk)) {
            break; /* the caller steps this sample through the general path */
        }
        if (contact) { /* as dv_obs_step(): the caller's step while engaged or engaging */
            double qa[8];
            _mm512_storeu_pd(qa, q);
            if ((yk != NULL && o->contact_hot) || !modal_open(o, qa, upv, ukv)) {
                break;
            }
        }
        q = modal_core(cols, mf, gain, q, upv, ukv, yk, &yh);
        r = yk != NULL ? _mm256_sub_pd(_mm256_loadu_pd(yk), yh) : _mm256_setzero_pd();
        if (y_pred != NULL) {
            _mm256_storeu_pd(y_pred + 4u * k, yh);
        }
        if (resid != NULL) {
            _mm256_storeu_pd(resid + 4u * k, r);
        }
        up = u[k];
    }
    if (k > 0u) {
        _mm512_storeu_pd(sv, q);
        _mm256_storeu_pd(o->z + DV_OBS8_NS, yh);
        _mm256_storeu_pd(o->resid, r);
        sv[DV_OBS8_COL_UPREV] = up;
        const uint32_t flags = y != NULL ? 0u : DV_OBS_FLAG_NO_MEAS;
        dv_priv_obs_tally(o, flags, flags, k, k);
    }
    return k;
}

#else
/* ISO C wants at least one declaration in a translation unit. */
typedef int dv_obskern_unused_t;
#endif

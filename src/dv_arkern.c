/* AR inner loops: autocorrelation, dot product, multi-output FIR and two Burg stages per sweep.
 *
 * The portable versions keep 4 independent partial sums, because C compilers may not reorder
 * floating-point sums and one accumulator chain is latency-bound (4 cycles per add). On x86-64
 * double builds the same loops also exist as AVX2/FMA and AVX-512F functions compiled with
 * target attributes and chosen at run time, so a plain -O2 build (SSE2 baseline) still runs
 * AR(60) residuals at a few ns per sample. The arm-none-eabi and float builds see only C. */
#include "dv_priv.h"

#if DV_SIMD_X86 /* dv_priv.h */
#include <immintrin.h>
#endif

/* ------------------------------------------------------------------------------------------ */
/* portable C                                                                                  */

static dv_real_t dot_c(const dv_real_t *a, const dv_real_t *b, size_t n)
{
    dv_real_t s0 = DV_R(0.0), s1 = DV_R(0.0), s2 = DV_R(0.0), s3 = DV_R(0.0);
    size_t i = 0u;
    for (; i + 4u <= n; i += 4u) {
        s0 += a[i] * b[i];
        s1 += a[i + 1u] * b[i + 1u];
        s2 += a[i + 2u] * b[i + 2u];
        s3 += a[i + 3u] * b[i + 3u];
    }
    for (; i < n; i++) {
        s0 += a[i] * b[i];
    }
    return (s0 + s1) + (s2 + s3);
}

static dv_real_t sum_c(const dv_real_t *x, size_t n)
{
    dv_real_t s0 = DV_R(0.0), s1 = DV_R(0.0), s2 = DV_R(0.0), s3 = DV_R(0.0);
    size_t i = 0u;
    for (; i + 4u <= n; i += 4u) {
        s0 += x[i];
        s1 += x[i + 1u];
        s2 += x[i + 2u];
        s3 += x[i + 3u];
    }
    for (; i < n; i++) {
        s0 += x[i];
    }
    return (s0 + s1) + (s2 + s3);
}

/* Pairwise dot product: blocks of 64 products (four chains of 16, as dot_c), the block sums
 * merged like a binary counter, lvl[k] holding the sum of 2^k blocks. The round-off bound
 * grows like 16 + log2(n / 64) roundings instead of n / 4. This matters for float Yule-Walker
 * fits of long records: the Toeplitz solve multiplies the autocorrelation's relative error by
 * its condition number (~2.5e4 for the lightly damped structure at AR(30)), and 4 plain chains
 * over 8192 samples left r_k off by ~4e-7 r_0 (AR(30) coefficients ~1e-3 off) against ~6e-8. */
static dv_real_t dot_pw_c(const dv_real_t *a, const dv_real_t *b, size_t n)
{
    enum { BLK = 64 };
    dv_real_t lvl[sizeof(size_t) * 8u];
    size_t nblk = 0u, i = 0u;
    for (; i + BLK <= n; i += BLK) {
        dv_real_t s0 = DV_R(0.0), s1 = DV_R(0.0), s2 = DV_R(0.0), s3 = DV_R(0.0);
        for (size_t j = i; j < i + BLK; j += 4u) {
            s0 += a[j] * b[j];
            s1 += a[j + 1u] * b[j + 1u];
            s2 += a[j + 2u] * b[j + 2u];
            s3 += a[j + 3u] * b[j + 3u];
        }
        dv_real_t s = (s0 + s1) + (s2 + s3);
        uint32_t k = 0u;
        for (size_t c = nblk; (c & 1u) != 0u; c >>= 1u, k++) {
            s = lvl[k] + s;
        }
        lvl[k] = s;
        nblk++;
    }
    dv_real_t s = dot_c(a + i, b + i, n - i);
    for (uint32_t k = 0u; (nblk >> k) != 0u; k++) {
        if (((nblk >> k) & 1u) != 0u) {
            s += lvl[k];
        }
    }
    return s;
}

static void acf_c(const dv_real_t *x, size_t n, size_t maxlag, dv_real_t *r)
{
    for (size_t k = 0u; k <= maxlag; k++) {
        r[k] = dot_pw_c(x, x + k, n - k);
    }
}

static void fir_c(const dv_real_t *c, size_t p, dv_real_t c0, const dv_real_t *x, size_t n,
                  dv_real_t *e)
{
    size_t i = 0u;
    /* Four outputs at a time share each coefficient load and give four independent chains. */
    for (; i + 4u <= n; i += 4u) {
        dv_real_t s0 = DV_R(0.0), s1 = DV_R(0.0), s2 = DV_R(0.0), s3 = DV_R(0.0);
        const dv_real_t *xi = x + i - 1; /* x_{i-j} for j = 1 */
        for (size_t j = 1u; j <= p; j++) {
            const dv_real_t aj = c[p - j];
            s0 += aj * xi[0];
            s1 += aj * xi[1];
            s2 += aj * xi[2];
            s3 += aj * xi[3];
            xi--;
        }
        e[i] = x[i] - c0 - s0;
        e[i + 1u] = x[i + 1u] - c0 - s1;
        e[i + 2u] = x[i + 2u] - c0 - s2;
        e[i + 3u] = x[i + 3u] - c0 - s3;
    }
    for (; i < n; i++) {
        dv_real_t s = DV_R(0.0);
        for (size_t j = 1u; j <= p; j++) {
            s += c[p - j] * x[i - j];
        }
        e[i] = x[i] - c0 - s;
    }
}


/* Two stages per pass: the error arrays (the memory traffic) are swept half as often. Stage-1
 * values at j and j+1 feed stage 2; the new values' lag-1 products use the previous element.
 * From element j on, with the sums so far in s (and fp, bp the last new f and b): the whole
 * pass from j = 0 with zeros, and the vector kernels' tails. */
static void burg2_from(dv_real_t *f, dv_real_t *b, size_t len, size_t j, dv_real_t k1,
                       dv_real_t k2, dv_real_t fp, dv_real_t bp, dv_real_t s[7])
{
    dv_real_t s0 = s[0], s1 = s[1], s2 = s[2], s3 = s[3], s4 = s[4], s5 = s[5], s6 = s[6];
    for (; j + 2u < len; j++) {
        const dv_real_t fa = f[j + 1u] - k1 * b[j + 1u], ba = b[j] - k1 * f[j];
        const dv_real_t fb = f[j + 2u] - k1 * b[j + 2u], bb = b[j + 1u] - k1 * f[j + 1u];
        const dv_real_t fn = fb - k2 * bb, bn = ba - k2 * fa;
        f[j] = fn;
        b[j] = bn;
        s0 += fn * fn;
        s1 += bn * bn;
        s2 += fn * bn;
        s3 += fn * bp;
        s4 += fn * fp;
        s5 += bn * bp;
        s6 += bn * fp;
        fp = fn;
        bp = bn;
    }
    s[0] = s0;
    s[1] = s1;
    s[2] = s2;
    s[3] = s3;
    s[4] = s4;
    s[5] = s5;
    s[6] = s6;
}

static void burg2_c(dv_real_t *f, dv_real_t *b, size_t len, dv_real_t k1, dv_real_t k2,
                    dv_real_t s[7])
{
    for (size_t i = 0; i < 7u; i++) {
        s[i] = DV_R(0.0);
    }
    burg2_from(f, b, len, 0u, k1, k2, DV_R(0.0), DV_R(0.0), s);
}

/* ------------------------------------------------------------------------------------------ */
/* x86-64, double: AVX2 + FMA                                                                  */
#if DV_SIMD_X86

#define DV_FALLTHROUGH __attribute__((fallthrough))

DV_TGT_AVX2 static double hsum256(__m256d v)
{
    const __m128d lo = _mm256_castpd256_pd128(v);
    const __m128d hi = _mm256_extractf128_pd(v, 1);
    const __m128d s = _mm_add_pd(lo, hi);
    return _mm_cvtsd_f64(_mm_add_sd(s, _mm_unpackhi_pd(s, s)));
}

DV_TGT_AVX2 static double dot_avx2(const double *a, const double *b, size_t n)
{
    __m256d s0 = _mm256_setzero_pd(), s1 = _mm256_setzero_pd();
    __m256d s2 = _mm256_setzero_pd(), s3 = _mm256_setzero_pd();
    size_t i = 0u;
    for (; i + 16u <= n; i += 16u) {
        s0 = _mm256_fmadd_pd(_mm256_loadu_pd(a + i), _mm256_loadu_pd(b + i), s0);
        s1 = _mm256_fmadd_pd(_mm256_loadu_pd(a + i + 4u), _mm256_loadu_pd(b + i + 4u), s1);
        s2 = _mm256_fmadd_pd(_mm256_loadu_pd(a + i + 8u), _mm256_loadu_pd(b + i + 8u), s2);
        s3 = _mm256_fmadd_pd(_mm256_loadu_pd(a + i + 12u), _mm256_loadu_pd(b + i + 12u), s3);
    }
    for (; i + 4u <= n; i += 4u) {
        s0 = _mm256_fmadd_pd(_mm256_loadu_pd(a + i), _mm256_loadu_pd(b + i), s0);
    }
    double s = hsum256(_mm256_add_pd(_mm256_add_pd(s0, s1), _mm256_add_pd(s2, s3)));
    for (; i < n; i++) {
        s += a[i] * b[i];
    }
    return s;
}

/* The vector autocorrelations sum rows in blocks of ACF_BLK and add each block's sums to the
 * totals: a lane's chain is ~ACF_BLK/2 + n/ACF_BLK additions instead of n (AVX2) or n/2
 * (AVX-512), whose round-off grows about like its square root. Burg's autocorrelation route
 * (dv_ar.c) amplifies r_k's error by up to ~1e5, and over whole-record chains it was the larger
 * part of that route's error (n = 8192: worst r_k error 4e-15 r_0 -> 7e-16 with blocks). */
enum { ACF_BLK = 256 };

/* Lags in groups of 32 (8 x 4 accumulators). Rows i are taken 4 apart (residue by residue), so
 * the 8 windows x[i+g+4q .. +3] of row i+4 are those of row i shifted by one: two loads per row
 * (the newest window, and the oldest, which is not kept: 8 accumulators, 7 windows and the
 * broadcast fill the 16 registers) instead of 8 (the loads, mostly cache-line splits, were the
 * bottleneck). */
DV_TGT_AVX2 static void acf_avx2(const double *x, size_t n, size_t maxlag, double *r)
{
    for (size_t g = 0u; g <= maxlag; g += 32u) {
        double tmp[32] = {0.0};
        const size_t imax = n > g + 31u ? n - g - 31u : 0u; /* rows whose 32 lags are in range */
        __m256d c0 = _mm256_setzero_pd(), c1 = c0, c2 = c0, c3 = c0, c4 = c0, c5 = c0, c6 = c0,
                c7 = c0;
        for (size_t i0 = 0u; i0 < imax; i0 += ACF_BLK) {
            const size_t iend = imax - i0 > ACF_BLK ? i0 + ACF_BLK : imax;
            for (size_t rho = i0; rho < i0 + 4u && rho < iend; rho++) {
                const double *w = x + rho + g;
                __m256d w1 = _mm256_loadu_pd(w + 4), w2 = _mm256_loadu_pd(w + 8),
                        w3 = _mm256_loadu_pd(w + 12), w4 = _mm256_loadu_pd(w + 16),
                        w5 = _mm256_loadu_pd(w + 20), w6 = _mm256_loadu_pd(w + 24),
                        w7 = _mm256_loadu_pd(w + 28);
                for (size_t i = rho;;) {
                    const __m256d xi = _mm256_broadcast_sd(x + i);
                    c0 = _mm256_fmadd_pd(xi, _mm256_loadu_pd(x + i + g), c0);
                    c1 = _mm256_fmadd_pd(xi, w1, c1);
                    c2 = _mm256_fmadd_pd(xi, w2, c2);
                    c3 = _mm256_fmadd_pd(xi, w3, c3);
                    c4 = _mm256_fmadd_pd(xi, w4, c4);
                    c5 = _mm256_fmadd_pd(xi, w5, c5);
                    c6 = _mm256_fmadd_pd(xi, w6, c6);
                    c7 = _mm256_fmadd_pd(xi, w7, c7);
                    i += 4u;
                    if (i >= iend) {
                        break;
                    }
                    w1 = w2; w2 = w3; w3 = w4; w4 = w5; w5 = w6; w6 = w7;
                    w7 = _mm256_loadu_pd(x + i + g + 28u);
                }
            }
            _mm256_storeu_pd(tmp, _mm256_add_pd(_mm256_loadu_pd(tmp), c0));
            _mm256_storeu_pd(tmp + 4, _mm256_add_pd(_mm256_loadu_pd(tmp + 4), c1));
            _mm256_storeu_pd(tmp + 8, _mm256_add_pd(_mm256_loadu_pd(tmp + 8), c2));
            _mm256_storeu_pd(tmp + 12, _mm256_add_pd(_mm256_loadu_pd(tmp + 12), c3));
            _mm256_storeu_pd(tmp + 16, _mm256_add_pd(_mm256_loadu_pd(tmp + 16), c4));
            _mm256_storeu_pd(tmp + 20, _mm256_add_pd(_mm256_loadu_pd(tmp + 20), c5));
            _mm256_storeu_pd(tmp + 24, _mm256_add_pd(_mm256_loadu_pd(tmp + 24), c6));
            _mm256_storeu_pd(tmp + 28, _mm256_add_pd(_mm256_loadu_pd(tmp + 28), c7));
            c0 = c1 = c2 = c3 = c4 = c5 = c6 = c7 = _mm256_setzero_pd();
        }
        for (size_t l = 0u; l < 32u && g + l <= maxlag; l++) {
            const size_t k = g + l;
            double s = tmp[l];
            for (size_t i = imax; i + k < n; i++) {
                s += x[i] * x[i + k];
            }
            r[k] = s;
        }
    }
}

/* 32 outputs at a time in 8 x 4 accumulators. Taps are taken 4 apart (j0, j0+4, ...): the 8
 * windows x[i+4t-j .. +3] of tap j+4 are those of tap j shifted by one, so each tap costs one
 * load, one broadcast and 8 FMAs. */
DV_TGT_AVX2 static void fir_avx2(const double *c, size_t p, double c0, const double *x, size_t n,
                                 double *e)
{
    const __m256d vc0 = _mm256_set1_pd(c0);
    size_t i = 0u;
    for (; i + 32u <= n; i += 32u) {
        const double *xi = x + i;
        __m256d s0 = _mm256_sub_pd(_mm256_loadu_pd(xi), vc0);
        __m256d s1 = _mm256_sub_pd(_mm256_loadu_pd(xi + 4), vc0);
        __m256d s2 = _mm256_sub_pd(_mm256_loadu_pd(xi + 8), vc0);
        __m256d s3 = _mm256_sub_pd(_mm256_loadu_pd(xi + 12), vc0);
        __m256d s4 = _mm256_sub_pd(_mm256_loadu_pd(xi + 16), vc0);
        __m256d s5 = _mm256_sub_pd(_mm256_loadu_pd(xi + 20), vc0);
        __m256d s6 = _mm256_sub_pd(_mm256_loadu_pd(xi + 24), vc0);
        __m256d s7 = _mm256_sub_pd(_mm256_loadu_pd(xi + 28), vc0);
        for (size_t j0 = 1u; j0 <= 4u && j0 <= p; j0++) {
            const double *w = xi - j0;
            __m256d w0 = _mm256_loadu_pd(w), w1 = _mm256_loadu_pd(w + 4), w2 = _mm256_loadu_pd(w + 8),
                    w3 = _mm256_loadu_pd(w + 12), w4 = _mm256_loadu_pd(w + 16),
                    w5 = _mm256_loadu_pd(w + 20), w6 = _mm256_loadu_pd(w + 24),
                    w7 = _mm256_loadu_pd(w + 28);
            for (size_t j = j0;;) {
                const __m256d aj = _mm256_broadcast_sd(c + p - j);
                s0 = _mm256_fnmadd_pd(aj, w0, s0);
                s1 = _mm256_fnmadd_pd(aj, w1, s1);
                s2 = _mm256_fnmadd_pd(aj, w2, s2);
                s3 = _mm256_fnmadd_pd(aj, w3, s3);
                s4 = _mm256_fnmadd_pd(aj, w4, s4);
                s5 = _mm256_fnmadd_pd(aj, w5, s5);
                s6 = _mm256_fnmadd_pd(aj, w6, s6);
                s7 = _mm256_fnmadd_pd(aj, w7, s7);
                j += 4u;
                if (j > p) {
                    break;
                }
                w -= 4;
                w7 = w6; w6 = w5; w5 = w4; w4 = w3; w3 = w2; w2 = w1; w1 = w0;
                w0 = _mm256_loadu_pd(w);
            }
        }
        _mm256_storeu_pd(e + i, s0);
        _mm256_storeu_pd(e + i + 4, s1);
        _mm256_storeu_pd(e + i + 8, s2);
        _mm256_storeu_pd(e + i + 12, s3);
        _mm256_storeu_pd(e + i + 16, s4);
        _mm256_storeu_pd(e + i + 20, s5);
        _mm256_storeu_pd(e + i + 24, s6);
        _mm256_storeu_pd(e + i + 28, s7);
    }
    for (; i + 4u <= n; i += 4u) {
        __m256d s = _mm256_sub_pd(_mm256_loadu_pd(x + i), vc0);
        for (size_t j = 1u; j <= p; j++) {
            s = _mm256_fnmadd_pd(_mm256_broadcast_sd(c + p - j), _mm256_loadu_pd(x + i - j), s);
        }
        _mm256_storeu_pd(e + i, s);
    }
    if (i < n) {
        fir_c(c, p, c0, x + i, n - i, e + i);
    }
}

/* burg2_c with 4 lanes; the previous element of each lane comes from a lane rotation. */
DV_TGT_AVX2 static __m256d prev4(__m256d v, __m256d vprev)
{
    /* [vprev3, v0, v1, v2] */
    const __m256d r = _mm256_permute4x64_pd(v, 0x93), rp = _mm256_permute4x64_pd(vprev, 0x93);
    return _mm256_blend_pd(r, rp, 0x1);
}

DV_TGT_AVX2 static void burg2_avx2(double *f, double *b, size_t len, double k1, double k2,
                                   double s[7])
{
    const __m256d v1 = _mm256_set1_pd(k1), v2 = _mm256_set1_pd(k2);
    __m256d a0 = _mm256_setzero_pd(), a1 = a0, a2 = a0, a3 = a0, a4 = a0, a5 = a0, a6 = a0;
    __m256d fprev = a0, bprev = a0;
    size_t j = 0u;
    for (; j + 4u + 2u <= len; j += 4u) {
        const __m256d f0 = _mm256_loadu_pd(f + j), f1 = _mm256_loadu_pd(f + j + 1u),
                      f2 = _mm256_loadu_pd(f + j + 2u);
        const __m256d b0 = _mm256_loadu_pd(b + j), b1 = _mm256_loadu_pd(b + j + 1u),
                      b2 = _mm256_loadu_pd(b + j + 2u);
        const __m256d fa = _mm256_fnmadd_pd(v1, b1, f1), ba = _mm256_fnmadd_pd(v1, f0, b0);
        const __m256d fb = _mm256_fnmadd_pd(v1, b2, f2), bb = _mm256_fnmadd_pd(v1, f1, b1);
        const __m256d fn = _mm256_fnmadd_pd(v2, bb, fb), bn = _mm256_fnmadd_pd(v2, fa, ba);
        _mm256_storeu_pd(f + j, fn);
        _mm256_storeu_pd(b + j, bn);
        const __m256d fs = prev4(fn, fprev), bs = prev4(bn, bprev);
        a0 = _mm256_fmadd_pd(fn, fn, a0);
        a1 = _mm256_fmadd_pd(bn, bn, a1);
        a2 = _mm256_fmadd_pd(fn, bn, a2);
        a3 = _mm256_fmadd_pd(fn, bs, a3);
        a4 = _mm256_fmadd_pd(fn, fs, a4);
        a5 = _mm256_fmadd_pd(bn, bs, a5);
        a6 = _mm256_fmadd_pd(bn, fs, a6);
        fprev = fn;
        bprev = bn;
    }
    double t[4];
    _mm256_storeu_pd(t, fprev);
    double fp = t[3];
    _mm256_storeu_pd(t, bprev);
    double bp = t[3];
    s[0] = hsum256(a0);
    s[1] = hsum256(a1);
    s[2] = hsum256(a2);
    s[3] = hsum256(a3);
    s[4] = hsum256(a4);
    s[5] = hsum256(a5);
    s[6] = hsum256(a6);
    burg2_from(f, b, len, j, k1, k2, fp, bp, s);
}

/* NaN/Inf make x - x NaN, which poisons the sums. */
DV_TGT_AVX2 static bool finite_avx2(const double *x, size_t n)
{
    __m256d a0 = _mm256_setzero_pd(), a1 = a0, a2 = a0, a3 = a0;
    size_t i = 0u;
    for (; i + 16u <= n; i += 16u) {
        const __m256d v0 = _mm256_loadu_pd(x + i), v1 = _mm256_loadu_pd(x + i + 4u);
        const __m256d v2 = _mm256_loadu_pd(x + i + 8u), v3 = _mm256_loadu_pd(x + i + 12u);
        a0 = _mm256_add_pd(a0, _mm256_sub_pd(v0, v0));
        a1 = _mm256_add_pd(a1, _mm256_sub_pd(v1, v1));
        a2 = _mm256_add_pd(a2, _mm256_sub_pd(v2, v2));
        a3 = _mm256_add_pd(a3, _mm256_sub_pd(v3, v3));
    }
    double s = hsum256(_mm256_add_pd(_mm256_add_pd(a0, a1), _mm256_add_pd(a2, a3)));
    for (; i < n; i++) {
        s += x[i] - x[i];
    }
    return s == 0.0;
}

/* Streaming residual: one 128-bit pair of the newest samples from two scalar loads (a wide load
 * over them would wait for their stores to drain: store forwarding takes one store per load).
 * The high half goes through asm: compilers merge _mm_load_sd + _mm_loadh_pd into one load. */
DV_TGT_AVX2 static inline __m128d pair_ld(const double *w)
{
    __m128d v = _mm_load_sd(w);
    __asm__("vmovhpd %1, %0, %0" : "+x"(v) : "m"(w[1]));
    return v;
}

/* Streaming residual's prediction sum_{k<L} c[k] w[k], L = 8 nb + 4, nb <= 8: c the zero-padded
 * reversed coefficients, w the L samples ending with the newest, wn = w + 8 nb the newest four
 * (layout: dv_ar.c). The blocks
 * straight-line (a jump into the unrolled tail),
 * four accumulators, the newest four folded into the last 128-bit step. */
DV_TGT_AVX2 static inline double rpred_avx2(const double *c, const double *w, const double *wn,
                                         uint32_t nb)
{
    __m256d s0 = _mm256_setzero_pd(), s1 = s0, s2 = s0, s3 = s0;
#define DV_RB(A, B, K)                                                                             \
    A = _mm256_fmadd_pd(_mm256_loadu_pd(c + (K)), _mm256_loadu_pd(w + (K)), A);                    \
    B = _mm256_fmadd_pd(_mm256_loadu_pd(c + (K) + 4), _mm256_loadu_pd(w + (K) + 4), B)
    switch (nb) {
    case 8: DV_RB(s0, s1, 56); DV_FALLTHROUGH;
    case 7: DV_RB(s2, s3, 48); DV_FALLTHROUGH;
    case 6: DV_RB(s0, s1, 40); DV_FALLTHROUGH;
    case 5: DV_RB(s2, s3, 32); DV_FALLTHROUGH;
    case 4: DV_RB(s0, s1, 24); DV_FALLTHROUGH;
    case 3: DV_RB(s2, s3, 16); DV_FALLTHROUGH;
    case 2: DV_RB(s0, s1, 8); DV_FALLTHROUGH;
    case 1: DV_RB(s2, s3, 0); DV_FALLTHROUGH;
    default: break;
    }
#undef DV_RB
    const __m256d t = _mm256_add_pd(_mm256_add_pd(s0, s1), _mm256_add_pd(s2, s3));
    __m128d u = _mm_add_pd(_mm256_castpd256_pd128(t), _mm256_extractf128_pd(t, 1));
    const double *cn = c + 8u * nb;
    u = _mm_fmadd_pd(_mm_loadu_pd(cn), pair_ld(wn), u);
    u = _mm_fmadd_pd(_mm_loadu_pd(cn + 2), pair_ld(wn + 2), u);
    return _mm_cvtsd_f64(_mm_add_sd(u, _mm_unpackhi_pd(u, u)));
}

/* ------------------------------------------------------------------------------------------ */
/* x86-64, double: AVX-512F                                                                    */

DV_TGT_AVX512 static double dot_avx512(const double *a, const double *b, size_t n)
{
    __m512d s0 = _mm512_setzero_pd(), s1 = _mm512_setzero_pd();
    size_t i = 0u;
    for (; i + 16u <= n; i += 16u) {
        s0 = _mm512_fmadd_pd(_mm512_loadu_pd(a + i), _mm512_loadu_pd(b + i), s0);
        s1 = _mm512_fmadd_pd(_mm512_loadu_pd(a + i + 8u), _mm512_loadu_pd(b + i + 8u), s1);
    }
    if (i + 8u <= n) {
        s0 = _mm512_fmadd_pd(_mm512_loadu_pd(a + i), _mm512_loadu_pd(b + i), s0);
        i += 8u;
    }
    if (i < n) {
        const __mmask8 m = (__mmask8)((1u << (unsigned)(n - i)) - 1u);
        s1 = _mm512_fmadd_pd(_mm512_maskz_loadu_pd(m, a + i), _mm512_maskz_loadu_pd(m, b + i), s1);
    }
    return _mm512_reduce_add_pd(_mm512_add_pd(s0, s1));
}

#define DV_FMA8(S, B, W0, W1, W2, W3, W4, W5, W6, W7)                                             \
    do {                                                                                        \
        S##0 = _mm512_fmadd_pd(B, W0, S##0);                                                    \
        S##1 = _mm512_fmadd_pd(B, W1, S##1);                                                    \
        S##2 = _mm512_fmadd_pd(B, W2, S##2);                                                    \
        S##3 = _mm512_fmadd_pd(B, W3, S##3);                                                    \
        S##4 = _mm512_fmadd_pd(B, W4, S##4);                                                    \
        S##5 = _mm512_fmadd_pd(B, W5, S##5);                                                    \
        S##6 = _mm512_fmadd_pd(B, W6, S##6);                                                    \
        S##7 = _mm512_fmadd_pd(B, W7, S##7);                                                    \
    } while (0)

/* T[8j..8j+7] += A_j + B_j, then A_j = B_j = 0 (j = 0..7): one block's sums into the totals */
#define DV_ACF_ADD1(T, J, AJ, BJ)                                                                 \
    do {                                                                                        \
        _mm512_storeu_pd((T) + 8 * (J),                                                         \
                         _mm512_add_pd(_mm512_loadu_pd((T) + 8 * (J)), _mm512_add_pd(AJ, BJ))); \
        AJ = BJ = _mm512_setzero_pd();                                                          \
    } while (0)
#define DV_ACF_FLUSH(T, A, B)                                                                     \
    do {                                                                                        \
        DV_ACF_ADD1(T, 0, A##0, B##0);                                                          \
        DV_ACF_ADD1(T, 1, A##1, B##1);                                                          \
        DV_ACF_ADD1(T, 2, A##2, B##2);                                                          \
        DV_ACF_ADD1(T, 3, A##3, B##3);                                                          \
        DV_ACF_ADD1(T, 4, A##4, B##4);                                                          \
        DV_ACF_ADD1(T, 5, A##5, B##5);                                                          \
        DV_ACF_ADD1(T, 6, A##6, B##6);                                                          \
        DV_ACF_ADD1(T, 7, A##7, B##7);                                                          \
    } while (0)

/* As acf_avx2 with 8 x 8 lags and rows 8 apart, two rows (i, i+8) per step into two sets of
 * accumulators: row i+8's windows are row i's shifted by one vector (w1..w8), so a step costs
 * two loads, two broadcasts and 16 FMAs, and each accumulator chain sees one FMA per 16 (the
 * FMA latency no longer limits). The last rows, whose windows run past the record, go through
 * a zero-padded copy with the same vector code instead of scalar loops. */
DV_TGT_AVX512 static void acf_avx512(const double *x, size_t n, size_t maxlag, double *r)
{
    for (size_t g = 0u; g <= maxlag; g += 64u) {
        const __m512d z = _mm512_setzero_pd();
        double tot[64] = {0.0};
        __m512d a0 = z, a1 = z, a2 = z, a3 = z, a4 = z, a5 = z, a6 = z, a7 = z;
        __m512d b0 = z, b1 = z, b2 = z, b3 = z, b4 = z, b5 = z, b6 = z, b7 = z;
        const size_t imax = n > g + 63u ? n - g - 63u : 0u; /* rows whose 64 lags are in range */
        for (size_t i0 = 0u; i0 < imax; i0 += ACF_BLK) {
            const size_t iend = imax - i0 > ACF_BLK ? i0 + ACF_BLK : imax;
            for (size_t rho = i0; rho < i0 + 8u && rho < iend; rho++) {
                const double *w = x + rho + g;
                __m512d w0 = _mm512_loadu_pd(w), w1 = _mm512_loadu_pd(w + 8),
                        w2 = _mm512_loadu_pd(w + 16), w3 = _mm512_loadu_pd(w + 24),
                        w4 = _mm512_loadu_pd(w + 32), w5 = _mm512_loadu_pd(w + 40),
                        w6 = _mm512_loadu_pd(w + 48);
                size_t i = rho;
                for (; i + 8u < iend; i += 16u) {
                    const __m512d w7 = _mm512_loadu_pd(x + i + g + 56u);
                    const __m512d w8 = _mm512_loadu_pd(x + i + g + 64u);
                    const __m512d xa = _mm512_set1_pd(x[i]), xb = _mm512_set1_pd(x[i + 8u]);
                    DV_FMA8(a, xa, w0, w1, w2, w3, w4, w5, w6, w7);
                    DV_FMA8(b, xb, w1, w2, w3, w4, w5, w6, w7, w8);
                    w0 = w2; w1 = w3; w2 = w4; w3 = w5; w4 = w6; w5 = w7; w6 = w8;
                }
                if (i < iend) {
                    const __m512d w7 = _mm512_loadu_pd(x + i + g + 56u);
                    const __m512d xa = _mm512_set1_pd(x[i]);
                    DV_FMA8(a, xa, w0, w1, w2, w3, w4, w5, w6, w7);
                }
            }
            DV_ACF_FLUSH(tot, a, b);
        }
        if (n > g) {
            /* rows imax .. n-g-1 (at most 63); later rows have no lag of this group in range */
            double tb[128];
            const size_t base = imax + g;
            for (size_t j = 0u; j < 128u; j++) {
                tb[j] = base + j < n ? x[base + j] : 0.0;
            }
            for (size_t i = imax; i + g < n; i++) {
                const double *w = tb + (i - imax);
                const __m512d xb = _mm512_set1_pd(x[i]);
                DV_FMA8(b, xb, _mm512_loadu_pd(w), _mm512_loadu_pd(w + 8), _mm512_loadu_pd(w + 16),
                        _mm512_loadu_pd(w + 24), _mm512_loadu_pd(w + 32), _mm512_loadu_pd(w + 40),
                        _mm512_loadu_pd(w + 48), _mm512_loadu_pd(w + 56));
            }
            DV_ACF_FLUSH(tot, a, b);
        }
        for (size_t l = 0u; l < 64u && g + l <= maxlag; l++) {
            r[g + l] = tot[l];
        }
    }
}

#undef DV_ACF_FLUSH
#undef DV_ACF_ADD1

DV_TGT_AVX512 static double sum_avx512(const double *x, size_t n)
{
    __m512d s0 = _mm512_setzero_pd(), s1 = s0, s2 = s0, s3 = s0;
    size_t i = 0u;
    for (; i + 32u <= n; i += 32u) {
        s0 = _mm512_add_pd(s0, _mm512_loadu_pd(x + i));
        s1 = _mm512_add_pd(s1, _mm512_loadu_pd(x + i + 8u));
        s2 = _mm512_add_pd(s2, _mm512_loadu_pd(x + i + 16u));
        s3 = _mm512_add_pd(s3, _mm512_loadu_pd(x + i + 24u));
    }
    for (; i + 8u <= n; i += 8u) {
        s0 = _mm512_add_pd(s0, _mm512_loadu_pd(x + i));
    }
    if (i < n) {
        const __mmask8 m = (__mmask8)((1u << (unsigned)(n - i)) - 1u);
        s1 = _mm512_add_pd(s1, _mm512_maskz_loadu_pd(m, x + i));
    }
    return _mm512_reduce_add_pd(_mm512_add_pd(_mm512_add_pd(s0, s1), _mm512_add_pd(s2, s3)));
}

DV_TGT_AVX512 static void sub_avx512(const double *x, size_t n, double c, double *y)
{
    const __m512d vc = _mm512_set1_pd(c);
    size_t i = 0u;
    for (; i + 16u <= n; i += 16u) {
        const __m512d v0 = _mm512_loadu_pd(x + i), v1 = _mm512_loadu_pd(x + i + 8u);
        _mm512_storeu_pd(y + i, _mm512_sub_pd(v0, vc));
        _mm512_storeu_pd(y + i + 8u, _mm512_sub_pd(v1, vc));
    }
    for (; i < n; i++) {
        y[i] = x[i] - c;
    }
}

/* As rpred_avx2, 8 wide. */
DV_TGT_AVX512 static inline double rpred_avx512(const double *c, const double *w, const double *wn,
                                         uint32_t nb)
{
    __m512d s0 = _mm512_setzero_pd(), s1 = s0;
#define DV_RB(A, K) A = _mm512_fmadd_pd(_mm512_loadu_pd(c + (K)), _mm512_loadu_pd(w + (K)), A)
    switch (nb) {
    case 8: DV_RB(s1, 56); DV_FALLTHROUGH;
    case 7: DV_RB(s0, 48); DV_FALLTHROUGH;
    case 6: DV_RB(s1, 40); DV_FALLTHROUGH;
    case 5: DV_RB(s0, 32); DV_FALLTHROUGH;
    case 4: DV_RB(s1, 24); DV_FALLTHROUGH;
    case 3: DV_RB(s0, 16); DV_FALLTHROUGH;
    case 2: DV_RB(s1, 8); DV_FALLTHROUGH;
    case 1: DV_RB(s0, 0); DV_FALLTHROUGH;
    default: break;
    }
#undef DV_RB
    s0 = _mm512_add_pd(s0, s1);
    const __m256d t = _mm256_add_pd(_mm512_castpd512_pd256(s0), _mm512_extractf64x4_pd(s0, 1));
    __m128d u = _mm_add_pd(_mm256_castpd256_pd128(t), _mm256_extractf128_pd(t, 1));
    const double *cn = c + 8u * nb;
    u = _mm_fmadd_pd(_mm_loadu_pd(cn), pair_ld(wn), u);
    u = _mm_fmadd_pd(_mm_loadu_pd(cn + 2), pair_ld(wn + 2), u);
    return _mm_cvtsd_f64(_mm_add_sd(u, _mm_unpackhi_pd(u, u)));
}

/* One dv_ar_resid_update() step (x finite) around a prediction kernel, one function per ISA
 * and block count NB (a compile-time constant: no jump into the unrolled blocks, and few
 * enough live values that the leaf saves no callee-saved register). The counters are updated
 * before the prediction so that only h, y and p stay live across it. */
#define DV_AR_RSTEP(TGT, PRED, NB)                                                                 \
    TGT static dv_status_t rstep_##PRED##_##NB(dv_ar_resid_t *r, double x, double *e)             \
    {                                                                                              \
        const uint32_t p = r->p, head = r->head;                                                   \
        const uint64_t cnt = r->count;                                                             \
        double *h = r->hist + head; /* the last p centred samples, oldest first */                 \
        const double y = x - r->mean;                                                              \
        r->head = head + 1u == p ? 0u : head + 1u;                                                 \
        r->count = cnt + 1u;                                                                       \
        dv_status_t st = DV_ENOTREADY;                                                             \
        if (cnt >= p) {                                                                            \
            *e = y - PRED(r->c, h - r->off, h + p - 4u, NB);                                       \
            st = DV_OK;                                                                            \
        }                                                                                          \
        h[0] = y;                                                                                  \
        h[p] = y;                                                                                  \
        return st;                                                                                 \
    }

#define DV_AR_RSTEPS(TGT, PRED)                                                                    \
    DV_AR_RSTEP(TGT, PRED, 0)                                                                      \
    DV_AR_RSTEP(TGT, PRED, 1)                                                                      \
    DV_AR_RSTEP(TGT, PRED, 2)                                                                      \
    DV_AR_RSTEP(TGT, PRED, 3)                                                                      \
    DV_AR_RSTEP(TGT, PRED, 4)                                                                      \
    DV_AR_RSTEP(TGT, PRED, 5)                                                                      \
    DV_AR_RSTEP(TGT, PRED, 6)                                                                      \
    DV_AR_RSTEP(TGT, PRED, 7)                                                                      \
    DV_AR_RSTEP(TGT, PRED, 8)

DV_AR_RSTEPS(DV_TGT_AVX2, rpred_avx2)
DV_AR_RSTEPS(DV_TGT_AVX512, rpred_avx512)

/* A switch (a jump table of offsets in .rodata), not a table of function pointers: that
 * would be relocated data (.data.rel.ro), which the fixed-memory check rejects. */
#define DV_AR_RSTEP_CASE(K, PRED, NB)                                                              \
    case K:                                                                                        \
        return rstep_##PRED##_##NB(r, x, e)

dv_status_t dv_priv_ar_rstep(dv_ar_resid_t *r, double x, double *e)
{
    switch (r->step) {
        DV_AR_RSTEP_CASE(0u, rpred_avx2, 0);
        DV_AR_RSTEP_CASE(1u, rpred_avx2, 1);
        DV_AR_RSTEP_CASE(2u, rpred_avx2, 2);
        DV_AR_RSTEP_CASE(3u, rpred_avx2, 3);
        DV_AR_RSTEP_CASE(4u, rpred_avx2, 4);
        DV_AR_RSTEP_CASE(5u, rpred_avx2, 5);
        DV_AR_RSTEP_CASE(6u, rpred_avx2, 6);
        DV_AR_RSTEP_CASE(7u, rpred_avx2, 7);
        DV_AR_RSTEP_CASE(8u, rpred_avx2, 8);
        DV_AR_RSTEP_CASE(9u, rpred_avx512, 0);
        DV_AR_RSTEP_CASE(10u, rpred_avx512, 1);
        DV_AR_RSTEP_CASE(11u, rpred_avx512, 2);
        DV_AR_RSTEP_CASE(12u, rpred_avx512, 3);
        DV_AR_RSTEP_CASE(13u, rpred_avx512, 4);
        DV_AR_RSTEP_CASE(14u, rpred_avx512, 5);
        DV_AR_RSTEP_CASE(15u, rpred_avx512, 6);
        DV_AR_RSTEP_CASE(16u, rpred_avx512, 7);
    default:
        return rstep_rpred_avx512_8(r, x, e); /* step 17 */
    }
}

#undef DV_AR_RSTEP_CASE
#undef DV_AR_RSTEPS
#undef DV_AR_RSTEP

/* As fir_avx2 with 8 x 8 outputs and taps 8 apart. */
DV_TGT_AVX512 static void fir_avx512(const double *c, size_t p, double c0, const double *x,
                                     size_t n, double *e)
{
    const __m512d vc0 = _mm512_set1_pd(c0);
    size_t i = 0u;
    for (; i + 64u <= n; i += 64u) {
        const double *xi = x + i;
        __m512d s0 = _mm512_sub_pd(_mm512_loadu_pd(xi), vc0);
        __m512d s1 = _mm512_sub_pd(_mm512_loadu_pd(xi + 8), vc0);
        __m512d s2 = _mm512_sub_pd(_mm512_loadu_pd(xi + 16), vc0);
        __m512d s3 = _mm512_sub_pd(_mm512_loadu_pd(xi + 24), vc0);
        __m512d s4 = _mm512_sub_pd(_mm512_loadu_pd(xi + 32), vc0);
        __m512d s5 = _mm512_sub_pd(_mm512_loadu_pd(xi + 40), vc0);
        __m512d s6 = _mm512_sub_pd(_mm512_loadu_pd(xi + 48), vc0);
        __m512d s7 = _mm512_sub_pd(_mm512_loadu_pd(xi + 56), vc0);
        for (size_t j0 = 1u; j0 <= 8u && j0 <= p; j0++) {
            const double *w = xi - j0;
            __m512d w0 = _mm512_loadu_pd(w), w1 = _mm512_loadu_pd(w + 8), w2 = _mm512_loadu_pd(w + 16),
                    w3 = _mm512_loadu_pd(w + 24), w4 = _mm512_loadu_pd(w + 32),
                    w5 = _mm512_loadu_pd(w + 40), w6 = _mm512_loadu_pd(w + 48),
                    w7 = _mm512_loadu_pd(w + 56);
            for (size_t j = j0;;) {
                const __m512d aj = _mm512_set1_pd(c[p - j]);
                s0 = _mm512_fnmadd_pd(aj, w0, s0);
                s1 = _mm512_fnmadd_pd(aj, w1, s1);
                s2 = _mm512_fnmadd_pd(aj, w2, s2);
                s3 = _mm512_fnmadd_pd(aj, w3, s3);
                s4 = _mm512_fnmadd_pd(aj, w4, s4);
                s5 = _mm512_fnmadd_pd(aj, w5, s5);
                s6 = _mm512_fnmadd_pd(aj, w6, s6);
                s7 = _mm512_fnmadd_pd(aj, w7, s7);
                j += 8u;
                if (j > p) {
                    break;
                }
                w -= 8;
                w7 = w6; w6 = w5; w5 = w4; w4 = w3; w3 = w2; w2 = w1; w1 = w0;
                w0 = _mm512_loadu_pd(w);
            }
        }
        _mm512_storeu_pd(e + i, s0);
        _mm512_storeu_pd(e + i + 8, s1);
        _mm512_storeu_pd(e + i + 16, s2);
        _mm512_storeu_pd(e + i + 24, s3);
        _mm512_storeu_pd(e + i + 32, s4);
        _mm512_storeu_pd(e + i + 40, s5);
        _mm512_storeu_pd(e + i + 48, s6);
        _mm512_storeu_pd(e + i + 56, s7);
    }
    for (; i + 8u <= n; i += 8u) {
        __m512d s = _mm512_sub_pd(_mm512_loadu_pd(x + i), vc0);
        for (size_t j = 1u; j <= p; j++) {
            s = _mm512_fnmadd_pd(_mm512_set1_pd(c[p - j]), _mm512_loadu_pd(x + i - j), s);
        }
        _mm512_storeu_pd(e + i, s);
    }
    if (i < n) {
        fir_c(c, p, c0, x + i, n - i, e + i);
    }
}

DV_TGT_AVX512 static __m512d prev8(__m512d v, __m512d vprev)
{
    /* [vprev7, v0 .. v6] */
    return _mm512_castsi512_pd(
        _mm512_alignr_epi64(_mm512_castpd_si512(v), _mm512_castpd_si512(vprev), 7));
}

DV_TGT_AVX512 static void burg2_avx512(double *f, double *b, size_t len, double k1, double k2,
                                       double s[7])
{
    const __m512d v1 = _mm512_set1_pd(k1), v2 = _mm512_set1_pd(k2);
    __m512d a0 = _mm512_setzero_pd(), a1 = a0, a2 = a0, a3 = a0, a4 = a0, a5 = a0, a6 = a0;
    __m512d fprev = a0, bprev = a0;
    size_t j = 0u;
    for (; j + 8u + 2u <= len; j += 8u) {
        const __m512d f0 = _mm512_loadu_pd(f + j), f1 = _mm512_loadu_pd(f + j + 1u),
                      f2 = _mm512_loadu_pd(f + j + 2u);
        const __m512d b0 = _mm512_loadu_pd(b + j), b1 = _mm512_loadu_pd(b + j + 1u),
                      b2 = _mm512_loadu_pd(b + j + 2u);
        const __m512d fa = _mm512_fnmadd_pd(v1, b1, f1), ba = _mm512_fnmadd_pd(v1, f0, b0);
        const __m512d fb = _mm512_fnmadd_pd(v1, b2, f2), bb = _mm512_fnmadd_pd(v1, f1, b1);
        const __m512d fn = _mm512_fnmadd_pd(v2, bb, fb), bn = _mm512_fnmadd_pd(v2, fa, ba);
        _mm512_storeu_pd(f + j, fn);
        _mm512_storeu_pd(b + j, bn);
        const __m512d fs = prev8(fn, fprev), bs = prev8(bn, bprev);
        a0 = _mm512_fmadd_pd(fn, fn, a0);
        a1 = _mm512_fmadd_pd(bn, bn, a1);
        a2 = _mm512_fmadd_pd(fn, bn, a2);
        a3 = _mm512_fmadd_pd(fn, bs, a3);
        a4 = _mm512_fmadd_pd(fn, fs, a4);
        a5 = _mm512_fmadd_pd(bn, bs, a5);
        a6 = _mm512_fmadd_pd(bn, fs, a6);
        fprev = fn;
        bprev = bn;
    }
    double t[8];
    _mm512_storeu_pd(t, fprev);
    double fp = t[7];
    _mm512_storeu_pd(t, bprev);
    double bp = t[7];
    s[0] = _mm512_reduce_add_pd(a0);
    s[1] = _mm512_reduce_add_pd(a1);
    s[2] = _mm512_reduce_add_pd(a2);
    s[3] = _mm512_reduce_add_pd(a3);
    s[4] = _mm512_reduce_add_pd(a4);
    s[5] = _mm512_reduce_add_pd(a5);
    s[6] = _mm512_reduce_add_pd(a6);
    burg2_from(f, b, len, j, k1, k2, fp, bp, s);
}

#endif /* DV_SIMD_X86 */

/* ------------------------------------------------------------------------------------------ */
/* dispatch                                                                                    */

void dv_priv_ar_acf(const dv_real_t *x, size_t n, size_t maxlag, dv_real_t *r, uint32_t kern)
{
#if DV_SIMD_X86
    if (kern == 2u) {
        acf_avx512(x, n, maxlag, r);
        return;
    }
    if (kern == 1u) {
        acf_avx2(x, n, maxlag, r);
        return;
    }
#endif
    (void)kern;
    acf_c(x, n, maxlag, r);
}

dv_real_t dv_priv_ar_dot(const dv_real_t *a, const dv_real_t *b, size_t n, uint32_t kern)
{
#if DV_SIMD_X86
    if (kern == 2u) {
        return dot_avx512(a, b, n);
    }
    if (kern == 1u) {
        return dot_avx2(a, b, n);
    }
#endif
    (void)kern;
    return dot_c(a, b, n);
}

void dv_priv_ar_fir(const dv_real_t *c, size_t p, dv_real_t c0, const dv_real_t *x, size_t n,
                    dv_real_t *e, uint32_t kern)
{
#if DV_SIMD_X86
    if (kern == 2u) {
        fir_avx512(c, p, c0, x, n, e);
        return;
    }
    if (kern == 1u) {
        fir_avx2(c, p, c0, x, n, e);
        return;
    }
#endif
    (void)kern;
    fir_c(c, p, c0, x, n, e);
}

void dv_priv_ar_burg2(dv_real_t *f, dv_real_t *b, size_t len, dv_real_t k1, dv_real_t k2,
                      dv_real_t s[7], uint32_t kern)
{
#if DV_SIMD_X86
    if (kern == 2u) {
        burg2_avx512(f, b, len, k1, k2, s);
        return;
    }
    if (kern == 1u) {
        burg2_avx2(f, b, len, k1, k2, s);
        return;
    }
#endif
    (void)kern;
    burg2_c(f, b, len, k1, k2, s);
}

bool dv_priv_ar_all_finite(const dv_real_t *x, size_t n, uint32_t kern)
{
#if DV_SIMD_X86
    if (kern != 0u) {
        return finite_avx2(x, n); /* memory-bound: AVX2 is enough on AVX-512 machines too */
    }
#endif
    (void)kern;
    return dv_priv_all_finite(x, n);
}

dv_real_t dv_priv_ar_sum(const dv_real_t *x, size_t n, uint32_t kern)
{
#if DV_SIMD_X86
    if (kern == 2u) {
        return sum_avx512(x, n);
    }
#endif
    (void)kern;
    return sum_c(x, n);
}

void dv_priv_ar_sub(const dv_real_t *x, size_t n, dv_real_t c, dv_real_t *y, uint32_t kern)
{
#if DV_SIMD_X86
    if (kern == 2u) {
        sub_avx512(x, n, c, y);
        return;
    }
#endif
    (void)kern;
    for (size_t i = 0u; i < n; i++) {
        y[i] = x[i] - c;
    }
}

/* Waveform-feature block kernels: the channel bundle's fused block pass (power sums about a
 * shift, extremes, time-weighted energy sums) and the sliding window's turn-over (exact power
 * sums of the ring plus suffix extremes).
 *
 * The portable versions are plain C with two accumulator chains. On x86-64 double builds the
 * same loops also exist as AVX2/FMA and AVX-512F functions compiled with target attributes and
 * chosen at run time (as in dv_arkern.c), so a plain -O2 build (SSE2 baseline) still gets the
 * vector units. The arm-none-eabi and float builds see only C. The vector versions add in a
 * different order and fuse multiply-adds: results agree with the C ones to round-off. */
#include "dv_feat_core.h"
#include "dv_priv.h"

#if DV_SIMD_X86
#include <immintrin.h>
#endif

/* ------------------------------------------------------------------------------------------ */
/* portable C                                                                                  */

static void block_c(const dv_real_t *restrict x, dv_real_t k, dv_real_t p[4], dv_real_t mm[2],
                    dv_real_t w[5])
{
    dv_real_t p1 = DV_R(0.0), p2 = DV_R(0.0), p3 = DV_R(0.0), p4 = DV_R(0.0);
    dv_real_t w0 = DV_R(0.0), w1 = DV_R(0.0), w2 = DV_R(0.0), w3 = DV_R(0.0), w4 = DV_R(0.0);
    dv_real_t mn = mm[0], mx = mm[1], t = DV_R(0.0);
    for (size_t i = 0u; i < DV_BLOCK_LEN; i++) {
        const dv_real_t v = x[i];
        const dv_real_t u = v - k, u2 = u * u;
        p1 += u;
        p2 += u2;
        p3 += u2 * u;
        p4 += u2 * u2;
        const dv_real_t e = v * v, e1 = e * t, e2 = e1 * t, e3 = e2 * t;
        w0 += e;
        w1 += e1;
        w2 += e2;
        w3 += e3;
        w4 += e3 * t;
        t += DV_R(1.0);
        mn = v < mn ? v : mn;
        mx = v > mx ? v : mx;
    }
    p[0] = p1;
    p[1] = p2;
    p[2] = p3;
    p[3] = p4;
    mm[0] = mn;
    mm[1] = mx;
    w[0] = w0;
    w[1] = w1;
    w[2] = w2;
    w[3] = w3;
    w[4] = w4;
}

/* Backward pass over r[0..n): power sums of r - k, and smax[i] / smin[i] = extremes of
 * r[i..n). */
static void turn_c(const dv_real_t *restrict r, uint32_t n, dv_real_t k, dv_real_t *restrict smax,
                   dv_real_t *restrict smin, dv_real_t s[4])
{
    dv_real_t mx = -DV_REAL_MAX, mn = DV_REAL_MAX;
    dv_real_t a1 = DV_R(0.0), a2 = DV_R(0.0), a3 = DV_R(0.0), a4 = DV_R(0.0);
    dv_real_t b1 = DV_R(0.0), b2 = DV_R(0.0), b3 = DV_R(0.0), b4 = DV_R(0.0);
    uint32_t i = n;
    for (; i >= 2u; i -= 2u) {
        const dv_real_t v = r[i - 1u], w = r[i - 2u];
        const dv_real_t u = v - k, z = w - k;
        const dv_real_t u2 = u * u, z2 = z * z;
        a1 += u;
        b1 += z;
        a2 += u2;
        b2 += z2;
        a3 += u2 * u;
        b3 += z2 * z;
        a4 += u2 * u2;
        b4 += z2 * z2;
        mx = v > mx ? v : mx;
        mn = v < mn ? v : mn;
        smax[i - 1u] = mx;
        smin[i - 1u] = mn;
        mx = w > mx ? w : mx;
        mn = w < mn ? w : mn;
        smax[i - 2u] = mx;
        smin[i - 2u] = mn;
    }
    if (i == 1u) {
        const dv_real_t v = r[0], u = v - k, u2 = u * u;
        a1 += u;
        a2 += u2;
        a3 += u2 * u;
        a4 += u2 * u2;
        mx = v > mx ? v : mx;
        mn = v < mn ? v : mn;
        smax[0] = mx;
        smin[0] = mn;
    }
    s[0] = a1 + b1;
    s[1] = a2 + b2;
    s[2] = a3 + b3;
    s[3] = a4 + b4;
}

#if DV_SIMD_X86

#define DV_TGT_AVX2 __attribute__((target("avx2,fma")))
#define DV_TGT_AVX512 __attribute__((target("avx512f,avx2,fma")))

DV_TGT_AVX2 static double hsum4(__m256d v)
{
    const __m128d s = _mm_add_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
    return _mm_cvtsd_f64(_mm_add_sd(s, _mm_unpackhi_pd(s, s)));
}

DV_TGT_AVX2 static double hmin4(__m256d v)
{
    const __m128d s = _mm_min_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
    return _mm_cvtsd_f64(_mm_min_sd(s, _mm_unpackhi_pd(s, s)));
}

DV_TGT_AVX2 static double hmax4(__m256d v)
{
    const __m128d s = _mm_max_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
    return _mm_cvtsd_f64(_mm_max_sd(s, _mm_unpackhi_pd(s, s)));
}

/* {sum a, sum b, sum c, sum d} in one vector */
DV_TGT_AVX2 static __m256d hsum4x4(__m256d a, __m256d b, __m256d c, __m256d d)
{
    const __m256d ab = _mm256_hadd_pd(a, b), cd = _mm256_hadd_pd(c, d);
    return _mm256_add_pd(_mm256_permute2f128_pd(ab, cd, 0x20), _mm256_permute2f128_pd(ab, cd, 0x31));
}

DV_TGT_AVX2 static void block_avx2(const double *x, double k, double p[4], double mm[2],
                                   double w[5])
{
    const __m256d kv = _mm256_set1_pd(k), four = _mm256_set1_pd(4.0);
    __m256d p1 = _mm256_setzero_pd(), p2 = p1, p3 = p1, p4 = p1;
    __m256d w0 = p1, w1 = p1, w2 = p1, w3 = p1, w4 = p1;
    __m256d mn = _mm256_set1_pd(mm[0]), mx = _mm256_set1_pd(mm[1]);
    __m256d t = _mm256_set_pd(3.0, 2.0, 1.0, 0.0);
    for (size_t i = 0u; i < DV_BLOCK_LEN; i += 4u) {
        const __m256d v = _mm256_loadu_pd(x + i);
        const __m256d u = _mm256_sub_pd(v, kv), u2 = _mm256_mul_pd(u, u);
        p1 = _mm256_add_pd(p1, u);
        p2 = _mm256_add_pd(p2, u2);
        p3 = _mm256_fmadd_pd(u2, u, p3);
        p4 = _mm256_fmadd_pd(u2, u2, p4);
        const __m256d e = _mm256_mul_pd(v, v), e1 = _mm256_mul_pd(e, t);
        const __m256d e2 = _mm256_mul_pd(e1, t), e3 = _mm256_mul_pd(e2, t);
        w0 = _mm256_add_pd(w0, e);
        w1 = _mm256_add_pd(w1, e1);
        w2 = _mm256_add_pd(w2, e2);
        w3 = _mm256_add_pd(w3, e3);
        w4 = _mm256_fmadd_pd(e3, t, w4);
        t = _mm256_add_pd(t, four);
        mn = _mm256_min_pd(v, mn);
        mx = _mm256_max_pd(v, mx);
    }
    _mm256_storeu_pd(p, hsum4x4(p1, p2, p3, p4));
    _mm256_storeu_pd(w, hsum4x4(w0, w1, w2, w3));
    w[4] = hsum4(w4);
    mm[0] = hmin4(mn);
    mm[1] = hmax4(mx);
}

/* Suffix extremes four at a time, from the ring's end backwards: within a vector by two
 * shift-and-compare steps, then against the carry from the samples to its right. */
DV_TGT_AVX2 static void turn_avx2(const double *r, double *dst, uint32_t n, double k, double *smax,
                                  double *smin, double s[4])
{
    double mxs = -DV_REAL_MAX, mns = DV_REAL_MAX;
    double a[4] = {0.0, 0.0, 0.0, 0.0};
    uint32_t i = n;
    for (; (i & 3u) != 0u; i--) { /* the n % 4 last samples */
        const double v = r[i - 1u], u = v - k, u2 = u * u;
        dst[i - 1u] = v;
        a[0] += u;
        a[1] += u2;
        a[2] += u2 * u;
        a[3] += u2 * u2;
        mxs = v > mxs ? v : mxs;
        mns = v < mns ? v : mns;
        smax[i - 1u] = mxs;
        smin[i - 1u] = mns;
    }
    const __m256d kv = _mm256_set1_pd(k);
    __m256d p1 = _mm256_setzero_pd(), p2 = p1, p3 = p1, p4 = p1;
    __m256d cmx = _mm256_set1_pd(mxs), cmn = _mm256_set1_pd(mns);
    for (; i >= 4u; i -= 4u) {
        const __m256d v = _mm256_loadu_pd(r + i - 4u);
        _mm256_storeu_pd(dst + i - 4u, v);
        const __m256d u = _mm256_sub_pd(v, kv), u2 = _mm256_mul_pd(u, u);
        p1 = _mm256_add_pd(p1, u);
        p2 = _mm256_add_pd(p2, u2);
        p3 = _mm256_fmadd_pd(u2, u, p3);
        p4 = _mm256_fmadd_pd(u2, u2, p4);
        /* lanes (0,1,2,3) -> (1,2,3,3), then -> (2,3,3,3) */
        __m256d hx = _mm256_max_pd(v, _mm256_permute4x64_pd(v, 0xF9));
        __m256d hn = _mm256_min_pd(v, _mm256_permute4x64_pd(v, 0xF9));
        hx = _mm256_max_pd(hx, _mm256_permute4x64_pd(hx, 0xFE));
        hn = _mm256_min_pd(hn, _mm256_permute4x64_pd(hn, 0xFE));
        hx = _mm256_max_pd(hx, cmx);
        hn = _mm256_min_pd(hn, cmn);
        _mm256_storeu_pd(smax + i - 4u, hx);
        _mm256_storeu_pd(smin + i - 4u, hn);
        cmx = _mm256_permute4x64_pd(hx, 0x00);
        cmn = _mm256_permute4x64_pd(hn, 0x00);
    }
    s[0] = hsum4(p1) + a[0];
    s[1] = hsum4(p2) + a[1];
    s[2] = hsum4(p3) + a[2];
    s[3] = hsum4(p4) + a[3];
}

/* Lane j of the result: sum of vector j (a, b, c, d, e, f, g, h) */
DV_TGT_AVX512 static __m512d pairsum8(__m512d a, __m512d b)
{
    return _mm512_add_pd(_mm512_unpacklo_pd(a, b), _mm512_unpackhi_pd(a, b));
}

DV_TGT_AVX512 static __m512d lanesum8(__m512d a, __m512d b)
{
    return _mm512_add_pd(_mm512_shuffle_f64x2(a, b, 0x88), _mm512_shuffle_f64x2(a, b, 0xDD));
}

DV_TGT_AVX512 static __m512d hsum8x8(__m512d a, __m512d b, __m512d c, __m512d d, __m512d e,
                                     __m512d f, __m512d g, __m512d h)
{
    const __m512d abcd = lanesum8(pairsum8(a, b), pairsum8(c, d));
    const __m512d efgh = lanesum8(pairsum8(e, f), pairsum8(g, h));
    return lanesum8(abcd, efgh);
}

DV_TGT_AVX512 static void block_avx512(const double *x, double k, double p[4], double mm[2],
                                       double w[5])
{
    const __m512d kv = _mm512_set1_pd(k), eight = _mm512_set1_pd(8.0);
    __m512d p1 = _mm512_setzero_pd(), p2 = p1, p3 = p1, p4 = p1;
    __m512d w0 = p1, w1 = p1, w2 = p1, w3 = p1, w4 = p1;
    __m512d mn = _mm512_set1_pd(mm[0]), mx = _mm512_set1_pd(mm[1]);
    __m512d t = _mm512_set_pd(7.0, 6.0, 5.0, 4.0, 3.0, 2.0, 1.0, 0.0);
    for (size_t i = 0u; i < DV_BLOCK_LEN; i += 8u) {
        const __m512d v = _mm512_loadu_pd(x + i);
        const __m512d u = _mm512_sub_pd(v, kv), u2 = _mm512_mul_pd(u, u);
        p1 = _mm512_add_pd(p1, u);
        p2 = _mm512_add_pd(p2, u2);
        p3 = _mm512_fmadd_pd(u2, u, p3);
        p4 = _mm512_fmadd_pd(u2, u2, p4);
        const __m512d e = _mm512_mul_pd(v, v), e1 = _mm512_mul_pd(e, t);
        const __m512d e2 = _mm512_mul_pd(e1, t), e3 = _mm512_mul_pd(e2, t);
        w0 = _mm512_add_pd(w0, e);
        w1 = _mm512_add_pd(w1, e1);
        w2 = _mm512_add_pd(w2, e2);
        w3 = _mm512_add_pd(w3, e3);
        w4 = _mm512_fmadd_pd(e3, t, w4);
        t = _mm512_add_pd(t, eight);
        mn = _mm512_min_pd(v, mn);
        mx = _mm512_max_pd(v, mx);
    }
    const __m512d sums = hsum8x8(p1, p2, p3, p4, w0, w1, w2, w3);
    _mm256_storeu_pd(p, _mm512_castpd512_pd256(sums));
    _mm256_storeu_pd(w, _mm512_extractf64x4_pd(sums, 1));
    w[4] = _mm512_reduce_add_pd(w4);
    mm[0] = _mm512_reduce_min_pd(mn);
    mm[1] = _mm512_reduce_max_pd(mx);
}

DV_TGT_AVX512 static void turn_avx512(const double *r, double *dst, uint32_t n, double k,
                                      double *smax, double *smin, double s[4])
{
    double mxs = -DV_REAL_MAX, mns = DV_REAL_MAX;
    double a[4] = {0.0, 0.0, 0.0, 0.0};
    uint32_t i = n;
    for (; (i & 7u) != 0u; i--) { /* the n % 8 last samples */
        const double v = r[i - 1u], u = v - k, u2 = u * u;
        dst[i - 1u] = v;
        a[0] += u;
        a[1] += u2;
        a[2] += u2 * u;
        a[3] += u2 * u2;
        mxs = v > mxs ? v : mxs;
        mns = v < mns ? v : mns;
        smax[i - 1u] = mxs;
        smin[i - 1u] = mns;
    }
    const __m512d kv = _mm512_set1_pd(k);
    const __m512i sh1 = _mm512_set_epi64(7, 7, 6, 5, 4, 3, 2, 1);
    const __m512i sh2 = _mm512_set_epi64(7, 7, 7, 6, 5, 4, 3, 2);
    const __m512i sh4 = _mm512_set_epi64(7, 7, 7, 7, 7, 6, 5, 4);
    const __m512i lane0 = _mm512_setzero_si512();
    __m512d p1 = _mm512_setzero_pd(), p2 = p1, p3 = p1, p4 = p1;
    __m512d cmx = _mm512_set1_pd(mxs), cmn = _mm512_set1_pd(mns);
    for (; i >= 8u; i -= 8u) {
        const __m512d v = _mm512_loadu_pd(r + i - 8u);
        _mm512_storeu_pd(dst + i - 8u, v);
        const __m512d u = _mm512_sub_pd(v, kv), u2 = _mm512_mul_pd(u, u);
        p1 = _mm512_add_pd(p1, u);
        p2 = _mm512_add_pd(p2, u2);
        p3 = _mm512_fmadd_pd(u2, u, p3);
        p4 = _mm512_fmadd_pd(u2, u2, p4);
        __m512d hx = _mm512_max_pd(v, _mm512_permutexvar_pd(sh1, v));
        __m512d hn = _mm512_min_pd(v, _mm512_permutexvar_pd(sh1, v));
        hx = _mm512_max_pd(hx, _mm512_permutexvar_pd(sh2, hx));
        hn = _mm512_min_pd(hn, _mm512_permutexvar_pd(sh2, hn));
        hx = _mm512_max_pd(hx, _mm512_permutexvar_pd(sh4, hx));
        hn = _mm512_min_pd(hn, _mm512_permutexvar_pd(sh4, hn));
        hx = _mm512_max_pd(hx, cmx);
        hn = _mm512_min_pd(hn, cmn);
        _mm512_storeu_pd(smax + i - 8u, hx);
        _mm512_storeu_pd(smin + i - 8u, hn);
        cmx = _mm512_permutexvar_pd(lane0, hx);
        cmn = _mm512_permutexvar_pd(lane0, hn);
    }
    s[0] = _mm512_reduce_add_pd(p1) + a[0];
    s[1] = _mm512_reduce_add_pd(p2) + a[1];
    s[2] = _mm512_reduce_add_pd(p3) + a[2];
    s[3] = _mm512_reduce_add_pd(p4) + a[3];
}

#endif /* DV_SIMD_X86 */

/* ------------------------------------------------------------------------------------------ */
/* dispatch                                                                                    */

void dv_priv_feat_block(uint32_t kern, const dv_real_t *x, dv_real_t k, dv_real_t p[4],
                        dv_real_t mm[2], dv_real_t w[5])
{
    (void)kern;
#if DV_SIMD_X86 && (DV_BLOCK_LEN % 8u == 0u)
    if (kern == 2u) {
        block_avx512(x, k, p, mm, w);
        return;
    }
    if (kern == 1u) {
        block_avx2(x, k, p, mm, w);
        return;
    }
#endif
    block_c(x, k, p, mm, w);
}

void dv_priv_feat_turn(const dv_real_t *src, dv_real_t *ring, uint32_t n, dv_real_t k,
                       dv_real_t *smax, dv_real_t *smin, dv_real_t s[4])
{
#if DV_SIMD_X86
    const uint32_t kern = dv_priv_simd_kern();
    if (kern == 2u) {
        turn_avx512(src, ring, n, k, smax, smin, s);
        return;
    }
    if (kern == 1u) {
        turn_avx2(src, ring, n, k, smax, smin, s);
        return;
    }
#endif
    if (src != ring) {
        for (uint32_t i = 0u; i < n; i++) {
            ring[i] = src[i];
        }
    }
    turn_c(ring, n, k, smax, smin, s);
}

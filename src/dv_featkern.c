/* Waveform-feature block kernels: the channel bundle's fused block pass (power sums about a
 * shift, extremes, time-weighted energy sums) and the sliding window's turn-over (exact power
 * sums of the ring and the extremes of each DV_SLIDING_BLK block).
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

/* From i (a multiple of DV_SLIDING_BLK) on: power sums of r - k added to a, and each block's
 * extremes bmax[b] / bmin[b] (the last block may be short). The portable turn-over, and the
 * vector ones' tails. */
static void turn_from(const dv_real_t *restrict r, uint32_t i, uint32_t n, dv_real_t k,
                      dv_real_t a[4], dv_real_t *restrict bmax, dv_real_t *restrict bmin)
{
    dv_real_t a1 = a[0], a2 = a[1], a3 = a[2], a4 = a[3];
    while (i < n) {
        const uint32_t b = i / DV_SLIDING_BLK;
        const uint32_t end = n - i < DV_SLIDING_BLK ? n : i + DV_SLIDING_BLK;
        dv_real_t mx = -DV_REAL_MAX, mn = DV_REAL_MAX;
        for (; i < end; i++) {
            const dv_real_t v = r[i], u = v - k, u2 = u * u;
            a1 += u;
            a2 += u2;
            a3 += u2 * u;
            a4 += u2 * u2;
            mx = v > mx ? v : mx;
            mn = v < mn ? v : mn;
        }
        bmax[b] = mx;
        bmin[b] = mn;
    }
    a[0] = a1;
    a[1] = a2;
    a[2] = a3;
    a[3] = a4;
}

#if DV_SIMD_X86


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

/* Whole blocks of DV_SLIDING_BLK = 16 samples as four vectors, then the scalar tail. */
DV_TGT_AVX2 static void turn_avx2(const double *r, double *dst, uint32_t n, double k,
                                  double *bmax, double *bmin, double s[4])
{
    double a[4] = {0.0, 0.0, 0.0, 0.0};
    const __m256d kv = _mm256_set1_pd(k);
    __m256d p1 = _mm256_setzero_pd(), p2 = p1, p3 = p1, p4 = p1;
    uint32_t i = 0u;
    for (; i + 16u <= n; i += 16u) {
        __m256d mx = _mm256_set1_pd(-DV_REAL_MAX), mn = _mm256_set1_pd(DV_REAL_MAX);
        for (uint32_t j = 0u; j < 16u; j += 4u) {
            const __m256d v = _mm256_loadu_pd(r + i + j);
            _mm256_storeu_pd(dst + i + j, v);
            const __m256d u = _mm256_sub_pd(v, kv), u2 = _mm256_mul_pd(u, u);
            p1 = _mm256_add_pd(p1, u);
            p2 = _mm256_add_pd(p2, u2);
            p3 = _mm256_fmadd_pd(u2, u, p3);
            p4 = _mm256_fmadd_pd(u2, u2, p4);
            mx = _mm256_max_pd(mx, v);
            mn = _mm256_min_pd(mn, v);
        }
        bmax[i / 16u] = hmax4(mx);
        bmin[i / 16u] = hmin4(mn);
    }
    for (uint32_t j = i; j < n; j++) {
        dst[j] = r[j];
    }
    turn_from(dst, i, n, k, a, bmax, bmin);
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
                                      double *bmax, double *bmin, double s[4])
{
    double a[4] = {0.0, 0.0, 0.0, 0.0};
    const __m512d kv = _mm512_set1_pd(k);
    __m512d p1 = _mm512_setzero_pd(), p2 = p1, p3 = p1, p4 = p1;
    uint32_t i = 0u;
    for (; i + 16u <= n; i += 16u) {
        const __m512d v = _mm512_loadu_pd(r + i), w = _mm512_loadu_pd(r + i + 8u);
        _mm512_storeu_pd(dst + i, v);
        _mm512_storeu_pd(dst + i + 8u, w);
        const __m512d u = _mm512_sub_pd(v, kv), u2 = _mm512_mul_pd(u, u);
        const __m512d z = _mm512_sub_pd(w, kv), z2 = _mm512_mul_pd(z, z);
        p1 = _mm512_add_pd(p1, _mm512_add_pd(u, z));
        p2 = _mm512_add_pd(p2, _mm512_add_pd(u2, z2));
        p3 = _mm512_fmadd_pd(u2, u, _mm512_fmadd_pd(z2, z, p3));
        p4 = _mm512_fmadd_pd(u2, u2, _mm512_fmadd_pd(z2, z2, p4));
        bmax[i / 16u] = _mm512_reduce_max_pd(_mm512_max_pd(v, w));
        bmin[i / 16u] = _mm512_reduce_min_pd(_mm512_min_pd(v, w));
    }
    for (uint32_t j = i; j < n; j++) {
        dst[j] = r[j];
    }
    turn_from(dst, i, n, k, a, bmax, bmin);
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

void dv_priv_feat_turn(uint32_t kern, const dv_real_t *src, dv_real_t *ring, uint32_t n,
                       dv_real_t k, dv_real_t *bmax, dv_real_t *bmin, dv_real_t s[4])
{
    (void)kern;
#if DV_SIMD_X86
    if (kern == 2u) {
        turn_avx512(src, ring, n, k, bmax, bmin, s);
        return;
    }
    if (kern == 1u) {
        turn_avx2(src, ring, n, k, bmax, bmin, s);
        return;
    }
#endif
    if (src != ring) {
        for (uint32_t i = 0u; i < n; i++) {
            ring[i] = src[i];
        }
    }
    dv_real_t a[4] = {DV_R(0.0), DV_R(0.0), DV_R(0.0), DV_R(0.0)};
    turn_from(ring, 0u, n, k, a, bmax, bmin);
    for (int q = 0; q < 4; q++) {
        s[q] = a[q];
    }
}

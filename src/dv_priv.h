/* Internal helpers shared by the dynval modules. Not installed, not part of the API. */
#ifndef DV_PRIV_H
#define DV_PRIV_H

#include <math.h>

#include "dynval/dv_types.h"
#include "dynval/dv_config.h"
#include "dynval/dv_moments.h"

#ifdef DV_REAL_DOUBLE
#define DV_SQRT(x) sqrt(x)
#define DV_FABS(x) fabs(x)
#define DV_CBRT(x) cbrt(x)
#define DV_EXP(x) exp(x)
#define DV_LOG(x) log(x)
#define DV_POW(x, y) pow(x, y)
#define DV_COS(x) cos(x)
#define DV_SIN(x) sin(x)
#define DV_FLOOR(x) floor(x)
#define DV_LDEXP(x, e) ldexp(x, e)
#define DV_FREXP(x, e) frexp(x, e)
#else
#define DV_SQRT(x) sqrtf(x)
#define DV_FABS(x) fabsf(x)
#define DV_CBRT(x) cbrtf(x)
#define DV_EXP(x) expf(x)
#define DV_LOG(x) logf(x)
#define DV_POW(x, y) powf(x, y)
#define DV_COS(x) cosf(x)
#define DV_SIN(x) sinf(x)
#define DV_FLOOR(x) floorf(x)
#define DV_LDEXP(x, e) ldexpf(x, e)
#define DV_FREXP(x, e) frexpf(x, e)
#endif

/* isfinite() without the macro's generic dispatch: x - x is 0 for finite x, NaN otherwise. */
static inline bool dv_priv_finite(dv_real_t x)
{
    return (x - x) == DV_R(0.0);
}

/* True when every x[0..n) is finite: NaN and Inf turn x - x into NaN, which poisons the sum.
 * Two lanes, no branches: a cheap pre-check for the block paths. */
static inline bool dv_priv_all_finite(const dv_real_t *x, size_t n)
{
    dv_real_t a = DV_R(0.0), b = DV_R(0.0);
    size_t i = 0u;
    for (; i + 1u < n; i += 2u) {
        a += x[i] - x[i];
        b += x[i + 1u] - x[i + 1u];
    }
    if (i < n) {
        a += x[i] - x[i];
    }
    return a + b == DV_R(0.0);
}

/* A sample the waveform features accept: finite and |x| <= DV_FEAT_MAX (one compare: NaN fails
 * it too). Beyond DV_FEAT_MAX a fourth-power sum could overflow. */
static inline bool dv_priv_in_range(dv_real_t x)
{
    return DV_FABS(x) <= DV_FEAT_MAX;
}

/* Smallest variance with a defined shape: var * var and var * std stay normal numbers. */
#ifdef DV_REAL_DOUBLE
#define DV_PRIV_VAR_MIN 3.054936363499605e-151 /* 2^-500 */
#else
#define DV_PRIV_VAR_MIN 8.6736174e-19f /* 2^-60 */
#endif

/* dv_priv_in_range() of every x[0..n), branch-free (vectorises). */
static inline bool dv_priv_all_in_range(const dv_real_t *x, size_t n)
{
    unsigned bad = 0u;
    for (size_t i = 0u; i < n; i++) {
        bad |= (unsigned)!(DV_FABS(x[i]) <= DV_FEAT_MAX);
    }
    return bad == 0u;
}

/* Central moments of a (weighted) set: weight n (count or sum of weights), mean,
 * and the central sums m2 = sum w (x-mean)^2, m3, m4. Exact to merge (Pebay 2008). */
typedef struct {
    dv_real_t n;
    dv_real_t mean;
    dv_real_t m2;
    dv_real_t m3;
    dv_real_t m4;
} dv_priv_cm_t;

/* Power sums s_k = sum w d^k (k = 0..4) about a shift, turned into central moments. */
void dv_priv_cm_from_sums(dv_priv_cm_t *out, dv_real_t shift, dv_real_t s0, dv_real_t s1,
                          dv_real_t s2, dv_real_t s3, dv_real_t s4);

/* a <- a (+) b: exact combination of two partial results (Chan et al. / Pebay). */
void dv_priv_cm_merge(dv_priv_cm_t *a, const dv_priv_cm_t *b);

/* Re-express power sums s1..s4 of n samples about shift k_old as sums about k_old - delta
 * (binomial expansion; exact in exact arithmetic, well conditioned for |delta| ~ spread). */
void dv_priv_sums_shift(dv_real_t s[4], dv_real_t n, dv_real_t delta);

/* Fill the statistics of a set from its central moments and extremes. */
void dv_priv_stats_fill(dv_stats_t *out, const dv_priv_cm_t *cm, uint64_t count, dv_real_t min,
                        dv_real_t max);

/* ---- Vector kernels: on x86-64 double builds (gcc, clang) the hot loops also exist as AVX2/FMA
 * and AVX-512F functions (target attributes), picked at run time (dv_arkern.c, dv_featkern.c,
 * dv_obskern.c); float and Cortex-M builds see only C. No public size depends on this
 * condition (DV_OBS_MODAL_LEN reserves the modal form in every double build). ---- */
#if defined(DV_REAL_DOUBLE) && defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && \
    !defined(DV_NO_SIMD)
#define DV_SIMD_X86 1
#else
#define DV_SIMD_X86 0
#endif

#if DV_SIMD_X86
/* The target attributes of the kernels, one definition: exactly the features
 * dv_priv_simd_kern() checks before it hands out kernel 2 (AVX-512) or 1 (AVX2). */
#define DV_TGT_AVX2 __attribute__((target("avx2,fma")))
#define DV_TGT_AVX512 __attribute__((target("avx512f,avx512dq,avx512vl,avx2,fma")))
#endif

/* The vector unit this CPU offers the kernels: 0 portable C, 1 AVX2 + FMA, 2 AVX-512 F, DQ and
 * VL (always 0 without DV_SIMD_X86). Instances (features, AR residual, observer) ask at init
 * and keep it; one-shot record functions ask once per call. */
#if DV_SIMD_X86
uint32_t dv_priv_simd_kern(void);
#else
static inline uint32_t dv_priv_simd_kern(void)
{
    return 0u; /* no call where there is nothing to ask (Cortex-M flash) */
}
#endif

/* ---- AR kernels (src/dv_arkern.c); kern from dv_priv_simd_kern(). ---- */

#if DV_SIMD_X86
#include "dynval/dv_ar.h"
/* dv_ar_resid_update() after the finite check, x finite, for r->kern != 0: a tail jump to the
 * whole step in one leaf function (prediction, history stores, counters) specialised for the
 * ISA and block count, r->step = 9 (kern - 1) + nb. */
dv_status_t dv_priv_ar_rstep(dv_ar_resid_t *r, double x, double *e);
#endif

/* r[k] = sum_{i=0}^{n-1-k} x_i x_{i+k}, k = 0..maxlag, maxlag < n (no 1/n). */
void dv_priv_ar_acf(const dv_real_t *x, size_t n, size_t maxlag, dv_real_t *r, uint32_t kern);

/* sum_{i<n} a_i b_i with independent partial sums. */
dv_real_t dv_priv_ar_dot(const dv_real_t *a, const dv_real_t *b, size_t n, uint32_t kern);

/* e[i] = x[i] - c0 - sum_{j=1..p} c[p-j] x[i-j], i = 0..n-1 (c = a_p..a_1, reversed);
 * x[-p..-1] must be readable. @p e must not overlap @p x. */
void dv_priv_ar_fir(const dv_real_t *c, size_t p, dv_real_t c0, const dv_real_t *x, size_t n,
                    dv_real_t *e, uint32_t kern);

/* Two Burg stages in one pass on aligned errors f[0..len), b[0..len) (f[j] = f(i),
 * b[j] = b(i-1)); one stage with k is b[j] -= k f[j]; f[j] = f[j+1] - k b[j+1] (old values),
 * j < len-1; first k1, then k2. Leaves len-2 values and returns the sums the next two stages need, over
 * the new values F, B (j < len-2): s[0] = sum F^2, s[1] = sum B^2, s[2] = sum F B, and the lag-1
 * sums s[3] = sum F[j+1] B[j], s[4] = sum F[j+1] F[j], s[5] = sum B[j+1] B[j],
 * s[6] = sum B[j+1] F[j]. Needs len >= 3. */
void dv_priv_ar_burg2(dv_real_t *f, dv_real_t *b, size_t len, dv_real_t k1, dv_real_t k2,
                      dv_real_t s[7], uint32_t kern);

/* dv_priv_all_finite with the AR kernels' vector units (block residual pre-check). */
bool dv_priv_ar_all_finite(const dv_real_t *x, size_t n, uint32_t kern);


/* sum_{i<n} x_i with independent partial sums (AR record mean). */
dv_real_t dv_priv_ar_sum(const dv_real_t *x, size_t n, uint32_t kern);

/* y[i] = x[i] - c, i < n (y may equal x). */
void dv_priv_ar_sub(const dv_real_t *x, size_t n, dv_real_t c, dv_real_t *y, uint32_t kern);

#endif /* DV_PRIV_H */

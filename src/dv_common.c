/* Status strings and the exact moment-merge arithmetic every feature module builds on. */
#include "dv_priv.h"

#if DV_SIMD_X86
uint32_t dv_priv_simd_kern(void)
{
    /* libgcc/compiler-rt check CPUID and that the OS saves the wide registers (XGETBV). */
    __builtin_cpu_init();
    /* F for every AVX-512 kernel; DQ and VL for the observer's (every AVX-512 x86-64 CPU
     * since Skylake-SP has all three) */
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
        __builtin_cpu_supports("avx512vl")) {
        return 2u;
    }
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
        return 1u;
    }
    return 0u;
}
#endif

const char *dv_status_str(dv_status_t st)
{
    switch (st) {
    case DV_OK: return "DV_OK";
    case DV_DONE: return "DV_DONE";
    case DV_RECORD: return "DV_RECORD";
    case DV_EINVAL: return "DV_EINVAL";
    case DV_ESIZE: return "DV_ESIZE";
    case DV_ENOTREADY: return "DV_ENOTREADY";
    case DV_ENUMERIC: return "DV_ENUMERIC";
    case DV_EUNSTABLE: return "DV_EUNSTABLE";
    case DV_ERANGE: return "DV_ERANGE";
    }
    return "DV_E?";
}

size_t dv_real_size(void)
{
    return sizeof(dv_real_t);
}

void dv_priv_cm_from_sums(dv_priv_cm_t *out, dv_real_t shift, dv_real_t s0, dv_real_t s1,
                          dv_real_t s2, dv_real_t s3, dv_real_t s4)
{
    const dv_real_t mu = s1 / s0; /* mean offset from the shift */
    const dv_real_t mu2 = mu * mu;
    out->n = s0;
    out->mean = shift + mu;
    out->m2 = s2 - mu * s1;
    out->m3 = s3 - DV_R(3.0) * mu * s2 + DV_R(2.0) * mu2 * s1;
    out->m4 = s4 - DV_R(4.0) * mu * s3 + DV_R(6.0) * mu2 * s2 - DV_R(3.0) * mu2 * mu * s1;
    if (out->m2 < DV_R(0.0)) {
        out->m2 = DV_R(0.0); /* round-off on a constant block */
    }
    if (out->m4 < DV_R(0.0)) {
        out->m4 = DV_R(0.0);
    }
}

void dv_priv_cm_merge(dv_priv_cm_t *a, const dv_priv_cm_t *b)
{
    if (b->n <= DV_R(0.0)) {
        return;
    }
    if (a->n <= DV_R(0.0)) {
        *a = *b;
        return;
    }
    const dv_real_t na = a->n, nb = b->n;
    const dv_real_t n = na + nb;
    const dv_real_t d = b->mean - a->mean;
    const dv_real_t dn = d / n;
    const dv_real_t dn2 = dn * dn;
    const dv_real_t c2 = d * dn * na * nb;       /* d^2 na nb / n */
    const dv_real_t m4 = a->m4 + b->m4 + c2 * dn2 * (na * na - na * nb + nb * nb) +
                         DV_R(6.0) * dn2 * (na * na * b->m2 + nb * nb * a->m2) +
                         DV_R(4.0) * dn * (na * b->m3 - nb * a->m3);
    const dv_real_t m3 = a->m3 + b->m3 + c2 * dn * (na - nb) +
                         DV_R(3.0) * dn * (na * b->m2 - nb * a->m2);
    a->m2 = a->m2 + b->m2 + c2;
    a->m3 = m3;
    a->m4 = m4;
    a->mean = a->mean + dn * nb;
    a->n = n;
}

void dv_priv_sums_shift(dv_real_t s[4], dv_real_t n, dv_real_t delta)
{
    /* d' = d + delta */
    const dv_real_t d2 = delta * delta, d3 = d2 * delta, d4 = d3 * delta;
    const dv_real_t s1 = s[0], s2 = s[1], s3 = s[2], s4 = s[3];
    s[0] = s1 + n * delta;
    s[1] = s2 + DV_R(2.0) * delta * s1 + n * d2;
    s[2] = s3 + DV_R(3.0) * delta * s2 + DV_R(3.0) * d2 * s1 + n * d3;
    s[3] = s4 + DV_R(4.0) * delta * s3 + DV_R(6.0) * d2 * s2 + DV_R(4.0) * d3 * s1 + n * d4;
}

/* Radix-2 decimation-in-time FFT: bit-reversal permutation, then log2(n) butterfly passes. */
#include "dynval/dv_fft.h"
#include "dv_priv.h"

dv_status_t dv_fft_init(dv_fft_t *f, size_t n, dv_real_t *buf, size_t len)
{
    if (f == NULL || buf == NULL || n < DV_FFT_MIN_LEN || n > DV_FFT_MAX_LEN ||
        (n & (n - 1u)) != 0u) {
        return DV_EINVAL;
    }
    if (len < DV_FFT_BUF_LEN(n)) {
        return DV_ESIZE;
    }
    /* Only the first octant is evaluated; the rest follows by symmetry, so that every twiddle
     * has the accuracy of a small-angle cos/sin (float cosf(x) near pi/2 loses digits in x). */
    const size_t h = n / 2u, q = n / 4u, e = n / 8u;
    const dv_real_t step = DV_R(6.283185307179586) / (dv_real_t)n;
    for (size_t k = 0u; k <= e && k < h; k++) {
        const dv_real_t c = DV_COS(step * (dv_real_t)k), s = DV_SIN(step * (dv_real_t)k);
        buf[2u * k] = c;
        buf[2u * k + 1u] = -s;
        if (k != 0u && k < q) { /* angle pi/2 - a: cos and sin swap */
            buf[2u * (q - k)] = s;
            buf[2u * (q - k) + 1u] = -c;
        }
    }
    if (q > 0u) {
        buf[2u * q] = DV_R(0.0);
        buf[2u * q + 1u] = DV_R(-1.0);
    }
    for (size_t k = q + 1u; k < h; k++) { /* angle pi/2 + a: cos(.) = -sin a, sin(.) = cos a */
        buf[2u * k] = buf[2u * (k - q) + 1u];
        buf[2u * k + 1u] = -buf[2u * (k - q)];
    }
    f->tw = buf;
    f->n = (uint32_t)n;
    return DV_OK;
}

/* n-point complex transform with the twiddles of a (stride n)-point table: the real transform
 * runs its n/2-point half on every other twiddle of the n-point table. */
static void cfft(const dv_real_t *tw, uint32_t tw_stride, uint32_t n, dv_real_t *x)
{
    for (uint32_t i = 1u, j = 0u; i < n; i++) {
        uint32_t bit = n >> 1;
        for (; (j & bit) != 0u; bit >>= 1) {
            j ^= bit;
        }
        j ^= bit;
        if (i < j) {
            const dv_real_t tr = x[2u * i], ti = x[2u * i + 1u];
            x[2u * i] = x[2u * j];
            x[2u * i + 1u] = x[2u * j + 1u];
            x[2u * j] = tr;
            x[2u * j + 1u] = ti;
        }
    }
    for (uint32_t half = 1u, stride = tw_stride * (n >> 1); half < n; half <<= 1, stride >>= 1) {
        for (uint32_t i = 0u; i < n; i += 2u * half) {
            for (uint32_t k = 0u; k < half; k++) {
                const dv_real_t wr = tw[2u * k * stride], wi = tw[2u * k * stride + 1u];
                dv_real_t *a = x + 2u * (i + k), *b = a + 2u * half;
                const dv_real_t tr = b[0] * wr - b[1] * wi, ti = b[0] * wi + b[1] * wr;
                b[0] = a[0] - tr;
                b[1] = a[1] - ti;
                a[0] += tr;
                a[1] += ti;
            }
        }
    }
}

void dv_fft_forward(const dv_fft_t *f, dv_real_t *x)
{
    DV_ASSERT(f != NULL && x != NULL);
    cfft(f->tw, 1u, f->n, x);
}

void dv_fft_forward_real(const dv_fft_t *f, dv_real_t *x)
{
    DV_ASSERT(f != NULL && x != NULL);
    /* z[m] = x[2m] + i x[2m+1] (h points): Z gives the even (E) and odd (O) samples' spectra,
     * X[k] = E[k] + W^k O[k] and X[h-k] = conj(E[k] - W^k O[k]), W = exp(-2 pi i / n). */
    const uint32_t h = f->n / 2u;
    cfft(f->tw, 2u, h, x);
    const dv_real_t z0r = x[0], z0i = x[1];
    x[0] = z0r + z0i;
    x[1] = z0r - z0i;
    for (uint32_t k = 1u; k <= h / 2u; k++) {
        dv_real_t *p = x + 2u * k, *q = x + 2u * (h - k);
        const dv_real_t er = DV_R(0.5) * (p[0] + q[0]), ei = DV_R(0.5) * (p[1] - q[1]);
        const dv_real_t or_ = DV_R(0.5) * (p[1] + q[1]), oi = DV_R(0.5) * (q[0] - p[0]);
        const dv_real_t wr = f->tw[2u * k], wi = f->tw[2u * k + 1u];
        const dv_real_t tr = wr * or_ - wi * oi, ti = wr * oi + wi * or_;
        q[0] = er - tr;
        q[1] = ti - ei;
        p[0] = er + tr;
        p[1] = ei + ti;
    }
}

/* Radix-4 decimation-in-time FFT: bit-reversal permutation, then log4(n) butterfly passes. */
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

static void swap_pt(dv_real_t *x, uint32_t i, uint32_t j)
{
    const dv_real_t tr = x[2u * i], ti = x[2u * i + 1u];
    x[2u * i] = x[2u * j];
    x[2u * i + 1u] = x[2u * j + 1u];
    x[2u * j] = tr;
    x[2u * j + 1u] = ti;
}

/* Bit-reversal permutation of n complex points. Each even i < n/2 has an even j = rev(i) < n/2,
 * and then rev(i + 1) = j + n/2 and rev(i + n/2 + 1) = j + n/2 + 1: one step of the reversed
 * counter places four points, so the counter (the costly part) runs n/4 times, not n. */
static void bit_reverse(uint32_t n, dv_real_t *x)
{
    const uint32_t h = n >> 1;
    for (uint32_t i = 0u, j = 0u; i < h; i += 2u) { /* n = 2: no iteration, the identity */
        if (i < j) {
            swap_pt(x, i, j);
            swap_pt(x, i + h + 1u, j + h + 1u);
        }
        swap_pt(x, i + 1u, j + h); /* odd below n/2 <-> even above: each pair met once */
        uint32_t bit = n >> 2;     /* i += 2 is a carry into bit n/4 of j, propagating down */
        for (; (j & bit) != 0u; bit >>= 1) {
            j ^= bit;
        }
        j ^= bit;
    }
}

/* The radix-4 butterfly on a0..a3 (a stride apart), given b1..b3: a1..a3 times their twiddles.
 * In bit-reversed order a1 holds the odd samples of the pair (a0, a1), so
 * X[k + ql] = sum_p (-i)^(pq) b_p with b_0 = a0: two radix-2 passes in one. */
static inline void bfly4(dv_real_t *a0, size_t stride, dv_real_t b1r, dv_real_t b1i,
                         dv_real_t b2r, dv_real_t b2i, dv_real_t b3r, dv_real_t b3i)
{
    dv_real_t *a1 = a0 + stride, *a2 = a1 + stride, *a3 = a2 + stride;
    const dv_real_t s0r = a0[0] + b1r, s0i = a0[1] + b1i, d0r = a0[0] - b1r, d0i = a0[1] - b1i;
    const dv_real_t s2r = b2r + b3r, s2i = b2i + b3i, d2r = b2r - b3r, d2i = b2i - b3i;
    a0[0] = s0r + s2r;
    a0[1] = s0i + s2i;
    a2[0] = s0r - s2r;
    a2[1] = s0i - s2i;
    a1[0] = d0r + d2i; /* d0 - i d2 */
    a1[1] = d0i - d2r;
    a3[0] = d0r - d2i; /* d0 + i d2 */
    a3[1] = d0i + d2r;
}

/* One radix-4 pass: four length-l transforms become one of length 4l, with the twiddles
 * W^2k, W^k, W^3k of W = exp(-2 pi i / 4l) for a1, a2, a3: 3 complex multiplies per 4 points
 * where two radix-2 passes take 4. W^m is table entry m s: each has the accuracy of its own
 * cos/sin, better than a product W^k W^2k. 3k passes the table's half 2l: W^(m + 2l) = -W^m.
 * The loop over k is outside, so that each twiddle is loaded once. */
static void radix4_pass(const dv_real_t *tw, uint32_t s, uint32_t n, uint32_t l, dv_real_t *x)
{
    const size_t st = 2u * (size_t)l;
    for (uint32_t k = 0u; k < l; k++) {
        const dv_real_t *w1 = tw + 2u * k * s, *w2 = tw + 4u * k * s;
        const int wrap = 3u * k >= 2u * l;
        const dv_real_t *w3 = tw + 2u * (3u * k - (wrap ? 2u * l : 0u)) * s;
        const dv_real_t sg = wrap ? DV_R(-1.0) : DV_R(1.0);
        const dv_real_t w1r = w1[0], w1i = w1[1], w2r = w2[0], w2i = w2[1];
        const dv_real_t w3r = sg * w3[0], w3i = sg * w3[1];
        /* A pointer, not a uint32_t index: the index's wrap at 2^32 kept the compiler from
         * stepping addresses, which cost 7 % more instructions. */
        for (dv_real_t *a = x + 2u * k; a < x + 2u * n; a += 8u * l) {
            const dv_real_t *a1 = a + st, *a2 = a1 + st, *a3 = a2 + st;
            bfly4(a, st, a1[0] * w2r - a1[1] * w2i, a1[0] * w2i + a1[1] * w2r,
                  a2[0] * w1r - a2[1] * w1i, a2[0] * w1i + a2[1] * w1r,
                  a3[0] * w3r - a3[1] * w3i, a3[0] * w3i + a3[1] * w3r);
        }
    }
}

/* n-point complex transform with the twiddles of a (stride n)-point table: the real transform
 * runs its n/2-point half on every other twiddle of the n-point table. */
static void cfft(const dv_real_t *tw, uint32_t tw_stride, uint32_t n, dv_real_t *x)
{
    bit_reverse(n, x);
    /* The first pass has only the twiddle 1: radix-2 when log2(n) is odd, else radix-4. */
    uint32_t l;
    if ((n & 0x55555555u) == 0u) {
        for (uint32_t i = 0u; i < 2u * n; i += 4u) {
            const dv_real_t ar = x[i], ai = x[i + 1u], br = x[i + 2u], bi = x[i + 3u];
            x[i] = ar + br;
            x[i + 1u] = ai + bi;
            x[i + 2u] = ar - br;
            x[i + 3u] = ai - bi;
        }
        l = 2u;
    } else {
        for (uint32_t i = 0u; i < 2u * n; i += 8u) {
            bfly4(x + i, 2u, x[i + 2u], x[i + 3u], x[i + 4u], x[i + 5u], x[i + 6u], x[i + 7u]);
        }
        l = 4u;
    }
    for (; l < n; l *= 4u) {
        radix4_pass(tw, tw_stride * (n / (4u * l)), n, l, x);
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

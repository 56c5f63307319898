/* Streaming Welch FRF: ring of the last seg_len pairs, one complex FFT of u + i y per segment,
 * running means of the unscaled one-sided products; ratios formed only when asked for. */
#include "dynval/dv_frf.h"
#include "dv_priv.h"

#define FS_MIN DV_R(1e-3)
#define FS_MAX DV_R(1e7)
#define HALF_POWER DV_R(0.70710678118654752)

static bool config_ok(const dv_frf_config_t *c)
{
    const uint32_t n = c->seg_len;
    return n >= DV_FRF_MIN_SEG && n <= DV_FRF_MAX_SEG && (n & (n - 1u)) == 0u && c->hop >= 1u &&
           c->hop <= n && c->fs_hz >= FS_MIN && c->fs_hz <= FS_MAX; /* NaN fails the compares */
}

size_t dv_frf_buffer_size(const dv_frf_config_t *cfg)
{
    if (cfg == NULL || !config_ok(cfg)) {
        return 0u;
    }
    return DV_FRF_BUF_LEN(cfg->seg_len);
}

/* Periodic Hann w[m] = (1 - cos(2 pi m / n)) / 2 from the twiddles (cos of 2 pi k / n for
 * k < n/2; cos is even about n/2), so the window costs no storage. */
static dv_real_t hann(const dv_fft_t *f, uint32_t m)
{
    const uint32_t n = f->n, h = n / 2u;
    const dv_real_t c = m < h ? f->tw[2u * m] : (m == h ? DV_R(-1.0) : f->tw[2u * (n - m)]);
    return DV_R(0.5) - DV_R(0.5) * c;
}

dv_status_t dv_frf_init(dv_frf_t *s, const dv_frf_config_t *cfg, dv_real_t *buf, size_t len)
{
    if (s == NULL || cfg == NULL || buf == NULL || !config_ok(cfg)) {
        return DV_EINVAL;
    }
    const size_t n = cfg->seg_len, nb = DV_FRF_N_BINS(n);
    if (len < DV_FRF_BUF_LEN(n)) {
        return DV_ESIZE;
    }
    const dv_status_t st = dv_fft_init(&s->fft, n, buf, DV_FFT_BUF_LEN(n));
    if (st != DV_OK) {
        return st;
    }
    s->hist_u = buf + DV_FFT_BUF_LEN(n);
    s->hist_y = s->hist_u + n;
    s->work = s->hist_y + n;
    s->guu = s->work + 2u * n;
    s->gyy = s->guu + nb;
    s->guy_re = s->gyy + nb;
    s->guy_im = s->guy_re + nb;
    s->cfg = *cfg;
    dv_real_t s2 = DV_R(0.0);
    for (uint32_t m = 0u; m < cfg->seg_len; m++) {
        const dv_real_t w = hann(&s->fft, m);
        s2 += w * w;
    }
    /* density 1 / (fs sum w^2), one-sided: doubled (except DC and Nyquist, see get_bin) */
    s->scale = DV_R(2.0) / (cfg->fs_hz * s2);
    dv_frf_reset(s);
    return DV_OK;
}

void dv_frf_reset(dv_frf_t *s)
{
    DV_ASSERT(s != NULL);
    const uint32_t n = s->cfg.seg_len;
    const size_t nb = DV_FRF_N_BINS(n);
    for (uint32_t i = 0u; i < n; i++) {
        s->hist_u[i] = s->hist_y[i] = DV_R(0.0);
    }
    for (size_t k = 0u; k < nb; k++) {
        s->guu[k] = s->gyy[k] = s->guy_re[k] = s->guy_im[k] = DV_R(0.0);
    }
    s->head = 0u;
    s->to_next = n;
    s->n_seg = 0u;
    s->n_nonfinite = 0u;
}

/* Window and transform the ring (oldest sample first), fold in the new spectra. Each channel has
 * its own real transform: packing u + i y into one complex FFT would cost the same but leak
 * round-off of the stronger channel into the weaker one (a silent input would get a Guu of
 * ~eps^2 Gyy, and an H1 of 1/eps instead of the defined 0). */
static void add_segment(dv_frf_t *s)
{
    const uint32_t n = s->cfg.seg_len, mask = n - 1u, h = n / 2u;
    dv_real_t *xu = s->work, *xy = s->work + n;
    for (uint32_t m = 0u; m < n; m++) {
        const uint32_t i = (s->head + m) & mask;
        const dv_real_t w = hann(&s->fft, m);
        xu[m] = w * s->hist_u[i];
        xy[m] = w * s->hist_y[i];
    }
    dv_fft_forward_real(&s->fft, xu);
    dv_fft_forward_real(&s->fft, xy);
    s->n_seg++;
    /* Plain mean while n_seg <= n_avg (or always), as a running mean so that the averages stay
     * the size of one segment's spectrum however long the stream runs; then exponential. */
    const uint64_t d = (s->cfg.n_avg == 0u || s->n_seg <= s->cfg.n_avg) ? s->n_seg : s->cfg.n_avg;
    const dv_real_t a = DV_R(1.0) / (dv_real_t)d;
    for (uint32_t k = 0u; k <= h; k++) {
        /* packed half spectrum: X[0] and X[n/2] are real, in x[0] and x[1] */
        const uint32_t re = k == h ? 1u : 2u * k, im = 2u * k + 1u;
        const bool edge = k == 0u || k == h;
        const dv_real_t ur = xu[re], ui = edge ? DV_R(0.0) : xu[im];
        const dv_real_t yr = xy[re], yi = edge ? DV_R(0.0) : xy[im];
        s->guu[k] += a * ((ur * ur + ui * ui) - s->guu[k]);
        s->gyy[k] += a * ((yr * yr + yi * yi) - s->gyy[k]);
        s->guy_re[k] += a * ((ur * yr + ui * yi) - s->guy_re[k]);
        s->guy_im[k] += a * ((ur * yi - ui * yr) - s->guy_im[k]);
    }
}

dv_status_t dv_frf_update(dv_frf_t *s, dv_real_t u, dv_real_t y)
{
    DV_ASSERT(s != NULL);
    if (!dv_priv_in_range(u) || !dv_priv_in_range(y)) {
        s->n_nonfinite++;
        return DV_ENUMERIC;
    }
    s->hist_u[s->head] = u;
    s->hist_y[s->head] = y;
    s->head = (s->head + 1u) & (s->cfg.seg_len - 1u);
    if (--s->to_next != 0u) {
        return DV_OK;
    }
    s->to_next = s->cfg.hop;
    add_segment(s);
    return DV_DONE;
}

dv_status_t dv_frf_update_block(dv_frf_t *s, const dv_real_t *u, const dv_real_t *y, size_t n)
{
    if (s == NULL || (n > 0u && (u == NULL || y == NULL))) {
        return DV_EINVAL;
    }
    bool done = false, dropped = false;
    for (size_t i = 0u; i < n; i++) {
        const dv_status_t st = dv_frf_update(s, u[i], y[i]);
        done = done || st == DV_DONE;
        dropped = dropped || st == DV_ENUMERIC;
    }
    return dropped ? DV_ENUMERIC : (done ? DV_DONE : DV_OK);
}

uint64_t dv_frf_segments(const dv_frf_t *s)
{
    return s == NULL ? 0u : s->n_seg;
}

uint64_t dv_frf_nonfinite(const dv_frf_t *s)
{
    return s == NULL ? 0u : s->n_nonfinite;
}

/* |re + i im| without overflow of the squares. */
static dv_real_t cabs_safe(dv_real_t re, dv_real_t im)
{
    dv_real_t a = DV_FABS(re), b = DV_FABS(im);
    if (a < b) {
        const dv_real_t t = a;
        a = b;
        b = t;
    }
    if (a == DV_R(0.0)) {
        return DV_R(0.0);
    }
    const dv_real_t r = b / a;
    return a * DV_SQRT(DV_R(1.0) + r * r);
}

/* H1 of bin k; 0 where Guu is 0 or the quotient overflows. */
static void h1_of(const dv_frf_t *s, size_t k, dv_real_t *re, dv_real_t *im)
{
    const dv_real_t g = s->guu[k];
    dv_real_t r = DV_R(0.0), i = DV_R(0.0);
    if (g > DV_R(0.0)) {
        r = s->guy_re[k] / g;
        i = s->guy_im[k] / g;
        if (!dv_priv_finite(r) || !dv_priv_finite(i)) {
            r = i = DV_R(0.0);
        }
    }
    *re = r;
    *im = i;
}

/* Coherence of bin k as Re(H1 conj Guy) / Gyy = |Guy|^2 / (Guu Gyy): no product of two spectra
 * (float |Guy|^2 of full-scale 24-bit data would overflow). */
static dv_real_t coh_of(const dv_frf_t *s, size_t k)
{
    dv_real_t hr, hi;
    h1_of(s, k, &hr, &hi);
    const dv_real_t gyy = s->gyy[k];
    if (!(gyy > DV_R(0.0))) {
        return DV_R(0.0);
    }
    const dv_real_t c = (hr * s->guy_re[k] + hi * s->guy_im[k]) / gyy;
    if (!(c > DV_R(0.0))) {
        return DV_R(0.0); /* also a NaN from an overflow */
    }
    return c < DV_R(1.0) ? c : DV_R(1.0);
}

/* H2 = Gyy / conj(Guy) = Gyy Guy / |Guy|^2, with Guy scaled by its larger part first. */
static void h2_of(const dv_frf_t *s, size_t k, dv_real_t *re, dv_real_t *im)
{
    const dv_real_t cr = s->guy_re[k], ci = s->guy_im[k];
    const dv_real_t a = DV_FABS(cr) > DV_FABS(ci) ? DV_FABS(cr) : DV_FABS(ci);
    dv_real_t r = DV_R(0.0), i = DV_R(0.0);
    if (a > DV_R(0.0)) {
        const dv_real_t xr = cr / a, xi = ci / a;
        const dv_real_t g = s->gyy[k] / a / (xr * xr + xi * xi);
        r = g * xr;
        i = g * xi;
        if (!dv_priv_finite(r) || !dv_priv_finite(i)) {
            r = i = DV_R(0.0);
        }
    }
    *re = r;
    *im = i;
}

static dv_real_t h1_mag(const dv_frf_t *s, size_t k)
{
    dv_real_t re, im;
    h1_of(s, k, &re, &im);
    return cabs_safe(re, im);
}

dv_status_t dv_frf_get_bin(const dv_frf_t *s, size_t k, dv_frf_bin_t *out)
{
    if (s == NULL || out == NULL) {
        return DV_EINVAL;
    }
    if (k >= DV_FRF_N_BINS(s->cfg.seg_len)) {
        return DV_ERANGE;
    }
    if (s->n_seg == 0u) {
        return DV_ENOTREADY;
    }
    /* DC and Nyquist are not doubled in a one-sided spectrum. */
    const dv_real_t sc = (k == 0u || 2u * k == s->cfg.seg_len) ? s->scale * DV_R(0.5) : s->scale;
    out->f_hz = (dv_real_t)k * s->cfg.fs_hz / (dv_real_t)s->cfg.seg_len;
    out->guu = s->guu[k] * sc;
    out->gyy = s->gyy[k] * sc;
    out->guy_re = s->guy_re[k] * sc;
    out->guy_im = s->guy_im[k] * sc;
    h1_of(s, k, &out->h1_re, &out->h1_im);
    h2_of(s, k, &out->h2_re, &out->h2_im);
    out->coh = coh_of(s, k);
    return DV_OK;
}

/* Shared checks of the whole-spectrum getters. */
static dv_status_t vec_check(const dv_frf_t *s, const void *a, const void *b, size_t len)
{
    if (s == NULL || a == NULL || b == NULL) {
        return DV_EINVAL;
    }
    if (len < DV_FRF_N_BINS(s->cfg.seg_len)) {
        return DV_ESIZE;
    }
    return s->n_seg == 0u ? DV_ENOTREADY : DV_OK;
}

dv_status_t dv_frf_get_h1(const dv_frf_t *s, dv_real_t *re, dv_real_t *im, size_t len)
{
    const dv_status_t st = vec_check(s, re, im, len);
    if (st != DV_OK) {
        return st;
    }
    for (size_t k = 0u; k < DV_FRF_N_BINS(s->cfg.seg_len); k++) {
        h1_of(s, k, &re[k], &im[k]);
    }
    return DV_OK;
}

dv_status_t dv_frf_get_h2(const dv_frf_t *s, dv_real_t *re, dv_real_t *im, size_t len)
{
    const dv_status_t st = vec_check(s, re, im, len);
    if (st != DV_OK) {
        return st;
    }
    for (size_t k = 0u; k < DV_FRF_N_BINS(s->cfg.seg_len); k++) {
        h2_of(s, k, &re[k], &im[k]);
    }
    return DV_OK;
}

dv_status_t dv_frf_get_coherence(const dv_frf_t *s, dv_real_t *coh, size_t len)
{
    const dv_status_t st = vec_check(s, coh, coh, len);
    if (st != DV_OK) {
        return st;
    }
    for (size_t k = 0u; k < DV_FRF_N_BINS(s->cfg.seg_len); k++) {
        coh[k] = coh_of(s, k);
    }
    return DV_OK;
}

/* Where |H1| falls to thr walking from bin k by dir (+1/-1), linearly interpolated, in bins;
 * -1 when it rises again (a valley, another mode) or the band ends first. */
static dv_real_t half_power_at(const dv_frf_t *s, size_t k, int dir, dv_real_t thr)
{
    const size_t last = DV_FRF_N_BINS(s->cfg.seg_len) - 1u;
    size_t j = k;
    dv_real_t mj = h1_mag(s, j);
    while (dir < 0 ? j > 0u : j < last) {
        const size_t nx = dir < 0 ? j - 1u : j + 1u;
        const dv_real_t mn = h1_mag(s, nx);
        if (mn <= thr) {
            const dv_real_t t = (mj - thr) / (mj - mn); /* mj > thr >= mn */
            return (dv_real_t)j + (dv_real_t)dir * t;
        }
        if (mn > mj) {
            return DV_R(-1.0);
        }
        j = nx;
        mj = mn;
    }
    return DV_R(-1.0);
}

dv_status_t dv_frf_get_peaks(const dv_frf_t *s, dv_frf_peak_t *peaks, size_t max_peaks,
                             size_t *n_found)
{
    if (s == NULL || peaks == NULL || n_found == NULL || max_peaks == 0u) {
        return DV_EINVAL;
    }
    if (s->n_seg == 0u) {
        return DV_ENOTREADY;
    }
    const size_t nb = DV_FRF_N_BINS(s->cfg.seg_len);
    size_t n = 0u;
    /* Pass 1: the strongest local maxima, sorted by bin magnitude (bin index kept in f_hz,
     * exact: < 2^24). */
    dv_real_t ml = h1_mag(s, 0u), mk = h1_mag(s, 1u);
    for (size_t k = 1u; k + 1u < nb; k++) {
        const dv_real_t mr = h1_mag(s, k + 1u);
        if (mk > ml && mk >= mr && (n < max_peaks || mk > peaks[n - 1u].mag)) {
            size_t i = n < max_peaks ? n++ : n - 1u;
            for (; i > 0u && peaks[i - 1u].mag < mk; i--) {
                peaks[i] = peaks[i - 1u];
            }
            peaks[i].f_hz = (dv_real_t)k;
            peaks[i].mag = mk;
        }
        ml = mk;
        mk = mr;
    }
    /* Pass 2: parabolic interpolation of the peak, half-power points. */
    const dv_real_t df = s->cfg.fs_hz / (dv_real_t)s->cfg.seg_len;
    for (size_t i = 0u; i < n; i++) {
        const size_t k = (size_t)peaks[i].f_hz;
        const dv_real_t a = h1_mag(s, k - 1u), b = peaks[i].mag, c = h1_mag(s, k + 1u);
        const dv_real_t den = a - DV_R(2.0) * b + c; /* < 0: b > a, b >= c */
        dv_real_t p = DV_R(0.5) * (a - c) / den;
        p = p > DV_R(0.5) ? DV_R(0.5) : (p < DV_R(-0.5) ? DV_R(-0.5) : p);
        const dv_real_t fk = (dv_real_t)k + p;
        dv_real_t mag = b - DV_R(0.25) * (a - c) * p;
        mag = mag > b ? mag : b;
        const dv_real_t thr = mag * HALF_POWER;
        const dv_real_t f1 = half_power_at(s, k, -1, thr), f2 = half_power_at(s, k, 1, thr);
        dv_real_t zeta = DV_R(0.0);
        if (f1 >= DV_R(0.0) && f2 >= DV_R(0.0)) {
            zeta = (f2 - f1) / (DV_R(2.0) * fk);
        } else if (f1 >= DV_R(0.0)) {
            zeta = (fk - f1) / fk;
        } else if (f2 >= DV_R(0.0)) {
            zeta = (f2 - fk) / fk;
        }
        peaks[i].f_hz = fk * df;
        peaks[i].mag = mag;
        peaks[i].zeta = zeta > DV_R(0.0) ? zeta : DV_R(0.0);
    }
    *n_found = n;
    return DV_OK;
}

/* CMSIS-DSP's real FFT (arm_rfft_fast_f32 / _f64) on bench/bench_fft.c's cases, with its
 * protocol (`--list`, `CASE REPS` -> `case=.. units=.. unit=.. ns=..`), for bench/compare_fft.py.
 * Not named bench_*.c: bench/CMakeLists.txt's glob links only dynval, and this program needs
 * CMSIS-DSP's sources, which compare_fft.py fetches and compiles with the same compiler and
 * flags. Built once per precision: -DDV_REAL_DOUBLE selects arm_rfft_fast_f64 (and dv's double
 * build for `--check`), otherwise arm_rfft_fast_f32.
 *
 * `--check CASE` transforms the same input with dv_fft_forward_real (src/dv_fft.c, compiled in)
 * and CMSIS (the same packing: X[0], X[n/2], then re/im of X[1..n/2-1]) and prints the largest
 * difference, absolute and relative to the largest |X|. */
#include <math.h>

#include "arm_math.h"
#include "bench_util.h"
#include "dynval/dv_fft.h"

#ifdef DV_REAL_DOUBLE
typedef float64_t cm_real_t;
typedef arm_rfft_fast_instance_f64 cm_plan_t;
#define CM_INIT arm_rfft_fast_init_f64
#define CM_RFFT arm_rfft_fast_f64
#else
typedef float32_t cm_real_t;
typedef arm_rfft_fast_instance_f32 cm_plan_t;
#define CM_INIT arm_rfft_fast_init_f32
#define CM_RFFT arm_rfft_fast_f32
#endif

enum { NMAX = 4096, BATCH_POINTS = 65536, REC = 16384, SEG = 1024, HOP = 512 };
static cm_real_t in[NMAX], work[NMAX], out[NMAX];
static cm_real_t u[REC], y[REC], win[SEG], xu[SEG], xy[SEG];
static cm_real_t guu[SEG / 2 + 1], gyy[SEG / 2 + 1], gre[SEG / 2 + 1], gim[SEG / 2 + 1];
static cm_plan_t plan;
static uint32_t plan_n;

static int plan_for(uint32_t n)
{
    if (plan_n == n) return 1;
    if (CM_INIT(&plan, (uint16_t)n) != ARM_MATH_SUCCESS) return 0;
    plan_n = n;
    return 1;
}

/* As bench_fft.c: BATCH_POINTS / n transforms per run, each on a fresh copy of the input
 * (arm_rfft_fast uses its input as scratch). */
static int run_fft(uint32_t n)
{
    if (!plan_for(n)) return 0;
    const int batch = (int)(BATCH_POINTS / n);
    for (int b = 0; b < batch; b++) {
        memcpy(work, in, sizeof(cm_real_t) * n);
        CM_RFFT(&plan, work, out, 0);
    }
    bench_sink = (double)out[3];
    return batch;
}

static int run_fft256(void) { return run_fft(256u); }
static int run_fft1024(void) { return run_fft(1024u); }
static int run_fft4096(void) { return run_fft(4096u); }

/* The same Welch average as dv_frf (periodic Hann, running mean of Guu, Gyy, Guy per segment)
 * written as plain block C around arm_rfft_fast: segments are read in place from the record
 * (no ring, no per-sample NaN check), so it is the floor of a streaming estimator's cost. */
static int run_frf(void)
{
    if (!plan_for(SEG)) return 0;
    memset(guu, 0, sizeof guu);
    memset(gyy, 0, sizeof gyy);
    memset(gre, 0, sizeof gre);
    memset(gim, 0, sizeof gim);
    int nseg = 0;
    for (int off = 0; off + SEG <= REC; off += HOP) {
        for (int m = 0; m < SEG; m++) {
            xu[m] = win[m] * u[off + m];
            xy[m] = win[m] * y[off + m];
        }
        CM_RFFT(&plan, xu, work, 0);
        CM_RFFT(&plan, xy, out, 0);
        nseg++;
        const cm_real_t a = (cm_real_t)1 / (cm_real_t)nseg;
        for (int k = 0; k <= SEG / 2; k++) {
            const int re = k == SEG / 2 ? 1 : 2 * k, im = 2 * k + 1;
            const int edge = k == 0 || k == SEG / 2;
            const cm_real_t ur = work[re], ui = edge ? 0 : work[im];
            const cm_real_t yr = out[re], yi = edge ? 0 : out[im];
            guu[k] += a * ((ur * ur + ui * ui) - guu[k]);
            gyy[k] += a * ((yr * yr + yi * yi) - gyy[k]);
            gre[k] += a * ((ur * yr + ui * yi) - gre[k]);
            gim[k] += a * ((ur * yi - ui * yr) - gim[k]);
        }
    }
    const cm_real_t c = (gre[100] * gre[100] + gim[100] * gim[100]) / (guu[100] * gyy[100]);
    bench_sink = (double)c;
    return REC;
}

static const struct {
    const char *name, *unit;
    bench_units_fn fn;
    uint32_t n;
} CASES[] = {
    {"fft_real_256", "transform", run_fft256, 256u},
    {"fft_real_1024", "transform", run_fft1024, 1024u},
    {"fft_real_4096", "transform", run_fft4096, 4096u},
    {"frf_welch_1024_sample", "sample", run_frf, SEG},
};
enum { NCASES = sizeof CASES / sizeof CASES[0] };

/* bench_fft.c's data (bench_util.h), and the periodic Hann window of the Welch loop. */
static void make_data(void)
{
    BENCH_FFT_DATA(cm_real_t, in, NMAX, u, y, REC);
    for (int m = 0; m < SEG; m++) win[m] = (cm_real_t)(0.5 - 0.5 * cos(6.283185307179586 * m / SEG));
}

static int check(uint32_t n)
{
    static dv_real_t dv_x[NMAX], dv_tw[DV_FFT_BUF_LEN(NMAX)];
    dv_fft_t f;
    if (!plan_for(n) || dv_fft_init(&f, n, dv_tw, DV_FFT_BUF_LEN(NMAX)) != DV_OK) return 1;
    for (uint32_t i = 0; i < n; i++) dv_x[i] = (dv_real_t)in[i];
    memcpy(work, in, sizeof(cm_real_t) * n);
    dv_fft_forward_real(&f, dv_x);
    CM_RFFT(&plan, work, out, 0);
    double diff = 0.0, big = 0.0;
    for (uint32_t i = 0; i < n; i++) {
        diff = fmax(diff, fabs((double)dv_x[i] - (double)out[i]));
        big = fmax(big, fabs((double)out[i]));
    }
    printf("n=%u maxdiff=%.3e rel=%.3e\n", (unsigned)n, diff, diff / big);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "--list") == 0) {
        for (int i = 0; i < NCASES; i++) printf("%s\n", CASES[i].name);
        return 0;
    }
    if (argc != 3) {
        fprintf(stderr, "usage: %s --list | --check CASE | CASE REPS\n", argv[0]);
        return 2;
    }
    make_data();
    const int want_check = strcmp(argv[1], "--check") == 0;
    const char *name = want_check ? argv[2] : argv[1];
    int reps = want_check ? 1 : atoi(argv[2]);
    if (reps < 1 || reps > 100000) reps = 1;
    for (int c = 0; c < NCASES; c++) {
        if (strcmp(name, CASES[c].name) != 0) continue;
        if (want_check) return check(CASES[c].n);
        return bench_time_units(name, CASES[c].unit, CASES[c].fn, reps);
    }
    fprintf(stderr, "unknown case %s\n", name);
    return 2;
}

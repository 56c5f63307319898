/* FFT and streaming FRF benchmarks: dv_fft_forward_real at 256, 1024 and 4096 points (ns and
 * instructions per transform) and dv_frf_update_block, the streaming Welch H1/coherence
 * estimator at seg 1024, hop 512 (per sample pair). bench/compare_fft.py times CMSIS-DSP's
 * arm_rfft_fast_f32/f64 on the same cases, compiled with the same compiler and flags. */
#include <math.h>

#include "bench_util.h"
#include "dynval/dv.h"

enum { NMAX = 4096, BATCH_POINTS = 65536, REC = 16384, SEG = 1024, HOP = 512 };
static dv_real_t in[NMAX], work[NMAX], tw[DV_FFT_BUF_LEN(NMAX)];
static dv_real_t u[REC], y[REC];
static dv_real_t frf_buf[DV_FRF_BUF_LEN(SEG)];
static dv_fft_t plan;
static uint32_t plan_n;

/* One run transforms BATCH_POINTS / n copies of the input (a single 256-point transform is too
 * short for the clock). The copy back is timed too: the transform is in place, and CMSIS's
 * arm_rfft_fast also overwrites its input, so the comparison does the same copy. */
static int run_fft(uint32_t n)
{
    if (plan_n != n && dv_fft_init(&plan, n, tw, DV_FFT_BUF_LEN(NMAX)) != DV_OK) return 0;
    plan_n = n;
    const int batch = (int)(BATCH_POINTS / n);
    for (int b = 0; b < batch; b++) {
        memcpy(work, in, sizeof(dv_real_t) * n);
        dv_fft_forward_real(&plan, work);
    }
    bench_sink = (double)work[3];
    return batch;
}

static int run_fft256(void) { return run_fft(256u); }
static int run_fft1024(void) { return run_fft(1024u); }
static int run_fft4096(void) { return run_fft(4096u); }

/* A fresh estimator per run over a 16384-pair record: 31 segments (one per 512 pairs). */
static int run_frf(void)
{
    const dv_frf_config_t cfg = {SEG, HOP, 0u, DV_R(1024.0)};
    dv_frf_t s;
    if (dv_frf_init(&s, &cfg, frf_buf, DV_FRF_BUF_LEN(SEG)) != DV_OK) return 0;
    (void)dv_frf_update_block(&s, u, y, REC);
    dv_frf_bin_t bin;
    (void)dv_frf_get_bin(&s, 100u, &bin);
    bench_sink = (double)bin.coh;
    return REC;
}

typedef int (*bench_fn)(void);
static const struct {
    const char *name, *unit;
    bench_fn fn;
} CASES[] = {
    {"fft_real_256", "transform", run_fft256},
    {"fft_real_1024", "transform", run_fft1024},
    {"fft_real_4096", "transform", run_fft4096},
    {"frf_welch_1024_sample", "sample", run_frf},
};
enum { NCASES = sizeof CASES / sizeof CASES[0] };

/* Input: unit-variance noise (the transform's speed does not depend on it); the FRF's output is
 * a two-tap filter of the input plus noise, so that the coherence is neither 0 nor 1. */
static void make_data(void)
{
    uint64_t seed = 4242;
    for (int i = 0; i < NMAX; i++) in[i] = (dv_real_t)bench_noise(&seed);
    double prev = 0.0;
    for (int i = 0; i < REC; i++) {
        const double ui = bench_noise(&seed);
        u[i] = (dv_real_t)ui;
        y[i] = (dv_real_t)(0.8 * ui + 0.5 * prev + 0.1 * bench_noise(&seed));
        prev = ui;
    }
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "--list") == 0) {
        for (int i = 0; i < NCASES; i++) printf("%s\n", CASES[i].name);
        return 0;
    }
    if (argc == 2 && strcmp(argv[1], "--sizes") == 0) {
        printf("size name=frf_state_seg1024 bytes=%zu\n",
               sizeof(dv_frf_t) + sizeof(dv_real_t) * DV_FRF_BUF_LEN(SEG));
        printf("size name=fft_twiddles_1024 bytes=%zu\n", sizeof(dv_real_t) * DV_FFT_BUF_LEN(1024));
        return 0;
    }
    if (argc != 3) {
        fprintf(stderr, "usage: %s --list | --sizes | CASE REPS\n", argv[0]);
        return 2;
    }
    int reps = atoi(argv[2]);
    if (reps < 1 || reps > 100000) reps = 1;
    make_data();
    for (int c = 0; c < NCASES; c++) {
        if (strcmp(argv[1], CASES[c].name) != 0) continue;
        double *t = malloc(sizeof(double) * (size_t)reps);
        int units = CASES[c].fn(); /* warm-up (and the plan) */
        if (units == 0 || t == NULL) {
            fprintf(stderr, "%s: setup failed\n", CASES[c].name);
            free(t);
            return 1;
        }
        for (int r = 0; r < reps; r++) {
            double t0 = bench_now_ns();
            CASES[c].fn();
            t[r] = (bench_now_ns() - t0) / units;
        }
        printf("case=%s units=%d unit=%s ns=%.3f\n", CASES[c].name, units, CASES[c].unit,
               bench_median(t, reps));
        free(t);
        return 0;
    }
    fprintf(stderr, "unknown case %s\n", argv[1]);
    return 2;
}

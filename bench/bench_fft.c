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

static const struct {
    const char *name, *unit;
    bench_units_fn fn;
} CASES[] = {
    {"fft_real_256", "transform", run_fft256},
    {"fft_real_1024", "transform", run_fft1024},
    {"fft_real_4096", "transform", run_fft4096},
    {"frf_welch_1024_sample", "sample", run_frf},
};
enum { NCASES = sizeof CASES / sizeof CASES[0] };

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
    BENCH_FFT_DATA(dv_real_t, in, NMAX, u, y, REC);
    for (int c = 0; c < NCASES; c++) {
        if (strcmp(argv[1], CASES[c].name) == 0) {
            return bench_time_units(CASES[c].name, CASES[c].unit, CASES[c].fn, reps);
        }
    }
    fprintf(stderr, "unknown case %s\n", argv[1]);
    return 2;
}

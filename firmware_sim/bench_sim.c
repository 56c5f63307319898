/* Throughput of the firmware loop without sockets: frames/s through decoder + features
 * (+ AR + observer stages, stubs until those modules land) for 5 channels.
 * Bench protocol: `bench_sim --list` prints the case names; `bench_sim CASE REPS` prints
 * `case=CASE units=U unit=frame ns=X` with X the median ns per frame over REPS runs.
 * Cases (records of 64 x 64 samples, window 256):
 *   loop_5ch_640        5 channels, 640 Hz-equivalent data (20 s per run), features only
 *   loop_5ch_640_full   the same with the AR stage (order 16: one baseline record fitted by
 *                       Burg inside the run, then residuals) and the observer (LANL 4-DOF
 *                       model, steady-state Kalman gain, a residual frame per step)
 *   loop_5ch_2560       5 channels at 2560 Hz (4 s per run), features only
 *   loop_5ch_2560_full  the same with AR and observer; the CPU share of one core at real time
 *                       is ns_per_frame * frames_per_second / 1e9, printed to stderr
 *   decode              dv_codec_decode alone
 * Model build and DARE solve (at configuration) are outside the timed loop; the AR fit of the
 * baseline record is inside it. */
#define _GNU_SOURCE
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sim_core.h"

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_d(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Interleaved sample frames of n_ch channels: a noisy decaying response per channel. */
static dv_can_frame_t *make_frames(unsigned n_ch, unsigned fs, double secs, size_t *n_out)
{
    const size_t per_ch = (size_t)(fs * secs) / 3u;
    dv_can_frame_t *f = malloc(per_ch * n_ch * sizeof *f);
    uint32_t lcg = 1u;
    size_t n = 0;
    for (size_t k = 0; k < per_ch; k++) {
        for (unsigned c = 0; c < n_ch; c++) {
            dv_msg_t m;
            m.kind = DV_MSG_SAMPLES;
            m.u.samples.channel = (uint8_t)c;
            m.u.samples.seq = (uint8_t)k;
            for (unsigned i = 0; i < 3; i++) {
                lcg = lcg * 1664525u + 1013904223u;
                const double t = (double)(3 * k + i) / fs;
                const double x = 8.0 * sin(2 * M_PI * (20.0 + 7 * c) * t) * exp(-0.2 * t) +
                                 ((double)(lcg >> 8) / 16777216.0 - 0.5);
                m.u.samples.raw[i] = dv_codec_sample_raw((dv_real_t)x, DV_CODEC_DEFAULT_LSB);
            }
            dv_codec_encode(&m, &f[n++]);
        }
    }
    *n_out = n;
    return f;
}

static void lanl_model(struct sim_config *cfg)
{
    static const float mass[4] = {6.54f, 6.66f, 6.86f, 6.8f};
    static const float k[4] = {10.0f, 399790.0f, 399790.0f, 399790.0f};
    static const float zeta[4] = {0.01f, 0.05f, 0.01f, 0.01f};
    cfg->model[SIM_MODEL_N_DOF] = 4.0f;
    for (int i = 0; i < 4; i++) {
        cfg->model[SIM_MODEL_MASS + i] = mass[i];
        cfg->model[SIM_MODEL_K + i] = k[i];
        cfg->model[SIM_MODEL_ZETA + i] = zeta[i];
    }
    cfg->model[SIM_MODEL_Q] = 1.0f;
    cfg->model[SIM_MODEL_R] = 0.04f;
    cfg->model[SIM_MODEL_INPUT_DOF] = 0.0f;
}

static int g_full; /* 1: AR and observer stages configured */

static double run_loop(unsigned fs, int reps, size_t *units)
{
    struct sim_config cfg;
    sim_config_default(&cfg);
    cfg.heartbeat_ms = 0;
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        cfg.fs_hz[i] = (uint16_t)fs;
    }
    if (g_full) {
        cfg.ar_order = 16;
        cfg.resid_decim = 1;
        lanl_model(&cfg);
    }
    size_t n;
    dv_can_frame_t *frames = make_frames(5, fs, fs == 640 ? 20.0 : 4.0, &n);
    static dv_can_frame_t out[SIM_CORE_MAX_OUT]; /* bench program: static is fine */
    double *t = malloc((size_t)reps * sizeof *t);
    volatile size_t sink = 0;
    for (int r = 0; r < reps; r++) {
        struct sim_core core;
        if (sim_core_init(&core, &cfg) != 0 ||
            (g_full && core.obs_status != SIM_STAGE_RUNNING)) {
            fprintf(stderr, "bench_sim: configuration failed (observer status %d)\n",
                    core.obs_status);
            exit(1);
        }
        const double t0 = now_s();
        for (size_t i = 0; i < n; i++) {
            sink += sim_core_handle(&core, &frames[i], out);
        }
        t[r] = (now_s() - t0) * 1e9 / (double)n;
        if (g_full && (core.ar_status != SIM_STAGE_RUNNING || core.obs.steps == 0)) {
            fprintf(stderr, "bench_sim: AR (%d) or observer (%u steps) did not run\n",
                    core.ar_status, (unsigned)core.obs.steps);
            exit(1);
        }
        sim_core_free(&core);
    }
    qsort(t, (size_t)reps, sizeof *t, cmp_d);
    const double med = t[reps / 2];
    free(t);
    free(frames);
    *units = n;
    (void)sink;
    return med;
}

static double run_decode(int reps, size_t *units)
{
    size_t n;
    dv_can_frame_t *frames = make_frames(5, 640, 6.0, &n);
    double *t = malloc((size_t)reps * sizeof *t);
    volatile unsigned sink = 0;
    for (int r = 0; r < reps; r++) {
        const double t0 = now_s();
        for (size_t i = 0; i < n; i++) {
            dv_msg_t m;
            sink += (unsigned)dv_codec_decode(&frames[i], &m) + m.u.samples.raw[0];
        }
        t[r] = (now_s() - t0) * 1e9 / (double)n;
    }
    qsort(t, (size_t)reps, sizeof *t, cmp_d);
    const double med = t[reps / 2];
    free(t);
    free(frames);
    *units = n;
    if (sink == 1u) { /* keeps the decode loop from being optimised away */
        fputs("", stderr);
    }
    return med;
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "--list") == 0) {
        puts("loop_5ch_640\nloop_5ch_640_full\nloop_5ch_2560\nloop_5ch_2560_full\ndecode");
        return 0;
    }
    if (argc != 3 || atoi(argv[2]) < 1) {
        fprintf(stderr, "usage: %s --list | %s CASE REPS\n", argv[0], argv[0]);
        return 2;
    }
    const int reps = atoi(argv[2]);
    size_t units;
    double ns;
    g_full = strstr(argv[1], "_full") != NULL;
    if (strncmp(argv[1], "loop_5ch_640", 12) == 0) {
        ns = run_loop(640, reps, &units);
        fprintf(stderr, "bench_sim: %.0f frames/s sustained (%.0f samples/s)\n", 1e9 / ns,
                3e9 / ns);
    } else if (strncmp(argv[1], "loop_5ch_2560", 13) == 0) {
        ns = run_loop(2560, reps, &units);
        const double fps = 5.0 * 2560.0 / 3.0;
        fprintf(stderr, "bench_sim: real time 5 ch x 2560 Hz = %.0f frames/s -> %.3f %% of one "
                        "core (AR and observer stages %s)\n",
                fps, 100.0 * ns * fps / 1e9, g_full ? "on" : "off");
    } else if (strcmp(argv[1], "decode") == 0) {
        ns = run_decode(reps, &units);
    } else {
        fprintf(stderr, "bench_sim: unknown case %s\n", argv[1]);
        return 2;
    }
    printf("case=%s units=%zu unit=frame ns=%.1f\n", argv[1], units, ns);
    return 0;
}

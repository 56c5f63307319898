/* Throughput of the firmware loop without sockets: frames/s through decoder + features
 * (+ AR + observer stages, stubs until those modules land) for 5 channels.
 * Bench protocol: `bench_sim --list` prints the case names; `bench_sim CASE REPS` prints
 * `case=CASE units=U unit=frame ns=X` with X the median ns per frame over REPS runs.
 * Cases:
 *   loop_5ch_640   5 channels, 640 Hz-equivalent data (6 s = 3840 samples per channel)
 *   loop_5ch_2560  5 channels at 2560 Hz (1 s of real time per run); the CPU share of one core
 *                  at real time is ns_per_frame * frames_per_second / 1e9, printed to stderr
 *   decode         dv_codec_decode alone */
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

static double run_loop(unsigned fs, int reps, size_t *units)
{
    struct sim_config cfg;
    sim_config_default(&cfg);
    cfg.heartbeat_ms = 0;
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        cfg.fs_hz[i] = (uint16_t)fs;
    }
    size_t n;
    dv_can_frame_t *frames = make_frames(5, fs, fs == 640 ? 6.0 : 1.0, &n);
    static dv_can_frame_t out[SIM_CORE_MAX_OUT];
    double *t = malloc((size_t)reps * sizeof *t);
    volatile size_t sink = 0;
    for (int r = 0; r < reps; r++) {
        struct sim_core core;
        sim_core_init(&core, &cfg);
        const double t0 = now_s();
        for (size_t i = 0; i < n; i++) {
            sink += sim_core_handle(&core, &frames[i], out);
        }
        t[r] = (now_s() - t0) * 1e9 / (double)n;
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
    return med;
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "--list") == 0) {
        puts("loop_5ch_640\nloop_5ch_2560\ndecode");
        return 0;
    }
    if (argc != 3 || atoi(argv[2]) < 1) {
        fprintf(stderr, "usage: %s --list | %s CASE REPS\n", argv[0], argv[0]);
        return 2;
    }
    const int reps = atoi(argv[2]);
    size_t units;
    double ns;
    if (strcmp(argv[1], "loop_5ch_640") == 0) {
        ns = run_loop(640, reps, &units);
        fprintf(stderr, "bench_sim: %.0f frames/s sustained (%.0f samples/s)\n", 1e9 / ns,
                3e9 / ns);
    } else if (strcmp(argv[1], "loop_5ch_2560") == 0) {
        ns = run_loop(2560, reps, &units);
        const double fps = 5.0 * 2560.0 / 3.0;
        fprintf(stderr, "bench_sim: real time 5 ch x 2560 Hz = %.0f frames/s -> %.3f %% of one "
                        "core (observer and AR stages: %s)\n",
                fps, 100.0 * ns * fps / 1e9, "not built yet");
    } else if (strcmp(argv[1], "decode") == 0) {
        ns = run_decode(reps, &units);
    } else {
        fprintf(stderr, "bench_sim: unknown case %s\n", argv[1]);
        return 2;
    }
    printf("case=%s units=%zu unit=frame ns=%.1f\n", argv[1], units, ns);
    return 0;
}

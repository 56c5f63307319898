/* Shared bench scaffolding: timing, medians, the one-line output protocol.
 * Protocol: `bench_X --list` prints case names; `bench_X CASE REPS` prints
 * `case=CASE units=U unit=UNIT ns=X` with X the median ns per unit over REPS runs. */
#ifndef DV_BENCH_UTIL_H
#define DV_BENCH_UTIL_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static inline double bench_now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

static int bench_cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static inline double bench_median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, bench_cmp);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Deterministic unit-variance noise (xorshift64*), independent of libc rand(). */
static inline double bench_noise(uint64_t *s)
{
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    uint64_t r = *s * 2685821657736338717ull;
    return ((double)(r >> 11) * (1.0 / 9007199254740992.0) * 2.0 - 1.0) * 1.7320508075688772;
}

static volatile double bench_sink;

/* A case whose call returns the units it did (0: its set-up failed). */
typedef int (*bench_units_fn)(void);

/* The protocol's timing of one such case: a warm-up call (which also makes any plan), then
 * REPS timed calls, the median ns per unit printed as the result line. 0, or 1 when the
 * set-up fails. */
static inline int bench_time_units(const char *name, const char *unit, bench_units_fn fn,
                                   int reps)
{
    double *t = malloc(sizeof(double) * (size_t)reps);
    const int units = fn();
    if (units == 0 || t == NULL) {
        fprintf(stderr, "%s: setup failed\n", name);
        free(t);
        return 1;
    }
    for (int r = 0; r < reps; r++) {
        const double t0 = bench_now_ns();
        fn();
        t[r] = (bench_now_ns() - t0) / units;
    }
    printf("case=%s units=%d unit=%s ns=%.3f\n", name, units, unit, bench_median(t, reps));
    free(t);
    return 0;
}

/* bench_fft.c's and cmsis/cmsis_fft_bench.c's data, one definition for both element types:
 * IN[0..NMAX) unit-variance noise (a transform's speed does not depend on it); the FRF's
 * input U[0..REC) noise and its output Y a two-tap filter of it plus noise, so that the
 * coherence is neither 0 nor 1. */
#define BENCH_FFT_DATA(REAL, IN, NMAX_, U, Y, REC_)                                         \
    do {                                                                                    \
        uint64_t seed_ = 4242;                                                              \
        for (int i_ = 0; i_ < (NMAX_); i_++) (IN)[i_] = (REAL)bench_noise(&seed_);          \
        double prev_ = 0.0;                                                                 \
        for (int i_ = 0; i_ < (REC_); i_++) {                                               \
            const double ui_ = bench_noise(&seed_);                                         \
            (U)[i_] = (REAL)ui_;                                                            \
            (Y)[i_] = (REAL)(0.8 * ui_ + 0.5 * prev_ + 0.1 * bench_noise(&seed_));          \
            prev_ = ui_;                                                                    \
        }                                                                                   \
    } while (0)

#endif

/* AR benchmarks. `bench_ar --list` prints the cases; `bench_ar CASE REPS` runs one case REPS
 * times on fixed synthetic data and prints one line
 *     case=CASE units=U unit=sample|fit ns=X
 * with X the median over the reps of ns per unit (CLOCK_MONOTONIC per rep). Small REPS runs
 * under valgrind --tool=callgrind (instructions per unit from two REPS values). */
#ifndef _POSIX_C_SOURCE
#define _POSIX_C_SOURCE 199309L
#endif
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "dynval/dv_ar.h"

enum { N = 8192, P = 60 };

static dv_real_t x[N], e[N];
static dv_real_t work[DV_AR_WORK_LEN(N, DV_AR_MAX_ORDER)];
static volatile double sink;

/* Fixed synthetic data: a lightly damped 2-mode process plus noise (LCG, no libc rand). */
static void make_data(void)
{
    unsigned long long s = 0x9e3779b97f4a7c15ull;
    double y1 = 0, y2 = 0, z1 = 0, z2 = 0;
    for (int i = 0; i < N; i++) {
        s = s * 6364136223846793005ull + 1442695040888963407ull;
        double u = (double)(s >> 11) / 9007199254740992.0 - 0.5;
        double y = 1.8 * y1 - 0.95 * y2 + u;
        double z = 0.6 * z1 - 0.9 * z2 + u;
        y2 = y1; y1 = y; z2 = z1; z1 = z;
        x[i] = (dv_real_t)(y + z + 0.05 * u);
    }
}

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

static int cmp(const void *a, const void *b)
{
    double d = *(const double *)a - *(const double *)b;
    return (d > 0) - (d < 0);
}

static dv_ar_model_t model;

/* One rep of each case; returns work units done. */
static size_t rep_resid_sample(void)
{
    dv_ar_resid_t r;
    dv_real_t h[DV_AR_RESID_BUF_LEN(P)];
    dv_ar_resid_init(&r, &model, h, DV_AR_RESID_BUF_LEN(P));
    double acc = 0;
    dv_real_t ei = 0;
    for (int i = 0; i < N; i++) {
        if (dv_ar_resid_update(&r, x[i], &ei) == DV_OK) acc += (double)ei;
    }
    sink = acc;
    return N;
}

static size_t rep_resid_block(void)
{
    dv_ar_resid_t r;
    dv_real_t h[DV_AR_RESID_BUF_LEN(P)];
    dv_ar_resid_init(&r, &model, h, DV_AR_RESID_BUF_LEN(P));
    size_t n_out = 0;
    dv_ar_resid_update_block(&r, x, N, e, &n_out);
    sink = (double)e[n_out / 2] + (double)n_out;
    return N;
}

static size_t rep_fit(dv_ar_method_t meth, uint32_t p)
{
    dv_ar_model_t m;
    dv_status_t st = dv_ar_fit(&m, meth, p, x, N, work, sizeof work / sizeof *work);
    sink = (double)m.a[0] + (double)st;
    return 1;
}

static size_t rep_levinson(void) { return rep_fit(DV_AR_YULE_WALKER, P); }
static size_t rep_burg(void) { return rep_fit(DV_AR_BURG, P); }

static size_t rep_acf(void)
{
    dv_real_t r[P + 1];
    dv_ar_autocorr(x, N, P, r);
    sink = (double)r[P];
    return 1;
}

static size_t rep_order(void)
{
    dv_ar_order_t o;
    dv_ar_order(&o, DV_AR_YULE_WALKER, DV_AR_MAX_ORDER, x, N, work, sizeof work / sizeof *work);
    sink = (double)o.p_aic;
    return 1;
}

static const struct {
    const char *name;
    const char *unit;
    size_t (*fn)(void);
} cases[] = {
    {"ar60_resid_sample", "sample", rep_resid_sample},
    {"ar60_resid_block", "sample", rep_resid_block},
    {"ar60_levinson_fit_8192", "fit", rep_levinson},
    {"ar60_burg_fit_8192", "fit", rep_burg},
    {"ar60_autocorr_8192", "fit", rep_acf},
    {"ar64_order_aic_8192", "fit", rep_order},
};

int main(int argc, char **argv)
{
    const size_t nc = sizeof cases / sizeof cases[0];
    if (argc == 2 && strcmp(argv[1], "--list") == 0) {
        for (size_t i = 0; i < nc; i++) puts(cases[i].name);
        return 0;
    }
    if (argc != 3) {
        fprintf(stderr, "usage: %s --list | CASE REPS\n", argv[0]);
        return 2;
    }
    long reps = strtol(argv[2], NULL, 10);
    if (reps < 1) {
        fprintf(stderr, "REPS must be >= 1\n");
        return 2;
    }
    for (size_t c = 0; c < nc; c++) {
        if (strcmp(argv[1], cases[c].name) != 0) continue;
        make_data();
        if (dv_ar_fit(&model, DV_AR_YULE_WALKER, P, x, N, work, sizeof work / sizeof *work) !=
            DV_OK) {
            fprintf(stderr, "fit of the benchmark data failed\n");
            return 1;
        }
        double *t = malloc(sizeof(double) * (size_t)reps);
        if (t == NULL) return 1;
        size_t units = cases[c].fn(); /* warm-up */
        for (long r = 0; r < reps; r++) {
            double t0 = now_ns();
            units = cases[c].fn();
            t[r] = (now_ns() - t0) / (double)units;
        }
        qsort(t, (size_t)reps, sizeof *t, cmp);
        double med = reps % 2 ? t[reps / 2] : 0.5 * (t[reps / 2 - 1] + t[reps / 2]);
        printf("case=%s units=%zu unit=%s ns=%.3f\n", cases[c].name, units, cases[c].unit, med);
        free(t);
        return 0;
    }
    fprintf(stderr, "unknown case %s\n", argv[1]);
    return 2;
}

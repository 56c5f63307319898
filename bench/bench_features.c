/* Waveform-feature benchmarks: ns and instructions per sample, per feature and for the whole
 * per-channel set (record moments + sliding 256 + segmented STD 64x64 + temporal moments),
 * per-sample and block APIs, against the obvious one-sample-at-a-time C code. */
#include <math.h>

#include "bench_util.h"
#include "dynval/dv.h"

enum { N = 16384, WIN = 256, SEG = 64, NSEG = 64 };
static dv_real_t x[N];
static dv_real_t buf[DV_CHAN_BUF_LEN(WIN, NSEG)];

typedef void (*bench_fn)(void);

static void run_moments(void)
{
    dv_moments_t m;
    dv_moments_init(&m);
    for (int i = 0; i < N; i++) dv_moments_update(&m, x[i]);
    dv_stats_t st;
    dv_moments_get(&m, &st);
    bench_sink = st.kurt;
}

static void run_moments_block(void)
{
    dv_moments_t m;
    dv_moments_init(&m);
    dv_moments_update_block(&m, x, N);
    dv_stats_t st;
    dv_moments_get(&m, &st);
    bench_sink = st.kurt;
}

static void run_sliding(void)
{
    dv_sliding_t s;
    dv_sliding_init(&s, WIN, buf, DV_SLIDING_BUF_LEN(WIN));
    for (int i = 0; i < N; i++) dv_sliding_update(&s, x[i]);
    dv_stats_t st;
    dv_sliding_get(&s, &st);
    bench_sink = st.crest;
}

static void run_segstd(void)
{
    dv_segstd_t s;
    dv_segstd_init(&s, SEG, NSEG, buf, DV_SEGSTD_BUF_LEN(NSEG));
    for (int i = 0; i < N; i++) dv_segstd_update(&s, x[i]);
    bench_sink = s.last;
}

static void run_temporal(void)
{
    dv_temporal_t s;
    dv_temporal_init(&s, DV_R(1.0) / DV_R(640.0));
    for (int i = 0; i < N; i++) dv_temporal_update(&s, x[i]);
    dv_temporal_out_t o;
    dv_temporal_get(&s, &o);
    bench_sink = o.rms_duration;
}

static const dv_chan_config_t CFG = {WIN, SEG, NSEG, DV_R(1.0) / DV_R(640.0), false};

static void run_chan(void)
{
    dv_chan_t c;
    dv_chan_init(&c, &CFG, buf, DV_CHAN_BUF_LEN(WIN, NSEG));
    for (int i = 0; i < N; i++) dv_chan_update(&c, x[i]);
    dv_stats_t st;
    dv_chan_get_window(&c, &st);
    bench_sink = st.crest + c.last_stats.std;
}

static void run_chan_block(void)
{
    dv_chan_t c;
    dv_chan_init(&c, &CFG, buf, DV_CHAN_BUF_LEN(WIN, NSEG));
    size_t off = 0, used;
    while (off < N) {
        dv_chan_update_block(&c, x + off, N - off, &used);
        off += used;
    }
    dv_stats_t st;
    dv_chan_get_window(&c, &st);
    bench_sink = st.crest + c.last_stats.std;
}

/* The obvious code, for scale: Welford mean/M2/M3/M4 with a divide per sample. */
static void run_naive_welford(void)
{
    double n = 0, mean = 0, m2 = 0, m3 = 0, m4 = 0;
    for (int i = 0; i < N; i++) {
        double xi = (double)x[i];
        double n1 = n;
        n += 1;
        double d = xi - mean, dn = d / n, dn2 = dn * dn, t1 = d * dn * n1;
        mean += dn;
        m4 += t1 * dn2 * (n * n - 3 * n + 3) + 6 * dn2 * m2 - 4 * dn * m3;
        m3 += t1 * dn * (n - 2) - 3 * dn * m2;
        m2 += t1;
    }
    bench_sink = m4 / (m2 * m2) * n + m3 + mean;
}

static const struct {
    const char *name;
    bench_fn fn;
} CASES[] = {
    {"moments_sample", run_moments},       {"moments_block", run_moments_block},
    {"sliding256_sample", run_sliding},    {"segstd64_sample", run_segstd},
    {"temporal_sample", run_temporal},     {"chan_set_sample", run_chan},
    {"chan_set_block", run_chan_block},    {"naive_welford_sample", run_naive_welford},
};
enum { NCASES = sizeof CASES / sizeof CASES[0] };

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "--list") == 0) {
        for (int i = 0; i < NCASES; i++) printf("%s\n", CASES[i].name);
        return 0;
    }
    if (argc == 2 && strcmp(argv[1], "--sizes") == 0) {
        printf("size name=chan_state_w256_s64x64 bytes=%zu\n",
               sizeof(dv_chan_t) + sizeof(dv_real_t) * DV_CHAN_BUF_LEN(WIN, NSEG));
        printf("size name=real_type bytes=%zu\n", sizeof(dv_real_t));
        return 0;
    }
    if (argc != 3) {
        fprintf(stderr, "usage: %s --list | --sizes | CASE REPS\n", argv[0]);
        return 2;
    }
    int reps = atoi(argv[2]);
    if (reps < 1 || reps > 100000) reps = 1;
    uint64_t seed = 12345;
    for (int i = 0; i < N; i++) x[i] = (dv_real_t)(3.0 + 2.0 * bench_noise(&seed));
    for (int c = 0; c < NCASES; c++) {
        if (strcmp(argv[1], CASES[c].name) != 0) continue;
        double *t = malloc(sizeof(double) * (size_t)reps);
        CASES[c].fn(); /* warm-up */
        for (int r = 0; r < reps; r++) {
            double t0 = bench_now_ns();
            CASES[c].fn();
            t[r] = (bench_now_ns() - t0) / N;
        }
        printf("case=%s units=%d unit=sample ns=%.3f\n", CASES[c].name, N, bench_median(t, reps));
        free(t);
        return 0;
    }
    fprintf(stderr, "unknown case %s\n", argv[1]);
    return 2;
}

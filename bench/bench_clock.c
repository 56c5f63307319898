/* The host's effective core clock during a benchmark run (not a test): a chain of dependent
 * 64-bit integer multiplies, 3 cycles each on x86-64 cores (and most others), so
 * GHz = 3 / (ns per multiply). bench/run.py runs it before and after the other benchmarks and
 * states the clock in bench/RESULTS.md: this shared host runs at very different speeds from
 * one period to the next, and ns figures only compare at a known clock.
 * `bench_clock --list` / `bench_clock CASE REPS`, the protocol of bench_util.h. */
#include "bench_util.h"

enum { NMUL = 1 << 22 };

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "--list") == 0) {
        printf("clock_imul_chain\n");
        return 0;
    }
    if (argc != 3 || strcmp(argv[1], "clock_imul_chain") != 0 || atoi(argv[2]) < 1) {
        fprintf(stderr, "usage: %s --list | %s clock_imul_chain REPS\n", argv[0], argv[0]);
        return 2;
    }
    const int reps = atoi(argv[2]);
    double *t = malloc(sizeof(double) * (size_t)reps);
    if (t == NULL) return 1;
    uint64_t x = 3u;
    for (int r = 0; r < reps; r++) {
        const double t0 = bench_now_ns();
        for (int i = 0; i < NMUL; i += 4) { /* each multiply waits for the previous one */
            x *= x;                            /* (odd x stays odd: never 0) */
            x *= x;
            x *= x;
            x *= x;
        }
        t[r] = (bench_now_ns() - t0) / NMUL;
    }
    printf("case=clock_imul_chain units=%d unit=imul ns=%.4f\n", NMUL, bench_median(t, reps));
    free(t);
    return (int)(x == 0u); /* uses x, so the chain is kept */
}

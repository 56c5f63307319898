/* Prints the features of a one-number-per-line file as exact hex floats (%a), so the Python
 * binding's results can be compared with the C library's bit for bit.
 * usage: dv_features_dump FILE FS_HZ WIN_LEN SEG_LEN */
#include <stdio.h>
#include <stdlib.h>

#include "dynval/dv.h"

enum { NMAX = 1 << 20 };
static dv_real_t x[NMAX];

int main(int argc, char **argv)
{
    if (argc != 5) {
        fprintf(stderr, "usage: %s FILE FS_HZ WIN_LEN SEG_LEN\n", argv[0]);
        return 2;
    }
    FILE *f = fopen(argv[1], "r");
    if (f == NULL) {
        perror(argv[1]);
        return 2;
    }
    size_t n = 0;
    double v;
    while (n < NMAX && fscanf(f, "%lf", &v) == 1) x[n++] = (dv_real_t)v;
    fclose(f);
    const double fs = atof(argv[2]);
    const size_t win = (size_t)atol(argv[3]), seg = (size_t)atol(argv[4]);

    dv_moments_t m;
    dv_stats_t st;
    dv_moments_init(&m);
    dv_moments_update_block(&m, x, n);
    if (dv_moments_get(&m, &st) == DV_OK)
        printf("moments %a %a %a %a %a %a %a\n", (double)st.mean, (double)st.std, (double)st.rms,
               (double)st.skew, (double)st.kurt, (double)st.peak, (double)st.crest);

    static dv_real_t sbuf[3 * 65536];
    dv_sliding_t s;
    if (win <= 65536 && dv_sliding_init(&s, win, sbuf, 3 * win) == DV_OK) {
        dv_sliding_update_block(&s, x, n);
        if (dv_sliding_get(&s, &st) == DV_OK)
            printf("sliding %a %a %a %a %a\n", (double)st.mean, (double)st.std, (double)st.rms,
                   (double)st.peak, (double)st.crest);
    }

    dv_temporal_t t;
    dv_temporal_out_t o;
    dv_temporal_init(&t, (dv_real_t)(1.0 / fs));
    dv_temporal_update_block(&t, x, n);
    if (dv_temporal_get(&t, &o) == DV_OK)
        printf("temporal %a %a %a %a %a\n", (double)o.energy, (double)o.central_time,
               (double)o.rms_duration, (double)o.central_skew, (double)o.central_kurt);

    const size_t nseg = n / seg;
    static dv_real_t gbuf[2 * 65536], vec[65536];
    dv_segstd_t g;
    if (nseg >= 1 && nseg <= 65536 && dv_segstd_init(&g, seg, nseg, gbuf, 2 * nseg) == DV_OK) {
        for (size_t i = 0; i < n; i++) dv_segstd_update(&g, x[i]);
        if (dv_segstd_get(&g, vec, nseg) == DV_OK) {
            printf("segstd");
            for (size_t i = 0; i < nseg; i++) printf(" %a", (double)vec[i]);
            printf("\n");
        }
    }
    return 0;
}

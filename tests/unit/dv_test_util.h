/* Test helpers: golden-vector loading and tolerance checks shared by the unit tests. */
#ifndef DV_TEST_UTIL_H
#define DV_TEST_UTIL_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dynval/dv_types.h"

#ifdef DV_REAL_DOUBLE
#define DV_TEST_RTOL 1e-10
#else
#define DV_TEST_RTOL 2e-4
#endif

/* Read one number per line from tests/data/<name> into x (max cap); returns the count. */
static inline size_t dv_test_load(const char *name, double *x, size_t cap)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", DV_TEST_DATA_DIR, name);
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        fprintf(stderr, "cannot open %s\n", path);
        return 0;
    }
    size_t n = 0;
    while (n < cap && fscanf(f, "%lf", &x[n]) == 1) {
        n++;
    }
    fclose(f);
    return n;
}

/* Look up case,feature in a case,feature,value CSV; returns NAN when absent. */
static inline double dv_test_expected(const char *file, const char *cas, const char *feat)
{
    char path[512], line[512];
    snprintf(path, sizeof path, "%s/%s", DV_TEST_DATA_DIR, file);
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        return NAN;
    }
    double v = NAN;
    while (fgets(line, sizeof line, f) != NULL) {
        char *c1 = strchr(line, ',');
        if (c1 == NULL) continue;
        char *c2 = strchr(c1 + 1, ',');
        if (c2 == NULL) continue;
        *c1 = '\0';
        *c2 = '\0';
        if (strcmp(line, cas) == 0 && strcmp(c1 + 1, feat) == 0) {
            v = strtod(c2 + 1, NULL);
            break;
        }
    }
    fclose(f);
    return v;
}

/* |got - want| <= rtol * max(|want|, scale): relative, with an absolute floor set by scale. */
static inline int dv_test_close(double got, double want, double rtol, double scale)
{
    double ref = fabs(want) > scale ? fabs(want) : scale;
    if (!(fabs(got - want) <= rtol * ref)) {
        fprintf(stderr, "  got %.17g want %.17g (rel err %.3g, rtol %.3g)\n", got, want,
                fabs(got - want) / ref, rtol);
        return 0;
    }
    return 1;
}

#ifdef DV_MOMENTS_H
/* Bitwise equality of every field of two dv_stats_t (padding excluded). */
static inline int dv_test_stats_identical(const dv_stats_t *a, const dv_stats_t *b)
{
    const dv_real_t fa[] = {a->mean, a->var, a->std, a->rms, a->skew, a->kurt, a->peak, a->min, a->max, a->crest, a->kfactor};
    const dv_real_t fb[] = {b->mean, b->var, b->std, b->rms, b->skew, b->kurt, b->peak, b->min, b->max, b->crest, b->kfactor};
    return memcmp(fa, fb, sizeof fa) == 0 && a->count == b->count && a->flags == b->flags;
}
#endif

#ifdef DV_MOMENTS_H
/* Two dv_stats_t agree: extremes and count exactly, the moments within rtol. */
static inline int dv_test_stats_close(const dv_stats_t *a, const dv_stats_t *b, double rtol)
{
    return a->count == b->count && a->min == b->min && a->max == b->max && a->peak == b->peak &&
           dv_test_close(a->mean, b->mean, rtol, b->std) && dv_test_close(a->std, b->std, rtol, 0) &&
           dv_test_close(a->rms, b->rms, rtol, 0) && dv_test_close(a->skew, b->skew, rtol, 1) &&
           dv_test_close(a->kurt, b->kurt, rtol, 0) && dv_test_close(a->crest, b->crest, rtol, 0);
}
#endif

#endif

/* Shared helpers of the model/observer tests: the report's 4-DOF model, CSV loading, NRMSE. */
#ifndef DV_MODEL_TEST_UTIL_H
#define DV_MODEL_TEST_UTIL_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dynval/dv_model.h"
#include "dynval/dv_obs.h"

#define MT_FS 640.0
#define MT_GAP 1.0e-4
#define MT_KB 1.925e6

/* Report Section 4.1: m = (6.54, 6.66, 6.86, 6.80) kg, k1 = 10, k2..4 = 399790 N/m, force at the
 * base, model L2 modal damping (0.01, 0.05, 0.01, 0.01), outputs: the 4 accelerations. */
static inline void mt_lanl_desc(dv_model_desc_t *d)
{
    static const double m[4] = {6.54, 6.66, 6.86, 6.80};
    static const double k[4] = {10.0, 399790.0, 399790.0, 399790.0};
    static const double z[4] = {0.01, 0.05, 0.01, 0.01};
    dv_model_desc_default(d);
    d->n_dof = 4;
    for (int i = 0; i < 4; i++) {
        d->mass_kg[i] = (dv_real_t)m[i];
        d->k_n_per_m[i] = (dv_real_t)k[i];
        d->zeta[i] = (dv_real_t)z[i];
    }
    d->damp_kind = DV_DAMP_MODAL;
    d->input_kind = DV_INPUT_FORCE;
    d->input_dof = 0;
    d->n_out = 4;
    for (int i = 0; i < 4; i++) {
        d->out[i].kind = DV_OUT_ACC;
        d->out[i].index = (uint16_t)i;
    }
}

/* The report's bumper between floors 2 and 3 (DOF 2 and 3, X = x3 - x2), positive side. */
static inline void mt_add_bumper(dv_model_desc_t *d, double delta, uint16_t nsub)
{
    d->n_elem = 1;
    d->elem[0].dof_a = 2;
    d->elem[0].dof_b = 3;
    d->elem[0].side = DV_SIDE_POS;
    d->elem[0].gap_m = (dv_real_t)MT_GAP;
    d->elem[0].delta_m = (dv_real_t)delta;
    d->elem[0].kb_n_per_m = (dv_real_t)MT_KB;
    d->n_sub = nsub;
}

/* Read every number of a comma/space separated file in tests/data; returns the count. */
static inline size_t mt_load(const char *name, double *x, size_t cap)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", DV_TEST_DATA_DIR, name);
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        fprintf(stderr, "cannot open %s\n", path);
        return 0;
    }
    size_t n = 0;
    char line[4096];
    while (n < cap && fgets(line, sizeof line, f) != NULL) {
        char *p = line;
        for (;;) {
            char *end;
            double v = strtod(p, &end);
            if (end == p) {
                break;
            }
            if (n < cap) {
                x[n++] = v;
            }
            p = end;
            while (*p == ',' || *p == ' ') {
                p++;
            }
        }
    }
    fclose(f);
    return n;
}

/* Worst channel of RMS(got - want) / RMS(want); got and want are n x stride, channels 0..nch-1
 * of got (stride gs) and want (stride ws). */
static inline double mt_nrmse(const dv_real_t *got, size_t gs, const double *want, size_t ws,
                              size_t n, size_t nch, size_t skip)
{
    double worst = 0.0;
    for (size_t c = 0; c < nch; c++) {
        double se = 0.0, sr = 0.0;
        for (size_t k = skip; k < n; k++) {
            double e = (double)got[k * gs + c] - want[k * ws + c];
            se += e * e;
            sr += want[k * ws + c] * want[k * ws + c];
        }
        double v = sqrt(se / sr);
        if (!(v <= worst)) {
            worst = v;
        }
    }
    return worst;
}

#endif

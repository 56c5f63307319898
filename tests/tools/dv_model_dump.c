/* Prints the open-loop prediction of the report's 4-DOF model (Section 4.1: m = 6.54, 6.66,
 * 6.86, 6.80 kg, k = 10, 399790 x 3 N/m, modal zeta = 0.01, 0.05, 0.01, 0.01, force at DOF 1,
 * accelerations of DOF 1..4) for a one-number-per-line force file, as exact hex floats (%a),
 * one sample per line, so the Python binding (dynval.model) can be compared bit for bit.
 * With GAP DELTA KB, a positive-side contact between DOF 3 and DOF 4 (8 sub-steps) is added.
 * usage: dv_model_dump FORCE_FILE FS_HZ [GAP_M DELTA_M KB_N_PER_M] */
#include <stdio.h>
#include <stdlib.h>

#include "dynval/dv.h"

enum { NMAX = 1 << 20, NOUT = 4 };
static dv_real_t u[NMAX];
static dv_real_t y[(size_t)NMAX * NOUT];
static dv_real_t mbuf[65536];
static dv_real_t obuf[65536];

int main(int argc, char **argv)
{
    if (argc != 3 && argc != 6) {
        fprintf(stderr, "usage: %s FORCE_FILE FS_HZ [GAP_M DELTA_M KB_N_PER_M]\n", argv[0]);
        return 2;
    }
    FILE *f = fopen(argv[1], "r");
    if (f == NULL) {
        perror(argv[1]);
        return 2;
    }
    size_t n = 0;
    double v;
    while (n < NMAX && fscanf(f, "%lf", &v) == 1) u[n++] = (dv_real_t)v;
    fclose(f);
    const double fs = atof(argv[2]);

    static const double mass[4] = {6.54, 6.66, 6.86, 6.80};
    static const double k[4] = {10.0, 399790.0, 399790.0, 399790.0};
    static const double zeta[4] = {0.01, 0.05, 0.01, 0.01};
    dv_model_desc_t d;
    dv_model_desc_default(&d);
    d.n_dof = 4;
    for (unsigned i = 0; i < 4; i++) {
        d.mass_kg[i] = (dv_real_t)mass[i];
        d.k_n_per_m[i] = (dv_real_t)k[i];
        d.zeta[i] = (dv_real_t)zeta[i];
    }
    d.damp_kind = DV_DAMP_MODAL;
    d.input_kind = DV_INPUT_FORCE;
    d.input_dof = 0;
    d.n_out = NOUT;
    for (unsigned i = 0; i < NOUT; i++) {
        d.out[i].kind = DV_OUT_ACC;
        d.out[i].index = (uint16_t)i;
    }
    d.n_sub = 1;
    if (argc == 6) {
        d.n_elem = 1;
        d.n_sub = 8;
        d.elem[0].dof_a = 2;
        d.elem[0].dof_b = 3;
        d.elem[0].side = DV_SIDE_POS;
        d.elem[0].gap_m = (dv_real_t)atof(argv[3]);
        d.elem[0].delta_m = (dv_real_t)atof(argv[4]);
        d.elem[0].kb_n_per_m = (dv_real_t)atof(argv[5]);
    }
    dv_model_t m;
    dv_obs_t o;
    const size_t mlen = dv_model_buf_len(&d);
    dv_status_t st = mlen <= 65536 ? dv_model_init(&m, &d, (dv_real_t)(1.0 / fs), mbuf, mlen)
                                   : DV_ESIZE;
    if (st != DV_OK) {
        fprintf(stderr, "dv_model_init: %s\n", dv_status_str(st));
        return 1;
    }
    const size_t olen = dv_obs_buf_len(&m);
    st = olen <= 65536 ? dv_obs_init(&o, &m, NULL, obuf, olen) : DV_ESIZE;
    if (st != DV_OK) {
        fprintf(stderr, "dv_obs_init: %s\n", dv_status_str(st));
        return 1;
    }
    st = dv_obs_simulate(&o, u, n, y);
    if (st != DV_OK) fprintf(stderr, "dv_obs_simulate: %s\n", dv_status_str(st));
    for (size_t i = 0; i < n; i++)
        printf("%a %a %a %a\n", (double)y[i * NOUT], (double)y[i * NOUT + 1],
               (double)y[i * NOUT + 2], (double)y[i * NOUT + 3]);
    return st == DV_OK ? 0 : 1;
}

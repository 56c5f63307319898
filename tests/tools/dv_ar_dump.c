/* Prints the AR/ARX results of the C library as exact hex floats (%a), so the Python binding
 * (gateway/src/dynval/ar.py) can be compared with the C library bit for bit.
 * usage: dv_ar_dump XFILE FFILE P PMAX NA NB NK K_SIGMA WIN
 * XFILE, FFILE: one number per line (output and input channel, same length). One line per result:
 *   NAME v0 v1 ...       (status != DV_OK prints "NAME status S") */
#include <stdio.h>
#include <stdlib.h>

#include "dynval/dv.h"

enum { NMAX = 1 << 16, CAP = 4096 };
static dv_real_t x[NMAX], f[NMAX], e[NMAX], work[DV_ARARX_WORK_LEN(NMAX, DV_AR_MAX_ORDER, DV_AR_MAX_ORDER, DV_AR_MAX_ORDER)];
static dv_real_t hist[DV_ARX_RESID_BUF_LEN(DV_AR_MAX_ORDER, DV_AR_MAX_ORDER, DV_AR_MAX_ORDER)];
static dv_real_t sbuf[DV_ARSTATS_BUF_LEN(65536)], sizes[CAP];
static uint32_t idx[CAP];
#define WL (sizeof work / sizeof *work)

static size_t load(const char *path, dv_real_t *v)
{
    FILE *fp = fopen(path, "r");
    if (fp == NULL) {
        perror(path);
        exit(2);
    }
    size_t n = 0;
    double d;
    while (n < NMAX && fscanf(fp, "%lf", &d) == 1) v[n++] = (dv_real_t)d;
    fclose(fp);
    return n;
}

static void vec(const char *name, const dv_real_t *v, size_t n)
{
    printf("%s", name);
    for (size_t i = 0; i < n; i++) printf(" %a", (double)v[i]);
    printf("\n");
}

static void ar_model(const char *name, const dv_ar_model_t *m)
{
    printf("%s %u %a %a", name, m->order, (double)m->mean, (double)m->sigma2);
    for (uint32_t j = 0; j < m->order; j++) printf(" %a", (double)m->a[j]);
    for (uint32_t j = 0; j < m->order; j++) printf(" %a", (double)m->refl[j]);
    printf("\n");
}

static void arx_model(const char *name, const dv_arx_model_t *m)
{
    printf("%s %u %a %a", name, m->n_rows, (double)m->sigma2, (double)m->rcond);
    for (uint32_t j = 0; j < m->na; j++) printf(" %a", (double)m->alpha[j]);
    for (uint32_t j = 0; j < m->nb; j++) printf(" %a", (double)m->beta[j]);
    printf("\n");
}

static void stats(const char *name, const dv_arstats_out_t *o)
{
    printf("%s %a %a %a %a %a %llu %llu", name, (double)o->rec.mean, (double)o->rec.std,
           (double)o->rec.rms, (double)o->rec.skew, (double)o->rec.kurt,
           (unsigned long long)o->n_outliers, (unsigned long long)o->n_nonfinite);
    for (uint64_t i = 0; i < o->n_stored; i++) printf(" %u:%a", idx[i], (double)sizes[i]);
    printf("\n");
}

int main(int argc, char **argv)
{
    if (argc != 10) {
        fprintf(stderr, "usage: %s XFILE FFILE P PMAX NA NB NK K_SIGMA WIN\n", argv[0]);
        return 2;
    }
    const size_t n = load(argv[1], x);
    if (load(argv[2], f) != n) {
        fprintf(stderr, "XFILE and FFILE differ in length\n");
        return 2;
    }
    const uint32_t p = (uint32_t)atol(argv[3]), pmax = (uint32_t)atol(argv[4]);
    const dv_arx_cfg_t cfg = {(uint32_t)atol(argv[5]), (uint32_t)atol(argv[6]),
                              (uint32_t)atol(argv[7])};
    const dv_real_t ks = (dv_real_t)atof(argv[8]);
    const size_t win = (size_t)atol(argv[9]);
    dv_status_t st;

    dv_real_t r[DV_AR_MAX_ORDER + 1];
    if ((st = dv_ar_autocorr(x, n, pmax, r)) == DV_OK) vec("autocorr", r, pmax + 1u);
    else printf("autocorr status %d\n", (int)st);

    static const char *const mname[2] = {"yw", "burg"};
    dv_ar_model_t m[2];
    for (int k = 0; k < 2; k++) {
        char name[32];
        snprintf(name, sizeof name, "fit_%s", mname[k]);
        if ((st = dv_ar_fit(&m[k], (dv_ar_method_t)k, p, x, n, work, WL)) == DV_OK) ar_model(name, &m[k]);
        else printf("%s status %d\n", name, (int)st);
        dv_ar_order_t o;
        snprintf(name, sizeof name, "order_%s", mname[k]);
        if ((st = dv_ar_order(&o, (dv_ar_method_t)k, pmax, x, n, work, WL)) == DV_OK) {
            printf("%s %u %u %u %a\n", name, o.pmax, o.p_aic, o.p_pacf, (double)o.band);
            snprintf(name, sizeof name, "aic_%s", mname[k]);
            vec(name, o.aic, o.pmax);
            snprintf(name, sizeof name, "pacf_%s", mname[k]);
            vec(name, o.pacf, o.pmax);
            snprintf(name, sizeof name, "sigma2_%s", mname[k]);
            vec(name, o.sigma2, o.pmax);
        } else {
            printf("%s status %d\n", name, (int)st);
        }
    }

    /* streaming residual of the Yule-Walker model: per sample and block */
    dv_ar_resid_t rs;
    size_t k = 0, n_out = 0;
    if (dv_ar_resid_init(&rs, &m[0], hist, sizeof hist / sizeof *hist) == DV_OK) {
        for (size_t i = 0; i < n; i++)
            if (dv_ar_resid_update(&rs, x[i], e + k) == DV_OK) k++;
        vec("resid_sample", e, k);
        dv_ar_resid_reset(&rs);
        dv_ar_resid_update_block(&rs, x, n, e, &n_out);
        vec("resid_block", e, n_out);
    }

    /* residual statistics of the block residual: record and stream */
    dv_arstats_out_t so;
    if ((st = dv_arstats_record(&so, ks, e, n_out, idx, sizes, CAP)) == DV_OK) stats("stats_record", &so);
    else printf("stats_record status %d\n", (int)st);
    dv_arstats_t ss;
    if (win <= 65536 && dv_arstats_init(&ss, ks, win, sbuf, sizeof sbuf / sizeof *sbuf, idx, sizes, CAP) == DV_OK) {
        for (size_t i = 0; i < n_out; i++) dv_arstats_update(&ss, e[i]);
        if ((st = dv_arstats_get(&ss, &so)) == DV_OK) stats("stats_stream", &so);
        else printf("stats_stream status %d\n", (int)st);
    }

    /* ARX, its residual, AR-ARX */
    dv_arx_model_t am;
    if ((st = dv_arx_fit(&am, &cfg, x, f, n, work, WL)) == DV_OK) {
        arx_model("arx", &am);
        dv_arx_resid_t ar;
        if (dv_arx_resid_init(&ar, &am, hist, sizeof hist / sizeof *hist) == DV_OK) {
            k = 0;
            for (size_t i = 0; i < n; i++)
                if (dv_arx_resid_update(&ar, x[i], f[i], e + k) == DV_OK) k++;
            vec("arx_resid", e, k);
        }
    } else {
        printf("arx status %d\n", (int)st);
    }
    dv_arx_cfg_t c2 = cfg;
    c2.nk = 0;
    dv_ar_model_t a1;
    if ((st = dv_ararx_fit(&am, &a1, &c2, p, x, n, work, WL)) == DV_OK) {
        arx_model("ararx", &am);
        ar_model("ararx_ar", &a1);
    } else {
        printf("ararx status %d\n", (int)st);
    }
    return 0;
}

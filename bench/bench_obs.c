/* Benchmark of the model observer (not a test).
 * `bench_obs --list` prints the cases; `bench_obs CASE REPS` prints one line
 * `case=CASE units=U unit=step|record ns=X`, X = median ns per unit over REPS repetitions.
 * The report's 4-DOF model (8 states, force input, 4 accelerations out, model L2 damping) at
 * 640 Hz; step cases run one 8192-sample record per repetition through dv_obs_step() with the
 * Kalman gain folded in and measured channels from a model with 5 % stiffer columns. The
 * contact cases use the report's bumper (gap 0.1 mm, Delta 0.1 mm, kB 1.925e6 N/m, 8 sub-steps;
 * this record's force engages it in 6 of 8192 steps, so they mostly measure the open element)
 * and, as the worst case a firmware budgets for, obs_step_4dof_contact_engaged: the same bumper
 * at zero gap on both sides, which solves the contact chain in every step. obs_block_4dof: the
 * obs_step_4dof steps through dv_obs_update_block() (predictions and residuals stored).
 * obs_step_4dof_contact_lanl: the contact model's steps on data it did not make, the independent
 * simulation of the report's structure with a bumper (../shared/data/synthetic/lanl4dof-bumper,
 * test_high_01: its force and four accelerations); listed only when the environment variable
 * DV_BENCH_DATA names that data directory (bench/run.py sets it when ../shared is there).
 * obs_step_5dof / obs_step_5dof_two_contacts: the general path (any size but 8 states and 4
 * outputs): a 5-DOF chain (6-7.2 kg, 4e5-3.2e5 N/m, 2 % modal damping, force at DOF 1, five
 * accelerations) with the gain, linear, and with two gap elements on story 2 (one per side,
 * gap 20 um, Delta 10 um, 1e6 N/m, 8 sub-steps: 18 nodes) that this force engages. */
#include "bench_util.h"

#include "dynval/dv_model.h"
#include "dynval/dv_obs.h"

enum { NREC = 8192, NBUF = 40000 };

static dv_real_t mbuf[NBUF], mbuf2[NBUF], obuf[NBUF], obuf2[NBUF];
static dv_real_t force[NREC], ymeas[NREC * 8], yout[NREC * 8], yres[NREC * 8];

static dv_input_hold_t g_hold = DV_HOLD_FOH;

static int g_engaged; /* the worst case: a bumper at zero gap on both sides, engaged every step */
static int g_chain5;  /* the 5-DOF chain instead of the report's structure */

/* The bumper test's force and accelerations into force / ymeas (NREC rows); 0 on success. */
static int load_lanl(void)
{
    const char *dir = getenv("DV_BENCH_DATA");
    char path[1024];
    if (dir == NULL ||
        snprintf(path, sizeof path, "%s/synthetic/lanl4dof-bumper/test_high_01.csv", dir) >=
            (int)sizeof path) {
        return -1;
    }
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        return -1;
    }
    char head[256];
    int k = 0;
    if (fgets(head, sizeof head, f) != NULL) {
        double t, v[5];
        while (k < NREC && fscanf(f, "%lf,%lf,%lf,%lf,%lf,%lf", &t, &v[0], &v[1], &v[2], &v[3],
                                  &v[4]) == 6) {
            force[k] = (dv_real_t)v[0];
            for (int q = 0; q < 4; q++) ymeas[4 * k + q] = (dv_real_t)v[q + 1];
            k++;
        }
    }
    fclose(f);
    return k == NREC ? 0 : -1;
}

/* The 5-DOF chain of the header comment; contact: its two gap elements on story 2. */
static void chain5(dv_model_desc_t *d, int contact, double kscale)
{
    dv_model_desc_default(d);
    d->n_dof = 5;
    for (int i = 0; i < 5; i++) {
        d->mass_kg[i] = (dv_real_t)(6.0 + 0.3 * i);
        d->k_n_per_m[i] = (dv_real_t)(4.0e5 * kscale * (1.0 - 0.05 * i));
        d->zeta[i] = (dv_real_t)0.02;
        d->out[i].kind = DV_OUT_ACC;
        d->out[i].index = (uint16_t)i;
    }
    d->n_out = 5;
    if (contact) {
        d->n_elem = 2;
        d->n_sub = 8;
        for (int e = 0; e < 2; e++) {
            d->elem[e].dof_a = 1;
            d->elem[e].dof_b = 2;
            d->elem[e].side = e ? DV_SIDE_NEG : DV_SIDE_POS;
            d->elem[e].gap_m = (dv_real_t)2e-5;
            d->elem[e].delta_m = (dv_real_t)1e-5;
            d->elem[e].kb_n_per_m = (dv_real_t)1e6;
        }
    }
}

static void lanl(dv_model_desc_t *d, int contact, uint16_t nsub, double kscale)
{
    if (g_chain5) {
        chain5(d, contact, kscale);
        return;
    }
    static const double m[4] = {6.54, 6.66, 6.86, 6.80};
    static const double z[4] = {0.01, 0.05, 0.01, 0.01};
    dv_model_desc_default(d);
    d->n_dof = 4;
    for (int i = 0; i < 4; i++) {
        d->mass_kg[i] = (dv_real_t)m[i];
        d->k_n_per_m[i] = (dv_real_t)(i == 0 ? 10.0 : 399790.0 * kscale);
        d->zeta[i] = (dv_real_t)z[i];
    }
    d->input_hold = g_hold;
    d->n_out = 4;
    for (int i = 0; i < 4; i++) {
        d->out[i].kind = DV_OUT_ACC;
        d->out[i].index = (uint16_t)i;
    }
    if (contact) {
        d->n_elem = 1;
        d->elem[0].dof_a = 2;
        d->elem[0].dof_b = 3;
        d->elem[0].side = g_engaged ? DV_SIDE_BOTH : DV_SIDE_POS;
        d->elem[0].gap_m = (dv_real_t)(g_engaged ? 0.0 : 1e-4);
        d->elem[0].delta_m = (dv_real_t)1e-4;
        d->elem[0].kb_n_per_m = (dv_real_t)1.925e6;
        d->n_sub = nsub;
    }
}

/* Force: white noise through a 2-pole resonator around 100 Hz, ~12 N RMS (deterministic). */
static void make_force(void)
{
    uint64_t s = 0x9E3779B97F4A7C15ull;
    double y1 = 0, y2 = 0;
    const double r = 0.9, c = 2 * r * 0.7071; /* poles at +-45 deg: ~80 Hz at 640 Hz */
    for (int k = 0; k < NREC; k++) {
        double y = bench_noise(&s) + c * y1 - r * r * y2;
        y2 = y1;
        y1 = y;
        force[k] = (dv_real_t)(3.0 * y);
    }
}

static int setup(dv_model_t *m, dv_obs_t *o, int contact, uint16_t nsub, int gain)
{
    dv_model_desc_t d;
    dv_model_t mt;
    dv_obs_t ot;
    const dv_real_t dt = (dv_real_t)(1.0 / 640.0);
    make_force();
    lanl(&d, contact, nsub, 1.05);
    if (dv_model_init(&mt, &d, dt, mbuf2, NBUF) != DV_OK ||
        dv_obs_init(&ot, &mt, NULL, obuf2, NBUF) != DV_OK) {
        return -1;
    }
    dv_obs_simulate(&ot, force, NREC, ymeas);
    lanl(&d, contact, nsub, 1.0);
    dv_obs_noise_t nz;
    for (unsigned i = 0; i < DV_MAX_DOF; i++) nz.q_force_n2[i] = 1;
    for (unsigned i = 0; i < DV_MAX_OUT; i++) nz.r_meas[i] = (dv_real_t)0.04;
    if (dv_model_init(m, &d, dt, mbuf, NBUF) != DV_OK ||
        dv_obs_init(o, m, gain ? &nz : NULL, obuf, NBUF) != DV_OK) {
        return -1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    static const char *cases[] = {"obs_step_4dof", "obs_step_4dof_contact",
                                  "obs_step_4dof_contact16", "sim_record_8192",
                                  "sim_record_8192_contact", "obs_step_4dof_cubic",
                                  "obs_step_4dof_contact_cubic", "sim_record_8192_cubic",
                                  "obs_step_4dof_contact_engaged", "obs_block_4dof",
                                  "obs_step_4dof_contact_lanl", "obs_step_5dof",
                                  "obs_step_5dof_two_contacts"};
    const int ncase = (int)(sizeof cases / sizeof cases[0]);
    if (argc == 2 && strcmp(argv[1], "--list") == 0) {
        for (int i = 0; i < ncase; i++) {
            if (i != 10 || load_lanl() == 0) printf("%s\n", cases[i]);
        }
        return 0;
    }
    if (argc == 2 && strcmp(argv[1], "--sizes") == 0) {
        /* bytes per instance: the structs, the storage the step touches (state vector,
         * prediction, residual, the folded matrix) and the whole init-time buffers */
        for (int c = 0; c < 2; c++) {
            dv_model_t m;
            dv_obs_t o;
            if (setup(&m, &o, c, 8, 1) != 0) return 1;
            const size_t nr = sizeof(dv_real_t);
            const size_t step = (size_t)o.ncol_gain + o.nrows + o.no +
                                (size_t)o.ns * o.ncol_gain + (size_t)o.no * o.ncol_open;
            printf("size name=obs_state_%s bytes=%zu\n", c ? "contact" : "linear",
                   sizeof(dv_obs_t) + step * nr);
            printf("size name=obs_struct_%s bytes=%zu\n", c ? "contact" : "linear",
                   sizeof(dv_obs_t));
            printf("size name=obs_buffer_%s bytes=%zu\n", c ? "contact" : "linear",
                   dv_obs_buf_len(&m) * nr);
            printf("size name=obs_persistent_%s bytes=%zu\n", c ? "contact" : "linear",
                   dv_obs_persistent_len(&m) * nr);
        }
        return 0;
    }
    if (argc != 3) {
        fprintf(stderr, "usage: %s --list | %s CASE REPS\n", argv[0], argv[0]);
        return 2;
    }
    const char *cs = argv[1];
    const int reps = atoi(argv[2]);
    if (reps < 1) {
        fprintf(stderr, "REPS must be >= 1\n");
        return 2;
    }
    int which = -1;
    for (int i = 0; i < ncase; i++)
        if (strcmp(cs, cases[i]) == 0) which = i;
    if (which < 0) {
        fprintf(stderr, "unknown case %s\n", cs);
        return 2;
    }
    const int contact = which == 1 || which == 2 || which == 4 || which == 6 || which == 8 ||
                        which == 10 || which == 12;
    const uint16_t nsub = which == 2 ? 16 : 8;
    const int is_step = which <= 2 || which == 5 || which == 6 || which == 8 || which == 9 ||
                        which >= 10;
    const int block = which == 9; /* the same steps through dv_obs_update_block() */
    if (which >= 5 && which <= 7) g_hold = DV_HOLD_CUBIC;
    g_engaged = which == 8;
    g_chain5 = which >= 11;
    dv_model_t m;
    dv_obs_t o;
    if (setup(&m, &o, contact, nsub, is_step) != 0 || (which == 10 && load_lanl() != 0)) {
        fprintf(stderr, "setup failed\n");
        return 1;
    }
    double *t = malloc(sizeof(double) * (size_t)reps);
    if (t == NULL) return 1;
    double acc = 0;
    for (int r = 0; r < reps; r++) {
        const double t0 = bench_now_ns();
        if (is_step) {
            dv_obs_reset(&o);
            if (block) {
                dv_obs_update_block(&o, force, ymeas, NREC, yout, yres);
            } else {
                for (int k = 0; k < NREC; k++) dv_obs_step(&o, force[k], ymeas + o.no * k);
            }
            acc += (double)o.resid[3];
            t[r] = (bench_now_ns() - t0) / NREC;
        } else {
            dv_obs_simulate(&o, force, NREC, yout);
            acc += (double)yout[4 * NREC - 1];
            t[r] = bench_now_ns() - t0;
        }
    }
    bench_sink = acc;
    printf("case=%s units=%d unit=%s ns=%.2f\n", cs, is_step ? NREC : 1,
           is_step ? "step" : "record", bench_median(t, reps));
    free(t);
    return 0;
}

/* The library's golden vectors on the target: features (dv_chan and the standalone modules),
 * AR fits and the streaming AR residual, observer steps of the report's 4-DOF model (linear,
 * with the bumper contact, with the Kalman gain), and the streaming Welch FRF of a resonance.
 * The same source is built for the Cortex-M4F image (semihosting) and for the host twin (stdio)
 * against the float library.
 *
 * Output, one line each:
 *   CHECK <PASS|FAIL> <name> n=<values> maxerr=<max |got-want|/ref> tol=<rtol>
 *   V <name> <hex> <hex> ...      every library output compared, as float bits (run_m4.sh
 *                                 diffs these against the host twin)
 *   INFO <text>
 *   RESULT <PASS|FAIL> <passed>/<checks>
 * Tolerances are those of the host float unit tests (DV_TEST_RTOL = 2e-4 and the per-test
 * values quoted in each block), judged as |got - want| <= rtol * max(|want|, scale). */
#include <math.h>
#include <string.h>

#include "dynval/dv.h"
#include "dv_m4_vectors.h"
#include "m4_plat.h"

#ifndef RTOL
#define RTOL 2e-4 /* DV_TEST_RTOL of the float build */
#endif

static uint32_t n_checks, n_failed;

static uint32_t bits(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

static void dump(const char *name, const float *v, size_t n)
{
    for (size_t i = 0; i < n; i += 8u) {
        m4_put("V ");
        m4_put(name);
        m4_put(" ");
        m4_put_u((uint32_t)i);
        for (size_t j = i; j < n && j < i + 8u; j++) {
            m4_put(" ");
            m4_put_hex32(bits(v[j]));
        }
        m4_line_end();
    }
}

static void info(const char *a, uint32_t v, const char *b)
{
    m4_put("INFO ");
    m4_put(a);
    m4_put_u(v);
    m4_put(b);
    m4_line_end();
}

static void report(const char *name, int ok, size_t n, double maxerr, double tol)
{
    n_checks++;
    n_failed += ok ? 0u : 1u;
    m4_put(ok ? "CHECK PASS " : "CHECK FAIL ");
    m4_put(name);
    m4_put(" n=");
    m4_put_u((uint32_t)n);
    m4_put(" maxerr=");
    m4_put_e(maxerr);
    m4_put(" tol=");
    m4_put_e(tol);
    m4_line_end();
}

/* A status/count check: pass when got == want. */
static void check_eq(const char *name, long got, long want)
{
    report(name, got == want, 1u, got == want ? 0.0 : 1.0, 0.0);
}

/* Accumulates the worst |got - want| / ref of a group, ref = max(|want|, scale). */
typedef struct {
    double worst;
    int ok;
    size_t n;
} acc_t;

static void acc_init(acc_t *a)
{
    a->worst = 0.0;
    a->ok = 1;
    a->n = 0u;
}

static void acc_add(acc_t *a, double got, double want, double rtol, double scale)
{
    double ref = fabs(want) > scale ? fabs(want) : scale;
    double err = fabs(got - want) / ref;
    if (!(err <= rtol)) {
        a->ok = 0;
    }
    if (!(err <= a->worst)) {
        a->worst = err;
    }
    a->n++;
}

/* ================================ features ================================================ */
enum { NF = 4096, WIN = 256, SEGL = 64, NSEG = 64 };
static const float *const feat_x[4] = {feat_random, feat_decay, feat_skewed, feat_offset};
static const char *const feat_name[4] = {"random", "decay", "skewed", "offset"};
static const double *const want_rec[4] = {want_rec_random, want_rec_decay, want_rec_skewed,
                                          want_rec_offset};
static const double *const want_win[4] = {want_win_random, want_win_decay, want_win_skewed,
                                          want_win_offset};
static const double *const want_tm[4] = {want_tm_random, want_tm_decay, want_tm_skewed,
                                         want_tm_offset};
static const double *const want_seg[4] = {want_seg_random, want_seg_decay, want_seg_skewed,
                                          want_seg_offset};
static dv_real_t chan_buf[DV_CHAN_BUF_LEN(WIN, NSEG)];
static dv_real_t win_buf[DV_SLIDING_BUF_LEN(WIN)];
static dv_real_t seg_buf[DV_SEGSTD_BUF_LEN(NSEG)];

static void name3(char *out, const char *a, const char *b, const char *c)
{
    strcpy(out, a);
    strcat(out, b);
    strcat(out, c);
}

/* Record statistics vs rec_* (test_dv_moments: mean on the STD's scale, var on STD^2, skew and
 * kurt with an absolute floor of 1; STD/var of the offset signal 5e-4: 1e4 + noise in float). */
static void check_rec(const char *name, int c, const dv_stats_t *st)
{
    const double *w = want_rec[c];
    const float got[11] = {st->mean, st->std, st->var, st->rms, st->skew, st->kurt,
                           st->peak, st->min, st->max, st->crest, st->kfactor};
    acc_t a;
    acc_init(&a);
    double tol = RTOL;
    for (int k = 0; k < 11; k++) {
        double scale = k == 0 ? w[1] : (k == 2 ? w[1] * w[1] : (k == 4 || k == 5 ? 1.0 : 0.0));
        double rtol = RTOL;
        if ((k == 1 || k == 2) && fabs(w[0]) > 100.0 * w[1]) {
            rtol = 5e-4;
            tol = rtol;
        }
        acc_add(&a, got[k], w[k], rtol, scale);
    }
    report(name, a.ok && st->count == NF, a.n, a.worst, tol);
    dump(name, got, 11u);
}

/* Window statistics vs win_* (test_dv_sliding: offset STD 1e-3). */
static void check_win(const char *name, int c, const dv_stats_t *st)
{
    const double *w = want_win[c];
    const float got[10] = {st->mean, st->std, st->rms, st->skew, st->kurt,
                           st->peak, st->min, st->max, st->crest, st->kfactor};
    acc_t a;
    acc_init(&a);
    double tol = RTOL;
    for (int k = 0; k < 10; k++) {
        double scale = k == 0 ? w[1] : (k == 3 || k == 4 ? 1.0 : 0.0);
        double rtol = (c == 3 && k == 1) ? 1e-3 : RTOL;
        tol = rtol > tol ? rtol : tol;
        acc_add(&a, got[k], w[k], rtol, scale);
    }
    report(name, a.ok && st->count == WIN, a.n, a.worst, tol);
    dump(name, got, 10u);
}

/* Temporal moments vs tm_* (time-like moments on the RMS duration's scale). */
static void check_tm(const char *name, int c, const dv_temporal_out_t *o)
{
    const double *w = want_tm[c];
    const float got[6] = {o->energy, o->central_time, o->rms_duration, o->central_skew,
                          o->central_kurt, o->root_energy_amp};
    acc_t a;
    acc_init(&a);
    for (int k = 0; k < 6; k++) {
        acc_add(&a, got[k], w[k], RTOL, (k >= 1 && k <= 4) ? w[2] : 0.0);
    }
    report(name, a.ok && o->count == NF, a.n, a.worst, RTOL);
    dump(name, got, 6u);
}

/* Segmented STD vs segstd_* (offset: 2e-3, the float input itself carries 3e-4 rounding). */
static void check_seg(const char *name, int c, const float *v)
{
    acc_t a;
    acc_init(&a);
    const double rtol = c == 3 ? 2e-3 : RTOL;
    for (int k = 0; k < NSEG; k++) {
        acc_add(&a, v[k], want_seg[c][k], rtol, 0.0);
    }
    report(name, a.ok, a.n, a.worst, rtol);
    dump(name, v, NSEG);
}

static void features(void)
{
    char name[64];
    for (int c = 0; c < 4; c++) {
        const float *x = feat_x[c];
        /* dv_chan: the per-channel bundle, one call per sample */
        dv_chan_t ch;
        const dv_chan_config_t cfg = {WIN, SEGL, NSEG, DV_R(1.0) / DV_R(640.0), false};
        dv_status_t st = dv_chan_init(&ch, &cfg, chan_buf, DV_CHAN_BUF_LEN(WIN, NSEG));
        long records = 0, segs = 0;
        for (int i = 0; i < NF; i++) {
            dv_status_t s = dv_chan_update(&ch, x[i]);
            records += s == DV_RECORD;
            segs += s == DV_DONE;
        }
        name3(name, "chan.", feat_name[c], ".segments+records");
        check_eq(name, (st == DV_OK) * 1000 + segs * 10 + records, 1000 + (NSEG - 1) * 10 + 1);
        dv_stats_t rs, ws;
        dv_temporal_out_t tm;
        dv_real_t sv[NSEG];
        int ok = dv_chan_get_record(&ch, &rs, &tm) == DV_OK &&
                 dv_chan_get_window(&ch, &ws) == DV_OK && dv_segstd_get(&ch.seg, sv, NSEG) == DV_OK;
        name3(name, "chan.", feat_name[c], ".get");
        check_eq(name, ok, 1);
        name3(name, "chan.", feat_name[c], ".rec");
        check_rec(name, c, &rs);
        name3(name, "chan.", feat_name[c], ".win");
        check_win(name, c, &ws);
        name3(name, "chan.", feat_name[c], ".temporal");
        check_tm(name, c, &tm);
        name3(name, "chan.", feat_name[c], ".segstd");
        check_seg(name, c, sv);

        /* the standalone modules, one call per sample each */
        dv_moments_t mo;
        dv_sliding_t sl;
        dv_segstd_t sg;
        dv_temporal_t tp;
        ok = dv_moments_init(&mo) == DV_OK &&
             dv_sliding_init(&sl, WIN, win_buf, DV_SLIDING_BUF_LEN(WIN)) == DV_OK &&
             dv_segstd_init(&sg, SEGL, NSEG, seg_buf, DV_SEGSTD_BUF_LEN(NSEG)) == DV_OK &&
             dv_temporal_init(&tp, (dv_real_t)(1.0 / 640.0)) == DV_OK;
        for (int i = 0; i < NF; i++) {
            ok &= dv_moments_update(&mo, x[i]) == DV_OK;
            ok &= dv_sliding_update(&sl, x[i]) == DV_OK;
            ok &= dv_segstd_update(&sg, x[i]) >= DV_OK;
            ok &= dv_temporal_update(&tp, x[i]) == DV_OK;
        }
        ok &= dv_moments_get(&mo, &rs) == DV_OK && dv_sliding_get(&sl, &ws) == DV_OK &&
              dv_temporal_get(&tp, &tm) == DV_OK && dv_segstd_get(&sg, sv, NSEG) == DV_OK;
        name3(name, "mod.", feat_name[c], ".status");
        check_eq(name, ok, 1);
        name3(name, "moments.", feat_name[c], ".rec");
        check_rec(name, c, &rs);
        name3(name, "sliding.", feat_name[c], ".win");
        check_win(name, c, &ws);
        name3(name, "temporal.", feat_name[c], "");
        check_tm(name, c, &tm);
        name3(name, "segstd.", feat_name[c], "");
        check_seg(name, c, sv);
    }
}

/* ================================ AR ====================================================== */
enum { NAR = 8192 };
static dv_real_t ar_work[DV_AR_WORK_LEN(NAR, 32)];
static dv_real_t resid[NAR], resid_blk[NAR];

/* Fit vs golden (test_dv_ar check_fit, float: RTOL_FIT 2e-3; coefficients on the scale of the
 * largest, reflection coefficients with a floor of 1, the mean on the record's STD). */
static void check_fit(const char *name, dv_ar_method_t meth, uint32_t p, const float *x,
                      const double *wa, const double *wr, double ws2, double wmean, double acf0)
{
    dv_ar_model_t m;
    dv_status_t st = dv_ar_fit(&m, meth, p, x, NAR, ar_work, sizeof ar_work / sizeof *ar_work);
    char nm[64];
    name3(nm, name, ".status", "");
    check_eq(nm, st, DV_OK);
    double sa = 0.0;
    for (uint32_t j = 0; j < p; j++) {
        sa = fabs(wa[j]) > sa ? fabs(wa[j]) : sa;
    }
    acc_t a;
    acc_init(&a);
    for (uint32_t j = 0; j < p; j++) {
        acc_add(&a, m.a[j], wa[j], 2e-3, sa);
        acc_add(&a, m.refl[j], wr[j], 2e-3, 1.0);
    }
    acc_add(&a, m.sigma2, ws2, 2e-3, 0.0);
    acc_add(&a, m.mean, wmean, 2e-3, sqrt(acf0));
    report(name, a.ok, a.n, a.worst, 2e-3);
    float v[2 * 8 + 2];
    for (uint32_t j = 0; j < p; j++) {
        v[j] = m.a[j];
        v[p + j] = m.refl[j];
    }
    v[2 * p] = m.sigma2;
    v[2 * p + 1] = m.mean;
    dump(name, v, 2u * p + 2u);
}

static void ar(void)
{
    check_fit("ar.yw4_fit", DV_AR_YULE_WALKER, 4, ar_ar4, want_yw4_a, want_yw4_pacf,
              want_yw4_sigma2, want_ar4_mean, want_ar4_acf0);
    check_fit("ar.burg8_fit", DV_AR_BURG, 8, ar_ar8, want_burg8_a, want_burg8_refl,
              want_burg8_sigma2, want_ar8_mean, want_ar8_acf0);

    /* streaming residual of the golden Burg AR(30) model of the structure record, per sample
     * and block, vs its definition in double (test_dv_ar: 100 * DV_TEST_RTOL of sigma) */
    dv_ar_model_t m;
    memset(&m, 0, sizeof m);
    m.order = 30;
    m.n = NAR;
    m.mean = struct_burg30_mean;
    m.sigma2 = (dv_real_t)struct_burg30_sigma2;
    for (int j = 0; j < 30; j++) {
        m.a[j] = struct_burg30_a[j];
    }
    static dv_real_t hist[DV_AR_RESID_BUF_LEN(32)], hist2[DV_AR_RESID_BUF_LEN(32)];
    dv_ar_resid_t r, r2;
    int ok = dv_ar_resid_init(&r, &m, hist, DV_AR_RESID_BUF_LEN(30)) == DV_OK &&
             dv_ar_resid_init(&r2, &m, hist2, DV_AR_RESID_BUF_LEN(30)) == DV_OK;
    size_t k = 0;
    for (size_t i = 0; i < NAR; i++) {
        k += dv_ar_resid_update(&r, ar_struct[i], &resid[k]) == DV_OK;
    }
    size_t kb = 0, got = 0;
    const size_t cuts[] = {0, 7, 8, 70, 71, 1500, 4099, NAR};
    for (int b = 0; b + 1 < 8; b++) {
        ok &= dv_ar_resid_update_block(&r2, ar_struct + cuts[b], cuts[b + 1] - cuts[b],
                                       resid_blk + kb, &got) == DV_OK;
        kb += got;
    }
    check_eq("ar.resid30.count", (long)(ok * 100000 + (int)k), 100000 + NAR - 30);
    check_eq("ar.resid30_block.count", (long)kb, NAR - 30);
    const double sig = sqrt(struct_burg30_sigma2);
    acc_t a, ab;
    acc_init(&a);
    acc_init(&ab);
    for (size_t i = 0; i < k; i++) {
        acc_add(&a, resid[i], want_struct_resid[i], 100 * RTOL, sig);
        acc_add(&ab, resid_blk[i], want_struct_resid[i], 100 * RTOL, sig);
    }
    report("ar.resid30", a.ok, a.n, a.worst, 100 * RTOL);
    report("ar.resid30_block", ab.ok, ab.n, ab.worst, 100 * RTOL);
    dump("ar.resid30", resid, k);
    dump("ar.resid30_block", resid_blk, kb);

    /* AR(32), the firmware order: Burg fit on the target, then its residual. The residual RMS
     * must be the model's innovation STD (within 5 %), and below the record's STD by far. */
    dv_ar_model_t m32;
    dv_status_t st = dv_ar_fit(&m32, DV_AR_BURG, 32, ar_struct, NAR, ar_work,
                               sizeof ar_work / sizeof *ar_work);
    check_eq("ar.burg32_fit.status", st, DV_OK);
    ok = dv_ar_resid_init(&r, &m32, hist, DV_AR_RESID_BUF_LEN(32)) == DV_OK;
    k = 0;
    for (size_t i = 0; i < NAR; i++) {
        k += dv_ar_resid_update(&r, ar_struct[i], &resid[k]) == DV_OK;
    }
    double ss = 0.0, sx = 0.0;
    for (size_t i = 0; i < k; i++) {
        ss += (double)resid[i] * resid[i];
    }
    for (size_t i = 0; i < NAR; i++) {
        sx += ((double)ar_struct[i] - m32.mean) * ((double)ar_struct[i] - m32.mean);
    }
    double rms = sqrt(ss / (double)k), sdx = sqrt(sx / NAR);
    double e = fabs(rms / sqrt(m32.sigma2) - 1.0);
    report("ar.resid32_rms_vs_sigma", ok && k == NAR - 32 && e <= 0.05 && rms < 0.5 * sdx, 1u, e,
           0.05);
    float v[34];
    for (int j = 0; j < 32; j++) {
        v[j] = m32.a[j];
    }
    v[32] = m32.sigma2;
    v[33] = m32.mean;
    dump("ar.burg32_fit", v, 34u);
    dump("ar.resid32", resid, k);
}

/* ================================ observer ================================================ */
enum { NS = 2048, MBUF = 4096 };
static dv_real_t mbuf[MBUF], obuf[MBUF];
static dv_real_t yout[NS * 5], ytrue[NS * 4], rbuf[NS * 4];

/* Report Section 4.1 (tests/unit/dv_model_test_util.h): m = (6.54, 6.66, 6.86, 6.80) kg,
 * k1 = 10, k2..4 = 399790 N/m, modal damping (0.01, 0.05, 0.01, 0.01), force at DOF 0,
 * outputs the 4 accelerations; the bumper between DOF 2 and 3, gap 0.1 mm, kB 1.925e6 N/m. */
static void lanl_desc(dv_model_desc_t *d)
{
    static const float m[4] = {6.54f, 6.66f, 6.86f, 6.80f};
    static const float k[4] = {10.0f, 399790.0f, 399790.0f, 399790.0f};
    static const float z[4] = {0.01f, 0.05f, 0.01f, 0.01f};
    dv_model_desc_default(d);
    d->n_dof = 4;
    for (int i = 0; i < 4; i++) {
        d->mass_kg[i] = m[i];
        d->k_n_per_m[i] = k[i];
        d->zeta[i] = z[i];
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

static void add_bumper(dv_model_desc_t *d, float delta, uint16_t nsub)
{
    d->n_elem = 1;
    d->elem[0].dof_a = 2;
    d->elem[0].dof_b = 3;
    d->elem[0].side = DV_SIDE_POS;
    d->elem[0].gap_m = 1.0e-4f;
    d->elem[0].delta_m = delta;
    d->elem[0].kb_n_per_m = 1.925e6f;
    d->n_sub = nsub;
}

/* Worst channel of RMS(got - want) / RMS(want) (tests/unit/dv_model_test_util.h mt_nrmse). */
static double nrmse(const float *got, size_t gs, const double *want, size_t ws, size_t nch)
{
    double worst = 0.0;
    for (size_t c = 0; c < nch; c++) {
        double se = 0.0, sr = 0.0;
        for (size_t k = 0; k < NS; k++) {
            double e = (double)got[k * gs + c] - want[k * ws + c];
            se += e * e;
            sr += want[k * ws + c] * want[k * ws + c];
        }
        double v = sqrt(se / sr);
        worst = v > worst ? v : worst;
    }
    return worst;
}

/* Open-loop steps (dv_obs_step, no measurement) from rest; outputs into yout. */
static int run_steps(dv_obs_t *o, size_t no)
{
    int ok = 1;
    for (size_t k = 0; k < NS; k++) {
        ok &= dv_obs_step(o, obs_force[k], NULL) == DV_OK;
        ok &= dv_obs_get(o, &yout[k * no], NULL, no) == DV_OK;
    }
    return ok;
}

static void observer(void)
{
    const dv_real_t dt = (dv_real_t)(1.0 / 640.0);
    dv_model_desc_t d;
    dv_model_t m;
    dv_obs_t o;

    /* natural frequencies vs scipy.linalg.eigh (test_dv_model: 2e-5; the 0.1 Hz rails mode,
     * k1/k2 = 2.5e-5, 5e-2 in float) */
    lanl_desc(&d);
    check_eq("model.lin.init", dv_model_init(&m, &d, dt, mbuf, MBUF), DV_OK);
    dv_real_t f[4];
    (void)dv_model_get_modes(&m, f, NULL, 0);
    acc_t a;
    acc_init(&a);
    for (int i = 1; i < 4; i++) {
        acc_add(&a, f[i], want_freq[i], 2e-5, 0.0);
    }
    report("model.freq_modes2-4", a.ok, a.n, a.worst, 2e-5);
    acc_init(&a);
    acc_add(&a, f[0], want_freq[0], 5e-2, 0.0);
    report("model.freq_mode1", a.ok, a.n, a.worst, 5e-2);
    dump("model.freq", f, 4u);

    /* linear: 2048 observer steps vs solve_ivp (NRMSE <= 2e-3 in float) */
    check_eq("obs.lin.init", dv_obs_init(&o, &m, NULL, obuf, MBUF), DV_OK);
    int ok = run_steps(&o, 4);
    double e = nrmse(yout, 4, want_lin_acc, 4, 4);
    report("obs.lin.steps_nrmse", ok && e <= 2e-3, 1u, e, 2e-3);
    dump("obs.lin.y", yout, NS * 4u);

    /* one contact: the bumper, delta 0.5 mm, 8 sub-steps, vs the event-located reference
     * (NRMSE: accelerations 2e-3, contact force 2e-2) */
    lanl_desc(&d);
    add_bumper(&d, 5.0e-4f, 8);
    d.n_out = 5;
    d.out[4].kind = DV_OUT_ELEM_FORCE;
    d.out[4].index = 0;
    check_eq("model.bump05.init", dv_model_init(&m, &d, dt, mbuf, MBUF), DV_OK);
    check_eq("obs.bump05.init", dv_obs_init(&o, &m, NULL, obuf, MBUF), DV_OK);
    ok = run_steps(&o, 5);
    e = nrmse(yout, 5, want_bump05, 5, 4);
    report("obs.bump05.steps_nrmse_acc", ok && e <= 2e-3, 1u, e, 2e-3);
    e = nrmse(yout + 4, 5, want_bump05 + 4, 5, 1);
    report("obs.bump05.steps_nrmse_force", ok && e <= 2e-2, 1u, e, 2e-2);
    dump("obs.bump05.y", yout, NS * 5u);

    /* The init-time scratch of both buffers is dead after init: everything past
     * dv_model_persistent_len() / dv_obs_persistent_len() is overwritten with NaN and the steps
     * must give the same bits (the persistent part is what the memory budget counts). */
    const size_t mlive = dv_model_persistent_len(&d);
    const size_t olive = dv_obs_persistent_len(&m);
    info("model live elements ", (uint32_t)mlive, "");
    info("model buffer elements (dv_model_buf_len) ", (uint32_t)dv_model_buf_len(&d), "");
    info("observer live elements ", (uint32_t)olive, "");
    info("observer buffer elements (dv_obs_buf_len) ", (uint32_t)dv_obs_buf_len(&m), "");
    static dv_real_t y_keep[NS * 5];
    memcpy(y_keep, yout, sizeof y_keep);
    for (size_t i = mlive; i < MBUF; i++) {
        mbuf[i] = (dv_real_t)NAN;
    }
    for (size_t i = olive; i < MBUF; i++) {
        obuf[i] = (dv_real_t)NAN;
    }
    dv_obs_reset(&o);
    ok = run_steps(&o, 5);
    report("obs.bump05.scratch_is_init_only", ok && memcmp(y_keep, yout, sizeof y_keep) == 0, 1u,
           0.0, 0.0);

    /* steady-state Kalman gain (k1 = 2e4, q = 1 N^2, r = 0.04) vs scipy's DARE (2e-2 of
     * max |L| in float) */
    lanl_desc(&d);
    d.k_n_per_m[0] = 2.0e4f;
    dv_obs_noise_t nz;
    for (unsigned i = 0; i < DV_MAX_DOF; i++) {
        nz.q_force_n2[i] = 1.0f;
    }
    for (unsigned i = 0; i < DV_MAX_OUT; i++) {
        nz.r_meas[i] = 0.04f;
    }
    check_eq("model.k1_2e4.init", dv_model_init(&m, &d, dt, mbuf, MBUF), DV_OK);
    check_eq("obs.kalman.init", dv_obs_init(&o, &m, &nz, obuf, MBUF), DV_OK);
    dv_real_t l[32];
    (void)dv_obs_get_gain(&o, l, 32);
    double lmax = 0.0, emax = 0.0;
    for (int i = 0; i < 32; i++) {
        lmax = fabs(want_kalman_gain[i]) > lmax ? fabs(want_kalman_gain[i]) : lmax;
        double di = fabs(l[i] - want_kalman_gain[i]);
        emax = di > emax ? di : emax;
    }
    report("obs.kalman_gain", emax <= 2e-2 * lmax, 32u, emax / lmax, 2e-2);
    dump("obs.kalman_gain", l, 32u);

    /* with contact and gain: measurements from the same model (bumper delta 0.1 mm, 8
     * sub-steps) give a residual at round-off (test_dv_obs: <= 1e-4 of the signal in float) */
    lanl_desc(&d);
    add_bumper(&d, 1.0e-4f, 8);
    check_eq("model.bump01.init", dv_model_init(&m, &d, dt, mbuf, MBUF), DV_OK);
    check_eq("obs.bump01_kalman.init", dv_obs_init(&o, &m, &nz, obuf, MBUF), DV_OK);
    ok = run_steps(&o, 4);
    memcpy(ytrue, yout, sizeof ytrue);
    dv_obs_reset(&o);
    for (size_t k = 0; k < NS; k++) {
        ok &= dv_obs_step(&o, obs_force[k], &ytrue[k * 4]) == DV_OK;
        ok &= dv_obs_get(&o, NULL, &rbuf[k * 4], 4) == DV_OK;
    }
    double sr = 0.0, sy = 0.0;
    for (size_t i = 0; i < NS * 4; i++) {
        sr += (double)rbuf[i] * rbuf[i];
        sy += (double)ytrue[i] * ytrue[i];
    }
    e = sqrt(sr / sy);
    report("obs.bump01_kalman.perfect_model_resid", ok && e <= 1e-4, 1u, e, 1e-4);
    dump("obs.bump01.y", ytrue, NS * 4u);
    dump("obs.bump01_kalman.resid", rbuf, NS * 4u);
}

/* ================================ FRF ===================================================== */
enum { FRF_SEG = 512, FRF_NB = FRF_SEG / 2 + 1 };
static dv_real_t frf_buf[DV_FRF_BUF_LEN(FRF_SEG)];

/* Streaming Welch vs scipy (test_dv_frf, float: H1 2e-5 relative, coherence 1e-5 absolute,
 * spectra 2e-5 of max(|G|, 1e-6 max G)); peak vs scipy's H1 parabola vertex and half-power
 * band (1e-5, 1e-3). */
static void frf(void)
{
    const size_t n = sizeof frf_u / sizeof frf_u[0];
    const dv_frf_config_t cfg = {FRF_SEG, FRF_SEG / 2u, 0u, 1024.0f};
    dv_frf_t s;
    check_eq("frf.init", dv_frf_init(&s, &cfg, frf_buf, DV_FRF_BUF_LEN(FRF_SEG)), DV_OK);
    int ok = 1;
    for (size_t i = 0; i < n; i++) {
        ok &= dv_frf_update(&s, frf_u[i], frf_y[i]) >= DV_OK;
    }
    check_eq("frf.segments", ok ? (long)dv_frf_segments(&s) : -1L, (long)want_frf_n_seg);
    double gmax = 0.0;
    for (int k = 0; k < FRF_NB; k++) {
        const double *r = &want_frf_ov50[5 * k];
        gmax = r[0] > gmax ? r[0] : gmax;
        gmax = r[1] > gmax ? r[1] : gmax;
    }
    static float h1[2 * FRF_NB], coh[FRF_NB];
    acc_t ah, ac, ag;
    acc_init(&ah);
    acc_init(&ac);
    acc_init(&ag);
    for (int k = 0; k < FRF_NB; k++) {
        const double *r = &want_frf_ov50[5 * k];
        dv_frf_bin_t b;
        ok &= dv_frf_get_bin(&s, (size_t)k, &b) == DV_OK;
        const double hr = r[2] / r[0], hi = r[3] / r[0], hm = sqrt(hr * hr + hi * hi);
        acc_add(&ah, b.h1_re, hr, 2e-5, hm);
        acc_add(&ah, b.h1_im, hi, 2e-5, hm);
        acc_add(&ac, b.coh, r[4], 1e-5, 1.0);
        const double gm = sqrt(r[2] * r[2] + r[3] * r[3]);
        acc_add(&ag, b.guu, r[0], 2e-5, 1e-6 * gmax);
        acc_add(&ag, b.gyy, r[1], 2e-5, 1e-6 * gmax);
        acc_add(&ag, b.guy_re, r[2], 2e-5, gm > 1e-6 * gmax ? gm : 1e-6 * gmax);
        acc_add(&ag, b.guy_im, r[3], 2e-5, gm > 1e-6 * gmax ? gm : 1e-6 * gmax);
        h1[2 * k] = b.h1_re;
        h1[2 * k + 1] = b.h1_im;
        coh[k] = b.coh;
    }
    report("frf.h1", ok && ah.ok, ah.n, ah.worst, 2e-5);
    report("frf.coherence", ok && ac.ok, ac.n, ac.worst, 1e-5);
    report("frf.spectra", ok && ag.ok, ag.n, ag.worst, 2e-5);
    dump("frf.h1", h1, 2u * FRF_NB);
    dump("frf.coherence", coh, FRF_NB);
    dv_frf_peak_t pk[3];
    size_t np = 0;
    ok = dv_frf_get_peaks(&s, pk, 3, &np) == DV_OK && np >= 1u;
    const double bw_ref = want_frf_hp_f2_hz - want_frf_hp_f1_hz;
    const double ef = ok ? fabs(pk[0].f_hz - want_frf_peak_hz) / want_frf_peak_hz : 1.0;
    const double eb = ok ? fabs(2.0 * pk[0].zeta * pk[0].f_hz - bw_ref) / bw_ref : 1.0;
    report("frf.peak_hz", ok && ef <= 1e-5, 1u, ef, 1e-5);
    report("frf.half_power_band", ok && eb <= 1e-3, 1u, eb, 1e-3);
    if (ok) {
        const float pv[3] = {pk[0].f_hz, pk[0].mag, pk[0].zeta};
        dump("frf.peak", pv, 3u);
    }
}

int main(void)
{
    m4_put("INFO dynval self-test, sizeof(dv_real_t)=");
    m4_put_u((uint32_t)sizeof(dv_real_t));
    m4_line_end();
    features();
    ar();
    observer();
    frf();
    m4_put(n_failed == 0u ? "RESULT PASS " : "RESULT FAIL ");
    m4_put_u(n_checks - n_failed);
    m4_put("/");
    m4_put_u(n_checks);
    m4_line_end();
    return n_failed == 0u ? 0 : 1;
}

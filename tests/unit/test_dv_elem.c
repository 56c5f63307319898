/* Element laws beyond the contact (dv_model.h): regularised Coulomb friction, cubic spring and
 * velocity-squared damper, through the same sub-node scheme as the contact. Each is checked
 * against an independent reference integration (classical RK4 at 64x the sample rate, in
 * double, on the model's own K and C, the force linear between samples as the model's hold
 * assumes), against the closed-form laws, and init's refusals. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include "dv_test_util.h"
#include "dv_model_test_util.h"

enum { NE = 2048, NBE = 60000, FINE = 64 };

static dv_real_t ebuf[NBE];
static dv_real_t eobuf[NBE];
static dv_real_t eu[NE];
static dv_real_t ey[NE * 4];
static double eref[NE * 4];

/* A smooth multi-sine force, N (components well below Nyquist, near the modes) */
static void make_force(double amp)
{
    for (int k = 0; k < NE; k++) {
        const double t = k / MT_FS;
        eu[k] = (dv_real_t)(amp * (sin(2 * M_PI * 23.0 * t) + 0.8 * sin(2 * M_PI * 41.3 * t + 1.0) +
                                   0.6 * sin(2 * M_PI * 67.1 * t + 2.0)));
    }
}

static double law(int lw, double p_delta, double p_kb, double a)
{
    switch (lw) {
    case DV_ELEM_FRICTION:
        return p_kb * a / sqrt(a * a + p_delta * p_delta);
    case DV_ELEM_CUBIC:
        return p_kb * a * a * a;
    case DV_ELEM_VV:
        return p_kb * a * fabs(a);
    case DV_ELEM_CONSTANT:
        return -p_kb;
    default:
        return 0.0;
    }
}

/* Stick-slip history: the force of each stick-slip element is a state gz[e] of the
 * reference, dg/dt = (F / z) V while it sticks (|g| < F, or V drives it back), else 0. */
static double gz[DV_MAX_ELEM], gdot[DV_MAX_ELEM], gzt[DV_MAX_ELEM];

/* acc = M^-1 (f e_in - C v - K x - elements), elements pushing a by +g and b by -g */
static void rhs(const dv_model_t *m, const double *kk, const double *cc, double f,
                const double *x, const double *v, double *acc)
{
    const size_t n = m->n_dof;
    double fe[DV_MAX_DOF] = {0};
    for (size_t e = 0; e < m->n_elem; e++) {
        const dv_elem_desc_t *c = &m->elem[e];
        const int vel = c->law == DV_ELEM_FRICTION || c->law == DV_ELEM_VV;
        const double *z = vel ? v : x;
        const double za = c->dof_a == (uint16_t)DV_GROUND ? 0.0 : z[c->dof_a];
        double g;
        if (c->law == DV_ELEM_STICKSLIP) {
            const double fs = (double)c->kb_n_per_m;
            const double va = c->dof_a == (uint16_t)DV_GROUND ? 0.0 : v[c->dof_a];
            const double vr = v[c->dof_b] - va;
            g = gzt[e];
            const int slipping = (g >= fs && vr > 0) || (g <= -fs && vr < 0);
            gdot[e] = slipping ? 0.0 : fs / (double)c->delta_m * vr;
        } else {
            g = law((int)c->law, (double)c->delta_m, (double)c->kb_n_per_m, z[c->dof_b] - za);
        }
        fe[c->dof_b] += g;
        if (c->dof_a != (uint16_t)DV_GROUND) {
            fe[c->dof_a] -= g;
        }
    }
    for (size_t i = 0; i < n; i++) {
        double s = (i == 0 ? f : 0.0) - fe[i];
        for (size_t j = 0; j < n; j++) {
            s -= kk[i * n + j] * x[j] + cc[i * n + j] * v[j];
        }
        acc[i] = s / (double)m->mass_kg[i];
    }
}

/* RK4 reference at FINE x the sample rate; accelerations at the samples into eref */
static void reference(const dv_model_t *m)
{
    const size_t n = m->n_dof;
    dv_mat_t kv, cv;
    assert_int_equal(dv_model_get_mat(m, DV_MODEL_MAT_K, &kv), DV_OK);
    assert_int_equal(dv_model_get_mat(m, DV_MODEL_MAT_C, &cv), DV_OK);
    double kk[DV_MAX_DOF * DV_MAX_DOF], cc[DV_MAX_DOF * DV_MAX_DOF];
    for (size_t i = 0; i < n * n; i++) {
        kk[i] = (double)kv.data[i];
        cc[i] = (double)cv.data[i];
    }
    double x[DV_MAX_DOF] = {0}, v[DV_MAX_DOF] = {0};
    double k1x[DV_MAX_DOF], k1v[DV_MAX_DOF], k2x[DV_MAX_DOF], k2v[DV_MAX_DOF];
    double k3x[DV_MAX_DOF], k3v[DV_MAX_DOF], k4x[DV_MAX_DOF], k4v[DV_MAX_DOF];
    double xt[DV_MAX_DOF], vt[DV_MAX_DOF], a[DV_MAX_DOF];
    const double h = 1.0 / (MT_FS * FINE);
    double g1[DV_MAX_ELEM], g2[DV_MAX_ELEM], g3[DV_MAX_ELEM], g4[DV_MAX_ELEM];
    const size_t nc = m->n_elem;
    for (size_t e = 0; e < nc; e++) gz[e] = gzt[e] = 0.0;
    rhs(m, kk, cc, (double)eu[0], x, v, a);
    for (size_t i = 0; i < n; i++) eref[i] = a[i];
    for (int k = 0; k + 1 < NE; k++) {
        for (int s = 0; s < FINE; s++) {
            const double f0 = (double)eu[k] + ((double)eu[k + 1] - (double)eu[k]) * s / FINE;
            const double f1 = (double)eu[k] + ((double)eu[k + 1] - (double)eu[k]) * (s + 1) / FINE;
            const double fm = 0.5 * (f0 + f1);
            for (size_t e = 0; e < nc; e++) gzt[e] = gz[e];
            rhs(m, kk, cc, f0, x, v, k1v);
            for (size_t e = 0; e < nc; e++) {
                g1[e] = gdot[e];
                gzt[e] = gz[e] + 0.5 * h * g1[e];
            }
            for (size_t i = 0; i < n; i++) {
                k1x[i] = v[i];
                xt[i] = x[i] + 0.5 * h * k1x[i];
                vt[i] = v[i] + 0.5 * h * k1v[i];
            }
            rhs(m, kk, cc, fm, xt, vt, k2v);
            for (size_t e = 0; e < nc; e++) {
                g2[e] = gdot[e];
                gzt[e] = gz[e] + 0.5 * h * g2[e];
            }
            for (size_t i = 0; i < n; i++) {
                k2x[i] = vt[i];
                xt[i] = x[i] + 0.5 * h * k2x[i];
                vt[i] = v[i] + 0.5 * h * k2v[i];
            }
            rhs(m, kk, cc, fm, xt, vt, k3v);
            for (size_t e = 0; e < nc; e++) {
                g3[e] = gdot[e];
                gzt[e] = gz[e] + h * g3[e];
            }
            for (size_t i = 0; i < n; i++) {
                k3x[i] = vt[i];
                xt[i] = x[i] + h * k3x[i];
                vt[i] = v[i] + h * k3v[i];
            }
            rhs(m, kk, cc, f1, xt, vt, k4v);
            for (size_t e = 0; e < nc; e++) {
                g4[e] = gdot[e];
                gz[e] += h / 6 * (g1[e] + 2 * g2[e] + 2 * g3[e] + g4[e]);
                const double fs = (double)m->elem[e].kb_n_per_m;
                gz[e] = gz[e] > fs ? fs : (gz[e] < -fs ? -fs : gz[e]);
            }
            for (size_t i = 0; i < n; i++) {
                k4x[i] = vt[i];
                x[i] += h / 6 * (k1x[i] + 2 * k2x[i] + 2 * k3x[i] + k4x[i]);
                v[i] += h / 6 * (k1v[i] + 2 * k2v[i] + 2 * k3v[i] + k4v[i]);
            }
        }
        for (size_t e = 0; e < nc; e++) gzt[e] = gz[e];
        rhs(m, kk, cc, (double)eu[k + 1], x, v, a);
        for (size_t i = 0; i < n; i++) eref[(size_t)(k + 1) * n + i] = a[i];
    }
}

/* dv_obs_simulate vs the reference: max over channels of RMS error / RMS reference, and the
 * same for the linear model without the element (how big the element's effect is). */
static void run_case(int lw, uint16_t a, uint16_t b, double delta, double kb, double amp,
                     double *err, double *effect)
{
    dv_model_desc_t d;
    dv_model_t m;
    dv_obs_t o;
    make_force(amp);
    mt_lanl_desc(&d);
    d.n_elem = 1;
    d.n_sub = 8;
    d.elem[0].dof_a = a;
    d.elem[0].dof_b = b;
    d.elem[0].side = DV_SIDE_POS;
    d.elem[0].delta_m = (dv_real_t)delta;
    d.elem[0].kb_n_per_m = (dv_real_t)kb;
    d.elem[0].law = (dv_elem_law_t)lw;
    assert_true(dv_model_buf_len(&d) <= NBE);
    assert_int_equal(dv_model_init(&m, &d, (dv_real_t)(1.0 / MT_FS), ebuf, NBE), DV_OK);
    assert_true(dv_obs_buf_len(&m) <= NBE);
    assert_int_equal(dv_obs_init(&o, &m, NULL, eobuf, NBE), DV_OK);
    assert_int_equal(dv_obs_simulate(&o, eu, NE, ey), DV_OK);
    reference(&m);
    double worst = 0.0;
    for (int c = 0; c < 4; c++) {
        double se = 0, sr = 0;
        for (int k = 0; k < NE; k++) {
            const double r = eref[k * 4 + c];
            se += ((double)ey[k * 4 + c] - r) * ((double)ey[k * 4 + c] - r);
            sr += r * r;
        }
        worst = fmax(worst, sqrt(se / sr));
    }
    *err = worst;
    d.n_elem = 0; /* the same model without the element */
    assert_int_equal(dv_model_init(&m, &d, (dv_real_t)(1.0 / MT_FS), ebuf, NBE), DV_OK);
    assert_int_equal(dv_obs_init(&o, &m, NULL, eobuf, NBE), DV_OK);
    assert_int_equal(dv_obs_simulate(&o, eu, NE, ey), DV_OK);
    double big = 0.0;
    for (int c = 0; c < 4; c++) {
        double se = 0, sr = 0;
        for (int k = 0; k < NE; k++) {
            const double r = eref[k * 4 + c];
            se += ((double)ey[k * 4 + c] - r) * ((double)ey[k * 4 + c] - r);
            sr += r * r;
        }
        big = fmax(big, sqrt(se / sr));
    }
    *effect = big;
}

static void test_elem_friction_matches_reference(void **state)
{
    (void)state;
    double err, eff;
    /* base on its rails with Coulomb friction 1.5 N, eps 1 mm/s */
    run_case(DV_ELEM_FRICTION, (uint16_t)DV_GROUND, 0, 1e-3, 1.5, 5.0, &err, &eff);
    fprintf(stderr, "friction: error %.3g, effect of the element %.3g\n", err, eff);
    assert_true(eff > 0.1);
    assert_true(err < 0.02 * eff);
}

static void test_elem_cubic_matches_reference(void **state)
{
    (void)state;
    double err, eff;
    run_case(DV_ELEM_CUBIC, 2, 3, 0.0, 2e13, 8.0, &err, &eff);
    fprintf(stderr, "cubic: error %.3g, effect of the element %.3g\n", err, eff);
    assert_true(eff > 0.1);
    assert_true(err < 0.02 * eff);
}

static void test_elem_softening_cubic_matches_reference(void **state)
{
    (void)state;
    double err, eff;
    /* k3 < 0: the story's restoring force peaks at X = sqrt(k / (3 |k3|)) = 0.15 mm, beyond
     * this record's drifts */
    run_case(DV_ELEM_CUBIC, 2, 3, 0.0, -6e12, 8.0, &err, &eff);
    fprintf(stderr, "softening cubic: error %.3g, effect of the element %.3g\n", err, eff);
    assert_true(eff > 0.01);
    assert_true(err < 0.02 * eff);
}

/* Driven past its peak force a softening spring runs away: every step from there reports
 * DV_EUNSTABLE (never DV_OK with a non-finite prediction), and so do the block calls. */
static void test_elem_runaway_is_reported(void **state)
{
    (void)state;
    dv_model_desc_t d;
    dv_model_t m;
    dv_obs_t o;
    make_force(200.0);
    mt_lanl_desc(&d);
    d.n_elem = 1;
    d.n_sub = 8;
    d.elem[0].dof_a = 2;
    d.elem[0].dof_b = 3;
    d.elem[0].side = DV_SIDE_POS;
    d.elem[0].law = DV_ELEM_CUBIC;
    d.elem[0].kb_n_per_m = (dv_real_t)-2e13;
    assert_int_equal(dv_model_init(&m, &d, (dv_real_t)(1.0 / MT_FS), ebuf, NBE), DV_OK);
    assert_int_equal(dv_obs_init(&o, &m, NULL, eobuf, NBE), DV_OK);
    assert_int_equal(dv_obs_simulate(&o, eu, NE, ey), DV_EUNSTABLE);
    dv_obs_reset(&o);
    int first_bad = -1;
    for (int k = 0; k < NE; k++) {
        const dv_status_t st = dv_obs_step(&o, eu[k], NULL);
        dv_real_t yk[4];
        assert_int_equal(dv_obs_get(&o, yk, NULL, 4), DV_OK);
        const bool finite = isfinite((double)yk[0]) && isfinite((double)yk[1]) &&
                            isfinite((double)yk[2]) && isfinite((double)yk[3]);
        if (st == DV_OK) {
            assert_true(finite);
            assert_int_equal(first_bad, -1); /* no recovery once it ran away */
        } else {
            assert_int_equal(st, DV_EUNSTABLE);
            first_bad = first_bad < 0 ? k : first_bad;
        }
    }
    assert_true(first_bad > 0);
    dv_obs_reset(&o);
    assert_int_equal(dv_obs_update_block(&o, eu, NULL, (size_t)first_bad, ey, NULL), DV_OK);
    assert_int_equal(dv_obs_update_block(&o, eu + first_bad, NULL, 16, ey, NULL), DV_EUNSTABLE);
    /* the same input on the hardening spring stays finite */
    d.elem[0].kb_n_per_m = (dv_real_t)2e13;
    assert_int_equal(dv_model_init(&m, &d, (dv_real_t)(1.0 / MT_FS), ebuf, NBE), DV_OK);
    assert_int_equal(dv_obs_init(&o, &m, NULL, eobuf, NBE), DV_OK);
    assert_int_equal(dv_obs_simulate(&o, eu, NE, ey), DV_OK);
}

static void test_elem_vv_matches_reference(void **state)
{
    (void)state;
    double err, eff;
    run_case(DV_ELEM_VV, 0, 1, 0.0, 1e4, 8.0, &err, &eff);
    fprintf(stderr, "v|v|: error %.3g, effect of the element %.3g\n", err, eff);
    assert_true(eff > 0.05);
    assert_true(err < 0.02 * eff);
}

static void test_elem_stickslip_matches_reference(void **state)
{
    (void)state;
    double err, eff;
    /* base on its rails with stick-slip friction: slips at 2 N after 5 um of stick */
    run_case(DV_ELEM_STICKSLIP, (uint16_t)DV_GROUND, 0, 5e-6, 2.0, 5.0, &err, &eff);
    fprintf(stderr, "stick-slip: error %.3g, effect of the element %.3g\n", err, eff);
    assert_true(eff > 0.1);
    assert_true(err < 0.05 * eff);
}

static void test_elem_constant_matches_reference(void **state)
{
    (void)state;
    double err, eff;
    /* a preload of 30 N between DOFs 2 and 3 from rest: a step load, whose decaying transient
     * is all the accelerometers see (between DOFs: a constant force to the ground would drive
     * this structure's near-rigid mode, k1 = 10 N/m, metres away in 3 s, beyond what float
     * resolves for the 10 um story motions) */
    run_case(DV_ELEM_CONSTANT, 1, 2, 0.0, 30.0, 5.0, &err, &eff);
    fprintf(stderr, "constant: error %.3g, effect of the element %.3g\n", err, eff);
    assert_true(eff > 0.002);
    assert_true(err < 0.02 * eff);
}

static void test_elem_laws_closed_form(void **state)
{
    (void)state;
    dv_elem_desc_t c = {0, 1, DV_SIDE_POS, (dv_real_t)0.0, (dv_real_t)1e-3,
                           (dv_real_t)2.0, DV_ELEM_FRICTION};
    const double tol = sizeof(dv_real_t) == 8 ? 1e-12 : 1e-5;
    assert_true(dv_test_close(dv_elem_force(&c, (dv_real_t)1e-3), 2.0 / sqrt(2.0), tol, 0));
    assert_true(dv_test_close(dv_elem_force(&c, (dv_real_t)-1.0), -2.0 / sqrt(1 + 1e-6), tol,
                              0));
    assert_true(dv_elem_force(&c, (dv_real_t)0.0) == 0);
    c.law = DV_ELEM_CUBIC;
    c.kb_n_per_m = (dv_real_t)3e12;
    assert_true(dv_test_close(dv_elem_force(&c, (dv_real_t)-1e-4), -3e12 * 1e-12, tol, 0));
    c.law = DV_ELEM_VV;
    c.kb_n_per_m = (dv_real_t)50.0;
    assert_true(dv_test_close(dv_elem_force(&c, (dv_real_t)-0.2), -50.0 * 0.04, tol, 0));
    assert_int_equal(dv_elem_check(&c), DV_OK);
    c.kb_n_per_m = (dv_real_t)-50.0; /* a negative coefficient: the constant force and the
                                        softening cubic spring only */
    assert_int_equal(dv_elem_check(&c), DV_EINVAL);
    c.law = DV_ELEM_CUBIC;
    assert_int_equal(dv_elem_check(&c), DV_OK);
    assert_true(dv_test_close(dv_elem_force(&c, (dv_real_t)0.1), -50.0 * 1e-3, tol, 0));
    c.law = DV_ELEM_FRICTION;
    assert_int_equal(dv_elem_check(&c), DV_EINVAL);
    c.law = DV_ELEM_CONSTANT;
    assert_int_equal(dv_elem_check(&c), DV_OK);
    assert_true(dv_elem_force(&c, (dv_real_t)-0.2) == (dv_real_t)50.0); /* g = -F */
    assert_true(dv_elem_force(&c, (dv_real_t)7.0) == (dv_real_t)50.0);
    assert_false(dv_elem_on_velocity(DV_ELEM_CONSTANT));
    assert_true(dv_elem_stiffness_bound(&c) == 0 && dv_elem_damping_bound(&c) == 0);
}

static void test_elem_init_refusals(void **state)
{
    (void)state;
    dv_model_desc_t d;
    dv_model_t m;
    mt_lanl_desc(&d);
    d.n_elem = 1;
    d.elem[0].dof_a = (uint16_t)DV_GROUND;
    d.elem[0].dof_b = 0;
    d.elem[0].side = DV_SIDE_POS;
    d.elem[0].law = DV_ELEM_FRICTION;
    d.elem[0].kb_n_per_m = (dv_real_t)1.0;
    d.elem[0].delta_m = (dv_real_t)0.0; /* eps must be > 0 */
    assert_int_equal(dv_model_init(&m, &d, (dv_real_t)(1.0 / MT_FS), ebuf, NBE), DV_EINVAL);
    d.elem[0].delta_m = (dv_real_t)1e-9; /* F / eps far too steep for the sub-step */
    assert_int_equal(dv_model_init(&m, &d, (dv_real_t)(1.0 / MT_FS), ebuf, NBE), DV_EUNSTABLE);
    d.elem[0].delta_m = (dv_real_t)1e-3;
    d.elem[0].law = (dv_elem_law_t)7;
    assert_int_equal(dv_model_init(&m, &d, (dv_real_t)(1.0 / MT_FS), ebuf, NBE), DV_EINVAL);
}

/* dv_elem_force_block: each law against its closed form over a record of X and V (the law
 * reads one of them: V for friction and v|v|), the stick-slip loop of a displacement cycle
 * (stick at F / z, slip at +-F, unload with the stick slope), NaN samples and refusals. */
static void test_elem_force_block(void **state)
{
    (void)state;
    enum { NB = 64 };
    dv_real_t x[NB], v[NB], f[NB];
    for (int i = 0; i < NB; i++) {
        x[i] = (dv_real_t)(2e-4 * sin(0.3 * i));
        v[i] = (dv_real_t)(0.05 * cos(0.3 * i));
    }
    const double tol = sizeof(dv_real_t) == 4 ? 1e-5 : 1e-12;
    dv_elem_desc_t c = {0, 1, DV_SIDE_BOTH, (dv_real_t)5e-5, (dv_real_t)1e-4, (dv_real_t)2e6,
                        DV_ELEM_CONTACT};
    assert_int_equal(dv_elem_force_block(&c, x, NULL, NB, NULL, f), DV_OK);
    for (int i = 0; i < NB; i++) { /* both sides: g_pos(X) - g_pos(-X), s = |X| - gap */
        const double xa = fabs((double)x[i]), s = xa - 5e-5;
        const double g1 = s <= 0 ? 0 : (s < 1e-4 ? 2e6 * s * s / 2e-4 : 2e6 * (s - 5e-5));
        assert_true(dv_test_close(f[i], x[i] < 0 ? -g1 : g1, tol, 1e-9));
    }
    const struct { dv_elem_law_t law; double delta, kb; } laws[] = {
        {DV_ELEM_FRICTION, 1e-3, 2.0}, {DV_ELEM_CUBIC, 0.0, 3e12}, {DV_ELEM_VV, 0.0, 50.0}};
    for (size_t k = 0; k < sizeof laws / sizeof laws[0]; k++) {
        c.law = laws[k].law;
        c.delta_m = (dv_real_t)laws[k].delta;
        c.kb_n_per_m = (dv_real_t)laws[k].kb;
        const bool vel = dv_elem_on_velocity(c.law);
        assert_int_equal(dv_elem_force_block(&c, vel ? NULL : x, vel ? v : NULL, NB, NULL, f),
                         DV_OK);
        for (int i = 0; i < NB; i++) {
            const double a = vel ? (double)v[i] : (double)x[i];
            assert_true(dv_test_close(f[i], law((int)c.law, laws[k].delta, laws[k].kb, a), tol,
                                      1e-12));
        }
    }
    /* stick-slip, F = 2 N, z = 1e-4 m: X 0 -> 3e-4 -> 0 -> -3e-4 in steps of 5e-5 */
    c.law = DV_ELEM_STICKSLIP;
    c.kb_n_per_m = 2;
    c.delta_m = (dv_real_t)1e-4;
    const double path[] = {5e-5, 1e-4, 1.5e-4, 3e-4, 2.5e-4, 1e-4, 0.0, -3e-4};
    const double want[] = {1.0, 2.0, 2.0, 2.0, 1.0, -2.0, -2.0, -2.0};
    dv_real_t xs[8], hist[2] = {0, 0};
    for (int i = 0; i < 8; i++) {
        xs[i] = (dv_real_t)path[i];
    }
    assert_int_equal(dv_elem_force_block(&c, xs, NULL, 8, hist, f), DV_OK);
    for (int i = 0; i < 8; i++) {
        assert_true(dv_test_close(f[i], want[i], tol, 1e-9));
    }
    assert_true(hist[0] == xs[7] && hist[1] == f[7]);
    /* the history carries over: moving back by 5e-5 unloads by 1 N */
    xs[0] = (dv_real_t)-2.5e-4;
    assert_int_equal(dv_elem_force_block(&c, xs, NULL, 1, hist, f), DV_OK);
    assert_true(dv_test_close(f[0], -1.0, tol, 1e-9));
    /* a NaN sample: force 0, DV_ENUMERIC, the history not advanced by it */
    hist[0] = hist[1] = 0;
    xs[0] = (dv_real_t)5e-5;
    xs[1] = (dv_real_t)NAN;
    xs[2] = (dv_real_t)1e-4;
    assert_int_equal(dv_elem_force_block(&c, xs, NULL, 3, hist, f), DV_ENUMERIC);
    assert_true(f[1] == 0 && dv_test_close(f[2], 2.0, tol, 1e-9));
    /* refusals */
    assert_int_equal(dv_elem_force_block(&c, xs, NULL, 3, NULL, f), DV_EINVAL);
    assert_int_equal(dv_elem_force_block(NULL, xs, NULL, 3, hist, f), DV_EINVAL);
    assert_int_equal(dv_elem_force_block(&c, NULL, v, 3, hist, f), DV_EINVAL);
    c.delta_m = 0;
    assert_int_equal(dv_elem_force_block(&c, xs, NULL, 3, hist, f), DV_EINVAL);
    assert_int_equal(dv_elem_check(&c), DV_EINVAL);
    c.delta_m = (dv_real_t)1e-4;
    c.law = (dv_elem_law_t)DV_ELEM_N_LAWS;
    assert_int_equal(dv_elem_check(&c), DV_EINVAL);
    c.law = DV_ELEM_STICKSLIP;
    assert_true(dv_test_close(dv_elem_stiffness_bound(&c), 2e4, tol, 0));
    assert_true(dv_elem_damping_bound(&c) == 0); /* on X: no damping-like slope */
    c.law = DV_ELEM_FRICTION; /* F / eps */
    assert_true(dv_test_close(dv_elem_damping_bound(&c), 2e4, tol, 0));
    assert_true(dv_elem_stiffness_bound(&c) == 0 && dv_elem_damping_bound(NULL) == 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_elem_friction_matches_reference),
        cmocka_unit_test(test_elem_cubic_matches_reference),
        cmocka_unit_test(test_elem_softening_cubic_matches_reference),
        cmocka_unit_test(test_elem_runaway_is_reported),
        cmocka_unit_test(test_elem_vv_matches_reference),
        cmocka_unit_test(test_elem_stickslip_matches_reference),
        cmocka_unit_test(test_elem_constant_matches_reference),
        cmocka_unit_test(test_elem_laws_closed_form),
        cmocka_unit_test(test_elem_init_refusals),
        cmocka_unit_test(test_elem_force_block),
    };
    return cmocka_run_group_tests_name("dv_elem", tests, NULL, NULL);
}

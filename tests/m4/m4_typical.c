/* "A typical firmware set" as a bare-metal image, for the memory budget and the instruction
 * counts (tests/m4/mem_budget.py):
 *   5 channels, each: every waveform feature through dv_chan (record statistics, sliding window
 *   of WIN samples, segmented STD of N_SEG x SEG_LEN, temporal moments) and the AR(32)
 *   residual (dv_ar_resid; coefficients fitted off-line and loaded, as firmware_sim's AR stage
 *   does after its baseline record);
 *   the report's 4-DOF observer with one contact (the bumper, 8 sub-steps) and the steady-state
 *   Kalman gain, built on the target (dv_model_init + dv_obs_init), channel 0 the force input
 *   and channels 1..4 the measured accelerations.
 * Every instance and buffer is a static object named ram_* so the map file / nm give the RAM.
 * Built normally, it runs 8192 samples of the whole set and prints PASS. Built with
 * -DM4_ICOUNT, it calls each hot function between marker functions (mark_*, mark_end) for
 * QEMU's instruction trace (mem_budget.py counts the instructions between the markers). */
#include <math.h>
#include <string.h>

#include "dynval/dv.h"
#include "m4_plat.h"

#define N_CH 5u
#define WIN 64u     /* sliding window, samples: 0.1 s at 640 Hz, 3 periods of the 29.8 Hz mode */
#define SEG_LEN 64u /* segmented STD: the report's 64 x 64 over a 4096-sample record */
#define N_SEG 64u
#define AR_P 32u
#define N_DOF 4u
#define N_CONTACT 1u
#define N_SUB 8u
#define N_OUT 4u

dv_chan_t ram_chan[N_CH];
/* segment STDs are published as each segment completes (as firmware_sim does): no vectors */
dv_real_t ram_chan_buf[N_CH][DV_CHAN_BUF_LEN(WIN, 0u)];
dv_ar_resid_t ram_ar[N_CH];
dv_real_t ram_ar_buf[N_CH][DV_AR_RESID_BUF_LEN(AR_P)];
dv_model_t ram_model;
dv_obs_t ram_obs;
/* Only what the steps read stays allocated for the observer's lifetime: the observer's
 * persistent storage and the model's step part (dv_model_keep_step_only moves it out of the
 * model's storage after dv_obs_init_ex). The model's storage and the init-time scratch
 * (eigen-solutions, expm, DARE; one area both inits share) are transient: free after init, here
 * static objects named tmp_* (not ram_*), which a firmware would overlay on buffers that are not
 * live during init, or put on the stack. */
dv_real_t ram_model_buf[DV_MODEL_STEP_LEN(N_DOF, N_CONTACT, N_SUB, N_OUT)];
dv_real_t ram_obs_buf[DV_OBS_PERSIST_LEN(N_DOF, N_CONTACT, N_SUB, N_OUT)];
dv_real_t tmp_model_build[DV_MODEL_PERSIST_LEN(N_DOF, N_CONTACT, N_SUB, N_OUT)];
#define MODEL_SCRATCH DV_MODEL_SCRATCH_LEN(N_DOF, N_CONTACT, N_SUB, N_OUT)
#define OBS_SCRATCH DV_OBS_SCRATCH_LEN(N_DOF, N_CONTACT, N_SUB, N_OUT)
dv_real_t tmp_init_scratch[MODEL_SCRATCH > OBS_SCRATCH ? MODEL_SCRATCH : OBS_SCRATCH];

static uint32_t rng = 2463534242u;
static dv_real_t noise(void) /* xorshift32, uniform in [-1, 1) */
{
    rng ^= rng << 13;
    rng ^= rng >> 17;
    rng ^= rng << 5;
    return (dv_real_t)((int32_t)rng) * (DV_R(1.0) / DV_R(2147483648.0));
}

/* engaged: the bumper at zero gap on both sides, so every step solves the contact chain (the
 * worst case a firmware budgets for; the instruction-count image only) */
static void lanl_desc(dv_model_desc_t *d, uint16_t n_elem, int engaged)
{
    static const float m[4] = {6.54f, 6.66f, 6.86f, 6.80f};
    static const float k[4] = {10.0f, 399790.0f, 399790.0f, 399790.0f};
    static const float z[4] = {0.01f, 0.05f, 0.01f, 0.01f};
    dv_model_desc_default(d);
    d->n_dof = N_DOF;
    for (unsigned i = 0; i < N_DOF; i++) {
        d->mass_kg[i] = m[i];
        d->k_n_per_m[i] = k[i];
        d->zeta[i] = z[i];
        d->out[i].kind = DV_OUT_ACC;
        d->out[i].index = (uint16_t)i;
    }
    d->damp_kind = DV_DAMP_MODAL;
    d->input_kind = DV_INPUT_FORCE;
    d->input_dof = 0;
    d->n_out = N_OUT;
    d->n_elem = n_elem;
    d->elem[0].dof_a = 2;
    d->elem[0].dof_b = 3;
    d->elem[0].side = engaged ? DV_SIDE_BOTH : DV_SIDE_POS;
    d->elem[0].gap_m = engaged ? 0.0f : 1.0e-4f;
    d->elem[0].delta_m = 5.0e-4f;
    d->elem[0].kb_n_per_m = 1.925e6f;
    d->n_sub = N_SUB;
}

static int init_all(uint16_t n_elem, int engaged)
{
    const dv_chan_config_t cfg = {WIN, SEG_LEN, N_SEG, DV_R(1.0) / DV_R(640.0), true};
    dv_ar_model_t am;
    memset(&am, 0, sizeof am);
    am.order = AR_P;
    am.sigma2 = DV_R(1.0);
    int ok = 1;
    for (unsigned c = 0; c < N_CH; c++) {
        for (unsigned j = 0; j < AR_P; j++) { /* a decaying, stable AR(32) */
            am.a[j] = DV_R(0.5) / (dv_real_t)((j + 1u) * (j + 1u + c));
        }
        ok &= dv_chan_init(&ram_chan[c], &cfg, ram_chan_buf[c], DV_CHAN_BUF_LEN(WIN, 0u)) == DV_OK;
        ok &= dv_ar_resid_init(&ram_ar[c], &am, ram_ar_buf[c], DV_AR_RESID_BUF_LEN(AR_P)) == DV_OK;
    }
    dv_model_desc_t d;
    lanl_desc(&d, n_elem, engaged);
    dv_obs_noise_t nz;
    for (unsigned i = 0; i < DV_MAX_DOF; i++) {
        nz.q_force_n2[i] = DV_R(1.0);
    }
    for (unsigned i = 0; i < DV_MAX_OUT; i++) {
        nz.r_meas[i] = DV_R(0.04);
    }
    const size_t nscr = sizeof tmp_init_scratch / sizeof *tmp_init_scratch;
    const size_t nbuild = sizeof tmp_model_build / sizeof *tmp_model_build;
    ok &= dv_model_init_ex(&ram_model, &d, DV_R(1.0) / DV_R(640.0), tmp_model_build, nbuild,
                           tmp_init_scratch, nscr) == DV_OK;
    ok &= dv_obs_init_ex(&ram_obs, &ram_model, &nz, ram_obs_buf,
                         sizeof ram_obs_buf / sizeof *ram_obs_buf, tmp_init_scratch,
                         nscr) == DV_OK;
    ok &= dv_model_keep_step_only(&ram_model, ram_model_buf,
                                  sizeof ram_model_buf / sizeof *ram_model_buf) == DV_OK;
    for (size_t i = 0; i < nscr; i++) { /* dead after init: prove it */
        tmp_init_scratch[i] = (dv_real_t)NAN;
    }
    for (size_t i = 0; i < nbuild; i++) {
        tmp_model_build[i] = (dv_real_t)NAN;
    }
    return ok;
}

#ifndef M4_ICOUNT
/* Stack high-water mark: paint the free stack, run, find the deepest word that changed. */
extern uint32_t _sstack[], _estack[];
#define STACK_PAINT 0xA5C3E1F7u

static void stack_paint(void)
{
    uint32_t *sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    for (volatile uint32_t *p = _sstack; p < sp - 16; p++) {
        *p = STACK_PAINT;
    }
}

static uint32_t stack_used(void)
{
    const uint32_t *p = _sstack;
    while (p < _estack && *p == STACK_PAINT) {
        p++;
    }
    return (uint32_t)((uintptr_t)_estack - (uintptr_t)p);
}

int main(void)
{
    stack_paint();
    int ok = init_all(N_CONTACT, 0);
    const uint32_t stack_init = stack_used();
    stack_paint();
    m4_put("LIVE model ");
    m4_put_u((uint32_t)(sizeof ram_model_buf / sizeof *ram_model_buf));
    m4_put(" obs ");
    m4_put_u((uint32_t)(sizeof ram_obs_buf / sizeof *ram_obs_buf));
    m4_put(" model_scratch ");
    m4_put_u((uint32_t)MODEL_SCRATCH);
    m4_put(" obs_scratch ");
    m4_put_u((uint32_t)OBS_SCRATCH);
    m4_line_end();
    uint32_t records = 0, resid_ok = 0, segs = 0;
    /* float, as a firmware would: double arithmetic here would pull libgcc's soft-float
     * routines into the image and count against the library's flash */
    dv_real_t rsum = DV_R(0.0);
    for (uint32_t k = 0; k < 2u * SEG_LEN * N_SEG; k++) {
        dv_real_t x[N_CH];
        for (unsigned c = 0; c < N_CH; c++) {
            x[c] = noise();
            const dv_status_t st = dv_chan_update(&ram_chan[c], x[c]);
            records += st == DV_RECORD;
            if (st == DV_DONE || st == DV_RECORD) { /* publish the segment's STD */
                dv_real_t sd;
                uint32_t idx;
                segs += dv_segstd_last(&ram_chan[c].seg, &sd, &idx) == DV_OK && sd > DV_R(0.0);
            }
            dv_real_t e;
            resid_ok += dv_ar_resid_update(&ram_ar[c], x[c], &e) == DV_OK;
        }
        ok &= dv_obs_step(&ram_obs, DV_R(10.0) * x[0], &x[1]) == DV_OK;
        dv_real_t r[N_OUT];
        ok &= dv_obs_get(&ram_obs, NULL, r, N_OUT) == DV_OK;
        rsum += r[0] * r[0];
    }
    ok &= records == 2u * N_CH && segs == 2u * N_SEG * N_CH && resid_ok == N_CH * (2u * SEG_LEN * N_SEG - AR_P) &&
          rsum - rsum == DV_R(0.0);
    m4_put("STACK init ");
    m4_put_u(stack_init);
    m4_put(" run ");
    m4_put_u(stack_used());
    m4_line_end();
    m4_put(ok ? "TYPICAL PASS records " : "TYPICAL FAIL records ");
    m4_put_u(records);
    m4_line_end();
    return ok ? 0 : 1;
}
#else
/* Markers: the trace counts the instructions from a mark_* entry to the next mark_end entry. */
#define MARK(name)                                                                              \
    __attribute__((noinline)) void name(void);                                                  \
    __attribute__((noinline)) void name(void) { __asm__ volatile("" ::: "memory"); }
MARK(mark_cal)
MARK(mark_chan)
MARK(mark_ar)
MARK(mark_obs_contact)
MARK(mark_obs_engaged)
MARK(mark_obs_linear)
MARK(mark_end)

/* Calibration: a call with the same argument shapes that does nothing. */
__attribute__((noinline)) dv_status_t nop_update(void *s, dv_real_t x, dv_real_t *e);
__attribute__((noinline)) dv_status_t nop_update(void *s, dv_real_t x, dv_real_t *e)
{
    __asm__ volatile("" ::"r"(s), "t"(x), "r"(e) : "memory");
    return DV_OK;
}

static volatile dv_status_t sink;

static void obs_phase(void (*mark)(void), uint32_t n)
{
    dv_real_t y[N_OUT] = {DV_R(0.0), DV_R(0.0), DV_R(0.0), DV_R(0.0)};
    sink = dv_obs_step(&ram_obs, DV_R(0.0), y); /* the first step only evaluates the output */
    for (uint32_t k = 0; k < n; k++) {
        dv_real_t u = DV_R(10.0) * noise();
        for (unsigned q = 0; q < N_OUT; q++) {
            y[q] = noise();
        }
        mark();
        sink = dv_obs_step(&ram_obs, u, y);
        mark_end();
    }
}

int main(void)
{
    int ok = init_all(N_CONTACT, 0);
    dv_real_t e = DV_R(0.0);
    for (uint32_t k = 0; k < 200u; k++) {
        dv_real_t x = noise();
        mark_cal();
        sink = nop_update(&ram_chan[0], x, &e);
        mark_end();
    }
    for (uint32_t k = 0; k < SEG_LEN * N_SEG; k++) { /* one whole record */
        dv_real_t x = noise();
        mark_chan();
        sink = dv_chan_update(&ram_chan[0], x);
        mark_end();
    }
    for (uint32_t k = 0; k < 1024u + AR_P; k++) {
        dv_real_t x = noise();
        if (k < AR_P) { /* fill the history first: the steady state is what is counted */
            sink = dv_ar_resid_update(&ram_ar[0], x, &e);
            continue;
        }
        mark_ar();
        sink = dv_ar_resid_update(&ram_ar[0], x, &e);
        mark_end();
    }
    obs_phase(mark_obs_contact, 256u);
    ok &= init_all(N_CONTACT, 1);
    obs_phase(mark_obs_engaged, 256u);
    ok &= init_all(0u, 0);
    obs_phase(mark_obs_linear, 256u);
    m4_write(ok ? "ICOUNT DONE\n" : "ICOUNT INIT FAILED\n");
    return ok ? 0 : 1;
}
#endif

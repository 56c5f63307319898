/* Cortex-M4F instruction counts of a 1024-point real FFT: dv_fft_forward_real (float) and
 * CMSIS-DSP's arm_rfft_fast_f32, both compiled into this image with the same compiler and flags
 * (tests/m4/fft_icount.py builds it and counts QEMU's trace lines between the markers, as
 * mem_budget.py does for m4_typical.c). Each transform is called between mark_* and mark_end;
 * the input copy is outside the markers. The two spectra are compared before the counts are
 * trusted: the image prints FFT MAXDIFF (relative to the largest |X|) and ICOUNT DONE. */
#include <math.h>
#include <string.h>

#include "arm_math.h"
#include "dynval/dv_fft.h"
#include "m4_plat.h"

#define N 1024u
#define CALLS 4u

static float ram_in[N], ram_dv[N], ram_cm_in[N], ram_cm_out[N];
static dv_real_t ram_tw[DV_FFT_BUF_LEN(N)];

#define MARK(name)                                                                              \
    __attribute__((noinline)) void name(void);                                                  \
    __attribute__((noinline)) void name(void) { __asm__ volatile("" ::: "memory"); }
MARK(mark_cal)
MARK(mark_dv_fft1024)
MARK(mark_cmsis_fft1024)
MARK(mark_end)

/* Calibration: a call with the same argument shapes that does nothing. */
__attribute__((noinline)) void nop_fft(const void *f, float *x);
__attribute__((noinline)) void nop_fft(const void *f, float *x)
{
    __asm__ volatile("" ::"r"(f), "r"(x) : "memory");
}

static uint32_t lcg = 12345u;
static float noise(void)
{
    lcg = lcg * 1664525u + 1013904223u;
    return (float)(lcg >> 8) * (1.0f / 16777216.0f) - 0.5f;
}

int main(void)
{
    dv_fft_t f;
    arm_rfft_fast_instance_f32 cm;
    int ok = dv_fft_init(&f, N, ram_tw, DV_FFT_BUF_LEN(N)) == DV_OK &&
             arm_rfft_fast_init_1024_f32(&cm) == ARM_MATH_SUCCESS;
    for (uint32_t i = 0; i < N; i++) ram_in[i] = noise();
    for (uint32_t k = 0; k < CALLS; k++) {
        memcpy(ram_dv, ram_in, sizeof ram_in);
        mark_cal();
        nop_fft(&f, ram_dv);
        mark_end();
        mark_dv_fft1024();
        dv_fft_forward_real(&f, ram_dv);
        mark_end();
        memcpy(ram_cm_in, ram_in, sizeof ram_in);
        mark_cmsis_fft1024();
        arm_rfft_fast_f32(&cm, ram_cm_in, ram_cm_out, 0);
        mark_end();
    }
    float diff = 0.0f, big = 0.0f;
    for (uint32_t i = 0; i < N; i++) {
        diff = fmaxf(diff, fabsf(ram_dv[i] - ram_cm_out[i]));
        big = fmaxf(big, fabsf(ram_cm_out[i]));
    }
    m4_put("FFT MAXDIFF ");
    m4_put_e((double)(diff / big));
    m4_line_end();
    ok &= diff <= 1e-5f * big;
    m4_write(ok ? "ICOUNT DONE\n" : "ICOUNT FFT MISMATCH\n");
    return ok ? 0 : 1;
}

/* Bare-metal Cortex-M4F start-up for the MPS2-AN386 board model (QEMU -M mps2-an386):
 * vector table, reset handler (FPU on via CPACR, .data copied from flash, .bss zeroed, main),
 * fault handlers, and ARM semihosting (bkpt 0xab) for console output and the exit status.
 * Compiled with -fno-tree-loop-distribute-patterns so the copy loops stay loops. */
#include <stdint.h>

#include "m4_plat.h"

extern uint32_t _sidata[], _sdata[], _edata[], _sbss[], _ebss[], _estack[];
int main(void);

/* ---- semihosting ------------------------------------------------------------------------ */
#define SYS_WRITE0 0x04
#define SYS_EXIT_EXTENDED 0x20
#define ADP_STOPPED_APPLICATION_EXIT 0x20026

static int semihost(int op, const void *arg)
{
    register int r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void m4_write(const char *s)
{
    (void)semihost(SYS_WRITE0, s);
}

void m4_exit(int status)
{
    /* SYS_EXIT_EXTENDED carries the status on AArch32 too; QEMU exits with it. */
    const uint32_t block[2] = {ADP_STOPPED_APPLICATION_EXIT, (uint32_t)status};
    (void)semihost(SYS_EXIT_EXTENDED, block);
    for (;;) {
    }
}

/* ---- reset and faults ------------------------------------------------------------------- */
void Reset_Handler(void);
void Fault_Handler(void);
void Default_Handler(void);

void Reset_Handler(void)
{
    /* CP10/CP11 full access before any floating-point instruction (Cortex-M4F TRM 7.1). */
    volatile uint32_t *const cpacr = (volatile uint32_t *)0xE000ED88u;
    *cpacr |= (0xFu << 20);
    __asm__ volatile("dsb\n\tisb" ::: "memory");
    for (uint32_t *src = _sidata, *dst = _sdata; dst < _edata;) {
        *dst++ = *src++;
    }
    for (uint32_t *dst = _sbss; dst < _ebss;) {
        *dst++ = 0u;
    }
    m4_exit(main());
}

void Fault_Handler(void)
{
    m4_write("FATAL: HardFault/MemManage/BusFault/UsageFault\n");
    m4_exit(3);
}

void Default_Handler(void)
{
    m4_write("FATAL: unexpected interrupt\n");
    m4_exit(4);
}

/* Cortex-M4 system exceptions; the AN386 peripherals' IRQs are not used (none enabled). */
__attribute__((section(".isr_vector"), used)) static void (*const vectors[16])(void) = {
    (void (*)(void))(uintptr_t)_estack, /* initial main stack pointer */
    Reset_Handler,
    Default_Handler, /* NMI */
    Fault_Handler,   /* HardFault */
    Fault_Handler,   /* MemManage */
    Fault_Handler,   /* BusFault */
    Fault_Handler,   /* UsageFault */
    0, 0, 0, 0,
    Default_Handler, /* SVCall */
    Default_Handler, /* DebugMonitor */
    0,
    Default_Handler, /* PendSV */
    Default_Handler, /* SysTick */
};

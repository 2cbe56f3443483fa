/* Cortex-M7 start-up: vector table, reset handler, fault handlers. */
#include "md_m7_startup.h"

#include <stddef.h>
#include <stdint.h>

#include "md_m7_semihost.h"

int main(void);

/* Linker-script symbols (mps2_an500.ld). Only their addresses are used. */
extern uint32_t __stack_limit[], __stack_top[], __stack_size[];
extern uint32_t __data_start[], __data_end[], __data_load[];
extern uint32_t __bss_start[], __bss_end[];
extern uint32_t __psram_bss_start[], __psram_bss_end[];

/* Reached from assembly only; global so the assembler can name them. */
void md_m7_reset_c(void);
__attribute__((noreturn)) void md_m7_fault_report(const uint32_t *frame, uint32_t ipsr);

/* Words between two linker symbols. */
static uint32_t words_between(const uint32_t *lo, const uint32_t *hi)
{
    return (uint32_t)(((uintptr_t)hi - (uintptr_t)lo) / sizeof(uint32_t));
}

/* System control block registers (ARMv7-M ARM, B3.2). */
#define SCB_VTOR (*(volatile uint32_t *)0xE000ED08u)
#define SCB_CCR (*(volatile uint32_t *)0xE000ED14u)
#define SCB_SHCSR (*(volatile uint32_t *)0xE000ED24u)
#define SCB_CFSR (*(volatile uint32_t *)0xE000ED28u)
#define SCB_HFSR (*(volatile uint32_t *)0xE000ED2Cu)
#define SCB_MMFAR (*(volatile uint32_t *)0xE000ED34u)
#define SCB_BFAR (*(volatile uint32_t *)0xE000ED38u)
#define SCB_CCR_DIV_0_TRP (1u << 4)
#define SCB_SHCSR_FAULTS_ENA ((1u << 16) | (1u << 17) | (1u << 18)) /* MemManage, BusFault, UsageFault */

#define STACK_PAINT 0xC0FFEE55u
/* Words below the live stack pointer left unpainted when painting starts. */
#define STACK_PAINT_MARGIN_WORDS 16u
/* External interrupt lines given a vector (QEMU wires the AN500 NVIC with 32, hw/arm/mps2.c). */
#define MD_M7_EXT_IRQS 32u

void (*md_m7_exit_hook)(void) = NULL;

static void fault_handler(void);
static void default_handler(void);
void SysTick_Handler(void) __attribute__((weak, alias("default_handler")));
void PendSV_Handler(void) __attribute__((weak, alias("default_handler")));
void SVC_Handler(void) __attribute__((weak, alias("default_handler")));
/* External interrupts 0, 2, 4, 18, 20 on the AN500: UART0..4 RX (md_can_uart.c). */
void UART0RX_IRQHandler(void) __attribute__((weak, alias("default_handler")));
void UART1RX_IRQHandler(void) __attribute__((weak, alias("default_handler")));
void UART2RX_IRQHandler(void) __attribute__((weak, alias("default_handler")));
void UART3RX_IRQHandler(void) __attribute__((weak, alias("default_handler")));
void UART4RX_IRQHandler(void) __attribute__((weak, alias("default_handler")));

#define DH4 default_handler, default_handler, default_handler, default_handler
#define DH16 DH4, DH4, DH4, DH4

typedef struct {
    const void *initial_sp;
    void (*handler[15 + MD_M7_EXT_IRQS])(void);
} md_m7_vector_table_t;

/* Placed first in flash (0x0) by the linker script; QEMU's reset reads the
 * initial SP and PC from here. Index = exception number - 1. */
__attribute__((section(".isr_vector"), used)) static const md_m7_vector_table_t md_m7_vectors = {
    .initial_sp = __stack_top,
    .handler =
        {
            [0] = Reset_Handler,
            [1] = fault_handler, /* NMI */
            [2] = fault_handler, /* HardFault */
            [3] = fault_handler, /* MemManage */
            [4] = fault_handler, /* BusFault */
            [5] = fault_handler, /* UsageFault */
            [10] = SVC_Handler,
            [11] = default_handler, /* DebugMonitor */
            [13] = PendSV_Handler,
            [14] = SysTick_Handler,
            /* external interrupts 0..31 (index 15 + n); UART RX lines 0, 2, 4, 18, 20 */
            [15] = UART0RX_IRQHandler,
            default_handler,
            [17] = UART1RX_IRQHandler,
            default_handler,
            [19] = UART2RX_IRQHandler,
            DH4,
            DH4,
            DH4,
            default_handler,
            [33] = UART3RX_IRQHandler,
            default_handler,
            [35] = UART4RX_IRQHandler,
            DH4,
            DH4,
            default_handler,
            default_handler,
            default_handler,
        },
};
_Static_assert(MD_M7_EXT_IRQS == 32u, "the initializer above lists 32 external vectors");

/* The FPU is switched on here, in assembly, before any compiled C code runs:
 * with -mfloat-abi=hard the compiler may use FP registers anywhere, and an FP
 * instruction with CP10/CP11 disabled is a UsageFault (NOCP). */
__attribute__((naked)) void Reset_Handler(void)
{
    __asm__ volatile("ldr r0, =0xE000ED88    \n" /* CPACR */
                     "ldr r1, [r0]           \n"
                     "orr r1, r1, #(0xF << 20)\n" /* CP10, CP11: full access */
                     "str r1, [r0]           \n"
                     "dsb                    \n"
                     "isb                    \n"
                     "b md_m7_reset_c        \n");
}

static void paint_stack(void)
{
    uint32_t sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    const uint32_t n_below_sp = words_between(__stack_limit, (const uint32_t *)sp);
    const uint32_t n_stack = words_between(__stack_limit, __stack_top);
    if (n_below_sp <= STACK_PAINT_MARGIN_WORDS || n_below_sp > n_stack) {
        return; /* SP outside the stack region: nothing sensible to paint */
    }
    for (uint32_t i = 0u; i < n_below_sp - STACK_PAINT_MARGIN_WORDS; ++i) {
        __stack_limit[i] = STACK_PAINT;
    }
}

void md_m7_reset_c(void)
{
    SCB_VTOR = (uint32_t)(uintptr_t)&md_m7_vectors;
    SCB_CCR |= SCB_CCR_DIV_0_TRP;
    SCB_SHCSR |= SCB_SHCSR_FAULTS_ENA;
    __asm__ volatile("dsb\n isb" ::: "memory");

    const uint32_t n_data = words_between(__data_start, __data_end);
    for (uint32_t i = 0u; i < n_data; ++i) {
        __data_start[i] = __data_load[i];
    }
    const uint32_t n_bss = words_between(__bss_start, __bss_end);
    for (uint32_t i = 0u; i < n_bss; ++i) {
        __bss_start[i] = 0u;
    }
    const uint32_t n_psram = words_between(__psram_bss_start, __psram_bss_end);
    for (uint32_t i = 0u; i < n_psram; ++i) {
        __psram_bss_start[i] = 0u;
    }
    paint_stack();

    md_m7_exit(main());
}

uint32_t md_m7_stack_size_bytes(void)
{
    return (uint32_t)(uintptr_t)__stack_size;
}

uint32_t md_m7_stack_used_bytes(void)
{
    const uint32_t n_words = words_between(__stack_limit, __stack_top);
    uint32_t untouched = 0u;
    while (untouched < n_words && __stack_limit[untouched] == STACK_PAINT) {
        ++untouched;
    }
    return 4u * (n_words - untouched);
}

void md_m7_exit(int code)
{
    if (md_m7_exit_hook != NULL) {
        md_m7_exit_hook();
    }
    md_sh_write0("[m7] stack high-water ");
    md_sh_write_uint(md_m7_stack_used_bytes());
    md_sh_write0(" of ");
    md_sh_write_uint(md_m7_stack_size_bytes());
    md_sh_write0(" bytes; exit status ");
    md_sh_write_uint(md_sh_exit_status(code));
    md_sh_write0("\n");
    md_sh_exit(code);
}

static const char *exception_name(uint32_t ipsr)
{
    switch (ipsr) {
    case 2u: return "NMI";
    case 3u: return "HardFault";
    case 4u: return "MemManage";
    case 5u: return "BusFault";
    case 6u: return "UsageFault";
    default: return "unexpected exception";
    }
}

static void print_reg(const char *name, uint32_t v)
{
    md_sh_write0(name);
    md_sh_write_hex(v);
}

/* Called from the fault vectors with the stacked exception frame
 * {r0, r1, r2, r3, r12, lr, pc, xpsr}. Prints and ends the program. */
void md_m7_fault_report(const uint32_t *frame, uint32_t ipsr)
{
    if (md_m7_exit_hook != NULL) {
        md_m7_exit_hook();
    }
    md_sh_write0("\n[m7] FAULT: ");
    md_sh_write0(exception_name(ipsr));
    print_reg(" (exception ", ipsr);
    print_reg(")\n[m7]   pc=", frame[6]);
    print_reg(" lr=", frame[5]);
    print_reg(" xpsr=", frame[7]);
    print_reg("\n[m7]   CFSR=", SCB_CFSR);
    print_reg(" HFSR=", SCB_HFSR);
    print_reg(" MMFAR=", SCB_MMFAR);
    print_reg(" BFAR=", SCB_BFAR);
    md_sh_write0("\n");
    md_sh_exit(MD_M7_FAULT_EXIT_STATUS);
}

/* Fault vectors: pick the stack the frame was pushed on (EXC_RETURN bit 2),
 * read IPSR for the exception number, report. Naked: a corrupt stack must
 * not be touched before the report. */
__attribute__((naked)) static void fault_handler(void)
{
    __asm__ volatile("tst lr, #4      \n"
                     "ite eq          \n"
                     "mrseq r0, msp   \n"
                     "mrsne r0, psp   \n"
                     "mrs r1, ipsr    \n"
                     "b md_m7_fault_report\n");
}

/* Any interrupt nobody claimed: nothing in this port enables one, so it is a
 * bug; report it like a fault. */
__attribute__((naked)) static void default_handler(void)
{
    __asm__ volatile("tst lr, #4      \n"
                     "ite eq          \n"
                     "mrseq r0, msp   \n"
                     "mrsne r0, psp   \n"
                     "mrs r1, ipsr    \n"
                     "b md_m7_fault_report\n");
}

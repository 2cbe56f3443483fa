/* md_port_t on the Cortex-M7 (QEMU mps2-an500): CAN over the UART link, SysTick clock. */
#include "md_port_m7.h"

#include <stdbool.h>
#include <stddef.h>
#include <string.h>

#include "md_can_uart.h"
#include "md_m7_startup.h"

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_CSR_ENABLE_TICKINT_CPUCLK 0x7u
#define SYST_CSR_COUNTFLAG (1u << 16)
#define SCB_ICSR (*(volatile uint32_t *)0xE000ED04u)
#define SCB_ICSR_PENDSTSET (1u << 26)

#define TICKS_PER_PERIOD (MD_M7_SYSCLK_HZ / MD_M7_TICK_HZ)
#define CLOCK_READ_TRIES 4u
_Static_assert(TICKS_PER_PERIOD <= 0x1000000u, "SysTick reload is 24 bits");
_Static_assert(MD_M7_SYSCLK_HZ % 1000000u == 0u, "whole ticks per microsecond");

/* Written only by SysTick_Handler; 64 bits so that it never wraps. */
static volatile uint64_t systick_periods;

void SysTick_Handler(void)
{
    systick_periods = systick_periods + 1u;
}

void md_port_m7_clock_start(void)
{
    SYST_CSR = 0u;
    SYST_RVR = TICKS_PER_PERIOD - 1u;
    SYST_CVR = 0u;
    systick_periods = 0u;
    SYST_CSR = SYST_CSR_ENABLE_TICKINT_CPUCLK;
}

uint64_t md_port_m7_ticks(void)
{
    /* The 64-bit period count is not read atomically, and the down-counter
     * may have wrapped with its interrupt still pending (not yet counted):
     * retry until the period count is stable, and count a pending wrap
     * (PENDSTSET) with the counter read after it was seen. */
    uint64_t periods = 0u;
    uint32_t elapsed = 0u;
    for (uint32_t i = 0u; i < CLOCK_READ_TRIES; ++i) {
        periods = systick_periods;
        uint32_t cvr = SYST_CVR;
        if ((SCB_ICSR & SCB_ICSR_PENDSTSET) != 0u) {
            cvr = SYST_CVR; /* after the wrap */
            periods += 1u;
        }
        elapsed = (TICKS_PER_PERIOD - 1u) - cvr;
        if (systick_periods + ((SCB_ICSR & SCB_ICSR_PENDSTSET) != 0u ? 1u : 0u) == periods) {
            break;
        }
    }
    return periods * TICKS_PER_PERIOD + elapsed;
}

uint64_t md_port_m7_now_us(void)
{
    return md_port_m7_ticks() / (MD_M7_SYSCLK_HZ / 1000000u);
}

static md_status_t port_send(void *ctx, const md_frame_t *frame)
{
    md_port_m7_ctx_t *const c = (md_port_m7_ctx_t *)ctx;
    if (c == NULL) {
        return MD_E_ARG;
    }
    if (frame == NULL || !md_frame_valid(frame)) {
        c->frames_refused++;
        return MD_E_IO;
    }
    /* The board's CAN FD driver: here the UART link (md_can_uart.c); a real
     * board's driver queues the frame in its controller's TX FIFO and returns
     * MD_E_IO when the FIFO is full or the controller is bus-off. */
    c->last_frame = *frame;
    if (md_can_uart_send(frame) != MD_OK) {
        c->frames_failed++;
        return MD_E_IO;
    }
    c->frames_sent++;
    return MD_OK;
}

bool md_port_m7_receive(md_port_m7_ctx_t *ctx, md_frame_t *out)
{
    if (ctx == NULL || out == NULL) {
        return false;
    }
    if (!md_can_uart_receive(out)) {
        return false;
    }
    ctx->frames_received++;
    return true;
}

static uint64_t port_work_now(void *ctx)
{
    const md_port_m7_ctx_t *const c = (const md_port_m7_ctx_t *)ctx;
    const uint64_t ticks = md_port_m7_ticks() - md_can_uart_isr_ticks();
    return (c == NULL) ? 0u : ticks * c->insn_per_tick;
}

/* One run of the calibration loop, in SysTick ticks. */
static uint64_t calib_loop_ticks(void)
{
    uint32_t n = MD_M7_CALIB_INSNS / 2u;
    const uint64_t t0 = md_port_m7_ticks();
    __asm__ volatile("1: subs %0, %0, #1\n bne 1b" : "+r"(n)::"cc");
    return md_port_m7_ticks() - t0;
}

static void port_work_section(void *ctx, bool enter)
{
    (void)ctx;
    md_can_uart_rx_hold(enter);
}

uint64_t md_port_m7_calibrate(md_port_m7_ctx_t *ctx)
{
    if (ctx == NULL) {
        return 0u;
    }
    /* The first run is a warm-up: under QEMU the first SysTick period after
     * the start is irregular (measured: 2 M instructions as 25 000 ticks at
     * shift 0, exactly 50 000 in every later run). */
    (void)calib_loop_ticks();
    const uint64_t ticks = calib_loop_ticks();
    ctx->insn_per_tick = (ticks == 0u) ? 0u : (uint32_t)((MD_M7_CALIB_INSNS + ticks / 2u) / ticks);
    return ticks * ctx->insn_per_tick;
}
static uint64_t port_now_us(void *ctx)
{
    (void)ctx;
    return md_port_m7_now_us();
}

md_status_t md_port_m7_init(md_port_t *port, md_port_m7_ctx_t *ctx)
{
    if (port == NULL || ctx == NULL) {
        return MD_E_ARG;
    }
    memset(ctx, 0, sizeof *ctx);
    port->send = port_send;
    port->now_us = port_now_us;
    port->ctx = ctx;
    port->work_now = port_work_now;
    port->work_section = port_work_section;
    md_can_uart_init();
    return MD_OK;
}

/// @file md_port_m7.h
/// The application port (md_port_t) on the Cortex-M7 / QEMU mps2-an500 build.
///
/// QEMU's AN500 model has no CAN controller: `send` validates and counts
/// frames, keeps the last one and hands it to the board's CAN FD driver,
/// which on this board is the UART link of md_can_uart.c (frames as md_link
/// packets to a host bridge, docs/pil.md). A real board replaces md_can_uart.c
/// with its CAN FD driver (same calls); received frames are pushed into the
/// application from the main loop (main_m7.c, md_port_m7_receive).
///
/// The clock is SysTick at 1 kHz from the 25 MHz AN500 system clock, refined
/// to microseconds with the SysTick down-counter. The work counter (md_port_t
/// work_now) is SysTick ticks outside the UART interrupt, times the
/// instructions per tick measured at start-up (md_port_m7_calibrate): under
/// QEMU -icount shift=N a tick is 40 / 2^N instructions.
#ifndef MD_PORT_M7_H
#define MD_PORT_M7_H

#include <stdbool.h>
#include <stdint.h>

#include "md_status.h"
#include "md_frame.h"
#include "md_port.h"

/// AN500 system (and SysTick) clock.
#define MD_M7_SYSCLK_HZ 25000000u
/// SysTick interrupt rate.
#define MD_M7_TICK_HZ 1000u

/// State behind the stub port; caller-owned (static storage in main).
typedef struct {
    uint32_t frames_sent;      ///< frames accepted by send()
    uint32_t frames_refused;   ///< frames send() rejected (invalid id/length/flags, NULL)
    uint32_t frames_received;  ///< frames md_port_m7_receive() handed out
    uint32_t frames_failed;    ///< valid frames the CAN driver could not send
    uint32_t insn_per_tick;    ///< work units per SysTick tick (md_port_m7_calibrate; 0 before)
    md_frame_t last_frame;     ///< copy of the last accepted frame
} md_port_m7_ctx_t;

/// Fill `port` with the Cortex-M7 send/now_us/work_now functions bound to
/// `ctx`, zero `ctx` and start the CAN driver (the UART link). MD_E_ARG if
/// either pointer is NULL. O(1).
md_status_t md_port_m7_init(md_port_t *port, md_port_m7_ctx_t *ctx);

/// Take the next received frame, if any, into `out`. False if none (or `out`
/// is NULL). From the CAN driver (here the UART link; on a board its CAN FD
/// RX FIFO). Bounded by the driver's receive buffer.
bool md_port_m7_receive(md_port_m7_ctx_t *ctx, md_frame_t *out);

/// Start SysTick at MD_M7_TICK_HZ; now_us() counts from this call. Call once.
void md_port_m7_clock_start(void);

/// Monotonic microseconds since md_port_m7_clock_start (0 before it).
uint64_t md_port_m7_now_us(void);

/// SysTick ticks (MD_M7_SYSCLK_HZ) since md_port_m7_clock_start. Safe in
/// interrupt handlers.
uint64_t md_port_m7_ticks(void);

/// Measures a loop of MD_M7_CALIB_INSNS instructions in SysTick ticks after
/// md_port_m7_clock_start and sets ctx->insn_per_tick (rounded). Returns the
/// loop's instructions as the work counter then measures them, so the caller
/// can print the check (equal to MD_M7_CALIB_INSNS under -icount).
uint64_t md_port_m7_calibrate(md_port_m7_ctx_t *ctx);

/// Instructions of the calibration loop (2 per iteration: subs, bne).
#define MD_M7_CALIB_INSNS 2000000u

#endif

/// @file md_port_m7.h
/// The application port (md_port_t) on the Cortex-M7 / QEMU mps2-an500 build.
///
/// QEMU's AN500 model has no CAN controller, so `send` is a stub that
/// validates and counts frames and keeps the last one. A real board replaces
/// the body of port_send() in md_port_m7.c with its CAN(-FD) driver (marked
/// "BOARD CAN DRIVER"); received frames are pushed into the application from
/// the main loop (main_m7.c, marked "BOARD CAN RX").
///
/// The clock is SysTick at 1 kHz from the 25 MHz AN500 system clock, refined
/// to microseconds with the SysTick down-counter.
#ifndef MD_PORT_M7_H
#define MD_PORT_M7_H

#include <stdbool.h>
#include <stdint.h>

#include "common/md_status.h"
#include "md_frame.h"
#include "md_port.h"

/// AN500 system (and SysTick) clock.
#define MD_M7_SYSCLK_HZ 25000000u
/// SysTick interrupt rate.
#define MD_M7_TICK_HZ 1000u

/// State behind the stub port; caller-owned (static storage in main).
typedef struct {
    uint32_t frames_sent;     ///< frames accepted by send()
    uint32_t frames_refused;  ///< frames send() rejected (invalid id/length/flags, NULL)
    uint32_t frames_received; ///< frames md_port_m7_receive() handed out
    md_frame_t last_frame;    ///< copy of the last accepted frame
} md_port_m7_ctx_t;

/// Fill `port` with the Cortex-M7 send/now_us functions bound to `ctx` and
/// zero `ctx`. MD_E_ARG if either pointer is NULL. O(1).
md_status_t md_port_m7_init(md_port_t *port, md_port_m7_ctx_t *ctx);

/// Take the next received frame, if any, into `out`. False if none (or `out`
/// is NULL). QEMU's AN500 has no CAN controller, so this stub never receives;
/// a real board reads its CAN(-FD) RX FIFO here ("BOARD CAN RX"). O(1).
bool md_port_m7_receive(md_port_m7_ctx_t *ctx, md_frame_t *out);

/// Start SysTick at MD_M7_TICK_HZ; now_us() counts from this call. Call once.
void md_port_m7_clock_start(void);

/// Monotonic microseconds since md_port_m7_clock_start (0 before it).
uint64_t md_port_m7_now_us(void);

#endif

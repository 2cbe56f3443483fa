/// @file md_port.h
/// What the controller application needs from its platform, and nothing more
/// (libcanard style): send a frame, read a monotonic clock (and, where the
/// platform can count it, the CPU work done). Frames are pushed
/// into the application by the platform's loop; the application never owns a
/// thread, a socket or a timer.
#ifndef MD_PORT_H
#define MD_PORT_H

#include <stdbool.h>
#include <stdint.h>

#include "md_status.h"
#include "md_frame.h"

typedef struct {
    /// Queue one frame for transmission. MD_E_IO if the platform refused it;
    /// the application counts every refusal.
    md_status_t (*send)(void *ctx, const md_frame_t *frame);
    /// Monotonic microseconds since an arbitrary origin.
    uint64_t (*now_us)(void *ctx);
    void *ctx;
    /// Optional (NULL: not measured): a monotonic count of the work the CPU
    /// did for the application, in instructions (Cortex-M7 under QEMU
    /// -icount) or CPU cycles (a board's cycle counter), with the time spent
    /// in the platform's own interrupts left out. The electrode cycle reports
    /// its cost in these units (TLM_STATUS CycleCost, ProcessCost).
    uint64_t (*work_now)(void *ctx);
    /// Optional (NULL: nothing to do): called with enter = true before and
    /// enter = false after each stretch of measured work, so that a platform
    /// can hold back its own interrupts meanwhile (the Cortex-M7 port masks
    /// its UART receive interrupts, which then neither count nor interleave).
    void (*work_section)(void *ctx, bool enter);
} md_port_t;

#endif

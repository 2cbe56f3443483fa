/// @file md_port.h
/// What the controller application needs from its platform, and nothing more
/// (libcanard style): send a frame, read a monotonic clock. Frames are pushed
/// into the application by the platform's loop; the application never owns a
/// thread, a socket or a timer.
#ifndef MD_PORT_H
#define MD_PORT_H

#include <stdint.h>

#include "common/md_status.h"
#include "md_frame.h"

typedef struct {
    /// Queue one frame for transmission. MD_E_IO if the platform refused it;
    /// the application counts every refusal.
    md_status_t (*send)(void *ctx, const md_frame_t *frame);
    /// Monotonic microseconds since an arbitrary origin.
    uint64_t (*now_us)(void *ctx);
    void *ctx;
} md_port_t;

#endif

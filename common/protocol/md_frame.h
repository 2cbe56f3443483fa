/// @file md_frame.h
/// One CAN or CAN FD frame as every part of the project carries it.
///
/// Mirrors Linux `struct canfd_frame` semantics without depending on Linux
/// headers, so the firmware core/app can use it on any platform. Validity
/// rules (md_frame_valid) are the ones a SocketCAN driver enforces.
#ifndef MD_FRAME_H
#define MD_FRAME_H

#include <stdbool.h>
#include <stdint.h>

#define MD_FRAME_MAX_DATA 64u    ///< CAN FD payload limit
#define MD_FRAME_FLAG_FD 0x01u   ///< CAN FD frame (length up to 64)
#define MD_FRAME_FLAG_EXT 0x02u  ///< 29-bit identifier
#define MD_FRAME_FLAG_BRS 0x04u  ///< FD bit-rate switch (informational)
#define MD_FRAME_STD_ID_MAX 0x7FFu
#define MD_FRAME_EXT_ID_MAX 0x1FFFFFFFu

typedef struct {
    uint32_t id;    ///< 11-bit, or 29-bit with MD_FRAME_FLAG_EXT
    uint8_t len;    ///< payload bytes: 0..8, or an FD length (12,16,20,24,32,48,64)
    uint8_t flags;  ///< MD_FRAME_FLAG_*
    uint8_t data[MD_FRAME_MAX_DATA];
} md_frame_t;

/// True if len is a length the frame's kind can carry on the wire.
static inline bool md_frame_len_valid(uint8_t len, bool fd)
{
    if (len <= 8u) {
        return true;
    }
    if (!fd) {
        return false;
    }
    return len == 12u || len == 16u || len == 20u || len == 24u || len == 32u || len == 48u || len == 64u;
}

/// True if the frame's id, flags and length are all representable on a bus.
static inline bool md_frame_valid(const md_frame_t *f)
{
    const bool ext = (f->flags & MD_FRAME_FLAG_EXT) != 0u;
    const uint32_t id_max = ext ? MD_FRAME_EXT_ID_MAX : MD_FRAME_STD_ID_MAX;
    const uint8_t known = (uint8_t)(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_EXT | MD_FRAME_FLAG_BRS);
    return f->id <= id_max && (f->flags & (uint8_t)~known) == 0u &&
           md_frame_len_valid(f->len, (f->flags & MD_FRAME_FLAG_FD) != 0u);
}

#endif

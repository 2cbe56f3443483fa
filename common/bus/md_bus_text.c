/// @file md_bus_text.c
/// can-utils frame syntax (cansend input, candump -L output); see md_bus_text.h.
#include "md_bus_text.h"

#include <errno.h>
#include <string.h>

static int hex_value(char c)
{
    if (c >= '0' && c <= '9') {
        return c - '0';
    }
    if (c >= 'a' && c <= 'f') {
        return c - 'a' + 10;
    }
    if (c >= 'A' && c <= 'F') {
        return c - 'A' + 10;
    }
    return -1;
}

static int fail(const char **why, const char *msg)
{
    if (why != NULL) {
        *why = msg;
    }
    return -EINVAL;
}

/// Smallest CAN FD length >= n (n <= 64).
static uint8_t fd_round_up(uint8_t n)
{
    static const uint8_t lens[] = {8, 12, 16, 20, 24, 32, 48, 64};
    if (n <= 8u) {
        return n;
    }
    for (size_t i = 0; i < sizeof lens; ++i) {
        if (lens[i] >= n) {
            return lens[i];
        }
    }
    return 64u;
}

static int parse_data(const char *p, md_frame_t *frame, uint8_t max_len, const char **why)
{
    uint8_t n = 0;
    // Bounded by the payload limit: every iteration consumes one byte or fails.
    for (unsigned guard = 0; *p != '\0' && guard <= 2u * MD_FRAME_MAX_DATA; ++guard) {
        if (*p == '.') {
            ++p;
            continue;
        }
        const int hi = hex_value(p[0]);
        const int lo = hi < 0 ? -1 : hex_value(p[1]);
        if (lo < 0) {
            return fail(why, "data must be pairs of hex digits (optionally separated by '.')");
        }
        if (n >= max_len) {
            return fail(why, max_len == 8u ? "classic CAN carries at most 8 bytes (use ## for CAN FD)"
                                           : "CAN FD carries at most 64 bytes");
        }
        frame->data[n++] = (uint8_t)((hi << 4) | lo);
        p += 2;
    }
    if (*p != '\0') {
        return fail(why, "data too long");
    }
    frame->len = n;
    return 0;
}

int md_bus_text_parse(const char *text, md_frame_t *frame, const char **why)
{
    if (text == NULL || frame == NULL) {
        return fail(why, "no text");
    }
    memset(frame, 0, sizeof *frame);
    const char *hash = strchr(text, '#');
    const size_t id_digits = hash == NULL ? 0u : (size_t)(hash - text);
    if (id_digits != 3u && id_digits != 8u) {
        return fail(why, "want <3 or 8 hex digit id>#<data> or <id>##<flags><data>");
    }
    uint32_t id = 0;
    for (size_t i = 0; i < id_digits; ++i) {
        const int v = hex_value(text[i]);
        if (v < 0) {
            return fail(why, "id must be hex");
        }
        id = (id << 4) | (uint32_t)v;
    }
    frame->id = id;
    if (id_digits == 8u) {
        frame->flags |= (uint8_t)MD_FRAME_FLAG_EXT;
    }
    const char *p = hash + 1;
    uint8_t max_len = 8u;
    if (*p == 'R' || *p == 'r') {
        return fail(why, "remote (RTR) frames are not supported");
    }
    if (*p == '#') {
        const int nibble = hex_value(p[1]);
        if (nibble < 0) {
            return fail(why, "CAN FD wants one hex flag digit after ## (1 = BRS)");
        }
        frame->flags |= (uint8_t)MD_FRAME_FLAG_FD;
        if ((nibble & 0x1) != 0) {
            frame->flags |= (uint8_t)MD_FRAME_FLAG_BRS;
        }
        p += 2;
        max_len = MD_FRAME_MAX_DATA;
    }
    const int rc = parse_data(p, frame, max_len, why);
    if (rc != 0) {
        return rc;
    }
    if ((frame->flags & MD_FRAME_FLAG_FD) != 0u) {
        frame->len = fd_round_up(frame->len);  // padding bytes are already zero
    }
    if (!md_frame_valid(frame)) {
        return fail(why, "id out of range (11-bit ids go up to 7FF; use 8 digits for 29-bit)");
    }
    return 0;
}

int md_bus_text_format(const md_frame_t *frame, char *out, size_t out_cap)
{
    static const char hex[] = "0123456789ABCDEF";
    if (frame == NULL || out == NULL || !md_frame_valid(frame)) {
        return -EINVAL;
    }
    char buf[MD_BUS_TEXT_MAX];
    size_t n = 0;
    const bool ext = (frame->flags & MD_FRAME_FLAG_EXT) != 0u;
    for (int shift = ext ? 28 : 8; shift >= 0; shift -= 4) {
        buf[n++] = hex[(frame->id >> (unsigned)shift) & 0xFu];
    }
    buf[n++] = '#';
    if ((frame->flags & MD_FRAME_FLAG_FD) != 0u) {
        buf[n++] = '#';
        // FDF (4) is always set on an FD frame, as candump prints it on
        // Linux >= 6.1; BRS is 1.
        buf[n++] = (frame->flags & MD_FRAME_FLAG_BRS) != 0u ? '5' : '4';
    }
    for (uint8_t i = 0; i < frame->len; ++i) {
        buf[n++] = hex[frame->data[i] >> 4];
        buf[n++] = hex[frame->data[i] & 0xFu];
    }
    if (n + 1u > out_cap) {
        return -ENOSPC;
    }
    memcpy(out, buf, n);
    out[n] = '\0';
    return (int)n;
}

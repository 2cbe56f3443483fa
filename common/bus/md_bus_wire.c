/// @file md_bus_wire.c
/// UDP bus datagram encode/decode (format in md_bus_wire.h and docs/bus.md).
#include "md_bus_wire.h"

#include <string.h>

// Multi-byte fields are big-endian (network order), written byte by byte so
// the format does not depend on the host's endianness or struct padding.
static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v >> 24);
    p[1] = (uint8_t)(v >> 16);
    p[2] = (uint8_t)(v >> 8);
    p[3] = (uint8_t)v;
}

static uint32_t get_u32(const uint8_t *p)
{
    return ((uint32_t)p[0] << 24) | ((uint32_t)p[1] << 16) | ((uint32_t)p[2] << 8) | (uint32_t)p[3];
}

uint16_t md_bus_wire_crc16(const uint8_t *data, size_t len)
{
    uint16_t crc = 0xFFFFu;
    for (size_t i = 0; i < len; ++i) {
        crc = (uint16_t)(crc ^ (uint16_t)((uint16_t)data[i] << 8));
        for (unsigned bit = 0; bit < 8u; ++bit) {
            const bool top = (crc & 0x8000u) != 0u;
            crc = (uint16_t)(crc << 1);
            if (top) {
                crc = (uint16_t)(crc ^ 0x1021u);
            }
        }
    }
    return crc;
}

int md_bus_wire_encode(const md_frame_t *frame, uint32_t sender_id, uint32_t seq, uint8_t *out, size_t out_cap)
{
    if (frame == NULL || out == NULL || sender_id == 0u) {
        return MD_BUS_WIRE_E_ARG;
    }
    if (!md_frame_valid(frame)) {
        return MD_BUS_WIRE_E_FRAME;
    }
    const size_t body = MD_BUS_WIRE_HEADER + (size_t)frame->len;
    const size_t size = body + MD_BUS_WIRE_CRC_LEN;
    if (out_cap < size) {
        return MD_BUS_WIRE_E_ARG;
    }
    out[0] = MD_BUS_WIRE_MAGIC0;
    out[1] = MD_BUS_WIRE_MAGIC1;
    out[2] = MD_BUS_WIRE_VERSION;
    out[3] = frame->flags;
    put_u32(&out[4], sender_id);
    put_u32(&out[8], seq);
    put_u32(&out[12], frame->id);
    out[16] = frame->len;
    out[17] = 0u;
    memcpy(&out[MD_BUS_WIRE_HEADER], frame->data, frame->len);
    const uint16_t crc = md_bus_wire_crc16(out, body);
    out[body] = (uint8_t)(crc >> 8);
    out[body + 1u] = (uint8_t)crc;
    return (int)size;
}

md_bus_wire_status_t md_bus_wire_decode(const uint8_t *buf, size_t size, md_frame_t *frame, uint32_t *sender_id,
                                        uint32_t *seq)
{
    if (buf == NULL || frame == NULL || sender_id == NULL || seq == NULL) {
        return MD_BUS_WIRE_E_ARG;
    }
    if (size < MD_BUS_WIRE_HEADER + MD_BUS_WIRE_CRC_LEN) {
        return MD_BUS_WIRE_E_SHORT;
    }
    if (buf[0] != MD_BUS_WIRE_MAGIC0 || buf[1] != MD_BUS_WIRE_MAGIC1) {
        return MD_BUS_WIRE_E_MAGIC;
    }
    if (buf[2] != MD_BUS_WIRE_VERSION) {
        return MD_BUS_WIRE_E_VERSION;
    }
    const uint8_t len = buf[16];
    // Checked before the CRC so a lying length can never make us read past
    // the datagram.
    if (len > MD_FRAME_MAX_DATA || size != MD_BUS_WIRE_HEADER + (size_t)len + MD_BUS_WIRE_CRC_LEN) {
        return MD_BUS_WIRE_E_LENGTH;
    }
    const size_t body = MD_BUS_WIRE_HEADER + (size_t)len;
    const uint16_t crc = (uint16_t)(((uint16_t)buf[body] << 8) | (uint16_t)buf[body + 1u]);
    if (md_bus_wire_crc16(buf, body) != crc) {
        return MD_BUS_WIRE_E_CRC;
    }
    const uint32_t sender = get_u32(&buf[4]);
    if (buf[17] != 0u || sender == 0u) {
        return MD_BUS_WIRE_E_RESERVED;
    }
    memset(frame, 0, sizeof *frame);
    frame->flags = buf[3];
    frame->id = get_u32(&buf[12]);
    frame->len = len;
    memcpy(frame->data, &buf[MD_BUS_WIRE_HEADER], len);
    if (!md_frame_valid(frame)) {
        return MD_BUS_WIRE_E_FRAME;
    }
    *sender_id = sender;
    *seq = get_u32(&buf[8]);
    return MD_BUS_WIRE_OK;
}

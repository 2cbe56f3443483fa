/// @file md_bus_wire.h
/// The UDP bus's datagram format: one CAN/CAN FD frame per datagram, with a
/// sender id (so a node can drop its own looped-back datagrams), a per-sender
/// sequence number and a CRC. Layout byte by byte in docs/bus.md. Pure
/// functions, no I/O: the UDP transport, the tests and mdcan share them.
#ifndef MD_BUS_WIRE_H
#define MD_BUS_WIRE_H

#include <stddef.h>
#include <stdint.h>

#include "md_frame.h"

#define MD_BUS_WIRE_MAGIC0 0x4Du  ///< 'M'
#define MD_BUS_WIRE_MAGIC1 0x42u  ///< 'B'
#define MD_BUS_WIRE_VERSION 1u
#define MD_BUS_WIRE_HEADER 18u  ///< bytes before the data
#define MD_BUS_WIRE_CRC_LEN 2u
#define MD_BUS_WIRE_MAX (MD_BUS_WIRE_HEADER + MD_FRAME_MAX_DATA + MD_BUS_WIRE_CRC_LEN)

/// Why a datagram was rejected (all negative; 0 = accepted).
typedef enum {
    MD_BUS_WIRE_OK = 0,
    MD_BUS_WIRE_E_SHORT = -1,  ///< shorter than header + CRC
    MD_BUS_WIRE_E_MAGIC = -2,
    MD_BUS_WIRE_E_VERSION = -3,
    MD_BUS_WIRE_E_LENGTH = -4,  ///< datagram size != header + len + CRC
    MD_BUS_WIRE_E_CRC = -5,
    MD_BUS_WIRE_E_FRAME = -6,     ///< !md_frame_valid (id, flags, len)
    MD_BUS_WIRE_E_RESERVED = -7,  ///< reserved byte not zero, or sender id 0
    MD_BUS_WIRE_E_ARG = -8        ///< NULL pointer or output too small
} md_bus_wire_status_t;

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no xorout);
/// check value over "123456789" is 0x29B1. O(len).
uint16_t md_bus_wire_crc16(const uint8_t *data, size_t len);

/// Encodes `frame` from `sender_id` (non-zero) with sequence `seq` into `out`.
/// Returns the datagram size (> 0), or MD_BUS_WIRE_E_FRAME for an invalid
/// frame, MD_BUS_WIRE_E_ARG if out_cap < size or sender_id is 0.
int md_bus_wire_encode(const md_frame_t *frame, uint32_t sender_id, uint32_t seq, uint8_t *out, size_t out_cap);

/// Decodes and fully validates one datagram of `size` bytes: magic, version,
/// reserved byte, sender id, size against len, CRC, md_frame_valid. On
/// MD_BUS_WIRE_OK fills *frame (unused data bytes zeroed), *sender_id, *seq;
/// on failure leaves them unspecified.
md_bus_wire_status_t md_bus_wire_decode(const uint8_t *buf, size_t size, md_frame_t *frame, uint32_t *sender_id,
                                        uint32_t *seq);

#endif

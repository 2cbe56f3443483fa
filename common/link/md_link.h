/// @file md_link.h
/// CAN (FD) frames over a byte stream (a UART, a pipe, a socket): the framing
/// the Cortex-M7 image and the host bridge (`mdcan bridge`) share, so that
/// a serial line carries exactly the frames a CAN FD bus would (docs/pil.md).
///
/// One frame on the wire, before byte stuffing:
///
///     flags (1) | len (1) | id (4, little-endian) | data (len) | crc16 (2, little-endian)
///
/// flags and id as md_frame_t (MD_FRAME_FLAG_*), len a CAN/CAN FD length;
/// crc16 = CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no
/// final xor) over flags..data. The packet is SLIP-stuffed (RFC 1055: 0xC0
/// ends a packet, 0xDB 0xDC stands for 0xC0, 0xDB 0xDD for 0xDB) and sent as
/// END packet END, so a receiver that joins mid-stream or sees line noise
/// resynchronises at the next END. Empty packets (END END) are ignored.
///
/// Pure code, no I/O, no heap; the decoder is a bounded state machine fed one
/// byte at a time, and every malformed packet is counted by its reason.
#ifndef MD_LINK_H
#define MD_LINK_H

#include <stddef.h>
#include <stdint.h>

#include "md_frame.h"

#define MD_LINK_END 0xC0u
#define MD_LINK_ESC 0xDBu
#define MD_LINK_ESC_END 0xDCu
#define MD_LINK_ESC_ESC 0xDDu

/// Header bytes (flags, len, id) and CRC bytes of a packet.
#define MD_LINK_HEADER_BYTES 6u
#define MD_LINK_CRC_BYTES 2u
/// Largest unstuffed packet.
#define MD_LINK_PACKET_MAX (MD_LINK_HEADER_BYTES + MD_FRAME_MAX_DATA + MD_LINK_CRC_BYTES)
/// Largest encoded frame: every byte escaped, plus the two END bytes.
#define MD_LINK_ENCODED_MAX (2u * MD_LINK_PACKET_MAX + 2u)

/// What md_link_decode_byte made of one byte.
typedef enum {
    MD_LINK_NONE = 0,        ///< inside a packet (or an ignored empty packet)
    MD_LINK_FRAME = 1,       ///< a valid frame is in *out
    MD_LINK_BAD_CRC = -1,    ///< a packet with a wrong CRC (dropped)
    MD_LINK_BAD_FRAME = -2,  ///< length, flags or id not a valid frame (dropped)
    MD_LINK_BAD_ESC = -3,    ///< an escape byte followed by neither 0xDC nor 0xDD (packet dropped)
    MD_LINK_TOO_LONG = -4,   ///< more bytes than the largest packet (dropped up to the next END)
} md_link_result_t;

/// Decoder state and its counters.
typedef struct {
    uint8_t buf[MD_LINK_PACKET_MAX];
    uint16_t n;       ///< bytes of the current packet so far
    uint8_t esc;      ///< the previous byte was MD_LINK_ESC
    uint8_t discard;  ///< the current packet is already bad: skip to END
    uint32_t frames;  ///< valid frames decoded
    uint32_t bad_crc;
    uint32_t bad_frame;
    uint32_t bad_esc;
    uint32_t too_long;
} md_link_decoder_t;

/// CRC-16/CCITT-FALSE of n bytes (check value of "123456789": 0x29B1).
uint16_t md_link_crc16(const uint8_t *p, size_t n);

/// Encodes `f` (which must be md_frame_valid) into `out`. Returns the bytes
/// written (at most MD_LINK_ENCODED_MAX), or 0 if the frame is invalid, an
/// argument is NULL or `cap` is too small for this frame. O(len).
size_t md_link_encode(const md_frame_t *f, uint8_t *out, size_t cap);

/// Empties the decoder and zeroes its counters.
void md_link_decoder_init(md_link_decoder_t *d);

/// Feeds one byte. MD_LINK_FRAME: a whole valid frame was decoded into *out.
/// A negative result names why a packet was dropped (also counted in `d`).
/// O(1) per byte except at the END of a packet (O(packet) for the CRC).
md_link_result_t md_link_decode_byte(md_link_decoder_t *d, uint8_t byte, md_frame_t *out);

#endif

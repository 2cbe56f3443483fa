/// @file md_link.c
/// SLIP framing of CAN (FD) frames with a CRC-16. See md_link.h.
#include "md_link.h"

#include <stdbool.h>
#include <string.h>

_Static_assert(MD_LINK_PACKET_MAX <= UINT16_MAX, "packet length fits the decoder's counter");
_Static_assert(MD_LINK_PACKET_MAX == 72u, "6 header bytes, 64 data bytes, 2 CRC bytes");

uint16_t md_link_crc16(const uint8_t *p, size_t n)
{
    /* CRC-16/CCITT-FALSE, computed in 32 bits and masked (no narrowing
     * conversion inside the loop for -Wconversion at any optimisation level). */
    uint32_t crc = 0xFFFFu;
    for (size_t i = 0u; i < n; ++i) {
        crc ^= (uint32_t)p[i] << 8;
        for (unsigned b = 0u; b < 8u; ++b) {
            const uint32_t shifted = (crc << 1) & 0xFFFFu;
            crc = ((crc & 0x8000u) != 0u) ? (shifted ^ 0x1021u) : shifted;
        }
    }
    return (uint16_t)crc;
}

/* Appends one byte, stuffed; the caller has checked the room (2 bytes). */
static size_t put_stuffed(uint8_t *out, size_t at, uint8_t b)
{
    if (b == MD_LINK_END) {
        out[at] = MD_LINK_ESC;
        out[at + 1u] = MD_LINK_ESC_END;
        return at + 2u;
    }
    if (b == MD_LINK_ESC) {
        out[at] = MD_LINK_ESC;
        out[at + 1u] = MD_LINK_ESC_ESC;
        return at + 2u;
    }
    out[at] = b;
    return at + 1u;
}

size_t md_link_encode(const md_frame_t *f, uint8_t *out, size_t cap)
{
    if (f == NULL || out == NULL || !md_frame_valid(f)) {
        return 0u;
    }
    uint8_t pkt[MD_LINK_PACKET_MAX];
    pkt[0] = f->flags;
    pkt[1] = f->len;
    pkt[2] = (uint8_t)(f->id & 0xFFu);
    pkt[3] = (uint8_t)((f->id >> 8) & 0xFFu);
    pkt[4] = (uint8_t)((f->id >> 16) & 0xFFu);
    pkt[5] = (uint8_t)((f->id >> 24) & 0xFFu);
    memcpy(&pkt[MD_LINK_HEADER_BYTES], f->data, f->len);
    const size_t n = MD_LINK_HEADER_BYTES + (size_t)f->len;
    const uint16_t crc = md_link_crc16(pkt, n);
    pkt[n] = (uint8_t)(crc & 0xFFu);
    pkt[n + 1u] = (uint8_t)(crc >> 8);
    const size_t total = n + MD_LINK_CRC_BYTES;
    if (cap < 2u * total + 2u) {
        return 0u; /* room for the worst case: every byte escaped */
    }
    size_t at = 0u;
    out[at++] = MD_LINK_END;
    for (size_t i = 0u; i < total; ++i) {
        at = put_stuffed(out, at, pkt[i]);
    }
    out[at++] = MD_LINK_END;
    return at;
}

void md_link_decoder_init(md_link_decoder_t *d)
{
    if (d != NULL) {
        memset(d, 0, sizeof *d);
    }
}

/* A complete packet of d->n bytes: check and unpack it. */
static md_link_result_t finish(md_link_decoder_t *d, md_frame_t *out)
{
    const size_t n = d->n;
    if (n < MD_LINK_HEADER_BYTES + MD_LINK_CRC_BYTES) {
        d->bad_frame++;
        return MD_LINK_BAD_FRAME;
    }
    const uint16_t crc = (uint16_t)((uint16_t)d->buf[n - 2u] | (uint16_t)((uint16_t)d->buf[n - 1u] << 8));
    if (md_link_crc16(d->buf, n - MD_LINK_CRC_BYTES) != crc) {
        d->bad_crc++;
        return MD_LINK_BAD_CRC;
    }
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.flags = d->buf[0];
    f.len = d->buf[1];
    f.id = (uint32_t)d->buf[2] | ((uint32_t)d->buf[3] << 8) | ((uint32_t)d->buf[4] << 16) | ((uint32_t)d->buf[5] << 24);
    if ((size_t)f.len != n - MD_LINK_HEADER_BYTES - MD_LINK_CRC_BYTES || !md_frame_valid(&f)) {
        d->bad_frame++;
        return MD_LINK_BAD_FRAME;
    }
    memcpy(f.data, &d->buf[MD_LINK_HEADER_BYTES], f.len);
    *out = f;
    d->frames++;
    return MD_LINK_FRAME;
}

md_link_result_t md_link_decode_byte(md_link_decoder_t *d, uint8_t byte, md_frame_t *out)
{
    if (d == NULL || out == NULL) {
        return MD_LINK_NONE;
    }
    if (byte == MD_LINK_END) {
        const bool had_packet = d->n > 0u || d->esc != 0u;
        const bool discard = d->discard != 0u;
        d->esc = 0u;
        d->discard = 0u;
        if (discard || !had_packet) {
            d->n = 0u;
            return MD_LINK_NONE; /* a dropped packet's end, or an empty packet */
        }
        const md_link_result_t r = finish(d, out);
        d->n = 0u;
        return r;
    }
    if (d->discard != 0u) {
        return MD_LINK_NONE;
    }
    uint8_t b = byte;
    if (d->esc != 0u) {
        d->esc = 0u;
        if (byte == MD_LINK_ESC_END) {
            b = MD_LINK_END;
        } else if (byte == MD_LINK_ESC_ESC) {
            b = MD_LINK_ESC;
        } else {
            d->discard = 1u;
            d->bad_esc++;
            return MD_LINK_BAD_ESC;
        }
    } else if (byte == MD_LINK_ESC) {
        d->esc = 1u;
        return MD_LINK_NONE;
    }
    if (d->n >= MD_LINK_PACKET_MAX) {
        d->discard = 1u;
        d->too_long++;
        return MD_LINK_TOO_LONG;
    }
    d->buf[d->n++] = b;
    return MD_LINK_NONE;
}

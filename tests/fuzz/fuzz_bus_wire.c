/// @file fuzz_bus_wire.c
/// Fuzz target 3a: the UDP bus datagram decoder (common/bus/md_bus_wire.h) on
/// arbitrary datagrams. The first input byte is a control byte, the rest the
/// datagram; control bit 0 repairs the length byte and bit 1 the CRC before
/// decoding, so the fuzzer also explores datagrams that get past those gates.
/// Checks:
///  - decode never reads outside the datagram (ASan: exact-size heap copy);
///  - an accepted datagram yields a valid frame with zeroed unused bytes, and
///    encoding that frame with the decoded sender and sequence reproduces the
///    datagram byte for byte (nothing accepted is ambiguous or lossy);
///  - encode refuses a buffer one byte too short and never writes past it;
///  - a rejection is one of the documented codes.
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_input.h"
#include "md_bus_wire.h"

static void repair(uint8_t *dg, size_t size, uint8_t control)
{
    if ((control & 1u) != 0u && size > MD_BUS_WIRE_HEADER) {
        const size_t len = size - MD_BUS_WIRE_HEADER - MD_BUS_WIRE_CRC_LEN;
        dg[16] = (uint8_t)len; /* wraps for oversize datagrams: still a lie to reject */
    }
    if ((control & 2u) != 0u && size >= MD_BUS_WIRE_HEADER + MD_BUS_WIRE_CRC_LEN) {
        const size_t body = size - MD_BUS_WIRE_CRC_LEN;
        const uint16_t crc = md_bus_wire_crc16(dg, body);
        dg[body] = (uint8_t)(crc >> 8u);
        dg[body + 1u] = (uint8_t)crc;
    }
}

static void check_roundtrip(const uint8_t *dg, size_t size, const md_frame_t *f, uint32_t sender, uint32_t seq)
{
    FUZZ_CHECK(md_frame_valid(f));
    FUZZ_CHECK(sender != 0u);
    for (size_t i = f->len; i < MD_FRAME_MAX_DATA; ++i) {
        FUZZ_CHECK(f->data[i] == 0u);
    }
    uint8_t *out = (uint8_t *)malloc(size);
    FUZZ_CHECK(out != NULL);
    FUZZ_CHECK(md_bus_wire_encode(f, sender, seq, out, size - 1u) == MD_BUS_WIRE_E_ARG);
    FUZZ_CHECK(md_bus_wire_encode(f, sender, seq, out, size) == (int)size);
    FUZZ_CHECK(memcmp(out, dg, size) == 0);
    free(out);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1u || size > 2u * MD_BUS_WIRE_MAX) {
        return 0;
    }
    const uint8_t control = data[0];
    const size_t dg_size = size - 1u;
    uint8_t *dg = (uint8_t *)malloc(dg_size);
    if (dg == NULL) {
        return 0;
    }
    memcpy(dg, data + 1, dg_size);
    repair(dg, dg_size, control);
    md_frame_t f;
    uint32_t sender = 0u;
    uint32_t seq = 0u;
    const md_bus_wire_status_t st = md_bus_wire_decode(dg, dg_size, &f, &sender, &seq);
    FUZZ_CHECK(st <= MD_BUS_WIRE_OK && st >= MD_BUS_WIRE_E_ARG && st != MD_BUS_WIRE_E_ARG);
    if (st == MD_BUS_WIRE_OK) {
        check_roundtrip(dg, dg_size, &f, sender, seq);
    }
    free(dg);
    return 0;
}

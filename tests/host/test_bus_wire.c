/// Host tests of the UDP bus datagram format (common/bus/md_bus_wire.h):
/// byte layout, CRC, and rejection of every kind of malformed datagram.
#include <string.h>

#include "md_bus_wire.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static md_frame_t golden_frame(void)
{
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = 0x123;
    f.len = 12;
    f.flags = (uint8_t)(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_BRS);
    for (uint8_t i = 0; i < f.len; ++i) {
        f.data[i] = (uint8_t)(0xA0u + i);
    }
    return f;
}

// Computed independently (Python, CRC-16/CCITT-FALSE) from docs/bus.md.
static const uint8_t GOLDEN[] = {0x4D, 0x42, 0x01, 0x05, 0x11, 0x22, 0x33, 0x44, 0x00, 0x00, 0x00,
                                 0x07, 0x00, 0x00, 0x01, 0x23, 0x0C, 0x00, 0xA0, 0xA1, 0xA2, 0xA3,
                                 0xA4, 0xA5, 0xA6, 0xA7, 0xA8, 0xA9, 0xAA, 0xAB, 0x85, 0x46};

/// Rewrites the CRC after a deliberate edit, so a test reaches the check
/// behind the CRC.
static void fix_crc(uint8_t *buf, size_t size)
{
    const uint16_t crc = md_bus_wire_crc16(buf, size - 2u);
    buf[size - 2u] = (uint8_t)(crc >> 8);
    buf[size - 1u] = (uint8_t)crc;
}

static md_bus_wire_status_t decode(const uint8_t *buf, size_t size)
{
    md_frame_t f;
    uint32_t sender = 0;
    uint32_t seq = 0;
    return md_bus_wire_decode(buf, size, &f, &sender, &seq);
}

static void test_crc16_check_value(void)
{
    TEST_ASSERT_EQUAL_HEX16(0x29B1, md_bus_wire_crc16((const uint8_t *)"123456789", 9));
}

static void test_encode_matches_the_documented_layout(void)
{
    const md_frame_t f = golden_frame();
    uint8_t buf[MD_BUS_WIRE_MAX];
    TEST_ASSERT_EQUAL_INT((int)sizeof GOLDEN, md_bus_wire_encode(&f, 0x11223344u, 7u, buf, sizeof buf));
    TEST_ASSERT_EQUAL_MEMORY(GOLDEN, buf, sizeof GOLDEN);
}

static void test_decode_round_trips_every_length_and_flag(void)
{
    const uint8_t lens[] = {0, 1, 7, 8, 12, 16, 20, 24, 32, 48, 64};
    for (size_t i = 0; i < sizeof lens; ++i) {
        for (uint8_t flags = 0; flags < 8u; ++flags) {
            md_frame_t f;
            memset(&f, 0, sizeof f);
            f.flags = flags;
            f.len = lens[i];
            f.id = (flags & MD_FRAME_FLAG_EXT) != 0u ? 0x1ABCDEF0u : 0x7FFu;
            for (uint8_t k = 0; k < f.len; ++k) {
                f.data[k] = (uint8_t)(k * 13u + flags);
            }
            uint8_t buf[MD_BUS_WIRE_MAX];
            const int size = md_bus_wire_encode(&f, 0xDEADBEEFu, 0xFFFFFFFFu, buf, sizeof buf);
            if (!md_frame_valid(&f)) {
                TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_FRAME, size);
                continue;
            }
            TEST_ASSERT_EQUAL_INT((int)(MD_BUS_WIRE_HEADER + f.len + MD_BUS_WIRE_CRC_LEN), size);
            md_frame_t r;
            uint32_t sender = 0;
            uint32_t seq = 0;
            TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_OK, md_bus_wire_decode(buf, (size_t)size, &r, &sender, &seq));
            TEST_ASSERT_EQUAL_HEX32(0xDEADBEEFu, sender);
            TEST_ASSERT_EQUAL_HEX32(0xFFFFFFFFu, seq);
            TEST_ASSERT_EQUAL_UINT32(f.id, r.id);
            TEST_ASSERT_EQUAL_UINT8(f.len, r.len);
            TEST_ASSERT_EQUAL_UINT8(f.flags, r.flags);
            TEST_ASSERT_EQUAL_MEMORY(f.data, r.data, MD_FRAME_MAX_DATA);  // tail zeroed too
        }
    }
}

static void test_each_malformation_is_rejected_with_its_reason(void)
{
    uint8_t buf[MD_BUS_WIRE_MAX + 1u];
    const size_t n = sizeof GOLDEN;
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_OK, decode(GOLDEN, n));
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_SHORT, decode(GOLDEN, 19));
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_SHORT, decode(GOLDEN, 0));
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_LENGTH, decode(GOLDEN, n - 1u));

    memcpy(buf, GOLDEN, n);
    buf[n] = 0;
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_LENGTH, decode(buf, n + 1u));

    memcpy(buf, GOLDEN, n);
    buf[0] = 'X';
    fix_crc(buf, n);
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_MAGIC, decode(buf, n));

    memcpy(buf, GOLDEN, n);
    buf[2] = 2;
    fix_crc(buf, n);
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_VERSION, decode(buf, n));

    memcpy(buf, GOLDEN, n);
    buf[16] = 200;  // len beyond any frame: refused before reading data
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_LENGTH, decode(buf, n));

    memcpy(buf, GOLDEN, n);
    buf[20] ^= 0x01u;
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_CRC, decode(buf, n));

    memcpy(buf, GOLDEN, n);
    buf[17] = 1;
    fix_crc(buf, n);
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_RESERVED, decode(buf, n));

    memcpy(buf, GOLDEN, n);
    memset(&buf[4], 0, 4);  // sender id 0 is reserved
    fix_crc(buf, n);
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_RESERVED, decode(buf, n));

    memcpy(buf, GOLDEN, n);
    buf[3] = 0x00;  // a classic frame cannot carry 12 bytes
    fix_crc(buf, n);
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_FRAME, decode(buf, n));

    memcpy(buf, GOLDEN, n);
    buf[3] = 0x09;  // unknown flag
    fix_crc(buf, n);
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_FRAME, decode(buf, n));

    memcpy(buf, GOLDEN, n);
    buf[14] = 0x08;  // 11-bit id 0x80123 without EXT
    fix_crc(buf, n);
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_FRAME, decode(buf, n));
}

static void test_every_single_bit_flip_is_rejected(void)
{
    uint8_t buf[sizeof GOLDEN];
    for (size_t byte = 0; byte < sizeof GOLDEN; ++byte) {
        for (unsigned bit = 0; bit < 8u; ++bit) {
            memcpy(buf, GOLDEN, sizeof buf);
            buf[byte] = (uint8_t)(buf[byte] ^ (1u << bit));
            TEST_ASSERT_TRUE(decode(buf, sizeof buf) != MD_BUS_WIRE_OK);
        }
    }
}

static void test_encode_refuses_bad_arguments(void)
{
    const md_frame_t f = golden_frame();
    uint8_t buf[MD_BUS_WIRE_MAX];
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_ARG, md_bus_wire_encode(&f, 0u, 0u, buf, sizeof buf));
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_ARG, md_bus_wire_encode(&f, 1u, 0u, buf, sizeof GOLDEN - 1u));
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_ARG, md_bus_wire_encode(NULL, 1u, 0u, buf, sizeof buf));
    md_frame_t bad = f;
    bad.len = 13;
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_FRAME, md_bus_wire_encode(&bad, 1u, 0u, buf, sizeof buf));
    TEST_ASSERT_EQUAL_INT(MD_BUS_WIRE_E_ARG, md_bus_wire_decode(GOLDEN, sizeof GOLDEN, NULL, NULL, NULL));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_crc16_check_value);
    RUN_TEST(test_encode_matches_the_documented_layout);
    RUN_TEST(test_decode_round_trips_every_length_and_flag);
    RUN_TEST(test_each_malformation_is_rejected_with_its_reason);
    RUN_TEST(test_every_single_bit_flip_is_rejected);
    RUN_TEST(test_encode_refuses_bad_arguments);
    return UNITY_END();
}

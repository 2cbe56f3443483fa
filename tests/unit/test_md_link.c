/* md_link: CAN (FD) frames over a byte stream (SLIP + CRC-16), the framing of
 * the Cortex-M7 image's UART link and mdcan bridge (docs/pil.md). Runs on the
 * host and on the target. */
#include <string.h>

#include "md_link.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static const uint8_t FD_LENGTHS[] = {0u, 1u, 7u, 8u, 12u, 16u, 20u, 24u, 32u, 48u, 64u};

static md_frame_t make_frame(uint32_t id, uint8_t len, uint8_t flags, uint8_t seed)
{
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = len;
    f.flags = flags;
    for (uint8_t i = 0u; i < len; ++i) {
        f.data[i] = (uint8_t)(seed + 37u * i); /* hits 0xC0 and 0xDB for some seeds */
    }
    return f;
}

/* Feeds n bytes; returns the number of frames decoded, the last in *out. */
static unsigned feed(md_link_decoder_t *d, const uint8_t *p, size_t n, md_frame_t *out, int *last_error)
{
    unsigned frames = 0u;
    for (size_t i = 0u; i < n; ++i) {
        const md_link_result_t r = md_link_decode_byte(d, p[i], out);
        if (r == MD_LINK_FRAME) {
            frames++;
        } else if (r != MD_LINK_NONE && last_error != NULL) {
            *last_error = (int)r;
        }
    }
    return frames;
}

static void test_crc_check_value(void)
{
    const uint8_t s[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
    TEST_ASSERT_EQUAL_HEX16(0x29B1u, md_link_crc16(s, sizeof s)); /* CRC-16/CCITT-FALSE */
    TEST_ASSERT_EQUAL_HEX16(0xFFFFu, md_link_crc16(s, 0u));
}

static void test_round_trip_every_length_and_kind(void)
{
    static md_link_decoder_t d;
    md_link_decoder_init(&d);
    for (unsigned seed = 0u; seed < 8u; ++seed) {
        for (size_t k = 0u; k < sizeof FD_LENGTHS; ++k) {
            const uint8_t len = FD_LENGTHS[k];
            const uint8_t flags = (len > 8u || seed % 2u == 1u) ? (uint8_t)(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_BRS) : 0u;
            const uint32_t id = (seed % 3u == 2u) ? 0x1ABCDEC0u : 0x4C0u + seed;
            const uint8_t ext = (seed % 3u == 2u) ? MD_FRAME_FLAG_EXT : 0u;
            const md_frame_t f = make_frame(id, len, (uint8_t)(flags | ext), (uint8_t)(0xB0u + 11u * seed));
            uint8_t buf[MD_LINK_ENCODED_MAX];
            const size_t n = md_link_encode(&f, buf, sizeof buf);
            TEST_ASSERT_TRUE(n >= MD_LINK_HEADER_BYTES + len + MD_LINK_CRC_BYTES + 2u);
            TEST_ASSERT_TRUE(n <= MD_LINK_ENCODED_MAX);
            TEST_ASSERT_EQUAL_HEX8(MD_LINK_END, buf[0]);
            TEST_ASSERT_EQUAL_HEX8(MD_LINK_END, buf[n - 1u]);
            for (size_t i = 1u; i + 1u < n; ++i) {
                TEST_ASSERT_NOT_EQUAL(MD_LINK_END, buf[i]); /* stuffed */
            }
            md_frame_t out;
            memset(&out, 0xEE, sizeof out);
            TEST_ASSERT_EQUAL_UINT(1u, feed(&d, buf, n, &out, NULL));
            TEST_ASSERT_EQUAL_HEX32(f.id, out.id);
            TEST_ASSERT_EQUAL_UINT8(f.len, out.len);
            TEST_ASSERT_EQUAL_HEX8(f.flags, out.flags);
            if (len > 0u) {
                TEST_ASSERT_EQUAL_HEX8_ARRAY(f.data, out.data, len);
            }
        }
    }
    TEST_ASSERT_EQUAL_UINT32(8u * sizeof FD_LENGTHS, d.frames);
    TEST_ASSERT_EQUAL_UINT32(0u, d.bad_crc + d.bad_frame + d.bad_esc + d.too_long);
}

static void test_encode_refuses_invalid_frames_and_small_buffers(void)
{
    uint8_t buf[MD_LINK_ENCODED_MAX];
    md_frame_t f = make_frame(0x800u, 2u, 0u, 1u); /* 12-bit id without EXT */
    TEST_ASSERT_EQUAL_UINT(0u, md_link_encode(&f, buf, sizeof buf));
    f = make_frame(0x10u, 12u, 0u, 1u); /* FD length on a classic frame */
    TEST_ASSERT_EQUAL_UINT(0u, md_link_encode(&f, buf, sizeof buf));
    f = make_frame(0x10u, 64u, MD_FRAME_FLAG_FD, 1u);
    TEST_ASSERT_EQUAL_UINT(0u, md_link_encode(&f, buf, 20u));
    TEST_ASSERT_EQUAL_UINT(0u, md_link_encode(NULL, buf, sizeof buf));
    TEST_ASSERT_EQUAL_UINT(0u, md_link_encode(&f, NULL, sizeof buf));
}

static void test_corruption_is_dropped_counted_and_resynchronised(void)
{
    static md_link_decoder_t d;
    md_link_decoder_init(&d);
    const md_frame_t f = make_frame(0x400u, 64u, MD_FRAME_FLAG_FD, 3u);
    uint8_t buf[MD_LINK_ENCODED_MAX];
    const size_t n = md_link_encode(&f, buf, sizeof buf);
    md_frame_t out;
    int err = 0;

    /* one flipped data bit: CRC */
    uint8_t bad[MD_LINK_ENCODED_MAX];
    memcpy(bad, buf, n);
    bad[20] ^= 0x01u;
    if (bad[20] == MD_LINK_END || bad[20] == MD_LINK_ESC) {
        bad[20] ^= 0x03u;
    }
    TEST_ASSERT_EQUAL_UINT(0u, feed(&d, bad, n, &out, &err));
    TEST_ASSERT_EQUAL_INT(MD_LINK_BAD_CRC, err);
    TEST_ASSERT_EQUAL_UINT32(1u, d.bad_crc);

    /* an escape followed by neither 0xDC nor 0xDD */
    const uint8_t esc[] = {MD_LINK_END, 0x01u, MD_LINK_ESC, 0x00u, 0x02u, MD_LINK_END};
    TEST_ASSERT_EQUAL_UINT(0u, feed(&d, esc, sizeof esc, &out, &err));
    TEST_ASSERT_EQUAL_INT(MD_LINK_BAD_ESC, err);
    TEST_ASSERT_EQUAL_UINT32(1u, d.bad_esc);

    /* a packet longer than any frame: dropped up to the next END */
    uint8_t lng[MD_LINK_PACKET_MAX + 10u];
    memset(lng, 0x11, sizeof lng);
    TEST_ASSERT_EQUAL_UINT(0u, feed(&d, lng, sizeof lng, &out, &err));
    TEST_ASSERT_EQUAL_INT(MD_LINK_TOO_LONG, err);
    TEST_ASSERT_EQUAL_UINT32(1u, d.too_long);

    /* a short packet, and one whose length byte disagrees with its size */
    const uint8_t shortp[] = {MD_LINK_END, 0x00u, 0x00u, 0x01u, MD_LINK_END};
    TEST_ASSERT_EQUAL_UINT(0u, feed(&d, shortp, sizeof shortp, &out, &err));
    TEST_ASSERT_EQUAL_INT(MD_LINK_BAD_FRAME, err);
    TEST_ASSERT_EQUAL_UINT32(1u, d.bad_frame);

    /* after all that (and empty packets) the next good frame decodes */
    const uint8_t empty[] = {MD_LINK_END, MD_LINK_END, MD_LINK_END};
    TEST_ASSERT_EQUAL_UINT(0u, feed(&d, empty, sizeof empty, &out, NULL));
    TEST_ASSERT_EQUAL_UINT(1u, feed(&d, buf, n, &out, NULL));
    TEST_ASSERT_EQUAL_HEX8_ARRAY(f.data, out.data, 64u);

    /* joining mid-packet: the tail of one frame, then a whole one */
    TEST_ASSERT_EQUAL_UINT(1u, feed(&d, &buf[n / 2u], n - n / 2u, &out, &err) + feed(&d, buf, n, &out, NULL));
    TEST_ASSERT_EQUAL_HEX32(0x400u, out.id);
}

static void test_null_arguments(void)
{
    md_frame_t out;
    TEST_ASSERT_EQUAL_INT(MD_LINK_NONE, md_link_decode_byte(NULL, MD_LINK_END, &out));
    static md_link_decoder_t d;
    md_link_decoder_init(&d);
    TEST_ASSERT_EQUAL_INT(MD_LINK_NONE, md_link_decode_byte(&d, MD_LINK_END, NULL));
    md_link_decoder_init(NULL); /* no effect */
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_crc_check_value);
    RUN_TEST(test_round_trip_every_length_and_kind);
    RUN_TEST(test_encode_refuses_invalid_frames_and_small_buffers);
    RUN_TEST(test_corruption_is_dropped_counted_and_resynchronised);
    RUN_TEST(test_null_arguments);
    return UNITY_END();
}

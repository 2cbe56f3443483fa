/// Host tests of can-utils frame syntax (common/bus/md_bus_text.h): what
/// cansend accepts and candump -L prints.
#include <errno.h>
#include <string.h>

#include "md_bus_text.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static md_frame_t parse_ok(const char *text)
{
    md_frame_t f;
    const char *why = "";
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, md_bus_text_parse(text, &f, &why), why);
    return f;
}

static void assert_formats_as(const char *expected, const md_frame_t *f)
{
    char out[MD_BUS_TEXT_MAX];
    TEST_ASSERT_EQUAL_INT((int)strlen(expected), md_bus_text_format(f, out, sizeof out));
    TEST_ASSERT_EQUAL_STRING(expected, out);
}

static void test_classic_standard_and_extended(void)
{
    md_frame_t f = parse_ok("123#DEADBEEF");
    TEST_ASSERT_EQUAL_HEX32(0x123, f.id);
    TEST_ASSERT_EQUAL_UINT8(4, f.len);
    TEST_ASSERT_EQUAL_UINT8(0, f.flags);
    TEST_ASSERT_EQUAL_HEX8(0xDE, f.data[0]);
    TEST_ASSERT_EQUAL_HEX8(0xEF, f.data[3]);
    assert_formats_as("123#DEADBEEF", &f);

    f = parse_ok("1abcdef0#00.11.22");
    TEST_ASSERT_EQUAL_HEX32(0x1ABCDEF0, f.id);
    TEST_ASSERT_EQUAL_UINT8(MD_FRAME_FLAG_EXT, f.flags);
    TEST_ASSERT_EQUAL_UINT8(3, f.len);
    assert_formats_as("1ABCDEF0#001122", &f);

    f = parse_ok("00000005#");  // 8 digits: extended even when small
    TEST_ASSERT_EQUAL_UINT8(MD_FRAME_FLAG_EXT, f.flags);
    TEST_ASSERT_EQUAL_UINT8(0, f.len);
    assert_formats_as("00000005#", &f);

    f = parse_ok("7FF#0102030405060708");
    TEST_ASSERT_EQUAL_UINT8(8, f.len);
    assert_formats_as("7FF#0102030405060708", &f);
}

static void test_fd_frames_with_flags_and_padding(void)
{
    md_frame_t f = parse_ok("123##1112233");
    TEST_ASSERT_EQUAL_UINT8(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_BRS, f.flags);
    TEST_ASSERT_EQUAL_UINT8(3, f.len);
    assert_formats_as("123##5112233", &f);  // FDF (4) added, as candump prints it

    // 9 bytes is no FD length: padded with zeros to 12, like cansend.
    f = parse_ok("1FFFFFFF##0010203040506070809");
    TEST_ASSERT_EQUAL_UINT8(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_EXT, f.flags);
    TEST_ASSERT_EQUAL_UINT8(12, f.len);
    TEST_ASSERT_EQUAL_HEX8(0x09, f.data[8]);
    TEST_ASSERT_EQUAL_HEX8(0x00, f.data[11]);
    assert_formats_as("1FFFFFFF##4010203040506070809000000", &f);

    char text[8 + 3 + 128 + 1] = "0000ABCD##4";
    for (size_t i = 0; i < 64u; ++i) {
        text[11 + 2 * i] = "0123456789ABCDEF"[i >> 4];
        text[12 + 2 * i] = "0123456789ABCDEF"[i & 0xFu];
    }
    text[11 + 128] = '\0';
    f = parse_ok(text);
    TEST_ASSERT_EQUAL_UINT8(64, f.len);
    TEST_ASSERT_EQUAL_HEX8(63, f.data[63]);
    assert_formats_as(text, &f);
}

static void test_fd_flag_nibble_takes_brs_and_ignores_esi_fdf(void)
{
    TEST_ASSERT_EQUAL_UINT8(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_BRS, parse_ok("123##501").flags);
    TEST_ASSERT_EQUAL_UINT8(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_BRS, parse_ok("123##F01").flags);
    TEST_ASSERT_EQUAL_UINT8(MD_FRAME_FLAG_FD, parse_ok("123##601").flags);
    TEST_ASSERT_EQUAL_UINT8(MD_FRAME_FLAG_FD, parse_ok("123##001").flags);
}

static void test_refused_syntax_says_why(void)
{
    static const char *const bad[] = {
        "",                         // nothing
        "123",                      // no '#'
        "12#00",                    // 2-digit id
        "1234#00",                  // 4-digit id
        "800#00",                   // 11-bit id out of range
        "20000000#00",              // 29-bit id out of range
        "12G#00",                   // not hex
        "123#ABC",                  // odd digits
        "123#0011223344556677889",  // classic > 8 bytes (and odd)
        "123#001122334455667788",   // classic > 8 bytes
        "123#R",                    // RTR
        "123##",                    // FD without flag digit
        "123##G00",                 // bad flag digit
        "123#00 11",                // space
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        md_frame_t f;
        const char *why = NULL;
        TEST_ASSERT_EQUAL_INT_MESSAGE(-EINVAL, md_bus_text_parse(bad[i], &f, &why), bad[i]);
        TEST_ASSERT_TRUE_MESSAGE(why != NULL, bad[i]);
    }
    md_frame_t f;
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_text_parse(NULL, &f, NULL));
    // 65 FD bytes
    char text[3 + 3 + 130 + 1] = "123##0";
    memset(&text[6], 'A', 130);
    text[136] = '\0';
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_text_parse(text, &f, NULL));
}

static void test_format_refuses_invalid_frames_and_small_buffers(void)
{
    md_frame_t f = parse_ok("123#DEADBEEF");
    char out[MD_BUS_TEXT_MAX];
    TEST_ASSERT_EQUAL_INT(-ENOSPC, md_bus_text_format(&f, out, 12));  // needs 13 with NUL
    TEST_ASSERT_EQUAL_INT(12, md_bus_text_format(&f, out, 13));
    f.len = 9;
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_text_format(&f, out, sizeof out));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_classic_standard_and_extended);
    RUN_TEST(test_fd_frames_with_flags_and_padding);
    RUN_TEST(test_fd_flag_nibble_takes_brs_and_ignores_esi_fdf);
    RUN_TEST(test_refused_syntax_says_why);
    RUN_TEST(test_format_refuses_invalid_frames_and_small_buffers);
    return UNITY_END();
}

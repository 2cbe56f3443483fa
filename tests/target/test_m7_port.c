/* Target-only: the Cortex-M7 stub port counts what it sends, refuses what a
 * CAN controller could not send, and its clock is monotonic and ticking. */
#include <stddef.h>
#include <string.h>

#include "md_port_m7.h"
#include "unity.h"

static md_port_m7_ctx_t ctx;
static md_port_t port;

void setUp(void)
{
    TEST_ASSERT_EQUAL_INT(MD_OK, md_port_m7_init(&port, &ctx));
}
void tearDown(void) {}

static void test_init_rejects_null(void)
{
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_port_m7_init(NULL, &ctx));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_port_m7_init(&port, NULL));
}

static void test_send_counts_valid_frames(void)
{
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = 0x123u;
    f.len = 2u;
    f.data[0] = 0xAAu;
    for (unsigned i = 0u; i < 5u; ++i) {
        TEST_ASSERT_EQUAL_INT(MD_OK, port.send(port.ctx, &f));
    }
    TEST_ASSERT_EQUAL_UINT32(5u, ctx.frames_sent);
    TEST_ASSERT_EQUAL_UINT32(0u, ctx.frames_refused);
    TEST_ASSERT_EQUAL_MEMORY(&f, &ctx.last_frame, sizeof f);
}

static void test_send_refuses_invalid_frames(void)
{
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = 0x800u; /* 12 bits without the extended flag */
    TEST_ASSERT_EQUAL_INT(MD_E_IO, port.send(port.ctx, &f));
    f.id = 0x10u;
    f.len = 12u; /* FD length on a classic frame */
    TEST_ASSERT_EQUAL_INT(MD_E_IO, port.send(port.ctx, &f));
    TEST_ASSERT_EQUAL_INT(MD_E_IO, port.send(port.ctx, NULL));
    TEST_ASSERT_EQUAL_UINT32(0u, ctx.frames_sent);
    TEST_ASSERT_EQUAL_UINT32(3u, ctx.frames_refused);
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, port.send(NULL, &f));
}

static void test_receive_stub_has_nothing(void)
{
    md_frame_t f;
    TEST_ASSERT_FALSE(md_port_m7_receive(&ctx, &f));
    TEST_ASSERT_FALSE(md_port_m7_receive(&ctx, NULL));
    TEST_ASSERT_FALSE(md_port_m7_receive(NULL, &f));
    TEST_ASSERT_EQUAL_UINT32(0u, ctx.frames_received);
}

static void test_clock_is_monotonic_and_ticks(void)
{
    md_port_m7_clock_start();
    uint64_t prev = port.now_us(port.ctx);
    for (unsigned i = 0u; i < 5u; ++i) {
        __asm__ volatile("wfi"); /* wakes on the next 1 ms SysTick */
        const uint64_t now = port.now_us(port.ctx);
        TEST_ASSERT_TRUE(now > prev);
        prev = now;
    }
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(4000u, prev);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_init_rejects_null);
    RUN_TEST(test_send_counts_valid_frames);
    RUN_TEST(test_send_refuses_invalid_frames);
    RUN_TEST(test_receive_stub_has_nothing);
    RUN_TEST(test_clock_is_monotonic_and_ticks);
    return UNITY_END();
}

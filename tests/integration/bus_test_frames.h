/// @file bus_test_frames.h
/// Frame helpers shared by the socket-bus integration tests. The including
/// file defines ARRIVE_US (longest wait for an expected frame),
/// ABSENT_US (silence that means "not sent") and BUS_TEST_PATTERN (the odd
/// multiplier of its payload pattern) before including this header, and calls
/// bus_test_reset() from setUp and bus_test_close_all() from tearDown.
#ifndef BUS_TEST_FRAMES_H
#define BUS_TEST_FRAMES_H

#include <string.h>

#include "md_bus.h"
#include "unity.h"

/// The endpoints of the running test. Tests take theirs from here, not from
/// their own stack, so that tearDown can close every one even when a failed
/// assertion ended the test before its own md_bus_close calls.
static md_bus_t bus_ep[3];

/// Marks every endpoint "not opened" (setUp).
static void bus_test_reset(void)
{
    memset(bus_ep, 0, sizeof bus_ep);
}

/// Closes every endpoint opened since bus_test_reset (tearDown); closing one
/// the test already closed is harmless.
static void bus_test_close_all(void)
{
    for (size_t i = 0; i < sizeof bus_ep / sizeof bus_ep[0]; ++i) {
        if (bus_ep[i].ops != NULL) {  // NULL: not passed to md_bus_open in this test
            md_bus_close(&bus_ep[i]);
        }
    }
}

/// A frame whose payload is a pattern of `seed`, so each test frame is distinct.
static md_frame_t make_frame(uint32_t id, uint8_t len, uint8_t flags, uint8_t seed)
{
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = len;
    f.flags = flags;
    for (uint8_t i = 0; i < len; ++i) {
        f.data[i] = (uint8_t)(seed ^ (i * BUS_TEST_PATTERN));
    }
    return f;
}

/// The next frame on `bus` is `e`, field for field, within ARRIVE_US.
static void expect_frame(md_bus_t *bus, const md_frame_t *e)
{
    md_frame_t r;
    TEST_ASSERT_EQUAL_INT(1, md_bus_receive(bus, &r, ARRIVE_US));
    TEST_ASSERT_EQUAL_UINT32(e->id, r.id);
    TEST_ASSERT_EQUAL_UINT8(e->len, r.len);
    TEST_ASSERT_EQUAL_UINT8(e->flags, r.flags);
    if (e->len > 0u) {  // Unity refuses to compare zero bytes; the lengths matched above
        TEST_ASSERT_EQUAL_MEMORY(e->data, r.data, e->len);
    }
}

/// Nothing arrives on `bus` for ABSENT_US.
static void expect_nothing(md_bus_t *bus)
{
    md_frame_t r;
    TEST_ASSERT_EQUAL_INT(0, md_bus_receive(bus, &r, ABSENT_US));
}

#endif

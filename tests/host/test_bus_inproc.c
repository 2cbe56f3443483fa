/// Host tests of the in-process bus and of md_bus_open's spec parsing (the
/// parts that open no socket). The UDP bus is tested in tests/integration
/// inside a private network namespace.
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "md_bus.h"
#include "unity.h"

/* The endpoints of the running test. They are static and tearDown closes
 * every one that was opened: a failed assertion ends its test before the
 * test's own md_bus_close calls, and an endpoint left open would hold a slot
 * of the process-wide in-process tables for every later test. */
static md_bus_t ep[MD_BUS_INPROC_MAX_ENDPOINTS + 1u];

void setUp(void)
{
    memset(ep, 0, sizeof ep);
}

void tearDown(void)
{
    for (size_t i = 0; i < sizeof ep / sizeof ep[0]; ++i) {
        if (ep[i].ops != NULL) {  // NULL: not passed to md_bus_open in this test
            md_bus_close(&ep[i]);
        }
    }
}

static md_frame_t make_frame(uint32_t id, uint8_t len, uint8_t flags, uint8_t seed)
{
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = len;
    f.flags = flags;
    for (uint8_t i = 0; i < len && i < MD_FRAME_MAX_DATA; ++i) {  // len may be deliberately invalid
        f.data[i] = (uint8_t)(seed + 7u * i);
    }
    return f;
}

static void assert_frame_equal(const md_frame_t *e, const md_frame_t *a)
{
    TEST_ASSERT_EQUAL_UINT32(e->id, a->id);
    TEST_ASSERT_EQUAL_UINT8(e->len, a->len);
    TEST_ASSERT_EQUAL_UINT8(e->flags, a->flags);
    if (e->len > 0u) {  // Unity refuses to compare zero bytes; the lengths matched above
        TEST_ASSERT_EQUAL_MEMORY(e->data, a->data, e->len);
    }
}

static void open_ok(md_bus_t *bus, const char *spec)
{
    char why[160] = "";
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, md_bus_open(bus, spec, why, sizeof why), why);
    TEST_ASSERT_EQUAL_INT(MD_BUS_INPROC, bus->kind);
    TEST_ASSERT_EQUAL_INT(-1, md_bus_fd(bus));
}

static void test_fan_out_to_every_other_endpoint_without_echo(void)
{
    md_bus_t *const a = &ep[0], *const b = &ep[1], *const c = &ep[2];
    open_ok(a, "inproc:fan");
    open_ok(b, "inproc:fan");
    open_ok(c, "inproc:fan");
    TEST_ASSERT_EQUAL_STRING("inproc:fan", a->name);
    const md_frame_t f = make_frame(0x123, 8, 0, 1);
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &f));
    md_frame_t r;
    TEST_ASSERT_EQUAL_INT(1, md_bus_receive(b, &r, 0));
    assert_frame_equal(&f, &r);
    TEST_ASSERT_EQUAL_INT(1, md_bus_receive(c, &r, 0));
    assert_frame_equal(&f, &r);
    TEST_ASSERT_EQUAL_INT(0, md_bus_receive(a, &r, 0));  // no echo
    TEST_ASSERT_EQUAL_INT(0, md_bus_receive(b, &r, 0));  // exactly once
    TEST_ASSERT_EQUAL_UINT64(1, a->stats.tx_frames);
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.rx_frames);
    TEST_ASSERT_EQUAL_UINT64(1, b->stats.rx_frames);
    md_bus_close(a);
    md_bus_close(b);
    md_bus_close(c);
}

static void test_buses_with_other_names_are_isolated(void)
{
    md_bus_t *const a = &ep[0], *const b = &ep[1], *const x = &ep[2];
    open_ok(a, "inproc:one");
    open_ok(b, "inproc:one");
    open_ok(x, "inproc:two");
    const md_frame_t f = make_frame(0x10, 1, 0, 9);
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &f));
    md_frame_t r;
    TEST_ASSERT_EQUAL_INT(0, md_bus_receive(x, &r, 0));
    TEST_ASSERT_EQUAL_INT(1, md_bus_receive(b, &r, 0));
    md_bus_close(a);
    md_bus_close(b);
    md_bus_close(x);
}

static void test_frames_arrive_in_send_order_across_senders(void)
{
    md_bus_t *const a = &ep[0], *const b = &ep[1], *const c = &ep[2];
    open_ok(a, "inproc:order");
    open_ok(b, "inproc:order");
    open_ok(c, "inproc:order");
    // a and b interleave; c must see the global send order, a and b each
    // other's frames in order.
    for (uint32_t i = 0; i < 200u; ++i) {
        const md_frame_t f = make_frame(i, (uint8_t)(i % 9u), 0, (uint8_t)i);
        TEST_ASSERT_EQUAL_INT(0, md_bus_send((i % 2u) == 0u ? a : b, &f));
    }
    md_frame_t r;
    for (uint32_t i = 0; i < 200u; ++i) {
        TEST_ASSERT_EQUAL_INT(1, md_bus_receive(c, &r, 0));
        TEST_ASSERT_EQUAL_UINT32(i, r.id);
        const md_frame_t e = make_frame(i, (uint8_t)(i % 9u), 0, (uint8_t)i);
        assert_frame_equal(&e, &r);
    }
    for (uint32_t i = 1; i < 200u; i += 2u) {
        TEST_ASSERT_EQUAL_INT(1, md_bus_receive(a, &r, 0));
        TEST_ASSERT_EQUAL_UINT32(i, r.id);
    }
    for (uint32_t i = 0; i < 200u; i += 2u) {
        TEST_ASSERT_EQUAL_INT(1, md_bus_receive(b, &r, 0));
        TEST_ASSERT_EQUAL_UINT32(i, r.id);
    }
    TEST_ASSERT_EQUAL_INT(0, md_bus_receive(c, &r, 0));
    md_bus_close(a);
    md_bus_close(b);
    md_bus_close(c);
}

static void test_fd_and_extended_frames_keep_flags_and_data(void)
{
    md_bus_t *const a = &ep[0], *const b = &ep[1];
    open_ok(a, "inproc:fd");
    open_ok(b, "inproc:fd");
    const uint8_t fd_lens[] = {0, 8, 12, 16, 20, 24, 32, 48, 64};
    for (size_t i = 0; i < sizeof fd_lens; ++i) {
        const uint8_t flags = (uint8_t)(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_EXT | MD_FRAME_FLAG_BRS);
        const md_frame_t f = make_frame(0x1FFFFFFFu - (uint32_t)i, fd_lens[i], flags, (uint8_t)(i * 31u));
        TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &f));
        md_frame_t r;
        TEST_ASSERT_EQUAL_INT(1, md_bus_receive(b, &r, 0));
        assert_frame_equal(&f, &r);
    }
    md_bus_close(a);
    md_bus_close(b);
}

static void test_overflow_is_counted_at_the_receiver_and_send_succeeds(void)
{
    md_bus_t *const a = &ep[0], *const b = &ep[1], *const c = &ep[2];
    open_ok(a, "inproc:ovf");
    open_ok(b, "inproc:ovf");
    open_ok(c, "inproc:ovf");
    const uint32_t extra = 5;
    for (uint32_t i = 0; i < MD_BUS_INPROC_QUEUE_LEN + extra; ++i) {
        const md_frame_t f = make_frame(i & 0x7FFu, 2, 0, (uint8_t)i);
        TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &f));
        md_frame_t r;  // c keeps up, b does not read at all
        TEST_ASSERT_EQUAL_INT(1, md_bus_receive(c, &r, 0));
        TEST_ASSERT_EQUAL_UINT32(i & 0x7FFu, r.id);
    }
    TEST_ASSERT_EQUAL_UINT64(MD_BUS_INPROC_QUEUE_LEN + extra, a->stats.tx_frames);
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.tx_errors);
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.rx_overflow);
    TEST_ASSERT_EQUAL_UINT64(extra, b->stats.rx_overflow);
    TEST_ASSERT_EQUAL_UINT64(0, c->stats.rx_overflow);
    // b kept the oldest frames: the first QUEUE_LEN, in order.
    md_frame_t r;
    for (uint32_t i = 0; i < MD_BUS_INPROC_QUEUE_LEN; ++i) {
        TEST_ASSERT_EQUAL_INT(1, md_bus_receive(b, &r, 0));
        TEST_ASSERT_EQUAL_UINT32(i & 0x7FFu, r.id);
    }
    TEST_ASSERT_EQUAL_INT(0, md_bus_receive(b, &r, 0));
    md_bus_close(a);
    md_bus_close(b);
    md_bus_close(c);
}

static void test_invalid_frames_are_refused_on_send_and_counted(void)
{
    md_bus_t *const a = &ep[0], *const b = &ep[1];
    open_ok(a, "inproc:bad");
    open_ok(b, "inproc:bad");
    const md_frame_t bad[] = {
        make_frame(0x800, 1, 0, 0),                        // std id too large
        make_frame(0x20000000u, 1, MD_FRAME_FLAG_EXT, 0),  // ext id too large
        make_frame(0x100, 9, 0, 0),                        // classic len > 8
        make_frame(0x100, 13, MD_FRAME_FLAG_FD, 0),        // not an FD length
        make_frame(0x100, 65, MD_FRAME_FLAG_FD, 0),        // beyond FD
        make_frame(0x100, 1, 0x08, 0),                     // unknown flag
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_send(a, &bad[i]));
    }
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_send(a, NULL));
    TEST_ASSERT_EQUAL_UINT64(sizeof bad / sizeof bad[0] + 1u, a->stats.tx_errors);
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.tx_frames);
    md_frame_t r;
    TEST_ASSERT_EQUAL_INT(0, md_bus_receive(b, &r, 0));
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_receive(b, &r, -1));
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_receive(b, NULL, 0));
    md_bus_close(a);
    md_bus_close(b);
}

static void test_closed_bus_returns_ebadf_and_stops_receiving(void)
{
    md_bus_t *const a = &ep[0], *const b = &ep[1];
    open_ok(a, "inproc:close");
    open_ok(b, "inproc:close");
    md_bus_close(b);
    md_bus_close(b);  // twice is harmless
    const md_frame_t f = make_frame(1, 0, 0, 0);
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &f));  // nobody else left: still fine
    md_frame_t r;
    TEST_ASSERT_EQUAL_INT(-EBADF, md_bus_receive(b, &r, 0));
    TEST_ASSERT_EQUAL_INT(-EBADF, md_bus_send(b, &f));
    TEST_ASSERT_EQUAL_INT(-1, md_bus_fd(b));
    TEST_ASSERT_EQUAL_UINT64(0, b->stats.rx_overflow);
    // A new endpoint on the same name starts empty.
    open_ok(b, "inproc:close");
    TEST_ASSERT_EQUAL_INT(0, md_bus_receive(b, &r, 0));
    md_bus_close(a);
    md_bus_close(b);
}

static void test_capacity_limits_are_reported_and_freed_on_close(void)
{
    char why[160] = "";
    for (uint32_t i = 0; i < MD_BUS_INPROC_MAX_ENDPOINTS; ++i) {
        open_ok(&ep[i], "inproc:cap");
    }
    TEST_ASSERT_EQUAL_INT(-ENOSPC, md_bus_open(&ep[MD_BUS_INPROC_MAX_ENDPOINTS], "inproc:cap", why, sizeof why));
    TEST_ASSERT_TRUE(strstr(why, "endpoints") != NULL);
    TEST_ASSERT_EQUAL_INT(-EBADF, md_bus_receive(&ep[MD_BUS_INPROC_MAX_ENDPOINTS], &(md_frame_t){0}, 0));
    for (uint32_t i = 0; i < MD_BUS_INPROC_MAX_ENDPOINTS; ++i) {
        md_bus_close(&ep[i]);
    }
    // Distinct names: MAX_BUSES fit, one more does not.
    char spec[32];
    for (uint32_t i = 0; i <= MD_BUS_INPROC_MAX_BUSES; ++i) {
        (void)snprintf(spec, sizeof spec, "inproc:bus%u", (unsigned)i);
        const int rc = md_bus_open(&ep[i], spec, why, sizeof why);
        TEST_ASSERT_EQUAL_INT(i < MD_BUS_INPROC_MAX_BUSES ? 0 : -ENOSPC, rc);
    }
    TEST_ASSERT_TRUE(strstr(why, "buses") != NULL);
    for (uint32_t i = 0; i < MD_BUS_INPROC_MAX_BUSES; ++i) {
        md_bus_close(&ep[i]);
    }
    open_ok(&ep[0], "inproc:again");
    md_bus_close(&ep[0]);
}

static void test_bad_specs_fail_with_a_message(void)
{
    static const struct {
        const char *spec;
        int rc;
    } cases[] = {
        {"", -EINVAL},
        {"udp:", -EINVAL},
        {"udp:0", -EINVAL},
        {"udp:65536", -EINVAL},
        {"udp:12a", -EINVAL},
        {"udp:-1", -EINVAL},
        {"inproc:", -EINVAL},
        {"inproc:aaaaaaaaaaaaaaaaaaaaaaaaa", -ENAMETOOLONG},  // 25 > MD_BUS_INPROC_NAME_MAX
        {"tcp:1234", -EINVAL},
        {"has space", -EINVAL},
        {"an_interface_name_too_long", -ENAMETOOLONG},
    };
    md_bus_t *const bus = &ep[0];
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        char why[160] = "";
        TEST_ASSERT_EQUAL_INT_MESSAGE(cases[i].rc, md_bus_open(bus, cases[i].spec, why, sizeof why), cases[i].spec);
        TEST_ASSERT_TRUE_MESSAGE(why[0] != '\0', cases[i].spec);
        TEST_ASSERT_EQUAL_INT(-EBADF, md_bus_send(bus, &(md_frame_t){0}));
        md_bus_close(bus);
    }
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_open(bus, NULL, NULL, 0));  // why may be NULL
}

static void test_socketcan_spec_errors_are_clear(void)
{
    // Our host kernel has no AF_CAN; a VM with vcan0 does. Either way an
    // interface that does not exist must fail cleanly with a message.
    char why[200] = "";
    const int rc = md_bus_open(&ep[0], "nocan7", why, sizeof why);
    TEST_ASSERT_TRUE_MESSAGE(rc == -EAFNOSUPPORT || rc == -ENODEV, why);
    TEST_ASSERT_TRUE_MESSAGE(strstr(why, rc == -EAFNOSUPPORT ? "AF_CAN" : "nocan7") != NULL, why);
    TEST_MESSAGE(why);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_fan_out_to_every_other_endpoint_without_echo);
    RUN_TEST(test_buses_with_other_names_are_isolated);
    RUN_TEST(test_frames_arrive_in_send_order_across_senders);
    RUN_TEST(test_fd_and_extended_frames_keep_flags_and_data);
    RUN_TEST(test_overflow_is_counted_at_the_receiver_and_send_succeeds);
    RUN_TEST(test_invalid_frames_are_refused_on_send_and_counted);
    RUN_TEST(test_closed_bus_returns_ebadf_and_stops_receiving);
    RUN_TEST(test_capacity_limits_are_reported_and_freed_on_close);
    RUN_TEST(test_bad_specs_fail_with_a_message);
    RUN_TEST(test_socketcan_spec_errors_are_clear);
    return UNITY_END();
}

/// Tests of the SocketCAN bus on a real vcan0 (CAN FD, mtu 72). Needs AF_CAN,
/// root and can-utils, so it runs under scripts/with-vcan.sh (a throwaway VM
/// when the host kernel has no SocketCAN):
///   scripts/with-vcan.sh <build>/bin/test_bus_socketcan
/// Besides our own endpoints talking, it checks interoperability with
/// can-utils both ways (cansend -> md_bus, md_bus -> candump -L).
#define _GNU_SOURCE
#include <errno.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "md_bus.h"
#include "md_bus_text.h"
#include "unity.h"

#define ARRIVE_US 2000000
#define ABSENT_US 50000
#define BUS_TEST_PATTERN 37u
#include "bus_test_frames.h"

/* Set once the test may have created its own interface vcan8: tearDown
 * deletes it if a failed assertion ended the test first. */
static bool vcan8_added;

void setUp(void)
{
    bus_test_reset();
}

void tearDown(void)
{
    bus_test_close_all();
    if (vcan8_added) {
        (void)system("ip link del dev vcan8");
        vcan8_added = false;
    }
}

static void open_can(md_bus_t *bus, const char *spec)
{
    char why[200] = "";
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, md_bus_open(bus, spec, why, sizeof why), why);
    TEST_ASSERT_EQUAL_INT(MD_BUS_SOCKETCAN, bus->kind);
}

static void run(const char *cmd)
{
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, system(cmd), cmd);
}

static void test_vcan0_opens_as_can_fd_and_auto_picks_it(void)
{
    md_bus_t *const bus = &bus_ep[0];
    char why[200] = "";
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, md_bus_open(bus, "vcan0", why, sizeof why), why);
    TEST_MESSAGE(why);
    TEST_ASSERT_TRUE(strstr(why, "CAN FD") != NULL);
    TEST_ASSERT_EQUAL_STRING("vcan0", bus->name);
    TEST_ASSERT_TRUE(md_bus_fd(bus) >= 0);
    md_bus_close(bus);
    TEST_ASSERT_EQUAL_INT(0, md_bus_open(bus, "auto", why, sizeof why));
    TEST_MESSAGE(why);
    TEST_ASSERT_EQUAL_INT(MD_BUS_SOCKETCAN, bus->kind);
    TEST_ASSERT_TRUE(strstr(why, "vcan0") != NULL);
    md_bus_close(bus);
}

static void test_three_endpoints_exchange_frames_without_echo(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_can(a, "vcan0");
    md_bus_t *const b = &bus_ep[1];
    open_can(b, "vcan0");
    md_bus_t *const c = &bus_ep[2];
    open_can(c, "vcan0");
    const md_frame_t classic = make_frame(0x123, 8, 0, 0xDE);
    const md_frame_t ext = make_frame(0x1ABCDE01u, 3, MD_FRAME_FLAG_EXT, 0x11);
    const md_frame_t fd = make_frame(0x0456, 64, (uint8_t)(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_BRS), 0x5A);
    const md_frame_t fd_ext = make_frame(0x1FFFFFFFu, 12, (uint8_t)(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_EXT), 1);
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &classic));
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &ext));
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(c, &fd));
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(b, &fd_ext));
    expect_frame(b, &classic);
    expect_frame(b, &ext);
    expect_frame(b, &fd);
    expect_frame(c, &classic);
    expect_frame(c, &ext);
    expect_frame(c, &fd_ext);
    expect_frame(a, &fd);
    expect_frame(a, &fd_ext);
    expect_nothing(a);
    expect_nothing(b);
    expect_nothing(c);
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.rx_malformed + b->stats.rx_malformed + c->stats.rx_malformed);
    md_bus_close(a);
    md_bus_close(b);
    md_bus_close(c);
}

static void test_many_frames_arrive_in_order(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_can(a, "vcan0");
    md_bus_t *const b = &bus_ep[1];
    open_can(b, "vcan0");
    for (uint32_t i = 0; i < 300u; ++i) {
        const md_frame_t f = make_frame(i, (uint8_t)(i % 9u), 0, (uint8_t)i);
        TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &f));
        if (i % 50u == 49u) {  // keep within vcan's tx queue (txqueuelen)
            for (uint32_t k = i - 49u; k <= i; ++k) {
                const md_frame_t e = make_frame(k, (uint8_t)(k % 9u), 0, (uint8_t)k);
                expect_frame(b, &e);
            }
        }
    }
    expect_nothing(b);
    TEST_ASSERT_EQUAL_UINT64(0, b->stats.rx_overflow);
    md_bus_close(a);
    md_bus_close(b);
}

static void test_cansend_frames_reach_md_bus_and_rtr_is_counted(void)
{
    md_bus_t *const b = &bus_ep[0];
    open_can(b, "vcan0");
    run("cansend vcan0 5A1#11.22.33");
    run("cansend vcan0 123#R");  // RTR: md_frame_t cannot carry it
    run("cansend vcan0 1F334455##1000102030405060708090A0B");
    const md_frame_t e1 = make_frame(0x5A1, 0, 0, 0);
    md_frame_t r;
    TEST_ASSERT_EQUAL_INT(1, md_bus_receive(b, &r, ARRIVE_US));
    TEST_ASSERT_EQUAL_UINT32(e1.id, r.id);
    TEST_ASSERT_EQUAL_UINT8(3, r.len);
    TEST_ASSERT_EQUAL_HEX8(0x33, r.data[2]);
    TEST_ASSERT_EQUAL_INT(1, md_bus_receive(b, &r, ARRIVE_US));
    TEST_ASSERT_EQUAL_UINT32(0x1F334455u, r.id);
    TEST_ASSERT_EQUAL_UINT8(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_EXT | MD_FRAME_FLAG_BRS, r.flags);
    TEST_ASSERT_EQUAL_UINT8(12, r.len);
    TEST_ASSERT_EQUAL_HEX8(0x0B, r.data[11]);
    TEST_ASSERT_EQUAL_UINT64(1, b->stats.rx_malformed);
    expect_nothing(b);
    md_bus_close(b);
}

/// Sends `f` until `candump -L -n 1` (started before) has logged a line, so
/// the test does not depend on how fast candump binds. Returns the frame text.
static void md_bus_to_candump(const md_frame_t *f, char *line, size_t cap)
{
    const char *log = "/tmp/test_bus_socketcan.candump";
    (void)remove(log);
    char cmd[160];
    (void)snprintf(cmd, sizeof cmd, "candump -L -n 1 vcan0 > %s 2>&1 &", log);
    run(cmd);
    md_bus_t *const a = &bus_ep[0];
    open_can(a, "vcan0");
    line[0] = '\0';
    for (unsigned i = 0; i < 200u && line[0] == '\0'; ++i) {
        TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, f));
        const struct timespec ts = {0, 20000000L};
        (void)nanosleep(&ts, NULL);
        FILE *in = fopen(log, "r");
        if (in != NULL) {
            if (fgets(line, (int)cap, in) == NULL) {
                line[0] = '\0';
            }
            (void)fclose(in);
        }
    }
    md_bus_close(a);
    line[strcspn(line, "\n")] = '\0';
    TEST_MESSAGE(line);
}

static void test_md_bus_frames_show_in_candump_as_mdcan_prints_them(void)
{
    const md_frame_t frames[] = {
        make_frame(0x123, 4, 0, 0xDE),
        make_frame(0x1ABCDEF0u, 8, MD_FRAME_FLAG_EXT, 7),
        make_frame(0x321, 16, (uint8_t)(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_BRS), 3),
        make_frame(0x321, 16, MD_FRAME_FLAG_FD, 3),
    };
    for (size_t i = 0; i < sizeof frames / sizeof frames[0]; ++i) {
        char line[256];
        md_bus_to_candump(&frames[i], line, sizeof line);
        char ours[MD_BUS_TEXT_MAX];
        TEST_ASSERT_TRUE(md_bus_text_format(&frames[i], ours, sizeof ours) > 0);
        // "(sec.usec) vcan0 FRAME": compare FRAME. Kernels before 6.1 do not
        // report FDF (4) in the flag nibble; md_frame_t's FD flag implies it.
        const char *theirs = strstr(line, " vcan0 ");
        TEST_ASSERT_NOT_NULL(theirs);
        char norm[MD_BUS_TEXT_MAX + 8];
        (void)snprintf(norm, sizeof norm, "%s", theirs + 7);
        char *dd = strstr(norm, "##");
        if (dd != NULL && dd[2] != '\0') {
            const int nib = dd[2] >= 'A' ? dd[2] - 'A' + 10 : dd[2] - '0';
            dd[2] = "0123456789ABCDEF"[(nib | 4) & 0xF];
        }
        TEST_ASSERT_EQUAL_STRING(ours, norm);
    }
}

static void test_interface_errors_are_clear(void)
{
    md_bus_t *const bus = &bus_ep[0];
    char why[200] = "";
    TEST_ASSERT_EQUAL_INT(-ENODEV, md_bus_open(bus, "vcan77", why, sizeof why));
    TEST_MESSAGE(why);
    TEST_ASSERT_TRUE(strstr(why, "ip link add dev vcan77 type vcan") != NULL);
    const int lo = md_bus_open(bus, "lo", why, sizeof why);  // not a CAN interface
    TEST_MESSAGE(why);
    TEST_ASSERT_TRUE(lo < 0);
    TEST_ASSERT_TRUE(strstr(why, "lo") != NULL);

    vcan8_added = true;
    run("ip link add dev vcan8 type vcan && ip link set vcan8 mtu 16");  // classic only, still down
    TEST_ASSERT_EQUAL_INT(-ENETDOWN, md_bus_open(bus, "vcan8", why, sizeof why));
    TEST_MESSAGE(why);
    run("ip link set vcan8 up");
    md_bus_t *const a = &bus_ep[1];
    open_can(a, "vcan8");
    md_bus_t *const b = &bus_ep[2];
    open_can(b, "vcan8");
    const md_frame_t fd = make_frame(0x10, 12, MD_FRAME_FLAG_FD, 0);
    TEST_ASSERT_EQUAL_INT(-EMSGSIZE, md_bus_send(a, &fd));
    TEST_ASSERT_EQUAL_UINT64(1, a->stats.tx_errors);
    const md_frame_t classic = make_frame(0x10, 8, 0, 0);
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &classic));
    expect_frame(b, &classic);
    md_bus_close(a);
    md_bus_close(b);
    run("ip link del dev vcan8");
    vcan8_added = false;
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_vcan0_opens_as_can_fd_and_auto_picks_it);
    RUN_TEST(test_three_endpoints_exchange_frames_without_echo);
    RUN_TEST(test_many_frames_arrive_in_order);
    RUN_TEST(test_cansend_frames_reach_md_bus_and_rtr_is_counted);
    RUN_TEST(test_md_bus_frames_show_in_candump_as_mdcan_prints_them);
    RUN_TEST(test_interface_errors_are_clear);
    return UNITY_END();
}

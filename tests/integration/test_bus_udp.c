/// Integration tests of the UDP multicast bus. Run only through
/// scripts/netns-run.sh: a private network namespace with nothing but
/// loopback, so no datagram can leave the machine and parallel runs cannot
/// hear each other.
#define _GNU_SOURCE
#include <arpa/inet.h>
#include <errno.h>
#include <net/if.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "md_bus.h"
#include "md_bus_wire.h"
#include "unity.h"

#define ARRIVE_US 2000000  // generous upper bound; returns as soon as the frame is there
#define ABSENT_US 50000    // loopback delivers in microseconds; 50 ms of silence means "not sent"
#define PEER_US \
    20000000  // a peer process's next frame: bounds a hang only (a loaded machine can starve a process for seconds)
#define BUS_TEST_PATTERN 29u
#include "bus_test_frames.h"

/* What a test opens besides bus_ep: tearDown releases it if a failed
 * assertion ended the test first (a child left running would go on answering
 * frames in the later tests). */
static int raw_fd = -1;
static pid_t child_pid = -1;

void setUp(void)
{
    bus_test_reset();
}

void tearDown(void)
{
    bus_test_close_all();
    if (raw_fd >= 0) {
        (void)close(raw_fd);
        raw_fd = -1;
    }
    if (child_pid > 0) {
        (void)kill(child_pid, SIGKILL);
        (void)waitpid(child_pid, NULL, 0);
        child_pid = -1;
    }
}

static void open_udp(md_bus_t *bus, const char *spec)
{
    char why[160] = "";
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, md_bus_open(bus, spec, why, sizeof why), why);
}

/// A plain UDP socket that can send anything to the bus's group, with the
/// same loopback-only settings as the bus. tearDown closes it.
static int raw_sender(void)
{
    raw_fd = socket(AF_INET, SOCK_DGRAM, 0);
    const int fd = raw_fd;
    TEST_ASSERT_TRUE(fd >= 0);
    const int ttl = 0;
    TEST_ASSERT_EQUAL_INT(0, setsockopt(fd, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof ttl));
    struct in_addr lo;
    (void)inet_pton(AF_INET, "127.0.0.1", &lo);
    TEST_ASSERT_EQUAL_INT(0, setsockopt(fd, IPPROTO_IP, IP_MULTICAST_IF, &lo, sizeof lo));
    return fd;
}

static void raw_send(int fd, const uint8_t *buf, size_t len)
{
    struct sockaddr_in to;
    memset(&to, 0, sizeof to);
    to.sin_family = AF_INET;
    to.sin_port = htons((uint16_t)MD_BUS_UDP_PORT_DEFAULT);
    (void)inet_pton(AF_INET, MD_BUS_UDP_GROUP, &to.sin_addr);
    TEST_ASSERT_EQUAL_INT((int)len, (int)sendto(fd, buf, len, 0, (const struct sockaddr *)&to, sizeof to));
}

static void test_open_reports_the_group_and_keeps_traffic_on_loopback(void)
{
    md_bus_t *const a = &bus_ep[0];
    char why[160] = "";
    TEST_ASSERT_EQUAL_INT(0, md_bus_open(a, "udp", why, sizeof why));
    TEST_MESSAGE(why);
    TEST_ASSERT_TRUE(strstr(why, "loopback") != NULL);
    TEST_ASSERT_EQUAL_INT(MD_BUS_UDP, a->kind);
    TEST_ASSERT_EQUAL_STRING("udp:239.71.0.1:57731", a->name);
    const int fd = md_bus_fd(a);
    TEST_ASSERT_TRUE(fd >= 0);
    int v = -1;
    socklen_t len = sizeof v;
    TEST_ASSERT_EQUAL_INT(0, getsockopt(fd, IPPROTO_IP, IP_MULTICAST_TTL, &v, &len));
    TEST_ASSERT_EQUAL_INT(0, v);  // TTL 0: never forwarded past this host
    len = sizeof v;
    TEST_ASSERT_EQUAL_INT(0, getsockopt(fd, IPPROTO_IP, IP_MULTICAST_LOOP, &v, &len));
    TEST_ASSERT_EQUAL_INT(1, v);
    struct in_addr ifaddr;
    len = sizeof ifaddr;
    TEST_ASSERT_EQUAL_INT(0, getsockopt(fd, IPPROTO_IP, IP_MULTICAST_IF, &ifaddr, &len));
    TEST_ASSERT_EQUAL_HEX32(htonl(INADDR_LOOPBACK), ifaddr.s_addr);
    md_bus_close(a);
    TEST_ASSERT_EQUAL_INT(-1, md_bus_fd(a));
}

static void test_three_endpoints_exchange_classic_and_fd_frames_without_echo(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_udp(a, "udp");
    md_bus_t *const b = &bus_ep[1];
    open_udp(b, "udp");
    md_bus_t *const c = &bus_ep[2];
    open_udp(c, "udp:57731");
    const md_frame_t classic = make_frame(0x123, 4, 0, 0xDE);
    const md_frame_t fd = make_frame(0x1ABCDE01u, 64,
                                     (uint8_t)(MD_FRAME_FLAG_FD | MD_FRAME_FLAG_EXT | MD_FRAME_FLAG_BRS), 0x5A);
    const md_frame_t empty = make_frame(0x7FF, 0, 0, 0);
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &classic));
    expect_frame(b, &classic);
    expect_frame(c, &classic);
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(c, &fd));
    expect_frame(a, &fd);
    expect_frame(b, &fd);
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(b, &empty));
    expect_frame(a, &empty);
    expect_frame(c, &empty);
    // Each sender's own datagrams were looped back to it and dropped.
    expect_nothing(a);
    expect_nothing(b);
    expect_nothing(c);
    TEST_ASSERT_EQUAL_UINT64(1, a->stats.tx_frames);
    TEST_ASSERT_EQUAL_UINT64(2, a->stats.rx_frames);
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.rx_malformed + b->stats.rx_malformed + c->stats.rx_malformed);
    md_bus_close(a);
    md_bus_close(b);
    md_bus_close(c);
}

static void test_many_frames_arrive_complete_and_in_order(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_udp(a, "udp");
    md_bus_t *const b = &bus_ep[1];
    open_udp(b, "udp");
    const uint32_t n = 300;  // well inside the socket buffer
    for (uint32_t i = 0; i < n; ++i) {
        const md_frame_t f = make_frame(i, (uint8_t)(i % 9u), 0, (uint8_t)i);
        TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &f));
    }
    for (uint32_t i = 0; i < n; ++i) {
        const md_frame_t f = make_frame(i, (uint8_t)(i % 9u), 0, (uint8_t)i);
        expect_frame(b, &f);
    }
    expect_nothing(b);
    TEST_ASSERT_EQUAL_UINT64(0, b->stats.rx_overflow);
    md_bus_close(a);
    md_bus_close(b);
}

static void test_malformed_datagrams_are_counted_and_ignored(void)
{
    md_bus_t *const b = &bus_ep[0];
    open_udp(b, "udp");
    const int raw = raw_sender();
    const md_frame_t good = make_frame(0x321, 8, 0, 0x11);
    uint8_t dg[MD_BUS_WIRE_MAX + 8u];
    const int n = md_bus_wire_encode(&good, 0x0BADF00Du, 1u, dg, sizeof dg);
    TEST_ASSERT_TRUE(n > 0);
    const size_t size = (size_t)n;
    uint8_t bad[sizeof dg];

    memcpy(bad, dg, size);
    bad[0] = 'X';  // bad magic
    raw_send(raw, bad, size);
    memcpy(bad, dg, size);
    bad[size - 1u] ^= 0xFFu;  // bad CRC
    raw_send(raw, bad, size);
    raw_send(raw, dg, size - 1u);  // too short for its len
    memcpy(bad, dg, size);
    bad[size] = 0;
    raw_send(raw, bad, size + 1u);  // too long for its len
    memcpy(bad, dg, size);
    bad[2] = 9;  // unknown version
    raw_send(raw, bad, size);
    raw_send(raw, dg, 0);  // empty datagram
    const md_frame_t invalid = make_frame(0x100, 8, 0, 0);
    TEST_ASSERT_TRUE(md_bus_wire_encode(&invalid, 0x0BADF00Du, 2u, bad, sizeof bad) > 0);
    bad[12] = 0x00;
    bad[14] = 0x08;  // id 0x800 without EXT, CRC recomputed: only md_frame_valid catches it
    {
        const uint16_t crc = md_bus_wire_crc16(bad, size - 2u);
        bad[size - 2u] = (uint8_t)(crc >> 8);
        bad[size - 1u] = (uint8_t)crc;
    }
    raw_send(raw, bad, size);
    raw_send(raw, dg, size);  // finally a good one

    expect_frame(b, &good);
    TEST_ASSERT_EQUAL_UINT64(7, b->stats.rx_malformed);
    TEST_ASSERT_EQUAL_UINT64(1, b->stats.rx_frames);
    expect_nothing(b);
    md_bus_close(b);
}

static void test_ports_are_separate_buses(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_udp(a, "udp");
    md_bus_t *const other = &bus_ep[1];
    open_udp(other, "udp:57732");
    TEST_ASSERT_EQUAL_STRING("udp:239.71.0.1:57732", other->name);
    const md_frame_t f = make_frame(0x55, 1, 0, 1);
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &f));
    expect_nothing(other);
    md_bus_close(a);
    md_bus_close(other);
}

static void test_invalid_frame_and_arguments_are_refused(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_udp(a, "udp");
    md_bus_t *const b = &bus_ep[1];
    open_udp(b, "udp");
    const md_frame_t bad = make_frame(0x100, 9, 0, 0);
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_send(a, &bad));
    TEST_ASSERT_EQUAL_UINT64(1, a->stats.tx_errors);
    expect_nothing(b);
    md_frame_t r;
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_receive(b, &r, -5));
    TEST_ASSERT_EQUAL_INT(-EINVAL, md_bus_receive(b, NULL, 0));
    md_bus_close(a);
    md_bus_close(b);
}

static int64_t now_us(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000 + ts.tv_nsec / 1000;
}

static void test_receive_waits_for_its_timeout_and_no_longer(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_udp(a, "udp");
    md_frame_t r;
    const int64_t t0 = now_us();
    TEST_ASSERT_EQUAL_INT(0, md_bus_receive(a, &r, 100000));
    const int64_t dt = now_us() - t0;
    TEST_ASSERT_GREATER_OR_EQUAL_INT(100000, (int)dt);
    TEST_ASSERT_LESS_THAN_INT(400000, (int)dt);
    const int64_t t1 = now_us();
    TEST_ASSERT_EQUAL_INT(0, md_bus_receive(a, &r, 0));
    TEST_ASSERT_LESS_THAN_INT(50000, (int)(now_us() - t1));
    md_bus_close(a);
}

static void test_kernel_drops_are_counted_as_overflow(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_udp(a, "udp");
    md_bus_t *const b = &bus_ep[1];
    open_udp(b, "udp");
    // Without flow control, b does not read while a floods: its socket
    // buffer must overflow (each datagram costs ~1 kB of buffer).
    TEST_ASSERT_EQUAL_INT(0, md_bus_udp_set_flow_wait(a, 0));
    const uint32_t n = 100000;
    for (uint32_t i = 0; i < n; ++i) {
        const md_frame_t f = make_frame(i & 0x7FFu, 64, MD_FRAME_FLAG_FD, (uint8_t)i);
        TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &f));
    }
    md_frame_t r;
    for (uint32_t i = 0; i < n && md_bus_receive(b, &r, ABSENT_US) == 1; ++i) {
    }
    char msg[96];
    (void)snprintf(msg, sizeof msg, "received %llu, overflow %llu", (unsigned long long)b->stats.rx_frames,
                   (unsigned long long)b->stats.rx_overflow);
    TEST_MESSAGE(msg);
    TEST_ASSERT_GREATER_THAN_UINT(0, (unsigned)b->stats.rx_overflow);
    TEST_ASSERT_EQUAL_UINT64(a->stats.tx_frames, b->stats.rx_frames + b->stats.rx_overflow);  // nothing uncounted
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.tx_flow_waits);
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.rx_overflow);  // its 100000 filtered echoes are no loss
    md_bus_close(a);
    md_bus_close(b);
}

static void test_endpoints_ask_for_the_stock_receive_buffer_only(void)
{
    md_bus_t *const a = &bus_ep[0];
    char why[200] = "";
    TEST_ASSERT_EQUAL_INT(0, md_bus_open(a, "udp", why, sizeof why));
    TEST_MESSAGE(why);
    TEST_ASSERT_EQUAL_UINT8(1, a->sock.flow);
    TEST_ASSERT_TRUE(strstr(why, "flow control") != NULL);
    int v = 0;
    socklen_t len = sizeof v;
    TEST_ASSERT_EQUAL_INT(0, getsockopt(md_bus_fd(a), SOL_SOCKET, SO_RCVBUF, &v, &len));
    TEST_ASSERT_EQUAL_INT(v, a->sock.rcvbuf);
    TEST_ASSERT_TRUE(v <= 2 * MD_BUS_UDP_RCVBUF_BYTES);  // the kernel doubles what it grants, never more
    md_bus_close(a);
}

/// Child side: opens an endpoint and announces itself with 0x700.
/// 0, or 10 (open failed) / 11 (send failed).
static int child_open(md_bus_t *bus)
{
    if (md_bus_open(bus, "udp", NULL, 0) != 0) {
        return 10;
    }
    const md_frame_t hello = make_frame(0x700, 0, 0, 0);
    return (md_bus_send(bus, &hello) == 0) ? 0 : 11;
}

/// A child process: n, m as its test needs them; its exit status, 0 = all well.
typedef int (*child_fn)(uint32_t n, uint32_t m);

/// Parent side: forks `child` and waits for its 0x700 on `a`.
static void start_child(md_bus_t *a, child_fn child, uint32_t n, uint32_t m)
{
    const pid_t pid = fork();
    TEST_ASSERT_TRUE(pid >= 0);
    if (pid == 0) {
        _exit(child(n, m));
    }
    child_pid = pid;
    const md_frame_t hello = make_frame(0x700, 0, 0, 0);
    expect_frame(a, &hello);
}

/// Parent side: the child exited with status 0.
static void expect_child_ok(void)
{
    int status = -1;
    TEST_ASSERT_EQUAL_INT((int)child_pid, (int)waitpid(child_pid, &status, 0));
    child_pid = -1;
    TEST_ASSERT_TRUE(WIFEXITED(status));
    TEST_ASSERT_EQUAL_INT(0, WEXITSTATUS(status));
}

/// Sends n 64-byte FD frames numbered by id and first byte.
static void send_numbered(md_bus_t *a, uint32_t n)
{
    for (uint32_t i = 0; i < n; ++i) {
        const md_frame_t f = make_frame(i & 0x7FFu, 64, MD_FRAME_FLAG_FD, (uint8_t)i);
        TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &f));
    }
}

/// Child: opens an endpoint, announces itself with 0x700, then reads `n`
/// frames slowly (a short sleep after each) and checks their order. Exit 0
/// if all arrived in order and the kernel dropped none.
static int child_slow_reader(uint32_t n, uint32_t m)
{
    (void)m;
    md_bus_t bus;
    const int opened = child_open(&bus);
    if (opened != 0) {
        return opened;
    }
    for (uint32_t i = 0; i < n; ++i) {
        md_frame_t f;
        if (md_bus_receive(&bus, &f, PEER_US) != 1) {
            return 12;
        }
        const md_frame_t e = make_frame(i & 0x7FFu, 64, MD_FRAME_FLAG_FD, (uint8_t)i);
        if (f.id != e.id || memcmp(f.data, e.data, 64) != 0) {
            return 13;
        }
        const struct timespec pause = {0, 100000L};  // 0.1 ms per frame: slower than the sender
        (void)nanosleep(&pause, NULL);
    }
    const int rc = (bus.stats.rx_overflow == 0u) ? 0 : 14;
    md_bus_close(&bus);
    return rc;
}

static void test_a_slow_reader_loses_nothing(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_udp(a, "udp");
    // 8x what the reader's socket buffer holds: without flow control a
    // reader this slow loses most of them.
    const uint32_t n = 4000;
    start_child(a, child_slow_reader, n, 0);
    send_numbered(a, n);
    char msg[128];
    (void)snprintf(msg, sizeof msg, "%u frames to a slow reader: sender waited %llu times, timed out %llu times",
                   (unsigned)n, (unsigned long long)a->stats.tx_flow_waits,
                   (unsigned long long)a->stats.tx_flow_timeouts);
    TEST_MESSAGE(msg);
    expect_child_ok();
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.tx_flow_timeouts);
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.rx_overflow);
    md_bus_close(a);
}

/// Child: announces itself with 0x700, reads `n` frames, then answers 0x701.
static int child_reader_then_answer(uint32_t n, uint32_t m)
{
    (void)m;
    md_bus_t bus;
    const int opened = child_open(&bus);
    if (opened != 0) {
        return opened;
    }
    for (uint32_t i = 0; i < n; ++i) {
        md_frame_t f;
        if (md_bus_receive(&bus, &f, PEER_US) != 1) {
            return 12;
        }
    }
    const md_frame_t answer = make_frame(0x701, 8, 0, 7);
    const int rc = (md_bus_send(&bus, &answer) == 0 && bus.stats.rx_overflow == 0u) ? 0 : 13;
    md_bus_close(&bus);
    return rc;
}

static void test_own_echoes_do_not_crowd_out_other_senders(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_udp(a, "udp");
    // a sends far more than its socket holds and reads nothing meanwhile:
    // its own looped-back datagrams must not fill its queue, or the reader's
    // answer would be dropped.
    const uint32_t n = 5000;
    start_child(a, child_reader_then_answer, n, 0);
    send_numbered(a, n);
    const md_frame_t answer = make_frame(0x701, 8, 0, 7);
    expect_frame(a, &answer);
    expect_child_ok();
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.rx_overflow);
    expect_nothing(a);
    md_bus_close(a);
}

/// Child: announces itself with 0x700, waits for 0x702, then streams `n`
/// frames without reading in between (as the simulator streams an interval),
/// then reads the parent's `m` frames. Exit 0 if they all arrived, none lost.
static int child_streamer(uint32_t n, uint32_t m)
{
    md_bus_t bus;
    const int opened = child_open(&bus);
    if (opened != 0) {
        return opened;
    }
    md_frame_t f;
    if (md_bus_receive(&bus, &f, PEER_US) != 1 || f.id != 0x702u) {
        return 12;
    }
    for (uint32_t i = 0; i < n; ++i) {
        const md_frame_t e = make_frame(i & 0x3FFu, 64, MD_FRAME_FLAG_FD, (uint8_t)i);
        if (md_bus_send(&bus, &e) != 0) {
            return 13;
        }
    }
    for (uint32_t i = 0; i < m; ++i) {
        if (md_bus_receive(&bus, &f, PEER_US) != 1 || f.id != (0x400u | (i & 0x3FFu))) {
            return 14;
        }
    }
    const int rc = (bus.stats.rx_overflow == 0u) ? 0 : 15;
    md_bus_close(&bus);
    return rc;
}

static void test_two_senders_that_do_not_read_while_sending_lose_nothing(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_udp(a, "udp");
    // The child streams 3000 frames at a; a meanwhile sends 200 of its own
    // before it reads anything (the controller's telemetry while the
    // simulator streams). a's echoes must not fill its queue, and the
    // child's stream must wait for a instead of being dropped there. (Both
    // sending much more than a buffer's worth at each other without reading
    // is beyond the flow control: docs/bus.md, "Flow control".)
    const uint32_t n = 3000, m = 200;
    start_child(a, child_streamer, n, m);
    const md_frame_t go = make_frame(0x702, 0, 0, 0);
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &go));
    for (uint32_t i = 0; i < m; ++i) {
        const md_frame_t f = make_frame(0x400u | (i & 0x3FFu), 8, 0, (uint8_t)i);
        TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &f));
    }
    for (uint32_t i = 0; i < n; ++i) {
        const md_frame_t e = make_frame(i & 0x3FFu, 64, MD_FRAME_FLAG_FD, (uint8_t)i);
        expect_frame(a, &e);
    }
    expect_child_ok();
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.rx_overflow);
    TEST_ASSERT_EQUAL_UINT64(0, a->stats.tx_flow_timeouts);
    md_bus_close(a);
}

static void test_a_reader_that_never_reads_is_marked_stalled_and_counted(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_udp(a, "udp");
    md_bus_t *const b = &bus_ep[1];
    open_udp(b, "udp");
    // b never reads: a waits for it once (here 50 ms instead of the default),
    // then marks it stalled and sends on; b's losses are counted at b.
    TEST_ASSERT_EQUAL_INT(0, md_bus_udp_set_flow_wait(a, 50000));
    const uint32_t n = 2000;
    send_numbered(a, n);
    TEST_ASSERT_EQUAL_UINT64(1, a->stats.tx_flow_waits);
    TEST_ASSERT_EQUAL_UINT64(1, a->stats.tx_flow_timeouts);
    md_frame_t r;
    for (uint32_t i = 0; i < n && md_bus_receive(b, &r, ABSENT_US) == 1; ++i) {
    }
    TEST_ASSERT_GREATER_THAN_UINT(0, (unsigned)b->stats.rx_overflow);
    TEST_ASSERT_EQUAL_UINT64(n, b->stats.rx_frames + b->stats.rx_overflow);
    md_bus_close(a);
    md_bus_close(b);
}

static void test_round_trip_time_is_reported(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_udp(a, "udp");
    md_bus_t *const b = &bus_ep[1];
    open_udp(b, "udp");
    const uint32_t n = 2000;
    const md_frame_t ping = make_frame(0x10, 64, MD_FRAME_FLAG_FD, 1);
    const md_frame_t pong = make_frame(0x11, 8, 0, 2);
    const int64_t t0 = now_us();
    for (uint32_t i = 0; i < n; ++i) {
        md_frame_t r;
        TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &ping));
        TEST_ASSERT_EQUAL_INT(1, md_bus_receive(b, &r, ARRIVE_US));
        TEST_ASSERT_EQUAL_INT(0, md_bus_send(b, &pong));
        TEST_ASSERT_EQUAL_INT(1, md_bus_receive(a, &r, ARRIVE_US));
        TEST_ASSERT_EQUAL_UINT32(0x11, r.id);
    }
    const int64_t dt = now_us() - t0;
    char msg[128];
    (void)snprintf(msg, sizeof msg, "UDP bus: %u round trips (64-byte FD ping, 8-byte pong) in %lld us: %.1f us each",
                   (unsigned)n, (long long)dt, (double)dt / (double)n);
    TEST_MESSAGE(msg);
    md_bus_close(a);
    md_bus_close(b);
}

/// Child: opens its own endpoint, announces itself, answers each frame with
/// id + 1 until it sees id 0x7FF. Exit status 0 = all well.
static int child_echo(uint32_t n, uint32_t m)
{
    (void)n;
    (void)m;
    md_bus_t bus;
    const int opened = child_open(&bus);
    if (opened != 0) {
        return opened;
    }
    for (unsigned i = 0; i < 100u; ++i) {
        md_frame_t f;
        if (md_bus_receive(&bus, &f, ARRIVE_US) != 1) {
            return 12;
        }
        if (f.id == 0x7FFu) {
            md_bus_close(&bus);
            return 0;
        }
        f.id += 1u;
        if (md_bus_send(&bus, &f) != 0) {
            return 13;
        }
    }
    return 14;
}

static void test_two_processes_talk_over_the_bus(void)
{
    md_bus_t *const a = &bus_ep[0];
    open_udp(a, "udp");
    start_child(a, child_echo, 0, 0);
    for (uint32_t i = 0; i < 10u; ++i) {
        const uint8_t flags = (uint8_t)((i % 2u) == 0u ? 0u : MD_FRAME_FLAG_FD);
        const md_frame_t f = make_frame(0x100u + 2u * i, (uint8_t)((i % 2u) == 0u ? 8u : 48u), flags, (uint8_t)i);
        TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &f));
        md_frame_t e = f;
        e.id += 1u;
        expect_frame(a, &e);
    }
    const md_frame_t stop = make_frame(0x7FF, 0, 0, 0);
    TEST_ASSERT_EQUAL_INT(0, md_bus_send(a, &stop));
    expect_child_ok();
    md_bus_close(a);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_open_reports_the_group_and_keeps_traffic_on_loopback);
    RUN_TEST(test_three_endpoints_exchange_classic_and_fd_frames_without_echo);
    RUN_TEST(test_many_frames_arrive_complete_and_in_order);
    RUN_TEST(test_malformed_datagrams_are_counted_and_ignored);
    RUN_TEST(test_ports_are_separate_buses);
    RUN_TEST(test_invalid_frame_and_arguments_are_refused);
    RUN_TEST(test_receive_waits_for_its_timeout_and_no_longer);
    RUN_TEST(test_kernel_drops_are_counted_as_overflow);
    RUN_TEST(test_endpoints_ask_for_the_stock_receive_buffer_only);
    RUN_TEST(test_a_slow_reader_loses_nothing);
    RUN_TEST(test_own_echoes_do_not_crowd_out_other_senders);
    RUN_TEST(test_two_senders_that_do_not_read_while_sending_lose_nothing);
    RUN_TEST(test_a_reader_that_never_reads_is_marked_stalled_and_counted);
    RUN_TEST(test_two_processes_talk_over_the_bus);
    RUN_TEST(test_round_trip_time_is_reported);
    return UNITY_END();
}

/// @file md_bus.c
/// Bus spec parsing, the `auto` rule, and helpers the socket transports share.
#include "md_bus.h"

#include <errno.h>
#include <poll.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <linux/sock_diag.h>

#include "md_bus_internal.h"

#define SPEC_UDP "udp"
#define SPEC_UDP_PORT "udp:"
#define SPEC_INPROC "inproc:"
#define AUTO_IFNAME "vcan0"
#define IFNAME_MAX 15u  // IFNAMSIZ - 1

static int closed_send(md_bus_t *bus, const md_frame_t *frame)
{
    (void)bus;
    (void)frame;
    return -EBADF;
}

static int closed_receive(md_bus_t *bus, md_frame_t *frame, int64_t timeout_us)
{
    (void)bus;
    (void)frame;
    (void)timeout_us;
    return -EBADF;
}

static int closed_fd(const md_bus_t *bus)
{
    (void)bus;
    return -1;
}

static void closed_close(md_bus_t *bus)
{
    (void)bus;
}

const md_bus_ops_t md_bus_closed_ops = {closed_send, closed_receive, closed_fd, closed_close};

void md_bus_set_closed(md_bus_t *bus)
{
    bus->ops = &md_bus_closed_ops;
    bus->impl = NULL;
    bus->sock.fd = -1;
    bus->sock.diag_fd = -1;
    bus->sock.flow = 0u;
}

void md_bus_why(char *why, size_t why_len, const char *fmt, ...)
{
    if (why == NULL || why_len == 0u) {
        return;
    }
    va_list ap;
    va_start(ap, fmt);
    (void)vsnprintf(why, why_len, fmt, ap);
    va_end(ap);
}

int64_t md_bus_now_us(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000 + (int64_t)ts.tv_nsec / 1000;
}

int md_bus_wait_fd(int fd, short events, int64_t deadline_us)
{
    struct pollfd pfd = {.fd = fd, .events = events, .revents = 0};
    // EINTR restarts with the remaining time; the deadline bounds the loop.
    for (;;) {
        int64_t left_us = deadline_us - md_bus_now_us();
        if (left_us < 0) {
            left_us = 0;
        }
        const struct timespec ts = {.tv_sec = (time_t)(left_us / 1000000),
                                    .tv_nsec = (long)(left_us % 1000000) * 1000L};
        const int n = ppoll(&pfd, 1, &ts, NULL);
        if (n > 0) {
            return 1;
        }
        if (n == 0) {
            return 0;
        }
        if (errno != EINTR) {
            return -errno;
        }
    }
}

/// Takes a cumulative kernel drop count. The cmsg of a queued datagram
/// carries the count at its enqueue time, which can be older than one already
/// read through SO_MEMINFO, so only forward steps count (wrap-aware).
/// UDP with the echo filter: the kernel's count includes our own echoes,
/// exactly one per datagram we sent, and at any moment at most tx_frames of
/// them have been dropped, so kernel_total - tx_frames is never more than the
/// real losses and equals them once our last echo has passed (microseconds
/// after the send, on loopback). rx_overflow keeps the highest value seen.
static void note_drops(md_bus_t *bus, uint32_t total)
{
    const uint32_t step = total - bus->sock.kernel_drops;
    if (step != 0u && step < 0x80000000u) {
        bus->sock.kernel_drops = total;
        bus->sock.kernel_total += step;
    }
    const uint64_t echoes = (bus->sock.echo_filter != 0u) ? bus->stats.tx_frames : 0u;
    const uint64_t lost = (bus->sock.kernel_total > echoes) ? bus->sock.kernel_total - echoes : 0u;
    if (lost > bus->stats.rx_overflow) {
        bus->stats.rx_overflow = lost;
    }
}

void md_bus_account_drops(md_bus_t *bus, struct msghdr *msg)
{
    for (struct cmsghdr *c = CMSG_FIRSTHDR(msg); c != NULL; c = CMSG_NXTHDR(msg, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL && c->cmsg_len >= CMSG_LEN(sizeof(uint32_t))) {
            uint32_t total;
            memcpy(&total, CMSG_DATA(c), sizeof total);
            note_drops(bus, total);
        }
    }
}

int md_bus_sock_receive(md_bus_t *bus, md_frame_t *frame, int64_t timeout_us, md_bus_read_one_fn read_one)
{
    if (frame == NULL || timeout_us < 0) {
        return -EINVAL;
    }
    const int64_t deadline_us = md_bus_now_us() + timeout_us;
    for (unsigned discarded = 0; discarded < MD_BUS_RX_DISCARD_MAX;) {
        const int r = read_one(bus, frame);
        if (r == 1) {
            bus->stats.rx_frames++;
            return 1;
        }
        if (r < 0) {
            return r;
        }
        if (r == 2) {
            ++discarded;
            continue;
        }
        md_bus_poll_drops(bus);
        const int w = md_bus_wait_fd(bus->sock.fd, POLLIN, deadline_us);
        if (w <= 0) {
            return w;
        }
    }
    return 0;
}

int md_bus_stats_format(const md_bus_stats_t *st, char *out, size_t len)
{
    return snprintf(out, len,
                    "bus stats: rx %llu, rx overflow %llu, rx malformed %llu, tx %llu, tx errors %llu, "
                    "flow waits %llu, flow timeouts %llu",
                    (unsigned long long)st->rx_frames, (unsigned long long)st->rx_overflow,
                    (unsigned long long)st->rx_malformed, (unsigned long long)st->tx_frames,
                    (unsigned long long)st->tx_errors, (unsigned long long)st->tx_flow_waits,
                    (unsigned long long)st->tx_flow_timeouts);
}

int md_bus_sock_fd(const md_bus_t *bus)
{
    return bus->sock.fd;
}

void md_bus_sock_close(md_bus_t *bus)
{
    if (bus->sock.fd >= 0) {
        (void)close(bus->sock.fd);
    }
    if (bus->sock.diag_fd >= 0) {
        (void)close(bus->sock.diag_fd);
    }
    md_bus_set_closed(bus);
}

void md_bus_poll_drops(md_bus_t *bus)
{
    // Drops after the last queued datagram ride on no cmsg; the socket's
    // meminfo has the current total.
    uint32_t info[SK_MEMINFO_VARS];
    socklen_t len = sizeof info;
    if (getsockopt(bus->sock.fd, SOL_SOCKET, SO_MEMINFO, info, &len) == 0 &&
        len > (socklen_t)(SK_MEMINFO_DROPS * sizeof info[0])) {
        note_drops(bus, info[SK_MEMINFO_DROPS]);
    }
}

int md_bus_sock_send(int fd, const void *buf, size_t len, const struct sockaddr *to, socklen_t to_len)
{
    const int64_t deadline_us = md_bus_now_us() + MD_BUS_TX_WAIT_US;
    // A full socket buffer (EAGAIN/ENOBUFS) gets one bounded wait, then fails:
    // the caller learns of it instead of blocking its cycle.
    for (unsigned attempt = 0; attempt < 2u; ++attempt) {
        const ssize_t n = sendto(fd, buf, len, MSG_DONTWAIT | MSG_NOSIGNAL, to, to_len);
        if (n >= 0) {
            return (size_t)n == len ? 0 : -EMSGSIZE;
        }
        const int err = errno;
        if (err == EINTR) {
            continue;
        }
        if (err != EAGAIN && err != EWOULDBLOCK && err != ENOBUFS) {
            return -err;
        }
        if (attempt == 0u) {
            const int w = md_bus_wait_fd(fd, POLLOUT, deadline_us);
            if (w < 0) {
                return w;
            }
        }
    }
    return -EAGAIN;
}

static int parse_port(const char *s, uint16_t *port)
{
    uint32_t v = 0;
    size_t i = 0;
    for (; i < 6u && s[i] >= '0' && s[i] <= '9'; ++i) {
        v = v * 10u + (uint32_t)(s[i] - '0');
    }
    if (i == 0u || s[i] != '\0' || v == 0u || v > 65535u) {
        return -EINVAL;
    }
    *port = (uint16_t)v;
    return 0;
}

static bool ifname_ok(const char *s)
{
    const size_t n = strnlen(s, IFNAME_MAX + 1u);
    if (n == 0u || n > IFNAME_MAX) {
        return false;
    }
    for (size_t i = 0; i < n; ++i) {
        // The kernel refuses '/', ':' and whitespace in interface names.
        if (s[i] == '/' || s[i] == ':' || s[i] <= ' ' || s[i] == 0x7F) {
            return false;
        }
    }
    return true;
}

static int open_auto(md_bus_t *bus, char *why, size_t why_len)
{
    char reason[160];
    const int rc = md_bus_open_socketcan(bus, AUTO_IFNAME, reason, sizeof reason);
    if (rc == 0) {
        md_bus_why(why, why_len, "auto: %s", reason);
        return 0;
    }
    char udp_why[160];
    const int urc = md_bus_open_udp(bus, (uint16_t)MD_BUS_UDP_PORT_DEFAULT, udp_why, sizeof udp_why);
    if (urc != 0) {
        md_bus_why(why, why_len, "auto: no SocketCAN (%s) and %s", reason, udp_why);
        return urc;
    }
    md_bus_why(why, why_len, "auto: %s, because SocketCAN is unusable: %s", udp_why, reason);
    return 0;
}

int md_bus_open(md_bus_t *bus, const char *spec, char *why, size_t why_len)
{
    if (bus == NULL) {
        md_bus_why(why, why_len, "md_bus_open: bus is NULL");
        return -EINVAL;
    }
    memset(bus, 0, sizeof *bus);
    md_bus_set_closed(bus);
    if (spec == NULL || spec[0] == '\0') {
        md_bus_why(why, why_len, "empty bus spec (use an interface name, udp, udp:<port>, inproc:<name> or auto)");
        return -EINVAL;
    }
    if (strcmp(spec, "auto") == 0) {
        return open_auto(bus, why, why_len);
    }
    if (strcmp(spec, SPEC_UDP) == 0) {
        return md_bus_open_udp(bus, (uint16_t)MD_BUS_UDP_PORT_DEFAULT, why, why_len);
    }
    if (strncmp(spec, SPEC_UDP_PORT, strlen(SPEC_UDP_PORT)) == 0) {
        uint16_t port = 0;
        if (parse_port(spec + strlen(SPEC_UDP_PORT), &port) != 0) {
            md_bus_why(why, why_len, "bad UDP bus spec '%.40s': want udp:<port 1..65535>", spec);
            return -EINVAL;
        }
        return md_bus_open_udp(bus, port, why, why_len);
    }
    if (strncmp(spec, SPEC_INPROC, strlen(SPEC_INPROC)) == 0) {
        return md_bus_open_inproc(bus, spec + strlen(SPEC_INPROC), why, why_len);
    }
    if (strnlen(spec, IFNAME_MAX + 1u) > IFNAME_MAX) {
        md_bus_why(why, why_len, "interface name '%.40s' longer than %u characters", spec, IFNAME_MAX);
        return -ENAMETOOLONG;
    }
    if (!ifname_ok(spec)) {
        md_bus_why(why, why_len,
                   "unknown bus spec '%.40s' (use an interface name, udp, udp:<port>, inproc:<name> or auto)", spec);
        return -EINVAL;
    }
    const int rc = md_bus_open_socketcan(bus, spec, why, why_len);
    if (rc == -EAFNOSUPPORT) {
        md_bus_why(why, why_len, "AF_CAN not supported by this kernel (no SocketCAN for '%s'): use bus 'udp' or 'auto'",
                   spec);
    }
    return rc;
}

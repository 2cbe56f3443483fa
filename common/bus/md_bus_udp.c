/// @file md_bus_udp.c
/// The UDP multicast bus: every endpoint is a socket joined to one
/// administratively scoped group on the loopback interface, with TTL 0, so a
/// datagram can reach only sockets of this machine (docs/bus.md). The kernel
/// loops every datagram back to every member, the sender included; the sender
/// id in each datagram lets a node drop its own, which gives CAN's "everyone
/// else sees it" semantics.
#include <arpa/inet.h>
#include <errno.h>
#include <net/if.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/random.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "md_bus.h"
#include "md_bus_internal.h"
#include "md_bus_wire.h"

/// Kernel receive buffer asked for: bursts of sample streams must fit
/// (a 10 s recording is ~10 000 datagrams of ~1 kB skb truesize each).
#define UDP_RCVBUF_BYTES (16 * 1024 * 1024)
#ifndef SO_RCVBUFFORCE
#define SO_RCVBUFFORCE 33 /* Linux; glibc hides it outside _GNU_SOURCE */
#endif

static struct sockaddr_in group_addr(uint16_t port)
{
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons(port);
    (void)inet_pton(AF_INET, MD_BUS_UDP_GROUP, &a.sin_addr);
    return a;
}

static int udp_send(md_bus_t *bus, const md_frame_t *frame)
{
    uint8_t buf[MD_BUS_WIRE_MAX];
    const int size = md_bus_wire_encode(frame, bus->sock.sender_id, bus->sock.tx_seq, buf, sizeof buf);
    if (size < 0) {
        bus->stats.tx_errors++;
        return -EINVAL;
    }
    // The destination is always our group: with IP_MULTICAST_IF = loopback and
    // TTL 0 (both verified at open) it cannot leave this machine.
    const struct sockaddr_in to = group_addr(bus->sock.port);
    const int rc = md_bus_sock_send(bus->sock.fd, buf, (size_t)size, (const struct sockaddr *)&to, sizeof to);
    if (rc != 0) {
        bus->stats.tx_errors++;
        return rc;
    }
    bus->sock.tx_seq++;
    bus->stats.tx_frames++;
    return 0;
}

/// Reads one datagram. Returns 1 frame, 2 discarded (own/malformed), 0 nothing
/// queued, negative error.
static int udp_read_one(md_bus_t *bus, md_frame_t *frame)
{
    uint8_t buf[MD_BUS_WIRE_MAX + 1u];  // one spare byte: oversize is detected
    union {
        struct cmsghdr align;
        uint8_t space[CMSG_SPACE(sizeof(uint32_t))];
    } ctrl;
    struct iovec iov = {.iov_base = buf, .iov_len = sizeof buf};
    struct msghdr msg;
    memset(&msg, 0, sizeof msg);
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = ctrl.space;
    msg.msg_controllen = sizeof ctrl.space;
    const ssize_t n = recvmsg(bus->sock.fd, &msg, MSG_DONTWAIT | MSG_TRUNC);
    if (n < 0) {
        return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? 0 : -errno;
    }
    md_bus_account_drops(bus, &msg);
    uint32_t sender = 0;
    uint32_t seq = 0;
    // MSG_TRUNC makes n the real datagram size, so oversize fails the length check.
    if (md_bus_wire_decode(buf, (size_t)n, frame, &sender, &seq) != MD_BUS_WIRE_OK) {
        bus->stats.rx_malformed++;
        return 2;
    }
    return sender == bus->sock.sender_id ? 2 : 1;
}

static int udp_receive(md_bus_t *bus, md_frame_t *frame, int64_t timeout_us)
{
    return md_bus_sock_receive(bus, frame, timeout_us, udp_read_one);
}

static const md_bus_ops_t udp_ops = {udp_send, udp_receive, md_bus_sock_fd, md_bus_sock_close};

static int set_int(int fd, int level, int opt, int value)
{
    return setsockopt(fd, level, opt, &value, sizeof value) == 0 ? 0 : -errno;
}

/// Every option that keeps traffic on this machine; a failure fails the open.
static int udp_configure(int fd, uint16_t port, const char **what)
{
    struct ip_mreqn mreq;
    memset(&mreq, 0, sizeof mreq);
    (void)inet_pton(AF_INET, MD_BUS_UDP_GROUP, &mreq.imr_multiaddr);
    (void)inet_pton(AF_INET, "127.0.0.1", &mreq.imr_address);
    mreq.imr_ifindex = (int)if_nametoindex("lo");
    const struct sockaddr_in bind_addr = group_addr(port);
    int rc = 0;
    if (rc == 0 && (rc = set_int(fd, SOL_SOCKET, SO_REUSEADDR, 1)) != 0) { *what = "SO_REUSEADDR"; }
    if (rc == 0 && (rc = set_int(fd, SOL_SOCKET, SO_REUSEPORT, 1)) != 0) { *what = "SO_REUSEPORT"; }
    if (rc == 0 && (rc = set_int(fd, SOL_SOCKET, SO_RXQ_OVFL, 1)) != 0) { *what = "SO_RXQ_OVFL"; }
    if (rc == 0 && (rc = set_int(fd, IPPROTO_IP, IP_MULTICAST_TTL, 0)) != 0) { *what = "IP_MULTICAST_TTL 0"; }
    if (rc == 0 && (rc = set_int(fd, IPPROTO_IP, IP_MULTICAST_LOOP, 1)) != 0) { *what = "IP_MULTICAST_LOOP 1"; }
    if (rc == 0 && (rc = set_int(fd, IPPROTO_IP, IP_MULTICAST_ALL, 0)) != 0) { *what = "IP_MULTICAST_ALL 0"; }
    if (rc == 0 && setsockopt(fd, IPPROTO_IP, IP_MULTICAST_IF, &mreq, sizeof mreq) != 0) {
        rc = -errno;
        *what = "IP_MULTICAST_IF lo";
    }
    if (rc == 0 && bind(fd, (const struct sockaddr *)&bind_addr, sizeof bind_addr) != 0) {
        rc = -errno;
        *what = "bind to the group";
    }
    if (rc == 0 && setsockopt(fd, IPPROTO_IP, IP_ADD_MEMBERSHIP, &mreq, sizeof mreq) != 0) {
        rc = -errno;
        *what = "IP_ADD_MEMBERSHIP on lo";
    }
    // A larger buffer is only a wish: FORCE needs CAP_NET_ADMIN (root, or
    // the owner of a private network namespace as in our tests), else
    // SO_RCVBUF is capped by net.core.rmem_max; drops still show up in
    // rx_overflow through SO_RXQ_OVFL.
    if (set_int(fd, SOL_SOCKET, SO_RCVBUFFORCE, UDP_RCVBUF_BYTES) != 0) {
        (void)set_int(fd, SOL_SOCKET, SO_RCVBUF, UDP_RCVBUF_BYTES);
    }
    return rc;
}

/// Reads back TTL and loop: the loopback-only guarantee must hold, not only
/// have been asked for.
static int udp_verify(int fd)
{
    int ttl = -1;
    socklen_t len = sizeof ttl;
    if (getsockopt(fd, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, &len) != 0) {
        return -errno;
    }
    return ttl == 0 ? 0 : -EPROTO;
}

static uint32_t new_sender_id(void)
{
    uint32_t id = 0;
    // Random, not pid-based: endpoints in one process and processes in other
    // pid namespaces must all differ. 0 is reserved (invalid on the wire).
    for (unsigned i = 0; i < 8u && id == 0u; ++i) {
        if (getrandom(&id, sizeof id, 0) != (ssize_t)sizeof id) {
            struct timespec ts;
            (void)clock_gettime(CLOCK_MONOTONIC, &ts);
            id = (uint32_t)getpid() * 2654435761u ^ (uint32_t)ts.tv_nsec ^ (i + 1u);
        }
    }
    return id == 0u ? 1u : id;
}

int md_bus_open_udp(md_bus_t *bus, uint16_t port, char *why, size_t why_len)
{
    md_bus_set_closed(bus);
    const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) {
        const int err = errno;
        md_bus_why(why, why_len, "UDP bus: socket(AF_INET): %s", strerror(err));
        return -err;
    }
    const char *what = "?";
    int rc = udp_configure(fd, port, &what);
    if (rc == 0 && (rc = udp_verify(fd)) != 0) {
        what = "verify multicast TTL 0";
    }
    if (rc != 0) {
        md_bus_why(why, why_len, "UDP bus %s:%u: %s failed: %s", MD_BUS_UDP_GROUP, (unsigned)port, what,
                   strerror(-rc));
        (void)close(fd);
        return rc;
    }
    bus->sock.fd = fd;
    bus->sock.port = port;
    bus->sock.sender_id = new_sender_id();
    bus->sock.tx_seq = 0;
    bus->sock.kernel_drops = 0;
    bus->kind = MD_BUS_UDP;
    (void)snprintf(bus->name, sizeof bus->name, "udp:%s:%u", MD_BUS_UDP_GROUP, (unsigned)port);
    bus->impl = &bus->sock;
    bus->ops = &udp_ops;
    md_bus_why(why, why_len, "UDP multicast %s:%u on loopback (TTL 0)", MD_BUS_UDP_GROUP, (unsigned)port);
    return 0;
}

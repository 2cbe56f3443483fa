/// @file md_bus_udp.c
/// The UDP multicast bus: every endpoint is a socket joined to one
/// administratively scoped group on the loopback interface, with TTL 0, so a
/// datagram can reach only sockets of this machine (docs/bus.md). The kernel
/// loops every datagram back to every member, the sender included; the sender
/// id in each datagram lets a node drop its own, which gives CAN's "everyone
/// else sees it" semantics.
///
/// Nothing here depends on a large socket buffer (docs/bus.md, "Flow
/// control"): a socket filter drops our own echoes in the kernel (they never
/// take room in our queue), and before every window of frames a sender asks
/// the kernel (sock_diag) how much room the other members' receive buffers
/// have left, waiting while the fullest one is short of room.
#include <arpa/inet.h>
#include <errno.h>
#include <linux/filter.h>
#include <linux/inet_diag.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>
#include <linux/sock_diag.h>
#include <net/if.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/random.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "md_bus.h"
#include "md_bus_internal.h"
#include "md_bus_wire.h"

/// Receive-buffer bytes one datagram is charged (skb truesize; 832 measured
/// for an 84-byte datagram on lo, Linux 6.x), rounded up for margin.
#define UDP_DATAGRAM_COST 1024u
/// Most frames sent between two looks at the receivers.
#define UDP_WINDOW_MAX 64u
/// Wait between two looks while a receiver is short of room.
#define UDP_FLOW_POLL_US 250

static struct sockaddr_in group_addr(uint16_t port)
{
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons(port);
    (void)inet_pton(AF_INET, MD_BUS_UDP_GROUP, &a.sin_addr);
    return a;
}

static void udp_flow(md_bus_t *bus);

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
    udp_flow(bus);
    const int rc = md_bus_sock_send(bus->sock.fd, buf, (size_t)size, (const struct sockaddr *)&to, sizeof to);
    if (rc != 0) {
        bus->stats.tx_errors++;
        return rc;
    }
    bus->sock.tx_seq++;
    bus->stats.tx_frames++;
    return 0;
}

/// Reads one datagram from the socket. Returns 1 frame, 2 discarded
/// (own/malformed), 0 nothing queued, negative error.
static int udp_read_socket(md_bus_t *bus, md_frame_t *frame)
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

/// While a send waits for room: moves what is queued on our socket into the
/// held ring, as long as the ring has room (never dropping), so that a peer
/// waiting for room in *our* buffer makes progress too.
static void udp_hold_queued(md_bus_t *bus)
{
    md_bus_sock_t *s = &bus->sock;
    while (s->held_count < MD_BUS_UDP_HELD_LEN) {
        md_frame_t f;
        const int r = udp_read_socket(bus, &f);
        if (r <= 0) {
            return;  // empty, or an error that receive will report
        }
        if (r == 1) {
            s->held[(s->held_head + s->held_count) % MD_BUS_UDP_HELD_LEN] = f;
            s->held_count++;
        }
    }
}

/// Reads one frame: first the frames held while a send waited (they arrived
/// before anything still queued in the socket), then the socket. Returns 1 frame, 2
/// discarded (own/malformed), 0 nothing queued, negative error.
static int udp_read_one(md_bus_t *bus, md_frame_t *frame)
{
    md_bus_sock_t *s = &bus->sock;
    if (s->held_count > 0u) {
        *frame = s->held[s->held_head];
        s->held_head = (s->held_head + 1u) % MD_BUS_UDP_HELD_LEN;
        s->held_count--;
        return 1;
    }
    return udp_read_socket(bus, frame);
}

static bool udp_is_stalled(const md_bus_sock_t *s, uint64_t inode, unsigned *slot)
{
    for (unsigned i = 0; i < MD_BUS_UDP_STALLED_MAX; ++i) {
        if (s->stalled[i] == inode && inode != 0u) {
            *slot = i;
            return true;
        }
    }
    return false;
}

/// Frames a receiver with `rmem` of `rcvbuf` bytes queued can take from us
/// now: a quarter of its buffer stays reserved for the other senders.
static uint32_t udp_receiver_credit(uint32_t rmem, uint32_t rcvbuf)
{
    const uint32_t capacity = rcvbuf / UDP_DATAGRAM_COST;
    const uint32_t free_frames = (rcvbuf > rmem) ? (rcvbuf - rmem) / UDP_DATAGRAM_COST : 0u;
    const uint32_t reserve = capacity / 4u;
    uint32_t window = capacity / 4u;
    window = (window > UDP_WINDOW_MAX) ? UDP_WINDOW_MAX : (window == 0u ? 1u : window);
    const uint32_t credit = (free_frames > reserve) ? free_frames - reserve : 0u;
    return (credit > window) ? window : credit;
}

/// What one look at the group's members found.
typedef struct {
    uint32_t credit;   ///< frames we may send now (UDP_WINDOW_MAX if no other member)
    uint64_t blocker;  ///< inode of the member that limits it (0: none)
    bool saw_self;     ///< our own socket was in the dump
} udp_room_t;

/// One member of the dump: skips our own socket and stalled ones (a stalled
/// one is released once it has read its buffer down to half).
static void udp_room_member(md_bus_sock_t *s, uint64_t inode, uint32_t rmem, uint32_t rcvbuf, udp_room_t *room)
{
    if (inode == s->inode) {
        room->saw_self = true;
        return;
    }
    unsigned slot = 0;
    if (udp_is_stalled(s, inode, &slot)) {
        if (rmem > rcvbuf / 2u) {
            return;
        }
        s->stalled[slot] = 0u;
    }
    const uint32_t c = udp_receiver_credit(rmem, rcvbuf);
    if (c < room->credit) {
        room->credit = c;
        room->blocker = inode;
    }
}

/// NLMSG_DATA without casting away const (clang's -Wcast-qual).
static const void *nlmsg_payload(const struct nlmsghdr *nlh)
{
    return (const uint8_t *)nlh + NLMSG_HDRLEN;
}

/// One message of the dump: a UDP socket; only members of our group and port count.
static void udp_room_msg(md_bus_sock_t *s, const struct nlmsghdr *nlh, in_addr_t group, udp_room_t *room)
{
    const struct inet_diag_msg *m = (const struct inet_diag_msg *)nlmsg_payload(nlh);
    if (nlh->nlmsg_len < NLMSG_LENGTH(sizeof *m) || m->id.idiag_sport != htons(s->port) ||
        m->id.idiag_src[0] != group) {
        return;
    }
    // The attributes (struct rtattr, 4-byte aligned) follow the message.
    const uint8_t *attrs = (const uint8_t *)(m + 1);
    const size_t len = nlh->nlmsg_len - NLMSG_LENGTH(sizeof *m);
    for (size_t off = 0; off + sizeof(struct rtattr) <= len;) {
        struct rtattr a;
        memcpy(&a, attrs + off, sizeof a);
        if (a.rta_len < sizeof a || off + a.rta_len > len) {
            return;
        }
        uint32_t mem[SK_MEMINFO_RCVBUF + 1u];
        if (a.rta_type == INET_DIAG_SKMEMINFO && a.rta_len - sizeof a >= sizeof mem) {
            memcpy(mem, attrs + off + sizeof a, sizeof mem);
            udp_room_member(s, m->idiag_inode, mem[SK_MEMINFO_RMEM_ALLOC], mem[SK_MEMINFO_RCVBUF], room);
        }
        off += ((size_t)a.rta_len + 3u) & ~(size_t)3u;
    }
}

/// Asks the kernel (NETLINK_SOCK_DIAG, what `ss -uam` shows) how full every
/// UDP socket bound to our group and port is. Returns 0 or -errno.
static int udp_room(md_bus_t *bus, udp_room_t *room)
{
    md_bus_sock_t *s = &bus->sock;
    room->credit = UDP_WINDOW_MAX;
    room->blocker = 0u;
    room->saw_self = false;
    static uint32_t seq_counter;
    struct {
        struct nlmsghdr nlh;
        struct inet_diag_req_v2 r;
    } req;
    memset(&req, 0, sizeof req);
    req.nlh.nlmsg_len = sizeof req;
    req.nlh.nlmsg_type = SOCK_DIAG_BY_FAMILY;
    req.nlh.nlmsg_flags = NLM_F_REQUEST | NLM_F_DUMP;
    req.nlh.nlmsg_seq = ++seq_counter;
    req.r.sdiag_family = AF_INET;
    req.r.sdiag_protocol = IPPROTO_UDP;
    req.r.idiag_ext = (uint8_t)(1u << (INET_DIAG_SKMEMINFO - 1));
    req.r.idiag_states = 0xFFFFFFFFu;
    struct sockaddr_nl kernel;
    memset(&kernel, 0, sizeof kernel);
    kernel.nl_family = AF_NETLINK;
    if (sendto(s->diag_fd, &req, sizeof req, 0, (const struct sockaddr *)&kernel, sizeof kernel) < 0) {
        return -errno;
    }
    in_addr_t group = 0;
    (void)inet_pton(AF_INET, MD_BUS_UDP_GROUP, &group);
    for (;;) {
        union {
            struct nlmsghdr align;
            uint8_t bytes[8192];
        } buf;
        const ssize_t n = recv(s->diag_fd, buf.bytes, sizeof buf.bytes, 0);
        if (n < 0) {
            if (errno == EINTR) {
                continue;
            }
            return -errno;
        }
        for (size_t off = 0; off + sizeof(struct nlmsghdr) <= (size_t)n;) {
            const struct nlmsghdr *h = (const struct nlmsghdr *)(const void *)(buf.bytes + off);
            if (h->nlmsg_len < sizeof *h || off + h->nlmsg_len > (size_t)n) {
                return -EPROTO;
            }
            off += NLMSG_ALIGN((size_t)h->nlmsg_len);
            if (h->nlmsg_seq != req.nlh.nlmsg_seq) {
                continue;  // a late answer to an earlier, abandoned request
            }
            if (h->nlmsg_type == NLMSG_DONE) {
                return 0;
            }
            if (h->nlmsg_type == NLMSG_ERROR) {
                const struct nlmsgerr *e = (const struct nlmsgerr *)nlmsg_payload(h);
                return (e->error != 0) ? e->error : -EPROTO;
            }
            udp_room_msg(s, h, group, room);
        }
    }
}

static bool udp_mark_stalled(md_bus_sock_t *s, uint64_t inode)
{
    for (unsigned i = 0; i < MD_BUS_UDP_STALLED_MAX; ++i) {
        if (s->stalled[i] == 0u) {
            s->stalled[i] = inode;
            return true;
        }
    }
    return false;
}

/// Flow control before one send: spends a credit, or looks at the receivers
/// until they have room for a window of frames. While it waits it keeps
/// reading its own socket into the held ring (two senders waiting for each
/// other both progress). A receiver that stays full for flow_wait_us is
/// marked stalled (counted in tx_flow_timeouts) and ignored until it reads.
static void udp_flow(md_bus_t *bus)
{
    md_bus_sock_t *s = &bus->sock;
    if (s->flow == 0u || s->flow_wait_us == 0) {
        return;
    }
    if (s->credit > 0u) {
        s->credit--;
        return;
    }
    bool waited = false;
    int64_t deadline_us = 0;
    for (;;) {
        udp_room_t room;
        if (udp_room(bus, &room) != 0) {
            bus->stats.tx_flow_timeouts++;  // cannot look: this frame goes out unchecked
            return;
        }
        if (room.credit > 0u) {
            s->credit = room.credit - 1u;
            return;
        }
        const int64_t now = md_bus_now_us();
        if (!waited) {
            waited = true;
            bus->stats.tx_flow_waits++;
            deadline_us = now + s->flow_wait_us;
        } else if (now >= deadline_us) {
            bus->stats.tx_flow_timeouts++;
            if (!udp_mark_stalled(s, room.blocker)) {
                return;  // too many stalled receivers: this frame goes out unchecked
            }
            deadline_us = now + s->flow_wait_us;
            continue;
        }
        udp_hold_queued(bus);
        const int64_t until = (now + UDP_FLOW_POLL_US < deadline_us) ? now + UDP_FLOW_POLL_US : deadline_us;
        if (s->held_count < MD_BUS_UDP_HELD_LEN) {
            (void)md_bus_wait_fd(s->fd, POLLIN, until);  // a frame for us ends the wait early
        } else {
            const struct timespec pause = {0, (long)(until - now) * 1000L};
            (void)nanosleep(&pause, NULL);
        }
    }
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
    if (rc == 0 && (rc = set_int(fd, SOL_SOCKET, SO_REUSEADDR, 1)) != 0) {
        *what = "SO_REUSEADDR";
    }
    if (rc == 0 && (rc = set_int(fd, SOL_SOCKET, SO_REUSEPORT, 1)) != 0) {
        *what = "SO_REUSEPORT";
    }
    if (rc == 0 && (rc = set_int(fd, SOL_SOCKET, SO_RXQ_OVFL, 1)) != 0) {
        *what = "SO_RXQ_OVFL";
    }
    if (rc == 0 && (rc = set_int(fd, IPPROTO_IP, IP_MULTICAST_TTL, 0)) != 0) {
        *what = "IP_MULTICAST_TTL 0";
    }
    if (rc == 0 && (rc = set_int(fd, IPPROTO_IP, IP_MULTICAST_LOOP, 1)) != 0) {
        *what = "IP_MULTICAST_LOOP 1";
    }
    if (rc == 0 && (rc = set_int(fd, IPPROTO_IP, IP_MULTICAST_ALL, 0)) != 0) {
        *what = "IP_MULTICAST_ALL 0";
    }
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
    // The stock rmem_max, never more (no SO_RCVBUFFORCE): root and everyone
    // else get the same buffer, and flow control, not the buffer's size,
    // keeps a slow receiver from losing frames. Capped lower by a smaller
    // rmem_max; drops show up in rx_overflow through SO_RXQ_OVFL.
    (void)set_int(fd, SOL_SOCKET, SO_RCVBUF, MD_BUS_UDP_RCVBUF_BYTES);
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

/// Attaches a classic BPF socket filter that drops datagrams carrying our
/// sender id (wire offset 4, after the 8-byte UDP header the filter sees):
/// our own echoes never take room in our receive queue. The kernel counts
/// what a filter drops in the socket's drop count; note_drops (md_bus.c)
/// subtracts one echo per datagram sent. Shorter datagrams pass (receive
/// counts them malformed). Returns 0 or -errno.
static int udp_filter_echoes(int fd, uint32_t sender_id)
{
    struct sock_filter code[] = {
        BPF_STMT(BPF_LD | BPF_W | BPF_LEN, 0),
        BPF_JUMP(BPF_JMP | BPF_JGE | BPF_K, 8u + 8u, 0, 2),  // UDP header + magic..sender id
        BPF_STMT(BPF_LD | BPF_W | BPF_ABS, 8u + 4u),         // sender id, big-endian as on the wire
        BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, sender_id, 1, 0),
        BPF_STMT(BPF_RET | BPF_K, 0xFFFFFFFFu),  // keep
        BPF_STMT(BPF_RET | BPF_K, 0u),           // our echo: drop
    };
    const struct sock_fprog prog = {.len = (unsigned short)(sizeof code / sizeof code[0]), .filter = code};
    return setsockopt(fd, SOL_SOCKET, SO_ATTACH_FILTER, &prog, sizeof prog) == 0 ? 0 : -errno;
}

/// Sets up the flow control: a sock_diag socket, our socket's inode, and one
/// look at the group that must find our own socket. Returns 0 or -errno.
static int udp_flow_open(md_bus_t *bus)
{
    md_bus_sock_t *s = &bus->sock;
    struct stat st;
    if (fstat(s->fd, &st) != 0) {
        return -errno;
    }
    s->inode = (uint64_t)st.st_ino;
    s->diag_fd = socket(AF_NETLINK, SOCK_DGRAM | SOCK_CLOEXEC, NETLINK_SOCK_DIAG);
    if (s->diag_fd < 0) {
        return -errno;
    }
    // A dump is answered at once; the timeout only bounds a kernel that never answers.
    const struct timeval tv = {.tv_sec = 1, .tv_usec = 0};
    (void)setsockopt(s->diag_fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    udp_room_t room;
    int rc = udp_room(bus, &room);
    if (rc == 0 && !room.saw_self) {
        rc = -ENOENT;  // the dump does not show our socket: we could not see the others either
    }
    if (rc != 0) {
        (void)close(s->diag_fd);
        s->diag_fd = -1;
        return rc;
    }
    s->flow = 1u;
    s->flow_wait_us = MD_BUS_UDP_FLOW_WAIT_US;
    s->credit = 0u;
    return 0;
}

int md_bus_udp_set_flow_wait(md_bus_t *bus, int64_t wait_us)
{
    if (wait_us < 0) {
        return -EINVAL;
    }
    if (bus->kind != MD_BUS_UDP || bus->impl == NULL || bus->sock.flow == 0u) {
        return -ENOTSUP;
    }
    bus->sock.flow_wait_us = wait_us;
    bus->sock.credit = 0u;
    return 0;
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
        md_bus_why(why, why_len, "UDP bus %s:%u: %s failed: %s", MD_BUS_UDP_GROUP, (unsigned)port, what, strerror(-rc));
        (void)close(fd);
        return rc;
    }
    md_bus_sock_t *s = &bus->sock;
    memset(s, 0, sizeof *s);
    s->fd = fd;
    s->diag_fd = -1;
    s->port = port;
    s->sender_id = new_sender_id();
    int granted = 0;
    socklen_t glen = sizeof granted;
    s->rcvbuf = (getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &granted, &glen) == 0) ? granted : 0;
    bus->kind = MD_BUS_UDP;
    (void)snprintf(bus->name, sizeof bus->name, "udp:%s:%u", MD_BUS_UDP_GROUP, (unsigned)port);
    bus->impl = s;
    bus->ops = &udp_ops;
    // Echoes not filtered: they are dropped on receive (sender id), but a
    // long send then fills our queue with them, so flow control is off too.
    int frc = udp_filter_echoes(fd, s->sender_id);
    const char *fwhat = "echo filter";
    if (frc == 0) {
        s->echo_filter = 1u;
        fwhat = "sock_diag";
        frc = udp_flow_open(bus);
    }
    if (frc == 0) {
        md_bus_why(why, why_len, "UDP multicast %s:%u on loopback (TTL 0), echo filter, flow control, rcvbuf %d B",
                   MD_BUS_UDP_GROUP, (unsigned)port, s->rcvbuf);
    } else {
        md_bus_why(why, why_len, "UDP multicast %s:%u on loopback (TTL 0), NO flow control (%s: %s), rcvbuf %d B",
                   MD_BUS_UDP_GROUP, (unsigned)port, fwhat, strerror(-frc), s->rcvbuf);
    }
    return 0;
}

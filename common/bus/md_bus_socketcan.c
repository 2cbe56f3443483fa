/// @file md_bus_socketcan.c
/// The SocketCAN bus: one CAN_RAW socket per endpoint, bound to one
/// interface, CAN FD frames enabled, own frames not received back
/// (CAN_RAW_RECV_OWN_MSGS off: every node sees every *other* node's frames).
#include <errno.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include "md_bus.h"
#include "md_bus_internal.h"

#ifndef SO_RCVBUFFORCE
#define SO_RCVBUFFORCE 33 /* Linux; glibc hides it outside _GNU_SOURCE */
#endif

/* Receive buffer asked for: a 10 s recording streams ~10 000 CAN FD frames
 * in a burst, and each one costs about 1 kB of kernel memory (skb truesize);
 * the default (~200 frames) overflows whenever the reader is briefly late. */
#define CAN_RCVBUF_BYTES (16 * 1024 * 1024)

_Static_assert(MD_FRAME_MAX_DATA == CANFD_MAX_DLEN, "md_frame_t must carry a full CAN FD payload");
_Static_assert(MD_FRAME_EXT_ID_MAX == CAN_EFF_MASK && MD_FRAME_STD_ID_MAX == CAN_SFF_MASK,
               "identifier ranges must match SocketCAN's");

static int can_send(md_bus_t *bus, const md_frame_t *frame)
{
    if (!md_frame_valid(frame)) {
        bus->stats.tx_errors++;
        return -EINVAL;
    }
    const bool fd = (frame->flags & MD_FRAME_FLAG_FD) != 0u;
    if (fd && bus->sock.fd_capable == 0u) {
        bus->stats.tx_errors++;
        return -EMSGSIZE;
    }
    struct canfd_frame cf;
    memset(&cf, 0, sizeof cf);
    cf.can_id = frame->id;
    if ((frame->flags & MD_FRAME_FLAG_EXT) != 0u) {
        cf.can_id |= CAN_EFF_FLAG;
    }
    cf.len = frame->len;
    if (fd && (frame->flags & MD_FRAME_FLAG_BRS) != 0u) {
        cf.flags |= CANFD_BRS;
    }
#ifdef CANFD_FDF
    if (fd) {
        cf.flags |= CANFD_FDF;
    }
#endif
    memcpy(cf.data, frame->data, frame->len);
    // Classic frames go out as struct can_frame (CAN_MTU bytes): the layouts
    // agree for the first CAN_MTU bytes, and the size tells the kernel the kind.
    const size_t size = fd ? CANFD_MTU : CAN_MTU;
    const int rc = md_bus_sock_send(bus->sock.fd, &cf, size, NULL, 0);
    if (rc != 0) {
        bus->stats.tx_errors++;
        return rc;
    }
    bus->stats.tx_frames++;
    return 0;
}

/// Converts one received kernel frame. Returns false for what md_frame_t
/// cannot represent (RTR, error frames, odd sizes).
static bool from_kernel(const struct canfd_frame *cf, ssize_t n, md_frame_t *frame)
{
    if ((n != (ssize_t)CAN_MTU && n != (ssize_t)CANFD_MTU) || (cf->can_id & (CAN_RTR_FLAG | CAN_ERR_FLAG)) != 0u) {
        return false;
    }
    memset(frame, 0, sizeof *frame);
    const bool ext = (cf->can_id & CAN_EFF_FLAG) != 0u;
    frame->id = cf->can_id & (ext ? CAN_EFF_MASK : CAN_SFF_MASK);
    frame->flags = ext ? (uint8_t)MD_FRAME_FLAG_EXT : 0u;
    if (n == (ssize_t)CANFD_MTU) {
        frame->flags |= (uint8_t)MD_FRAME_FLAG_FD;
        if ((cf->flags & CANFD_BRS) != 0u) {
            frame->flags |= (uint8_t)MD_FRAME_FLAG_BRS;
        }
    }
    frame->len = cf->len;
    if (!md_frame_valid(frame)) {
        return false;
    }
    memcpy(frame->data, cf->data, frame->len);
    return true;
}

/// Returns 1 frame, 2 discarded, 0 nothing queued, negative error.
static int can_read_one(md_bus_t *bus, md_frame_t *frame)
{
    struct canfd_frame cf;
    union {
        struct cmsghdr align;
        uint8_t space[CMSG_SPACE(sizeof(uint32_t))];
    } ctrl;
    struct iovec iov = {.iov_base = &cf, .iov_len = sizeof cf};
    struct msghdr msg;
    memset(&msg, 0, sizeof msg);
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = ctrl.space;
    msg.msg_controllen = sizeof ctrl.space;
    const ssize_t n = recvmsg(bus->sock.fd, &msg, MSG_DONTWAIT);
    if (n < 0) {
        return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? 0 : -errno;
    }
    md_bus_account_drops(bus, &msg);
    if (!from_kernel(&cf, n, frame)) {
        bus->stats.rx_malformed++;
        return 2;
    }
    return 1;
}

static int can_receive(md_bus_t *bus, md_frame_t *frame, int64_t timeout_us)
{
    return md_bus_sock_receive(bus, frame, timeout_us, can_read_one);
}

static const md_bus_ops_t can_ops = {can_send, can_receive, md_bus_sock_fd, md_bus_sock_close};

/// Interface checks with messages a user can act on. Returns 0 or -errno.
static int check_interface(int fd, const char *ifname, int *ifindex, bool *fd_capable, char *why, size_t why_len)
{
    *ifindex = (int)if_nametoindex(ifname);
    if (*ifindex == 0) {
        md_bus_why(why, why_len,
                   "no interface '%s' (a virtual one: ip link add dev %s type vcan && ip link set %s mtu 72 up)",
                   ifname, ifname, ifname);
        return -ENODEV;
    }
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    (void)snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "%s", ifname);
    if (ioctl(fd, SIOCGIFFLAGS, &ifr) == 0 && (ifr.ifr_flags & IFF_UP) == 0) {
        md_bus_why(why, why_len, "interface '%s' is down (ip link set %s up)", ifname, ifname);
        return -ENETDOWN;
    }
    *fd_capable = ioctl(fd, SIOCGIFMTU, &ifr) == 0 && ifr.ifr_mtu >= (int)CANFD_MTU;
    return 0;
}

static int configure(int fd, int ifindex, const char **what)
{
    const int on = 1;
    const int off = 0;
    if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) != 0) {
        *what = "CAN_RAW_FD_FRAMES";
        return -errno;
    }
    // Off is the kernel default; set explicitly because the bus semantics
    // (no echo to the sender) depend on it.
    if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &off, sizeof off) != 0) {
        *what = "CAN_RAW_RECV_OWN_MSGS";
        return -errno;
    }
    if (setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) != 0) {
        *what = "SO_RXQ_OVFL";
        return -errno;
    }
    // Best effort: FORCE passes rmem_max but needs CAP_NET_ADMIN; without
    // it the kernel caps SO_RCVBUF at rmem_max. Drops stay visible either
    // way (SO_RXQ_OVFL -> md_bus_stats_t.rx_overflow).
    const int rcvbuf = CAN_RCVBUF_BYTES;
    if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &rcvbuf, sizeof rcvbuf) != 0) {
        (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    }
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifindex;
    if (bind(fd, (const struct sockaddr *)&addr, sizeof addr) != 0) {
        *what = "bind (is it a CAN interface?)";
        return -errno;
    }
    return 0;
}

int md_bus_open_socketcan(md_bus_t *bus, const char *ifname, char *why, size_t why_len)
{
    md_bus_set_closed(bus);
    const int fd = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
    if (fd < 0) {
        const int err = errno;
        if (err == EAFNOSUPPORT) {
            md_bus_why(why, why_len, "AF_CAN not supported by this kernel (no SocketCAN)");
        } else {
            md_bus_why(why, why_len, "socket(AF_CAN, SOCK_RAW, CAN_RAW): %s", strerror(err));
        }
        return -err;
    }
    int ifindex = 0;
    bool fd_capable = false;
    int rc = check_interface(fd, ifname, &ifindex, &fd_capable, why, why_len);
    if (rc == 0) {
        const char *what = "?";
        rc = configure(fd, ifindex, &what);
        if (rc != 0) {
            md_bus_why(why, why_len, "SocketCAN on '%s': %s failed: %s", ifname, what, strerror(-rc));
        }
    }
    if (rc != 0) {
        (void)close(fd);
        return rc;
    }
    bus->sock.fd = fd;
    int granted = 0;
    socklen_t glen = sizeof granted;
    bus->sock.rcvbuf = (getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &granted, &glen) == 0) ? granted : 0;
    bus->sock.fd_capable = fd_capable ? 1u : 0u;
    bus->sock.kernel_drops = 0;
    bus->sock.kernel_total = 0;
    bus->kind = MD_BUS_SOCKETCAN;
    (void)snprintf(bus->name, sizeof bus->name, "%s", ifname);
    bus->impl = &bus->sock;
    bus->ops = &can_ops;
    md_bus_why(why, why_len, "SocketCAN on %s (%s)", ifname,
               fd_capable ? "CAN FD" : "classic CAN only: MTU 16, set mtu 72 for FD");
    return 0;
}

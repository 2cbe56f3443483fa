/// @file md_bus.h
/// The host-side transport interface: one small vtable, three buses that carry
/// the same frames (SocketCAN, UDP multicast on loopback, in-process).
///
/// Semantics are those of a CAN bus: every frame a node sends is seen by every
/// *other* node on the bus (not echoed to the sender), in send order per
/// sender. Receive never blocks longer than the timeout asked for.
///
/// Memory: no bus allocates. The socket buses keep their state inside the
/// md_bus_t (`sock`); the in-process bus uses fixed static tables sized by the
/// MD_BUS_INPROC_* constants below. `impl` points into one of those, so an open
/// md_bus_t must stay at the same address (never copy or move it) until
/// md_bus_close(). See docs/bus.md for the wire format and the `auto` rule.
#ifndef MD_BUS_H
#define MD_BUS_H

#include <stddef.h>
#include <stdint.h>

#include "md_frame.h"

/// UDP bus: administratively scoped group (RFC 2365), joined on loopback only.
#define MD_BUS_UDP_GROUP "239.71.0.1"
#define MD_BUS_UDP_PORT_DEFAULT 57731u
/// UDP bus: receive buffer each endpoint asks for with plain SO_RCVBUF (never
/// SO_RCVBUFFORCE): the stock net.core.rmem_max, so every user gets the same
/// buffer (the kernel doubles it: 425984 bytes, ~500 datagrams).
#define MD_BUS_UDP_RCVBUF_BYTES 212992
/// UDP bus: longest a send waits for room in a receiver's socket buffer
/// (flow control, docs/bus.md) before it marks that receiver stalled.
#define MD_BUS_UDP_FLOW_WAIT_US 10000000
/// UDP bus: frames a sender waiting for room at a receiver moves out of its
/// own socket (so that a peer waiting for room in ours progresses too).
#define MD_BUS_UDP_HELD_LEN 64u
/// UDP bus: receivers a sender can mark stalled at once (see md_bus_stats_t).
#define MD_BUS_UDP_STALLED_MAX 4u
/// In-process bus: frames each endpoint can queue before it overflows (power of 2).
#define MD_BUS_INPROC_QUEUE_LEN 4096u
/// In-process bus: endpoints open at once in one process, over all buses.
#define MD_BUS_INPROC_MAX_ENDPOINTS 8u
/// In-process bus: distinct bus names open at once in one process.
#define MD_BUS_INPROC_MAX_BUSES 4u
/// Longest in-process bus name (without "inproc:").
#define MD_BUS_INPROC_NAME_MAX 24u

typedef enum {
    MD_BUS_SOCKETCAN = 1,  ///< raw CAN FD socket on a named interface (vcan0, can0)
    MD_BUS_UDP = 2,        ///< UDP multicast on loopback (hosts without AF_CAN)
    MD_BUS_INPROC = 3      ///< nodes in one process (tests, batch evaluation)
} md_bus_kind_t;

/// Counters every bus keeps; nothing is dropped without a count.
typedef struct {
    uint64_t tx_frames, rx_frames;
    uint64_t tx_errors;         ///< send failed (reported to the caller too)
    uint64_t rx_malformed;      ///< datagram/frame that failed validation (or cannot be
                                ///< represented: SocketCAN RTR/error frames)
    uint64_t rx_overflow;       ///< frames lost because this endpoint's queue was full:
                                ///< in-process ring, or the kernel socket buffer
                                ///< (SO_RXQ_OVFL) for SocketCAN and UDP (UDP: less our own
                                ///< echoes, which its socket filter drops)
    uint64_t tx_flow_waits;     ///< UDP: sends that waited for room at a receiver
    uint64_t tx_flow_timeouts;  ///< UDP: waits that gave up after MD_BUS_UDP_FLOW_WAIT_US
                                ///< (that receiver is then ignored until it reads again;
                                ///< whatever it loses counts in its rx_overflow)
} md_bus_stats_t;

/// State of the socket buses (SocketCAN, UDP), kept inside md_bus_t so that no
/// bus needs the heap or a global pool. Private to common/bus.
typedef struct {
    int fd;                                    ///< the socket; -1 when closed or not a socket bus
    uint32_t sender_id;                        ///< UDP: random non-zero id stamped on our datagrams
    uint32_t tx_seq;                           ///< UDP: sequence number of our next datagram
    uint32_t kernel_drops;                     ///< last cumulative SO_RXQ_OVFL count seen
    uint64_t kernel_total;                     ///< the kernel's drop count since open, unwrapped
    uint8_t echo_filter;                       ///< UDP: our echoes are dropped by a socket filter, and
                                               ///< so counted in kernel_total (one per datagram sent)
    uint16_t port;                             ///< UDP: the group's port
    uint8_t fd_capable;                        ///< SocketCAN: interface MTU allows CAN FD frames
    uint8_t flow;                              ///< UDP: flow control works (sock_diag answered at open)
    int rcvbuf;                                ///< receive buffer the kernel granted (SO_RCVBUF read back), bytes
    int diag_fd;                               ///< UDP: NETLINK_SOCK_DIAG socket of the flow control, or -1
    uint64_t inode;                            ///< UDP: our socket's inode (to tell it apart in sock_diag)
    uint32_t credit;                           ///< UDP: frames we may send before we look at the receivers again
    int64_t flow_wait_us;                      ///< UDP: longest flow-control wait (0: no flow control)
    uint64_t stalled[MD_BUS_UDP_STALLED_MAX];  ///< UDP: inodes of receivers marked stalled
    uint32_t held_head, held_count;            ///< UDP: ring of frames read while sending
    md_frame_t held[MD_BUS_UDP_HELD_LEN];
} md_bus_sock_t;

typedef struct md_bus md_bus_t;

/// Operations of one bus endpoint (one node's connection).
typedef struct {
    /// Sends one frame. Returns 0, or a negative errno-style code: -EINVAL if
    /// !md_frame_valid(frame), -EMSGSIZE for an FD frame on a classic-only
    /// interface, -EAGAIN if the socket stayed full, other -errno from the OS.
    /// Every failure also counts in stats.tx_errors. Success means "on the bus",
    /// not "received": like CAN, the sender cannot know who read the frame.
    int (*send)(md_bus_t *bus, const md_frame_t *frame);
    /// Receives one frame, waiting at most timeout_us (0 = poll; negative is
    /// -EINVAL). Returns 1 with *frame filled (always md_frame_valid), 0 on
    /// timeout, negative on error. Invalid input is counted and skipped, never
    /// returned. The in-process bus never waits (single thread: nothing can
    /// arrive while it would wait).
    int (*receive)(md_bus_t *bus, md_frame_t *frame, int64_t timeout_us);
    /// File descriptor usable with poll(), or -1 (in-process, or closed).
    /// UDP: a waiting send may have moved frames into the held ring (sock.held), which
    /// poll() cannot see: poll only after receive(..., 0) returned 0.
    int (*fd)(const md_bus_t *bus);
    /// Releases the endpoint; safe to call twice. Afterwards every operation
    /// returns -EBADF.
    void (*close)(md_bus_t *bus);
} md_bus_ops_t;

struct md_bus {
    const md_bus_ops_t *ops;
    md_bus_kind_t kind;
    md_bus_stats_t stats;
    char name[32];       ///< "vcan0", "udp:239.71.0.1:57731", "inproc:<n>"
    void *impl;          ///< transport's private state (&sock, or a static inproc slot)
    md_bus_sock_t sock;  ///< socket buses' state (see md_bus_sock_t)
};

/// Opens a bus by spec: "vcan0"/"can0"/any interface name (SocketCAN),
/// "udp" or "udp:<port>" (multicast on loopback), "inproc:<name>" (shared by
/// every endpoint opened with the same name in this process), or "auto"
/// (SocketCAN on vcan0 if that interface exists and AF_CAN works, else UDP on
/// the default port). Writes a one-line explanation of the choice, or of the
/// failure, into `why` (may be NULL; truncated to why_len). Returns 0 or -errno:
/// -EINVAL bad spec, -ENAMETOOLONG, -EAFNOSUPPORT no SocketCAN in this kernel,
/// -ENODEV no such (CAN) interface, -ENETDOWN interface down, -ENOSPC in-process
/// tables full, or the failing socket call's errno. On failure `bus` is left
/// closed (operations return -EBADF). O(1) except the in-process name lookup.
int md_bus_open(md_bus_t *bus, const char *spec, char *why, size_t why_len);

static inline int md_bus_send(md_bus_t *bus, const md_frame_t *f)
{
    return bus->ops->send(bus, f);
}
static inline int md_bus_receive(md_bus_t *bus, md_frame_t *f, int64_t timeout_us)
{
    return bus->ops->receive(bus, f, timeout_us);
}
static inline int md_bus_fd(const md_bus_t *bus)
{
    return bus->ops->fd(bus);
}

/// Writes the endpoint's counters as one line (no newline) that
/// microdrive-session reads back from the logs of its processes:
/// "bus stats: rx N, rx overflow N, rx malformed N, tx N, tx errors N, flow waits N, flow timeouts N".
/// Returns what snprintf returns.
int md_bus_stats_format(const md_bus_stats_t *st, char *out, size_t len);

/// UDP bus: sets the longest flow-control wait of this endpoint (default
/// MD_BUS_UDP_FLOW_WAIT_US; 0 turns flow control off: sends never wait, a
/// slow receiver overflows and counts it). Returns 0, -ENOTSUP if the bus is
/// not UDP or its flow control is unavailable (then `bus->sock.flow` is 0),
/// -EINVAL for a negative wait.
int md_bus_udp_set_flow_wait(md_bus_t *bus, int64_t wait_us);
static inline void md_bus_close(md_bus_t *bus)
{
    bus->ops->close(bus);
}

#endif

/// @file md_bus.h
/// The host-side transport interface: one small vtable, three buses that carry
/// the same frames (SocketCAN, UDP multicast on loopback, in-process).
///
/// Semantics are those of a CAN bus: every frame a node sends is seen by every
/// *other* node on the bus (not echoed to the sender), in send order per
/// sender. Receive never blocks longer than the timeout asked for.
#ifndef MD_BUS_H
#define MD_BUS_H

#include <stddef.h>
#include <stdint.h>

#include "md_frame.h"

typedef enum {
    MD_BUS_SOCKETCAN = 1,   ///< raw CAN FD socket on a named interface (vcan0, can0)
    MD_BUS_UDP = 2,         ///< UDP multicast on loopback (hosts without AF_CAN)
    MD_BUS_INPROC = 3       ///< nodes in one process (tests, batch evaluation)
} md_bus_kind_t;

/// Counters every bus keeps; nothing is dropped without a count.
typedef struct {
    uint64_t tx_frames, rx_frames;
    uint64_t tx_errors;        ///< send failed (reported to the caller too)
    uint64_t rx_malformed;     ///< datagram/frame that failed validation
    uint64_t rx_overflow;      ///< in-process queue full: frames lost
} md_bus_stats_t;

typedef struct md_bus md_bus_t;

/// Operations of one bus endpoint (one node's connection).
typedef struct {
    /// Sends one frame. Returns 0, or a negative errno-style code.
    int (*send)(md_bus_t *bus, const md_frame_t *frame);
    /// Receives one frame, waiting at most timeout_us (0 = poll).
    /// Returns 1 with *frame filled, 0 on timeout, negative on error.
    int (*receive)(md_bus_t *bus, md_frame_t *frame, int64_t timeout_us);
    /// File descriptor usable with poll(), or -1 (in-process).
    int (*fd)(const md_bus_t *bus);
    void (*close)(md_bus_t *bus);
} md_bus_ops_t;

struct md_bus {
    const md_bus_ops_t *ops;
    md_bus_kind_t kind;
    md_bus_stats_t stats;
    char name[32];             ///< "vcan0", "udp:239.71.0.1:57731", "inproc:<n>"
    void *impl;                ///< transport's private state
};

/// Opens a bus by spec: "vcan0"/"can0"/any interface name (SocketCAN),
/// "udp" or "udp:<port>" (multicast on loopback), "inproc:<name>" (shared by
/// every endpoint opened with the same name in this process), or "auto"
/// (SocketCAN on vcan0 if that interface exists, else UDP). Writes a one-line
/// explanation of the choice into `why` (may be NULL). Returns 0 or -errno.
int md_bus_open(md_bus_t *bus, const char *spec, char *why, size_t why_len);

static inline int md_bus_send(md_bus_t *bus, const md_frame_t *f) { return bus->ops->send(bus, f); }
static inline int md_bus_receive(md_bus_t *bus, md_frame_t *f, int64_t timeout_us)
{
    return bus->ops->receive(bus, f, timeout_us);
}
static inline void md_bus_close(md_bus_t *bus) { bus->ops->close(bus); }

#endif

/// @file md_bus_internal.h
/// Shared by the transports of common/bus only; not part of the bus API.
#ifndef MD_BUS_INTERNAL_H
#define MD_BUS_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "md_bus.h"

#include <sys/socket.h>

/// Datagrams/frames one receive call discards (own echoes, malformed) before it
/// gives up and reports a timeout; bounds the loop against a flood.
#define MD_BUS_RX_DISCARD_MAX 1024u
/// How long send waits for room in a full socket buffer before -EAGAIN.
#define MD_BUS_TX_WAIT_US 100000

/// Operations of a closed (or never opened) bus: everything returns -EBADF.
extern const md_bus_ops_t md_bus_closed_ops;

/// Puts `bus` in the closed state (ops, fd -1, impl NULL); keeps the stats.
void md_bus_set_closed(md_bus_t *bus);

/// snprintf into `why` when it is non-NULL and non-empty.
void md_bus_why(char *why, size_t why_len, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/// Monotonic time in microseconds.
int64_t md_bus_now_us(void);

/// Waits until `fd` is readable (events = POLLIN) or writable (POLLOUT) or
/// the monotonic deadline passes. Returns 1 ready, 0 timeout, -errno.
int md_bus_wait_fd(int fd, short events, int64_t deadline_us);

/// Adds the kernel's SO_RXQ_OVFL drop count (cumulative, in the control data
/// of `msg`) to bus->stats.rx_overflow as a delta since the last one seen.
void md_bus_account_drops(md_bus_t *bus, struct msghdr *msg);

/// Brings stats.rx_overflow up to the socket's current drop total
/// (SO_MEMINFO); called when a receive finds the queue empty.
void md_bus_poll_drops(md_bus_t *bus);

/// Sends `len` bytes on a non-blocking socket, waiting up to MD_BUS_TX_WAIT_US
/// for room. `to` may be NULL (connected/bound socket). Returns 0 or -errno.
int md_bus_sock_send(int fd, const void *buf, size_t len, const struct sockaddr *to, socklen_t to_len);

/// Reads at most one frame from a socket bus without blocking: 1 frame read,
/// 0 queue empty, 2 datagram/frame discarded (own echo, malformed), -errno.
typedef int (*md_bus_read_one_fn)(md_bus_t *bus, md_frame_t *frame);

/// The receive operation of every socket bus: reads with `read_one` until a
/// frame arrives, at most MD_BUS_RX_DISCARD_MAX are discarded, or timeout_us
/// passes (polling the socket between reads). Same returns as md_bus_ops_t.receive.
int md_bus_sock_receive(md_bus_t *bus, md_frame_t *frame, int64_t timeout_us, md_bus_read_one_fn read_one);

/// fd and close operations shared by the socket buses.
int md_bus_sock_fd(const md_bus_t *bus);
void md_bus_sock_close(md_bus_t *bus);

int md_bus_open_socketcan(md_bus_t *bus, const char *ifname, char *why, size_t why_len);
int md_bus_open_udp(md_bus_t *bus, uint16_t port, char *why, size_t why_len);
int md_bus_open_inproc(md_bus_t *bus, const char *name, char *why, size_t why_len);

#endif

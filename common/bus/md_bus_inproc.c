/// @file md_bus_inproc.c
/// The in-process bus: endpoints opened with the same name share a bus; a
/// send copies the frame into the ring of every *other* endpoint of that bus.
///
/// Memory is static and fixed (MD_BUS_INPROC_* in md_bus.h): one ring of
/// MD_BUS_INPROC_QUEUE_LEN frames per endpoint slot. Rings live in .bss, so an
/// unused slot costs address space, not RAM.
///
/// Not thread-safe, by design: the in-process bus serves lockstep simulation,
/// where every node runs in one thread. For the same reason receive never
/// waits: nothing can arrive while the only thread is waiting.
///
/// A full receiver ring drops the new frame and counts it in the receiver's
/// stats.rx_overflow. The send still succeeds: on CAN the sender cannot know
/// whether a receiver kept up, so the loss is reported where it happened.
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "md_bus.h"
#include "md_bus_internal.h"

_Static_assert((MD_BUS_INPROC_QUEUE_LEN & (MD_BUS_INPROC_QUEUE_LEN - 1u)) == 0u && MD_BUS_INPROC_QUEUE_LEN >= 2u,
               "ring length must be a power of two");
_Static_assert(MD_BUS_INPROC_QUEUE_LEN <= 65536u, "ring indices are uint32_t with headroom");
_Static_assert(MD_BUS_INPROC_MAX_ENDPOINTS >= 2u && MD_BUS_INPROC_MAX_ENDPOINTS <= 64u,
               "a bus needs two endpoints; the fan-out loop is linear in this");
_Static_assert(MD_BUS_INPROC_MAX_BUSES >= 1u && MD_BUS_INPROC_MAX_BUSES <= 255u, "bus index is a uint8_t");
_Static_assert(sizeof "inproc:" - 1u + MD_BUS_INPROC_NAME_MAX < sizeof(((md_bus_t *)0)->name),
               "md_bus_t.name must hold inproc:<name>");

typedef struct {
    md_frame_t ring[MD_BUS_INPROC_QUEUE_LEN];
    uint32_t head;    ///< next slot to read (free-running, masked on use)
    uint32_t tail;    ///< next slot to write; tail - head = frames queued
    md_bus_t *owner;  ///< NULL: slot free
    uint8_t bus_index;
} inproc_endpoint_t;

typedef struct {
    char name[MD_BUS_INPROC_NAME_MAX + 1u];
    uint32_t endpoints;  ///< open endpoints; 0 = bus slot free
} inproc_bus_t;

static inproc_endpoint_t g_endpoints[MD_BUS_INPROC_MAX_ENDPOINTS];
static inproc_bus_t g_buses[MD_BUS_INPROC_MAX_BUSES];

#define RING_MASK (MD_BUS_INPROC_QUEUE_LEN - 1u)

static int inproc_send(md_bus_t *bus, const md_frame_t *frame)
{
    const inproc_endpoint_t *self = bus->impl;
    if (frame == NULL || !md_frame_valid(frame)) {
        bus->stats.tx_errors++;
        return -EINVAL;
    }
    for (uint32_t i = 0; i < MD_BUS_INPROC_MAX_ENDPOINTS; ++i) {
        inproc_endpoint_t *ep = &g_endpoints[i];
        if (ep == self || ep->owner == NULL || ep->bus_index != self->bus_index) {
            continue;
        }
        if (ep->tail - ep->head >= MD_BUS_INPROC_QUEUE_LEN) {
            ep->owner->stats.rx_overflow++;
            continue;
        }
        ep->ring[ep->tail & RING_MASK] = *frame;
        ep->tail++;
    }
    bus->stats.tx_frames++;
    return 0;
}

static int inproc_receive(md_bus_t *bus, md_frame_t *frame, int64_t timeout_us)
{
    inproc_endpoint_t *self = bus->impl;
    if (frame == NULL || timeout_us < 0) {
        return -EINVAL;
    }
    if (self->tail == self->head) {
        return 0;
    }
    *frame = self->ring[self->head & RING_MASK];
    self->head++;
    bus->stats.rx_frames++;
    return 1;
}

static int inproc_fd(const md_bus_t *bus)
{
    (void)bus;
    return -1;
}

static void inproc_close(md_bus_t *bus)
{
    inproc_endpoint_t *self = bus->impl;
    if (self != NULL && self->owner == bus) {
        inproc_bus_t *b = &g_buses[self->bus_index];
        b->endpoints--;
        if (b->endpoints == 0u) {
            b->name[0] = '\0';
        }
        self->owner = NULL;
        self->head = 0;
        self->tail = 0;
    }
    md_bus_set_closed(bus);
}

static const md_bus_ops_t inproc_ops = {inproc_send, inproc_receive, inproc_fd, inproc_close};

/// Index of the bus named `name`, creating it if needed; -1 if the table is full.
static int find_or_add_bus(const char *name)
{
    int free_index = -1;
    for (uint32_t i = 0; i < MD_BUS_INPROC_MAX_BUSES; ++i) {
        if (g_buses[i].endpoints > 0u && strcmp(g_buses[i].name, name) == 0) {
            return (int)i;
        }
        if (g_buses[i].endpoints == 0u && free_index < 0) {
            free_index = (int)i;
        }
    }
    if (free_index >= 0) {
        (void)snprintf(g_buses[free_index].name, sizeof g_buses[free_index].name, "%s", name);
    }
    return free_index;
}

int md_bus_open_inproc(md_bus_t *bus, const char *name, char *why, size_t why_len)
{
    md_bus_set_closed(bus);
    const size_t n = strnlen(name, MD_BUS_INPROC_NAME_MAX + 1u);
    if (n == 0u || n > MD_BUS_INPROC_NAME_MAX) {
        md_bus_why(why, why_len, "in-process bus name must have 1..%u characters", MD_BUS_INPROC_NAME_MAX);
        return n == 0u ? -EINVAL : -ENAMETOOLONG;
    }
    inproc_endpoint_t *slot = NULL;
    for (uint32_t i = 0; i < MD_BUS_INPROC_MAX_ENDPOINTS && slot == NULL; ++i) {
        if (g_endpoints[i].owner == NULL) {
            slot = &g_endpoints[i];
        }
    }
    const int bus_index = slot != NULL ? find_or_add_bus(name) : -1;
    if (bus_index < 0) {
        md_bus_why(why, why_len, "in-process bus '%s': all %u %s in use", name,
                   slot == NULL ? MD_BUS_INPROC_MAX_ENDPOINTS : MD_BUS_INPROC_MAX_BUSES,
                   slot == NULL ? "endpoints" : "buses");
        return -ENOSPC;
    }
    g_buses[bus_index].endpoints++;
    slot->owner = bus;
    slot->bus_index = (uint8_t)bus_index;
    slot->head = 0;
    slot->tail = 0;
    bus->kind = MD_BUS_INPROC;
    (void)snprintf(bus->name, sizeof bus->name, "inproc:%s", name);
    bus->impl = slot;
    bus->ops = &inproc_ops;
    md_bus_why(why, why_len, "in-process bus '%s' (endpoint %u of this process)", name, (unsigned)(slot - g_endpoints));
    return 0;
}

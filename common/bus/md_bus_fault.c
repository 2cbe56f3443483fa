/// @file md_bus_fault.c
/// Fault-injecting bus wrapper (see md_bus_fault.h).
#include "md_bus_fault.h"

#include <errno.h>
#include <string.h>

#include "md_bus_internal.h"

enum { DIR_TX = 0, DIR_RX = 1 };

static uint64_t splitmix64(uint64_t x)
{
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

/* xorshift64*: small, deterministic on every host; never zero state. */
static uint64_t rng_next(uint64_t *s)
{
    uint64_t x = *s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    *s = x;
    return x * 0x2545F4914F6CDD1Dull;
}

static double rng_uniform(uint64_t *s)
{
    return (double)(rng_next(s) >> 11) * 0x1.0p-53;
}

void md_bus_fault_default_params(md_bus_fault_params_t *p)
{
    memset(p, 0, sizeof *p);
    p->delay_frames = 4u;
    p->directions = MD_BUS_FAULT_TX | MD_BUS_FAULT_RX;
    p->frame_to = UINT64_MAX;
    p->t_from_us = INT64_MIN;
    p->t_to_us = INT64_MAX;
}

const char *md_bus_fault_kind_name(md_bus_fault_kind_t k)
{
    static const char *const names[MD_BUS_FAULT_KINDS] = {"loss", "corrupt", "dup", "delay", "reorder"};
    return ((unsigned)k < (unsigned)MD_BUS_FAULT_KINDS) ? names[k] : "?";
}

static bool fault_active(md_bus_fault_t *f, const md_frame_t *fr, uint32_t dir_bit)
{
    const md_bus_fault_params_t *p = &f->p;
    if ((p->directions & dir_bit) == 0u || (fr->id & p->id_mask) != p->id_match) {
        return false;
    }
    const uint64_t idx = f->c.frames_seen - 1u;
    if (idx < p->frame_from || idx >= p->frame_to) {
        return false;
    }
    if (f->clock != NULL) {
        const int64_t t = f->clock(f->clock_ctx);
        if (t < p->t_from_us || t >= p->t_to_us) {
            return false;
        }
    }
    return true;
}

/* A frame leaving the wrapper: tx to the inner bus, rx to the caller's queue. */
static int emit(md_bus_fault_t *f, int dir, const md_frame_t *fr)
{
    if (dir == DIR_TX) {
        return f->inner->ops->send(f->inner, fr);
    }
    if (f->rx_ready_n < MD_BUS_FAULT_HOLD_MAX + 2u) {
        f->rx_ready[f->rx_ready_n++] = *fr;
        return 0;
    }
    f->bus.stats.rx_overflow++; /* cannot happen: at most hold + 2 due at once */
    return 0;
}

/* Emits held frames whose release count has come, oldest first. */
static int release_due(md_bus_fault_t *f, int dir, bool all)
{
    md_bus_fault_hold_t *h = &f->hold[dir];
    int rc = 0;
    uint32_t kept = 0u;
    for (uint32_t i = 0u; i < h->n; ++i) {
        if (all || h->release_at[i] <= f->dir_count[dir]) {
            const int r = emit(f, dir, &h->frame[i]);
            rc = (rc == 0) ? r : rc;
        } else {
            h->frame[kept] = h->frame[i];
            h->release_at[kept] = h->release_at[i];
            kept++;
        }
    }
    h->n = kept;
    return rc;
}

static bool hold(md_bus_fault_t *f, int dir, const md_frame_t *fr, uint64_t wait)
{
    md_bus_fault_hold_t *h = &f->hold[dir];
    if (h->n >= MD_BUS_FAULT_HOLD_MAX) {
        f->c.hold_full++;
        return false;
    }
    h->frame[h->n] = *fr;
    h->release_at[h->n] = f->dir_count[dir] + wait;
    h->n++;
    return true;
}

/* Applies the fault chosen for one frame; returns the emit status. */
static int apply(md_bus_fault_t *f, int dir, md_frame_t *fr, md_bus_fault_kind_t k, uint64_t bit)
{
    switch (k) {
    case MD_BUS_FAULT_LOSS: return 0;
    case MD_BUS_FAULT_CORRUPT: fr->data[(bit / 8u) % fr->len] ^= (uint8_t)(1u << (bit % 8u)); return emit(f, dir, fr);
    case MD_BUS_FAULT_DUP: {
        const int rc = emit(f, dir, fr);
        return (rc == 0) ? emit(f, dir, fr) : rc;
    }
    case MD_BUS_FAULT_DELAY: return hold(f, dir, fr, f->p.delay_frames) ? 0 : emit(f, dir, fr);
    case MD_BUS_FAULT_REORDER: return hold(f, dir, fr, 1u) ? 0 : emit(f, dir, fr);
    case MD_BUS_FAULT_KINDS:
    default: return emit(f, dir, fr);
    }
}

/* One frame through the pipeline of direction `dir`. */
static int process(md_bus_fault_t *f, int dir, md_frame_t fr)
{
    f->c.frames_seen++;
    f->dir_count[dir]++;
    /* two draws per frame whatever happens: the stream stays aligned */
    const double u = rng_uniform(&f->rng);
    const uint64_t bit = rng_next(&f->rng) % ((uint64_t)MD_FRAME_MAX_DATA * 8u);
    md_bus_fault_kind_t k = MD_BUS_FAULT_KINDS;
    if (fault_active(f, &fr, dir == DIR_TX ? MD_BUS_FAULT_TX : MD_BUS_FAULT_RX)) {
        double acc = 0.0;
        for (uint32_t i = 0u; i < (uint32_t)MD_BUS_FAULT_KINDS && k == MD_BUS_FAULT_KINDS; ++i) {
            acc += f->p.prob[i];
            if (u < acc) {
                k = (md_bus_fault_kind_t)i;
            }
        }
    }
    if (k == MD_BUS_FAULT_CORRUPT && fr.len == 0u) {
        k = MD_BUS_FAULT_KINDS; /* no payload bit to flip */
    }
    const uint64_t full_before = f->c.hold_full;
    const int rc = apply(f, dir, &fr, k, bit);
    if (k != MD_BUS_FAULT_KINDS && f->c.hold_full == full_before) {
        f->c.injected[k]++;
    }
    const int rr = release_due(f, dir, false);
    return (rc != 0) ? rc : rr;
}

static md_bus_fault_t *self(md_bus_t *bus)
{
    return (md_bus_fault_t *)bus->impl;
}

static int fault_send(md_bus_t *bus, const md_frame_t *frame)
{
    if (frame == NULL || !md_frame_valid(frame)) {
        bus->stats.tx_errors++;
        return -EINVAL;
    }
    const int rc = process(self(bus), DIR_TX, *frame);
    if (rc != 0) {
        bus->stats.tx_errors++;
    } else {
        bus->stats.tx_frames++;
    }
    return rc;
}

static bool pop_ready(md_bus_fault_t *f, md_frame_t *out)
{
    if (f->rx_ready_n == 0u) {
        return false;
    }
    *out = f->rx_ready[0];
    f->rx_ready_n--;
    memmove(&f->rx_ready[0], &f->rx_ready[1], f->rx_ready_n * sizeof f->rx_ready[0]);
    f->bus.stats.rx_frames++;
    return true;
}

static int fault_receive(md_bus_t *bus, md_frame_t *frame, int64_t timeout_us)
{
    md_bus_fault_t *f = self(bus);
    if (frame == NULL || timeout_us < 0) {
        return -EINVAL;
    }
    /* bounded: every lost frame costs one iteration, at most RX_DROP_MAX */
    for (uint32_t i = 0u; i <= MD_BUS_FAULT_RX_DROP_MAX; ++i) {
        if (pop_ready(f, frame)) {
            return 1;
        }
        md_frame_t in;
        const int rc = f->inner->ops->receive(f->inner, &in, (i == 0u) ? timeout_us : 0);
        if (rc < 0) {
            return rc;
        }
        if (rc == 0) {
            /* the bus went quiet: whatever was held arrives now */
            (void)release_due(f, DIR_TX, true);
            (void)release_due(f, DIR_RX, true);
            return pop_ready(f, frame) ? 1 : 0;
        }
        (void)process(f, DIR_RX, in);
    }
    return pop_ready(f, frame) ? 1 : 0;
}

static int fault_fd(const md_bus_t *bus)
{
    const md_bus_fault_t *f = (const md_bus_fault_t *)bus->impl;
    return f->inner->ops->fd(f->inner);
}

static void fault_close(md_bus_t *bus)
{
    md_bus_fault_t *f = self(bus);
    f->inner->ops->close(f->inner);
    md_bus_set_closed(bus);
}

static const md_bus_ops_t FAULT_OPS = {fault_send, fault_receive, fault_fd, fault_close};

static bool params_ok(const md_bus_fault_params_t *p)
{
    double sum = 0.0;
    for (uint32_t i = 0u; i < (uint32_t)MD_BUS_FAULT_KINDS; ++i) {
        if (!(p->prob[i] >= 0.0 && p->prob[i] <= 1.0)) {
            return false;
        }
        sum += p->prob[i];
    }
    return sum <= 1.0 + 1e-12 && p->delay_frames >= 1u && p->delay_frames <= MD_BUS_FAULT_HOLD_MAX;
}

int md_bus_fault_wrap(md_bus_fault_t *f, md_bus_t *inner, const md_bus_fault_params_t *p, md_bus_fault_clock_t clock,
                      void *clock_ctx)
{
    if (f == NULL || inner == NULL || p == NULL || !params_ok(p)) {
        return -EINVAL;
    }
    memset(f, 0, sizeof *f);
    f->inner = inner;
    f->p = *p;
    f->clock = clock;
    f->clock_ctx = clock_ctx;
    f->rng = splitmix64(p->seed);
    if (f->rng == 0u) {
        f->rng = 0x9E3779B97F4A7C15ull;
    }
    f->bus.ops = &FAULT_OPS;
    f->bus.kind = inner->kind;
    f->bus.impl = f;
    f->bus.sock.fd = -1;
    f->bus.sock.diag_fd = -1;
    memcpy(f->bus.name, inner->name, sizeof f->bus.name);
    f->bus.name[sizeof f->bus.name - 1u] = '\0';
    return 0;
}

int md_bus_fault_flush(md_bus_fault_t *f)
{
    const int rc = release_due(f, DIR_TX, true);
    (void)release_due(f, DIR_RX, true);
    return rc;
}

md_bus_fault_counters_t md_bus_fault_counters(const md_bus_fault_t *f)
{
    return f->c;
}

/// @file md_bus_fault.h
/// Fault-injecting wrapper around any open md_bus_t: frame loss, corruption,
/// duplication, delay and reordering, seeded and deterministic, with a
/// counter per kind and an activity window (frame index and/or time).
///
/// The wrapper is itself an md_bus_t (`f->bus`): hand `&f->bus` to whatever
/// used the inner endpoint. Faults act on the frames that pass through it in
/// the directions asked for (MD_BUS_FAULT_TX: frames this endpoint sends;
/// MD_BUS_FAULT_RX: frames it receives). Decisions come from one xorshift
/// stream seeded by `seed`, drawn a fixed number of times per frame, so the
/// same frame sequence and seed give the same faults on every run and host.
///
/// Delay and reorder hold frames in a small fixed queue (no heap):
/// - delay: the frame is released after `delay_frames` further frames have
///   passed the wrapper in the same direction (a frame-count clock, so the
///   outcome does not depend on wall time), or when a receive finds the
///   inner bus idle (the bus went quiet: held frames drain in order);
/// - reorder: the frame is held until the next frame of that direction has
///   gone out, i.e. two consecutive frames swap.
/// A full hold queue passes the frame through unfaulted (counted in
/// `hold_full`). Corruption flips one payload bit (the frame stays valid:
/// it models a fault CRC does not catch, e.g. a faulty node's buffer).
///
/// Memory: everything lives in md_bus_fault_t, which must not move while
/// open (it is the bus's impl). Closing it closes the inner bus too.
#ifndef MD_BUS_FAULT_H
#define MD_BUS_FAULT_H

#include <stdbool.h>
#include <stdint.h>

#include "md_bus.h"

/// Frames held at once for delay/reorder, per direction.
#define MD_BUS_FAULT_HOLD_MAX 32u
/// Frames a single receive call discards (lost) before it reports a timeout.
#define MD_BUS_FAULT_RX_DROP_MAX 256u

/// Direction bits.
#define MD_BUS_FAULT_TX 0x1u
#define MD_BUS_FAULT_RX 0x2u

typedef enum {
    MD_BUS_FAULT_LOSS = 0,
    MD_BUS_FAULT_CORRUPT = 1,
    MD_BUS_FAULT_DUP = 2,
    MD_BUS_FAULT_DELAY = 3,
    MD_BUS_FAULT_REORDER = 4,
    MD_BUS_FAULT_KINDS = 5
} md_bus_fault_kind_t;

/// Optional time source for the time window (e.g. the simulator's clock);
/// returns microseconds.
typedef int64_t (*md_bus_fault_clock_t)(void *ctx);

/// What to inject. Probabilities are per frame, each in [0, 1] and summing to
/// at most 1: one uniform draw per frame picks at most one fault (loss,
/// corrupt, dup, delay, reorder in that order of the cumulative sum).
typedef struct {
    double prob[MD_BUS_FAULT_KINDS];
    uint32_t delay_frames;          ///< frames a delayed frame waits (1..MD_BUS_FAULT_HOLD_MAX)
    uint32_t directions;            ///< MD_BUS_FAULT_TX | MD_BUS_FAULT_RX bits (0: none)
    uint32_t id_mask, id_match;     ///< only frames with (id & id_mask) == id_match (mask 0: all)
    uint64_t frame_from, frame_to;  ///< active for frame index in [from, to) (counted over both directions)
    int64_t t_from_us, t_to_us;     ///< and, with a clock, for clock time in [from, to)
    uint64_t seed;                  ///< stream seed (any value; 0 is fine)
} md_bus_fault_params_t;

/// Counters: `injected[kind]` per fault kind, plus bookkeeping.
typedef struct {
    uint64_t injected[MD_BUS_FAULT_KINDS];
    uint64_t frames_seen;  ///< frames that passed the wrapper, both directions
    uint64_t hold_full;    ///< delay/reorder refused: hold queue full
} md_bus_fault_counters_t;

typedef struct {
    md_frame_t frame[MD_BUS_FAULT_HOLD_MAX];
    uint64_t release_at[MD_BUS_FAULT_HOLD_MAX];  ///< direction frame count that frees it
    uint32_t n;
} md_bus_fault_hold_t;

typedef struct {
    md_bus_t bus;  ///< the faulty endpoint: use &bus like any md_bus_t
    md_bus_t *inner;
    md_bus_fault_params_t p;
    md_bus_fault_clock_t clock;
    void *clock_ctx;
    uint64_t rng;
    uint64_t dir_count[2];  ///< frames seen per direction (0 tx, 1 rx)
    md_bus_fault_hold_t hold[2];
    md_frame_t rx_ready[MD_BUS_FAULT_HOLD_MAX + 2u];  ///< frames due to the caller
    uint32_t rx_ready_n;
    md_bus_fault_counters_t c;
} md_bus_fault_t;

/// No faults, both directions, window open forever, delay 4 frames.
void md_bus_fault_default_params(md_bus_fault_params_t *p);

/// Wraps the open endpoint `inner` (not owned until close; must outlive the
/// wrapper). `clock` may be NULL (the time window is then ignored). Returns 0,
/// or -EINVAL for a NULL argument, a probability outside [0, 1] or NaN, a sum
/// above 1, or
/// delay_frames outside 1..MD_BUS_FAULT_HOLD_MAX. O(1).
int md_bus_fault_wrap(md_bus_fault_t *f, md_bus_t *inner, const md_bus_fault_params_t *p, md_bus_fault_clock_t clock,
                      void *clock_ctx);

/// Releases every held frame now (tx: sent on the inner bus; rx: made
/// available to receive). Returns 0 or the first send error. O(held).
int md_bus_fault_flush(md_bus_fault_t *f);

/// Counters so far.
md_bus_fault_counters_t md_bus_fault_counters(const md_bus_fault_t *f);

/// Name of a kind ("loss", "corrupt", "dup", "delay", "reorder"); "?" otherwise.
const char *md_bus_fault_kind_name(md_bus_fault_kind_t k);

#endif

/// @file simnode_act.h
/// Actuator driver node (node 2): executes ACT_CMD on the piezo models of the
/// world and reports ACT_STATUS; latches on ESTOP until NMT clear-e-stop; EMCY
/// for stalls and end stops.
///
/// ACT_STATUS goes out (a) at once for every accepted or refused command,
/// echoing its Seq in CmdSeq (the controller's acknowledgement), (b) whenever
/// the state or the end-stop bits change, (c) periodically: every
/// status_moving_ms while any electrode moves, else every status_idle_ms.
/// While the e-stop is latched every electrode reports State = fault.
#ifndef SIMNODE_ACT_H
#define SIMNODE_ACT_H

#include <stdbool.h>
#include <stdint.h>

#include "simnode.h"
#include "simnode_world.h"

/// Per-electrode bookkeeping of the driver.
typedef struct {
    uint8_t cmd_seq;         ///< Seq of the last ACT_CMD (echoed as CmdSeq)
    uint8_t reported_state;  ///< State field last sent
    uint8_t reported_stops;  ///< EndStops field last sent
} simnode_act_electrode_t;

typedef struct {
    simnode_t node;
    simnode_world_t *world;
    uint32_t status_moving_ms;  ///< periodic ACT_STATUS while moving
    uint32_t status_idle_ms;    ///< periodic ACT_STATUS otherwise
    uint64_t next_status_us;    ///< next periodic report
    uint8_t estop_source;       ///< EstopSource of the latching ESTOP
    simnode_act_electrode_t el[SIMNODE_MAX_ELECTRODES];
} simnode_act_t;

/// Initialises the node (state BOOT) on `world`. Periods must be > 0.
void simnode_act_init(simnode_act_t *a, simnode_world_t *world, bool autostart, bool lockstep,
                      uint32_t status_moving_ms, uint32_t status_idle_ms, simnode_sink_t sink);

/// Reports every electrode (what a controller needs after start/reset) and
/// restarts the periodic schedule at t_us.
void simnode_act_announce(simnode_act_t *a, uint64_t t_us);

/// Handles an ACT_CMD frame at world time t_us: validates (length, electrode,
/// command, direction, count >= 1 and rate >= 1 for a step), refuses when not
/// operational (silently) or e-stopped (ACT_STATUS fault), else starts or
/// halts the motion. Returns the electrode whose motion started, else -1.
int simnode_act_on_cmd(simnode_act_t *a, const md_frame_t *f, uint64_t t_us);

/// ESTOP received: halts every electrode, latches, reports. The EMCY goes out
/// on the transition into the latched state only.
void simnode_act_on_estop(simnode_act_t *a, uint8_t source, uint64_t t_us);

/// Reacts to an NMT command's effect on this node.
void simnode_act_on_nmt(simnode_act_t *a, simnode_nmt_effect_t effect, uint64_t t_us);

/// Earliest time of this node's next event (a step, a periodic report).
uint64_t simnode_act_next_event_us(const simnode_act_t *a);

/// Runs the node's events due at t_us (the world is already at t_us):
/// reports state/end-stop changes (with EMCY on a stall) and periodic status.
void simnode_act_run(simnode_act_t *a, uint64_t t_us);

/// True while any electrode is moving.
bool simnode_act_busy(const simnode_act_t *a);

#endif

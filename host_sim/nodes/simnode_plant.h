/// @file simnode_plant.h
/// The simulator's three plant nodes on one bus endpoint, and the owner of
/// simulated time (docs/sim-process.md has the whole design).
///
/// Received frames are validated here once (id, length, ranges) and routed:
/// ESTOP -> actuator (halt + latch) and front-end (abort stream); NMT -> every
/// addressed node; ACT_CMD -> actuator; REC_REQ -> front-end; SIM_ADVANCE ->
/// the front-end, which lets time pass (lockstep settling). Other ids are
/// not ours and are ignored (counted); malformed frames are counted and
/// ignored.
///
/// Two time modes, one event loop (events in time order; at equal times the
/// actuator, then the sensor, then the front-end):
///  - lockstep (default, deterministic): simulated time moves only while a
///    command the controller gave is in progress. simnode_plant_handle runs
///    the plant from the frame's arrival until no motion and no stream is
///    left, instantly in wall time. The frames one received frame causes form
///    a batch: SIM_CLOCK(t_start) goes before its first frame, and
///    SIM_CLOCK(t_end) after its last one if time moved. SIM_ADVANCE(d) is the
///    one frame that moves time with nothing commanded: the batch always
///    opens with SIM_CLOCK(t) and closes with SIM_CLOCK(t + d) (d > 0), with
///    the periodic frames of (t, t + d] between. The output is a pure
///    function of (scenario, seed, received frames in order).
///  - realtime: the caller moves time with simnode_plant_advance (wall clock);
///    SIM_CLOCK every clock_period_ms.
/// Heartbeats are not part of either: the process sends them on the wall clock.
#ifndef SIMNODE_PLANT_H
#define SIMNODE_PLANT_H

#include <stdbool.h>
#include <stdint.h>

#include "simnode.h"
#include "simnode_act.h"
#include "simnode_fe.h"
#include "simnode_hall.h"
#include "simnode_world.h"

typedef struct {
    bool lockstep;              ///< true: fast deterministic mode; false: realtime
    bool autostart;             ///< nodes operational after boot without NMT start
    double hall_rate_hz;        ///< HALL_READING rate; <= 0: the scenario's rate
    uint32_t calib_period_ms;   ///< HALL_CALIB repeat period
    uint32_t status_moving_ms;  ///< ACT_STATUS period while moving
    uint32_t status_idle_ms;    ///< ACT_STATUS period otherwise
    uint32_t clock_period_ms;   ///< realtime only: SIM_CLOCK period
} simnode_plant_cfg_t;

/// Plant-level counters (each node keeps its own too).
typedef struct {
    uint64_t rx_frames;         ///< every frame handed in
    uint64_t rx_ignored;        ///< not addressed to the plant (other ids, extended ids, our own kinds)
    uint64_t rx_malformed;      ///< failed validation (also counted by the node concerned)
    uint64_t rx_foreign_clock;  ///< SIM_CLOCK from someone else: a second simulator on the bus?
    uint64_t clock_frames;      ///< SIM_CLOCK frames sent
    uint64_t batches;           ///< lockstep batches that sent frames
    uint64_t steps;             ///< SIM_ADVANCE requests served (lockstep settling)
} simnode_plant_stats_t;

typedef struct {
    simnode_plant_cfg_t cfg;
    simnode_world_t *world;  ///< borrowed; outlives the plant
    simnode_sink_t out;      ///< the bus
    uint64_t now_us;         ///< simulated time
    bool batch_open;         ///< lockstep: a batch is being produced
    bool batch_clock_sent;   ///< its opening SIM_CLOCK is out
    uint64_t batch_start_us;
    uint64_t next_clock_us;  ///< realtime SIM_CLOCK schedule
    simnode_act_t act;
    simnode_hall_t hall;
    simnode_fe_t fe;
    simnode_plant_stats_t stats;
    uint64_t silence_t_us;  ///< latest time the node silences were evaluated at
} simnode_plant_t;

/// Defaults: lockstep, autostart, scenario Hall rate, calibration every 10 s,
/// status every 100 ms moving / 1000 ms idle, realtime clock every 10 ms.
void simnode_plant_cfg_default(simnode_plant_cfg_t *cfg);

/// Initialises the three nodes on `world` (state BOOT; nothing is sent).
/// MD_E_ARG for a zero period or a world without electrodes.
md_status_t simnode_plant_init(simnode_plant_t *p, const simnode_plant_cfg_t *cfg, simnode_world_t *world,
                               simnode_sink_t out);

/// Completes the boot of every node at time 0: with autostart each becomes
/// operational and announces itself (ACT_STATUS, HALL_CALIB + HALL_READING,
/// FE_INFO), as one batch. The process sends the boot-up heartbeats first.
void simnode_plant_start(simnode_plant_t *p);

/// Handles one received frame (lockstep: runs the plant until it is quiet).
void simnode_plant_handle(simnode_plant_t *p, const md_frame_t *f);

/// Realtime: runs every event due by t_us and moves time there. Ignored
/// (returns false) in lockstep or for t_us < now.
bool simnode_plant_advance(simnode_plant_t *p, uint64_t t_us);

/// Earliest pending event (realtime scheduling); UINT64_MAX if none.
uint64_t simnode_plant_next_event_us(const simnode_plant_t *p);

/// Fault injection (scenario `node_silent`): sets each node's `silent` flag
/// from the world's silence windows at max(t_us, any earlier time given or
/// reached), so silences follow whichever clock is ahead (the plant's
/// simulated time, or the launcher's clock while the plant stands still in
/// lockstep). The plant calls it itself at every event; launchers call it
/// before sending heartbeats. SIM_CLOCK (simulation infrastructure, not a
/// node's frame) is never silenced. O(silences).
void simnode_plant_silence_at(simnode_plant_t *p, uint64_t t_us);
/// The node with this id (MD_NODE_ACT, _HALL, _FE), or NULL.
simnode_t *simnode_plant_node(simnode_plant_t *p, md_node_id_t id);

#endif

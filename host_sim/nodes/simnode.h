/// @file simnode.h
/// What every simulated plant node shares (actuator driver, position sensor,
/// neural front-end): the NMT state machine, heartbeat and EMCY frames, frame
/// checks, counters and the sink that frames leave through.
///
/// A node never owns a socket, a thread or a clock (libcanard style): the plant
/// (simnode_plant.h) pushes received frames in and hands the node the current
/// simulated time; everything the node sends goes through its sink. Heartbeats
/// are built here but *sent by the process* on the wall clock, so liveness is
/// visible even while simulated time stands still (docs/sim-process.md).
#ifndef SIMNODE_H
#define SIMNODE_H

#include <stdbool.h>
#include <stdint.h>

#include "md_frame.h"
#include "md_protocol.h"

/// Most electrodes a simulated plant serves (scenarios normally have 3).
#define SIMNODE_MAX_ELECTRODES 8u

/// Where a node's frames go. `send` returns 0 or a negative errno-style code
/// (the md_bus convention); the node counts every failure in tx_errors.
typedef struct {
    int (*send)(void *ctx, const md_frame_t *frame);
    void *ctx;
} simnode_sink_t;

/// Counters of one node; nothing is dropped without a count.
typedef struct {
    uint64_t rx_frames;     ///< valid frames this node consumed
    uint64_t rx_malformed;  ///< frames of this node's ids that failed validation (ignored)
    uint64_t rx_refused;    ///< valid frames refused in the node's state (not operational, e-stop, busy)
    uint64_t tx_frames;     ///< frames the sink accepted
    uint64_t tx_errors;     ///< frames the sink refused
    uint64_t emcy_sent;     ///< EMCY frames among tx_frames
    uint64_t tx_silenced;   ///< frames swallowed while the node was silent (fault injection)
} simnode_stats_t;

/// The shared part of a node. Plain data, owned by the caller.
typedef struct {
    uint8_t id;             ///< md_node_id_t of this node
    md_node_state_t state;  ///< NMT state, reported in the heartbeat
    bool autostart;         ///< enter OPERATIONAL on boot/reset without NMT start
    bool lockstep;          ///< heartbeat flag bit2
    bool estop_latched;     ///< heartbeat flag bit0 (only the actuator latches)
    bool fault;             ///< heartbeat flag bit1: a fault is present
    bool silent;            ///< injected fault (scenario node_silent): sends nothing, heartbeat
                            ///< included; the plant sets it from the scenario's windows
    uint32_t resets;        ///< NMT resets so far (the process restarts the uptime)
    uint32_t electrodes;    ///< reported in the heartbeat
    simnode_stats_t stats;
    simnode_sink_t sink;
} simnode_t;

/// What an NMT command did to a node (the node-specific code reacts to it).
typedef enum {
    SIMNODE_NMT_NOT_ADDRESSED = 0,  ///< the command targets another node
    SIMNODE_NMT_ENTER_OP,           ///< start: node is (now or still) operational; re-announce
    SIMNODE_NMT_LEAVE_OP,           ///< stop or pre-op: plant activity must stop
    SIMNODE_NMT_RESET,              ///< reset: application state back to power-on
    SIMNODE_NMT_CLEAR_ESTOP         ///< clear e-stop: the latch is released
} simnode_nmt_effect_t;

/// Initialises a node in state BOOT. O(1).
void simnode_init(simnode_t *n, md_node_id_t id, uint32_t electrodes, bool autostart, bool lockstep,
                  simnode_sink_t sink);

/// Finishes booting (power-on or after reset): OPERATIONAL with autostart,
/// else PRE-OPERATIONAL. Returns true if the node became operational. O(1).
bool simnode_boot_done(simnode_t *n);

/// True if plant frames (commands in, data out) are allowed: OPERATIONAL.
bool simnode_operational(const simnode_t *n);

/// Applies a validated NMT command (command in the md_nmt_command_t set,
/// target 0..127) to the node's state. Reset moves to BOOT, sends the boot-up
/// heartbeat through the sink, then completes the boot (simnode_boot_done).
/// The e-stop latch survives every command except clear-e-stop. O(1).
simnode_nmt_effect_t simnode_nmt_apply(simnode_t *n, uint8_t command, uint8_t target);

/// Builds this node's heartbeat (0x700 + id): NodeState, MD_PROTOCOL_VERSION,
/// Flags (e-stop, fault, lockstep), electrodes and the given uptime. O(1).
void simnode_heartbeat_frame(const simnode_t *n, uint32_t uptime_s, md_frame_t *out);

/// Sends one frame through the sink and counts the outcome. Returns the
/// sink's code (0 or negative). A silent node swallows the frame (counted in
/// tx_silenced) and returns 0: the node does not know it is not heard.
int simnode_send(simnode_t *n, const md_frame_t *frame);

/// Sends an EMCY (0x080 + id) with the given md_emcy_code_t, electrode and info.
/// The error register follows CANopen: bit0 generic always, bit4 for
/// communication errors (0x81xx, 0x82xx), bit7 (manufacturer) for motion.
int simnode_emcy(simnode_t *n, uint16_t code, uint8_t electrode, uint32_t info);

/// Counts a malformed frame addressed to this node (ignored otherwise) and
/// sends EMCY PROTOCOL (Info = frame id) on the 1st, 2nd, 4th, 8th... so a
/// flood of bad frames cannot become a flood of EMCYs. Deterministic.
void simnode_malformed(simnode_t *n, uint32_t frame_id);

/// Prepares an empty frame with a standard id and the given length; FD flag
/// (with bit-rate switch) when the length needs CAN FD. O(1).
void simnode_frame_init(md_frame_t *f, uint32_t id, uint8_t len);

/// True if `f` carries the standard (11-bit) identifier `id`.
bool simnode_frame_is(const md_frame_t *f, uint32_t id);

#endif

/// @file md_node.h
/// The controller as a node on the bus: NMT-like state, heartbeat producer and
/// consumer, latched e-stop, EMCY producer, parameter service and validation of
/// every received frame (libcanard style: the platform pushes frames in with
/// md_node_on_frame and calls md_node_poll for periodic work; the node sends
/// through md_port_t and owns no thread, socket or timer).
///
/// All state is in the caller-owned md_node_t; no heap; every loop is bounded
/// by MD_ELECTRODES, MD_NODE_MONITORED or the parameter/rule tables.
///
/// Safety rules (docs/protocol.md has the full story):
/// - ESTOP (id 0) from anyone latches: halt every electrode, one EMCY
///   MD_EMCY_ESTOP, heartbeat flag, state pre-operational, motion and
///   motion-related parameter sets refused. Only NMT clear-e-stop unlatches it;
///   reset-node does not. Clearing never restarts motion: NMT start is needed.
/// - A monitored node (actuator, sensor, front-end) that has been heard and then
///   stays silent longer than heartbeat_timeout_ms: one EMCY
///   MD_EMCY_HEARTBEAT_LOST (Info = node id), halt every electrode, motion
///   inhibited until its heartbeat returns (then an EMCY MD_EMCY_NONE, Info =
///   node id, notes that it is back).
/// - A frame that fails validation is counted by kind and changes nothing, with
///   one fail-safe exception: a malformed frame with id 0 (ESTOP) still latches
///   the e-stop (source MD_NODE_ESTOP_SOURCE_UNKNOWN).
#ifndef MD_NODE_H
#define MD_NODE_H

#include <stdbool.h>
#include <stdint.h>

#include "md_config.h"
#include "md_frame.h"
#include "md_params.h"
#include "md_port.h"
#include "md_protocol.h"

/// Nodes whose heartbeat the controller supervises: actuator, sensor, front-end.
#define MD_NODE_MONITORED 3u

/// EMCY Electrode value for errors that concern no single electrode.
#define MD_NODE_EMCY_NO_ELECTRODE 0xFFu

/// EMCY Info / estop source recorded for an ESTOP frame too malformed to decode.
#define MD_NODE_ESTOP_SOURCE_UNKNOWN 0xFFu

/// EMCY ErrorRegister bits (CANopen object 0x1001 meanings).
#define MD_NODE_ERREG_GENERIC 0x01u        ///< any error active
#define MD_NODE_ERREG_COMMUNICATION 0x10u  ///< heartbeat lost or protocol error
#define MD_NODE_ERREG_MANUFACTURER 0x80u   ///< e-stop latched

_Static_assert(MD_ELECTRODES <= 8u, "halt_pending is an 8-bit mask");

/// Supervision of one remote node's heartbeat.
typedef struct {
    uint8_t node_id;     ///< MD_NODE_ACT, MD_NODE_HALL or MD_NODE_FE
    bool seen;           ///< a valid heartbeat arrived since init/reset/enable
    bool lost;           ///< silent longer than the timeout; motion inhibited until it is back
    uint8_t last_state;  ///< NodeState of its last heartbeat
    uint64_t last_us;    ///< arrival time of its last heartbeat
} md_node_monitor_t;

/// Diagnostic counters; every one is readable as a parameter (md_params.h, 0x30xx).
/// They survive NMT reset-node so that the evidence of a fault stays readable.
typedef struct {
    uint32_t rx_frames;     ///< every frame pushed in
    uint32_t rx_malformed;  ///< bad length/FD flag + bad range + invalid frames
    uint32_t rx_unknown_id;
    uint32_t rx_bad_length;
    uint32_t rx_bad_range;
    uint32_t rx_bad_sequence;
    uint32_t rx_id_conflict;  ///< someone else sent an id only the controller sends
    uint32_t tx_frames;
    uint32_t tx_failures;
    uint32_t emcy_sent;
    uint32_t heartbeat_lost;
    uint32_t node_back;
    uint32_t estop_events;
    uint32_t nmt_refused;
    uint32_t cycles_done;     ///< electrode cycles completed (md_cycle)
    uint32_t cycles_skipped;  ///< cycles whose processing failed (md_cycle)
    uint32_t rec_failed;      ///< recordings aborted/incomplete/timed out (md_cycle)
    uint32_t moves_failed;    ///< servo moves that failed (md_cycle)
} md_node_counters_t;

/// Last accepted state of one electrode's peripherals (for the closed loop).
typedef struct {
    uint8_t act_state;  ///< ACT_STATUS State
    uint8_t act_seq;    ///< Seq of the last ACT_CMD sent
    bool hall_seen;
    uint8_t hall_seq;       ///< Seq of the last accepted HALL_READING
    uint16_t hall_code;     ///< RawCode of the last accepted HALL_READING
    uint16_t rec_next_seq;  ///< REC_DATA Seq expected next in this interval
    uint32_t rec_samples;   ///< samples accepted in this interval
} md_node_electrode_t;

/// The whole node. Treat fields as read-only outside md_node.c.
typedef struct {
    md_port_t port;
    md_params_t params;
    md_node_state_t state;
    bool boot_pending;  ///< boot-up heartbeat not sent yet (poll sends it)
    bool estop_latched;
    uint8_t estop_source, estop_reason;
    uint64_t boot_us;  ///< time of md_node_init: origin of uptime
    uint64_t next_heartbeat_us;
    bool protocol_emcy_sent;    ///< a protocol EMCY went out (inhibit applies)
    uint64_t protocol_emcy_us;  ///< when it went out
    uint64_t sim_time_us;       ///< last SIM_CLOCK (lockstep mode)
    uint8_t halt_pending;       ///< electrodes (bit e) whose halt still has to be sent
    md_node_monitor_t monitor[MD_NODE_MONITORED];
    md_node_electrode_t electrode[MD_ELECTRODES];
    md_node_counters_t counters;
} md_node_t;

/// Initialises the node in state boot with default parameters; nothing is sent
/// until the first md_node_poll (which sends the boot-up heartbeat).
/// `port->send` must be non-NULL; the port is copied. MD_E_ARG otherwise.
md_status_t md_node_init(md_node_t *node, const md_port_t *port, uint64_t now_us);

/// Handles one received frame: validates it (id known, length and FD flag per
/// the DBC, signal ranges, stream sequence) and acts on it. MD_OK if accepted
/// (including frames valid but addressed to another node), MD_E_FRAME if
/// rejected (counted by kind, state unchanged), MD_E_ARG on NULL arguments.
/// May send frames (responses, EMCY, halts). O(table sizes).
md_status_t md_node_on_frame(md_node_t *node, const md_frame_t *frame, uint64_t now_us);

/// Periodic work: boot-up, heartbeat production, heartbeat supervision,
/// retries of halts that could not be sent. Call at least by
/// md_node_next_deadline_us(). MD_OK, or MD_E_IO if a send failed (counted).
md_status_t md_node_poll(md_node_t *node, uint64_t now_us);

/// Earliest time md_node_poll has work to do (a heartbeat due, a monitored
/// node's timeout expiring, a pending boot-up or halt: then now).
uint64_t md_node_next_deadline_us(const md_node_t *node, uint64_t now_us);

/// True if an electrode may move now: operational, e-stop not latched, no
/// monitored node lost, and the actuator heard from (when it is monitored).
bool md_node_motion_allowed(const md_node_t *node);

/// Sends one ACT_CMD step. MD_E_STATE if motion is not allowed, MD_E_ARG on a
/// bad electrode/direction, MD_E_IO if the send failed (counted).
md_status_t md_node_step(md_node_t *node, uint8_t electrode, uint8_t direction, uint16_t steps, uint16_t rate_hz);

/// Sends one frame the controller owns (telemetry, REC_REQ, SIM_ADVANCE, ...):
/// counted in tx_frames / tx_failures. `fd` marks a CAN FD frame. MD_E_ARG
/// on a bad length, MD_E_IO if the platform refused it.
md_status_t md_node_send(md_node_t *node, uint32_t id, const uint8_t *data, int len, bool fd);

/// Sends EMCY_CTRL with `code`, `electrode` and `info` (counted). MD_E_IO on failure.
md_status_t md_node_emcy(md_node_t *node, md_emcy_code_t code, uint8_t electrode, uint32_t info);

/// Heartbeat Flags byte (MD_HB_FLAG_*) as it would be sent now.
uint8_t md_node_heartbeat_flags(const md_node_t *node);

/// Forgets what was heard of monitored node `node_id` (md_node_id_t) when its
/// supervision is disabled (parameter monitor_*), which lifts the motion
/// inhibit its silence caused; no-op while it is enabled or for an id that is
/// not monitored. The parameter service calls it after a set. O(1).
void md_node_monitor_refresh(md_node_t *node, uint8_t node_id);

#endif

/// @file md_controller.h
/// The whole controller as one object: the node (NMT, heartbeat, e-stop,
/// EMCY, parameters: md_node.h) plus the autonomous positioning cycle of every
/// electrode (record, process, score, decide, move, settle, telemetry; thesis
/// §2.2). libcanard style: the platform pushes every received frame in with
/// md_controller_on_frame(), calls md_controller_poll() by
/// md_controller_next_deadline_us(), and provides md_port_t (send, clock).
/// The controller owns no thread, socket or timer, and uses no heap: its
/// state is one static instance (md_controller_instance()).
///
/// The same four calls drive it in every host: the posix process
/// (microdrive-fw), the Cortex-M7 image (microdrive-fw-m7) and the in-process
/// session launcher (microdrive-session), which owns the bus and the virtual
/// clock.
///
/// Time: `now_us` arguments are the platform's monotonic clock (heartbeats
/// and their supervision run on it). In lockstep with the simulator (its
/// heartbeat carries the lockstep flag, or SIM_CLOCK frames arrive) the cycle
/// takes its own time from SIM_CLOCK and waits for the simulator's answers
/// (REC_END, final ACT_STATUS, the SIM_CLOCK closing a SIM_ADVANCE) instead of
/// timers; the wall clock then only bounds how long it waits (a timeout).
#ifndef MD_CONTROLLER_H
#define MD_CONTROLLER_H

#include <stdint.h>

#include "md_status.h"
#include "md_cycle.h"
#include "md_frame.h"
#include "md_node.h"
#include "md_port.h"

/// All controller state: the node and the per-electrode cycles with their one
/// shared processing workspace. Treat as opaque outside firmware/app.
struct md_controller {
    md_node_t node;    ///< NMT, heartbeat, e-stop, parameters, frame validation
    md_cycle_t cycle;  ///< electrodes' cycles (record .. telemetry) and the shared workspace
};
typedef struct md_controller md_controller_t;

/// The one statically allocated instance (no heap). Never NULL. O(1).
md_controller_t *md_controller_instance(void);

/// Initialises node and cycles (node in boot; the boot-up heartbeat goes out
/// on the first poll). `port->send` must be non-NULL (copied). MD_E_ARG on
/// NULL arguments, MD_E_STATE if the parameter table is inconsistent.
/// O(size of the state) (clears it).
md_status_t md_controller_init(md_controller_t *c, const md_port_t *port, uint64_t now_us);

/// Handles one received frame: the node validates it first (a rejected frame
/// is counted there and changes nothing else); accepted frames then drive the
/// cycle (REC_DATA into the detector, REC_END, ACT_STATUS, HALL_READING,
/// HALL_CALIB, FE_INFO, SIM_CLOCK). May send frames and may run a whole
/// interval's processing (REC_END). `now_us`: platform monotonic time.
void md_controller_on_frame(md_controller_t *c, const md_frame_t *f, uint64_t now_us);

/// Periodic work of node and cycles: heartbeats, supervision, starting the
/// next cycle step, timed waits (real-time settling, answer timeouts).
/// Call at least at md_controller_next_deadline_us().
void md_controller_poll(md_controller_t *c, uint64_t now_us);

/// Earliest platform time at which md_controller_poll() has work to do; 0 if
/// it has work now. Between two calls of on_frame/poll this value is stable.
uint64_t md_controller_next_deadline_us(const md_controller_t *c);

/// The node, e.g. to set parameters (md_params_set on node->params) before
/// the first poll. Never NULL for a non-NULL c.
md_node_t *md_controller_node(md_controller_t *c);

#endif

/// @file md_cycle.h
/// The autonomous positioning cycle (thesis §2.2, Fig. 2.2), every electrode
/// independently, one electrode at a time (round robin):
///   record  REC_REQ; REC_DATA streamed into the detector (ic_push), REC_END;
///   process PCA of the interval's windows, features, noise covariance Ξ,
///           MHTC step with the interval's basis, per-track SNR, isolation
///           distance of the dominant track (pipeline/interval_chain.h,
///           through md_interval.h);
///   decide  SNR curve (§2.2.3) + SFSM (§2.2.4, Table 2.1);
///   move    depth servo to depth + step (md_servo.h), only if the SFSM asked
///           and the node allows motion;
///   settle  SIM_ADVANCE in lockstep, a timed wait otherwise;
///   and telemetry of every cycle (md_telemetry.h).
///
/// Memory: per electrode md_electrode_t (tracker, curves, SFSM, servo) and
/// ONE md_workspace_t shared by whichever electrode is being recorded or
/// processed; all of it lives in md_cycle_t, which the controller owns
/// statically (md_controller.h). No heap.
///
/// Time: cycle logic uses the simulator's time (SIM_CLOCK) in lockstep and
/// the platform's monotonic clock otherwise; every wait for an answer is also
/// bounded in platform time (a timeout ends the cycle, counted). In lockstep
/// that bound only guards against a dead plant: it runs from the plant's
/// latest frame (heartbeats included), so a slow but live simulator never
/// changes a decision; a dead one is stopped by heartbeat supervision
/// (docs/safety.md H6) and, 5 s after its last frame, by the timeout. A live
/// plant whose answer got lost (heartbeats, but no answer frame for 30 s
/// after the request or the last answer) times out too, so a lost frame on a
/// socket bus never hangs the cycle.
#ifndef MD_CYCLE_H
#define MD_CYCLE_H

#include <stdbool.h>
#include <stdint.h>

#include "control/approach_guard.h"
#include "control/sfsm.h"
#include "control/snr_curve.h"
#include "md_config.h"
#include "md_frame.h"
#include "md_node.h"
#include "md_servo.h"
#include "pipeline/interval_chain.h"
#include "tracking/mhtc.h"

/// TLM_STATUS Flags bits (docs/controller.md).
#define MD_TLM_F_SKIPPED 0x0001u           ///< processing failed: cycle skipped, tracks and SFSM kept
#define MD_TLM_F_REC_FAILED 0x0002u        ///< recording aborted / out of sequence / incomplete / timed out
#define MD_TLM_F_MOVE 0x0004u              ///< the SFSM asked for a step and the servo starts it
#define MD_TLM_F_INHIBITED 0x0008u         ///< the SFSM asked for a step but motion is not allowed
#define MD_TLM_F_CLAMPED 0x0010u           ///< the SFSM shortened the step to the depth window
#define MD_TLM_F_LAST_MOVE_OK 0x0020u      ///< the previous move converged
#define MD_TLM_F_LAST_MOVE_FAILED 0x0040u  ///< the previous move ended otherwise (see moves_failed)
#define MD_TLM_F_LOCKSTEP 0x0080u          ///< simulator lockstep: cycle time is SIM_CLOCK
#define MD_TLM_F_NO_DEPTH 0x0100u          ///< no calibrated Hall depth: no decision, no motion
#define MD_TLM_F_GUARD_LIMITED 0x0200u     ///< the approach guard shortened, cancelled or reversed the SFSM's step
#define MD_TLM_F_GUARD_RETRACT 0x0400u     ///< the approach guard ordered a retraction
#define MD_TLM_F_GUARD_CEILING 0x0800u     ///< an approach-guard ceiling holds after this cycle
#define MD_TLM_REASON_SHIFT 16u            ///< bits 16..23: sfsm_reason_t of the decision

/// Where one electrode is in its cycle.
typedef enum {
    MD_CYC_IDLE = 0,   ///< waiting for its turn / for the node to be operational
    MD_CYC_RECORDING,  ///< REC_REQ sent; REC_DATA streaming
    MD_CYC_PROCESS,    ///< REC_END received; poll processes the interval
    MD_CYC_MOVING,     ///< servo move in progress
    MD_CYC_SETTLING    ///< waiting settle_ms before the next electrode's turn
} md_cycle_phase_t;

/// What a waiting phase waits for (besides its frames).
typedef enum {
    MD_WAIT_NONE = 0,
    MD_WAIT_SIM,  ///< lockstep: SIM_CLOCK reaching wait_sim_us
    MD_WAIT_WALL  ///< real time: platform clock reaching wait_wall_us
} md_wait_t;

/// Per-electrode state that persists across cycles.
typedef struct {
    mhtc_state_t mhtc;  ///< tracker (thesis ch. 4)
    sc_table_t curves;  ///< SNR curve per track (§2.2.3)
    sfsm_t sfsm;        ///< supervisory state machine (§2.2.4)
    ag_state_t guard;   ///< approach guard after the SFSM (approach_guard.h)
    double guard_amp;   ///< robust amplitude of the last processed interval
    md_servo_t servo;   ///< depth servo
    md_cycle_phase_t phase;
    uint16_t cycle;           ///< cycles completed (TLM Cycle, wraps)
    uint16_t interval_id;     ///< REC_REQ IntervalId of the current/last interval
    uint32_t rec_requested;   ///< NumSamples asked
    uint32_t rec_samples;     ///< samples streamed into the detector
    bool rec_bad;             ///< a frame of this interval was lost or rejected
    md_status_t rec_status;   ///< first ic_push failure of this interval (MD_OK if none)
    uint64_t rec_start_us;    ///< cycle time of the interval's first sample
    bool rec_clock_seen;      ///< a SIM_CLOCK arrived since the REC_REQ (lockstep start time)
    bool rec_end_ok;          ///< lockstep: a complete REC_END arrived, the batch's closing SIM_CLOCK not yet
    bool fe_info;             ///< FE_INFO received
    uint32_t sample_rate_hz;  ///< from FE_INFO
    double gain_uv;           ///< µV per ADC count, from FE_INFO
    bool resume;              ///< operator resume (NMT start) not yet seen by the SFSM
    double depth_um;          ///< depth used by the last decision
    double tracked_depth_um;  ///< depth of the last interval the tracker processed
    bool tracked_depth_ok;    ///< tracked_depth_um is a measurement
    double move_um;           ///< travel since that interval (0 if unknown): the tracker's Q grows with it
    double target_um;         ///< requested target of the last decision
    bool has_dominant;
    uint32_t dominant;     ///< dominant track id
    double snr, iqm;       ///< of the dominant track
    uint32_t flags;        ///< MD_TLM_F_* of the last cycle
    uint64_t cost_detect;  ///< work (md_port_t work_now units) of this interval's detection (REC_DATA)
    uint64_t cost_chain;   ///< work of processing, scoring and deciding the last interval
    md_servo_result_t last_move;
    /* counters */
    uint32_t cycles, skipped, rec_failed, moves, moves_failed, inhibited, timeouts, guard_limited;
} md_electrode_t;

/// The interval being processed and the scratch of every stage
/// (pipeline/interval_chain.h). One for all electrodes.
typedef ic_workspace_t md_workspace_t;

/// Scratch of one electrode's decision (the SFSM's and the approach guard's
/// inputs and outputs), kept out of the stack frame that also calls down the
/// tracker, the deepest path (docs/static-analysis.md). One for all electrodes.
typedef struct {
    sfsm_input_t sfsm_in;
    sfsm_output_t sfsm_out;
    ag_unit_t unit[AG_UNITS_MAX];
} md_decision_scratch_t;

/// All cycles and the shared workspace.
typedef struct {
    md_electrode_t el[MD_ELECTRODES];
    md_workspace_t ws;
    md_decision_scratch_t dec;
    uint8_t active;        ///< electrode whose turn it is
    bool lockstep;         ///< the front-end's heartbeat carries the lockstep flag
    bool was_operational;  ///< node state at the previous call (resume detection)
    md_wait_t wait;
    uint64_t wait_sim_us;      ///< MD_WAIT_SIM: simulated time that ends the wait
    uint32_t wait_step_us;     ///< MD_WAIT_SIM: the SIM_ADVANCE's duration (anchored at the next SIM_CLOCK)
    uint64_t wait_wall_us;     ///< MD_WAIT_WALL: platform time that ends the wait
    uint64_t timeout_wall_us;  ///< the current wait/answer ends here in platform time
    uint64_t plant_alive_us;   ///< platform time of the plant's latest frame (lockstep timeouts)
    uint64_t answer_us;        ///< platform time of the latest request or answer frame (lockstep)
    uint8_t sim_token;         ///< SIM_ADVANCE Token
    uint32_t cycles;           ///< cycles completed, all electrodes
} md_cycle_t;

/// Resets every electrode (trackers, curves, SFSM in Spike Search, servo
/// without calibration) with the node's current parameters. MD_E_ARG on NULL,
/// or the first error of a unit's init. O(size of the state).
md_status_t md_cycle_init(md_cycle_t *c, const md_node_t *node);

/// A frame the node has validated (`accepted`) or rejected. Drives the
/// recording, the servo's inputs, FE_INFO and the lockstep detection.
void md_cycle_on_frame(md_cycle_t *c, md_node_t *node, const md_frame_t *f, bool accepted, uint64_t now_us);

/// Advances the active electrode's cycle: starts recordings, processes a
/// finished interval, drives the servo, ends waits, enforces timeouts and
/// aborts everything when motion/recording is no longer allowed.
void md_cycle_poll(md_cycle_t *c, md_node_t *node, uint64_t now_us);

/// Earliest platform time at which md_cycle_poll has work (0: now;
/// UINT64_MAX: only frames can make progress).
uint64_t md_cycle_next_deadline_us(const md_cycle_t *c, const md_node_t *node);

/// Cycle time now: SIM_CLOCK in lockstep, else the platform clock.
uint64_t md_cycle_time_us(const md_cycle_t *c, const md_node_t *node, uint64_t now_us);

#endif

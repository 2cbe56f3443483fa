/// @file md_servo.h
/// Depth servo of one electrode (thesis ch. 5: stick-slip piezo actuator with
/// sub-micron, imprecise steps; Hall sensor read-out of the carrier depth).
///
/// Pure logic, no I/O: the cycle (md_cycle.h) feeds it the Hall readings,
/// the calibration frames and the actuator's status, and executes the action
/// it returns (send an ACT_CMD step, let time pass for fresh readings, or
/// finished). One move = a bounded number of iterations of
///   measure (average of avg_n fresh readings, polynomial calibration in the
///   normalised code) -> command round(error / learned step) steps -> wait
///   for the actuator's final status,
/// until |error| <= tol_um. The effective step length is learned per
/// direction from the Hall displacement of every move (stick-slip drives
/// advance and retract by different amounts, and their step varies).
///
/// Safety, enforced here whatever the caller asks:
/// - the target is clamped into the allowed region: the depth window
///   [win_min, win_max] intersected with [d0 - step_max, d0 + step_max] about
///   the depth d0 measured when the move starts (Δmax per cycle);
/// - a command never plans to pass the region's edge even if the steps were
///   MD_SERVO_STEP_SAFETY times longer than learned;
/// - the steps commanded in one move, each direction counted at its learned
///   step length (at least MD_SERVO_STEP_FLOOR × step_nm), never add up to more
///   than the distance from d0 to the region's edge: a sensor that stops
///   following (stuck, dead) cannot make the servo command more than Δmax;
/// - the commands of one move grow from a probe: the first carries at most
///   MD_SERVO_PROBE_STEPS steps, each later one at most MD_SERVO_CHUNK_GROWTH
///   times the steps already commanded in the move, and each is measured
///   before the next goes out. A drive that runs against the command (a
///   slipping carrier) is therefore caught after a probe's travel, not after
///   a whole move's worth of steps (docs/safety.md, H4);
/// - stalls (ACT_STATUS stalled, or no Hall change for a commanded travel),
///   end stops and actuator faults end the move (no retry). A no-change stall
///   marks the sensor suspect: the next move does not start while every
///   fresh reading still repeats the stuck code;
/// - a measured displacement against the commanded direction, or far beyond
///   the commanded travel, is measured again from independent readings (one
///   Hall glitch must not stop the electrode); if it persists the actuator is
///   running away (slipping): the move ends and motion is LATCHED off until
///   md_servo_init() or md_servo_clear_fault() (operator action);
/// - depths are the median of the readings (robust to Hall glitches);
/// - no calibration or no fresh readings: no motion;
/// - once calibrated, a coefficient that arrives with another value is only
///   applied when the next repetition carries the same value, and another
///   coefficient count only when the next frame carries it too: one corrupted
///   HALL_CALIB payload that passed the frame checks cannot shift the depth
///   (docs/fault-campaign.md, bus_corrupt).
/// The caller decides WHETHER to move at all (SFSM, node state, recording).
#ifndef MD_SERVO_H
#define MD_SERVO_H

#include <stdbool.h>
#include <stdint.h>

#include "md_status.h"

#define MD_SERVO_CAL_MAX 16u          ///< calibration coefficients (degree <= 15)
#define MD_SERVO_AVG_MAX 16u          ///< Hall readings kept for averaging
#define MD_SERVO_ITER_MAX 32u         ///< bound of max_iter
#define MD_SERVO_STEP_SAFETY 1.5      ///< planned travel × this must stay inside the region
#define MD_SERVO_STALL_FRACTION 0.25  ///< less Hall travel than this × expected counts as "no motion"
#define MD_SERVO_STALL_MIN_UM 2.0     ///< expected travel below this is never judged a stall
#define MD_SERVO_STALL_REPEATS 2u     ///< consecutive no-motion moves before a stall is declared
#define MD_SERVO_NOISE_UM 1.0         ///< allowance for the median's Hall noise in the motion checks
/// The per-move travel budget counts a step as at least this fraction of
/// step_nm: stick-slip retract steps run 0.8-0.9 of the advance step, so the
/// learned length is used, but a drifting estimate cannot buy many more steps.
#define MD_SERVO_STEP_FLOOR 0.75
/// Steps of a move's first command: at 40 nm a probe of 0.4 µm; a drive that
/// slips 2 µm back on every step (50 step lengths, beyond any stick-slip
/// stroke) is caught 20 µm away, inside Δmax.
#define MD_SERVO_PROBE_STEPS 10u
/// A later command of the move carries at most this × the steps commanded
/// before it (10, 30, 120, 480 ...: a 30 µm move takes 5 commands).
#define MD_SERVO_CHUNK_GROWTH 3u
#define MD_SERVO_CAL_INDEX_MID 0xF0u   ///< HALL_CALIB CoeffIndex of code_mid (DBC comment)
#define MD_SERVO_CAL_INDEX_HALF 0xF1u  ///< HALL_CALIB CoeffIndex of code_half

/// Tunables (md_params rows servo_*).
typedef struct {
    double tol_um;      ///< converged when |target - depth| <= tol_um (> 0; 2 µm)
    uint8_t max_iter;   ///< step commands per move, 1..MD_SERVO_ITER_MAX
    uint8_t avg_n;      ///< readings averaged per measurement, 1..MD_SERVO_AVG_MAX
    double step_nm;     ///< initial estimate of one step's travel, both directions (> 0)
    uint16_t rate_hz;   ///< ACT_CMD StepRate_hz (>= 1)
    uint32_t wait_us;   ///< time to let pass when fresh readings are missing (> 0)
    uint8_t max_waits;  ///< consecutive such waits before MD_SERVO_R_NO_SENSOR (>= 1)
} md_servo_config_t;

/// What the servo wants the caller to do now.
typedef enum {
    MD_SERVO_A_NONE = 0,  ///< nothing: waiting for an ACT_STATUS or a reading
    MD_SERVO_A_STEP,      ///< send ACT_CMD step (direction, steps, rate_hz), then md_servo_sent()
    MD_SERVO_A_WAIT,      ///< let wait_us pass (SIM_ADVANCE in lockstep, a timer otherwise), then call again
    MD_SERVO_A_FINISHED   ///< the move is over: see md_servo_t.result
} md_servo_action_kind_t;

typedef struct {
    md_servo_action_kind_t kind;
    uint8_t direction;  ///< MD_ACT_DIR_ADVANCE (deeper) or MD_ACT_DIR_RETRACT
    uint16_t steps;
    uint16_t rate_hz;
    uint32_t wait_us;
} md_servo_action_t;

/// How the last move ended.
typedef enum {
    MD_SERVO_R_NONE = 0,       ///< no move finished yet / in progress
    MD_SERVO_R_CONVERGED,      ///< within tol_um of the (clamped) target
    MD_SERVO_R_NOT_CONVERGED,  ///< max_iter commands spent
    MD_SERVO_R_STALL,          ///< actuator stalled or the Hall code did not follow
    MD_SERVO_R_END_STOP,       ///< an end stop was hit
    MD_SERVO_R_FAULT,          ///< actuator fault (e.g. its e-stop) or a command refused
    MD_SERVO_R_NO_SENSOR,      ///< no calibration, or no fresh readings in time
    MD_SERVO_R_OUT_OF_REGION,  ///< measured depth left the allowed region (never planned)
    MD_SERVO_R_ABORTED,        ///< md_servo_abort()
    MD_SERVO_R_RUNAWAY         ///< motion against or far beyond the command, twice: motion latched off
} md_servo_result_t;

typedef enum {
    MD_SERVO_IDLE = 0,
    MD_SERVO_MEASURE,  ///< collecting fresh readings
    MD_SERVO_MOVING    ///< a step command is out; waiting for its final ACT_STATUS
} md_servo_phase_t;

/// Counters (never reset except by init).
typedef struct {
    uint32_t moves, converged, not_converged, stalls, end_stops, faults, no_sensor, out_of_region, aborted;
    uint32_t commands;          ///< ACT_CMD steps issued
    uint32_t steps;             ///< steps commanded in total
    uint32_t clamped;           ///< targets clamped into the region
    uint32_t bad_readings;      ///< readings that the calibration turned into non-finite depths
    uint32_t budget_limited;    ///< commands shortened by the per-move travel budget
    uint32_t chunk_limited;     ///< commands shortened by the probe / chunk growth bound
    uint32_t rechecks;          ///< implausible displacements measured again
    uint32_t runaways;          ///< MD_SERVO_R_RUNAWAY (motion latched off)
    uint32_t suspect_refusals;  ///< moves refused because the sensor still repeats its stuck code
    uint32_t latched_refusals;  ///< md_servo_begin refused while motion is latched off
    uint32_t cal_unconfirmed;   ///< calibration values that differed from the one in use (held back)
    uint32_t cal_changes;       ///< calibration values changed after a confirming repetition
} md_servo_stats_t;

/// The servo of one electrode (caller-owned; ~0.8 kB).
typedef struct {
    md_servo_config_t cfg;
    /* calibration: staged until every coefficient, code_mid and code_half arrived */
    double cal_coef[MD_SERVO_CAL_MAX];
    double cal_mid, cal_half;
    uint8_t cal_count;  ///< CoeffCount of the staged set
    uint32_t cal_have;  ///< bit k: coefficient k received; bits 30/31 mid/half
    bool calibrated;
    double cal_pend[MD_SERVO_CAL_MAX + 2u];  ///< changed values awaiting confirmation; [MAX] mid, [MAX+1] half
    uint32_t cal_pend_have;                  ///< bits as cal_have: which cal_pend entries are set
    uint8_t cal_pend_count;                  ///< another CoeffCount seen once while calibrated (0: none)
    /* readings (raw codes; converted when averaged, so a new calibration applies at once) */
    uint16_t code[MD_SERVO_AVG_MAX];
    uint8_t code_head, code_count;
    uint8_t fresh;  ///< readings since the last md_servo_clear_readings()
    /* learned travel of one step, µm, [0] advance, [1] retract */
    double step_um[2];
    /* the move in progress */
    md_servo_phase_t phase;
    md_servo_result_t result;
    double target_um;  ///< requested target
    double goal_um;    ///< target clamped into the region
    double region_lo_um, region_hi_um;
    double win_min_um, win_max_um, move_max_um;
    bool have_start;    ///< d0 measured (region known)
    double start_um;    ///< d0
    double depth_um;    ///< latest depth measured by a move (this one or the last)
    bool have_depth;    ///< depth_um is set
    double before_um;   ///< depth measured before the command in flight
    uint8_t iter;       ///< commands issued in this move
    uint8_t waits;      ///< consecutive waits for readings
    uint8_t no_motion;  ///< consecutive moves without Hall change
    uint8_t cmd_seq;    ///< Seq of the command in flight
    uint8_t cmd_dir;
    uint16_t cmd_steps;
    double cmd_travel_um[2];  ///< travel commanded in this move, [0] advance, [1] retract (worst-case step)
    uint32_t move_steps;      ///< steps commanded in this move (sizes the next chunk)
    bool rechecking;          ///< an implausible displacement is being measured again
    bool hall_suspect;        ///< the last stall showed no Hall change at all
    uint16_t stuck_code;      ///< the code the suspect sensor repeated
    bool motion_latched;      ///< runaway seen: no move until md_servo_init / md_servo_clear_fault
    md_servo_stats_t stats;
} md_servo_t;

/// Documented defaults: tol 2 µm, 8 iterations, 5 readings, 40 nm, 1000 Hz,
/// 60 ms wait, 4 waits.
void md_servo_config_default(md_servo_config_t *cfg);

/// MD_OK if every field is in its documented range, else MD_E_ARG.
md_status_t md_servo_config_check(const md_servo_config_t *cfg);

/// Clears everything (no calibration, no readings, estimates = cfg->step_nm).
/// MD_E_ARG on NULL or an invalid config. O(1).
md_status_t md_servo_init(md_servo_t *s, const md_servo_config_t *cfg);

/// Replaces the tunables (a move in progress keeps going with the new ones;
/// learned step lengths are kept). MD_E_ARG if invalid (nothing changed).
md_status_t md_servo_configure(md_servo_t *s, const md_servo_config_t *cfg);

/// One HALL_CALIB frame: index < count a coefficient of x^index, or
/// MD_SERVO_CAL_INDEX_MID / _HALF. Until the first set is complete the values
/// are staged; then the calibration is in use. After that, a value that
/// differs from the one in use waits for the next repetition and is applied
/// only if that carries the same value (stats.cal_unconfirmed,
/// stats.cal_changes). A different count, confirmed by the very next frame
/// (while calibrated; at once otherwise), drops the calibration and starts a
/// new set (no motion until it is complete); a count seen once is ignored and
/// counted as unconfirmed, since a new set staged from it would be taken
/// without confirmation. MD_E_ARG on a non-finite value,
/// count 0 or > MD_SERVO_CAL_MAX, an index out of range, or code_half <= 0. O(1).
md_status_t md_servo_calib(md_servo_t *s, uint8_t index, uint8_t count, double value);

/// Depth of one raw code through the calibration (Horner in the normalised
/// code). MD_E_STATE before a complete calibration, MD_E_NUMERIC if not
/// finite. O(count).
md_status_t md_servo_code_to_depth_um(const md_servo_t *s, uint16_t code, double *depth_um);

/// One accepted HALL_READING (the node checked its sequence). O(1).
void md_servo_reading(md_servo_t *s, uint16_t code);

/// Forgets the readings (they no longer describe the position). O(1).
void md_servo_clear_readings(md_servo_t *s);

/// Median depth of the readings kept since the last clear (up to
/// MD_SERVO_AVG_MAX; a move measures with avg_n of them): a median, not a
/// mean, so that a glitching sensor's outliers do not move the depth.
/// MD_E_STATE without a calibration or readings, MD_E_NUMERIC if a depth is
/// not finite. O(MD_SERVO_AVG_MAX · (count + MD_SERVO_AVG_MAX)).
md_status_t md_servo_depth_um(const md_servo_t *s, double *depth_um);

/// Starts a move to target_um inside [win_min_um, win_max_um] and at most
/// move_max_um from the depth measured first (fresh readings are collected
/// before anything moves). MD_E_ARG on non-finite or inconsistent arguments
/// (nothing changes), MD_E_STATE if a move is in progress or motion is
/// latched off after a runaway (counted). O(1).
md_status_t md_servo_begin(md_servo_t *s, double target_um, double win_min_um, double win_max_um, double move_max_um);

/// The caller sent the ACT_CMD step of the last MD_SERVO_A_STEP with this Seq. O(1).
void md_servo_sent(md_servo_t *s, uint8_t seq);

/// The caller could not send it (refused by the node: not allowed to move,
/// or the bus): the move ends with MD_SERVO_R_FAULT. O(1).
void md_servo_send_failed(md_servo_t *s);

/// An accepted ACT_STATUS of this electrode. Only the final status
/// (not moving) of the command in flight (CmdSeq) matters. O(1).
void md_servo_act_status(md_servo_t *s, uint8_t cmd_seq, uint8_t state, uint8_t end_stops, uint16_t steps_done);

/// Next action; call after every input and after a wait. O(avg_n · count).
md_servo_action_t md_servo_next(md_servo_t *s);

/// Ends a move at once (e-stop, node left operational). The caller halts
/// the actuator. Result MD_SERVO_R_ABORTED if a move was in progress. O(1).
void md_servo_abort(md_servo_t *s);

/// Lifts the motion latch of a runaway (the operator has checked the
/// actuator) and forgets a suspect sensor. O(1).
void md_servo_clear_fault(md_servo_t *s);

/// True while motion is latched off after a runaway.
bool md_servo_latched(const md_servo_t *s);

/// True while a move is in progress.
bool md_servo_busy(const md_servo_t *s);

/// Short name of a result ("converged", ...).
const char *md_servo_result_name(md_servo_result_t r);

#endif

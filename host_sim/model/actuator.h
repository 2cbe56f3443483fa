/// @file actuator.h
/// Inertial stick-slip piezo actuator, one per electrode (thesis ch. 5: the
/// drive's Klocke linear actuators, sub-micron steps, ~5.6 mm travel, no gear
/// backlash).
///
/// Position axis: `position_um` is the carrier position, which is also the
/// electrode tip depth in the simulator's depth frame (0 = upper end stop,
/// `travel_um` = lower end stop, positive = deeper). A step command (count,
/// direction, rate) is executed over simulated time: step i of a command
/// happens at t_start + i / rate. Each step moves by a random length around
/// `step_nm` (advance) or `step_nm * retract_ratio` (retract: the direction
/// asymmetry of stick-slip drives); rarely a step is missed (no motion) or the
/// slider slips back by `slip_nm`. A step that would pass an end stop leaves
/// the carrier exactly on the stop, sets the end-stop flag and the state
/// STALLED, and drops the rest of the command: a stop is never passed.
/// Reversing direction has no dead band (no backlash), by construction.
#ifndef SIM_ACTUATOR_H
#define SIM_ACTUATOR_H

#include <stdbool.h>
#include <stdint.h>

#include "md_status.h"
#include "model/sim_fault.h"
#include "model/sim_rng.h"

/// Parameters; defaults in actuator_default_params() and docs/simulator.md.
typedef struct {
    double step_nm;        ///< mean advance step length (default 40 nm)
    double step_cv;        ///< step-to-step coefficient of variation (default 0.10)
    double retract_ratio;  ///< mean retract step / mean advance step (default 0.85)
    double miss_prob;      ///< probability that a step does not move (default 0.002)
    double slip_prob;      ///< probability that a step slips backwards instead (default 0.0005)
    double slip_nm;        ///< backward motion of a slip (default 120 nm)
    double max_rate_hz;    ///< highest step rate; faster commands are clamped (default 2000 Hz)
    double travel_um;      ///< distance between the end stops (default 5600 um)
} actuator_params_t;

typedef enum { ACTUATOR_IDLE = 0, ACTUATOR_MOVING = 1, ACTUATOR_STALLED = 2 } actuator_state_t;

/// What the actuator reports (the driver node publishes this).
typedef struct {
    actuator_state_t state;
    int direction;                ///< +1 advance (deeper), -1 retract, of the last command
    uint32_t steps_requested;     ///< of the last command
    uint32_t steps_done;          ///< of the last command (a stalled step is not done)
    bool at_upper_stop;           ///< carrier on the upper stop (position 0)
    bool at_lower_stop;           ///< carrier on the lower stop (position travel_um)
    uint32_t stall_count;         ///< stalls since start
    uint32_t rate_clamped_count;  ///< commands whose rate was above max_rate_hz
} actuator_status_t;

/// The actuator; plain data, owned by the caller.
typedef struct {
    actuator_params_t p;
    sim_rng_t rng;
    double position_um;    ///< true carrier position (ground truth)
    double t_s;            ///< model time: everything up to here is executed
    double t_cmd_s;        ///< start time of the current command
    double rate_hz;        ///< step rate of the current command
    double t_last_step_s;  ///< time of the most recent executed step (-1: none)
    actuator_status_t st;
    uint64_t missed_steps, slips;        ///< counters of the model's imperfections
    sim_model_faults_t faults;           ///< injected stall/slip windows (actuator_set_faults)
    sim_rng_t fault_rng;                 ///< their own stream: the healthy one stays aligned
    uint64_t fault_stalls, fault_slips;  ///< injected events that happened
} actuator_t;

/// Fills the documented defaults.
void actuator_default_params(actuator_params_t *p);
/// Checks every parameter's range; returns MD_E_ARG naming nothing (the
/// scenario parser does per-field checks with line numbers).
md_status_t actuator_params_check(const actuator_params_t *p);
/// Initialises at `start_um` (clamped into the travel) at time 0. The stream
/// is derived from (seed, electrode).
md_status_t actuator_init(actuator_t *a, const actuator_params_t *p, double start_um, uint64_t seed,
                          uint32_t electrode);
/// Starts a command at time `t_now_s` (>= model time): `count` steps in
/// `direction` (+1/-1) at `rate_hz` (> 0; clamped to max_rate_hz and counted).
/// count 0 stops. Replaces any command in progress. A new command clears
/// STALLED. Returns MD_E_ARG for a bad direction/rate.
md_status_t actuator_command(actuator_t *a, double t_now_s, uint32_t count, int direction, double rate_hz);
/// Executes every step scheduled at or before `t_s` and moves the model time
/// there. Returns the net displacement (um) over the call. O(steps executed).
double actuator_advance_to(actuator_t *a, double t_s);
/// Current status (state at the model time).
actuator_status_t actuator_status(const actuator_t *a);
/// Installs the stall/slip windows of `f` (copied) with a fault stream of
/// (seed, electrode). A stalled step does not move: the state becomes STALLED
/// (stall_count++) and the rest of the command is dropped, as at an end stop.
/// A slipping step moves back by act_slip_um instead of forward.
void actuator_set_faults(actuator_t *a, const sim_model_faults_t *f, uint64_t seed, uint32_t electrode);
/// Steps needed for `distance_um` at the mean step length of that direction.
uint32_t actuator_steps_for(const actuator_params_t *p, double distance_um);

#endif

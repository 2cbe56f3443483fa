/// @file simnode_world.h
/// The physical plant behind the bus nodes: one piezo actuator, one Hall
/// sensor and one recording site per electrode, with the tissue and neurons
/// around it. This is the only place where the nodes meet the models of
/// `md_sim` (host_sim/model, host_sim/scenario); the nodes see depths, codes
/// and samples, never the models' internals.
///
/// Time is simulated microseconds since the start of the session, and only
/// moves forward (simnode_world_advance). Every query answers "at the world's
/// current time". Same scenario + seed + call sequence -> same numbers.
#ifndef SIMNODE_WORLD_H
#define SIMNODE_WORLD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "md_status.h"
#include "scenario/scenario.h"

/// Most polynomial coefficients of a Hall calibration.
#define SIMNODE_WORLD_CAL_MAX 16u
/// Electrodes of the default world (no scenario file).
#define SIMNODE_WORLD_DEFAULT_ELECTRODES 3u

typedef struct simnode_world simnode_world_t;

/// Motion state of one actuator as the driver node reports it.
typedef struct {
    uint8_t state;             ///< md_act_state_t: idle, moving or stalled
    uint32_t steps_requested;  ///< of the last command
    uint32_t steps_done;       ///< of the last command
    bool at_upper_stop;        ///< carrier on the top (shallow) end stop
    bool at_lower_stop;        ///< carrier on the bottom (deep) end stop
} simnode_act_report_t;

/// Hall calibration as sent in HALL_CALIB: depth_um = sum_k coef[k] * x^k with
/// x = (code - code_mid) / code_half (normalised so float32 coefficients keep
/// sub-micron accuracy).
typedef struct {
    uint32_t count;  ///< coefficients in coef (degree + 1)
    double coef[SIMNODE_WORLD_CAL_MAX];
    double code_mid, code_half;
} simnode_hall_cal_t;

/// Builds the plant of the scenario file `scenario_path` (NULL: the models'
/// defaults with SIMNODE_WORLD_DEFAULT_ELECTRODES electrodes and no neurons)
/// with every random stream derived from `seed`. On failure returns NULL and
/// writes the reason(s) into err. Owns heap memory: release with
/// simnode_world_destroy.
simnode_world_t *simnode_world_create(const char *scenario_path, uint64_t seed, char *err, size_t errlen);

/// The same from a parsed scenario (host_sim/scenario/scenario.h).
simnode_world_t *simnode_world_create_scenario(const scenario_t *sc, uint64_t seed, char *err, size_t errlen);

/// The scenario's launcher/node-level faults (bus faults, node silences,
/// controller restarts; host_sim/scenario/scenario.h). All empty for the
/// default world. Borrowed: valid while the world lives.
const scenario_faults_t *simnode_world_faults(const simnode_world_t *w);
/// Releases the world; NULL is allowed.
void simnode_world_destroy(simnode_world_t *w);

/// Electrodes of the scenario (1..SIMNODE_MAX_ELECTRODES).
uint32_t simnode_world_electrodes(const simnode_world_t *w);

/// The world's current time.
uint64_t simnode_world_time_us(const simnode_world_t *w);

/// Moves every model to time t_us (executing actuator steps due by then and
/// letting the tissue relax). Earlier times are ignored. O(steps executed).
void simnode_world_advance(simnode_world_t *w, uint64_t t_us);

/// Starts a motion of electrode e now: `count` steps (0 = halt) in direction
/// +1 (advance, deeper) or -1 (retract) at rate_hz (> 0; the model clamps it
/// to the actuator's maximum). Replaces any motion in progress.
md_status_t simnode_world_act_command(simnode_world_t *w, uint32_t e, uint32_t count, int direction, double rate_hz);

/// Motion state of electrode e.
simnode_act_report_t simnode_world_act_report(const simnode_world_t *w, uint32_t e);

/// Earliest time (> current time) at which advancing executes the next step of
/// electrode e's motion; UINT64_MAX when it is not moving.
uint64_t simnode_world_act_next_step_us(const simnode_world_t *w, uint32_t e);

/// One raw Hall reading of electrode e now (draws the sensor's noise).
uint16_t simnode_world_hall_read(simnode_world_t *w, uint32_t e);

/// Electrode e's factory calibration.
void simnode_world_hall_cal(const simnode_world_t *w, uint32_t e, simnode_hall_cal_t *cal);

/// Hall reporting rate the scenario asks for (Hz).
double simnode_world_hall_rate_hz(const simnode_world_t *w);

/// Front-end sampling rate (Hz) and ADC gain (uV per LSB).
uint32_t simnode_world_fe_rate_hz(const simnode_world_t *w);
double simnode_world_fe_gain_uv(const simnode_world_t *w);

/// Starts recording electrode e at the world's current time: from now on its
/// time moves only through simnode_world_record_next (so no sample is
/// skipped or repeated), until simnode_world_record_stop. With a truth sink
/// it writes the `state` records (label "rec e<e> i<interval_id>") and then
/// one `interval` record: {electrode, interval, t_us, start_sample,
/// num_samples, sample_rate_hz}, where start_sample is the electrode's sample
/// clock at the interval's first sample (the clock of the `spike` records):
/// detection k of the interval lies at start_sample + k.
/// MD_E_ARG for a bad electrode, MD_E_STATE if already recording.
md_status_t simnode_world_record_start(simnode_world_t *w, uint32_t e, uint32_t interval_id, uint32_t n_samples);

/// The next n samples (ADC codes) of electrode e's recording; the samples do
/// not depend on how a recording is cut into calls. O(n + spikes).
md_status_t simnode_world_record_next(simnode_world_t *w, uint32_t e, uint32_t n, int16_t *out);

/// Ends electrode e's recording; its time rejoins the world's at the next
/// simnode_world_advance.
void simnode_world_record_stop(simnode_world_t *w, uint32_t e);

/// Injected model faults that happened so far, summed over the electrodes
/// (host_sim/model/sim_fault.h): what a reader of a faulty session's output
/// needs to see that the fault really acted.
typedef struct {
    uint64_t hall_glitches, hall_stuck_reads;
    uint64_t act_stalls, act_slips;
    uint64_t storm_events, saturated_samples;
} simnode_world_fault_counts_t;
simnode_world_fault_counts_t simnode_world_fault_counts(const simnode_world_t *w);
/// Samples the ADC saturated so far (all electrodes).
uint64_t simnode_world_adc_clipped(const simnode_world_t *w);

/// Sends the ground truth (JSON lines, see host_sim/model/sim_world.h) to f
/// (not owned; NULL: none). Writes the session and neuron records at once.
void simnode_world_set_truth(simnode_world_t *w, FILE *f);

#endif

/// @file sim_fault.h
/// Model faults of one electrode's plant, declared in a scenario's `faults:`
/// section (docs/safety.md, docs/simulator.md): Hall glitches and stuck
/// readings, actuator stalls and slips, ADC saturation and artifact storms.
///
/// Each fault has a simulated-time window [from_s, to_s); an empty window
/// (to_s <= from_s, the default) disables it. The electrode model applies
/// them itself (sim_electrode_init copies cfg->faults), so every simulator
/// front end (microdrive-sim, microdrive-session, sim-export) sees them with
/// no hook. Random choices come from streams of their own (SIM_RNG_FAULT),
/// so a fault never shifts the healthy model's random numbers: outside its
/// window a faulty session is sample-identical to the healthy one.
#ifndef SIM_FAULT_H
#define SIM_FAULT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "model/sim_rng.h"

/// Artifact-storm events rendered at once (overlapping transients).
#define SIM_FAULT_STORM_ACTIVE_MAX 8u
/// Samples of the storm transient template, at most.
#define SIM_FAULT_STORM_TMPL_MAX 96u

typedef struct {
    double from_s, to_s;  ///< active for from_s <= t < to_s
} sim_window_t;

typedef struct {
    sim_window_t hall_glitch;     ///< a reading jumps by +-hall_glitch_codes with hall_glitch_prob
    double hall_glitch_prob;      ///< per reading (default 0.1)
    double hall_glitch_codes;     ///< jump (default 2000 codes, ~100+ um)
    sim_window_t hall_stuck;      ///< readings frozen at the last one before the window
    sim_window_t act_stall;       ///< no step moves; the actuator reports STALLED
    sim_window_t act_slip;        ///< a step slips back act_slip_um with act_slip_prob
    double act_slip_prob;         ///< per step (default 0.2)
    double act_slip_um;           ///< backward motion of a slip (default 2 um)
    sim_window_t adc_saturation;  ///< every sample pinned to the ADC rail of its sign
    sim_window_t artifact_storm;  ///< large transients at storm_rate_hz, storm_amp_uv ptp
    double storm_rate_hz;         ///< default 20 Hz
    double storm_amp_uv;          ///< default 3000 uV
} sim_model_faults_t;

/// Hall fault state (per sensor).
typedef struct {
    sim_rng_t rng;
    bool have_last;
    uint32_t last_code;  ///< last reading before a stuck window
    uint64_t glitches, stuck_reads;
} sim_hall_fault_state_t;

/// Signal fault state (per electrode): pending storm transients.
typedef struct {
    sim_rng_t rng;
    double tmpl[SIM_FAULT_STORM_TMPL_MAX];
    uint32_t tmpl_len;
    double next_event_s;                         ///< next storm transient (<0: not drawn)
    uint64_t start[SIM_FAULT_STORM_ACTIVE_MAX];  ///< first sample of each live transient
    double amp[SIM_FAULT_STORM_ACTIVE_MAX];      ///< its ptp (uV), signed
    uint32_t n_active;
    uint64_t storm_events, saturated_samples, storm_dropped;
} sim_signal_fault_state_t;

/// Actuator step outcome under faults.
typedef enum { SIM_STEP_NORMAL = 0, SIM_STEP_STALL = 1, SIM_STEP_SLIP = 2 } sim_step_fault_t;

/// Every window empty; magnitudes at their defaults.
void sim_model_faults_default(sim_model_faults_t *f);
/// True if t_s is inside w.
static inline bool sim_window_active(const sim_window_t *w, double t_s)
{
    return t_s >= w->from_s && t_s < w->to_s;
}
/// True if any window of f is non-empty.
bool sim_model_faults_any(const sim_model_faults_t *f);

/// Initialises the Hall fault stream for (seed, electrode).
void sim_hall_fault_init(sim_hall_fault_state_t *s, uint64_t seed, uint32_t electrode);
/// Applies Hall faults to one raw reading `code` (0..code_max) taken at t_s.
/// Stuck wins over glitch. O(1).
uint32_t sim_fault_hall_apply(const sim_model_faults_t *f, sim_hall_fault_state_t *s, double t_s, uint32_t code,
                              uint32_t code_max);

/// Decides the fate of one actuator step at t_s; `rng` is the actuator's
/// fault stream (drawn once per step inside the slip window only).
sim_step_fault_t sim_fault_actuator_step(const sim_model_faults_t *f, sim_rng_t *rng, double t_s);

/// Initialises the signal fault state for (seed, electrode) at sampling rate fs.
void sim_signal_fault_init(sim_signal_fault_state_t *s, uint64_t seed, uint32_t electrode, double fs);
/// Applies signal faults to n int16 samples whose first is absolute sample
/// `first` at rate fs, gain_uv per LSB. Saturation pins a sample to +32767
/// (>= 0) or -32768; storm transients add, then round and clamp. O(n).
void sim_fault_signal_apply(const sim_model_faults_t *f, sim_signal_fault_state_t *s, uint64_t first, double fs,
                            double gain_uv, int16_t *x, size_t n);

#endif

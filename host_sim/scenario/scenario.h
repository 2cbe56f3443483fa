/// @file scenario.h
/// Declarative session description, read from a YAML file with libyaml's
/// document API (every node carries its line, so every semantic error is
/// reported as `file:line: reason`).
///
/// Layout (every key optional unless marked required; defaults in
/// docs/simulator.md and the *_default_params() functions):
/// ```yaml
/// name: single_neuron          # string
/// seed: 1                      # uint64: session reproducibility
/// duration_s: 600              # how long microdrive-sim runs a session
/// signal: {...}                # signal_params_t fields (all electrodes)
/// actuator: {...}              # actuator_params_t fields (defaults for all electrodes)
/// sensor: {...}                # hall_params_t fields
/// tissue: {...}                # tissue_params_t fields
/// neuron_model: {...}          # neuron_model_params_t fields
/// neuron_defaults: {...}       # neuron_params_t fields for every neuron below
/// electrodes:                  # required, 1..8 entries
///   - start_um: 1000
///     actuator/sensor/tissue: {...}   # per-electrode overrides
///     neurons: [{depth_um: 1200, ...}]  # depth_um required
///     random_neurons: {count: 5, ...}
/// export: {intervals: 20, interval_s: 10, step_um: 10, settle_s: 1}
/// faults:                      # injected faults (docs/safety.md), any order
///   - {kind: hall_glitch, electrode: 0, from_s: 30, to_s: 60, prob: 0.1, codes: 2000}
///   - {kind: hall_stuck | actuator_stall | adc_saturation, electrode: 0, from_s: .., to_s: ..}
///   - {kind: actuator_slip, prob: 0.2, slip_um: 2, from_s: .., to_s: ..}
///   - {kind: artifact_storm, rate_hz: 20, amp_uv: 3000, from_s: .., to_s: ..}
///   - {kind: bus_loss | bus_corrupt | bus_dup | bus_delay | bus_reorder, prob: 0.05,
///      direction: both|tx|rx, can_id: 528, frames: 4 (bus_delay only), from_s: .., to_s: ..}
///   - {kind: node_silent, node: act|hall|fe, from_s: 40, to_s: 55}
///   - {kind: controller_restart, at_s: 120}
/// ```
/// Fault windows are simulated time [from_s, to_s) (defaults 0 and forever);
/// `electrode` omitted = every electrode. Model faults go into each
/// electrode's cfg.faults (the model applies them); bus, node and restart
/// faults are in scenario_t.faults for the launcher and the sim nodes.
/// Errors: unknown key, duplicate key, wrong node kind or scalar type, value
/// out of range, missing required field, inconsistent combination: each one
/// line `file:line: reason`; parsing goes on after an error so that one run
/// reports all of them.
#ifndef SIM_SCENARIO_H
#define SIM_SCENARIO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "model/sim_world.h"
#include "scenario/scenario_faults.h"

#define SCENARIO_NAME_MAX 64u

/// The scripted trajectory of export mode (no firmware drives then).
typedef struct {
    uint32_t intervals;  ///< recording intervals (default 20)
    double interval_s;   ///< length of each (default 10 s)
    double step_um;      ///< move after each interval, signed (default 10 um: deeper)
    double settle_s;     ///< wait after a move before the next interval (default 1 s)
} scenario_export_t;

typedef struct {
    char name[SCENARIO_NAME_MAX];
    uint64_t seed;      ///< default 1
    double duration_s;  ///< default 600 s
    uint32_t n_electrodes;
    sim_electrode_config_t electrodes[SIM_MAX_ELECTRODES];
    scenario_export_t export_cfg;
    scenario_faults_t faults;  ///< launcher/node-level faults (model faults are per electrode)
} scenario_t;

/// Every default, one electrode with no neurons.
void scenario_default(scenario_t *sc);
/// Parses YAML text; `file` names it in messages. Returns the number of
/// errors (0 = *sc valid); messages, one per line, go to err (truncated to
/// errlen, always NUL-terminated when errlen > 0).
int scenario_parse(scenario_t *sc, const char *text, size_t len, const char *file, char *err, size_t errlen);
/// Reads and parses a file. -1 if it cannot be read (message in err).
int scenario_load(scenario_t *sc, const char *path, char *err, size_t errlen);
/// True while simulated node `node` (md_node_id_t) must stay silent at t_s.
bool scenario_node_silent(const scenario_t *sc, uint32_t node, double t_s);
/// Number of controller restarts scheduled in (t_prev_s, t_now_s]: the
/// launcher restarts the controller when this is non-zero.
uint32_t scenario_restarts_due(const scenario_t *sc, double t_prev_s, double t_now_s);
/// The same two on the faults alone: scenario_faults.h.
/// True if the scenario declares any fault at all.
bool scenario_has_faults(const scenario_t *sc);
/// Builds the world of a scenario with `seed`.
md_status_t scenario_make_world(const scenario_t *sc, uint64_t seed, sim_world_t *w);

#endif

/// @file scenario_faults.h
/// The fault schedule of a scenario beyond the models: bus faults (the
/// launcher wraps the simulator's endpoint in md_bus_fault), silences of
/// simulated nodes and controller restarts, and the queries the sim nodes
/// and the launcher make of it while a session runs. scenario.h reads it
/// from the `faults` list of the YAML; docs/safety.md.
#ifndef SIM_SCENARIO_FAULTS_H
#define SIM_SCENARIO_FAULTS_H

#include <stdbool.h>
#include <stdint.h>

#define SCENARIO_BUS_FAULTS_MAX 8u
#define SCENARIO_SILENT_MAX 4u
#define SCENARIO_RESTARTS_MAX 4u

/// One bus fault (a md_bus_fault wrapper around the simulator's endpoint).
typedef struct {
    uint32_t kind;        ///< md_bus_fault_kind_t: 0 loss, 1 corrupt, 2 dup, 3 delay, 4 reorder
    double prob;          ///< per frame, required
    double from_s, to_s;  ///< simulated-time window
    uint32_t directions;  ///< 1 frames the simulator sends, 2 frames it receives, 3 both (default)
    uint32_t frames;      ///< delay in frames (bus_delay; default 4)
    uint32_t can_id;      ///< only this CAN id (has_id), else every frame
    uint32_t has_id;
} scenario_bus_fault_t;

/// One silence of a simulated node (it sends nothing, heartbeat included).
typedef struct {
    uint32_t node;  ///< md_node_id_t: 2 act, 3 hall, 4 fe
    double from_s, to_s;
} scenario_silence_t;

/// The launcher- and node-level faults of a scenario (model faults are per
/// electrode, in sim_electrode_config_t.faults).
typedef struct {
    uint32_t n_bus;
    scenario_bus_fault_t bus[SCENARIO_BUS_FAULTS_MAX];
    uint32_t n_silent;
    scenario_silence_t silent[SCENARIO_SILENT_MAX];
    uint32_t n_restarts;
    double restart_at_s[SCENARIO_RESTARTS_MAX];  ///< controller restarts, ascending
} scenario_faults_t;

/// True while simulated node `node` (md_node_id_t) must stay silent at t_s
/// (a window [from_s, to_s) of f). O(SCENARIO_SILENT_MAX).
bool scenario_faults_node_silent(const scenario_faults_t *f, uint32_t node, double t_s);
/// Number of controller restarts of f scheduled in (t_prev_s, t_now_s].
/// O(SCENARIO_RESTARTS_MAX).
uint32_t scenario_faults_restarts_due(const scenario_faults_t *f, double t_prev_s, double t_now_s);

#endif

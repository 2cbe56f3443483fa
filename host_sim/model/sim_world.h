/// @file sim_world.h
/// All electrodes of a session, and the session's ground-truth file.
///
/// The electrodes are independent physical systems (own actuator, sensor,
/// tissue, neurons, random streams); the world keeps their clocks together
/// when time passes without recording. Recording streams (generate) advance
/// one electrode's clock: a front-end that records all electrodes at once
/// generates the same number of samples for each.
///
/// Ground-truth file: JSON lines, one object per line, "type" first:
///   session  {seed, sample_rate_hz, electrodes, bg_rms_uv[]}
///   neuron   {electrode, neuron, x_um, y_um, depth_um, amp_uv, rate_hz, shape}
///   spike    {electrode, sample, neuron, amp_uv}   (neuron -1: large artifact)
///   death    {electrode, neuron, t_s, distance_um}
///   state    {t_s, label, electrode, tip_um, neurons:[{neuron, depth_um,
///             alive, distance_um, closest_um, snr, snr_peak_depth_um, snr_peak}]}
/// Spikes appear as they are generated; `state` lines when the caller asks
/// (sim_world_truth_snapshot, e.g. once per recording interval).
#ifndef SIM_WORLD_H
#define SIM_WORLD_H

#include <stdio.h>

#include "model/electrode.h"

#define SIM_MAX_ELECTRODES 8u

typedef struct {
    uint64_t seed;
    uint32_t n_electrodes;
    sim_electrode_t el[SIM_MAX_ELECTRODES];
    FILE *truth;  ///< not owned
} sim_world_t;

/// Builds every electrode from its configuration. ~0.4 MB per electrode:
/// host code should allocate the world (it is too large for a stack).
md_status_t sim_world_init(sim_world_t *w, const sim_electrode_config_t *cfgs, uint32_t n, uint64_t seed);
/// Lets dt_s pass on every electrode without recording (rounded to samples).
void sim_world_advance_s(sim_world_t *w, double dt_s);
/// Attaches a ground-truth sink and writes the session and neuron records.
void sim_world_set_truth(sim_world_t *w, FILE *f);
/// Writes one `state` record per electrode (no-op without a sink).
void sim_world_truth_snapshot(sim_world_t *w, const char *label);
/// True when no actuator is moving.
bool sim_world_idle(const sim_world_t *w);

#endif

/// @file electrode.h
/// One simulated electrode: its piezo actuator, Hall sensor, the tissue and
/// neurons around its track, and the recorded signal.
///
/// Time is counted in samples of the electrode's ADC (`cursor`). The slow
/// models (actuator, tissue, neuron geometry, damage, waveform templates) are
/// updated at every multiple of SIM_BLOCK samples (8.5 ms at 30 kHz) and at
/// the first sample after a jump in time; noise and spike timing are per
/// sample. Hence the samples produced do not depend on how a recording is
/// cut into generate() calls: same scenario + seed + same sequence of
/// commands and time advances -> the same samples, byte for byte.
///
/// Ground truth of a chunk: every spike whose trough sample lies in the chunk
/// (sample index in the electrode's absolute sample count, neuron id; -1 for
/// a large artifact). Spikes during unrecorded time (advance()) are not
/// reported. Memory: ~0.35 MB per electrode, no allocation.
#ifndef SIM_ELECTRODE_H
#define SIM_ELECTRODE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "model/actuator.h"
#include "model/hall_sensor.h"
#include "model/neuron.h"
#include "model/sim_fault.h"
#include "model/signal.h"
#include "model/tissue.h"

#define SIM_MAX_NEURONS 64u    ///< neurons per electrode (explicit + random)
#define SIM_BLOCK 256u         ///< samples between slow-model updates
#define SIM_ACC_LEN 1024u      ///< overlap-add ring (>= SIM_BLOCK + longest window)
#define SIM_PENDING_MAX 2048u  ///< rendered spikes not yet delivered

_Static_assert((SIM_ACC_LEN & (SIM_ACC_LEN - 1u)) == 0u, "ring length must be a power of two");
_Static_assert(SIM_ACC_LEN >= SIM_BLOCK + 2u * SIM_WAVE_MAX, "ring must hold a block plus a window");

/// Random neurons placed around the track at session start.
typedef struct {
    uint32_t count;                   ///< default 0
    double depth_min_um;              ///< default 500
    double depth_max_um;              ///< default 5000
    double radius_um;                 ///< lateral placement radius (default 120 um)
    double amp_min_uv, amp_max_uv;    ///< default 150..500
    double rate_min_hz, rate_max_hz;  ///< log-uniform, default 1..30
} sim_random_neurons_t;

/// Everything that defines one electrode.
typedef struct {
    actuator_params_t actuator;
    hall_params_t hall;
    tissue_params_t tissue;
    signal_params_t signal;
    neuron_model_params_t neuron_model;
    double start_um;     ///< initial tip depth (default 1000)
    uint32_t n_neurons;  ///< explicit neurons
    neuron_params_t neurons[SIM_MAX_NEURONS];
    sim_random_neurons_t random_neurons;
    sim_model_faults_t faults;  ///< injected plant faults (default: none)
} sim_electrode_config_t;

/// One ground-truth spike.
typedef struct {
    uint64_t sample;    ///< trough sample (absolute)
    int32_t neuron_id;  ///< -1: large artifact (not a neuron)
    double amp_uv;      ///< its peak-to-peak amplitude
} sim_gt_spike_t;

/// Ground truth of one neuron at the electrode's current time.
typedef struct {
    uint32_t id;
    double x_um, y_um;
    double depth_um;  ///< apparent depth = tissue depth + tissue displacement
    bool alive;
    double died_s;             ///< -1 when alive
    double distance_um;        ///< tip to soma
    double closest_um;         ///< smallest tip-soma distance so far (along the path, as the damage check)
    double snr;                ///< true SNR at the tip's current depth (0 when dead)
    double snr_peak_depth_um;  ///< tip depth of the maximum of its SNR-vs-depth curve
    double snr_peak;           ///< SNR there
} sim_neuron_truth_t;

typedef struct {
    uint32_t index;
    sim_electrode_config_t cfg;
    actuator_t act;
    hall_sensor_t hall;
    tissue_t tissue;
    uint32_t n_neurons;
    neuron_t neurons[SIM_MAX_NEURONS];
    double tmpl[SIM_MAX_NEURONS][SIM_WAVE_MAX];
    double tmpl_ptp[SIM_MAX_NEURONS];  ///< ptp (uV) of each current template
    bool in_range[SIM_MAX_NEURONS];
    double prev_dz[SIM_MAX_NEURONS];
    double closest_um[SIM_MAX_NEURONS];  ///< closest approach so far, per neuron (ground truth)
    sim_rng_t noise_rng, mua_rng, art_rng;
    sim_noise_filter_t filt;
    double fs;
    double bg_rms_uv;
    double mua_tmpl[SIM_SHORT_WAVE_MAX], art_tmpl[SIM_SHORT_WAVE_MAX];
    uint32_t mua_len, art_len;
    double mua_next_s, art_next_s;
    double motion_t0_s;       ///< last actuator step seen (ringing starts there)
    double acc[SIM_ACC_LEN];  ///< overlap-add of spikes/MUA/artifacts (uV)
    uint64_t cursor;          ///< next sample to produce
    uint64_t rendered_until;  ///< events starting before this are rendered
    uint64_t model_sample;    ///< sample of the last slow-model update
    sim_gt_spike_t pending[SIM_PENDING_MAX];
    size_t n_pending;
    uint64_t gt_dropped;                 ///< truth entries lost to full buffers (counted, never silent)
    uint64_t adc_clipped;                ///< samples saturated by the ADC
    sim_hall_fault_state_t hall_fault;   ///< injected Hall faults (cfg.faults)
    sim_signal_fault_state_t sig_fault;  ///< injected signal faults (cfg.faults)
    FILE *truth;                         ///< optional JSON-lines truth sink (not owned)
} sim_electrode_t;

void sim_electrode_default_config(sim_electrode_config_t *c);
void sim_random_neurons_default(sim_random_neurons_t *r);
/// Initialises electrode `index` from `cfg` and `seed`: places random neurons
/// (own stream), builds all models. MD_E_ARG on a bad configuration.
md_status_t sim_electrode_init(sim_electrode_t *el, const sim_electrode_config_t *cfg, uint64_t seed, uint32_t index);
/// Current time (s) = cursor / fs.
double sim_electrode_time_s(const sim_electrode_t *el);
/// Lets `n_samples` of time pass without recording (actuator and tissue move,
/// neurons fire unrecorded, damage is checked).
void sim_electrode_advance(sim_electrode_t *el, uint64_t n_samples);
/// Records the next n samples into out[n] (ADC codes) and returns in gt[] the
/// spikes whose trough is among them (at most gt_cap; the excess is counted
/// in gt_dropped). Returns the number of gt entries. O(n + spikes).
size_t sim_electrode_generate(sim_electrode_t *el, int16_t *out, size_t n, sim_gt_spike_t *gt, size_t gt_cap);
/// Starts an actuator command now (see actuator_command).
md_status_t sim_electrode_command(sim_electrode_t *el, uint32_t count, int direction, double rate_hz);
/// One Hall reading now.
uint32_t sim_electrode_hall_read(sim_electrode_t *el);
/// True tip depth (um) at the last model update.
double sim_electrode_tip_um(const sim_electrode_t *el);
/// Ground truth of every neuron; returns how many were written (<= cap).
size_t sim_electrode_truth(const sim_electrode_t *el, sim_neuron_truth_t *out, size_t cap);
/// True SNR of neuron k with the tip at depth tip_um (current tissue state).
double sim_electrode_snr_at(const sim_electrode_t *el, uint32_t k, double tip_um);

#endif

/// @file neuron.h
/// One neuron near an electrode's track: position, spike waveform, firing.
///
/// Geometry: the track is the z axis of the electrode's frame; a neuron sits
/// at lateral offset (x_um, y_um) and tissue depth depth_um (+ its own drift),
/// and appears at that depth + the tissue displacement s(t). With the tip at
/// depth z_tip, dz = z_tip - z_neuron, r = hypot(x, y), d = hypot(r, dz).
///
/// Amplitude: peak-to-peak A(d) = amp_uv / (1 + (d / falloff_um)^falloff_exp)
/// (amp_uv is the value at contact). A(d) falls monotonically with d, so along
/// the track SNR(z_tip) has exactly one maximum, at dz = 0: the neuron's true
/// SNR-peak depth is its apparent depth. Neurons beyond range_um are not
/// rendered (their spikes would be < ~1 noise sigma with the defaults).
///
/// Shape: two unit-ptp bases, "near" (the neuron's own biphasic or triphasic
/// shape with its own widths) and "far" (broader, repolarisation-dominant),
/// mixed with weight w = shape_mix * (1 + sin(theta)) / 2, theta =
/// atan2(dz, r) the elevation of the tip seen from the soma; the mix is
/// renormalised to unit ptp and scaled by A(d). So the waveform's features
/// drift as the electrode passes the neuron while the ptp follows A(d).
///
/// Firing: a renewal process with an absolute refractory period:
/// ISI = refractory + Exp(m); with probability burst_prob an event is a burst
/// of 1..burst_spikes extra spikes at ~burst_isi_ms (>= refractory), each
/// scaled by burst_amp_decay^k; m is set so that the long-run mean rate while
/// active is exactly rate_hz. Optional alternation of active and silent
/// stretches (exponential durations), an appearance time and a disappearance
/// time. A neuron whose distance to the tip falls below damage_um dies.
#ifndef SIM_NEURON_H
#define SIM_NEURON_H

#include <stdbool.h>
#include <stdint.h>

#include "md_status.h"
#include "model/sim_rng.h"

#define SIM_WAVE_MAX 128u  ///< samples of one rendered spike window, at most

typedef enum { NEURON_BIPHASIC = 0, NEURON_TRIPHASIC = 1 } neuron_shape_t;

/// Model parameters shared by all neurons of a session.
typedef struct {
    double falloff_um;      ///< default 30 um
    double falloff_exp;     ///< default 2
    double range_um;        ///< default 150 um: beyond this a neuron is not rendered
    double damage_um;       ///< default 12 um: closer than this the neuron dies
    double shape_mix;       ///< default 0.6: largest weight of the far basis
    double window_pre_ms;   ///< default 0.6 ms before the trough
    double window_post_ms;  ///< default 1.4 ms after the trough
} neuron_model_params_t;

/// Per-neuron parameters.
typedef struct {
    double x_um, y_um;        ///< lateral offset from the track (default 20, 0)
    double depth_um;          ///< tissue depth (required in a scenario)
    double amp_uv;            ///< ptp at contact (default 400 uV)
    neuron_shape_t shape;     ///< default biphasic
    double trough_ms;         ///< trough sigma (default 0.10 ms)
    double repol_ms;          ///< repolarisation sigma (default 0.25 ms)
    double repol_ratio;       ///< repolarisation / trough height (default 0.35)
    double rate_hz;           ///< mean rate while active (default 8 Hz)
    double refractory_ms;     ///< absolute refractory period (default 2 ms)
    double burst_prob;        ///< probability an event is a burst (default 0.05)
    uint32_t burst_spikes;    ///< most extra spikes in a burst (default 3)
    double burst_isi_ms;      ///< mean ISI inside a burst (default 4 ms)
    double burst_amp_decay;   ///< amplitude factor per burst spike (default 0.85)
    double amp_jitter;        ///< spike-to-spike relative amplitude sigma (default 0.05)
    double active_mean_s;     ///< mean active stretch (default 0: always active)
    double silent_mean_s;     ///< mean silent stretch (default 0: never silent)
    double appear_s;          ///< starts firing at (default 0)
    double disappear_s;       ///< stops firing at (default 0: never)
    double drift_um_per_min;  ///< the neuron's own axial drift (default 0)
    double drift_start_s;     ///< its start (default 0)
} neuron_params_t;

typedef struct {
    neuron_params_t p;
    uint32_t id;
    sim_rng_t rng;
    bool alive;
    double died_s;    ///< time of death (-1: alive)
    double next_s;    ///< time of the next spike (trough), INFINITY: none
    double next_amp;  ///< amplitude factor of that spike
    uint32_t burst_left, burst_index;
    double active_until_s;
    double mean_gap_s;            ///< m of the ISI law
    uint32_t wave_len, wave_pre;  ///< window length and trough index (samples)
    double basis_near[SIM_WAVE_MAX], basis_far[SIM_WAVE_MAX];
} neuron_t;

void neuron_default_model_params(neuron_model_params_t *p);
void neuron_default_params(neuron_params_t *p);
md_status_t neuron_model_params_check(const neuron_model_params_t *p, double sample_rate_hz);
/// Checks a neuron's parameters; on failure *why names the problem.
md_status_t neuron_params_check(const neuron_params_t *p, const char **why);
/// Builds the bases at `sample_rate_hz` and schedules the first spike.
md_status_t neuron_init(neuron_t *n, const neuron_params_t *p, const neuron_model_params_t *m, uint32_t id,
                        double sample_rate_hz, uint64_t seed, uint32_t electrode);
/// Tissue depth at time t (its own drift, without the tissue displacement).
double neuron_depth_um(const neuron_t *n, double t_s);
/// Peak-to-peak amplitude at distance d (uV).
double neuron_amplitude_uv(const neuron_model_params_t *m, const neuron_t *n, double d_um);
/// Renders the waveform (uV) for the tip offset (r, dz) into out[wave_len].
void neuron_template(const neuron_model_params_t *m, const neuron_t *n, double r_um, double dz_um, double *out);
/// Consumes the pending spike and schedules the next one. O(1) amortised.
void neuron_pop_spike(neuron_t *n);

#endif

/// @file spike_synth.h
/// Deterministic synthetic recording intervals with known spike times, for
/// detector self-tests (unit tests, on-target tests, tools/detector_report).
///
/// A trace is Gaussian noise (white, or band-limited by a [1 2 1] binomial
/// low-pass, i.e. -3 dB at fs/4) of RMS `noise_rms` plus copies of one fixed
/// biphasic template: a negative Gaussian trough (sigma 0.12 ms) followed by a
/// positive bump (sigma 0.22 ms, +0.35 ms later, 0.35 of the trough). The
/// sampled template is scaled so that its peak-to-peak amplitude is exactly
/// snr * noise_rms, i.e. SNR = peak-to-peak / noise RMS, the definition of
/// the SNR metric (thesis §2.2.2.4).
#ifndef SPIKE_SYNTH_H
#define SPIKE_SYNTH_H

#include <stddef.h>
#include <stdint.h>

#include "md_status.h"

#define SYNTH_TEMPLATE_MAX 96u  ///< template samples (1.7 ms at up to 50 kHz)

/// Parameters of a synthetic interval.
typedef struct {
    uint32_t sample_rate_hz;  ///< 5000..50000
    double noise_rms;         ///< noise RMS in ADC counts (> 0)
    int band_limited;         ///< 0 white, 1 binomial low-pass (same RMS)
    double snr;               ///< template peak-to-peak / noise_rms (>= 0)
    double rate_hz;           ///< mean firing rate (Poisson with refractory gap)
    double refractory_ms;     ///< smallest gap between spikes
    uint64_t seed;
} synth_config_t;

/// Writes n samples into `out` and the sample index of every inserted
/// spike's trough (ascending) into `peaks` (capacity `peaks_cap`; spikes
/// that would not fit are not inserted). Values are rounded and clipped to
/// int16. MD_E_ARG on invalid parameters. O(n).
md_status_t synth_trace(const synth_config_t *cfg, int16_t *out, size_t n, uint32_t *peaks, size_t peaks_cap,
                        size_t *n_peaks);

/// The sampled template at `sample_rate_hz` with peak-to-peak 1.0 and its
/// trough at index *trough; returns the length (0 on invalid arguments).
size_t synth_template(uint32_t sample_rate_hz, double *tmpl, size_t cap, size_t *trough);

/// Scores detections against ground truth: both lists ascending; a detection
/// within `tol` samples of a not yet matched true spike is a hit, every other
/// detection a false positive. Greedy in time order, O(n_truth + n_det).
void synth_match(const uint32_t *truth, size_t n_truth, const uint32_t *det, size_t n_det, uint32_t tol, size_t *hits,
                 size_t *false_pos);

#endif

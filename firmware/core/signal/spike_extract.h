/// @file spike_extract.h
/// Extraction of aligned spike windows and spike-free noise snippets from a
/// detected interval (thesis §2.2.2.1: windows of d_w samples aligned by the
/// waveform minimum; §2.2.2.4: a spike-free noise sample for the SNR).
///
/// Input is the interval buffer and the events of spike_detect.h. Windows
/// are converted to double, DC offset removed and scaled by `gain` (e.g.
/// microvolts per ADC count). Nothing is dropped silently: windows too close
/// to an interval edge, duplicates and capacity overflows are counted.
#ifndef SPIKE_EXTRACT_H
#define SPIKE_EXTRACT_H

#include <stddef.h>
#include <stdint.h>

#include "common/md_status.h"
#include "md_config.h"
#include "signal/spike_detect.h"

/// Extraction parameters; fill with sx_config_default().
typedef struct {
    size_t d_w;        ///< samples per window, 4..MD_WAVE_LEN_MAX (thesis: 23 at 20 kHz)
    size_t pre_peak;   ///< samples before the minimum, < d_w
    uint32_t realign;  ///< re-find the minimum within +-realign samples of the event (0: trust the event)
    double gain;       ///< output units per ADC count (> 0)
    size_t n_noise;    ///< noise snippets wanted, 0..MD_MAX_NOISE_SNIPPETS
    uint32_t guard;    ///< a noise window keeps this many samples clear of every detection
    uint64_t seed;     ///< seed of the snippet positions (deterministic)
} sx_config_t;

#define SX_FLAG_OVERFLOW 0x1u     ///< the detector overflowed: not every spike of the interval is here
#define SX_FLAG_NOISE_SHORT 0x2u  ///< fewer noise snippets than requested could be placed

/// Aligned spike windows of one interval (caller-owned; ~200 kB with the
/// default capacities). Row i holds d_w valid samples.
typedef struct {
    double wave[MD_MAX_SPIKES][MD_WAVE_LEN_MAX];
    uint32_t t[MD_MAX_SPIKES];  ///< sample index of each window's minimum
    size_t n;
    size_t d_w;
    uint32_t n_edge_skipped;    ///< events whose window would leave the interval
    uint32_t n_duplicate;       ///< events realigned onto an already extracted minimum
    uint32_t n_overflow;        ///< events the detector could not store (copied from it)
    uint32_t flags;             ///< SX_FLAG_*
} sx_spikes_t;

/// Spike-free noise windows of one interval (caller-owned).
typedef struct {
    double wave[MD_MAX_NOISE_SNIPPETS][MD_WAVE_LEN_MAX];
    uint32_t start[MD_MAX_NOISE_SNIPPETS];  ///< first sample of each snippet
    size_t n;
    size_t d_w;
    uint32_t n_rejected;  ///< random positions rejected for touching a detection
    uint32_t flags;       ///< SX_FLAG_*
} sx_noise_t;

/// Defaults at `sample_rate_hz`: d_w = round(1.15 ms * fs) (23 at 20 kHz,
/// the thesis' window), pre_peak = round(0.4 ms * fs) (8 at 20 kHz), no
/// realignment, gain 1, 128 noise snippets, guard d_w, seed 1.
void sx_config_default(sx_config_t *cfg, uint32_t sample_rate_hz);

/// Cuts one window per event: samples [t - pre_peak, t - pre_peak + d_w).
/// x/n: the interval (sd_samples()); ev: its events (offset and times).
/// MD_E_ARG on invalid arguments or configuration (d_w > MD_WAVE_LEN_MAX).
/// O(events * (d_w + realign)).
md_status_t sx_extract_spikes(const int16_t *x, size_t n, const sd_events_t *ev, const sx_config_t *cfg,
                              sx_spikes_t *out);

/// Draws up to cfg->n_noise windows at positions uniform over the interval
/// (seeded PRNG), rejecting any window within cfg->guard samples of an event.
/// If the detector overflowed, positions are restricted to the part of the
/// interval its stored events cover. Bounded to 16 draws per snippet;
/// shortfall sets SX_FLAG_NOISE_SHORT (MD_E_DEGENERATE if none was placed
/// while some were wanted). O(draws * (log events + d_w)).
md_status_t sx_extract_noise(const int16_t *x, size_t n, const sd_events_t *ev, const sx_config_t *cfg,
                             sx_noise_t *out);

#endif

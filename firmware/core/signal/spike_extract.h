/// @file spike_extract.h
/// Extraction of aligned spike windows and spike-free noise snippets (thesis
/// §2.2.2.1: windows of d_w samples aligned by the waveform minimum;
/// §2.2.2.4: a spike-free noise sample for the SNR).
///
/// Streaming (sx_stream_t): windows are cut from the detector's delay line
/// as soon as an event is committed and its samples have arrived; noise
/// snippet candidates are placed at seeded random gaps and confirmed only
/// once the detector guarantees that no detection lies within `guard`
/// samples of them (sd_stream_horizon), through a bounded pending queue. A
/// reservoir keeps a uniform random subset of n_noise confirmed snippets
/// over the whole interval without knowing its length. Output is compact:
/// int16 ADC counts with the DC offset removed (sx_windows_t, sx_snippets_t),
/// converted to physical units (`gain`) by the accessors below or directly by
/// the _i16 entry points of features/pca.h and metrics/quality.h.
///
/// The buffer-based sx_extract_spikes()/sx_extract_noise() are kept
/// as the OFFLINE CONVENIENCE PATH: thin wrappers running the same window
/// cutter and snippet picker over a linear interval buffer, with double
/// output. Nothing is dropped silently: windows at interval edges,
/// duplicates, capacity overflows, expired or rejected candidates are counted.
#ifndef SPIKE_EXTRACT_H
#define SPIKE_EXTRACT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "numeric/md_rng.h"
#include "md_status.h"
#include "md_config.h"
#include "signal/spike_detect.h"

#define SX_QUEUE_MAX 64u                                 ///< noise candidates waiting for confirmation
#define SX_MIN_SPACING (SD_RING_SAMPLES / SX_QUEUE_MAX)  ///< smallest candidate gap: the queue cannot overflow
#define SX_SERVICE_MAX 128u  ///< sx_stream_service() must run at least every this many samples

/// Extraction parameters; fill with sx_config_default().
typedef struct {
    size_t d_w;        ///< samples per window, 4..MD_WAVE_LEN_MAX (thesis: 23 at 20 kHz)
    size_t pre_peak;   ///< samples before the minimum, < d_w
    uint32_t realign;  ///< re-find the minimum within +-realign samples of the event (0: trust the event)
    double gain;       ///< output units per ADC count (> 0)
    size_t n_noise;    ///< noise snippets wanted, 0..MD_MAX_NOISE_SNIPPETS
    uint32_t guard;    ///< a noise window keeps this many samples clear of every detection
    uint64_t seed;     ///< seed of the snippet positions (deterministic)
    uint32_t spacing;  ///< mean gap between snippet candidates, samples
    bool subsample;    ///< align spike windows on the sub-sample minimum (below); noise snippets are never shifted
    uint32_t margin;   ///< raw samples kept on each side of a spike window for a later alignment
                       ///< (spike_align.h), 0..SX_MARGIN_MAX; needs subsample off
} sx_config_t;

#define SX_MARGIN_MAX 4u  ///< largest margin of a raw window

#define SX_INTERP_MARGIN 2u  ///< samples the sub-sample resampling reads on each side of a window

#define SX_FLAG_OVERFLOW 0x1u     ///< the detector overflowed: not every spike of the interval is here
#define SX_FLAG_NOISE_SHORT 0x2u  ///< fewer noise snippets than requested could be placed

/// Aligned spike windows of one interval, compact (caller-owned; 50 kB with
/// the default capacities). Row i holds d_w valid samples: x - offset in ADC
/// counts, saturated to int16; cut with a margin, it holds margin raw samples
/// more on each side (d_w + 2 margin) until an alignment (spike_align.h)
/// turns it into d_w samples from index 0 and sets margin to 0.
typedef struct {
    int16_t wave[MD_MAX_SPIKES][MD_WAVE_LEN_MAX];
    uint32_t t[MD_MAX_SPIKES];  ///< sample index of each window's minimum
    size_t n;
    size_t d_w;
    size_t margin;             ///< raw samples on each side of the d_w of every row (0: aligned)
    size_t pre_peak;           ///< samples before the minimum in the d_w of a row
    int32_t offset;            ///< DC offset removed, ADC counts
    double gain;               ///< physical units per count (from the configuration)
    uint32_t n_edge_skipped;   ///< events whose window would leave the interval
    uint32_t n_duplicate;      ///< events realigned onto an already extracted minimum
    uint32_t n_overflow;       ///< events the detector could not store
    uint32_t n_lost;           ///< windows no longer in the delay line (0 unless the configuration is extreme)
    uint32_t n_clipped;        ///< samples saturated to int16
    uint32_t n_align_clamped;  ///< windows whose alignment shift reached its bound (spike_align.h)
    uint32_t flags;            ///< SX_FLAG_*
} sx_windows_t;

/// Spike-free noise windows of one interval, compact (caller-owned; 25 kB).
/// Order is that of the reservoir, not of time.
typedef struct {
    int16_t wave[MD_MAX_NOISE_SNIPPETS][MD_WAVE_LEN_MAX];
    uint32_t start[MD_MAX_NOISE_SNIPPETS];  ///< first sample of each snippet
    size_t n;
    size_t d_w;
    int32_t offset;
    double gain;
    uint32_t n_candidates;  ///< candidate positions drawn
    uint32_t n_confirmed;   ///< candidates clear of every detection (the reservoir's population)
    uint32_t n_rejected;    ///< candidates touching a detection +- guard
    uint32_t n_expired;     ///< candidates whose samples left the delay line before confirmation
    uint32_t n_queue_full;  ///< candidates dropped because SX_QUEUE_MAX were pending
    uint32_t flags;         ///< SX_FLAG_*
} sx_snippets_t;

/// Candidate sequence, guard check and reservoir of the snippet picker.
typedef struct {
    md_rng_t pos_rng; /* candidate gaps */
    md_rng_t res_rng; /* reservoir replacement */
    uint32_t next;    /* start of the next candidate */
    uint32_t min_gap;
    uint32_t span; /* gaps are min_gap + U[0, span] */
    size_t cursor; /* first event not entirely before the current candidate's guard zone */
} sx_picker_t;

/// Streaming extractor of one channel (caller-owned, ~0.4 kB; members private).
typedef struct {
    sx_config_t cfg;
    sx_picker_t pick;
    uint32_t queue[SX_QUEUE_MAX];
    uint32_t q_head;
    uint32_t q_count;
    size_t ev_cursor;
    sx_windows_t *win;
    sx_snippets_t *noise;
} sx_stream_t;

/// Defaults at `sample_rate_hz`: d_w = round(1.15 ms * fs) (23 at 20 kHz,
/// the thesis' window), pre_peak = round(0.4 ms * fs) (8 at 20 kHz), no
/// realignment, gain 1, 128 noise snippets, guard d_w, seed 1, candidate
/// spacing 10 s * fs / (4 * 128) (four candidates per wanted snippet in a
/// 10 s interval; set it for other interval lengths), sub-sample alignment on.
///
/// Sub-sample alignment: the thesis aligns windows on the sample of the
/// minimum, so a spike whose true trough falls between two samples is cut up
/// to half a sample early or late. For a sharp trough that shift is a large
/// change of the window's samples, and at 30 kHz it splits one neuron into a
/// centred cluster and two shifted side clusters in PCA space (as many
/// tracks). With `subsample` the trough is located between samples by the
/// parabola through the minimum and its two neighbours, δ ∈ [−½, ½], and the
/// window is resampled at t + δ with Keys' cubic convolution (a = −½; four
/// samples, exact for quadratics), as interpolated alignment does in spike
/// sorting (Blanche & Swindale 2006). `t` stays the sample of the minimum.
/// A window then needs SX_INTERP_MARGIN more samples on each side.
void sx_config_default(sx_config_t *cfg, uint32_t sample_rate_hz);

/// Binds the caller's outputs and checks that windows and guard fit the
/// detector's delay line. MD_E_ARG on invalid arguments. O(1).
md_status_t sx_stream_init(sx_stream_t *sx, const sx_config_t *cfg, const sd_stream_t *det, sx_windows_t *win,
                           sx_snippets_t *noise);

/// Starts a new interval (clears the outputs). O(1).
md_status_t sx_stream_restart(sx_stream_t *sx);

/// Cuts the windows of newly committed events and confirms or rejects noise
/// candidates, from the detector's current state. Call at least every
/// SX_SERVICE_MAX processed samples, at the same sample indices whatever the
/// chunking (spike_pipeline.h calls it at multiples of SX_SERVICE_MAX), and
/// once with `final` after sd_stream_finish(). O(new events * d_w + candidates * d_w).
md_status_t sx_stream_service(sx_stream_t *sx, const sd_stream_t *det, bool final);

/// Window i as doubles in physical units (gain * counts) into dst[0..d_w).
/// MD_E_ARG if i >= n. O(d_w).
md_status_t sx_window_to_double(const sx_windows_t *w, size_t i, double *dst);

/// Snippet i as doubles in physical units into dst[0..d_w). O(d_w).
md_status_t sx_snippet_to_double(const sx_snippets_t *s, size_t i, double *dst);

/* ---- offline convenience path (buffered API) ------------------------------ */

/// Aligned spike windows of one interval as doubles (caller-owned; ~200 kB).
typedef struct {
    double wave[MD_MAX_SPIKES][MD_WAVE_LEN_MAX];
    uint32_t t[MD_MAX_SPIKES];  ///< sample index of each window's minimum
    size_t n;
    size_t d_w;
    uint32_t n_edge_skipped;  ///< events whose window would leave the interval
    uint32_t n_duplicate;     ///< events realigned onto an already extracted minimum
    uint32_t n_overflow;      ///< events the detector could not store (copied from it)
    uint32_t flags;           ///< SX_FLAG_*
} sx_spikes_t;

/// Spike-free noise windows of one interval as doubles (caller-owned).
typedef struct {
    double wave[MD_MAX_NOISE_SNIPPETS][MD_WAVE_LEN_MAX];
    uint32_t start[MD_MAX_NOISE_SNIPPETS];  ///< first sample of each snippet
    size_t n;
    size_t d_w;
    uint32_t n_rejected;  ///< candidate positions rejected for touching a detection
    uint32_t flags;       ///< SX_FLAG_*
} sx_noise_t;

/// OFFLINE CONVENIENCE PATH. Cuts one window per event: samples
/// [t - pre_peak, t - pre_peak + d_w) of the interval x/n (sd_samples()),
/// offset removed, times gain. MD_E_ARG on invalid arguments or
/// configuration. O(events * (d_w + realign)).
md_status_t sx_extract_spikes(const int16_t *x, size_t n, const sd_events_t *ev, const sx_config_t *cfg,
                              sx_spikes_t *out);

/// OFFLINE CONVENIENCE PATH. The streaming snippet picker run over the
/// whole interval with every event known: the same candidates, the same
/// reservoir, hence the same snippets as sx_stream_t (in doubles). If the
/// detector overflowed, only the part of the interval its stored events
/// cover is used. Shortfall sets SX_FLAG_NOISE_SHORT (MD_E_DEGENERATE if none
/// was placed while some were wanted). O(candidates * (d_w + log events)).
md_status_t sx_extract_noise(const int16_t *x, size_t n, const sd_events_t *ev, const sx_config_t *cfg,
                             sx_noise_t *out);

#endif

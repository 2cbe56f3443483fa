/// @file spike_detect.h
/// Streaming spike detection over one recording interval (thesis §2.2.2.1).
///
/// Two detectors, chosen by sd_config_t.method:
///  - SD_METHOD_THRESHOLD: amplitude threshold k * median(|x|)/0.6745 with a
///    dead time (the usual baseline);
///  - SD_METHOD_WAVELET: the per-scale Bayesian wavelet detector of Nenadic &
///    Burdick (IEEE TBME 52(1), 2005) that the thesis uses, on a fixed bank of
///    Mexican-hat (or first-derivative-of-Gaussian) filters; see docs/detector.md
///    for how it differs from the published bior1.5 CWT.
///
/// Memory and passes. Both detectors need interval-wide statistics (medians)
/// before any threshold is known, and the extractor needs samples on both
/// sides of each spike. The detector therefore copies the streamed chunks
/// into an int16 interval buffer that the caller owns (one sample per entry,
/// sized for the longest interval), and runs detection in sd_finish() as a
/// bounded number of passes over it. Estimating the noise from the first
/// chunks instead would save that buffer but would not be the published
/// detector (its σ, M and priors are interval-wide) and would still need a
/// ring buffer for extraction. All other storage is inside sd_detector_t.
///
/// Use: sd_init() once, then per interval sd_push() chunks in order,
/// sd_finish(), read sd_samples() for extraction, and sd_restart().
#ifndef SPIKE_DETECT_H
#define SPIKE_DETECT_H

#include <stddef.h>
#include <stdint.h>

#include "common/md_status.h"
#include "md_config.h"
#include "signal/robust_stats.h"

#define SD_MAX_INTERVAL_SAMPLES (1u << 24)  ///< longest interval accepted (14 min at 20 kHz)
#define SD_TAPS_MAX 161u                    ///< taps of the widest wavelet filter
#define SD_HIST_BINS 2048u                  ///< histogram bins for the wavelet-coefficient median

_Static_assert(MD_WAVELET_SCALES_MAX >= 1u && MD_WAVELET_SCALES_MAX <= 16u, "1..16 wavelet scales");
_Static_assert((SD_TAPS_MAX % 2u) == 1u, "filters are centred: odd tap count");
_Static_assert(MD_MAX_SPIKES <= SD_MAX_INTERVAL_SAMPLES, "spike list indexes samples");

/// Which detector sd_finish() runs.
typedef enum {
    SD_METHOD_THRESHOLD = 0,  ///< k * MAD-sigma amplitude threshold with dead time
    SD_METHOD_WAVELET = 1     ///< Nenadic & Burdick per-scale Bayesian wavelet detector
} sd_method_t;

/// Threshold-crossing polarity of the amplitude detector.
typedef enum {
    SD_POLARITY_NEG = 0,  ///< x - offset < -threshold (spikes aligned by their minimum)
    SD_POLARITY_BOTH = 1  ///< |x - offset| > threshold
} sd_polarity_t;

/// Mother wavelet of the filter bank.
typedef enum {
    SD_WAVELET_MEXHAT = 0,  ///< Mexican hat (negative 2nd derivative of a Gaussian)
    SD_WAVELET_DOG1 = 1     ///< 1st derivative of a Gaussian (biphasic)
} sd_wavelet_t;

/// Detector parameters; fill with sd_config_default() and adjust.
typedef struct {
    sd_method_t method;
    uint32_t sample_rate_hz;   ///< 1000..200000
    double align_ms;           ///< an event's time is moved to the minimum of x within this distance (> 0)
    /* amplitude threshold detector */
    double k_sigma;            ///< threshold in robust noise sigmas (about 4..5)
    double dead_time_ms;       ///< crossings closer than this to an accepted event are the same event
    sd_polarity_t polarity;
    /* wavelet detector */
    sd_wavelet_t wavelet;
    double width_min_ms;       ///< expected spike width range (Nenadic & Burdick: 0.5..1.0 ms)
    double width_max_ms;
    unsigned n_scales;         ///< 1..MD_WAVELET_SCALES_MAX, widths spaced evenly in the range
    double cost_ratio_l;       ///< L in [-0.2, 0.2] (scaled by 36.74 as in the reference code); > 0 favours fewer false alarms
} sd_config_t;

/// Result flags of one interval (bit set).
#define SD_FLAG_OVERFLOW 0x1u   ///< more events than MD_MAX_SPIKES: later ones were counted, not stored
#define SD_FLAG_TRUNCATED 0x2u  ///< samples beyond the interval buffer were dropped

/// Events of one interval. Times are sample indices of the waveform minimum,
/// ascending; every event is at least the dedupe distance from its neighbours.
typedef struct {
    uint32_t t[MD_MAX_SPIKES];
    size_t n;                   ///< events stored
    uint32_t n_overflow;        ///< events found but not stored (capacity)
    uint32_t n_merged;          ///< candidates folded into a neighbouring event
    uint32_t flags;             ///< SD_FLAG_*
    uint32_t n_samples;         ///< samples the detection ran on
    int32_t offset;             ///< DC offset removed (rounded mean of the interval), ADC counts
    double noise_sigma;         ///< median(|x - offset|)/0.6745, ADC counts
    double threshold;           ///< amplitude detector: k * noise_sigma (0 for the wavelet detector)
    unsigned n_scales;          ///< wavelet detector: scales used
    double scale_width_ms[MD_WAVELET_SCALES_MAX];  ///< spike width each scale is tuned to
    double scale_sigma[MD_WAVELET_SCALES_MAX];     ///< coefficient noise sigma per scale
    double scale_dth[MD_WAVELET_SCALES_MAX];       ///< Bayesian decision threshold per scale
    uint32_t scale_hits[MD_WAVELET_SCALES_MAX];    ///< coefficients above the hard threshold
} sd_events_t;

/// Detector state. Caller-owned (static storage recommended: ~30 kB with
/// the default capacities); treat every member as private.
typedef struct {
    sd_config_t cfg;
    int16_t *buf;
    size_t cap;
    size_t n;
    int64_t sum;
    uint32_t n_chunks;
    uint32_t n_dropped;
    int state;
    uint32_t dead_samples;
    uint32_t align_samples;
    uint32_t merge_samples;
    size_t half_max;
    size_t half[MD_WAVELET_SCALES_MAX];
    double taps[MD_WAVELET_SCALES_MAX][SD_TAPS_MAX];
    uint32_t hist[SD_HIST_BINS];
    rs_hist_t rs;
} sd_detector_t;

/// Fills `cfg` with the defaults for `method` at `sample_rate_hz`:
/// align 0.5 ms, k 4.0, dead time 1.0 ms, negative polarity, Mexican hat,
/// widths 0.5..1.0 ms at 4 scales, L = 0.05 (slightly conservative; see docs/detector.md).
void sd_config_default(sd_config_t *cfg, sd_method_t method, uint32_t sample_rate_hz);

/// Validates `cfg`, builds the filter bank and binds the caller's interval
/// buffer `buf` of `cap` samples (1..SD_MAX_INTERVAL_SAMPLES), which must
/// outlive the detector. MD_E_ARG on an invalid parameter (including a
/// wavelet wider than SD_TAPS_MAX at this sample rate). O(scales * taps).
md_status_t sd_init(sd_detector_t *det, const sd_config_t *cfg, int16_t *buf, size_t cap);

/// Starts a new interval with the same configuration and buffer. O(1).
md_status_t sd_restart(sd_detector_t *det);

/// Appends a chunk of samples in stream order. n == 0 is allowed. If the
/// buffer fills, the samples that fit are kept, the rest are counted as
/// dropped and MD_E_CAPACITY is returned (sd_finish then sets
/// SD_FLAG_TRUNCATED). MD_E_STATE after sd_finish(). O(n).
md_status_t sd_push(sd_detector_t *det, const int16_t *samples, size_t n);

/// Runs detection over the buffered interval and fills `ev`.
/// MD_E_DEGENERATE if the interval is too short for the filters or its noise
/// level is zero (a flat channel); MD_E_STATE if called twice.
/// Cost: threshold O(N); wavelet O(N * taps * scales) in 4 passes per scale.
md_status_t sd_finish(sd_detector_t *det, sd_events_t *ev);

/// The buffered samples of the current interval and their count (NULL if
/// `det` is NULL). Valid until sd_restart().
const int16_t *sd_samples(const sd_detector_t *det, size_t *n);

#endif

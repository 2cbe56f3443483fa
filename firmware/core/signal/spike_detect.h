/// @file spike_detect.h
/// Streaming spike detection over one recording interval (thesis §2.2.2.1).
///
/// Two detectors, chosen by sd_config_t.method:
///  - SD_METHOD_THRESHOLD: amplitude threshold k * median(|x|)/0.6745 with a
///    dead time (the usual baseline);
///  - SD_METHOD_WAVELET: the per-scale Bayesian decision rule of Nenadic &
///    Burdick (IEEE TBME 52(1), 2005) that the thesis uses, on an undecimated
///    bank of B-spline wavelets computed from running integer sums (5 taps
///    per scale and sample, exact integer arithmetic); see docs/detector.md.
///
/// Streaming with fixed memory. The thresholds need interval statistics
/// (median-based sigmas), so the first `warmup_ms` of the interval are kept
/// in a small buffer inside sd_stream_t (at most SD_WARMUP_MAX samples). At
/// the end of the warm-up the statistics are computed from it (exact
/// medians by histogram), the warm-up samples are re-scanned by the online
/// detector ("replay"), and every later sample is decided as it arrives.
/// The wavelet detector optionally refines M and P(spike) of each scale from
/// all coefficients seen so far (`refine`); the sigmas stay those of the
/// warm-up. A ring delay line of SD_RING_SAMPLES raw samples (aliased onto
/// the start of the warm-up buffer once the warm-up has been replayed)
/// serves the alignment search and the extractor (spike_extract.h).
///
/// Results do not depend on how the input is chunked: every decision is tied
/// to a sample index, and sd_stream_push() stops at multiples of
/// SD_STEP_SAMPLES so that a consumer serviced between calls sees the same
/// state at the same sample indices whatever the chunk sizes.
///
/// Two APIs:
///  - streaming (sd_stream_*): what the firmware runs, one sd_stream_t per
///    channel (~25 kB), usually through spike_pipeline.h;
///  - sd_detector_t (sd_init/sd_push/sd_finish/sd_samples): the OFFLINE
///    CONVENIENCE PATH, a thin wrapper over the stream that also keeps a
///    copy of the interval (spike_detect_offline.h).
#ifndef SPIKE_DETECT_H
#define SPIKE_DETECT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "md_status.h"
#include "md_config.h"
#include "signal/robust_stats.h"

#define SD_MAX_INTERVAL_SAMPLES (1u << 24)  ///< longest interval accepted (14 min at 20 kHz)
#define SD_WARMUP_MAX 8192u                 ///< warm-up buffer (0.41 s at 20 kHz, 0.27 s at 30 kHz)
#define SD_RING_SAMPLES 2048u               ///< raw-sample delay line (power of two)
#define SD_P2_HIST 192u                     ///< history of the second running sum kept between steps
#define SD_BOX_MAX 32u                      ///< widest B-spline box (samples; 1 ms at 80 kHz); support 4*box - 1
#define SD_STEP_SAMPLES 32u                 ///< sd_stream_push() stops at multiples of this sample index
#define SD_CAND_MAX 64u                     ///< candidates waiting for their alignment look-ahead
#define SD_ALIGN_MAX 128u                   ///< longest alignment search on either side (samples)
#define SD_RUN_MAX 256u                     ///< a supra-threshold run longer than this is split
#define SD_REFINE_SAMPLES 4096u             ///< refinement period of the wavelet statistics (samples)
#define SD_SIGMA_STRIDE 2u                  ///< sigma from every 2nd warm-up coefficient (neighbours are correlated)

_Static_assert(MD_WAVELET_SCALES_MAX >= 1u && MD_WAVELET_SCALES_MAX <= 16u, "1..16 wavelet scales");
_Static_assert((SD_RING_SAMPLES & (SD_RING_SAMPLES - 1u)) == 0u, "ring size is a power of two");
_Static_assert((SD_RING_SAMPLES % SD_STEP_SAMPLES) == 0u, "a step never wraps the delay line");
_Static_assert(SD_P2_HIST >= 4u * SD_BOX_MAX + 2u * SD_BOX_MAX, "the widest kernel and its lag fit the history");
_Static_assert((SD_REFINE_SAMPLES % SD_STEP_SAMPLES) == 0u && SD_STEP_SAMPLES == 32u,
               "steps never straddle a refinement; one bit per step sample");
_Static_assert(SD_WARMUP_MAX >= SD_RING_SAMPLES, "the delay line aliases the warm-up buffer");
_Static_assert(4ull * SD_BOX_MAX * SD_BOX_MAX * 32768ull < 2147483648ull, "coefficients fit int32 exactly");
_Static_assert(MD_MAX_SPIKES <= SD_MAX_INTERVAL_SAMPLES, "spike list indexes samples");

/// Which detector runs.
typedef enum {
    SD_METHOD_THRESHOLD = 0,  ///< k * MAD-sigma amplitude threshold with dead time
    SD_METHOD_WAVELET = 1     ///< Nenadic & Burdick per-scale Bayesian wavelet detector
} sd_method_t;

/// Threshold-crossing polarity of the amplitude detector.
typedef enum {
    SD_POLARITY_NEG = 0,  ///< x - offset < -threshold (spikes aligned by their minimum)
    SD_POLARITY_BOTH = 1  ///< |x - offset| > threshold
} sd_polarity_t;

/// Mother wavelet of the bank (both are B-spline approximations, correlation
/// >= 0.98 with the continuous wavelet at the matched width).
typedef enum {
    SD_WAVELET_MEXHAT = 0,  ///< second difference of a linear B-spline (Mexican-hat-like, 5 taps)
    SD_WAVELET_DOG1 = 1     ///< first difference of a linear B-spline (biphasic, 4 taps)
} sd_wavelet_t;

/// Detector parameters; fill with sd_config_default() and adjust.
typedef struct {
    sd_method_t method;
    uint32_t sample_rate_hz;  ///< 1000..200000
    double align_ms;          ///< an event's time is moved to the minimum of x within this distance (> 0)
    /* amplitude threshold detector */
    double k_sigma;       ///< threshold in robust noise sigmas (about 4..5)
    double dead_time_ms;  ///< crossings closer than this to an accepted event are the same event
    sd_polarity_t polarity;
    /* wavelet detector */
    sd_wavelet_t wavelet;
    double width_min_ms;  ///< expected spike width range (Nenadic & Burdick: 0.5..1.0 ms)
    double width_max_ms;
    unsigned n_scales;  ///< 1..MD_WAVELET_SCALES_MAX, widths spaced evenly in the range
    double
        cost_ratio_l;  ///< L in [-0.2, 0.2] (scaled by 36.74 as in the reference code); > 0 favours fewer false alarms
    /* streaming */
    double warmup_ms;   ///< statistics prefix, 5 ms .. SD_WARMUP_MAX samples
    double interval_s;  ///< nominal interval length: N of the universal threshold sqrt(2 ln N)
    bool refine;        ///< wavelet: refine M and P(spike) from every coefficient seen so far
} sd_config_t;

/// Result flags of one interval (bit set).
#define SD_FLAG_OVERFLOW 0x1u   ///< more events than MD_MAX_SPIKES: later ones were counted, not stored
#define SD_FLAG_TRUNCATED 0x2u  ///< samples beyond the interval buffer were dropped (sd_detector_t only)
#define SD_FLAG_SHORT 0x4u      ///< the interval ended inside the warm-up: statistics from what arrived

/// Events of one interval. Times are sample indices of the waveform minimum,
/// ascending; every event is at least the dedupe distance from its neighbours.
typedef struct {
    uint32_t t[MD_MAX_SPIKES];
    size_t n;                                      ///< events stored
    uint32_t n_overflow;                           ///< events found but not stored (capacity)
    uint32_t n_merged;                             ///< candidates folded into a neighbouring event
    uint32_t flags;                                ///< SD_FLAG_*
    uint32_t n_samples;                            ///< samples the detection ran on
    int32_t offset;                                ///< DC offset removed (rounded mean of the warm-up), ADC counts
    double noise_sigma;                            ///< median(|x - offset|)/0.6745 over the warm-up, ADC counts
    double threshold;                              ///< amplitude detector: k * noise_sigma (0 for the wavelet detector)
    unsigned n_scales;                             ///< wavelet detector: scales used
    double scale_width_ms[MD_WAVELET_SCALES_MAX];  ///< spike width each scale is tuned to
    double scale_sigma[MD_WAVELET_SCALES_MAX];     ///< coefficient noise sigma per scale (unit-L2 kernel, counts)
    double scale_dth[MD_WAVELET_SCALES_MAX];       ///< Bayesian decision threshold per scale (same units), last value
    uint32_t scale_hits[MD_WAVELET_SCALES_MAX];    ///< coefficients above the hard threshold (whole interval)
    uint32_t warmup_samples;                       ///< samples the statistics came from
    uint32_t n_cand_dropped;  ///< candidates lost because SD_CAND_MAX were waiting (never seen in practice)
} sd_events_t;

/// Streaming detector of one channel. Caller-owned (static storage), about
/// 25 kB; treat every member as private.
typedef struct {
    sd_config_t cfg;
    int phase;
    md_status_t status;
    uint32_t warm_target;
    uint32_t warm_n;
    uint32_t replay_pos;
    int64_t warm_sum;
    int16_t warm_min;
    int16_t warm_max;
    uint32_t n; /* samples processed online */
    /* amplitude detector */
    int32_t thr_lo;
    int32_t thr_hi;
    bool above_prev;
    /* wavelet bank */
    unsigned ns;
    uint32_t box[MD_WAVELET_SCALES_MAX];
    uint32_t stride[MD_WAVELET_SCALES_MAX];
    uint32_t lag[MD_WAVELET_SCALES_MAX];
    uint32_t back[MD_WAVELET_SCALES_MAX]; /* lag + span * box: P2 history a centre's oldest tap reaches back */
    uint8_t kind[MD_WAVELET_SCALES_MAX];  /* straight-code scan body of the scale (spike_detect.c) */
    uint32_t dmax;
    uint32_t c_first;
    double knorm[MD_WAVELET_SCALES_MAX];
    uint32_t kl1[MD_WAVELET_SCALES_MAX];
    uint32_t lo_i[MD_WAVELET_SCALES_MAX];
    uint32_t hard_i[MD_WAVELET_SCALES_MAX];
    uint32_t dth_i[MD_WAVELET_SCALES_MAX];
    double sigma_c[MD_WAVELET_SCALES_MAX];
    double hard_c[MD_WAVELET_SCALES_MAX];
    uint64_t sum_sig[MD_WAVELET_SCALES_MAX];
    uint32_t hits[MD_WAVELET_SCALES_MAX];
    uint32_t n_coefs;
    uint32_t next_refine;
    uint32_t p1;
    uint32_t p2;
    uint32_t hist_len;
    uint32_t p2_base; /* p2lin index of the current step's first sum (>= hist_len of history before it) */
    uint32_t
        p2lin[SD_P2_HIST + 10u * SD_STEP_SAMPLES]; /* running sums P2: history, then the steps since the last shift */
    bool in_run;
    uint32_t run_start;
    bool grp_open;
    uint32_t grp_first;
    uint32_t grp_last;
    uint32_t merge;
    /* candidates, merging, commit */
    uint32_t cand[SD_CAND_MAX];
    uint32_t cand_head;
    uint32_t cand_count;
    uint32_t before;
    uint32_t after;
    uint32_t dedupe;
    bool has_pend;
    uint32_t pend_t;
    uint32_t due;
    uint32_t latency;
    rs_hist_t rs;
    rs_hist_t rs2;
    sd_events_t ev;
    int16_t buf[SD_WARMUP_MAX]; /* warm-up samples; its first SD_RING_SAMPLES are the delay line */
} sd_stream_t;

/// Fills `cfg` with the defaults for `method` at `sample_rate_hz`:
/// align 0.5 ms, k 4.0, dead time 1.0 ms, negative polarity,
/// widths 0.5..1.0 ms at 2 scales of the first-difference (DOG1) B-spline
/// wavelet, L = 0.05 (slightly conservative), warm-up
/// 250 ms, nominal interval 10 s, refinement on (see docs/detector.md).
void sd_config_default(sd_config_t *cfg, sd_method_t method, uint32_t sample_rate_hz);

/// Validates `cfg` (MD_E_ARG on an invalid parameter, including a wavelet
/// wider than SD_BOX_MAX, a warm-up longer than SD_WARMUP_MAX, or delays
/// that would not fit the delay line) and starts the first interval. O(scales * box).
md_status_t sd_stream_init(sd_stream_t *st, const sd_config_t *cfg);

/// Starts a new interval with the same configuration. O(1).
md_status_t sd_stream_restart(sd_stream_t *st);

/// Feeds samples in stream order and processes at most up to the next
/// multiple of SD_STEP_SAMPLES of the online sample index; *used receives
/// the number of input samples consumed (possibly 0 while the warm-up is
/// replayed: call again, with the same remaining input, until
/// sd_stream_busy() is false and the input is used up). MD_E_DEGENERATE
/// once the warm-up turned out flat (no noise); MD_E_STATE after the end.
/// O(n * scales).
md_status_t sd_stream_push(sd_stream_t *st, const int16_t *x, size_t n, size_t *used);

/// True while warm-up samples wait to be replayed.
bool sd_stream_busy(const sd_stream_t *st);

/// Marks the end of the input. If the interval ended inside the warm-up the
/// statistics are computed from what arrived (SD_FLAG_SHORT) and a replay
/// starts: drive it with sd_stream_push(st, NULL, 0, &used) until
/// sd_stream_busy() is false, then call sd_stream_finish(). O(warm-up).
md_status_t sd_stream_end(sd_stream_t *st);

/// Flushes runs, candidates and the last event after sd_stream_end(); the
/// events are then final (sd_stream_events()). MD_E_DEGENERATE if the
/// interval was too short or flat. O(SD_CAND_MAX * align).
md_status_t sd_stream_finish(sd_stream_t *st);

/// Events committed so far (final: a committed event never changes). Valid
/// until sd_stream_restart(). NULL if st is NULL.
const sd_events_t *sd_stream_events(const sd_stream_t *st);

/// Samples processed online so far (the delay line holds the last
/// SD_RING_SAMPLES of them).
uint32_t sd_stream_processed(const sd_stream_t *st);

/// Lower bound on the time of every event not yet committed: events with
/// t < horizon are all in sd_stream_events() except at most the pending one
/// (*pend_t, *has_pend), which can only move later. UINT32_MAX after finish.
uint32_t sd_stream_horizon(const sd_stream_t *st, bool *has_pend, uint32_t *pend_t);

/// Bound on how far behind the newest sample the detector may still need
/// or commit samples (kernel delay, capped runs and groups, alignment,
/// dedupe, one step). A consumer of the delay line must fit its own window
/// within SD_RING_SAMPLES - latency. 0 if st is NULL.
uint32_t sd_stream_latency(const sd_stream_t *st);

/// Copies raw samples [start, start + len) from the delay line into dst.
/// MD_E_ARG if any of them is not (or no longer) in it. O(len).
md_status_t sd_stream_copy(const sd_stream_t *st, uint32_t start, size_t len, int16_t *dst);

/// Read-only view of a sample history: x[i & mask] for lo <= i < hi. The
/// delay line is a ring (mask = SD_RING_SAMPLES - 1); a linear interval
/// buffer has mask = UINT32_MAX and lo = 0.
typedef struct {
    const int16_t *x;
    uint32_t mask;
    uint32_t lo;
    uint32_t hi;
} sd_view_t;

/// The delay line as a view.
sd_view_t sd_stream_view(const sd_stream_t *st);

/// Index of the first minimum of the view over [lo, hi] (clamped to the
/// view); lo if the range is empty. O(hi - lo).
uint32_t sd_view_argmin(const sd_view_t *v, uint32_t lo, uint32_t hi);

#endif

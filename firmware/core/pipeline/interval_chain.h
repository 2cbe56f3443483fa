/// @file interval_chain.h
/// The processing of one recording interval of one channel, from its int16
/// samples to the tracker's answer: the controller's chain (thesis §2.2.2 and
/// ch. 4), the one that firmware/app/md_interval.c and the offline tools
/// (mhtc-replay, md-bench) run, so an offline figure is the firmware's.
///
/// Stages of an interval, in this order:
///  1. ic_begin, then ic_push for every chunk of samples: streaming wavelet
///     detection and extraction (spike_pipeline.h) into int16 windows aligned
///     by their minimum and spike-free noise snippets (§2.2.2.1, §2.2.2.4);
///     results do not depend on the chunk sizes;
///  2. ic_end: flushes detection and extraction and aligns the windows on
///     their template to a fraction of a sample (spike_align.h);
///  3. ic_features: the PCA basis B^k of the windows (§2.2.2.2), which is the
///     tracker's measurement matrix H^k (§4.4.2) — from the noise snippets
///     when fewer than 2 windows were cut, so H^k stays defined and every track
///     is missed —, features of windows and snippets, the noise feature
///     covariance Ξ of the outlier component (Remark 3.2), the noise RMS, and
///     the robust amplitude of every window (approach_guard.h; outliers
///     included, so the guard does not depend on the tracker);
///  4. ic_track: one tracker step (mhtc_update: MHTC or a baseline) with B^k
///     and Ξ on the int16 windows, the interval's duration being the samples
///     pushed over the sample rate, and the electrode's travel since the
///     previous tracked interval (its process noise grows with it, §4.6);
///  5. ic_score: SNR of every track of the leading hypothesis (peak-to-peak
///     over noise RMS), the dominant track (the highest SNR, §2.2.2.4) and its
///     isolation distance ID_g under its fitted Σ_g = λ C_g, noise snippets
///     counting as non-members.
/// ic_run runs 2-5. A stage before the one it needs returns MD_E_STATE;
/// stages 3-5 may be run again on the same interval (their inputs stay:
/// a benchmark repeats them; a second ic_track steps the tracker again); a
/// new ic_begin may start at any time.
///
/// Memory: ic_workspace_t (about 310 kB at the default capacities of
/// md_config.h, 218 kB of it the union below) is caller-owned and holds
/// everything of an interval; one serves every channel processed in turn.
/// Stages that never overlap share storage (the streaming channel while
/// recording, the PCA scratch, the tracker's workspace during and right after
/// its step, the isolation scratch). The tracker state (mhtc_state_t, one per
/// channel) is the caller's. No heap, no recursion, every loop bounded by
/// md_config.h.
///
/// Errors: every function returns its status, and every failure is also
/// counted in ic_workspace_t.stats (zero in a zeroed workspace: static
/// storage, or memset). A failure of ic_end, ic_features or ic_track leaves
/// the tracker unchanged (mhtc_update guarantees it for its own errors), so the
/// caller may skip the interval.
///
/// Use:
///     static ic_workspace_t ws;              // zeroed
///     ic_begin(&ws, &cfg);                   // per interval
///     ic_push(&ws, x, n); ...                // as the samples arrive
///     ic_run(&ws, &tracker, move_um, &out); // or ic_end/ic_features/ic_track/ic_score
///     read out, ws.win (spike times), ws.res (labels, tracks), ws.track_snr
#ifndef INTERVAL_CHAIN_H
#define INTERVAL_CHAIN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "md_status.h"
#include "features/pca.h"
#include "md_config.h"
#include "metrics/quality.h"
#include "signal/spike_align.h"
#include "signal/spike_pipeline.h"
#include "tracking/mhtc.h"

#define IC_D 2u                   ///< PCA feature dimension d (thesis: 2-D features)
#define IC_SNIPPET_CANDIDATES 4u  ///< noise candidates drawn per wanted snippet (spike_extract.h spacing)
_Static_assert(IC_D <= MD_FEAT_DIM_MAX, "feature dimension within the configured capacity");
_Static_assert(MD_MAX_SPIKES <= EM_N_MAX, "every window fits the tracker's input");

/// What an interval is (fixed at ic_begin).
typedef struct {
    uint32_t sample_rate_hz;  ///< samples per second of the channel: 7500..32768 at the detector's
                              ///< defaults (its narrowest wavelet box >= 2 samples; its 250 ms
                              ///< warm-up within SD_WARMUP_MAX samples)
    double gain_uv;           ///< µV per ADC count (> 0): windows and features are in µV
    uint32_t num_samples;     ///< samples the interval will have (> 0): N of the detector's universal
                              ///< threshold and the spacing of noise-snippet candidates
    uint8_t guard_top_k;      ///< robust amplitude = k-th largest window amplitude (1..AG_TOP_K_MAX)
} ic_config_t;

/// What the interval says, for the decision and the telemetry (ic_score).
typedef struct {
    uint32_t n_windows;  ///< windows cut (every detection kept; the telemetry's spikes)
    uint32_t n_spikes;   ///< windows given to the tracker (0 when fewer than 2 were cut)
    bool has_dominant;
    uint32_t dominant;         ///< its track id
    uint8_t dominant_cluster;  ///< its cluster in the leading model (1..G)
    double snr;                ///< its SNR (peak-to-peak / noise RMS)
    double iqm;                ///< its isolation distance ID_g (sqrt), 0 if undefined
    double amp;                ///< robust amplitude of all windows (approach guard), noise RMS units
} ic_out_t;

/// Failures, counted over the workspace's life (nothing is dropped silently).
typedef struct {
    uint32_t intervals;       ///< ic_begin calls accepted
    uint32_t begin_errors;    ///< configurations rejected by ic_begin
    uint32_t push_errors;     ///< ic_push calls that failed (flat warm-up, capacity, state)
    uint32_t end_errors;      ///< ic_end failures other than a degenerate interval (which ic_features judges)
    uint32_t feature_errors;  ///< ic_features failures (too few noise snippets, a flat interval, PCA, Ξ ...)
    uint32_t track_errors;    ///< tracker steps that failed
    uint32_t snr_undefined;   ///< detected tracks whose SNR could not be computed (reported as 0)
    uint32_t iso_undefined;   ///< dominant tracks without an isolation distance (reported as 0)
} ic_stats_t;

/// Everything of one interval (caller-owned; members are readable outputs as
/// documented, written only by this unit).
typedef struct {
    /// Storage of stages that never overlap in time.
    union {
        sp_channel_t sp;        ///< stages 1-2: streaming detector and extractor
        sa_work_t align;        ///< stage 2, after the extractor: window alignment
        pca_work_t pca;         ///< stage 3: PCA scratch
        mhtc_workspace_t mhtc;  ///< stage 4, and mhtc_hyp_labels after it until ic_score/ic_isolation
        double qm_work[(MD_MAX_SPIKES + MD_MAX_NOISE_SNIPPETS) * IC_D];  ///< stage 5: isolation scratch
    } u;
    sx_windows_t win;                ///< spike windows (int16; t: sample of each minimum), aligned by ic_end
    sx_snippets_t noise;             ///< spike-free noise snippets (int16)
    double y[MD_MAX_SPIKES * IC_D];  ///< spike features, n_spikes × d
    double noise_y[MD_MAX_NOISE_SNIPPETS * IC_D];  ///< noise features, noise.n × d
    double xi[IC_D * IC_D];                        ///< Ξ
    pca_basis_t basis;                             ///< B^k
    mhtc_result_t res;                             ///< leading hypothesis of the interval (ic_track)
    double track_snr[MHTC_TARGETS_MAX];            ///< SNR per reported track of res (0 if missed; ic_score)
    double noise_rms_uv;                           ///< RMS of the noise snippets (ic_features)
    double amp;                                    ///< robust amplitude (ic_features)
    uint32_t n_spikes;                             ///< windows given to the tracker (ic_features)
    uint32_t n_pushed;                             ///< samples pushed in this interval
    ic_config_t cfg;                               ///< of the current interval
    int stage;                                     ///< private: the last stage completed
    ic_stats_t stats;
} ic_workspace_t;

/// Starts an interval: validates cfg and sets up detection and extraction
/// (the detector's N and the snippet spacing from cfg->num_samples). MD_E_ARG
/// on NULL or a configuration the chain does not support (nothing started).
/// O(scales · box).
md_status_t ic_begin(ic_workspace_t *ws, const ic_config_t *cfg);

/// Streams n samples (any chunking, n == 0 allowed). Errors of sp_push
/// (MD_E_DEGENERATE: flat warm-up; MD_E_CAPACITY: beyond
/// SD_MAX_INTERVAL_SAMPLES) or MD_E_STATE outside an interval. O(n · scales).
md_status_t ic_push(ic_workspace_t *ws, const int16_t *x, size_t n);

/// Ends the interval: flushes detection, cuts the last windows, confirms the
/// last snippets. A degenerate interval (too short, flat, no snippet) is not
/// an error here: ic_features refuses it. MD_E_STATE if not recording.
md_status_t ic_end(ic_workspace_t *ws);

/// Basis, features, Ξ, noise RMS and robust amplitude (stage 3).
/// MD_E_DEGENERATE if there are no more than d noise snippets (Ξ needs more),
/// else the first error of pca_fit_i16, the projections, Ξ, the noise RMS or
/// the amplitude. MD_E_STATE before ic_end. O(n d_w² + d_w³).
md_status_t ic_features(ic_workspace_t *ws);

/// One step of `tracker` with this interval (stage 4): ws->res. `move_um`:
/// electrode travel since the tracker's previous interval, µm (>= 0; 0 if
/// unknown; mhtc_input_t.move_um). On an error the tracker is unchanged but
/// for its update_errors counter. MD_E_STATE before ic_features.
/// O(tracker step, mhtc.h).
md_status_t ic_track(ic_workspace_t *ws, mhtc_state_t *tracker, double move_um);

/// SNR of every track of ws->res into ws->track_snr, the dominant track and
/// its isolation distance into *out (stage 5). MD_E_STATE before ic_track.
/// O(n d_w + (n + m) d²).
md_status_t ic_score(ic_workspace_t *ws, ic_out_t *out);

/// ic_end, ic_features, ic_track, ic_score: MD_OK or the first error.
md_status_t ic_run(ic_workspace_t *ws, mhtc_state_t *tracker, double move_um, ic_out_t *out);

/// Isolation distance of cluster `cluster` (1..G) of the leading hypothesis
/// (qm_isolation_distance with its Σ_g = λ C_g and the noise snippets as
/// non-members), after ic_track. Ends the validity of mhtc_hyp_labels on this
/// workspace (it uses the tracker's scratch). MD_E_ARG for a cluster outside
/// 1..G; MD_E_STATE before ic_track; else qm_isolation_distance's status.
md_status_t ic_isolation(ic_workspace_t *ws, uint8_t cluster, qm_isolation_t *iso);

#endif

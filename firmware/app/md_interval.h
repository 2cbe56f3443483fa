/// @file md_interval.h
/// Processing of one recording interval of one electrode: the controller's
/// adapter of the interval chain (pipeline/interval_chain.h: streaming
/// detection and extraction, PCA basis B^k, features, Ξ, one tracker step,
/// per-track SNR and the isolation distance of the dominant track). The
/// electrode's FE_INFO (sample rate, gain) and approach guard (top_k) make
/// the chain's configuration, its tracker takes the step, and the `tracker`
/// parameter chooses which tracker that is. Uses only the shared
/// md_workspace_t (= ic_workspace_t) and the electrode's tracker; on any
/// failure the tracker is unchanged and the caller skips the cycle.
#ifndef MD_INTERVAL_H
#define MD_INTERVAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "md_status.h"
#include "md_cycle.h"

/// What the interval says, for the decision and the telemetry.
typedef struct {
    uint32_t n_spikes;  ///< windows given to the tracker
    bool spikes_seen;   ///< windows cut / duration >= min_rate_hz
    bool has_dominant;
    uint32_t dominant;         ///< its track id
    uint8_t dominant_cluster;  ///< its cluster in the leading model (1..G)
    double snr;                ///< its SNR (peak-to-peak / noise RMS)
    double iqm;                ///< its isolation distance ID_g (sqrt), 0 if undefined
    double amp;                ///< robust amplitude of all detections (approach guard), noise RMS units
} md_interval_out_t;

/// Tracker selected by the `tracker` parameter (0 MHTC, 1 MAP-NN, 2 ML-NN,
/// 3 GNN); a value outside the table's range falls back to MHTC. O(1).
mhtc_tracker_t md_interval_tracker(const md_params_t *p);

/// Starts an interval of `num_samples` of electrode `el` (ic_begin with its
/// FE_INFO sample rate and gain and its guard's top_k). MD_E_ARG if FE_INFO
/// is missing or the chain rejects the configuration. O(scales · box).
md_status_t md_interval_begin(md_workspace_t *ws, const md_electrode_t *el, uint32_t num_samples);

/// Streams samples of the interval. Errors as ic_push.
md_status_t md_interval_push(md_workspace_t *ws, const int16_t *x, size_t n);

/// Ends the interval and runs every stage (ic_run with the electrode's
/// tracker and its travel el->move_um); spikes_seen: the windows cut over `duration_s` reach
/// `min_rate_hz`. MD_OK, or the first stage's error (MD_E_DEGENERATE: too few
/// noise snippets or a flat interval; MD_E_NUMERIC / MD_E_NOCONVERGE from
/// PCA or the tracker ...). O(tracker step).
md_status_t md_interval_run(md_workspace_t *ws, md_electrode_t *el, double duration_s, double min_rate_hz,
                            md_interval_out_t *out);

#endif

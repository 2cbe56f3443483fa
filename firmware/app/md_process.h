/// @file md_process.h
/// Processing of one recording interval of one electrode (thesis §2.2.2 and
/// ch. 4): streaming detection/extraction set-up and feed, then PCA basis
/// B^k of the interval's windows, features, noise feature covariance Ξ, one
/// MHTC step with that basis, per-track SNR and the isolation distance of the
/// dominant track (the track of the leading hypothesis with the highest SNR).
/// Uses only the shared md_workspace_t and the electrode's tracker; on any
/// failure the tracker is unchanged (mhtc_step guarantees it) and the caller
/// skips the cycle.
#ifndef MD_PROCESS_H
#define MD_PROCESS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/md_status.h"
#include "md_cycle.h"

/// What the interval says, for the decision and the telemetry.
typedef struct {
    uint32_t n_spikes;          ///< windows given to the tracker
    bool spikes_seen;           ///< n_spikes / duration >= min_rate_hz
    bool has_dominant;
    uint32_t dominant;          ///< its track id
    uint8_t dominant_cluster;   ///< its cluster in the leading model (1..G)
    double snr;                 ///< its SNR (peak-to-peak / noise RMS)
    double iqm;                 ///< its isolation distance ID_g (sqrt), 0 if undefined
    double amp;                 ///< robust amplitude of all detections (approach guard), noise RMS units
} md_process_out_t;

/// Tracker selected by the `tracker` parameter (0 MHTC, 1 MAP-NN, 2 ML-NN,
/// 3 GNN); a value outside the table's range falls back to MHTC. O(1).
mhtc_tracker_t md_process_tracker(const md_params_t *p);

/// Prepares the shared channel for an interval of `num_samples` of electrode
/// `el` (its FE_INFO sample rate and gain). MD_E_ARG if FE_INFO is missing or
/// a configuration is rejected. O(scales · box).
md_status_t md_process_begin(md_workspace_t *ws, const md_electrode_t *el, uint32_t num_samples);

/// Streams samples of the interval. Errors as sp_push.
md_status_t md_process_push(md_workspace_t *ws, const int16_t *x, size_t n);

/// Ends the interval and runs every stage, and the robust amplitude of all
/// detections with the k of the electrode's approach guard. MD_OK, or the first stage's
/// error (MD_E_DEGENERATE: too few noise snippets or a flat interval;
/// MD_E_NUMERIC / MD_E_NOCONVERGE from PCA or the tracker ...). O(tracker step).
md_status_t md_process_interval(md_workspace_t *ws, md_electrode_t *el, double duration_s, double min_rate_hz,
                                md_process_out_t *out);

#endif

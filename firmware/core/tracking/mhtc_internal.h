/// @file mhtc_internal.h
/// Functions shared by the MHTC translation units (mhtc.c, mhtc_commit.c,
/// mhtc_baseline.c). Not part of the public API.
#ifndef MHTC_INTERNAL_H
#define MHTC_INTERNAL_H

#include "tracking/mhtc.h"

/// Tag of a new track from cluster g (1..G) of model slot m, before it has an ID.
#define MHTC_TAG_NEW(m, g) (-2 - (int32_t)((m)*MHTC_G_MAX + ((g)-1u)))

/// Parent hypothesis p of this interval (the empty root before the first interval).
const mhtc_hyp_t *mhtc_parent(const mhtc_state_t *st, size_t p);

/// Fills ws->targets from parent p's tracks (predictions of mhtc_predict_pool). Returns N_t.
size_t mhtc_fill_targets(const mhtc_state_t *st, mhtc_workspace_t *ws, size_t p);

/// Cluster tags of solution s of model m (track ID, new tag, MHTC_ID_FALSE) into tag[0..G).
void mhtc_solution_tags(const mhtc_state_t *st, const mhtc_workspace_t *ws, size_t m, size_t s, int32_t *tag);

/// Tracks the child would keep (not deleted) plus its new tracks.
size_t mhtc_child_track_count(const mhtc_state_t *st, const mhtc_workspace_t *ws, size_t m, size_t s, uint32_t k_miss);

/// Offers a child to the best-L list with duplicate pruning (§4.4.1).
void mhtc_offer(mhtc_state_t *st, mhtc_workspace_t *ws, const mhtc_cand_t *c);

/// Steps 8-9 for the candidates in ws->cand: stage records (pool rule), build
/// the next hypotheses, replace the state's generation, fill out.
md_status_t mhtc_commit(mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws, mhtc_result_t *out);

/// One interval of a single-hypothesis baseline (MAP-NN, ML-NN, GNN): fills ws->cand[0].
md_status_t mhtc_baseline(mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws);

/// Σ_j of record t (waveform space, rank ≤ d) seen through the basis h (d × dw),
/// with a small ridge so it stays SPD, into c (d × d).
void mhtc_map_sigma(const mhtc_track_t *t, const double *h, size_t d, size_t dw, double *c);

/// Prediction of a record's filter for an interval after `move_um` of electrode
/// travel (eq. 4.7-4.8): Q = q·I plus, from the travel, an uncertain gain of
/// the whole waveform (variance (q_move_per_um · move_um)², kf_predict_scaled).
md_status_t mhtc_predict_record(const mhtc_state_t *st, kf_state_t *kf, double move_um, kf_work_t *ws);

/// Adds a usable G = 0 model (every track missed) for parent p; returns its slot or MHTC_MODELS_MAX.
size_t mhtc_empty_model(mhtc_state_t *st, mhtc_workspace_t *ws, size_t p);

#endif

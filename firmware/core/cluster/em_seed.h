/// @file em_seed.h
/// Seed partitions for MAP-EM from the previous interval's clusters (thesis §3.3.4).
///
/// "Previous clusters" are the caller's predicted targets (em_target_t: the
/// predicted mean and the cluster covariance Σ_j^{k-1}), either from the last
/// interval or from a parent hypothesis of the tracker. With G_m clusters
/// wanted and J = n_targets previous clusters:
/// - G_m = J (§3.3.4.1): each point goes to the prior cluster of least
///   squared Mahalanobis distance d_j^2 (eq. 3.16);
/// - G_m < J (§3.3.4.2): of all C(J, G_m) subsets of prior clusters, the one
///   with the least Σ_i min_{j∈S} d_j^2(y_i) is kept and points assigned within it;
/// - G_m > J (§3.3.4.3): points are assigned to all J clusters, then G_m - J
///   times the group with the largest mean point-to-centroid Euclidean
///   distance is split on its principal axis at the largest gap between
///   neighbouring projections, the gap restricted to the middle 90 % of the
///   group (footnote 10). With J = 0 the splitting starts from one group.
#ifndef EM_SEED_H
#define EM_SEED_H

#include "cluster/em_model.h"

#define EM_SEED_MIDDLE_FRACTION 0.90  ///< part of a group where a split may fall (footnote 10)

/// Scratch space for em_seed_from_targets (caller-owned, no heap).
typedef struct {
    double key[EM_N_MAX];
    uint16_t idx[EM_N_MAX];
} em_seed_work_t;

/// Computes seed labels (0..g-1, one per point) for a model with g clusters.
/// targets may be NULL when n_targets = 0. Each target's cluster_cov must be SPD.
/// MD_E_ARG on bad arguments, MD_E_NUMERIC if a cluster_cov is not SPD or a
/// point is not finite,
/// MD_E_DEGENERATE if the partition cannot reach g non-empty groups
/// (too few points or every group too small to split).
/// O(C(J,g) · n · g · d^2) for the subset search, O(n log n) per split.
md_status_t em_seed_from_targets(const em_data_t *data, const em_target_t *targets, size_t n_targets, size_t g,
                                 em_seed_work_t *ws, uint8_t *labels);

/// Splits group `victim` of `labels` into itself and a new group `new_label`
/// along its principal axis at the largest gap inside the middle 90 % (§3.3.4.3).
/// MD_E_DEGENERATE if the group has fewer than 2 points or no spread.
md_status_t em_seed_split(const em_data_t *data, uint8_t *labels, uint8_t victim, uint8_t new_label,
                          em_seed_work_t *ws);

#endif

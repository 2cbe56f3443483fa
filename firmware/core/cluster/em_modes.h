/// @file em_modes.h
/// Is a fitted mixture splitting one mode into several components?
///
/// The clusters of thesis §3.3 share one volume (Σ_g = λ C_g), so a neuron
/// whose spikes spread more than the others' (amplitude jitter grows with
/// amplitude; bursts add a tail of smaller spikes) is covered by two or three
/// overlapping components of the best model, and every one of them becomes a
/// track. Tracks of overlapping components predict nearly the same place, so
/// the association between them is a coin toss each interval and the neuron's
/// identity swaps between them.
///
/// The test here is the ridgeline of Ray & Lindsay (2005): every mode of a
/// two-component Gaussian mixture lies on
///   x(α) = [(1−α)Σ_a⁻¹ + αΣ_b⁻¹]⁻¹ [(1−α)Σ_a⁻¹μ_a + αΣ_b⁻¹μ_b],  α ∈ [0, 1],
/// so the pair density π_a N(x; μ_a, Σ_a) + π_b N(x; μ_b, Σ_b) along that
/// curve shows whether the pair has one mode or two. The ridgeline ratio
/// (Hennig 2010, "Methods for merging Gaussian mixture components") is the
/// deepest point of the curve relative to the lower of the highest points on
/// either side of it: 1 for one mode, small for two well separated modes.
///
/// Cost: EM_RIDGE_POINTS points per pair, each a d × d Cholesky solve; for
/// G = 4, d = 2 about 200 small solves. No allocation, no recursion.
#ifndef EM_MODES_H
#define EM_MODES_H

#include <stdbool.h>

#include "cluster/em_model.h"

#define EM_RIDGE_POINTS 41u  ///< α grid on [0, 1] (a step of 0.025)

/// Ridgeline ratio in (0, 1] of w_a N(m_a, c_a) + w_b N(m_b, c_b) in d ≤ EM_D_MAX
/// dimensions (c_*: row-major d × d covariances, SPD; weights > 0).
/// MD_E_ARG on bad arguments, MD_E_NUMERIC if a covariance is not SPD.
md_status_t em_gauss_ridge_ratio(size_t d, double w_a, const double *m_a, const double *c_a, double w_b,
                                 const double *m_b, const double *c_b, double *ratio);

/// Ridgeline ratio in (0, 1] of components a and b (1-based cluster
/// numbers, a ≠ b, both ≤ p->g) of the fitted parameters p. The weights are
/// the pair's own π_a, π_b; the outlier component and the other clusters are
/// left out (the pairwise criterion of Hennig 2010). MD_E_ARG on bad indices or
/// parameters, MD_E_NUMERIC if a shape is not SPD or a value is not finite.
md_status_t em_ridge_ratio(const em_params_t *p, size_t a, size_t b, double *ratio);

/// True in *oversplit if some pair of clusters of p has a ridgeline ratio
/// ≥ min_ratio (that pair is one mode). min_ratio in (0, 1]. Errors as
/// em_ridge_ratio; *oversplit is false on error.
md_status_t em_params_oversplit(const em_params_t *p, double min_ratio, bool *oversplit);

#endif

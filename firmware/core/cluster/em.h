/// @file em.h
/// MAP-EM for the mixture of thesis §3.3 (outlier component + G shared-volume
/// Gaussians) under the mean prior of eq. 3.8-3.10.
///
/// E-step: z_ig (the expectation after eq. 3.13) and ζ_gj (eq. 3.14).
/// M-step (§3.3.3.2): π_g = n_g / N; MAP means by eq. 3.15 using the Σ_g of
/// the previous iteration (Remark 3.6); shared-volume covariance
/// Σ_g = λ W_g / |W_g|^{1/d}, λ = Σ_g |W_g|^{1/d} / Σ_{g≥1} n_g.
/// (The thesis writes N in the λ denominator; with an outlier component the
/// stationary point of the likelihood has the Gaussian components' total soft
/// count there, which is what makes the Laplace expansion of em_evidence.h
/// sit at a true maximum.)
///
/// The ML baseline of §3.5 is the same iteration with an empty prior
/// (em_prior_init with no targets): the uniform 1/V prior leaves eq. 3.15
/// equal to the weighted average of the points.
///
/// All likelihoods are evaluated in the log domain (log-sum-exp), so no
/// responsibility underflows to 0/0. Iterations are bounded by
/// em_options_t.max_iter ≤ MD_EM_MAX_ITER.
#ifndef EM_H
#define EM_H

#include "cluster/em_model.h"

/// Iteration controls.
typedef struct {
    uint32_t max_iter;  ///< 1..MD_EM_MAX_ITER
    double tol;         ///< stop when |Δ log-posterior| ≤ tol · max(1, |log-posterior|)
    bool accelerate;    ///< SQUAREM extrapolation between EM steps (same fixed point, fewer iterations)
} em_options_t;

/// Defaults: max_iter = MD_EM_MAX_ITER, tol = MD_EM_TOL_REL (md_config.h),
/// accelerate = true.
void em_options_default(em_options_t *opt);

/// Result of one fit of one model class.
typedef struct {
    md_status_t status;                    ///< MD_OK, MD_E_NOCONVERGE (usable), or a failure
    em_reason_t reason;                    ///< EM_OK or why it failed
    em_params_t params;                    ///< Θ̂ (valid when status is MD_OK or MD_E_NOCONVERGE)
    double n_soft[EM_G_MAX + 1u];          ///< n_g = Σ_i z_ig, g = 0..G
    double zeta[EM_G_MAX][EM_J_MAX + 1u];  ///< ζ_gj, j = 0 (uniform) .. J (eq. 3.14)
    double log_lik;                        ///< log p(Y | Θ̂) (eq. 3.5)
    double log_post;      ///< log_lik + Σ_g log p(μ̂_g) (eq. 3.4 without the constant C of eq. 3.10)
    uint32_t iterations;  ///< M-steps taken
} em_fit_t;

/// Fits one model class with G = g clusters, seeded by a hard partition.
///
/// seed_labels: one label per point in 0..g-1 (em_seed.h / em_hac.h make
/// them); every label must occur. The seed gives the initial means (group
/// centroids), one pooled shape for all clusters and π_0 = 0.05.
/// z: caller workspace of n·(g+1) doubles; on return it holds the final
/// responsibilities z_ig (row i, column g, g = 0 is the outlier component).
/// outlier, prior: from em_outlier_init / em_prior_init for the same d and V.
///
/// Returns the status also stored in out->status. Failures (with out->reason):
/// MD_E_ARG, MD_E_DEGENERATE (too few points, empty or collinear cluster),
/// MD_E_NUMERIC, MD_E_NOCONVERGE (parameters still usable). Never NaN.
/// O(max_iter · n · g · d^2).
md_status_t em_fit(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                   const uint8_t *seed_labels, size_t g, const em_options_t *opt, double *z, em_fit_t *out);

/// The same iteration as em_fit, started from a given Θ instead of a hard
/// partition: a converged fit of the same model class under a similar prior
/// (MHTC's warm start, docs/mhtc.md) reaches this prior's MAP optimum in a
/// few steps. The start must have start->d == data->d, 1 ≤ start->g ≤
/// EM_G_MAX, finite means and shapes, 0 < π_g ≤ 1, 0 ≤ π_0 ≤ 1, λ > 0
/// (else MD_E_ARG); a shape that is not SPD fails as MD_E_NUMERIC. z and the
/// other arguments as for em_fit (z holds n·(start->g + 1) doubles).
md_status_t em_fit_from(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                        const em_params_t *start, const em_options_t *opt, double *z, em_fit_t *out);

/// Hard labels from responsibilities: label[i] = argmax_g z_ig (0 = outlier).
void em_labels(const double *z, size_t n, size_t g, uint8_t *label);

#endif

/// @file cluster.h
/// Clustering of one recording interval over every model class G = 1..G_max
/// (thesis Fig. 3.1): seeds, EM, model evidence and the model posterior of
/// eq. 3.17 — the entry point the tracker (MHTC) and the controller call.
///
/// Two methods behind one interface:
/// - CLUSTER_MAP (§3.3): mean prior from the caller's predicted targets,
///   seeds of §3.3.4 from the same targets, Laplace evidence (eq. 3.18).
/// - CLUSTER_ML (§3.5 baseline): no mean prior (uniform 1/V, so plain ML
///   means), seeds from Ward's agglomerative clustering, BIC. Same outlier
///   and covariance model.
/// Either evidence can be chosen for either method.
///
/// Every model class is returned with its fit, log evidence (MHTC's P4),
/// log model prior (P3) and posterior probability, so the tracker can keep
/// several model hypotheses; best_g is the convenience choice.
/// A model whose EM hit the iteration bound (MD_E_NOCONVERGE) still takes
/// part: EM is monotone, so its last iterate is the best point found.
#ifndef CLUSTER_H
#define CLUSTER_H

#include "cluster/em.h"
#include "cluster/em_evidence.h"
#include "cluster/em_hac.h"
#include "cluster/em_seed.h"

#define CLUSTER_ALPHA_FORGET 0.95  ///< α of the model-prior forgetting factor (§3.3.5)

typedef enum {
    CLUSTER_MAP = 0,  ///< MAP-EM of §3.3
    CLUSTER_ML = 1    ///< ML baseline of §3.5
} cluster_method_t;

typedef enum {
    CLUSTER_EVIDENCE_LAPLACE = 0,  ///< eq. 3.18 with the App. B Hessian
    CLUSTER_EVIDENCE_BIC = 1       ///< footnote 11 (BIC/2 as log evidence)
} cluster_evidence_t;

/// Configuration; fill with cluster_config_default() and adjust.
typedef struct {
    cluster_method_t method;
    cluster_evidence_t evidence;
    size_t g_max;              ///< model classes G = 1..g_max, 1 ≤ g_max ≤ EM_G_MAX
    em_options_t em;           ///< iteration bound and tolerance
    double lambda_new;         ///< λν (Table 4.1: 0.01)
    double lambda_false;       ///< λφ (Table 4.1: 0.015)
    double shape_prior_width;  ///< w_c of the shape prior (em_evidence.h)
    double unimodal_ratio;     ///< a class with two clusters forming one mode (ridgeline ratio ≥ this,
                               ///< em_modes.h) is not usable; 0 (the default) keeps every fit
} cluster_config_t;

/// The data of one interval and what the tracker knows before it.
typedef struct {
    em_data_t data;              ///< n × d features (n ≤ EM_N_MAX, d ≤ EM_D_MAX)
    const double *noise_cov;     ///< Ξ, d × d, SPD: noise snippets in feature space
    const em_target_t *targets;  ///< predicted targets (MAP prior and seeds); NULL if none
    size_t n_targets;            ///< 0..EM_J_MAX; ignored by CLUSTER_ML
    const double *model_prior;   ///< P(M_m | Y^{1:k-1}) for G = 1..g_max, or NULL = uniform
} cluster_input_t;

/// One model class.
typedef struct {
    em_fit_t fit;              ///< parameters, ζ, log-likelihood, status and reason
    double log_evidence;       ///< log p(Y^k | Y^{1:k-1}, M_m) (valid when usable)
    double log_model_prior;    ///< log P(M_m | Y^{1:k-1})
    double post_prob;          ///< P(M_m | Y^{1:k}) of eq. 3.17; 0 when not usable
    bool usable;               ///< fit and evidence succeeded
    uint8_t labels[EM_N_MAX];  ///< argmax_g z_ig per point (0 = outlier)
} cluster_model_t;

typedef struct {
    size_t g_max;
    cluster_model_t model[EM_G_MAX];  ///< model[g-1] holds G = g
    size_t best_g;                    ///< argmax posterior, 0 when none is usable
} cluster_result_t;

/// Caller-owned scratch (size: see docs/clustering.md; no heap).
typedef struct {
    double z[EM_N_MAX * (EM_G_MAX + 1u)];
    uint8_t seed[EM_N_MAX];
    em_seed_work_t seed_ws;
    em_hac_work_t hac;
    em_evidence_work_t ev;
    em_outlier_t outlier;
    em_prior_t prior;
} cluster_workspace_t;

/// Thesis defaults: MAP → Laplace, ML → BIC; g_max = EM_G_MAX; Table 4.1 λν, λφ.
void cluster_config_default(cluster_config_t *cfg, cluster_method_t method);

/// Fits every model class G = 1..cfg->g_max and evaluates eq. 3.17.
/// Returns MD_OK when at least one model is usable; otherwise the status of
/// the G = 1 failure (MD_E_DEGENERATE, MD_E_NUMERIC, MD_E_ARG) with every
/// model's reason filled in. Never leaves NaN in the result.
/// O(g_max · (EM cost + n η^2)); Ward seeding adds O(n^2 d) for CLUSTER_ML.
md_status_t cluster_fit_models(const cluster_config_t *cfg, const cluster_input_t *in, cluster_workspace_t *ws,
                               cluster_result_t *out);

/// Model prior with forgetting (§3.3.5): prior_m = α prev_m + (1 - α)/m_count.
/// prev: the previous posterior (sums to 1). MD_E_ARG on bad input.
md_status_t cluster_model_prior_forget(const double *prev, size_t m_count, double alpha, double *prior);

#endif

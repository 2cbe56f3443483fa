/// @file em_model.h
/// The mixture model of thesis §3.3.1 and the prior on cluster means of §3.3.2:
/// types shared by the EM fit, the seeding, the evidence and the model
/// selection, plus the densities they all evaluate.
///
/// Model (Remark 3.2): component g = 0 is the outlier density
///   f0(y) = ½ (N(y | 0, K·Ξ) + 1/V),
/// Ξ the covariance of the interval's noise snippets in feature space, K = 4,
/// V the volume of the bounding box of the interval's points; components
/// g = 1..G are Gaussians with shared-volume covariance Σ_g = λ C_g, det C_g = 1.
/// The prior on each mean (eq. 3.8-3.10) mixes one Gaussian per predicted
/// target with a uniform component over V.
///
/// All storage is fixed-size (no heap); every array is bounded by the
/// capacities below. Points are row-major `n × d` doubles owned by the caller.
#ifndef EM_MODEL_H
#define EM_MODEL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "md_status.h"
#include "md_config.h"

#define EM_D_MAX MD_FEAT_DIM_MAX                            ///< feature dimension d, 1..3
#define EM_G_MAX MD_G_MAX                                   ///< Gaussian clusters per model
#define EM_N_MAX MD_MAX_SPIKES                              ///< points per interval
#define EM_J_MAX MD_MAX_TARGETS                             ///< predicted targets in the mean prior
#define EM_NC_MAX ((EM_D_MAX * (EM_D_MAX + 1u)) / 2u - 1u)  ///< free elements of C_g (det C_g = 1)
/// Independent parameters of the largest model: {π_g, μ_g, c_g}_{g=1..G} and λ (eq. B.2).
#define EM_ETA_MAX (EM_G_MAX * (1u + EM_D_MAX + EM_NC_MAX) + 1u)

#define EM_OUTLIER_K 4.0       ///< K of the outlier Gaussian (Remark 3.2)
#define EM_LAMBDA_NEW 0.01     ///< λν, expected new neurons per interval (Table 4.1)
#define EM_LAMBDA_FALSE 0.015  ///< λφ, expected false clusters per interval (Table 4.1)

_Static_assert(EM_D_MAX >= 1u && EM_D_MAX <= 3u, "App. B algebra is implemented for d <= 3");
_Static_assert(EM_G_MAX <= 8u, "labels are stored as uint8_t and subsets as 8-bit masks");
_Static_assert(EM_J_MAX <= 8u, "seed subsets of the targets are enumerated as 8-bit masks");
_Static_assert(EM_N_MAX <= 65535u, "point indices are stored as uint16_t");

/// Why a fit (or one model class) failed. Every failed fit carries one.
typedef enum {
    EM_OK = 0,               ///< fitted and usable
    EM_FAIL_ARG,             ///< invalid argument (NULL, d or G out of range, bad input values)
    EM_FAIL_TOO_FEW_POINTS,  ///< N < G · EM_MIN_POINTS_PER_CLUSTER(d)
    EM_FAIL_ZERO_VOLUME,     ///< bounding-box volume V is 0 (identical or axis-collinear points)
    EM_FAIL_NOISE_COV,       ///< K·Ξ is not symmetric positive definite
    EM_FAIL_SEED,            ///< the seeding could not produce G non-empty groups
    EM_FAIL_EMPTY_CLUSTER,   ///< a cluster's soft count fell below EM_MIN_POINTS_PER_CLUSTER(d)
    EM_FAIL_SINGULAR_COV,    ///< a cluster's scatter matrix is (near) singular: collinear members
    EM_FAIL_NUMERIC,         ///< a non-finite value or a failed factorisation
    EM_FAIL_NOCONVERGE,      ///< iteration bound reached; parameters are the last (monotone) iterate
    EM_FAIL_HESSIAN,         ///< Hessian of the log-posterior not positive definite: no Laplace evidence
    EM_FAIL_NOT_RUN,         ///< model class not attempted (G above the configured G_max)
    EM_FAIL_ONE_MODE         ///< two clusters form one mode (em_modes.h): the class with fewer clusters reads it
} em_reason_t;

/// Rule for degenerate clusters: a cluster needs a soft count of at least
/// d + 2 points (d + 1 points span a d-simplex; one more makes the scatter
/// estimate non-trivially determined). Below it the model is rejected.
#define EM_MIN_POINTS_PER_CLUSTER(d) ((double)(d) + 2.0)

/// Rule for singular covariance: the scatter W_g is rejected when
/// det(W_g) < EM_SINGULAR_REL · (tr(W_g)/d)^d, i.e. its shape condition is
/// beyond ~1e8 (collinear points).
#define EM_SINGULAR_REL 1e-8

/// A predicted target j of the mean prior (eq. 3.8), in the current feature space.
typedef struct {
    double mean[EM_D_MAX];              ///< predicted mean μ̂_j^{k|k-1} (eq. 4.9)
    double s_cov[EM_D_MAX * EM_D_MAX];  ///< S_j = R_j + Q (eq. 4.13), SPD, row-major d×d in the first d·d entries
    double cluster_cov[EM_D_MAX * EM_D_MAX];  ///< Σ_j^{k-1} (same layout), for seeding (eq. 3.16)
    double p_detect;                          ///< P_d,j in (0, 1]
} em_target_t;

/// The points of one interval (borrowed, row-major n × d).
typedef struct {
    const double *y;
    size_t n;
    size_t d;
} em_data_t;

/// Outlier component g = 0 (Remark 3.2), precomputed by em_outlier_init().
typedef struct {
    size_t d;
    double log_volume;                 ///< log V of the bounding box
    double chol[EM_D_MAX * EM_D_MAX];  ///< Cholesky factor of K·Ξ
    double log_norm;                   ///< -½ (d log 2π + log det K·Ξ)
    const double *tab_y;               ///< points tabulated by em_outlier_tabulate() (identity), or NULL
    size_t tab_n;                      ///< number of tabulated points
    double tab_log_f0[EM_N_MAX];       ///< log f0(y_i) of the tabulated points
} em_outlier_t;

/// Mean prior of eq. 3.8-3.9, precomputed by em_prior_init(). n_targets = 0
/// is the uniform prior 1/V, under which the MAP means equal the ML means.
typedef struct {
    size_t d;
    size_t n_targets;
    double log_w0_over_v;                          ///< log(ω_0 / V)
    double log_w_norm[EM_J_MAX];                   ///< log ω_j - ½(d log 2π + log det S_j)
    double mean[EM_J_MAX][EM_D_MAX];               ///< prior means μ̂_j
    double s_chol[EM_J_MAX][EM_D_MAX * EM_D_MAX];  ///< Cholesky of S_j
    double s_inv[EM_J_MAX][EM_D_MAX * EM_D_MAX];   ///< S_j^{-1}
} em_prior_t;

/// Parameters Θ of one model class (eq. 3.5): π_0 = 1 - Σ π_g.
typedef struct {
    size_t d;
    size_t g;
    double pi0;
    double pi[EM_G_MAX];
    double mean[EM_G_MAX][EM_D_MAX];
    double shape[EM_G_MAX][EM_D_MAX * EM_D_MAX];  ///< C_g, symmetric, det C_g = 1
    double lambda;                                ///< shared volume λ (Σ_g = λ C_g)
} em_params_t;

/// Volume of the bounding box of the points, V = Π_j (max y_j - min y_j).
/// Returns MD_E_DEGENERATE (V = 0 or non-finite) or MD_E_ARG. O(n d).
md_status_t em_bounding_volume(const em_data_t *data, double *volume);

/// Prepares f0 from Ξ (d×d, SPD) and V > 0. K = EM_OUTLIER_K.
/// MD_E_NUMERIC if K·Ξ is not SPD. O(d^3).
md_status_t em_outlier_init(size_t d, const double *noise_cov, double volume, em_outlier_t *out);

/// log f0(y) of Remark 3.2, evaluated in the log domain. NaN (never a density)
/// for a non-finite y or an outlier not prepared by em_outlier_init().
double em_outlier_logpdf(const em_outlier_t *outlier, const double *y);

/// Tabulates log f0(y_i) for every point of `data` (f0 does not change during
/// a fit: the EM and the evidence then read the table instead of evaluating it
/// per point and iteration). The table is used only for the same points array
/// (pointer and n); it stays valid until em_outlier_init() or the next call,
/// so the caller must re-tabulate if it changes the points in place.
/// MD_E_ARG on bad input, MD_E_NUMERIC for a non-finite point (the table is
/// then cleared). O(n d^2).
md_status_t em_outlier_tabulate(em_outlier_t *outlier, const em_data_t *data);

/// log f0(y_i) of point i of `data`: from the table when it was made for this
/// data, else evaluated. O(1) or O(d^2).
double em_outlier_logpdf_at(const em_outlier_t *outlier, const em_data_t *data, size_t i);

/// Prepares the mean prior (eq. 3.8, 3.9) from the targets (may be NULL when
/// n_targets = 0): ω_0 ∝ λ0 = λν + λφ, ω_j ∝ P_d,j. lambda0 > 0.
/// MD_E_ARG on bad P_d or count, MD_E_NUMERIC if some S_j is not SPD.
md_status_t em_prior_init(size_t d, const em_target_t *targets, size_t n_targets, double lambda0, double volume,
                          em_prior_t *out);

/// log p(μ) of eq. 3.8; when zeta is non-NULL it receives ζ_j, j = 0..J (eq. 3.14).
/// A target whose Mahalanobis distance to μ overflows contributes weight 0; a
/// non-finite μ gives -inf (and ζ = 0). NaN (and ζ = 0) only for a prior not
/// prepared by em_prior_init(). O(J d^2).
double em_prior_log_mean(const em_prior_t *prior, const double *mu, double *zeta);

/// log(e^a + e^b) without overflow.
double em_logaddexp(double a, double b);

/// Sorts key[0..n) ascending, permuting idx alongside (heapsort: no recursion,
/// O(n log n), in place).
void em_sort_keys(double *key, uint16_t *idx, size_t n);

/// Short constant name of a reason code, for logs and test messages.
const char *em_reason_name(em_reason_t reason);

#endif

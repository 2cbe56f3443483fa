/// @file em_evidence.h
/// Model evidence p(Y^k | Y^{1:k-1}, M_m) of one fitted model class (thesis §3.3.5).
///
/// Laplace's method (eq. 3.18, App. A.2, eq. A.8):
///   log J ≈ log p(Y|Θ̂) + log p(Θ̂) + (η/2) log 2π - ½ log det H(Θ̂),
/// with H the negative Hessian of the log-posterior (eq. B.1), computed
/// analytically as in App. B: per-point second derivatives of the mixture
/// log-likelihood (eq. B.12-B.18) plus the block-diagonal mean-prior term
/// (eq. B.21-B.23). The derivatives are written for any d ≤ 3 through the
/// derivatives of Σ_g = λ C_g with respect to each parameter, so the d = 2
/// case is exactly App. B's and d = 1, 3 follow from the same identities
/// (B.7-B.10).
///
/// Parameter vector Θ (eq. B.2), in this order:
///   for g = 1..G: π_g, μ_g (d values), the free elements of C_g; then λ.
/// Free elements of C_g: the upper triangle (row-major, i ≤ j) except
/// c_dd, which the constraint det C_g = 1 fixes (eq. B.3 for d = 2:
/// c_22 = (c_12^2 + 1)/c_11). η = G (1 + d + d(d+1)/2 - 1) + 1.
///
/// Parameter prior (eq. 3.10): the mean prior of em_model.h times the
/// constant C of the diffuse priors, which the thesis leaves open. Chosen here
/// so that C is proper and the evidence is comparable across G:
///   π (π_0..π_G) uniform on the simplex: density G!;
///   each free element of C_g uniform over a width w_c (default
///   EM_SHAPE_PRIOR_WIDTH; C_g is dimensionless);
///   λ: the same diffuse prior in every model class, so it is left out
///   (it cancels in eq. 3.17 and in the tracker's comparisons on one interval).
///
/// Boundary rule: when the data hold no outliers, EM drives π_0 to the
/// boundary π_0 = 0 where the log-posterior still rises outward, so the
/// Gaussian (Laplace) factor of that one direction is wrong and H is often
/// indefinite. When the outward slope s = ∂ log p/∂π_G (π_0 = 1 - Σπ_g, the
/// other π_g held) exceeds one posterior standard deviation, sqrt(-∂²/∂π_G²),
/// π_G is eliminated (π_G = 1 - π_0 - Σ_{g<G} π_g), the Laplace factor is taken
/// over the remaining η - 1 coordinates, and the π_0 direction contributes the
/// exact one-sided integral ∫_0^∞ e^{-s u} du = 1/s.
///
/// BIC (footnote 11) is the cheap alternative: log J ≈ l_M - (η/2) log N.
#ifndef EM_EVIDENCE_H
#define EM_EVIDENCE_H

#include "cluster/em_model.h"

#define EM_P_MAX (EM_NC_MAX + 1u)  ///< covariance parameters of one cluster: its C_g elements and λ
#define EM_SHAPE_PRIOR_WIDTH 10.0  ///< default w_c: C_g elements uniform over a width of 10

/// Per-cluster derivative tables (internal to em_evidence.c; exposed for sizing).
typedef struct {
    double chol[EM_D_MAX * EM_D_MAX];
    double sigma_inv[EM_D_MAX * EM_D_MAX];
    double logdet;
    double n_t[EM_P_MAX][EM_D_MAX * EM_D_MAX];             ///< Σ^{-1} Σ_t Σ^{-1}
    double tr_m[EM_P_MAX];                                 ///< tr(Σ^{-1} Σ_t)
    double k_ts[EM_P_MAX][EM_P_MAX];                       ///< constant part of ∂²log Φ/∂t∂s
    double q_ts[EM_P_MAX][EM_P_MAX][EM_D_MAX * EM_D_MAX];  ///< quadratic-form part of ∂²log Φ/∂t∂s
} em_comp_deriv_t;

/// Per-cluster constants of the d = 2 pass (internal to em_evidence_d2.c;
/// exposed for sizing): Σ⁻¹, log π_g - ½(2 log 2π + log det Σ), π_g, -½ tr(Σ⁻¹Σ_t),
/// ½ N_t and q_ts as (r0², r0 r1, r1²) coefficients, N_t, k_ts for the six pairs s ≥ t.
typedef struct {
    double si[4];
    double cst;
    double pi;
    double half_tr[3];
    double half_n[3][3];
    double n_t[3][4];
    double k_ts[6];
    double q_ts[6][3];
} em_d2_comp_t;

/// Caller-owned workspace of the Hessian (about 37 KB at d = 3, G = 4).
/// Between em_evidence_data and em_evidence_finish it holds the data part.
typedef struct {
    em_comp_deriv_t comp[EM_G_MAX];
    double hess[EM_ETA_MAX * EM_ETA_MAX];  ///< data part: Σ_i ∇∇ l_i (eq. B.17), full
    double scaled[EM_ETA_MAX * EM_ETA_MAX];
    double u[EM_ETA_MAX];
    double grad[EM_ETA_MAX];  ///< data part: Σ_i ∇ l_i
    double data_ll;           ///< data part: log p(Y|Θ̂) = Σ_i l_i
    size_t data_d;            ///< d and G the data part was made for (0: none)
    size_t data_g;
    double prior_h[EM_G_MAX][EM_D_MAX * EM_D_MAX];  ///< ∇∇ log p(μ_g) of the prior being finished
    em_d2_comp_t d2[EM_G_MAX];                      ///< d = 2 pass: per-cluster constants
    double d2_blk[EM_G_MAX][21];                    ///< d = 2 pass: per-cluster curvature sums (6 × 6 upper)
} em_evidence_work_t;

/// η, the number of independent parameters of a model with g clusters in d dimensions.
size_t em_param_count(size_t d, size_t g);

/// Θ → vector (layout above). theta holds em_param_count(d, g) doubles.
md_status_t em_theta_pack(const em_params_t *p, double *theta);

/// Vector → Θ; rebuilds c_dd from det C_g = 1 and π_0 = 1 - Σ π_g.
/// MD_E_NUMERIC if some C_g is not positive definite, λ ≤ 0, π_g ≤ 0 or π_0 < 0.
md_status_t em_theta_unpack(const double *theta, size_t d, size_t g, em_params_t *p);

/// log-posterior log p(Y|Θ) + Σ_g log p(μ_g) (eq. 3.4 without the constant C),
/// and optionally its gradient (η values) and Hessian (η × η, row-major) with
/// respect to Θ. grad or hess may be NULL. O(n (g d^2 P^2 + η^2)).
md_status_t em_log_post_derivs(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                               const em_params_t *p, double *log_post, double *grad, double *hess,
                               em_evidence_work_t *ws);

/// log C of eq. 3.10 under the priors stated above.
double em_param_prior_log_const(size_t d, size_t g, double shape_prior_width);

/// Laplace log evidence (eq. 3.18) at the fitted Θ̂. shape_prior_width > 0.
/// MD_E_NUMERIC if H is not positive definite (Θ̂ is not a local maximum);
/// the caller reports EM_FAIL_HESSIAN then.
md_status_t em_evidence_laplace(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                                const em_params_t *p, double shape_prior_width, em_evidence_work_t *ws,
                                double *log_evidence);

/// The data part of the Laplace evidence at Θ̂ = p: log p(Y|Θ̂) and its
/// gradient and Hessian (the per-point sums of eq. B.12-B.18), kept in ws
/// for em_evidence_finish. The mean prior enters eq. 3.18 only through
/// log p(μ̂) and the mean blocks of H (eq. B.21-B.23), so one data part
/// serves every prior evaluated at the same Θ̂ (MHTC re-evaluates one fit
/// under similar priors, thesis §4.6). MD_E_ARG on bad arguments,
/// MD_E_NUMERIC if some π_g ≤ 0, a C_g is not SPD or a sum is not finite
/// (ws then holds no data part). O(n g² d⁴).
md_status_t em_evidence_data(const em_data_t *data, const em_outlier_t *outlier, const em_params_t *p,
                             em_evidence_work_t *ws);

/// Laplace log evidence (eq. 3.18) from the data part in ws (made by
/// em_evidence_data for this p) under the mean prior `prior`; the data part
/// is left unchanged, so the call can be repeated for other priors. Same
/// results and statuses as em_evidence_laplace; MD_E_ARG if ws holds no data
/// part for p's d and G. O(g J d² + η³).
md_status_t em_evidence_finish(const em_prior_t *prior, const em_params_t *p, double shape_prior_width,
                               em_evidence_work_t *ws, double *log_evidence);

/// BIC/2 (footnote 11): log_lik - (η/2) log n.
double em_evidence_bic(double log_lik, size_t d, size_t g, size_t n);

#endif

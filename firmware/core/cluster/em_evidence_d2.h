/// @file em_evidence_d2.h
/// The per-point pass of the Laplace Hessian (thesis App. B, eq. B.17, B.18)
/// written out for d = 2, the controller's feature dimension. Internal to
/// em_evidence.c, which keeps the general-d loop for d = 1 and 3.
///
/// Same sums as the general loop: l_i, u_i = ∇ l_i and S_i - u_i u_iᵀ, but
/// each cluster's curvature S_i goes into a compact 6 × 6 block (its five
/// parameters π_g, μ_g, c_11, c_12 and the shared λ) that is scattered into
/// H once after the loop, the 2 × 2 quadratic forms use precomputed
/// symmetric coefficients, and u u^T runs over the upper triangle of a
/// contiguous vector. Results agree with the general loop to rounding.
#ifndef EM_EVIDENCE_D2_H
#define EM_EVIDENCE_D2_H

#include "cluster/em_evidence.h"

/// Σ_i l_i (the log-likelihood) at p; grad (η) and hess (η × η, upper
/// triangle only: the caller mirrors it) receive Σ_i u_i and Σ_i (S_i - u_i u_iᵀ).
/// Preconditions (checked by the caller): p->d == 2, 1 ≤ p->g ≤ EM_G_MAX,
/// every π_g > 0, ws->comp[g] prepared for p (em_comp_prepare), grad and hess
/// zeroed. log_pi[0..g]: log π_0 (floored) and log π_g.
/// ws->comp holds the prepared clusters; ws->d2 and ws->d2_blk are its scratch.
double em_d2_points(const em_data_t *data, const em_outlier_t *outlier, const em_params_t *p, const double *log_pi,
                    em_evidence_work_t *ws, double *grad, double *hess);

#endif

/// @file kalman.h
/// Kalman filter of one neuron target in full waveform space (thesis §4.2.1.2,
/// §4.4.2): state x = the neuron's mean waveform (d_w samples), F = I,
/// H^k = B^k (the interval's d × d_w PCA basis), Q = q·I.
///
/// Covariance representation (why): a dense d_w × d_w covariance per track is
/// 18 KB in double at d_w = 48, and a tracker keeps dozens of tracks per
/// electrode. With F = I and isotropic Q the covariance always has the form
///   Λ = a·I + Σ_i e_i v_i v_iᵀ      (v_i orthonormal, e_i real)
/// because prediction only raises a (eq. 4.8) and an update (eq. 4.17) only
/// changes Λ inside span{v_i, rows of H}. The filter keeps at most
/// KF_RANK_MAX directions; when an update would need more, the directions of
/// smallest |e_i| are dropped (their variance returns to a). Starting from
/// Λ = a·I the e_i are ≤ 0, so dropping one only raises a variance: the
/// approximation is conservative. Below the rank bound it is exact (the unit
/// test compares with a dense filter).
///
/// A positive direction (kf_predict_scaled) is the one exception to e_i ≤ 0:
/// it is kept while its |e_i| is among the KF_RANK_MAX largest.
///
/// Memory: kf_state_t is ~2.3 KB at d_w = 48; kf_work_t is caller scratch.
/// Time: predict O(1); measure O(r d d_w); update O((r+d)^2 d_w + (r+d)^3).
#ifndef KALMAN_H
#define KALMAN_H

#include <stddef.h>
#include <stdint.h>

#include "md_status.h"
#include "md_config.h"

#define KF_DW_MAX MD_WAVE_LEN_MAX  ///< waveform length d_w
#define KF_D_MAX MD_FEAT_DIM_MAX   ///< feature (measurement) dimension d
#define KF_RANK_MAX 8u             ///< low-rank directions kept per track
#define KF_SPAN_MAX (KF_RANK_MAX + KF_D_MAX)
#define KF_JACOBI_SWEEPS 40u

_Static_assert(KF_RANK_MAX >= KF_D_MAX, "one measurement's directions must fit");
_Static_assert(KF_SPAN_MAX <= 64u, "span fits linalg's order bound");
_Static_assert(KF_RANK_MAX <= 255u, "rank stored in uint8_t");

/// State estimate x̂ and covariance Λ of one target (eq. 4.7-4.8, 4.16-4.17).
typedef struct {
    uint16_t d_w;                     ///< waveform length
    uint8_t rank;                     ///< directions in use (≤ KF_RANK_MAX)
    double a;                         ///< isotropic variance part of Λ
    double x[KF_DW_MAX];              ///< x̂, mean waveform
    double e[KF_RANK_MAX];            ///< eigen-offsets e_i (Λ = aI + Σ e_i v_i v_iᵀ)
    float v[KF_RANK_MAX][KF_DW_MAX];  ///< orthonormal directions v_i
} kf_state_t;

/// Scratch of kf_update (caller-owned, ~7 KB).
typedef struct {
    double w[KF_SPAN_MAX][KF_DW_MAX];       ///< orthonormal basis of span{v_i, rows of H}
    double p[KF_DW_MAX * KF_D_MAX];         ///< Λ Hᵀ, d_w × d
    double m[KF_SPAN_MAX * KF_SPAN_MAX];    ///< Λ' - aI in the basis w
    double vec[KF_SPAN_MAX * KF_SPAN_MAX];  ///< its eigenvectors
    double val[KF_SPAN_MAX];
    double s[KF_D_MAX * KF_D_MAX];
    double sl[KF_D_MAX * KF_D_MAX];
} kf_work_t;

/// Starts a target at x0 with Λ = a0·I + Hᵀ(R - a0·I_d)H, i.e. the measured
/// directions (rows of h, d × d_w, orthonormal) carry R (d × d, SPD) and every
/// other direction a0 > 0. r may be NULL (then Λ = a0·I).
/// MD_E_ARG on bad sizes/values, MD_E_NUMERIC on non-finite input.
md_status_t kf_init(kf_state_t *st, size_t d_w, const double *x0, double a0, const double *h, size_t d, const double *r,
                    kf_work_t *ws);

/// eq. 4.7-4.8 with F = I, Q = q·I (q ≥ 0): x̂ unchanged, a += q.
md_status_t kf_predict(kf_state_t *st, double q);

/// eq. 4.7-4.8 with an uncertain gain of the whole waveform on top:
/// Q = q·I + s2·x̂ x̂ᵀ. s2 ≥ 0 is the variance of the relative amplitude change
/// (the electrode moved: every sample of a neuron's waveform scales by the
/// same factor, so the uncertainty lies along x̂ itself, not in every
/// direction). s2 = 0 or x̂ = 0 is kf_predict. The new direction joins the
/// low-rank part; past KF_RANK_MAX the smallest |e_i| are dropped (as in
/// kf_update). MD_E_ARG on bad q/s2, MD_E_NUMERIC if the eigen-decomposition
/// fails (st unchanged then). O((r+1)^2 d_w + (r+1)^3).
md_status_t kf_predict_scaled(kf_state_t *st, double q, double s2, kf_work_t *ws);

/// Predicted measurement μ̂ = H x̂ (eq. 4.9) and H Λ Hᵀ (the first term of
/// S, eq. 4.13) for h (d × d_w). mu: d values, hlh: d × d. O(r d d_w).
md_status_t kf_measure(const kf_state_t *st, const double *h, size_t d, double *mu, double *hlh);

/// Measurement update with μ (d values) and R (d × d SPD): eq. 4.15-4.17.
/// MD_E_NUMERIC if S is not SPD or a result is not finite (st unchanged then).
md_status_t kf_update(kf_state_t *st, const double *h, size_t d, const double *mu, const double *r, kf_work_t *ws);

/// Dense Λ (d_w × d_w, row-major) for tests and diagnostics. O(r d_w^2).
void kf_covariance(const kf_state_t *st, double *lambda);

#endif

/// @file quality.h
/// Signal and isolation quality metrics of one interval (thesis §2.2.2.4)
/// and the noise covariance the clustering's outlier component needs.
///
/// - SNR of a cluster: mean peak-to-peak amplitude of its waveforms divided
///   by the RMS of the interval's spike-free noise snippets.
/// - Isolation distance of a cluster g (Schmitzer-Torbert et al. 2005, as
///   used in the thesis): the squared Mahalanobis distance, under Σ_g, from
///   μ_g to the n_g-th closest point that is not in g, where n_g is the size
///   of g and the noise snippets projected into the same feature space count
///   as non-members. The thesis' ID_g is its square root; both are reported.
///
/// Waveform arrays: row i starts at wave[i*stride], d_w values. Feature
/// arrays: packed n × d (the clustering's point layout). Labels: one uint8_t
/// per spike, the clustering's hard labels (0 = outlier).
#ifndef QUALITY_H
#define QUALITY_H

#include <stddef.h>
#include <stdint.h>

#include "md_status.h"
#include "features/pca.h"
#include "md_config.h"

/// Isolation distance of one cluster.
typedef struct {
    int defined;          ///< 0 if there are fewer non-members than members (then id2 = id = 0)
    double id2;           ///< squared Mahalanobis distance to the n_g-th closest non-member
    double id;            ///< sqrt(id2), the thesis' ID_g
    size_t n_members;     ///< n_g
    size_t n_nonmembers;  ///< other spikes plus noise snippets
} qm_isolation_t;

/// RMS over every sample of m noise snippets. MD_E_DEGENERATE if m == 0 or
/// the RMS is zero. O(m d_w).
md_status_t qm_noise_rms(const double *noise, size_t m, size_t stride, size_t d_w, double *rms);

/// SNR of the waveforms whose label equals `label` (all waveforms if labels
/// is NULL): mean over them of (max - min) / noise_rms. *n_members receives
/// their count (may be NULL). MD_E_DEGENERATE if there are none;
/// MD_E_ARG if noise_rms <= 0. O(n d_w).
md_status_t qm_snr(const double *wave, size_t n, size_t stride, size_t d_w, const uint8_t *labels, uint8_t label,
                   double noise_rms, double *snr, size_t *n_members);

/// Isolation distance of cluster `label` among n points y (packed n × d)
/// plus m noise points noise_y (packed m × d, may be NULL if m == 0).
/// centre/cov: μ_g and Σ_g (d and d×d values) from the clustering; if either
/// is NULL both are estimated from the members (mean, 1/(n_g-1) covariance).
/// work: at least (n + m) * d doubles. MD_E_DEGENERATE if the cluster has fewer than
/// 2 members (or d+1 when Σ_g is estimated); MD_E_NUMERIC if Σ_g is not PD or
/// a point is not finite.
/// O((n + m) d^2) plus an O(n + m) expected selection.
md_status_t qm_isolation_distance(const double *y, size_t n, size_t d, const uint8_t *labels, uint8_t label,
                                  const double *noise_y, size_t m, const double *centre, const double *cov,
                                  double *work, size_t work_len, qm_isolation_t *out);

/// Sample covariance (1/(m-1)) of m points, packed m × d, into cov (d×d);
/// mean (d values) optional. MD_E_DEGENERATE if m < 2. O(m d^2).
md_status_t qm_feature_cov(const double *y, size_t m, size_t d, double *mean, double *cov);

/// Ξ: covariance of the noise snippets projected with `basis` (thesis
/// Remark 3.2 outlier component), d×d in xi. Checked positive definite:
/// MD_E_DEGENERATE if m < d + 1, MD_E_NUMERIC if Ξ is singular. Two passes,
/// no storage beyond xi: O(m d d_w).
md_status_t qm_noise_feature_cov(const pca_basis_t *basis, const double *noise, size_t m, size_t stride, double *xi);

/* Compact inputs (spike_extract.h: int16 counts, physical value = gain *
 * count): same results as the double entry points on the converted rows. */

/// qm_noise_rms on compact snippets (exact integer sum of squares). gain > 0.
md_status_t qm_noise_rms_i16(const int16_t *noise, size_t m, size_t stride, size_t d_w, double gain, double *rms);

/// qm_snr on compact windows. gain > 0.
md_status_t qm_snr_i16(const int16_t *wave, size_t n, size_t stride, size_t d_w, double gain, const uint8_t *labels,
                       uint8_t label, double noise_rms, double *snr, size_t *n_members);

/// qm_noise_feature_cov on compact snippets. gain > 0.
md_status_t qm_noise_feature_cov_i16(const pca_basis_t *basis, const int16_t *noise, size_t m, size_t stride,
                                     double gain, double *xi);

#endif

/// @file pca.h
/// Per-interval PCA feature space (thesis §2.2.2.2).
///
/// The basis is the d leading eigenvectors of the sample covariance (thesis
/// footnote 5, 1/(N-1) normalisation) of the interval's waveforms; features
/// are y = B x with B the d × d_w matrix whose rows are those eigenvectors
/// (the thesis' y_i = W^T x_i, W = B^T, without subtracting the mean). The
/// tracker uses the same B as its measurement matrix H^k (thesis §4.4.2), so
/// B is part of the output.
///
/// Sign convention: each eigenvector is flipped so that its component of
/// largest magnitude is positive (lowest index among components within 1e-9
/// relative of the largest). Eigenvectors are only
/// defined up to sign; the convention makes bases of consecutive intervals
/// with similar waveforms comparable.
#ifndef PCA_H
#define PCA_H

#include <float.h>
#include <stddef.h>
#include <stdint.h>

#include "numeric/eigen_top.h"
#include "md_status.h"
#include "md_config.h"

/// Waveforms whose RMS spread sqrt(total_var / d_w) is at most this fraction
/// of their largest magnitude are equal within rounding: the mean is a
/// rounded sum / n, so identical windows leave deviations of up to
/// ~n·DBL_EPSILON·max|x| (< 1e-11·max|x| for every n accepted), and a basis
/// fitted to them is noise. Real windows (int16 counts, >= 1 count apart out
/// of <= 32768) are >= 3e-5 relative apart.
#define PCA_DEGENERATE_REL 1e-10
/// Smallest total variance fitted: below DBL_MIN / DBL_EPSILON (~2e-292) the
/// squared deviations fall into the subnormal range, lose relative precision,
/// and an eigenvalue can exceed the trace (docs/fuzzing.md finding 5). No
/// physical recording comes near it (int16 counts × a µV gain).
#define PCA_VAR_MIN (DBL_MIN / DBL_EPSILON)

/// A PCA basis of one interval.
typedef struct {
    size_t d;                                     ///< feature dimension, 1..MD_FEAT_DIM_MAX
    size_t d_w;                                   ///< waveform length
    double b[MD_FEAT_DIM_MAX * MD_WAVE_LEN_MAX];  ///< B, row-major d × d_w in the first d*d_w entries
    double eigval[MD_FEAT_DIM_MAX];               ///< variance along each row of B, descending
    double total_var;                             ///< trace of the covariance (all d_w eigenvalues)
    double mean[MD_WAVE_LEN_MAX];                 ///< sample mean waveform (informational)
} pca_basis_t;

/// Scratch storage of pca_fit (caller-owned, ~22 kB at d_w = 48).
typedef struct {
    double cov[MD_WAVE_LEN_MAX * MD_WAVE_LEN_MAX];
    double vecs[MD_FEAT_DIM_MAX * MD_WAVE_LEN_MAX];  ///< leading eigenvectors, one per row
    double vals[MD_FEAT_DIM_MAX];
    eigen_top_work_t eig;
} pca_work_t;

/// Fits the basis to n waveforms: waveform i is wave[i*stride .. i*stride+d_w).
/// Preconditions: n >= 2, d_w in [d, MD_WAVE_LEN_MAX], stride >= d_w,
/// 1 <= d <= MD_FEAT_DIM_MAX. MD_E_DEGENERATE if all waveforms are equal
/// within rounding (sqrt(total_var / d_w) <= PCA_DEGENERATE_REL · max|x|,
/// zero variance included) or if total_var < PCA_VAR_MIN, MD_E_NUMERIC on non-finite input or when the
/// mean, a covariance entry, the trace or an eigenpair is not finite
/// (magnitudes near sqrt(DBL_MAX) overflow), MD_E_NOCONVERGE from the
/// eigen-solver (eigen_top.h: only the d leading pairs are computed).
/// Nothing non-finite is reported with MD_OK. O(n d_w^2 + d_w^3).
md_status_t pca_fit(const double *wave, size_t n, size_t stride, size_t d_w, size_t d, pca_work_t *work,
                    pca_basis_t *basis);

/// Features of one waveform: y (d values) = B x (d_w values). O(d d_w).
md_status_t pca_project(const pca_basis_t *basis, const double *x, double *y);

/// Features of n waveforms (layout as in pca_fit) into y, packed n × d
/// (the clustering's point layout). O(n d d_w).
md_status_t pca_project_all(const pca_basis_t *basis, const double *wave, size_t n, size_t stride, double *y);

/// pca_fit on compact windows (spike_extract.h sx_windows_t: int16 counts,
/// physical value = gain * count), without a double copy of the interval.
/// Same preconditions and result as pca_fit on the converted rows; gain > 0.
md_status_t pca_fit_i16(const int16_t *wave, size_t n, size_t stride, size_t d_w, double gain, size_t d,
                        pca_work_t *work, pca_basis_t *basis);

/// Features of one compact window: y = B (gain * x). O(d d_w).
md_status_t pca_project_i16(const pca_basis_t *basis, const int16_t *x, double gain, double *y);

/// Features of n compact windows into y, packed n × d. O(n d d_w).
md_status_t pca_project_all_i16(const pca_basis_t *basis, const int16_t *wave, size_t n, size_t stride, double gain,
                                double *y);

#endif

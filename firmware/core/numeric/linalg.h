/// @file linalg.h
/// Small dense linear algebra on caller-owned, row-major double arrays.
///
/// Shared by PCA, metrics, clustering and tracking. No allocation: every
/// routine works in place or in buffers the caller passes. Sizes are bounded
/// by LINALG_MAX_N so every loop is bounded. Every fallible routine returns an
/// md_status_t: MD_E_ARG for a NULL pointer or an order outside
/// 1..LINALG_MAX_N, MD_E_NUMERIC for a matrix that is not positive definite or
/// a non-finite input or result. A bad argument never yields a plausible value.
#ifndef LINALG_H
#define LINALG_H

#include <stddef.h>

#include "md_status.h"

#define LINALG_MAX_N 64u  ///< largest matrix order any caller uses (Laplace Hessian, waveform space)

/// In-place Cholesky factorisation A = L L^T of a symmetric positive definite
/// n×n matrix; on success the lower triangle holds L and the strict upper
/// triangle is zeroed. MD_E_NUMERIC if A is not (numerically) positive definite.
/// O(n^3/6).
md_status_t linalg_cholesky(double *a, size_t n);

/// log det(A) from its Cholesky factor L (2 Σ log L_ii). NaN for a NULL `l`
/// or an order outside 1..LINALG_MAX_N.
double linalg_cholesky_logdet(const double *l, size_t n);

/// Solves A x = b in place (b becomes x) given the Cholesky factor L of A
/// (from linalg_cholesky). MD_E_ARG (b untouched) on a bad argument,
/// MD_E_NUMERIC if the solution is not finite. O(n^2).
md_status_t linalg_cholesky_solve(const double *l, size_t n, double *b);

/// Inverse of a symmetric positive definite matrix. `work` holds n*n doubles.
/// Also returns log det(A) through `logdet` when non-NULL.
md_status_t linalg_spd_inverse(const double *a, size_t n, double *inv, double *work, double *logdet);

/// Squared Mahalanobis distance (x-m)^T S^{-1} (x-m) into *d2, given the
/// Cholesky factor L of S (from linalg_cholesky). `work` holds n doubles.
/// A distance beyond the double range is +inf (MD_OK: x is farther from m than
/// any finite distance). MD_E_ARG on a NULL pointer or an order outside
/// 1..LINALG_MAX_N; MD_E_NUMERIC if x, m or the lower triangle of L is not
/// finite or L has a zero diagonal entry. On failure *d2 (if d2 is non-NULL)
/// is NaN, never a distance. O(n^2).
md_status_t linalg_mahalanobis2(const double *l, size_t n, const double *x, const double *m, double *work, double *d2);

/// Eigen-decomposition of a symmetric n×n matrix by cyclic Jacobi rotations.
/// `a` is destroyed. Eigenvalues are returned in descending order; column k of
/// the row-major n×n `eigvecs` is the unit eigenvector of eigvals[k].
/// MD_E_NOCONVERGE if off-diagonal mass is not negligible after max_sweeps.
md_status_t linalg_sym_eigen(double *a, size_t n, double *eigvals, double *eigvecs, unsigned max_sweeps);

/// C = A B for row-major A (r×k) and B (k×c); the loops are bounded by the
/// caller's sizes. MD_E_ARG, and nothing written, if a pointer is NULL.
md_status_t linalg_matmul(const double *a, const double *b, double *c, size_t r, size_t k, size_t cols);

/// True if every one of the n values is finite.
int linalg_all_finite(const double *v, size_t n);

#endif

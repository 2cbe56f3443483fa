/// @file eigen_top.h
/// The k largest eigenpairs of a symmetric matrix, for PCA (thesis §2.2.2.2
/// keeps d = 2 of d_w ≈ 35 directions).
///
/// Cyclic Jacobi (linalg_sym_eigen) finds all d_w pairs at ~10 sweeps of
/// d_w³ rotations each; PCA needs only the leading d. This unit does what
/// LAPACK's dsyevx does for a subset of the spectrum:
///   1. Householder reduction A = Q T Qᵀ, T tridiagonal ((4/3) n³ flops);
///   2. each wanted eigenvalue of T by bisection on Sturm counts (exact
///      count of eigenvalues below a shift; O(n) per step, ≤ 64 + 16 steps);
///   3. its eigenvector by inverse iteration on T - λI (tridiagonal LU with
///      partial pivoting, O(n) per iteration), orthogonalised against the
///      pairs already found so that close eigenvalues get orthogonal vectors;
///   4. back-transformation with the stored reflectors (O(n²) per vector).
/// Eigenvalues are accurate to a few ulps of ‖A‖; eigenvectors of
/// eigenvalues closer than that are an orthonormal basis of their invariant
/// subspace, as any solver's would be.
///
/// Input magnitudes: the caller scales A near 1 (PCA divides by a power of
/// two), so squares neither overflow nor lose precision; entries below
/// ~1e-150 relative to the largest are treated as zero (they are far below
/// the rounding of the result).
#ifndef EIGEN_TOP_H
#define EIGEN_TOP_H

#include <stddef.h>

#include "numeric/linalg.h"
#include "md_status.h"

#define EIGEN_TOP_K_MAX 4u  ///< most eigenpairs one call returns

/// Scratch storage (caller-owned): the reflectors and the tridiagonal system.
typedef struct {
    double beta[LINALG_MAX_N];                ///< reflector scale β_j of step j
    double diag[LINALG_MAX_N];                ///< T's diagonal
    double off[LINALG_MAX_N];                 ///< T's sub-diagonal off[j] = T[j+1][j]
    double off2[LINALG_MAX_N];                ///< off[j]²
    double lu[4][LINALG_MAX_N];               ///< LU of T - λI: diagonal, super, second super, multipliers
    unsigned char piv[LINALG_MAX_N];          ///< rows swapped at step j of the LU
    double z[EIGEN_TOP_K_MAX][LINALG_MAX_N];  ///< eigenvectors of T
} eigen_top_work_t;

/// The k largest eigenvalues of the symmetric n × n row-major matrix `a`
/// (destroyed: it holds the reflectors on return), in descending order, and
/// their unit eigenvectors: vecs[i * n + j] is component j of vector i (row i).
/// Only the lower triangle of `a` is read. 1 ≤ k ≤ min(n, EIGEN_TOP_K_MAX),
/// n ≤ LINALG_MAX_N. MD_E_ARG on bad arguments, MD_E_NUMERIC on non-finite
/// input or result. O(n³) for the reduction, O(k n²) for the rest.
md_status_t linalg_sym_eigen_top(double *a, size_t n, size_t k, double *vals, double *vecs, eigen_top_work_t *ws);

#endif

/// @file linalg.c
/// Dense linear algebra for small SPD / symmetric matrices (see linalg.h).
///
/// Every loop is bounded by n <= LINALG_MAX_N or by the caller's sweep bound
/// (linalg_matmul: by the caller's sizes). Routines that return md_status_t
/// report misuse; linalg_cholesky_logdet returns NaN for it.
#include "numeric/linalg.h"

#include <math.h>
#include <string.h>

/* A Cholesky pivot is rejected when it falls below this fraction of the
 * largest diagonal entry: below it the factor loses all significant digits
 * (condition number beyond ~1e13) and downstream inverses would be noise. */
#define LINALG_PIVOT_REL_TOL 1e-13

/* Jacobi stops when the off-diagonal Frobenius norm is this small relative to
 * the matrix norm: eigenvalues are then exact to ~1e-12 relative, while the
 * rounding floor of the rotations (~n ulps at n = 64) stays well below it. */
#define LINALG_JACOBI_REL_TOL 1e-12
#define LINALG_JACOBI_SWEEPS_CAP 100u

static int linalg_size_ok(size_t n)
{
    return (n >= 1u) && (n <= LINALG_MAX_N);
}

int linalg_all_finite(const double *v, size_t n)
{
    if (v == NULL) {
        return 0;
    }
    for (size_t i = 0u; i < n; ++i) {
        if (!isfinite(v[i])) {
            return 0;
        }
    }
    return 1;
}

md_status_t linalg_cholesky(double *a, size_t n)
{
    if ((a == NULL) || !linalg_size_ok(n)) {
        return MD_E_ARG;
    }
    if (!linalg_all_finite(a, n * n)) {
        return MD_E_NUMERIC;
    }
    double scale = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        scale = fmax(scale, fabs(a[i * n + i]));
    }
    if (!(scale > 0.0)) {
        return MD_E_NUMERIC;
    }
    const double min_pivot = LINALG_PIVOT_REL_TOL * scale;
    for (size_t j = 0u; j < n; ++j) {
        double d = a[j * n + j];
        for (size_t k = 0u; k < j; ++k) {
            d -= a[j * n + k] * a[j * n + k];
        }
        if (!(d > min_pivot)) {
            return MD_E_NUMERIC;
        }
        const double ljj = sqrt(d);
        a[j * n + j] = ljj;
        for (size_t i = j + 1u; i < n; ++i) {
            double s = a[i * n + j];
            for (size_t k = 0u; k < j; ++k) {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / ljj;
        }
        for (size_t k = j + 1u; k < n; ++k) {
            a[j * n + k] = 0.0;
        }
    }
    return MD_OK;
}

double linalg_cholesky_logdet(const double *l, size_t n)
{
    if ((l == NULL) || !linalg_size_ok(n)) {
        return (double)NAN;
    }
    double s = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        s += log(l[i * n + i]);
    }
    return 2.0 * s;
}

/* Solves L y = b in place (forward substitution). */
static void linalg_forward(const double *l, size_t n, double *b)
{
    for (size_t i = 0u; i < n; ++i) {
        double s = b[i];
        for (size_t k = 0u; k < i; ++k) {
            s -= l[i * n + k] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
}

md_status_t linalg_cholesky_solve(const double *l, size_t n, double *b)
{
    if ((l == NULL) || (b == NULL) || !linalg_size_ok(n)) {
        return MD_E_ARG;
    }
    linalg_forward(l, n, b);
    /* L^T x = y, backward; i counts down without unsigned wrap-around. */
    for (size_t r = 0u; r < n; ++r) {
        const size_t i = n - 1u - r;
        double s = b[i];
        for (size_t k = i + 1u; k < n; ++k) {
            s -= l[k * n + i] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
    return linalg_all_finite(b, n) ? MD_OK : MD_E_NUMERIC;
}

md_status_t linalg_spd_inverse(const double *a, size_t n, double *inv, double *work, double *logdet)
{
    if ((a == NULL) || (inv == NULL) || (work == NULL) || !linalg_size_ok(n)) {
        return MD_E_ARG;
    }
    memcpy(work, a, n * n * sizeof(double));
    const md_status_t st = linalg_cholesky(work, n);
    if (st < 0) {
        return st;
    }
    /* Column j of A^{-1} solves A x = e_j; columns are written transposed into
     * rows, which is the same because A^{-1} is symmetric. */
    for (size_t j = 0u; j < n; ++j) {
        double *row = &inv[j * n];
        for (size_t i = 0u; i < n; ++i) {
            row[i] = (i == j) ? 1.0 : 0.0;
        }
        if (linalg_cholesky_solve(work, n, row) != MD_OK) {
            return MD_E_NUMERIC;
        }
    }
    /* Symmetrise away the rounding asymmetry of the two triangles. */
    for (size_t i = 0u; i < n; ++i) {
        for (size_t j = i + 1u; j < n; ++j) {
            const double m = 0.5 * (inv[i * n + j] + inv[j * n + i]);
            inv[i * n + j] = m;
            inv[j * n + i] = m;
        }
    }
    if (!linalg_all_finite(inv, n * n)) {
        return MD_E_NUMERIC;
    }
    if (logdet != NULL) {
        *logdet = linalg_cholesky_logdet(work, n);
    }
    return MD_OK;
}

/* True if the lower triangle of l is finite and its diagonal non-zero: a
 * triangular factor the forward substitution can use. */
static int linalg_factor_ok(const double *l, size_t n)
{
    for (size_t i = 0u; i < n; ++i) {
        if (!linalg_all_finite(&l[i * n], i + 1u) || !(fabs(l[i * n + i]) > 0.0)) {
            return 0;
        }
    }
    return 1;
}

md_status_t linalg_mahalanobis2(const double *l, size_t n, const double *x, const double *m, double *work, double *d2)
{
    if (d2 != NULL) {
        *d2 = (double)NAN;
    }
    if ((l == NULL) || (x == NULL) || (m == NULL) || (work == NULL) || (d2 == NULL) || !linalg_size_ok(n)) {
        return MD_E_ARG;
    }
    for (size_t i = 0u; i < n; ++i) {
        work[i] = x[i] - m[i];
    }
    /* (x-m)^T (L L^T)^{-1} (x-m) = |L^{-1}(x-m)|^2 */
    linalg_forward(l, n, work);
    double s = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        s += work[i] * work[i];
    }
    if (isfinite(s) != 0) {
        *d2 = s;
        return MD_OK;
    }
    /* A non-finite x, m or factor entry, or a zero pivot, always makes the sum
     * non-finite, so the inputs are checked only here, off the common path.
     * With all of them valid, a non-finite sum is an overflow (x - m beyond
     * the double range, or inf - inf in the solve): a distance larger than
     * any double. */
    if (!linalg_all_finite(x, n) || !linalg_all_finite(m, n) || !linalg_factor_ok(l, n)) {
        return MD_E_NUMERIC;
    }
    *d2 = HUGE_VAL;
    return MD_OK;
}

/* Sum of squares of the strict upper triangle and of the whole matrix. */
static void linalg_offdiag_mass(const double *a, size_t n, double *off, double *total)
{
    double o = 0.0;
    double t = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        t += a[i * n + i] * a[i * n + i];
        for (size_t j = i + 1u; j < n; ++j) {
            o += a[i * n + j] * a[i * n + j];
        }
    }
    *off = o;
    *total = t + 2.0 * o;
}

/* One Jacobi rotation annihilating a[p][q] (Golub & Van Loan, sym.schur2):
 * A <- J^T A J, V <- V J. */
static void linalg_jacobi_rotate(double *a, double *v, size_t n, size_t p, size_t q)
{
    const double apq = a[p * n + q];
    const double theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
    const double t = ((theta >= 0.0) ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
    const double c = 1.0 / sqrt(t * t + 1.0);
    const double s = t * c;
    for (size_t k = 0u; k < n; ++k) {
        const double akp = a[k * n + p];
        const double akq = a[k * n + q];
        a[k * n + p] = c * akp - s * akq;
        a[k * n + q] = s * akp + c * akq;
    }
    for (size_t k = 0u; k < n; ++k) {
        const double apk = a[p * n + k];
        const double aqk = a[q * n + k];
        a[p * n + k] = c * apk - s * aqk;
        a[q * n + k] = s * apk + c * aqk;
    }
    a[p * n + q] = 0.0;
    a[q * n + p] = 0.0;
    for (size_t k = 0u; k < n; ++k) {
        const double vkp = v[k * n + p];
        const double vkq = v[k * n + q];
        v[k * n + p] = c * vkp - s * vkq;
        v[k * n + q] = s * vkp + c * vkq;
    }
}

/* Selection sort of eigenpairs, descending eigenvalue; columns move with them. */
static void linalg_sort_eigen(double *vals, double *vecs, size_t n)
{
    for (size_t i = 0u; i < n; ++i) {
        size_t best = i;
        for (size_t j = i + 1u; j < n; ++j) {
            if (vals[j] > vals[best]) {
                best = j;
            }
        }
        if (best != i) {
            const double tv = vals[i];
            vals[i] = vals[best];
            vals[best] = tv;
            for (size_t k = 0u; k < n; ++k) {
                const double tmp = vecs[k * n + i];
                vecs[k * n + i] = vecs[k * n + best];
                vecs[k * n + best] = tmp;
            }
        }
    }
}

/* Exponent e of max|x_i| (frexp: max in [2^(e-1), 2^e)); 0 if all are 0. */
static int linalg_pow2_exponent(const double *x, size_t count)
{
    double m = 0.0;
    for (size_t i = 0u; i < count; ++i) {
        m = fmax(m, fabs(x[i]));
    }
    int e = 0;
    if (m > 0.0) {
        (void)frexp(m, &e);
    }
    return e;
}

/* x_i *= 2^e, exactly (barring underflow of entries negligible next to the largest). */
static void linalg_ldexp_all(double *x, size_t count, int e)
{
    for (size_t i = 0u; i < count; ++i) {
        x[i] = ldexp(x[i], e);
    }
}

md_status_t linalg_sym_eigen(double *a, size_t n, double *eigvals, double *eigvecs, unsigned max_sweeps)
{
    if ((a == NULL) || (eigvals == NULL) || (eigvecs == NULL) || !linalg_size_ok(n) || (max_sweeps == 0u)) {
        return MD_E_ARG;
    }
    if (!linalg_all_finite(a, n * n)) {
        return MD_E_NUMERIC;
    }
    const unsigned sweeps = (max_sweeps < LINALG_JACOBI_SWEEPS_CAP) ? max_sweeps : LINALG_JACOBI_SWEEPS_CAP;
    for (size_t i = 0u; i < n; ++i) {
        for (size_t j = 0u; j < n; ++j) {
            eigvecs[i * n + j] = (i == j) ? 1.0 : 0.0;
            if (j > i) { /* use the symmetric part; rounding asymmetry is harmless */
                const double m = 0.5 * (a[i * n + j] + a[j * n + i]);
                a[i * n + j] = m;
                a[j * n + i] = m;
            }
        }
    }
    /* Work on a / 2^e, 2^e ~ max|a_ij| (exact): the convergence test squares
     * entries, which overflows above ~1e154 and underflows below ~1e-154 and
     * would then report "converged" before any rotation. */
    const int scale_exp = linalg_pow2_exponent(a, n * n);
    linalg_ldexp_all(a, n * n, -scale_exp);
    int converged = 0;
    for (unsigned sweep = 0u; (sweep <= sweeps) && !converged; ++sweep) {
        double off = 0.0;
        double total = 0.0;
        linalg_offdiag_mass(a, n, &off, &total);
        const double tol = LINALG_JACOBI_REL_TOL * LINALG_JACOBI_REL_TOL * total;
        if (!(off > tol)) {
            converged = 1;
        } else if (sweep < sweeps) {
            for (size_t p = 0u; p + 1u < n; ++p) {
                for (size_t q = p + 1u; q < n; ++q) {
                    if (fabs(a[p * n + q]) > 0.0) {
                        linalg_jacobi_rotate(a, eigvecs, n, p, q);
                    }
                }
            }
        } else {
            /* last pass only measured: fall out unconverged */
        }
    }
    linalg_ldexp_all(a, n * n, scale_exp); /* a holds the rotated matrix, as before */
    for (size_t i = 0u; i < n; ++i) {
        eigvals[i] = a[i * n + i];
    }
    linalg_sort_eigen(eigvals, eigvecs, n);
    if (!linalg_all_finite(eigvals, n) || !linalg_all_finite(eigvecs, n * n)) {
        return MD_E_NUMERIC;
    }
    return converged ? MD_OK : MD_E_NOCONVERGE;
}

md_status_t linalg_matmul(const double *a, const double *b, double *c, size_t r, size_t k, size_t cols)
{
    if ((a == NULL) || (b == NULL) || (c == NULL)) {
        return MD_E_ARG;
    }
    for (size_t i = 0u; i < r; ++i) {
        for (size_t j = 0u; j < cols; ++j) {
            double s = 0.0;
            for (size_t m = 0u; m < k; ++m) {
                s += a[i * k + m] * b[m * cols + j];
            }
            c[i * cols + j] = s;
        }
    }
    return MD_OK;
}

/// @file eigen_top.c
/// Leading eigenpairs by tridiagonalisation, bisection and inverse iteration
/// (see eigen_top.h; Golub & Van Loan §8.3, §8.4.1 and LAPACK dsytrd, dstebz, dstein).
#include "numeric/eigen_top.h"

#include <float.h>
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#define ET_BISECT_MAX 96u /* halvings of a Gershgorin interval down to ~2 ulps of ‖T‖ need ≤ 64 */
#define ET_INVIT_MAX 8u   /* inverse iterations per vector; 1-2 suffice at a bisected λ */
#define ET_INVIT_MIN 3u   /* always this many: the last ones only polish */
#define ET_RESID_REL 1e-9 /* accepted ‖T z - λ z‖ / ‖T‖ (the method reaches ~1e-15) */
#define ET_RESCALE 1e150  /* back substitution rescales its vector beyond this magnitude */

/* Reflector of step j: (I - τ v vᵀ) x = μ e1 for x = A[j+1.., j]; v_0 = 1 is
 * implicit, v_i (i ≥ 1) overwrite x_i in column j. LAPACK's dlarfg
 * convention: μ = -sign(x_0)·‖x‖, so v_0 = x_0 - μ adds two numbers of one
 * sign, |v_i| ≤ 1 and τ ∈ [1, 2] (Golub & Van Loan's μ = +‖x‖ needs
 * v_0 = -σ/(x_0 + ‖x‖), which underflows when x is nearly e1). Norms are taken
 * of x / max|x_i|, so squares of entries near 1e-160 keep their precision. */
static double et_house(double *a, size_t n, size_t j, double *mu)
{
    const size_t m = n - j - 1u;
    double amax = 0.0;
    for (size_t i = 0u; i < m; ++i) {
        amax = fmax(amax, fabs(a[(j + 1u + i) * n + j]));
    }
    const double x0 = a[(j + 1u) * n + j];
    if (!(amax > 0.0)) {
        *mu = 0.0; /* a zero column */
        return 0.0;
    }
    double sigma = 0.0;
    for (size_t i = 1u; i < m; ++i) {
        const double xs = a[(j + 1u + i) * n + j] / amax;
        sigma += xs * xs;
    }
    if (!(sigma > 0.0)) {
        *mu = x0; /* already reduced (or the rest is below 1e-154 of it: negligible) */
        return 0.0;
    }
    const double xs0 = x0 / amax;
    const double norm = sqrt(xs0 * xs0 + sigma);
    const double mus = (xs0 >= 0.0) ? -norm : norm;
    const double v0 = xs0 - mus;
    for (size_t i = 1u; i < m; ++i) {
        a[(j + 1u + i) * n + j] = (a[(j + 1u + i) * n + j] / amax) / v0;
    }
    *mu = mus * amax;
    return (mus - xs0) / mus;
}

/* Component i of reflector j's vector. */
static double et_v(const double *a, size_t n, size_t j, size_t i)
{
    return (i == 0u) ? 1.0 : a[(j + 1u + i) * n + j];
}

/* Trailing block B = A[j+1.., j+1..] (lower triangle) ← H B H, as the
 * rank-2 update B - v wᵀ - w vᵀ, w = p - (β/2)(pᵀv) v, p = β B v. */
static void et_reflect_block(double *a, size_t n, size_t j, double beta, double *p)
{
    const size_t o = j + 1u;
    const size_t m = n - o;
    memset(p, 0, m * sizeof p[0]);
    for (size_t r = 0u; r < m; ++r) { /* p = B v from the lower triangle */
        const double vr = et_v(a, n, j, r);
        double s = a[(o + r) * n + o + r] * vr;
        for (size_t c = 0u; c < r; ++c) {
            const double b = a[(o + r) * n + o + c];
            s += b * et_v(a, n, j, c);
            p[c] += b * vr;
        }
        p[r] += s;
    }
    double pv = 0.0;
    for (size_t r = 0u; r < m; ++r) {
        p[r] *= beta;
        pv += p[r] * et_v(a, n, j, r);
    }
    const double k = 0.5 * beta * pv;
    for (size_t r = 0u; r < m; ++r) {
        p[r] -= k * et_v(a, n, j, r); /* p is w from here on */
    }
    for (size_t r = 0u; r < m; ++r) {
        const double vr = et_v(a, n, j, r);
        for (size_t c = 0u; c <= r; ++c) {
            a[(o + r) * n + o + c] -= vr * p[c] + p[r] * et_v(a, n, j, c);
        }
    }
}

/* A = Q T Qᵀ: T's diagonal and sub-diagonal, reflectors kept in a and ws->beta. */
static void et_tridiagonalise(double *a, size_t n, eigen_top_work_t *ws)
{
    memset(ws->beta, 0, sizeof ws->beta);
    for (size_t j = 0u; j + 2u < n; ++j) {
        double mu = 0.0;
        ws->beta[j] = et_house(a, n, j, &mu);
        if (ws->beta[j] > 0.0) {
            et_reflect_block(a, n, j, ws->beta[j], ws->z[0]); /* z[0]: scratch until step 3 */
        }
        ws->diag[j] = a[j * n + j];
        ws->off[j] = mu;
    }
    if (n >= 2u) {
        ws->diag[n - 2u] = a[(n - 2u) * n + n - 2u];
        ws->off[n - 2u] = a[(n - 1u) * n + n - 2u];
    }
    ws->diag[n - 1u] = a[(n - 1u) * n + n - 1u];
    ws->off[n - 1u] = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        ws->off2[i] = ws->off[i] * ws->off[i];
    }
}

/* Number of eigenvalues of T not above x (Sturm sequence of the LDLᵀ pivots, dstebz). */
static size_t et_count_below(const eigen_top_work_t *ws, size_t n, double x, double pivmin)
{
    size_t count = 0u;
    double q = ws->diag[0] - x;
    for (size_t i = 0u; i < n; ++i) {
        if (i > 0u) {
            q = ws->diag[i] - x - ws->off2[i - 1u] / q;
        }
        if (fabs(q) < pivmin) {
            q = -pivmin;
        }
        count += (q <= 0.0) ? 1u : 0u;
    }
    return count;
}

/* Eigenvalue of ascending index m of T by bisection inside [lo, hi]. */
static double et_bisect(const eigen_top_work_t *ws, size_t n, size_t m, double lo, double hi, double pivmin)
{
    const double tnorm = fmax(fabs(lo), fabs(hi));
    for (unsigned it = 0u; it < ET_BISECT_MAX; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (!((hi - lo) > 2.0 * DBL_EPSILON * tnorm + 4.0 * pivmin) || !(mid > lo) || !(mid < hi)) {
            break;
        }
        if (et_count_below(ws, n, mid, pivmin) > m) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    return 0.5 * (lo + hi);
}

/* Gershgorin interval of T, widened so both ends bracket strictly. */
static void et_gershgorin(const eigen_top_work_t *ws, size_t n, double pivmin, double *lo, double *hi)
{
    double l = ws->diag[0];
    double h = ws->diag[0];
    for (size_t i = 0u; i < n; ++i) {
        const double r = fabs(ws->off[i]) + ((i > 0u) ? fabs(ws->off[i - 1u]) : 0.0);
        l = fmin(l, ws->diag[i] - r);
        h = fmax(h, ws->diag[i] + r);
    }
    const double pad = 2.0 * DBL_EPSILON * fmax(fabs(l), fabs(h)) * (double)n + 2.0 * pivmin;
    *lo = l - pad;
    *hi = h + pad;
}

/* LU with partial pivoting of T - λI (dlagtf): U has two super-diagonals; a
 * zero pivot becomes `tiny` (inverse iteration wants the near-singular system). */
static void et_factor(eigen_top_work_t *ws, size_t n, double lambda, double tiny)
{
    double r0 = ws->diag[0] - lambda; /* active row, columns i and i+1 */
    double r1 = ws->off[0];
    for (size_t i = 0u; i + 1u < n; ++i) {
        const double sub = ws->off[i];
        const double dn = ws->diag[i + 1u] - lambda;
        const double sup = ws->off[i + 1u];
        ws->piv[i] = (fabs(r0) >= fabs(sub)) ? (unsigned char)0u : (unsigned char)1u;
        if (ws->piv[i] == 0u) {
            const double mult = (fabs(r0) > 0.0) ? (sub / r0) : 0.0;
            ws->lu[0][i] = (fabs(r0) > 0.0) ? r0 : tiny;
            ws->lu[1][i] = r1;
            ws->lu[2][i] = 0.0;
            ws->lu[3][i] = mult;
            r0 = dn - mult * r1;
            r1 = sup;
        } else {
            const double mult = r0 / sub;
            ws->lu[0][i] = sub;
            ws->lu[1][i] = dn;
            ws->lu[2][i] = sup;
            ws->lu[3][i] = mult;
            r0 = r1 - mult * dn;
            r1 = -mult * sup;
        }
    }
    ws->lu[0][n - 1u] = (fabs(r0) > 0.0) ? r0 : tiny;
}

/* x ← (T - λI)⁻¹ x from et_factor, rescaled whenever it grows past ET_RESCALE. */
static void et_solve(const eigen_top_work_t *ws, size_t n, double *x)
{
    for (size_t i = 0u; i + 1u < n; ++i) {
        if (ws->piv[i] != 0u) {
            const double t = x[i];
            x[i] = x[i + 1u];
            x[i + 1u] = t;
        }
        x[i + 1u] -= ws->lu[3][i] * x[i];
    }
    for (size_t k = 0u; k < n; ++k) {
        const size_t i = n - 1u - k;
        double s = x[i];
        s -= (i + 1u < n) ? ws->lu[1][i] * x[i + 1u] : 0.0;
        s -= (i + 2u < n) ? ws->lu[2][i] * x[i + 2u] : 0.0;
        x[i] = s / ws->lu[0][i];
        if (!(fabs(x[i]) <= ET_RESCALE)) {
            for (size_t j = 0u; j < n; ++j) {
                x[j] /= ET_RESCALE; /* a common factor: the direction is what counts */
            }
        }
    }
}

/* x ← x minus its components along the vectors already found, then unit length. False if nothing is left.
 * Two Gram-Schmidt passes ("twice is enough", Kahan-Parlett): near a cluster inverse iteration
 * amplifies the earlier vectors' directions by up to 1/ε, and one pass leaves ~ε of them per unit
 * of amplification. */
static bool et_orthonormalise(const eigen_top_work_t *ws, size_t n, size_t done, double *x)
{
    for (unsigned pass = 0u; pass < 2u; ++pass) {
        double big0 = 0.0;
        for (size_t i = 0u; i < n; ++i) {
            big0 = fmax(big0, fabs(x[i]));
        }
        const double div0 = ((big0 > 0.0) && isfinite(big0)) ? big0 : 1.0;
        for (size_t i = 0u; i < n; ++i) {
            x[i] /= div0; /* unit scale first: the dot products cannot overflow */
        }
        for (size_t q = 0u; q < done; ++q) {
            double dot = 0.0;
            for (size_t i = 0u; i < n; ++i) {
                dot += ws->z[q][i] * x[i];
            }
            for (size_t i = 0u; i < n; ++i) {
                x[i] -= dot * ws->z[q][i];
            }
        }
    }
    double big = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        big = fmax(big, fabs(x[i]));
    }
    if (!(big > 0.0) || !isfinite(big)) {
        return false;
    }
    double ss = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        x[i] /= big; /* first to ~1, so the squares stay in range */
        ss += x[i] * x[i];
    }
    const double inv = 1.0 / sqrt(ss);
    for (size_t i = 0u; i < n; ++i) {
        x[i] *= inv;
    }
    return true;
}

/* ‖T x - λ x‖₂. */
static double et_residual(const eigen_top_work_t *ws, size_t n, double lambda, const double *x)
{
    double ss = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        double r = (ws->diag[i] - lambda) * x[i];
        r += (i > 0u) ? ws->off[i - 1u] * x[i - 1u] : 0.0;
        r += (i + 1u < n) ? ws->off[i] * x[i + 1u] : 0.0;
        ss += r * r;
    }
    return sqrt(ss);
}

/* Deterministic start vector, different for each wanted pair (dstein starts from random numbers). */
static void et_start(size_t n, size_t which, double *x)
{
    uint32_t s = 0x2545F491u + 0x9E3779B9u * (uint32_t)which;
    for (size_t i = 0u; i < n; ++i) {
        s = s * 1664525u + 1013904223u; /* Numerical Recipes' LCG: only a spread of signs and sizes is needed */
        x[i] = ((double)(s >> 8) / 16777216.0) * 2.0 - 1.0;
    }
}

/* Eigenvector `which` of T for λ, orthogonal to z[0..which). */
static md_status_t et_vector(eigen_top_work_t *ws, size_t n, size_t which, double lambda, double tnorm)
{
    double *x = ws->z[which];
    et_factor(ws, n, lambda, DBL_EPSILON * tnorm);
    et_start(n, which, x);
    bool ok = et_orthonormalise(ws, n, which, x);
    for (unsigned it = 0u; ok && (it < ET_INVIT_MAX); ++it) {
        et_solve(ws, n, x);
        ok = et_orthonormalise(ws, n, which, x);
        if (ok && (it + 1u >= ET_INVIT_MIN) && (et_residual(ws, n, lambda, x) <= ET_RESID_REL * tnorm)) {
            return MD_OK;
        }
    }
    return ok ? MD_E_NOCONVERGE : MD_E_NUMERIC;
}

/* Row i of vecs ← Q z[i], applying the reflectors last to first. */
static void et_back_transform(const double *a, size_t n, const eigen_top_work_t *ws, size_t i, double *out)
{
    memcpy(out, ws->z[i], n * sizeof out[0]);
    for (size_t k = 0u; k + 2u < n; ++k) {
        const size_t j = n - 3u - k;
        if (!(ws->beta[j] > 0.0)) {
            continue;
        }
        double s = 0.0;
        for (size_t r = 0u; r + j + 1u < n; ++r) {
            s += et_v(a, n, j, r) * out[j + 1u + r];
        }
        s *= ws->beta[j];
        for (size_t r = 0u; r + j + 1u < n; ++r) {
            out[j + 1u + r] -= s * et_v(a, n, j, r);
        }
    }
}

md_status_t linalg_sym_eigen_top(double *a, size_t n, size_t k, double *vals, double *vecs, eigen_top_work_t *ws)
{
    if ((a == NULL) || (vals == NULL) || (vecs == NULL) || (ws == NULL) || (n < 1u) || (n > LINALG_MAX_N) || (k < 1u) ||
        (k > n) || (k > EIGEN_TOP_K_MAX)) {
        return MD_E_ARG;
    }
    for (size_t r = 0u; r < n; ++r) {
        if (!linalg_all_finite(&a[r * n], r + 1u)) { /* the lower triangle is the input */
            return MD_E_NUMERIC;
        }
    }
    et_tridiagonalise(a, n, ws);
    double max_off2 = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        max_off2 = fmax(max_off2, ws->off2[i]);
    }
    const double pivmin = (DBL_MIN / DBL_EPSILON) * fmax(1.0, max_off2);
    double lo = 0.0;
    double hi = 0.0;
    et_gershgorin(ws, n, pivmin, &lo, &hi);
    const double tnorm = fmax(fmax(fabs(lo), fabs(hi)), DBL_MIN);
    md_status_t st = isfinite(lo) && isfinite(hi) ? MD_OK : MD_E_NUMERIC;
    for (size_t i = 0u; (st == MD_OK) && (i < k); ++i) {
        vals[i] = et_bisect(ws, n, n - 1u - i, lo, hi, pivmin);
        st = et_vector(ws, n, i, vals[i], tnorm);
    }
    for (size_t i = 0u; (st == MD_OK) && (i < k); ++i) {
        et_back_transform(a, n, ws, i, &vecs[i * n]);
    }
    const bool finite = (st != MD_OK) || (linalg_all_finite(vals, k) && linalg_all_finite(vecs, k * n));
    return finite ? st : MD_E_NUMERIC;
}

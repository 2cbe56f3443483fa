/// @file pca.c
/// PCA basis from the waveform sample covariance (see pca.h).
#include "features/pca.h"

#include <math.h>
#include <string.h>

#include "numeric/linalg.h"

_Static_assert(MD_WAVE_LEN_MAX <= LINALG_MAX_N, "the covariance must fit the eigen-solver");
_Static_assert(MD_FEAT_DIM_MAX <= EIGEN_TOP_K_MAX, "the eigen-solver must return every basis row");

/* Waveform rows from doubles or from compact int16 counts times a gain. */
typedef struct {
    const double *d;
    const int16_t *s;
    size_t stride;
    double gain;
} pca_src_t;

static const double *pca_row(const pca_src_t *src, size_t i, size_t d_w, double *tmp)
{
    if (src->d != NULL) {
        return &src->d[i * src->stride];
    }
    for (size_t j = 0u; j < d_w; ++j) {
        tmp[j] = src->gain * (double)src->s[i * src->stride + j];
    }
    return tmp;
}

#define PCA_ROWS_PER_PASS 4u /* deviation rows folded into the covariance per pass over it */

/* Thesis footnote 5: Sigma = 1/(N-1) sum (x_i - xbar)(x_i - xbar)^T, upper
 * triangle accumulated PCA_ROWS_PER_PASS rows at a time (each entry is read
 * and written once per pass, not once per row), then mirrored. */
static void pca_covariance(const pca_src_t *src, size_t n, size_t d_w, double *mean, double *cov)
{
    double tmp[MD_WAVE_LEN_MAX];
    double dev[PCA_ROWS_PER_PASS][MD_WAVE_LEN_MAX];
    memset(mean, 0, d_w * sizeof(double));
    for (size_t i = 0u; i < n; ++i) {
        const double *x = pca_row(src, i, d_w, tmp);
        for (size_t a = 0u; a < d_w; ++a) {
            mean[a] += x[a];
        }
    }
    for (size_t a = 0u; a < d_w; ++a) {
        mean[a] /= (double)n;
    }
    memset(cov, 0, d_w * d_w * sizeof(double));
    for (size_t i0 = 0u; i0 < n; i0 += PCA_ROWS_PER_PASS) {
        for (size_t r = 0u; r < PCA_ROWS_PER_PASS; ++r) { /* rows past n contribute zeros */
            const double *x = (i0 + r < n) ? pca_row(src, i0 + r, d_w, tmp) : mean;
            for (size_t a = 0u; a < d_w; ++a) {
                dev[r][a] = x[a] - mean[a];
            }
        }
        for (size_t a = 0u; a < d_w; ++a) {
            const double d0 = dev[0][a];
            const double d1 = dev[1][a];
            const double d2 = dev[2][a];
            const double d3 = dev[3][a];
            double *row = &cov[a * d_w];
            for (size_t b = a; b < d_w; ++b) {
                row[b] += ((d0 * dev[0][b] + d1 * dev[1][b]) + d2 * dev[2][b]) + d3 * dev[3][b];
            }
        }
    }
    for (size_t a = 0u; a < d_w; ++a) {
        for (size_t b = a; b < d_w; ++b) {
            cov[a * d_w + b] /= (double)(n - 1u);
            cov[b * d_w + a] = cov[a * d_w + b];
        }
    }
}
_Static_assert(PCA_ROWS_PER_PASS == 4u, "pca_covariance unrolls four rows");

/* Flips a basis row so that its largest-magnitude component is positive.
 * Components within a relative 1e-9 of the largest count as tied and the
 * lowest index wins, so rounding cannot flip the choice between near-equal
 * components. */
static void pca_fix_sign(double *row, size_t d_w)
{
    double big = 0.0;
    for (size_t j = 0u; j < d_w; ++j) {
        big = fmax(big, fabs(row[j]));
    }
    size_t pick = 0u;
    for (size_t j = 0u; j < d_w; ++j) {
        if (fabs(row[j]) >= (1.0 - 1e-9) * big) {
            pick = j;
            break;
        }
    }
    if (row[pick] < 0.0) {
        for (size_t j = 0u; j < d_w; ++j) {
            row[j] = -row[j];
        }
    }
}

/* Largest magnitude of any sample: the scale of the rounding floor. */
static double pca_max_abs(const pca_src_t *src, size_t n, size_t d_w)
{
    double tmp[MD_WAVE_LEN_MAX];
    double big = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        const double *x = pca_row(src, i, d_w, tmp);
        for (size_t j = 0u; j < d_w; ++j) {
            big = fmax(big, fabs(x[j]));
        }
    }
    return big;
}

/* Trace of the covariance after checking that it is usable: MD_E_NUMERIC if
 * the mean, an entry or the sum overflowed; MD_E_DEGENERATE if the spread is
 * zero, rounding error (PCA_DEGENERATE_REL) or too small to hold full
 * precision (PCA_VAR_MIN). */
static md_status_t pca_check_cov(const pca_src_t *src, size_t n, size_t d_w, const double *mean, const double *cov,
                                 double *trace)
{
    if (!linalg_all_finite(mean, d_w) || !linalg_all_finite(cov, d_w * d_w)) {
        return MD_E_NUMERIC;
    }
    double t = 0.0;
    for (size_t a = 0u; a < d_w; ++a) {
        t += cov[a * d_w + a];
    }
    if (!isfinite(t)) {
        return MD_E_NUMERIC;
    }
    /* compared as an RMS so that the floor cannot overflow for large data */
    if (!(t >= PCA_VAR_MIN) || !(sqrt(t / (double)d_w) > PCA_DEGENERATE_REL * pca_max_abs(src, n, d_w))) {
        return MD_E_DEGENERATE;
    }
    *trace = t;
    return MD_OK;
}

static md_status_t pca_fit_src(const pca_src_t *src, size_t n, size_t d_w, size_t d, pca_work_t *work,
                               pca_basis_t *basis)
{
    if ((work == NULL) || (basis == NULL) || (d < 1u) || (d > MD_FEAT_DIM_MAX) || (d_w < d) ||
        (d_w > MD_WAVE_LEN_MAX) || (src->stride < d_w) || (n > MD_MAX_SPIKES * 64u) || !isfinite(src->gain)) {
        return MD_E_ARG;
    }
    if (n < 2u) {
        return MD_E_DEGENERATE;
    }
    for (size_t i = 0u; (src->d != NULL) && (i < n); ++i) {
        if (!linalg_all_finite(&src->d[i * src->stride], d_w)) {
            return MD_E_NUMERIC;
        }
    }
    pca_covariance(src, n, d_w, basis->mean, work->cov);
    double trace = 0.0;
    const md_status_t cst = pca_check_cov(src, n, d_w, basis->mean, work->cov, &trace);
    if (cst != MD_OK) {
        return cst;
    }
    /* Scaling by a power of two near the largest entry is exact and keeps
     * the eigen-solver's squares (reflector norms, Sturm pivots) in range
     * for data near 1e±154. */
    double cmax = 0.0;
    for (size_t i = 0u; i < d_w * d_w; ++i) {
        cmax = fmax(cmax, fabs(work->cov[i]));
    }
    int e2 = 0;
    (void)frexp(cmax, &e2);
    const double down = ldexp(1.0, -e2); /* 2^-e2, e2 in [-974, 1024]: representable */
    for (size_t i = 0u; i < d_w * d_w; ++i) {
        work->cov[i] *= down;
    }
    const md_status_t st = linalg_sym_eigen_top(work->cov, d_w, d, work->vals, work->vecs, &work->eig);
    if (st < 0) {
        return st;
    }
    for (size_t k = 0u; k < d; ++k) {
        work->vals[k] = ldexp(work->vals[k], e2);
    }
    if (!linalg_all_finite(work->vals, d)) {
        return MD_E_NUMERIC;
    }
    basis->d = d;
    basis->d_w = d_w;
    basis->total_var = trace;
    for (size_t k = 0u; k < d; ++k) {
        double *row = &basis->b[k * d_w];
        for (size_t j = 0u; j < d_w; ++j) {
            row[j] = work->vecs[k * d_w + j];
        }
        pca_fix_sign(row, d_w);
        basis->eigval[k] = fmax(work->vals[k], 0.0);
    }
    return MD_OK;
}

md_status_t pca_fit(const double *wave, size_t n, size_t stride, size_t d_w, size_t d, pca_work_t *work,
                    pca_basis_t *basis)
{
    const pca_src_t src = {wave, NULL, stride, 1.0};
    return (wave == NULL) ? MD_E_ARG : pca_fit_src(&src, n, d_w, d, work, basis);
}

md_status_t pca_fit_i16(const int16_t *wave, size_t n, size_t stride, size_t d_w, double gain, size_t d,
                        pca_work_t *work, pca_basis_t *basis)
{
    const pca_src_t src = {NULL, wave, stride, gain};
    return ((wave == NULL) || !(gain > 0.0)) ? MD_E_ARG : pca_fit_src(&src, n, d_w, d, work, basis);
}

md_status_t pca_project_i16(const pca_basis_t *basis, const int16_t *x, double gain, double *y)
{
    double row[MD_WAVE_LEN_MAX];
    if ((basis == NULL) || (x == NULL) || (basis->d_w > MD_WAVE_LEN_MAX) || !isfinite(gain)) {
        return MD_E_ARG;
    }
    for (size_t j = 0u; j < basis->d_w; ++j) {
        row[j] = gain * (double)x[j];
    }
    return pca_project(basis, row, y);
}

md_status_t pca_project_all_i16(const pca_basis_t *basis, const int16_t *wave, size_t n, size_t stride, double gain,
                                double *y)
{
    if ((basis == NULL) || (wave == NULL) || (y == NULL) || (stride < basis->d_w)) {
        return MD_E_ARG;
    }
    for (size_t i = 0u; i < n; ++i) {
        const md_status_t st = pca_project_i16(basis, &wave[i * stride], gain, &y[i * basis->d]);
        if (st < 0) {
            return st;
        }
    }
    return MD_OK;
}

md_status_t pca_project(const pca_basis_t *basis, const double *x, double *y)
{
    if ((basis == NULL) || (x == NULL) || (y == NULL) || (basis->d < 1u) || (basis->d > MD_FEAT_DIM_MAX) ||
        (basis->d_w > MD_WAVE_LEN_MAX)) {
        return MD_E_ARG;
    }
    if (linalg_matmul(basis->b, x, y, basis->d, basis->d_w, 1u) != MD_OK) {
        return MD_E_ARG;
    }
    return linalg_all_finite(y, basis->d) ? MD_OK : MD_E_NUMERIC;
}

md_status_t pca_project_all(const pca_basis_t *basis, const double *wave, size_t n, size_t stride, double *y)
{
    if ((basis == NULL) || (wave == NULL) || (y == NULL) || (stride < basis->d_w)) {
        return MD_E_ARG;
    }
    for (size_t i = 0u; i < n; ++i) {
        const md_status_t st = pca_project(basis, &wave[i * stride], &y[i * basis->d]);
        if (st < 0) {
            return st;
        }
    }
    return MD_OK;
}

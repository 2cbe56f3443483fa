/// @file quality.c
/// SNR, isolation distance and noise covariance (see quality.h).
#include "metrics/quality.h"

#include <math.h>
#include <string.h>

#include "numeric/linalg.h"

#define QM_MAX_POINTS (1u << 20) /* bound on n + m: every loop below is O(points) */

md_status_t qm_noise_rms(const double *noise, size_t m, size_t stride, size_t d_w, double *rms)
{
    if ((noise == NULL) || (rms == NULL) || (d_w == 0u) || (stride < d_w) || (m > QM_MAX_POINTS)) {
        return MD_E_ARG;
    }
    if (m == 0u) {
        return MD_E_DEGENERATE;
    }
    double ss = 0.0;
    for (size_t i = 0u; i < m; ++i) {
        for (size_t j = 0u; j < d_w; ++j) {
            const double v = noise[i * stride + j];
            ss += v * v;
        }
    }
    const double r = sqrt(ss / (double)(m * d_w));
    if (!isfinite(r)) {
        return MD_E_NUMERIC;
    }
    if (!(r > 0.0)) {
        return MD_E_DEGENERATE;
    }
    *rms = r;
    return MD_OK;
}

md_status_t qm_snr(const double *wave, size_t n, size_t stride, size_t d_w, const uint8_t *labels, uint8_t label,
                   double noise_rms, double *snr, size_t *n_members)
{
    if ((wave == NULL) || (snr == NULL) || (d_w == 0u) || (stride < d_w) || (n > QM_MAX_POINTS) || !(noise_rms > 0.0) ||
        !isfinite(noise_rms)) {
        return MD_E_ARG;
    }
    double sum_ptp = 0.0;
    size_t count = 0u;
    for (size_t i = 0u; i < n; ++i) {
        if ((labels != NULL) && (labels[i] != label)) {
            continue;
        }
        const double *x = &wave[i * stride];
        double lo = x[0];
        double hi = x[0];
        for (size_t j = 1u; j < d_w; ++j) {
            lo = fmin(lo, x[j]);
            hi = fmax(hi, x[j]);
        }
        sum_ptp += hi - lo;
        count++;
    }
    if (n_members != NULL) {
        *n_members = count;
    }
    if (count == 0u) {
        return MD_E_DEGENERATE;
    }
    const double s = sum_ptp / (double)count / noise_rms;
    if (!isfinite(s)) {
        return MD_E_NUMERIC;
    }
    *snr = s;
    return MD_OK;
}

md_status_t qm_feature_cov(const double *y, size_t m, size_t d, double *mean, double *cov)
{
    double mu[MD_FEAT_DIM_MAX];
    if ((y == NULL) || (cov == NULL) || (d == 0u) || (d > MD_FEAT_DIM_MAX) || (m > QM_MAX_POINTS)) {
        return MD_E_ARG;
    }
    if (m < 2u) {
        return MD_E_DEGENERATE;
    }
    memset(mu, 0, sizeof mu);
    memset(cov, 0, d * d * sizeof(double));
    for (size_t i = 0u; i < m; ++i) {
        for (size_t a = 0u; a < d; ++a) {
            mu[a] += y[i * d + a] / (double)m;
        }
    }
    for (size_t i = 0u; i < m; ++i) {
        for (size_t a = 0u; a < d; ++a) {
            for (size_t b = 0u; b < d; ++b) {
                cov[a * d + b] += (y[i * d + a] - mu[a]) * (y[i * d + b] - mu[b]) / (double)(m - 1u);
            }
        }
    }
    if (mean != NULL) {
        memcpy(mean, mu, d * sizeof(double));
    }
    return (linalg_all_finite(cov, d * d) && linalg_all_finite(mu, d)) ? MD_OK : MD_E_NUMERIC;
}

/* k-th smallest (0-based) of v[0..n) by iterative quickselect (Hoare
 * partition, middle pivot); reorders v. Each round shrinks [lo, hi]. */
static double qm_select(double *v, size_t n, size_t k)
{
    size_t lo = 0u;
    size_t hi = n - 1u;
    for (size_t round = 0u; (round < n) && (lo < hi); ++round) {
        const double pivot = v[lo + (hi - lo) / 2u];
        size_t i = lo;
        size_t j = hi;
        while (i <= j) { /* i rises and j falls by >= 1 per pass: at most n steps */
            while (v[i] < pivot) {
                ++i;
            }
            while (v[j] > pivot) {
                --j;
            }
            if (i <= j) {
                const double t = v[i];
                v[i] = v[j];
                v[j] = t;
                ++i;
                if (j == 0u) {
                    break;
                }
                --j;
            }
        }
        if (k <= j) {
            hi = j;
        } else if (k >= i) {
            lo = i;
        } else {
            return v[k];
        }
    }
    return v[k];
}

/* Members' mean and covariance into centre/cov; copies members to work first. */
static md_status_t qm_member_stats(const double *y, size_t n, size_t d, const uint8_t *labels, uint8_t label,
                                   double *work, double *centre, double *cov)
{
    size_t m = 0u;
    for (size_t i = 0u; i < n; ++i) {
        if (labels[i] == label) {
            memcpy(&work[m * d], &y[i * d], d * sizeof(double));
            ++m;
        }
    }
    if (m < d + 1u) {
        return MD_E_DEGENERATE;
    }
    return qm_feature_cov(work, m, d, centre, cov);
}

md_status_t qm_isolation_distance(const double *y, size_t n, size_t d, const uint8_t *labels, uint8_t label,
                                  const double *noise_y, size_t m, const double *centre, const double *cov,
                                  double *work, size_t work_len, qm_isolation_t *out)
{
    double mu[MD_FEAT_DIM_MAX];
    double chol[MD_FEAT_DIM_MAX * MD_FEAT_DIM_MAX];
    double tmp[MD_FEAT_DIM_MAX];
    if ((y == NULL) || (labels == NULL) || (work == NULL) || (out == NULL) || (d == 0u) || (d > MD_FEAT_DIM_MAX) ||
        ((noise_y == NULL) && (m > 0u)) || (n + m > QM_MAX_POINTS) || (work_len < (n + m) * d)) {
        return MD_E_ARG;
    }
    memset(out, 0, sizeof *out);
    if ((centre == NULL) || (cov == NULL)) {
        const md_status_t st = qm_member_stats(y, n, d, labels, label, work, mu, chol);
        if (st < 0) {
            return st;
        }
    } else {
        memcpy(mu, centre, d * sizeof(double));
        memcpy(chol, cov, d * d * sizeof(double));
    }
    const md_status_t st = linalg_cholesky(chol, d);
    if (st < 0) {
        return st;
    }
    size_t k = 0u; /* non-member distances collected in work[0..k) */
    for (size_t i = 0u; i < n; ++i) {
        if (labels[i] == label) {
            out->n_members++;
        } else {
            const md_status_t sd = linalg_mahalanobis2(chol, d, &y[i * d], mu, tmp, &work[k++]);
            if (sd != MD_OK) {
                return sd;
            }
        }
    }
    for (size_t i = 0u; i < m; ++i) {
        const md_status_t sd = linalg_mahalanobis2(chol, d, &noise_y[i * d], mu, tmp, &work[k++]);
        if (sd != MD_OK) {
            return sd;
        }
    }
    out->n_nonmembers = k;
    if (out->n_members < 2u) {
        return MD_E_DEGENERATE;
    }
    if (k < out->n_members) {
        return MD_OK; /* undefined: not enough non-members for the definition */
    }
    out->id2 = qm_select(work, k, out->n_members - 1u);
    out->id = sqrt(out->id2);
    out->defined = 1;
    return isfinite(out->id2) ? MD_OK : MD_E_NUMERIC;
}

md_status_t qm_noise_feature_cov(const pca_basis_t *basis, const double *noise, size_t m, size_t stride, double *xi)
{
    double mu[MD_FEAT_DIM_MAX];
    double yv[MD_FEAT_DIM_MAX];
    double chol[MD_FEAT_DIM_MAX * MD_FEAT_DIM_MAX];
    if ((basis == NULL) || (noise == NULL) || (xi == NULL) || (basis->d == 0u) || (basis->d > MD_FEAT_DIM_MAX) ||
        (stride < basis->d_w) || (m > QM_MAX_POINTS)) {
        return MD_E_ARG;
    }
    const size_t d = basis->d;
    if (m < d + 1u) {
        return MD_E_DEGENERATE;
    }
    memset(mu, 0, sizeof mu);
    for (size_t i = 0u; i < m; ++i) { /* pass 1: mean feature */
        const md_status_t st = pca_project(basis, &noise[i * stride], yv);
        if (st < 0) {
            return st;
        }
        for (size_t a = 0u; a < d; ++a) {
            mu[a] += yv[a] / (double)m;
        }
    }
    memset(xi, 0, d * d * sizeof(double));
    for (size_t i = 0u; i < m; ++i) { /* pass 2: scatter about it */
        (void)pca_project(basis, &noise[i * stride], yv);
        for (size_t a = 0u; a < d; ++a) {
            for (size_t b = 0u; b < d; ++b) {
                xi[a * d + b] += (yv[a] - mu[a]) * (yv[b] - mu[b]) / (double)(m - 1u);
            }
        }
    }
    memcpy(chol, xi, d * d * sizeof(double));
    return linalg_cholesky(chol, d);
}

/* ---- compact (int16 counts times gain) entry points --------------------- */

md_status_t qm_noise_rms_i16(const int16_t *noise, size_t m, size_t stride, size_t d_w, double gain, double *rms)
{
    if ((noise == NULL) || (rms == NULL) || (d_w == 0u) || (stride < d_w) || (m > QM_MAX_POINTS) || !(gain > 0.0) ||
        !isfinite(gain)) {
        return MD_E_ARG;
    }
    if (m == 0u) {
        return MD_E_DEGENERATE;
    }
    uint64_t ss = 0u; /* exact: 2^20 points * 48 * 2^30 < 2^64 */
    for (size_t i = 0u; i < m; ++i) {
        for (size_t j = 0u; j < d_w; ++j) {
            const int64_t v = noise[i * stride + j];
            ss += (uint64_t)(v * v);
        }
    }
    const double r = gain * sqrt((double)ss / (double)(m * d_w));
    if (!(r > 0.0)) {
        return MD_E_DEGENERATE;
    }
    *rms = r;
    return MD_OK;
}

md_status_t qm_snr_i16(const int16_t *wave, size_t n, size_t stride, size_t d_w, double gain, const uint8_t *labels,
                       uint8_t label, double noise_rms, double *snr, size_t *n_members)
{
    if ((wave == NULL) || (snr == NULL) || (d_w == 0u) || (stride < d_w) || (n > QM_MAX_POINTS) || !(noise_rms > 0.0) ||
        !isfinite(noise_rms) || !(gain > 0.0) || !isfinite(gain)) {
        return MD_E_ARG;
    }
    uint64_t sum_ptp = 0u;
    size_t count = 0u;
    for (size_t i = 0u; i < n; ++i) {
        if ((labels != NULL) && (labels[i] != label)) {
            continue;
        }
        const int16_t *x = &wave[i * stride];
        int32_t lo = x[0];
        int32_t hi = x[0];
        for (size_t j = 1u; j < d_w; ++j) {
            lo = (x[j] < lo) ? x[j] : lo;
            hi = (x[j] > hi) ? x[j] : hi;
        }
        sum_ptp += (uint64_t)(hi - lo);
        count++;
    }
    if (n_members != NULL) {
        *n_members = count;
    }
    if (count == 0u) {
        return MD_E_DEGENERATE;
    }
    *snr = gain * (double)sum_ptp / (double)count / noise_rms;
    return MD_OK;
}

md_status_t qm_noise_feature_cov_i16(const pca_basis_t *basis, const int16_t *noise, size_t m, size_t stride,
                                     double gain, double *xi)
{
    double mu[MD_FEAT_DIM_MAX];
    double yv[MD_FEAT_DIM_MAX];
    double chol[MD_FEAT_DIM_MAX * MD_FEAT_DIM_MAX];
    if ((basis == NULL) || (noise == NULL) || (xi == NULL) || (basis->d == 0u) || (basis->d > MD_FEAT_DIM_MAX) ||
        (stride < basis->d_w) || (m > QM_MAX_POINTS) || !(gain > 0.0)) {
        return MD_E_ARG;
    }
    const size_t d = basis->d;
    if (m < d + 1u) {
        return MD_E_DEGENERATE;
    }
    memset(mu, 0, sizeof mu);
    for (size_t i = 0u; i < m; ++i) { /* pass 1: mean feature */
        const md_status_t st = pca_project_i16(basis, &noise[i * stride], gain, yv);
        if (st < 0) {
            return st;
        }
        for (size_t a = 0u; a < d; ++a) {
            mu[a] += yv[a] / (double)m;
        }
    }
    memset(xi, 0, d * d * sizeof(double));
    for (size_t i = 0u; i < m; ++i) { /* pass 2: scatter about it */
        (void)pca_project_i16(basis, &noise[i * stride], gain, yv);
        for (size_t a = 0u; a < d; ++a) {
            for (size_t b = 0u; b < d; ++b) {
                xi[a * d + b] += (yv[a] - mu[a]) * (yv[b] - mu[b]) / (double)(m - 1u);
            }
        }
    }
    memcpy(chol, xi, d * d * sizeof(double));
    return linalg_cholesky(chol, d);
}

/// @file em_model.c
/// Densities of the §3.3.1 mixture and the §3.3.2 mean prior (see em_model.h).
#include "cluster/em_model.h"

#include <math.h>
#include <string.h>

#include "numeric/linalg.h"

#define EM_LOG_2PI 1.8378770664093454836

double em_logaddexp(double a, double b)
{
    const double hi = (a > b) ? a : b;
    const double lo = (a > b) ? b : a;
    return hi + log1p(exp(lo - hi));
}

md_status_t em_bounding_volume(const em_data_t *data, double *volume)
{
    if ((data == NULL) || (volume == NULL) || (data->y == NULL) || (data->n == 0u) || (data->d == 0u) ||
        (data->d > EM_D_MAX) || (data->n > EM_N_MAX)) {
        return MD_E_ARG;
    }
    double v = 1.0;
    for (size_t j = 0u; j < data->d; ++j) {
        double lo = data->y[j];
        double hi = data->y[j];
        for (size_t i = 1u; i < data->n; ++i) {
            lo = fmin(lo, data->y[i * data->d + j]);
            hi = fmax(hi, data->y[i * data->d + j]);
        }
        v *= hi - lo;
    }
    *volume = v;
    return (isfinite(v) && (v > 0.0)) ? MD_OK : MD_E_DEGENERATE;
}

md_status_t em_outlier_init(size_t d, const double *noise_cov, double volume, em_outlier_t *out)
{
    if ((noise_cov == NULL) || (out == NULL) || (d == 0u) || (d > EM_D_MAX) || !(volume > 0.0) || !isfinite(volume)) {
        return MD_E_ARG;
    }
    memset(out, 0, sizeof *out);
    out->d = d;
    for (size_t k = 0u; k < d * d; ++k) {
        out->chol[k] = EM_OUTLIER_K * noise_cov[k];
    }
    const md_status_t st = linalg_cholesky(out->chol, d);
    if (st != MD_OK) {
        return MD_E_NUMERIC;
    }
    out->log_volume = log(volume);
    out->log_norm = -0.5 * ((double)d * EM_LOG_2PI + linalg_cholesky_logdet(out->chol, d));
    return MD_OK;
}

double em_outlier_logpdf(const em_outlier_t *outlier, const double *y)
{
    const double zero[EM_D_MAX] = {0.0};
    double work[EM_D_MAX];
    double m2 = 0.0;
    if (linalg_mahalanobis2(outlier->chol, outlier->d, y, zero, work, &m2) != MD_OK) {
        return (double)NAN; /* not a density: the caller's finiteness check fails the fit */
    }
    /* Remark 3.2: f0 = ½ (N(0, KΞ) + 1/V) */
    return log(0.5) + em_logaddexp(outlier->log_norm - 0.5 * m2, -outlier->log_volume);
}

md_status_t em_outlier_tabulate(em_outlier_t *outlier, const em_data_t *data)
{
    if (outlier == NULL) {
        return MD_E_ARG;
    }
    outlier->tab_y = NULL;
    outlier->tab_n = 0u;
    if ((data == NULL) || (data->y == NULL) || (data->n > EM_N_MAX) || (data->d != outlier->d)) {
        return MD_E_ARG;
    }
    for (size_t i = 0u; i < data->n; ++i) {
        outlier->tab_log_f0[i] = em_outlier_logpdf(outlier, &data->y[i * data->d]);
        if (isnan(outlier->tab_log_f0[i]) != 0) {
            return MD_E_NUMERIC;
        }
    }
    outlier->tab_y = data->y;
    outlier->tab_n = data->n;
    return MD_OK;
}

double em_outlier_logpdf_at(const em_outlier_t *outlier, const em_data_t *data, size_t i)
{
    if ((outlier->tab_y == data->y) && (outlier->tab_n == data->n) && (i < data->n)) {
        return outlier->tab_log_f0[i];
    }
    return em_outlier_logpdf(outlier, &data->y[i * data->d]);
}

static md_status_t em_prior_target(size_t d, const em_target_t *t, double log_w, em_prior_t *p, size_t j)
{
    double work[EM_D_MAX * EM_D_MAX];
    double logdet = 0.0;
    memcpy(p->mean[j], t->mean, d * sizeof(double));
    memcpy(p->s_chol[j], t->s_cov, d * d * sizeof(double));
    if ((linalg_cholesky(p->s_chol[j], d) != MD_OK) ||
        (linalg_spd_inverse(t->s_cov, d, p->s_inv[j], work, &logdet) != MD_OK)) {
        return MD_E_NUMERIC;
    }
    p->log_w_norm[j] = log_w - 0.5 * ((double)d * EM_LOG_2PI + logdet);
    return MD_OK;
}

md_status_t em_prior_init(size_t d, const em_target_t *targets, size_t n_targets, double lambda0, double volume,
                          em_prior_t *out)
{
    if ((out == NULL) || (d == 0u) || (d > EM_D_MAX) || (n_targets > EM_J_MAX) ||
        ((targets == NULL) && (n_targets > 0u)) || !(lambda0 > 0.0) || !(volume > 0.0) || !isfinite(volume)) {
        return MD_E_ARG;
    }
    memset(out, 0, sizeof *out);
    out->d = d;
    out->n_targets = n_targets;
    double c = lambda0; /* eq. 3.9: normalisation of ω */
    for (size_t j = 0u; j < n_targets; ++j) {
        const double pd = targets[j].p_detect;
        if (!(pd > 0.0) || (pd > 1.0) || !linalg_all_finite(targets[j].mean, d)) {
            return MD_E_ARG;
        }
        c += pd;
    }
    out->log_w0_over_v = log(lambda0 / c) - log(volume);
    for (size_t j = 0u; j < n_targets; ++j) {
        const md_status_t st = em_prior_target(d, &targets[j], log(targets[j].p_detect / c), out, j);
        if (st != MD_OK) {
            return st;
        }
    }
    return MD_OK;
}

double em_prior_log_mean(const em_prior_t *prior, const double *mu, double *zeta)
{
    if (!linalg_all_finite(mu, prior->d)) {
        if (zeta != NULL) {
            memset(zeta, 0, (prior->n_targets + 1u) * sizeof(double));
        }
        return -HUGE_VAL; /* no density for a non-finite mean; the caller's isfinite check fails the fit */
    }
    double lw[EM_J_MAX + 1u];
    double lse = prior->log_w0_over_v;
    lw[0] = lse;
    for (size_t j = 0u; j < prior->n_targets; ++j) {
        double work[EM_D_MAX];
        double m2 = 0.0;
        if (linalg_mahalanobis2(prior->s_chol[j], prior->d, mu, prior->mean[j], work, &m2) != MD_OK) {
            if (zeta != NULL) {
                memset(zeta, 0, (prior->n_targets + 1u) * sizeof(double));
            }
            return (double)NAN; /* a prior not prepared by em_prior_init: the caller's isfinite check fails the fit */
        }
        /* eq. 3.8, j-th Gaussian term. A finite mean and target so far apart that
         * the distance overflows (m2 = +inf) have a density of 0 under this
         * term: weight -inf, never NaN. */
        lw[j + 1u] = prior->log_w_norm[j] - 0.5 * m2;
        lse = em_logaddexp(lse, lw[j + 1u]);
    }
    if (zeta != NULL) {
        for (size_t j = 0u; j <= prior->n_targets; ++j) {
            zeta[j] = exp(lw[j] - lse); /* eq. 3.14 */
        }
    }
    return lse;
}

/* Restores the heap property below node `root` of key[0..n). */
static void em_sift_down(double *key, uint16_t *idx, size_t root, size_t n)
{
    size_t r = root;
    for (size_t guard = 0u; guard < 32u; ++guard) { /* depth of a heap of <= 2^32 nodes */
        size_t child = 2u * r + 1u;
        if (child >= n) {
            return;
        }
        if ((child + 1u < n) && (key[child + 1u] > key[child])) {
            child += 1u;
        }
        if (!(key[child] > key[r])) {
            return;
        }
        const double tk = key[r];
        key[r] = key[child];
        key[child] = tk;
        const uint16_t ti = idx[r];
        idx[r] = idx[child];
        idx[child] = ti;
        r = child;
    }
}

void em_sort_keys(double *key, uint16_t *idx, size_t n)
{
    if ((key == NULL) || (idx == NULL) || (n < 2u)) {
        return;
    }
    for (size_t k = n / 2u; k > 0u; --k) {
        em_sift_down(key, idx, k - 1u, n);
    }
    for (size_t end = n - 1u; end > 0u; --end) {
        const double tk = key[0];
        key[0] = key[end];
        key[end] = tk;
        const uint16_t ti = idx[0];
        idx[0] = idx[end];
        idx[end] = ti;
        em_sift_down(key, idx, 0u, end);
    }
}

const char *em_reason_name(em_reason_t reason)
{
    switch (reason) {
    case EM_OK: return "EM_OK";
    case EM_FAIL_ARG: return "EM_FAIL_ARG";
    case EM_FAIL_TOO_FEW_POINTS: return "EM_FAIL_TOO_FEW_POINTS";
    case EM_FAIL_ZERO_VOLUME: return "EM_FAIL_ZERO_VOLUME";
    case EM_FAIL_NOISE_COV: return "EM_FAIL_NOISE_COV";
    case EM_FAIL_SEED: return "EM_FAIL_SEED";
    case EM_FAIL_EMPTY_CLUSTER: return "EM_FAIL_EMPTY_CLUSTER";
    case EM_FAIL_SINGULAR_COV: return "EM_FAIL_SINGULAR_COV";
    case EM_FAIL_NUMERIC: return "EM_FAIL_NUMERIC";
    case EM_FAIL_NOCONVERGE: return "EM_FAIL_NOCONVERGE";
    case EM_FAIL_HESSIAN: return "EM_FAIL_HESSIAN";
    case EM_FAIL_NOT_RUN: return "EM_FAIL_NOT_RUN";
    case EM_FAIL_ONE_MODE: return "EM_FAIL_ONE_MODE";
    default: return "EM_FAIL_UNKNOWN";
    }
}

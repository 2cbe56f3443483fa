/// @file em_modes.c
/// Ridgeline ratio of component pairs (em_modes.h).
#include "cluster/em_modes.h"

#include <math.h>
#include <string.h>

#include "numeric/linalg.h"

/* One component's inverse covariance and the constant of its log density. */
typedef struct {
    double inv[EM_D_MAX * EM_D_MAX]; /* Σ⁻¹ */
    double log_c;                    /* log w − ½ log det Σ (the 2π term cancels in the ratio) */
} ridge_comp_t;

static md_status_t ridge_comp(size_t d, double w, const double *cov, ridge_comp_t *c)
{
    double work[EM_D_MAX * EM_D_MAX];
    double logdet = 0.0;
    if (linalg_spd_inverse(cov, d, c->inv, work, &logdet) != MD_OK) {
        return MD_E_NUMERIC;
    }
    c->log_c = log(w) - 0.5 * logdet;
    return isfinite(c->log_c) ? MD_OK : MD_E_NUMERIC;
}

/* log of w N(x; μ, Σ) up to the shared 2π constant. */
static double ridge_log_density(const ridge_comp_t *c, const double *mu, const double *x, size_t d)
{
    double q = 0.0;
    for (size_t i = 0u; i < d; ++i) {
        for (size_t j = 0u; j < d; ++j) {
            q += (x[i] - mu[i]) * c->inv[i * d + j] * (x[j] - mu[j]);
        }
    }
    return c->log_c - 0.5 * q;
}

/* x(α) of the ridgeline: [(1−α)Σa⁻¹ + αΣb⁻¹] x = (1−α)Σa⁻¹μa + αΣb⁻¹μb. */
static md_status_t ridge_point(const ridge_comp_t *ca, const double *ma, const ridge_comp_t *cb, const double *mb,
                               size_t d, double alpha, double *x)
{
    double a[EM_D_MAX * EM_D_MAX];
    for (size_t i = 0u; i < d; ++i) {
        x[i] = 0.0;
        for (size_t j = 0u; j < d; ++j) {
            const double ia = (1.0 - alpha) * ca->inv[i * d + j];
            const double ib = alpha * cb->inv[i * d + j];
            a[i * d + j] = ia + ib;
            x[i] += ia * ma[j] + ib * mb[j];
        }
    }
    if ((linalg_cholesky(a, d) != MD_OK) || (linalg_cholesky_solve(a, d, x) != MD_OK)) {
        return MD_E_NUMERIC;
    }
    return MD_OK;
}

static double log_add(double u, double v)
{
    const double hi = (u > v) ? u : v;
    const double lo = (u > v) ? v : u;
    return hi + log1p(exp(lo - hi));
}

/* exp of the deepest point of logf below the lower of the highest values on its two sides. */
static double ridge_dip(const double *logf)
{
    double right_max[EM_RIDGE_POINTS];
    right_max[EM_RIDGE_POINTS - 1u] = logf[EM_RIDGE_POINTS - 1u];
    for (size_t k = EM_RIDGE_POINTS - 1u; k > 0u; --k) {
        right_max[k - 1u] = fmax(logf[k - 1u], right_max[k]);
    }
    double left_max = logf[0];
    double dip = 0.0;
    for (size_t k = 0u; k < EM_RIDGE_POINTS; ++k) {
        left_max = fmax(left_max, logf[k]);
        dip = fmin(dip, logf[k] - fmin(left_max, right_max[k]));
    }
    return exp(dip);
}

md_status_t em_gauss_ridge_ratio(size_t d, double w_a, const double *m_a, const double *c_a, double w_b,
                                 const double *m_b, const double *c_b, double *ratio)
{
    if ((ratio == NULL) || (m_a == NULL) || (c_a == NULL) || (m_b == NULL) || (c_b == NULL) || (d < 1u) ||
        (d > EM_D_MAX) || !(w_a > 0.0) || !(w_b > 0.0) || !isfinite(w_a) || !isfinite(w_b) ||
        !linalg_all_finite(m_a, d) || !linalg_all_finite(m_b, d)) {
        return MD_E_ARG;
    }
    *ratio = 0.0;
    ridge_comp_t ca;
    ridge_comp_t cb;
    if ((ridge_comp(d, w_a, c_a, &ca) != MD_OK) || (ridge_comp(d, w_b, c_b, &cb) != MD_OK)) {
        return MD_E_NUMERIC;
    }
    double logf[EM_RIDGE_POINTS];
    const double last = (double)EM_RIDGE_POINTS - 1.0;
    for (size_t k = 0u; k < EM_RIDGE_POINTS; ++k) {
        double x[EM_D_MAX];
        const double alpha = (double)k / last;
        if (ridge_point(&ca, m_a, &cb, m_b, d, alpha, x) != MD_OK) {
            return MD_E_NUMERIC;
        }
        logf[k] = log_add(ridge_log_density(&ca, m_a, x, d), ridge_log_density(&cb, m_b, x, d));
        if (!isfinite(logf[k])) {
            return MD_E_NUMERIC;
        }
    }
    *ratio = ridge_dip(logf);
    return MD_OK;
}

static bool ridge_args_ok(const em_params_t *p, size_t a, size_t b)
{
    return (p != NULL) && (p->d >= 1u) && (p->d <= EM_D_MAX) && (p->g <= EM_G_MAX) && (a >= 1u) && (b >= 1u) &&
           (a <= p->g) && (b <= p->g) && (a != b) && (p->lambda > 0.0) && isfinite(p->lambda);
}

md_status_t em_ridge_ratio(const em_params_t *p, size_t a, size_t b, double *ratio)
{
    if ((ratio == NULL) || !ridge_args_ok(p, a, b)) {
        return MD_E_ARG;
    }
    const size_t d = p->d;
    double ca[EM_D_MAX * EM_D_MAX];
    double cb[EM_D_MAX * EM_D_MAX];
    for (size_t i = 0u; i < d * d; ++i) {
        ca[i] = p->lambda * p->shape[a - 1u][i]; /* Σ_g = λ C_g */
        cb[i] = p->lambda * p->shape[b - 1u][i];
    }
    return em_gauss_ridge_ratio(d, p->pi[a - 1u], p->mean[a - 1u], ca, p->pi[b - 1u], p->mean[b - 1u], cb, ratio);
}

md_status_t em_params_oversplit(const em_params_t *p, double min_ratio, bool *oversplit)
{
    if ((oversplit == NULL) || (p == NULL) || !(min_ratio > 0.0) || !(min_ratio <= 1.0) || (p->g > EM_G_MAX)) {
        return MD_E_ARG;
    }
    *oversplit = false;
    for (size_t a = 1u; a <= p->g; ++a) {
        for (size_t b = a + 1u; b <= p->g; ++b) {
            double r = 0.0;
            const md_status_t s = em_ridge_ratio(p, a, b, &r);
            if (s != MD_OK) {
                *oversplit = false;
                return s;
            }
            if (r >= min_ratio) {
                *oversplit = true;
            }
        }
    }
    return MD_OK;
}

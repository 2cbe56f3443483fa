/// @file em.c
/// MAP-EM iteration of thesis §3.3.3 (see em.h).
#include "cluster/em.h"

#include <math.h>
#include <string.h>

#include "numeric/linalg.h"
#include "numeric/md_exp.h"

#define EM_PI0_INIT 0.05     /* initial outlier weight of a seed */
#define EM_LOG_TINY (-700.0) /* log of a weight that is numerically zero */

/* Per-component factors of Σ_g = λ C_g used by the E-step and eq. 3.15. */
typedef struct {
    double chol[EM_G_MAX][EM_D_MAX * EM_D_MAX];
    double linv[EM_G_MAX][EM_D_MAX * EM_D_MAX]; /* L^{-1}, lower triangular */
    double inv[EM_G_MAX][EM_D_MAX * EM_D_MAX];
    double logdet[EM_G_MAX];
    double log_norm[EM_G_MAX]; /* -½ (d log 2π + log det Σ_g) of eq. 3.1 */
} em_cache_t;

#define EM_LOG_2PI 1.8378770664093454836
#define EM_LN2 0.69314718055994530942
#define EM_LOG_BATCH 64u /* points per log of the E-step's product of normalisers */
_Static_assert(EM_G_MAX <= 8u, "EM_LOG_BATCH products of G + 1 <= 9 stay below 2^203");

/* L^{-1} of a lower-triangular L with positive diagonal (column by column forward substitution). */
static void em_tri_inverse(const double *l, size_t d, double *li)
{
    memset(li, 0, d * d * sizeof(double));
    for (size_t c = 0u; c < d; ++c) {
        li[c * d + c] = 1.0 / l[c * d + c];
        for (size_t r = c + 1u; r < d; ++r) {
            double s = 0.0;
            for (size_t q = c; q < r; ++q) {
                s += l[r * d + q] * li[q * d + c];
            }
            li[r * d + c] = -s / l[r * d + r];
        }
    }
}

/* (y - μ)^T Σ^{-1} (y - μ) = |L^{-1}(y - μ)|^2: multiplies only, no division per point. */
static double em_quad_tri(const double *li, size_t d, const double *y, const double *mu)
{
    double r[EM_D_MAX];
    for (size_t j = 0u; j < d; ++j) {
        r[j] = y[j] - mu[j];
    }
    double m2 = 0.0;
    for (size_t a = 0u; a < d; ++a) {
        double w = 0.0;
        for (size_t b = 0u; b <= a; ++b) {
            w += li[a * d + b] * r[b];
        }
        m2 += w * w;
    }
    return m2;
}

void em_options_default(em_options_t *opt)
{
    if (opt != NULL) {
        opt->max_iter = MD_EM_MAX_ITER;
        opt->tol = MD_EM_TOL_REL;
        opt->accelerate = true;
    }
}

static md_status_t em_fail(em_fit_t *out, md_status_t st, em_reason_t reason)
{
    out->status = st;
    out->reason = reason;
    if ((st != MD_OK) && (st != MD_E_NOCONVERGE)) {
        /* A failed fit has no likelihood: clear what the loop may have left
         * non-finite, so no NaN leaves em_fit (docs/fuzzing.md finding 4). */
        out->log_lik = 0.0;
        out->log_post = 0.0;
        memset(out->n_soft, 0, sizeof out->n_soft);
        memset(out->zeta, 0, sizeof out->zeta);
    }
    return st;
}

static double em_safe_log(double w)
{
    return (w > 0.0) ? fmax(log(w), EM_LOG_TINY) : EM_LOG_TINY;
}

/* Σ_g = L Lᵀ, log det Σ_g, L⁻¹ (the E-step's quadratic form) and Σ_g⁻¹ = L⁻ᵀ L⁻¹
 * (eq. 3.15's), one Cholesky factorisation per component. */
static md_status_t em_build_cache(const em_params_t *p, em_cache_t *c)
{
    const size_t d = p->d;
    for (size_t g = 0u; g < p->g; ++g) {
        for (size_t k = 0u; k < d * d; ++k) {
            c->chol[g][k] = p->lambda * p->shape[g][k];
        }
        if (linalg_cholesky(c->chol[g], d) != MD_OK) {
            return MD_E_NUMERIC;
        }
        c->logdet[g] = linalg_cholesky_logdet(c->chol[g], d);
        c->log_norm[g] = -0.5 * ((double)d * EM_LOG_2PI + c->logdet[g]);
        em_tri_inverse(c->chol[g], d, c->linv[g]);
        for (size_t a = 0u; a < d; ++a) {
            for (size_t b = a; b < d; ++b) {
                double s = 0.0;
                for (size_t r = b; r < d; ++r) { /* L⁻¹ is lower triangular: rows r ≥ max(a, b) */
                    s += c->linv[g][r * d + a] * c->linv[g][r * d + b];
                }
                c->inv[g][a * d + b] = s;
                c->inv[g][b * d + a] = s;
            }
        }
        if (!isfinite(c->logdet[g]) || !linalg_all_finite(c->inv[g], d * d)) {
            return MD_E_NUMERIC;
        }
    }
    return MD_OK;
}

/* Soft counts n_g and weighted sums Σ_i z_ig y_i of the M-step, accumulated in the same pass. */
typedef struct {
    double n_soft[EM_G_MAX + 1u];
    double sum[EM_G_MAX][EM_D_MAX];
} em_moments_t;

/* One point of the E-step: z_i· from the log-weights, its moments; returns the largest
 * log-term hi and sets *sum so that log p(y_i|Θ) = hi + log(*sum), *sum in [1, G + 1].
 * lw: log π_0, then log π_g - ½(d log 2π + log det Σ_g) for g ≥ 1.
 * Inline with a literal d = 2 below, so the d-loops unroll for the controller's case. */
static inline double em_estep_point(const double *y, size_t d, double lf0, const double *lw, const em_params_t *p,
                                    const em_cache_t *c, double *zi, em_moments_t *mom, double *sum_out)
{
    const size_t k = p->g + 1u;
    zi[0] = lw[0] + lf0;
    double hi = zi[0];
    for (size_t g = 0u; g < p->g; ++g) {
        /* eq. 3.1 */
        zi[g + 1u] = lw[g + 1u] - 0.5 * em_quad_tri(c->linv[g], d, y, p->mean[g]);
        hi = (zi[g + 1u] > hi) ? zi[g + 1u] : hi;
    }
    double sum = 0.0;
    for (size_t g = 0u; g < k; ++g) {
        zi[g] = md_exp(zi[g] - hi); /* the largest term is exactly 1: sum >= 1 */
        sum += zi[g];
    }
    const double inv = 1.0 / sum;
    zi[0] *= inv;
    mom->n_soft[0] += zi[0];
    for (size_t g = 1u; g < k; ++g) {
        zi[g] *= inv;
        mom->n_soft[g] += zi[g];
        for (size_t j = 0u; j < d; ++j) {
            mom->sum[g - 1u][j] += zi[g] * y[j];
        }
    }
    *sum_out = sum;
    return hi;
}

/* E-step: z_ig (after eq. 3.13) in the log domain; returns log p(Y|Θ) (eq. 3.5).
 * One log-sum-exp per point about its largest term (G + 1 exp per point, one log
 * per pass); the log-weights and Gaussian normalisers are taken once per iteration. */
static double em_estep(const em_data_t *data, const em_outlier_t *outlier, const em_params_t *p, const em_cache_t *c,
                       double *z, em_moments_t *mom)
{
    memset(mom, 0, sizeof *mom);
    const size_t k = p->g + 1u;
    double lw[EM_G_MAX + 1u]; /* per iteration, not per point */
    lw[0] = em_safe_log(p->pi0);
    for (size_t g = 0u; g < p->g; ++g) {
        lw[g + 1u] = em_safe_log(p->pi[g]) + c->log_norm[g];
    }
    const bool tab = (outlier->tab_y == data->y) && (outlier->tab_n == data->n);
    /* eq. 3.5 as Σ_i hi_i + log Π_i sum_i: one log per call, the product
     * renormalised by frexp every EM_LOG_BATCH points (sum_i ≤ G + 1 ≤ 9) */
    double hi_sum = 0.0;
    double prod = 1.0;
    int prod_exp = 0;
    for (size_t i = 0u; i < data->n; ++i) {
        const double *y = &data->y[i * data->d];
        const double lf0 = tab ? outlier->tab_log_f0[i] : em_outlier_logpdf(outlier, y);
        double sum = 1.0;
        hi_sum += (data->d == 2u) ? em_estep_point(y, 2u, lf0, lw, p, c, &z[i * k], mom, &sum)
                                  : em_estep_point(y, data->d, lf0, lw, p, c, &z[i * k], mom, &sum);
        prod *= sum;
        if ((i % EM_LOG_BATCH) == (EM_LOG_BATCH - 1u)) {
            int e = 0;
            prod = frexp(prod, &e);
            prod_exp += e;
        }
    }
    return hi_sum + (log(prod) + (double)prod_exp * EM_LN2);
}

/* eq. 3.15: MAP mean with Σ_g^{-1} of the previous iteration (Remark 3.6). */
static md_status_t em_map_mean(const em_prior_t *prior, const double *sigma_inv, double n_g, const double *sum,
                               const double *zeta, double *mean)
{
    const size_t d = prior->d;
    double a[EM_D_MAX * EM_D_MAX];
    double b[EM_D_MAX];
    for (size_t r = 0u; r < d; ++r) {
        b[r] = 0.0;
        for (size_t c = 0u; c < d; ++c) {
            a[r * d + c] = n_g * sigma_inv[r * d + c];
            b[r] += sigma_inv[r * d + c] * sum[c];
        }
    }
    for (size_t j = 0u; j < prior->n_targets; ++j) {
        const double w = zeta[j + 1u];
        for (size_t r = 0u; r < d; ++r) {
            for (size_t c = 0u; c < d; ++c) {
                a[r * d + c] += w * prior->s_inv[j][r * d + c];
                b[r] += w * prior->s_inv[j][r * d + c] * prior->mean[j][c];
            }
        }
    }
    if ((linalg_cholesky(a, d) != MD_OK) || (linalg_cholesky_solve(a, d, b) != MD_OK)) {
        return MD_E_NUMERIC;
    }
    memcpy(mean, b, d * sizeof(double));
    return MD_OK;
}

/* W_g = Σ_i z_ig (y_i - μ_g)(y_i - μ_g)^T for one component. */
static inline void em_scatter_d(const em_data_t *data, size_t d, const double *z, size_t k, size_t col,
                                const double *mean, double *w)
{
    memset(w, 0, d * d * sizeof(double));
    for (size_t i = 0u; i < data->n; ++i) {
        const double zi = z[i * k + col];
        double r[EM_D_MAX];
        for (size_t j = 0u; j < d; ++j) {
            r[j] = data->y[i * d + j] - mean[j];
        }
        for (size_t a = 0u; a < d; ++a) {
            const double zr = zi * r[a];
            for (size_t b = 0u; b <= a; ++b) {
                w[a * d + b] += zr * r[b];
            }
        }
    }
    for (size_t a = 0u; a < d; ++a) { /* symmetric: mirror the lower triangle */
        for (size_t b = a + 1u; b < d; ++b) {
            w[a * d + b] = w[b * d + a];
        }
    }
}

/* W_g with a literal d = 2 for the controller's case (the loops unroll). */
static void em_scatter(const em_data_t *data, const double *z, size_t k, size_t col, const double *mean, double *w)
{
    if (data->d == 2u) {
        em_scatter_d(data, 2u, z, k, col, mean, w);
    } else {
        em_scatter_d(data, data->d, z, k, col, mean, w);
    }
}

/* |W|^{1/d} with the collinearity rule of EM_SINGULAR_REL; 0 when rejected. */
static double em_det_root(const double *w, size_t d)
{
    double l[EM_D_MAX * EM_D_MAX];
    memcpy(l, w, d * d * sizeof(double));
    double tr = 0.0;
    for (size_t j = 0u; j < d; ++j) {
        tr += w[j * d + j];
    }
    if (!(tr > 0.0) || (linalg_cholesky(l, d) != MD_OK)) {
        return 0.0;
    }
    const double root = exp(linalg_cholesky_logdet(l, d) / (double)d);
    return (root >= pow(EM_SINGULAR_REL, 1.0 / (double)d) * tr / (double)d) ? root : 0.0;
}

/* §3.3.3.2 shared-volume covariance from the scatters W_g of the new means. */
static em_reason_t em_shared_volume(const em_data_t *data, const double *z, const double *n_soft, em_params_t *p)
{
    const size_t d = data->d;
    const size_t k = p->g + 1u;
    double roots = 0.0;
    double n_gauss = 0.0;
    for (size_t g = 0u; g < p->g; ++g) {
        double w[EM_D_MAX * EM_D_MAX];
        em_scatter(data, z, k, g + 1u, p->mean[g], w);
        const double root = em_det_root(w, d);
        if (!(root > 0.0)) {
            return EM_FAIL_SINGULAR_COV;
        }
        for (size_t e = 0u; e < d * d; ++e) {
            p->shape[g][e] = w[e] / root; /* C_g = W_g / |W_g|^{1/d}, det C_g = 1 */
        }
        roots += root;
        n_gauss += n_soft[g + 1u];
    }
    p->lambda = roots / n_gauss;
    return (isfinite(p->lambda) && (p->lambda > 0.0)) ? EM_OK : EM_FAIL_NUMERIC;
}

/* M-step of §3.3.3.2; zeta holds ζ at the current means, c the previous Σ. */
static em_reason_t em_mstep(const em_data_t *data, const em_prior_t *prior, const double *z, const em_moments_t *mom,
                            const em_cache_t *c, double zeta[][EM_J_MAX + 1u], em_params_t *p)
{
    const double *n_soft = mom->n_soft;
    const double n = (double)data->n;
    p->pi0 = n_soft[0] / n;
    for (size_t g = 0u; g < p->g; ++g) {
        if (n_soft[g + 1u] < EM_MIN_POINTS_PER_CLUSTER(data->d)) {
            return EM_FAIL_EMPTY_CLUSTER;
        }
        p->pi[g] = n_soft[g + 1u] / n;
        if (em_map_mean(prior, c->inv[g], n_soft[g + 1u], mom->sum[g], zeta[g], p->mean[g]) != MD_OK) {
            return EM_FAIL_NUMERIC;
        }
    }
    return em_shared_volume(data, z, n_soft, p);
}

/* Initial Θ from a hard partition: centroids, one pooled shape, π_0 = EM_PI0_INIT. */
static em_reason_t em_init_params(const em_data_t *data, const uint8_t *labels, size_t g_count, em_params_t *p)
{
    const size_t d = data->d;
    double count[EM_G_MAX] = {0.0};
    double sum[EM_G_MAX][EM_D_MAX];
    memset(sum, 0, sizeof sum);
    memset(p, 0, sizeof *p);
    p->d = d;
    p->g = g_count;
    for (size_t i = 0u; i < data->n; ++i) {
        if (labels[i] >= g_count) {
            return EM_FAIL_ARG;
        }
        count[labels[i]] += 1.0;
        for (size_t j = 0u; j < d; ++j) {
            sum[labels[i]][j] += data->y[i * d + j];
        }
    }
    for (size_t g = 0u; g < g_count; ++g) {
        if (!(count[g] > 0.0)) {
            return EM_FAIL_SEED;
        }
        p->pi[g] = (1.0 - EM_PI0_INIT) * count[g] / (double)data->n;
        for (size_t j = 0u; j < d; ++j) {
            p->mean[g][j] = sum[g][j] / count[g];
        }
    }
    p->pi0 = EM_PI0_INIT;
    double w[EM_D_MAX * EM_D_MAX] = {0.0};
    for (size_t i = 0u; i < data->n; ++i) {
        for (size_t a = 0u; a < d; ++a) {
            for (size_t b = 0u; b < d; ++b) {
                w[a * d + b] += (data->y[i * d + a] - p->mean[labels[i]][a]) *
                                (data->y[i * d + b] - p->mean[labels[i]][b]);
            }
        }
    }
    const double root = em_det_root(w, d);
    if (!(root > 0.0)) {
        return EM_FAIL_SINGULAR_COV;
    }
    for (size_t g = 0u; g < g_count; ++g) {
        for (size_t e = 0u; e < d * d; ++e) {
            p->shape[g][e] = w[e] / root;
        }
    }
    p->lambda = root / (double)data->n;
    return EM_OK;
}

static bool em_fit_args_ok(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior, size_t g,
                           const em_options_t *opt, const double *z)
{
    return (data != NULL) && (data->y != NULL) && (outlier != NULL) && (prior != NULL) && (opt != NULL) &&
           (z != NULL) && (data->d >= 1u) && (data->d <= EM_D_MAX) && (data->n <= EM_N_MAX) && (g >= 1u) &&
           (g <= EM_G_MAX) && (outlier->d == data->d) && (prior->d == data->d) && (opt->max_iter >= 1u) &&
           (opt->max_iter <= MD_EM_MAX_ITER) && (opt->tol > 0.0) && linalg_all_finite(data->y, data->n * data->d);
}

/* log-posterior of eq. 3.4 (without C) and ζ at the current means. */
static double em_log_post(const em_prior_t *prior, const em_params_t *p, double loglik, double zeta[][EM_J_MAX + 1u])
{
    double lp = loglik;
    for (size_t g = 0u; g < p->g; ++g) {
        lp += em_prior_log_mean(prior, p->mean[g], zeta[g]);
    }
    return lp;
}

/* Converged, or bounded out; n_g of the final z (the last E-step's moments). */
static md_status_t em_finish(const em_moments_t *mom, bool converged, em_fit_t *out)
{
    memcpy(out->n_soft, mom->n_soft, sizeof out->n_soft);
    if (!isfinite(out->log_post) || !isfinite(out->log_lik)) {
        return em_fail(out, MD_E_NUMERIC, EM_FAIL_NUMERIC);
    }
    return converged ? em_fail(out, MD_OK, EM_OK) : em_fail(out, MD_E_NOCONVERGE, EM_FAIL_NOCONVERGE);
}

/* ---- SQUAREM (Varadhan & Roland 2008, scheme S3) ---------------------------
 * EM converges linearly, slowly when components overlap. Two EM steps from
 * θ0 give r = θ1 - θ0 and v = θ2 - 2θ1 + θ0; the extrapolation
 * θ' = θ0 - 2αr + α²v, α = -|r|/|v|, is kept only if its log-posterior is not
 * below that of θ2 (MAP-EM's monotonicity), else EM goes on from θ2. Every
 * fit still ends on plain EM steps that meet the tolerance, so the fixed
 * point is that of eq. 3.13-3.15. The vector holds the means, the Cholesky
 * factors of Σ_g (log diagonal: they stay SPD) and log π_g: linear
 * extrapolation keeps the shared volume (equal log det Σ_g) to rounding. */
#define EM_SQ_TRI (EM_D_MAX * (EM_D_MAX + 1u) / 2u)
#define EM_SQ_VEC_MAX (EM_G_MAX * (EM_D_MAX + EM_SQ_TRI) + EM_G_MAX + 1u)
#define EM_SQ_ALPHA_MAX 64.0 /* bound on |α|: θ' stays in reach of the data */

static bool em_sq_pack(const em_params_t *p, double *v, size_t *len)
{
    const size_t d = p->d;
    size_t k = 0u;
    for (size_t g = 0u; g < p->g; ++g) {
        double l[EM_D_MAX * EM_D_MAX];
        for (size_t e = 0u; e < d * d; ++e) {
            l[e] = p->lambda * p->shape[g][e];
        }
        if (linalg_cholesky(l, d) != MD_OK) {
            return false;
        }
        for (size_t a = 0u; a < d; ++a) {
            v[k++] = p->mean[g][a];
            for (size_t b = 0u; b < a; ++b) {
                v[k++] = l[a * d + b];
            }
            v[k++] = log(l[a * d + a]);
        }
        v[k++] = em_safe_log(p->pi[g]);
    }
    v[k++] = em_safe_log(p->pi0);
    *len = k;
    return true;
}

/* Θ from a packed vector: Σ_g = L L^T, λ the geometric mean of |Σ_g|^{1/d}, π normalised. */
static bool em_sq_unpack(const double *v, em_params_t *p)
{
    const size_t d = p->d;
    const size_t stride = d + (d * (d + 1u)) / 2u + 1u;
    const double lw0 = v[p->g * stride];
    double hi = lw0;
    double log_lambda = 0.0;
    for (size_t g = 0u; g < p->g; ++g) {
        const double *q = &v[g * stride];
        double l[EM_D_MAX * EM_D_MAX] = {0.0};
        double logdet = 0.0;
        size_t k = 0u;
        for (size_t a = 0u; a < d; ++a) {
            p->mean[g][a] = q[k++];
            for (size_t b = 0u; b < a; ++b) {
                l[a * d + b] = q[k++];
            }
            logdet += 2.0 * q[k];
            l[a * d + a] = exp(q[k++]);
        }
        hi = fmax(hi, q[k]);
        const double root = exp(logdet / (double)d); /* |Σ_g|^{1/d} */
        for (size_t a = 0u; a < d; ++a) {
            for (size_t b = 0u; b < d; ++b) {
                double s = 0.0;
                for (size_t c = 0u; (c <= a) && (c <= b); ++c) {
                    s += l[a * d + c] * l[b * d + c];
                }
                p->shape[g][a * d + b] = s / root; /* det C_g = 1 */
            }
        }
        log_lambda += logdet / (double)d;
    }
    p->lambda = exp(log_lambda / (double)p->g);
    double sum = exp(lw0 - hi);
    for (size_t g = 0u; g < p->g; ++g) {
        sum += exp(v[g * stride + stride - 1u] - hi);
    }
    p->pi0 = exp(lw0 - hi) / sum;
    for (size_t g = 0u; g < p->g; ++g) {
        p->pi[g] = exp(v[g * stride + stride - 1u] - hi) / sum;
    }
    return (p->lambda > 0.0) && isfinite(p->lambda) &&
           linalg_all_finite(&p->mean[0][0], sizeof p->mean / sizeof p->mean[0][0]) &&
           linalg_all_finite(&p->shape[0][0], sizeof p->shape / sizeof p->shape[0][0]);
}

/* θ' of scheme S3 into t0 (which holds θ0); r holds θ1 - θ0; t2 is θ2. False when there is no step. */
static bool em_sq_extrapolate(double *t0, const double *r, const double *t2, size_t len)
{
    double rr = 0.0;
    double vv = 0.0;
    for (size_t k = 0u; k < len; ++k) {
        const double v = t2[k] - t0[k] - 2.0 * r[k]; /* θ2 - 2θ1 + θ0 */
        rr += r[k] * r[k];
        vv += v * v;
    }
    if (!(vv > 0.0) || !isfinite(rr) || !isfinite(vv)) {
        return false;
    }
    const double alpha = -fmin(sqrt(rr / vv), EM_SQ_ALPHA_MAX);
    if (!(alpha < -1.0)) {
        return false; /* α = -1 is θ2 itself */
    }
    for (size_t k = 0u; k < len; ++k) {
        const double v = t2[k] - t0[k] - 2.0 * r[k];
        t0[k] = t0[k] - 2.0 * alpha * r[k] + alpha * alpha * v;
    }
    return true;
}

/* Cache, E-step and log-posterior of eq. 3.4 at p; false if Σ_g is not SPD or a figure is not finite. */
static bool em_evaluate(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                        const em_params_t *p, em_cache_t *cache, double *z, em_moments_t *mom, em_fit_t *out)
{
    if (em_build_cache(p, cache) != MD_OK) {
        return false;
    }
    out->log_lik = em_estep(data, outlier, p, cache, z, mom);
    out->log_post = em_log_post(prior, p, out->log_lik, out->zeta);
    return isfinite(out->log_post);
}

/* Every Gaussian keeps the soft count the next M-step needs. */
static bool em_counts_ok(const em_moments_t *mom, size_t g, size_t d)
{
    for (size_t c = 1u; c <= g; ++c) {
        if (mom->n_soft[c] < EM_MIN_POINTS_PER_CLUSTER(d)) {
            return false;
        }
    }
    return true;
}

/* State of one fit: the current Θ lives in out->params, its E-step in z/mom/out. */
typedef struct {
    em_cache_t cache;
    em_moments_t mom;
    double t0[EM_SQ_VEC_MAX]; /* θ0, then θ' */
    double r[EM_SQ_VEC_MAX];  /* θ1 - θ0 */
    double t2[EM_SQ_VEC_MAX]; /* θ2 */
    em_params_t p2;           /* θ2 exactly, to go on from if θ' is rejected */
    uint32_t it;              /* M-steps taken */
    bool converged;
} em_run_t;

/* One M-step and the E-step at the new Θ; false ends the fit (converged, bound, failure in *r). */
static bool em_plain_step(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                          const em_options_t *opt, double *z, em_run_t *s, em_fit_t *out, em_reason_t *r)
{
    const double lp_prev = out->log_post;
    *r = em_mstep(data, prior, z, &s->mom, &s->cache, out->zeta, &out->params);
    if (*r != EM_OK) {
        return false;
    }
    s->it += 1u;
    out->iterations = s->it;
    if (!em_evaluate(data, outlier, prior, &out->params, &s->cache, z, &s->mom, out)) {
        *r = EM_FAIL_NUMERIC;
        return false;
    }
    s->converged = fabs(out->log_post - lp_prev) <= opt->tol * fmax(1.0, fabs(out->log_post));
    return !s->converged && (s->it < opt->max_iter);
}

/* Two EM steps and one S3 extrapolation, kept only if the log-posterior did not decrease. */
static bool em_squarem_cycle(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                             const em_options_t *opt, double *z, em_run_t *s, em_fit_t *out, em_reason_t *r)
{
    size_t len = 0u;
    const bool packed0 = em_sq_pack(&out->params, s->t0, &len);
    if (!em_plain_step(data, outlier, prior, opt, z, s, out, r)) {
        return false;
    }
    const bool packed1 = packed0 && em_sq_pack(&out->params, s->r, &len);
    if (!em_plain_step(data, outlier, prior, opt, z, s, out, r)) {
        return false;
    }
    if (!packed1 || !em_sq_pack(&out->params, s->t2, &len)) {
        return true;
    }
    for (size_t k = 0u; k < len; ++k) {
        s->r[k] -= s->t0[k];
    }
    if (!em_sq_extrapolate(s->t0, s->r, s->t2, len)) {
        return true;
    }
    const double lp2 = out->log_post;
    s->p2 = out->params;
    if (em_sq_unpack(s->t0, &out->params) &&
        em_evaluate(data, outlier, prior, &out->params, &s->cache, z, &s->mom, out) && (out->log_post >= lp2) &&
        em_counts_ok(&s->mom, out->params.g, data->d)) {
        return true;
    }
    out->params = s->p2; /* rejected: EM goes on from θ2 */
    if (!em_evaluate(data, outlier, prior, &out->params, &s->cache, z, &s->mom, out)) {
        *r = EM_FAIL_NUMERIC;
        return false;
    }
    return true;
}

/* EM (SQUAREM-accelerated) to convergence or the bound, from the hard partition seed_labels
 * into g groups, or (seed_labels NULL) from the Θ in out->params. One frame for the
 * initialisation and the iteration: the stack bound is the larger of the two, not the sum. */
static md_status_t em_run(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                          const em_options_t *opt, double *z, const uint8_t *seed_labels, size_t g, em_fit_t *out)
{
    em_reason_t r = (seed_labels != NULL) ? em_init_params(data, seed_labels, g, &out->params) : EM_OK;
    em_run_t s;
    memset(&s, 0, sizeof s);
    if ((r == EM_OK) && !em_evaluate(data, outlier, prior, &out->params, &s.cache, z, &s.mom, out)) {
        r = EM_FAIL_NUMERIC;
    }
    /* Each cycle takes at least one M-step, so max_iter cycles bound the fit. */
    for (uint32_t cyc = 0u; (r == EM_OK) && (cyc < opt->max_iter); ++cyc) {
        const bool more = opt->accelerate ? em_squarem_cycle(data, outlier, prior, opt, z, &s, out, &r)
                                          : em_plain_step(data, outlier, prior, opt, z, &s, out, &r);
        if (!more) {
            break;
        }
    }
    if (r != EM_OK) {
        md_status_t st = MD_E_DEGENERATE;
        if (r == EM_FAIL_NUMERIC) {
            st = MD_E_NUMERIC;
        } else if (r == EM_FAIL_ARG) {
            st = MD_E_ARG;
        } else {
            /* every other reason is a degenerate data set or seed */
        }
        return em_fail(out, st, r);
    }
    return em_finish(&s.mom, s.converged, out);
}

md_status_t em_fit(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                   const uint8_t *seed_labels, size_t g, const em_options_t *opt, double *z, em_fit_t *out)
{
    if (out == NULL) {
        return MD_E_ARG;
    }
    memset(out, 0, sizeof *out);
    if ((seed_labels == NULL) || !em_fit_args_ok(data, outlier, prior, g, opt, z)) {
        return em_fail(out, MD_E_ARG, EM_FAIL_ARG);
    }
    if ((double)data->n < (double)g * EM_MIN_POINTS_PER_CLUSTER(data->d)) {
        return em_fail(out, MD_E_DEGENERATE, EM_FAIL_TOO_FEW_POINTS);
    }
    return em_run(data, outlier, prior, opt, z, seed_labels, g, out);
}

/* A starting Θ that the iteration can take: finite, π in range, λ > 0. */
static bool em_start_ok(const em_params_t *p, size_t d)
{
    if ((p->d != d) || (p->g < 1u) || (p->g > EM_G_MAX) || !(p->lambda > 0.0) || !isfinite(p->lambda) ||
        !(p->pi0 >= 0.0) || !(p->pi0 <= 1.0)) {
        return false;
    }
    for (size_t g = 0u; g < p->g; ++g) {
        if (!(p->pi[g] > 0.0) || !(p->pi[g] <= 1.0) || !linalg_all_finite(p->mean[g], d) ||
            !linalg_all_finite(p->shape[g], d * d)) {
            return false;
        }
    }
    return true;
}

md_status_t em_fit_from(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                        const em_params_t *start, const em_options_t *opt, double *z, em_fit_t *out)
{
    if (out == NULL) {
        return MD_E_ARG;
    }
    memset(out, 0, sizeof *out);
    if ((start == NULL) || (data == NULL) || !em_start_ok(start, data->d) ||
        !em_fit_args_ok(data, outlier, prior, start->g, opt, z)) {
        return em_fail(out, MD_E_ARG, EM_FAIL_ARG);
    }
    if ((double)data->n < (double)start->g * EM_MIN_POINTS_PER_CLUSTER(data->d)) {
        return em_fail(out, MD_E_DEGENERATE, EM_FAIL_TOO_FEW_POINTS);
    }
    out->params = *start;
    return em_run(data, outlier, prior, opt, z, NULL, start->g, out);
}

void em_labels(const double *z, size_t n, size_t g, uint8_t *label)
{
    if ((z == NULL) || (label == NULL) || (g > EM_G_MAX)) {
        return;
    }
    for (size_t i = 0u; i < n; ++i) {
        size_t best = 0u;
        for (size_t c = 1u; c <= g; ++c) {
            if (z[i * (g + 1u) + c] > z[i * (g + 1u) + best]) {
                best = c;
            }
        }
        label[i] = (uint8_t)best;
    }
}

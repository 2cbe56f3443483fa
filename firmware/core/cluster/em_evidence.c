/// @file em_evidence.c
/// Laplace evidence with the analytic Hessian of thesis App. B (see em_evidence.h).
///
/// Notation: Φ_g = N(y | μ_g, Σ_g), P = Σ_m π_m f_m (eq. B.11), r = y - μ_g.
/// For any covariance parameter t of cluster g (an element of C_g or λ):
///   ∂log Φ/∂t   = -½ tr(Σ^{-1}Σ_t) + ½ r^T Σ^{-1}Σ_tΣ^{-1} r           (B.9, B.10)
///   ∂²log Φ/∂t∂s = ½ tr(Σ^{-1}Σ_sΣ^{-1}Σ_t) - ½ tr(Σ^{-1}Σ_ts)
///                 - r^T sym(Σ^{-1}Σ_sΣ^{-1}Σ_tΣ^{-1}) r + ½ r^T Σ^{-1}Σ_tsΣ^{-1} r
/// with Σ_t = λ ∂C/∂c (shape) or C (volume). Dividing eq. B.17 by P turns
/// every factor π_g Φ_g / P into the responsibility z_ig, so each point
/// contributes S_i - u_i u_i^T, u_i = ∇ l_i, S_i = ∇∇P / P (eq. B.17, B.18).
#include "cluster/em_evidence.h"

#include <math.h>
#include <string.h>

#include "cluster/em_evidence_d2.h"
#include "numeric/linalg.h"

#define EM_LOG_2PI 1.8378770664093454836
#define EM_LOG_TINY (-700.0)

/* C_g as a function of its free elements (eq. B.3 generalised: c_dd from det C = 1). */
typedef struct {
    double c[EM_D_MAX * EM_D_MAX];
    double dc[EM_NC_MAX + 1u][EM_D_MAX * EM_D_MAX]; /* ∂C/∂c_t */
    double f_ts[EM_NC_MAX + 1u][EM_NC_MAX + 1u];    /* ∂²c_dd/∂c_t∂c_s, the only entry of ∂²C */
} em_shape_t;

/* Per point and cluster: r, Σ^{-1} r, ∂log Φ/∂t, log Φ. */
typedef struct {
    double r[EM_D_MAX];
    double sr[EM_D_MAX];
    double dt[EM_P_MAX];
    double log_phi;
} em_point_t;

static size_t em_nc(size_t d)
{
    return (d * (d + 1u)) / 2u - 1u;
}

size_t em_param_count(size_t d, size_t g)
{
    return g * (1u + d + em_nc(d)) + 1u;
}

/* Row and column of free element t (upper triangle, row-major; c_dd is last). */
static void em_free_rc(size_t d, size_t t, size_t *row, size_t *col)
{
    size_t k = 0u;
    for (size_t i = 0u; i < d; ++i) {
        for (size_t j = i; j < d; ++j) {
            if (k == t) {
                *row = i;
                *col = j;
                return;
            }
            k++;
        }
    }
}

/* det C = c_dd · m + r: m (leading minor) and r (det with c_dd = 0) with
 * their gradients and Hessians in the free elements. */
static void em_shape_poly(size_t d, const double *x, double *mr, double g[2][EM_NC_MAX + 1u],
                          double h[2][EM_NC_MAX + 1u][EM_NC_MAX + 1u])
{
    memset(g, 0, 2u * sizeof g[0]);
    memset(h, 0, 2u * sizeof h[0]);
    if (d == 2u) { /* x = (c11, c12): m = c11, r = -c12^2 */
        mr[0] = x[0];
        mr[1] = -x[1] * x[1];
        g[0][0] = 1.0;
        g[1][1] = -2.0 * x[1];
        h[1][1][1] = -2.0;
        return;
    }
    /* d = 3, x = (c11, c12, c13, c22, c23) */
    mr[0] = x[0] * x[3] - x[1] * x[1];
    mr[1] = -x[0] * x[4] * x[4] + 2.0 * x[1] * x[2] * x[4] - x[3] * x[2] * x[2];
    g[0][0] = x[3];
    g[0][1] = -2.0 * x[1];
    g[0][3] = x[0];
    h[0][0][3] = 1.0;
    h[0][3][0] = h[0][0][3];
    h[0][1][1] = -2.0;
    g[1][0] = -x[4] * x[4];
    g[1][1] = 2.0 * x[2] * x[4];
    g[1][2] = 2.0 * x[1] * x[4] - 2.0 * x[3] * x[2];
    g[1][3] = -x[2] * x[2];
    g[1][4] = -2.0 * x[0] * x[4] + 2.0 * x[1] * x[2];
    h[1][0][4] = -2.0 * x[4];
    h[1][4][0] = h[1][0][4];
    h[1][1][2] = 2.0 * x[4];
    h[1][2][1] = h[1][1][2];
    h[1][1][4] = 2.0 * x[2];
    h[1][4][1] = h[1][1][4];
    h[1][2][2] = -2.0 * x[3];
    h[1][2][3] = -2.0 * x[2];
    h[1][3][2] = h[1][2][3];
    h[1][2][4] = 2.0 * x[1];
    h[1][4][2] = h[1][2][4];
    h[1][4][4] = -2.0 * x[0];
}

/* c_dd = (1 - r)/m and its derivatives by the quotient rule on f m = 1 - r. */
static md_status_t em_shape_last(size_t d, const double *x, em_shape_t *s, double *ft)
{
    const size_t nc = em_nc(d);
    double mr[2];
    double g[2][EM_NC_MAX + 1u];
    double h[2][EM_NC_MAX + 1u][EM_NC_MAX + 1u];
    em_shape_poly(d, x, mr, g, h);
    const double f = (1.0 - mr[1]) / mr[0];
    if (!(mr[0] > 0.0) || !(f > 0.0) || !isfinite(f)) {
        return MD_E_NUMERIC;
    }
    for (size_t t = 0u; t < nc; ++t) {
        ft[t] = (-g[1][t] - f * g[0][t]) / mr[0];
    }
    for (size_t t = 0u; t < nc; ++t) {
        for (size_t u = 0u; u < nc; ++u) {
            s->f_ts[t][u] = (-h[1][t][u] - ft[t] * g[0][u] - ft[u] * g[0][t] - f * h[0][t][u]) / mr[0];
        }
    }
    s->c[d * d - 1u] = f;
    return MD_OK;
}

static md_status_t em_shape_build(size_t d, const double *x, em_shape_t *s)
{
    memset(s, 0, sizeof *s);
    if (d == 1u) {
        s->c[0] = 1.0;
        return MD_OK;
    }
    const size_t nc = em_nc(d);
    double ft[EM_NC_MAX + 1u];
    if (em_shape_last(d, x, s, ft) != MD_OK) {
        return MD_E_NUMERIC;
    }
    for (size_t t = 0u; t < nc; ++t) {
        size_t i = 0u;
        size_t j = 0u;
        em_free_rc(d, t, &i, &j);
        s->c[i * d + j] = x[t];
        s->c[j * d + i] = s->c[i * d + j];
        s->dc[t][i * d + j] = 1.0;
        s->dc[t][j * d + i] = s->dc[t][i * d + j];
        s->dc[t][d * d - 1u] += ft[t];
    }
    double l[EM_D_MAX * EM_D_MAX];
    memcpy(l, s->c, sizeof l);
    return (linalg_cholesky(l, d) == MD_OK) ? MD_OK : MD_E_NUMERIC;
}

md_status_t em_theta_pack(const em_params_t *p, double *theta)
{
    if ((p == NULL) || (theta == NULL) || (p->d == 0u) || (p->d > EM_D_MAX) || (p->g == 0u) || (p->g > EM_G_MAX)) {
        return MD_E_ARG;
    }
    const size_t d = p->d;
    size_t k = 0u;
    for (size_t g = 0u; g < p->g; ++g) {
        theta[k++] = p->pi[g];
        for (size_t j = 0u; j < d; ++j) {
            theta[k++] = p->mean[g][j];
        }
        for (size_t t = 0u; t < em_nc(d); ++t) {
            size_t i = 0u;
            size_t j = 0u;
            em_free_rc(d, t, &i, &j);
            theta[k++] = p->shape[g][i * d + j];
        }
    }
    theta[k] = p->lambda;
    return MD_OK;
}

md_status_t em_theta_unpack(const double *theta, size_t d, size_t g, em_params_t *p)
{
    if ((theta == NULL) || (p == NULL) || (d == 0u) || (d > EM_D_MAX) || (g == 0u) || (g > EM_G_MAX) ||
        !linalg_all_finite(theta, em_param_count(d, g))) {
        return MD_E_ARG;
    }
    memset(p, 0, sizeof *p);
    p->d = d;
    p->g = g;
    p->pi0 = 1.0;
    size_t k = 0u;
    for (size_t c = 0u; c < g; ++c) {
        p->pi[c] = theta[k++];
        p->pi0 -= p->pi[c];
        memcpy(p->mean[c], &theta[k], d * sizeof(double));
        k += d;
        em_shape_t s;
        if (!(p->pi[c] > 0.0) || (em_shape_build(d, &theta[k], &s) != MD_OK)) {
            return MD_E_NUMERIC;
        }
        memcpy(p->shape[c], s.c, sizeof s.c);
        k += em_nc(d);
    }
    p->lambda = theta[k];
    return ((p->lambda > 0.0) && (p->pi0 >= 0.0)) ? MD_OK : MD_E_NUMERIC;
}

/* Σ_ts for covariance parameters t, s (index nc = λ). */
static void em_sigma_ts(const em_shape_t *sh, size_t d, double lambda, size_t t, size_t s, double *out)
{
    const size_t nc = em_nc(d);
    memset(out, 0, d * d * sizeof(double));
    if ((t < nc) && (s < nc)) {
        out[d * d - 1u] = lambda * sh->f_ts[t][s];
    } else if ((t < nc) || (s < nc)) {
        memcpy(out, sh->dc[(t < nc) ? t : s], d * d * sizeof(double));
    }
}

static double em_trace(const double *a, size_t d)
{
    double t = 0.0;
    for (size_t j = 0u; j < d; ++j) {
        t += a[j * d + j];
    }
    return t;
}

/* First-order tables: Σ, Σ^{-1}, N_t = Σ^{-1}Σ_tΣ^{-1}, tr(Σ^{-1}Σ_t). */
static md_status_t em_comp_first(const em_shape_t *sh, size_t d, double lambda, double sig_t[][EM_D_MAX * EM_D_MAX],
                                 em_comp_deriv_t *cd)
{
    const size_t np = em_nc(d) + 1u;
    double sigma[EM_D_MAX * EM_D_MAX];
    double work[EM_D_MAX * EM_D_MAX];
    for (size_t e = 0u; e < d * d; ++e) {
        sigma[e] = lambda * sh->c[e];
    }
    /* cppcheck-suppress uninitvar ; the loop above set the d x d elements copied */
    memcpy(cd->chol, sigma, d * d * sizeof sigma[0]); /* only the d x d part is set */
    if ((linalg_cholesky(cd->chol, d) != MD_OK) || (linalg_spd_inverse(sigma, d, cd->sigma_inv, work, NULL) != MD_OK)) {
        return MD_E_NUMERIC;
    }
    cd->logdet = linalg_cholesky_logdet(cd->chol, d);
    for (size_t t = 0u; t < np; ++t) {
        for (size_t e = 0u; e < d * d; ++e) {
            sig_t[t][e] = (t + 1u < np) ? lambda * sh->dc[t][e] : sh->c[e];
        }
        double m[EM_D_MAX * EM_D_MAX];
        if ((linalg_matmul(cd->sigma_inv, sig_t[t], m, d, d, d) != MD_OK) ||
            (linalg_matmul(m, cd->sigma_inv, cd->n_t[t], d, d, d) != MD_OK)) {
            return MD_E_ARG;
        }
        cd->tr_m[t] = em_trace(m, d);
    }
    return MD_OK;
}

/* Second-order tables k_ts, q_ts of ∂²log Φ/∂t∂s = k_ts + r^T q_ts r. */
static md_status_t em_comp_prepare(const em_params_t *p, size_t g, em_comp_deriv_t *cd)
{
    const size_t d = p->d;
    const size_t np = em_nc(d) + 1u;
    double x[EM_NC_MAX + 1u];
    for (size_t t = 0u; t + 1u < np; ++t) {
        size_t i = 0u;
        size_t j = 0u;
        em_free_rc(d, t, &i, &j);
        x[t] = p->shape[g][i * d + j];
    }
    em_shape_t sh;
    double sig_t[EM_P_MAX][EM_D_MAX * EM_D_MAX];
    if ((em_shape_build(d, x, &sh) != MD_OK) || (em_comp_first(&sh, d, p->lambda, sig_t, cd) != MD_OK)) {
        return MD_E_NUMERIC;
    }
    for (size_t t = 0u; t < np; ++t) {
        for (size_t s = 0u; s < np; ++s) {
            double sts[EM_D_MAX * EM_D_MAX];
            double a[EM_D_MAX * EM_D_MAX];
            double b[EM_D_MAX * EM_D_MAX];
            double m[EM_D_MAX * EM_D_MAX];
            em_sigma_ts(&sh, d, p->lambda, t, s, sts);
            if ((linalg_matmul(cd->n_t[s], sig_t[t], m, d, d, d) != MD_OK) || /* Σ^{-1}Σ_sΣ^{-1}Σ_t */
                (linalg_matmul(m, cd->sigma_inv, a, d, d, d) != MD_OK) ||     /* ... Σ^{-1} */
                (linalg_matmul(cd->sigma_inv, sts, b, d, d, d) != MD_OK)) {   /* Σ^{-1}Σ_ts */
                return MD_E_ARG;
            }
            cd->k_ts[t][s] = 0.5 * (em_trace(m, d) - em_trace(b, d));
            if (linalg_matmul(b, cd->sigma_inv, m, d, d, d) != MD_OK) { /* Σ^{-1}Σ_tsΣ^{-1} */
                return MD_E_ARG;
            }
            for (size_t r = 0u; r < d; ++r) {
                for (size_t c = 0u; c < d; ++c) {
                    cd->q_ts[t][s][r * d + c] = 0.5 * m[r * d + c] - 0.5 * (a[r * d + c] + a[c * d + r]);
                }
            }
        }
    }
    return MD_OK;
}

static inline double em_quad(const double *a, const double *r, size_t d)
{
    double q = 0.0;
    for (size_t i = 0u; i < d; ++i) {
        for (size_t j = 0u; j < d; ++j) {
            q += r[i] * a[i * d + j] * r[j];
        }
    }
    return q;
}

static inline void em_point_terms(const em_params_t *p, size_t d, const em_comp_deriv_t *cd, const double *y,
                                  em_point_t *pt)
{
    for (size_t g = 0u; g < p->g; ++g) {
        for (size_t j = 0u; j < d; ++j) {
            pt[g].r[j] = y[j] - p->mean[g][j];
        }
        double m2 = 0.0;
        for (size_t j = 0u; j < d; ++j) {
            pt[g].sr[j] = 0.0;
            for (size_t k = 0u; k < d; ++k) {
                pt[g].sr[j] += cd[g].sigma_inv[j * d + k] * pt[g].r[k];
            }
            m2 += pt[g].r[j] * pt[g].sr[j];
        }
        pt[g].log_phi = -0.5 * ((double)d * EM_LOG_2PI + cd[g].logdet + m2); /* eq. 3.1 */
        for (size_t t = 0u; t <= em_nc(d); ++t) {
            pt[g].dt[t] = -0.5 * cd[g].tr_m[t] + 0.5 * em_quad(cd[g].n_t[t], pt[g].r, d);
        }
    }
}

/* Index of covariance parameter t of cluster g in Θ (t = nc is the shared λ). */
static size_t em_cov_index(size_t d, size_t g_count, size_t g, size_t t)
{
    const size_t nc = em_nc(d);
    return (t < nc) ? (g * (1u + d + nc) + 1u + d + t) : (em_param_count(d, g_count) - 1u);
}

static void em_sym_add(double *h, size_t eta, size_t a, size_t b, double v)
{
    h[a * eta + b] += v;
    if (a != b) {
        h[b * eta + a] += v;
    }
}

/* S_i = ∇∇P / P for one cluster (eq. B.18 last term and B.2.2), a = Φ/P, q = πΦ/P.
 * Only the upper triangle of H is meant (the symmetric blocks are summed for
 * column ≥ row; em_log_post_derivs mirrors it once after the point loop). */
static inline void em_point_curvature(const em_params_t *p, size_t d, const em_comp_deriv_t *cd, const em_point_t *pt,
                                      size_t g, double a, double q, double *h)
{
    const size_t np = em_nc(d) + 1u;
    const size_t eta = em_param_count(d, p->g);
    const size_t ip = g * (1u + d + np - 1u);
    for (size_t j = 0u; j < d; ++j) {
        em_sym_add(h, eta, ip, ip + 1u + j, a * pt->sr[j]); /* means – weights */
        for (size_t k = j; k < d; ++k) {                    /* means – means (upper) */
            h[(ip + 1u + j) * eta + ip + 1u + k] += q * (pt->sr[j] * pt->sr[k] - cd->sigma_inv[j * d + k]);
        }
        for (size_t t = 0u; t < np; ++t) { /* means – (co)variances, volume */
            double ntr = 0.0;
            for (size_t k = 0u; k < d; ++k) {
                ntr += cd->n_t[t][j * d + k] * pt->r[k];
            }
            em_sym_add(h, eta, ip + 1u + j, em_cov_index(d, p->g, g, t), q * (pt->sr[j] * pt->dt[t] - ntr));
        }
    }
    for (size_t t = 0u; t < np; ++t) {
        const size_t it = em_cov_index(d, p->g, g, t);
        em_sym_add(h, eta, ip, it, a * pt->dt[t]); /* (co)variances, volume – weights */
        for (size_t s = t; s < np; ++s) {          /* (co)variances, volume pairs (upper) */
            h[it * eta + em_cov_index(d, p->g, g, s)] += q * (pt->dt[t] * pt->dt[s] + cd->k_ts[t][s] +
                                                              em_quad(cd->q_ts[t][s], pt->r, d));
        }
    }
}

/* u = ∇ l_i (App. B.2.1 divided by P). Returns l_i = log P. */
static inline double em_point_gradient(const em_params_t *p, size_t d, double lf0, const double *log_pi,
                                       const em_point_t *pt, double *u, double *a, double *q)
{
    const size_t np = em_nc(d) + 1u;
    const size_t eta = em_param_count(d, p->g);
    /* One log-sum-exp about the largest term: G + 1 exp and one log per point;
     * Φ_g/P = w_g / (s π_g) with π_g > 0 (checked by em_log_post_derivs). */
    double w[EM_G_MAX + 1u];
    w[0] = log_pi[0] + lf0;
    double hi = w[0];
    for (size_t g = 0u; g < p->g; ++g) {
        w[g + 1u] = log_pi[g + 1u] + pt[g].log_phi;
        hi = (w[g + 1u] > hi) ? w[g + 1u] : hi;
    }
    double sum = 0.0;
    for (size_t g = 0u; g <= p->g; ++g) {
        w[g] = exp(w[g] - hi); /* the largest is exactly 1: sum >= 1 */
        sum += w[g];
    }
    const double lp = hi + log(sum);
    const double b = exp(lf0 - lp); /* f0/P; π_0 may be 0, so not from w_0 */
    memset(u, 0, eta * sizeof(double));
    for (size_t g = 0u; g < p->g; ++g) {
        const size_t ip = g * (1u + d + np - 1u);
        a[g] = w[g + 1u] / (sum * p->pi[g]);
        q[g] = p->pi[g] * a[g];
        u[ip] = a[g] - b;
        for (size_t j = 0u; j < d; ++j) {
            u[ip + 1u + j] = q[g] * pt[g].sr[j];
        }
        for (size_t t = 0u; t < np; ++t) {
            u[em_cov_index(d, p->g, g, t)] += q[g] * pt[g].dt[t];
        }
    }
    return lp;
}

/* log p(μ) of eq. 3.8 with gradient and Hessian (App. B.3). */
static double em_prior_derivs(const em_prior_t *prior, const double *mu, double *grad, double *hess)
{
    const size_t d = prior->d;
    double zeta[EM_J_MAX + 1u];
    const double lp = em_prior_log_mean(prior, mu, zeta);
    double e[EM_J_MAX][EM_D_MAX]; /* S_j^{-1} (μ - μ̂_j) */
    memset(grad, 0, d * sizeof(double));
    memset(hess, 0, d * d * sizeof(double));
    for (size_t j = 0u; j < prior->n_targets; ++j) {
        for (size_t r = 0u; r < d; ++r) {
            e[j][r] = 0.0;
            for (size_t c = 0u; c < d; ++c) {
                e[j][r] += prior->s_inv[j][r * d + c] * (mu[c] - prior->mean[j][c]);
            }
            grad[r] -= zeta[j + 1u] * e[j][r];
        }
    }
    for (size_t j = 0u; j < prior->n_targets; ++j) {
        for (size_t r = 0u; r < d; ++r) {
            for (size_t c = 0u; c < d; ++c) {
                hess[r * d + c] += zeta[j + 1u] * (e[j][r] * e[j][c] - prior->s_inv[j][r * d + c]);
            }
        }
    }
    for (size_t r = 0u; r < d; ++r) {
        for (size_t c = 0u; c < d; ++c) {
            hess[r * d + c] -= grad[r] * grad[c];
        }
    }
    return lp;
}

static double em_add_prior(const em_prior_t *prior, const em_params_t *p, double *grad, double *hess)
{
    const size_t d = p->d;
    const size_t eta = em_param_count(d, p->g);
    double lp = 0.0;
    for (size_t g = 0u; g < p->g; ++g) {
        double gm[EM_D_MAX];
        double hm[EM_D_MAX * EM_D_MAX];
        const size_t im = g * (1u + d + em_nc(d)) + 1u;
        lp += em_prior_derivs(prior, p->mean[g], gm, hm);
        for (size_t r = 0u; r < d; ++r) {
            if (grad != NULL) {
                grad[im + r] += gm[r];
            }
            for (size_t c = 0u; (hess != NULL) && (c < d); ++c) {
                hess[(im + r) * eta + im + c] += hm[r * d + c];
            }
        }
    }
    return lp;
}

static bool em_data_args_ok(const em_data_t *data, const em_outlier_t *outlier, const em_params_t *p,
                            const em_evidence_work_t *ws)
{
    return (data != NULL) && (data->y != NULL) && (outlier != NULL) && (p != NULL) && (ws != NULL) &&
           (p->d == data->d) && (p->d >= 1u) && (p->d <= EM_D_MAX) && (p->g >= 1u) && (p->g <= EM_G_MAX) &&
           (data->n <= EM_N_MAX) && (outlier->d == p->d) && (p->lambda > 0.0);
}

static bool em_derivs_args_ok(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                              const em_params_t *p, const em_evidence_work_t *ws)
{
    return em_data_args_ok(data, outlier, p, ws) && (prior != NULL) && (prior->d == p->d);
}

/* One point's l_i, its gradient u and its Hessian terms (eq. B.17, B.18), added to grad/hess.
 * The general-d loop (d = 2 with a Hessian takes em_d2_points). */
static double em_point_add(const em_params_t *p, size_t d, double lf0, const double *log_pi, const double *y,
                           double *grad, double *hess, em_evidence_work_t *ws)
{
    const size_t eta = em_param_count(d, p->g);
    em_point_t pt[EM_G_MAX];
    double a[EM_G_MAX];
    double q[EM_G_MAX];
    em_point_terms(p, d, ws->comp, y, pt);
    const double li = em_point_gradient(p, d, lf0, log_pi, pt, ws->u, a, q);
    if (grad != NULL) {
        for (size_t k = 0u; k < eta; ++k) {
            grad[k] += ws->u[k];
        }
    }
    if (hess != NULL) {
        for (size_t g = 0u; g < p->g; ++g) {
            em_point_curvature(p, d, &ws->comp[g], &pt[g], g, a[g], q[g], hess);
        }
        for (size_t r = 0u; r < eta; ++r) { /* upper triangle; em_data_derivs mirrors it */
            const double ur = ws->u[r];
            for (size_t c = r; c < eta; ++c) {
                hess[r * eta + c] -= ur * ws->u[c]; /* eq. B.17 first term */
            }
        }
    }
    return li;
}

/* Σ_i l_i and optionally Σ_i ∇ l_i, Σ_i ∇∇ l_i (full, mirrored): the data part of eq. B.1. */
static md_status_t em_data_derivs(const em_data_t *data, const em_outlier_t *outlier, const em_params_t *p,
                                  double *log_lik, double *grad, double *hess, em_evidence_work_t *ws)
{
    const size_t eta = em_param_count(p->d, p->g);
    for (size_t g = 0u; g < p->g; ++g) {
        if (!(p->pi[g] > 0.0) || (em_comp_prepare(p, g, &ws->comp[g]) != MD_OK)) {
            return MD_E_NUMERIC;
        }
    }
    /* the d = 2 pass always sums the gradient; ws->u is free then */
    double *gsum = ((grad == NULL) && (hess != NULL) && (p->d == 2u)) ? ws->u : grad;
    if (gsum != NULL) {
        memset(gsum, 0, eta * sizeof(double));
    }
    if (hess != NULL) {
        memset(hess, 0, eta * eta * sizeof(double));
    }
    double log_pi[EM_G_MAX + 1u]; /* per model, not per point */
    log_pi[0] = (p->pi0 > 0.0) ? fmax(log(p->pi0), EM_LOG_TINY) : EM_LOG_TINY;
    for (size_t g = 0u; g < p->g; ++g) {
        log_pi[g + 1u] = log(p->pi[g]);
    }
    double ll = 0.0;
    if ((p->d == 2u) && (hess != NULL)) {
        ll = em_d2_points(data, outlier, p, log_pi, ws, gsum, hess);
    } else {
        const bool tab = (outlier->tab_y == data->y) && (outlier->tab_n == data->n);
        for (size_t i = 0u; i < data->n; ++i) {
            const double *y = &data->y[i * p->d];
            const double lf0 = tab ? outlier->tab_log_f0[i] : em_outlier_logpdf(outlier, y);
            ll += em_point_add(p, p->d, lf0, log_pi, y, gsum, hess, ws);
        }
    }
    if (hess != NULL) { /* the per-point terms are symmetric: the lower triangle is the upper one */
        for (size_t r = 1u; r < eta; ++r) {
            for (size_t c = 0u; c < r; ++c) {
                hess[r * eta + c] = hess[c * eta + r];
            }
        }
    }
    *log_lik = ll;
    const bool ok = isfinite(ll) && ((grad == NULL) || linalg_all_finite(grad, eta)) &&
                    ((hess == NULL) || linalg_all_finite(hess, eta * eta));
    return ok ? MD_OK : MD_E_NUMERIC;
}

md_status_t em_log_post_derivs(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                               const em_params_t *p, double *log_post, double *grad, double *hess,
                               em_evidence_work_t *ws)
{
    if (!em_derivs_args_ok(data, outlier, prior, p, ws) || (log_post == NULL)) {
        return MD_E_ARG;
    }
    double ll = 0.0;
    const md_status_t st = em_data_derivs(data, outlier, p, &ll, grad, hess, ws);
    if (st != MD_OK) {
        return st;
    }
    const size_t eta = em_param_count(p->d, p->g);
    const double lp = ll + em_add_prior(prior, p, grad, hess);
    *log_post = lp;
    const bool ok = isfinite(lp) && ((grad == NULL) || linalg_all_finite(grad, eta)) &&
                    ((hess == NULL) || linalg_all_finite(hess, eta * eta));
    return ok ? MD_OK : MD_E_NUMERIC;
}

double em_param_prior_log_const(size_t d, size_t g, double shape_prior_width)
{
    double log_gfact = 0.0; /* uniform density on the G-simplex of (π_0..π_G) is G! */
    for (size_t k = 2u; k <= g; ++k) {
        log_gfact += log((double)k);
    }
    return log_gfact - (double)(g * em_nc(d)) * log(shape_prior_width);
}

/* Old index of reduced coordinate a when π_G (index ig) is eliminated. */
static size_t em_old_index(size_t a, size_t ig)
{
    return (a < ig) ? a : a + 1u;
}

/* Entry (a, b) of the log-posterior Hessian: the data part plus, in the
 * mean block of one cluster, ∇∇ log p(μ_g) (eq. B.21-B.23). */
static double em_h_entry(const em_evidence_work_t *ws, size_t eta, const em_params_t *p, size_t a, size_t b)
{
    const size_t d = p->d;
    const size_t blk = 1u + d + em_nc(d);
    double v = ws->hess[a * eta + b];
    const size_t ga = a / blk;
    if ((a + 1u < eta) && (b + 1u < eta) && (ga == b / blk)) {
        const size_t ia = a % blk;
        const size_t ib = b % blk;
        if ((ia >= 1u) && (ia <= d) && (ib >= 1u) && (ib <= d)) {
            v += ws->prior_h[ga][(ia - 1u) * d + (ib - 1u)];
        }
    }
    return v;
}

/* H' = J^T H J for θ = J q: π_G = -Σ_{g<G} π_g (+ const), other coordinates kept. */
static double em_reduced_entry(const em_evidence_work_t *ws, size_t eta, const em_params_t *p, size_t ig, size_t a,
                               size_t b)
{
    const size_t blk = em_param_count(p->d, p->g) / p->g;
    const size_t oa = em_old_index(a, ig);
    const size_t ob = em_old_index(b, ig);
    const bool pa = (oa < ig) && ((oa % blk) == 0u);
    const bool pb = (ob < ig) && ((ob % blk) == 0u);
    double v = em_h_entry(ws, eta, p, oa, ob);
    v -= pa ? em_h_entry(ws, eta, p, ig, ob) : 0.0;
    v -= pb ? em_h_entry(ws, eta, p, oa, ig) : 0.0;
    v += (pa && pb) ? em_h_entry(ws, eta, p, ig, ig) : 0.0;
    return v;
}

/* log det of the SPD matrix -H (or of its reduced form when ig < eta), via
 * diagonal scaling so the Cholesky pivot test is unit-free. */
static md_status_t em_neg_logdet(em_evidence_work_t *ws, size_t eta, const em_params_t *p, size_t ig, double *logdet)
{
    const size_t m = (ig < eta) ? eta - 1u : eta;
    double log_diag = 0.0;
    for (size_t k = 0u; k < m; ++k) {
        const double hkk = -((ig < eta) ? em_reduced_entry(ws, eta, p, ig, k, k) : em_h_entry(ws, eta, p, k, k));
        if (!(hkk > 0.0)) {
            return MD_E_NUMERIC;
        }
        ws->u[k] = 1.0 / sqrt(hkk);
        log_diag += log(hkk);
    }
    for (size_t r = 0u; r < m; ++r) {
        for (size_t c = 0u; c < m; ++c) {
            const double h = (ig < eta) ? em_reduced_entry(ws, eta, p, ig, r, c) : em_h_entry(ws, eta, p, r, c);
            ws->scaled[r * m + c] = -h * ws->u[r] * ws->u[c];
        }
    }
    if (linalg_cholesky(ws->scaled, m) != MD_OK) {
        return MD_E_NUMERIC;
    }
    *logdet = linalg_cholesky_logdet(ws->scaled, m) + log_diag;
    return MD_OK;
}

md_status_t em_evidence_data(const em_data_t *data, const em_outlier_t *outlier, const em_params_t *p,
                             em_evidence_work_t *ws)
{
    if (!em_data_args_ok(data, outlier, p, ws)) {
        return MD_E_ARG;
    }
    ws->data_d = 0u;
    ws->data_g = 0u;
    const md_status_t st = em_data_derivs(data, outlier, p, &ws->data_ll, ws->grad, ws->hess, ws);
    if (st == MD_OK) {
        ws->data_d = p->d;
        ws->data_g = p->g;
    }
    return st;
}

md_status_t em_evidence_finish(const em_prior_t *prior, const em_params_t *p, double shape_prior_width,
                               em_evidence_work_t *ws, double *log_evidence)
{
    if ((prior == NULL) || (p == NULL) || (ws == NULL) || (log_evidence == NULL) || !(shape_prior_width > 0.0) ||
        (p->d == 0u) || (p->d != ws->data_d) || (p->g != ws->data_g) || (prior->d != p->d)) {
        return MD_E_ARG;
    }
    double lp = ws->data_ll;
    for (size_t g = 0u; g < p->g; ++g) {
        double gm[EM_D_MAX];
        lp += em_prior_derivs(prior, p->mean[g], gm, ws->prior_h[g]);
    }
    const size_t eta = em_param_count(p->d, p->g);
    if (!isfinite(lp) || !linalg_all_finite(&ws->prior_h[0][0], p->g * EM_D_MAX * EM_D_MAX)) {
        return MD_E_NUMERIC;
    }
    /* H = -∇∇ log posterior (eq. B.1, B.4); boundary rule of em_evidence.h for π_0
     * (the prior has no π terms, so slope and curvature are the data part's) */
    const size_t ig = (p->g - 1u) * (eta / p->g);
    const double slope = ws->grad[ig];
    const double curv = -ws->hess[ig * eta + ig];
    const bool boundary = (curv > 0.0) && (slope > sqrt(curv));
    double logdet_h = 0.0;
    if (em_neg_logdet(ws, eta, p, boundary ? ig : eta, &logdet_h) != MD_OK) {
        return MD_E_NUMERIC;
    }
    const size_t dims = boundary ? eta - 1u : eta;
    *log_evidence = lp + em_param_prior_log_const(p->d, p->g, shape_prior_width) + 0.5 * (double)dims * EM_LOG_2PI -
                    0.5 * logdet_h - (boundary ? log(slope) : 0.0); /* eq. 3.18 */
    return isfinite(*log_evidence) ? MD_OK : MD_E_NUMERIC;
}

md_status_t em_evidence_laplace(const em_data_t *data, const em_outlier_t *outlier, const em_prior_t *prior,
                                const em_params_t *p, double shape_prior_width, em_evidence_work_t *ws,
                                double *log_evidence)
{
    if ((log_evidence == NULL) || !(shape_prior_width > 0.0) || !em_derivs_args_ok(data, outlier, prior, p, ws)) {
        return MD_E_ARG;
    }
    const md_status_t st = em_evidence_data(data, outlier, p, ws);
    return (st == MD_OK) ? em_evidence_finish(prior, p, shape_prior_width, ws, log_evidence) : st;
}

double em_evidence_bic(double log_lik, size_t d, size_t g, size_t n)
{
    const double nn = (n > 0u) ? (double)n : 1.0;
    return log_lik - 0.5 * (double)em_param_count(d, g) * log(nn); /* footnote 11, halved */
}

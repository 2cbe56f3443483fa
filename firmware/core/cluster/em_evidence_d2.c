/// @file em_evidence_d2.c
/// Per-point Hessian pass of the Laplace evidence for d = 2 (see em_evidence_d2.h).
///
/// Parameters of cluster g in a 6-slot local block: 0 π_g, 1-2 μ_g,
/// 3 c_11, 4 c_12 (the free elements of C_g, eq. B.3), 5 the shared λ.
/// Covariance parameter t = 0, 1, 2 is slot 3 + t.
#include "cluster/em_evidence_d2.h"

#include <math.h>
#include <string.h>

#include "numeric/md_exp.h"

#define D2_SLOTS 6u
#define D2_UPPER 21u /* entries of a 6 × 6 upper triangle */
#define D2_NP 3u     /* covariance parameters: c_11, c_12, λ */
#define D2_PAIRS 6u  /* (t, s), s ≥ t, of the covariance parameters */
#define D2_LOG_2PI 1.8378770664093454836
#define D2_LN2 0.69314718055994530942
#define D2_OUTER_BATCH 4u /* point gradients folded into H per pass over it */
#define D2_LOG_BATCH 64u  /* points per renormalisation of the product of normalisers (each ≤ G + 1 ≤ 9) */

_Static_assert(EM_D_MAX >= 2u, "the d = 2 pass needs room for 2-D points");

/* Packed index of (i, j), i ≤ j, in a 6 × 6 upper triangle. */
static const uint8_t D2_UP[D2_SLOTS][D2_SLOTS] = {{0u, 1u, 2u, 3u, 4u, 5u},     {0u, 6u, 7u, 8u, 9u, 10u},
                                                  {0u, 0u, 11u, 12u, 13u, 14u}, {0u, 0u, 0u, 15u, 16u, 17u},
                                                  {0u, 0u, 0u, 0u, 18u, 19u},   {0u, 0u, 0u, 0u, 0u, 20u}};
static const uint8_t D2_PAIR_T[D2_PAIRS] = {0u, 0u, 0u, 1u, 1u, 2u};
static const uint8_t D2_PAIR_S[D2_PAIRS] = {0u, 1u, 2u, 1u, 2u, 2u};

/* A symmetric 2 × 2 form a as three coefficients of (r0², r0 r1, r1²). */
static void d2_quad_of(const double *a, double *q)
{
    q[0] = a[0];
    q[1] = a[1] + a[2];
    q[2] = a[3];
}

static double d2_quad(const double *q, const double *rr)
{
    return (q[0] * rr[0] + q[1] * rr[1]) + q[2] * rr[2];
}

static void d2_prepare(const em_params_t *p, const em_comp_deriv_t *cd, const double *log_pi, em_d2_comp_t *k)
{
    for (size_t g = 0u; g < p->g; ++g) {
        const em_comp_deriv_t *c = &cd[g];
        em_d2_comp_t *o = &k[g];
        memcpy(o->si, c->sigma_inv, sizeof o->si);
        o->cst = log_pi[g + 1u] - 0.5 * (2.0 * D2_LOG_2PI + c->logdet);
        o->pi = p->pi[g];
        for (size_t t = 0u; t < D2_NP; ++t) {
            const double half[4] = {0.5 * c->n_t[t][0], 0.5 * c->n_t[t][1], 0.5 * c->n_t[t][2], 0.5 * c->n_t[t][3]};
            o->half_tr[t] = -0.5 * c->tr_m[t];
            d2_quad_of(half, o->half_n[t]);
            memcpy(o->n_t[t], c->n_t[t], sizeof o->n_t[t]);
        }
        for (size_t q = 0u; q < D2_PAIRS; ++q) {
            o->k_ts[q] = c->k_ts[D2_PAIR_T[q]][D2_PAIR_S[q]];
            d2_quad_of(c->q_ts[D2_PAIR_T[q]][D2_PAIR_S[q]], o->q_ts[q]);
        }
    }
}

/* Per point and cluster: r, Σ⁻¹ r, ∂log Φ/∂t, (N_t r), r r^T, and the exponent of π_g Φ_g. */
typedef struct {
    double sr[2];
    double dt[D2_NP];
    double ntr[D2_NP][2];
    double rr[3];
    double w;
} d2_point_t;

static void d2_point(const em_d2_comp_t *k, const double *mean, const double *y, d2_point_t *o)
{
    const double r0 = y[0] - mean[0];
    const double r1 = y[1] - mean[1];
    o->sr[0] = k->si[0] * r0 + k->si[1] * r1;
    o->sr[1] = k->si[2] * r0 + k->si[3] * r1;
    o->rr[0] = r0 * r0;
    o->rr[1] = r0 * r1;
    o->rr[2] = r1 * r1;
    o->w = k->cst - 0.5 * (r0 * o->sr[0] + r1 * o->sr[1]); /* eq. 3.1 plus log π_g */
    for (size_t t = 0u; t < D2_NP; ++t) {
        o->dt[t] = k->half_tr[t] + d2_quad(k->half_n[t], o->rr); /* eq. B.9, B.10 */
        o->ntr[t][0] = k->n_t[t][0] * r0 + k->n_t[t][1] * r1;
        o->ntr[t][1] = k->n_t[t][2] * r0 + k->n_t[t][3] * r1;
    }
}

/* S_i of one cluster (eq. B.18 and App. B.2.2) into its block; a = Φ/P, q = πΦ/P. */
static void d2_curvature(const em_d2_comp_t *k, const d2_point_t *pt, double a, double q, double *blk)
{
    blk[D2_UP[0][1]] += a * pt->sr[0]; /* weight – means */
    blk[D2_UP[0][2]] += a * pt->sr[1];
    blk[D2_UP[1][1]] += q * (pt->sr[0] * pt->sr[0] - k->si[0]); /* means – means */
    blk[D2_UP[1][2]] += q * (pt->sr[0] * pt->sr[1] - k->si[1]);
    blk[D2_UP[2][2]] += q * (pt->sr[1] * pt->sr[1] - k->si[3]);
    for (size_t t = 0u; t < D2_NP; ++t) {
        blk[D2_UP[0][3u + t]] += a * pt->dt[t]; /* weight – (co)variances, volume */
        blk[D2_UP[1][3u + t]] += q * (pt->sr[0] * pt->dt[t] - pt->ntr[t][0]);
        blk[D2_UP[2][3u + t]] += q * (pt->sr[1] * pt->dt[t] - pt->ntr[t][1]);
    }
    for (size_t m = 0u; m < D2_PAIRS; ++m) {
        const size_t t = D2_PAIR_T[m];
        const size_t s = D2_PAIR_S[m];
        blk[D2_UP[3u + t][3u + s]] += q * (pt->dt[t] * pt->dt[s] + k->k_ts[m] + d2_quad(k->q_ts[m], pt->rr));
    }
}

/* One point: u_i into u (length eta), curvature into the blocks; returns the largest
 * log-term hi, and *sum_out such that l_i = hi + log(*sum_out). */
static double d2_one_point(const em_params_t *p, const em_d2_comp_t *k, const double *y, double lf0, double log_pi0,
                           double *u, double blk[][D2_UPPER], double *sum_out)
{
    const size_t eta = 5u * p->g + 1u;
    d2_point_t pt[EM_G_MAX];
    double hi = log_pi0 + lf0;
    for (size_t g = 0u; g < p->g; ++g) {
        d2_point(&k[g], p->mean[g], y, &pt[g]);
        hi = (pt[g].w > hi) ? pt[g].w : hi;
    }
    double e[EM_G_MAX];
    double sum = md_exp(log_pi0 + lf0 - hi); /* one log-sum-exp about the largest term */
    for (size_t g = 0u; g < p->g; ++g) {
        e[g] = md_exp(pt[g].w - hi);
        sum += e[g];
    }
    *sum_out = sum;
    const double b = md_exp(lf0 - hi) / sum; /* f0/P; π_0 may be 0 */
    u[eta - 1u] = 0.0;
    for (size_t g = 0u; g < p->g; ++g) {
        const double a = e[g] / (sum * k[g].pi);
        const double q = k[g].pi * a;
        double *ug = &u[5u * g];
        ug[0] = a - b; /* App. B.2.1 divided by P */
        ug[1] = q * pt[g].sr[0];
        ug[2] = q * pt[g].sr[1];
        ug[3] = q * pt[g].dt[0];
        ug[4] = q * pt[g].dt[1];
        u[eta - 1u] += q * pt[g].dt[2];
        d2_curvature(&k[g], &pt[g], a, q, blk[g]);
    }
    return hi;
}

/* H (upper) += Σ of the cluster blocks: slot i < 5 is parameter 5g + i, slot 5 is λ. */
static void d2_scatter(size_t g_count, double blk[][D2_UPPER], double *hess)
{
    const size_t eta = 5u * g_count + 1u;
    for (size_t g = 0u; g < g_count; ++g) {
        for (size_t i = 0u; i < D2_SLOTS; ++i) {
            const size_t gi = (i < 5u) ? (5u * g + i) : (eta - 1u);
            for (size_t j = i; j < D2_SLOTS; ++j) {
                const size_t gj = (j < 5u) ? (5u * g + j) : (eta - 1u);
                hess[gi * eta + gj] += blk[g][D2_UP[i][j]];
            }
        }
    }
}

/* H (upper) -= Σ_k u_k u_kᵀ and grad += Σ_k u_k over D2_OUTER_BATCH gradients (rows of u,
 * unused rows zero): each entry of H is read and written once per batch, not per point. */
static void d2_outer(size_t eta, double u[][EM_ETA_MAX], double *grad, double *hess)
{
    for (size_t r = 0u; r < eta; ++r) {
        const double u0 = u[0][r];
        const double u1 = u[1][r];
        const double u2 = u[2][r];
        const double u3 = u[3][r];
        double *row = &hess[r * eta];
        grad[r] += ((u0 + u1) + u2) + u3;
        for (size_t c = r; c < eta; ++c) {
            row[c] -= ((u0 * u[0][c] + u1 * u[1][c]) + u2 * u[2][c]) + u3 * u[3][c]; /* eq. B.17 first term */
        }
    }
}
_Static_assert(D2_OUTER_BATCH == 4u, "d2_outer folds four gradients");

double em_d2_points(const em_data_t *data, const em_outlier_t *outlier, const em_params_t *p, const double *log_pi,
                    em_evidence_work_t *ws, double *grad, double *hess)
{
    const size_t eta = 5u * p->g + 1u;
    double u[D2_OUTER_BATCH][EM_ETA_MAX];
    memset(u, 0, sizeof u);
    memset(ws->d2_blk, 0, sizeof ws->d2_blk);
    d2_prepare(p, ws->comp, log_pi, ws->d2);
    const bool tab = (outlier->tab_y == data->y) && (outlier->tab_n == data->n);
    double hi_sum = 0.0; /* Σ_i l_i = Σ_i hi_i + log Π_i sum_i, renormalised as in em.c */
    double prod = 1.0;
    int prod_exp = 0;
    for (size_t i = 0u; i < data->n; ++i) {
        const double *y = &data->y[2u * i];
        const double lf0 = tab ? outlier->tab_log_f0[i] : em_outlier_logpdf(outlier, y);
        double sum = 1.0;
        hi_sum += d2_one_point(p, ws->d2, y, lf0, log_pi[0], u[i % D2_OUTER_BATCH], ws->d2_blk, &sum);
        prod *= sum;
        if ((i % D2_LOG_BATCH) == (D2_LOG_BATCH - 1u)) {
            int e = 0;
            prod = frexp(prod, &e);
            prod_exp += e;
        }
        if (((i % D2_OUTER_BATCH) == (D2_OUTER_BATCH - 1u)) || (i + 1u == data->n)) {
            d2_outer(eta, u, grad, hess);
            memset(u, 0, sizeof u);
        }
    }
    d2_scatter(p->g, ws->d2_blk, hess);
    return hi_sum + (log(prod) + (double)prod_exp * D2_LN2);
}

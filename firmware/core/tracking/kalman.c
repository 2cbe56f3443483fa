/// @file kalman.c
/// Waveform-space Kalman filter with an isotropic-plus-low-rank covariance (see kalman.h).
#include "tracking/kalman.h"

#include <math.h>
#include <stdbool.h>
#include <string.h>

#include "numeric/linalg.h"

#define KF_DROP_NORM 1e-9 /* Gram-Schmidt: a vector this short is already in the span */

static double kf_dot_fd(const float *v, const double *h, size_t n)
{
    double s = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        s += (double)v[i] * h[i];
    }
    return s;
}

static double kf_dot(const double *a, const double *b, size_t n)
{
    double s = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        s += a[i] * b[i];
    }
    return s;
}

md_status_t kf_predict(kf_state_t *st, double q)
{
    if ((st == NULL) || !(q >= 0.0) || !isfinite(q)) {
        return MD_E_ARG;
    }
    st->a += q; /* eq. 4.8: F = I, Q = qI only moves the isotropic part */
    return MD_OK;
}

md_status_t kf_measure(const kf_state_t *st, const double *h, size_t d, double *mu, double *hlh)
{
    if ((st == NULL) || (h == NULL) || (mu == NULL) || (hlh == NULL) || (d == 0u) || (d > KF_D_MAX)) {
        return MD_E_ARG;
    }
    const size_t n = st->d_w;
    double hv[KF_RANK_MAX][KF_D_MAX];
    for (size_t r = 0u; r < st->rank; ++r) {
        for (size_t c = 0u; c < d; ++c) {
            hv[r][c] = kf_dot_fd(st->v[r], &h[c * n], n);
        }
    }
    for (size_t c = 0u; c < d; ++c) {
        mu[c] = kf_dot(&h[c * n], st->x, n); /* eq. 4.9 */
        for (size_t c2 = 0u; c2 < d; ++c2) {
            double s = st->a * kf_dot(&h[c * n], &h[c2 * n], n);
            for (size_t r = 0u; r < st->rank; ++r) {
                s += st->e[r] * hv[r][c] * hv[r][c2];
            }
            hlh[c * d + c2] = s; /* H Λ Hᵀ, first term of eq. 4.13 */
        }
    }
    return (linalg_all_finite(mu, d) && linalg_all_finite(hlh, d * d)) ? MD_OK : MD_E_NUMERIC;
}

/* Appends vec to the orthonormal set w[0..*k) unless it is (numerically) in its span. */
static void kf_gs_append(kf_work_t *ws, size_t *k, const double *vec, size_t n)
{
    double *w = ws->w[*k];
    memcpy(w, vec, n * sizeof *w);
    const double norm0 = sqrt(kf_dot(w, w, n));
    for (size_t pass = 0u; pass < 2u; ++pass) { /* twice is enough (Kahan–Parlett) */
        for (size_t j = 0u; j < *k; ++j) {
            const double c = kf_dot(ws->w[j], w, n);
            for (size_t i = 0u; i < n; ++i) {
                w[i] -= c * ws->w[j][i];
            }
        }
    }
    const double norm = sqrt(kf_dot(w, w, n));
    if (!(norm > KF_DROP_NORM * (norm0 > 1.0 ? norm0 : 1.0))) {
        return;
    }
    for (size_t i = 0u; i < n; ++i) {
        w[i] /= norm;
    }
    ++*k;
}

/* Eigen-decomposes ws->m (k×k), keeps the KF_RANK_MAX entries of largest |e| as the new directions. */
static md_status_t kf_rebuild(kf_state_t *st, kf_work_t *ws, size_t k)
{
    const size_t n = st->d_w;
    if (linalg_sym_eigen(ws->m, k, ws->val, ws->vec, KF_JACOBI_SWEEPS) != MD_OK) {
        return MD_E_NUMERIC;
    }
    bool taken[KF_SPAN_MAX] = {false};
    const double tiny = 1e-12 * (st->a > 0.0 ? st->a : 1.0);
    uint8_t rank = 0u;
    for (size_t slot = 0u; slot < KF_RANK_MAX; ++slot) {
        size_t best = k;
        for (size_t j = 0u; j < k; ++j) {
            if (!taken[j] && (fabs(ws->val[j]) > tiny) && ((best == k) || (fabs(ws->val[j]) > fabs(ws->val[best])))) {
                best = j;
            }
        }
        if (best == k) {
            break;
        }
        taken[best] = true;
        for (size_t i = 0u; i < n; ++i) {
            double s = 0.0;
            for (size_t j = 0u; j < k; ++j) {
                s += ws->vec[j * k + best] * ws->w[j][i];
            }
            st->v[rank][i] = (float)s;
        }
        st->e[rank] = ws->val[best];
        ++rank;
    }
    st->rank = rank;
    return MD_OK;
}

/* M = Wᵀ (Σ e_i v_i v_iᵀ) W for the current directions, k×k. */
/* M += w·c cᵀ (k×k): one direction of Λ - aI seen in the basis W. */
static void kf_add_outer(kf_work_t *ws, size_t k, const double *c, double w)
{
    for (size_t i = 0u; i < k; ++i) {
        for (size_t j = 0u; j < k; ++j) {
            ws->m[i * k + j] += w * c[i] * c[j];
        }
    }
}

/* Appends the current directions v_i to the orthonormal set w[0..*k). */
static void kf_span_lowrank(const kf_state_t *st, kf_work_t *ws, size_t *k)
{
    double v[KF_DW_MAX];
    for (size_t r = 0u; r < st->rank; ++r) {
        for (size_t i = 0u; i < st->d_w; ++i) {
            v[i] = (double)st->v[r][i];
        }
        kf_gs_append(ws, k, v, st->d_w);
    }
}

static void kf_project_lowrank(const kf_state_t *st, kf_work_t *ws, size_t k)
{
    const size_t n = st->d_w;
    memset(ws->m, 0, k * k * sizeof ws->m[0]);
    for (size_t r = 0u; r < st->rank; ++r) {
        double c[KF_SPAN_MAX];
        for (size_t j = 0u; j < k; ++j) {
            c[j] = kf_dot_fd(st->v[r], ws->w[j], n);
        }
        kf_add_outer(ws, k, c, st->e[r]);
    }
}

md_status_t kf_predict_scaled(kf_state_t *st, double q, double s2, kf_work_t *ws)
{
    if ((st == NULL) || (ws == NULL) || !(s2 >= 0.0) || !isfinite(s2) || (st->d_w > KF_DW_MAX)) {
        return MD_E_ARG;
    }
    const size_t n = st->d_w;
    const double xx = kf_dot(st->x, st->x, n);
    if (!(s2 > 0.0) || !(xx > 0.0)) {
        return kf_predict(st, q);
    }
    if (!(q >= 0.0) || !isfinite(q)) {
        return MD_E_ARG;
    }
    size_t k = 0u;
    kf_span_lowrank(st, ws, &k);
    kf_gs_append(ws, &k, st->x, n);
    kf_project_lowrank(st, ws, k);
    double c[KF_SPAN_MAX];
    for (size_t j = 0u; j < k; ++j) {
        c[j] = kf_dot(ws->w[j], st->x, n);
    }
    kf_add_outer(ws, k, c, s2);
    if (kf_rebuild(st, ws, k) != MD_OK) { /* fails before it writes st */
        return MD_E_NUMERIC;
    }
    st->a += q;
    return MD_OK;
}

md_status_t kf_init(kf_state_t *st, size_t d_w, const double *x0, double a0, const double *h, size_t d, const double *r,
                    kf_work_t *ws)
{
    if ((st == NULL) || (x0 == NULL) || (ws == NULL) || (d_w == 0u) || (d_w > KF_DW_MAX) || !(a0 > 0.0) ||
        !isfinite(a0) || ((r != NULL) && ((h == NULL) || (d == 0u) || (d > KF_D_MAX)))) {
        return MD_E_ARG;
    }
    if (!linalg_all_finite(x0, d_w)) {
        return MD_E_NUMERIC;
    }
    memset(st, 0, sizeof *st);
    st->d_w = (uint16_t)d_w;
    st->a = a0;
    memcpy(st->x, x0, d_w * sizeof *x0);
    if (r == NULL) {
        return MD_OK;
    }
    size_t k = 0u;
    for (size_t c = 0u; c < d; ++c) {
        kf_gs_append(ws, &k, &h[c * d_w], d_w);
    }
    if (k != d) {
        return MD_E_ARG; /* rows of H are dependent */
    }
    /* Λ0 - a0 I = Hᵀ (R - a0 I) H expressed in the orthonormal basis W of the rows of H. */
    double wh[KF_D_MAX * KF_D_MAX];
    for (size_t i = 0u; i < d; ++i) {
        for (size_t c = 0u; c < d; ++c) {
            wh[i * d + c] = kf_dot(ws->w[i], &h[c * d_w], d_w);
        }
    }
    for (size_t i = 0u; i < d; ++i) {
        for (size_t j = 0u; j < d; ++j) {
            double s = 0.0;
            for (size_t c = 0u; c < d; ++c) {
                for (size_t c2 = 0u; c2 < d; ++c2) {
                    s += wh[i * d + c] * (r[c * d + c2] - ((c == c2) ? a0 : 0.0)) * wh[j * d + c2];
                }
            }
            ws->m[i * d + j] = s;
        }
    }
    return kf_rebuild(st, ws, d);
}

/* Λ Hᵀ (d_w × d) into ws->p and S = H Λ Hᵀ + R (eq. 4.13) factorised into ws->sl. */
static md_status_t kf_gain_terms(const kf_state_t *st, const double *h, size_t d, const double *r, kf_work_t *ws)
{
    const size_t n = st->d_w;
    for (size_t c = 0u; c < d; ++c) {
        const double *hc = &h[c * n];
        for (size_t i = 0u; i < n; ++i) {
            ws->p[i * d + c] = st->a * hc[i];
        }
        for (size_t q = 0u; q < st->rank; ++q) {
            const double f = st->e[q] * kf_dot_fd(st->v[q], hc, n);
            for (size_t i = 0u; i < n; ++i) {
                ws->p[i * d + c] += f * (double)st->v[q][i];
            }
        }
    }
    for (size_t c = 0u; c < d; ++c) {
        for (size_t c2 = 0u; c2 < d; ++c2) {
            double s = 0.0;
            for (size_t i = 0u; i < n; ++i) {
                s += h[c * n + i] * ws->p[i * d + c2];
            }
            ws->s[c * d + c2] = s + 0.5 * (r[c * d + c2] + r[c2 * d + c]);
        }
    }
    memcpy(ws->sl, ws->s, d * d * sizeof ws->s[0]);
    return linalg_cholesky(ws->sl, d);
}

/* The mean's update (eq. 4.15-4.16): xnew = x + P S⁻¹ ν with the innovation
 * ν = μ - H x; ws->p and ws->sl hold P and chol(S) (kf_gain_terms). */
static md_status_t kf_mean_update(const kf_state_t *st, const double *h, size_t d, const double *mu,
                                  const kf_work_t *ws, double *xnew)
{
    const size_t n = st->d_w;
    double z[KF_D_MAX];
    for (size_t c = 0u; c < d; ++c) {
        z[c] = mu[c] - kf_dot(&h[c * n], st->x, n); /* innovation */
    }
    if (linalg_cholesky_solve(ws->sl, d, z) != MD_OK) {
        return MD_E_NUMERIC;
    }
    for (size_t i = 0u; i < n; ++i) {
        xnew[i] = st->x[i] + kf_dot(&ws->p[i * d], z, d); /* eq. 4.15-4.16: x += P S⁻¹ ν */
    }
    return linalg_all_finite(xnew, n) ? MD_OK : MD_E_NUMERIC;
}

/* The covariance's downdate in the basis W (k vectors of length n in ws->w):
 * M -= (Wᵀ P) S⁻¹ (Wᵀ P)ᵀ, then symmetrised against rounding. */
static md_status_t kf_downdate(kf_work_t *ws, size_t k, size_t d, size_t n)
{
    double pc[KF_SPAN_MAX][KF_D_MAX]; /* Wᵀ P */
    for (size_t j = 0u; j < k; ++j) {
        for (size_t c = 0u; c < d; ++c) {
            double s = 0.0;
            for (size_t i = 0u; i < n; ++i) {
                s += ws->w[j][i] * ws->p[i * d + c];
            }
            pc[j][c] = s;
        }
    }
    for (size_t j = 0u; j < k; ++j) {
        double sol[KF_D_MAX];
        memcpy(sol, pc[j], d * sizeof sol[0]);
        if (linalg_cholesky_solve(ws->sl, d, sol) != MD_OK) {
            return MD_E_NUMERIC;
        }
        for (size_t i = 0u; i < k; ++i) {
            ws->m[i * k + j] -= kf_dot(pc[i], sol, d);
        }
    }
    for (size_t i = 0u; i < k; ++i) { /* symmetrise against rounding */
        for (size_t j = i + 1u; j < k; ++j) {
            const double s = 0.5 * (ws->m[i * k + j] + ws->m[j * k + i]);
            ws->m[i * k + j] = s;
            ws->m[j * k + i] = s;
        }
    }
    return linalg_all_finite(ws->m, k * k) ? MD_OK : MD_E_NUMERIC;
}

md_status_t kf_update(kf_state_t *st, const double *h, size_t d, const double *mu, const double *r, kf_work_t *ws)
{
    if ((st == NULL) || (h == NULL) || (mu == NULL) || (r == NULL) || (ws == NULL) || (d == 0u) || (d > KF_D_MAX)) {
        return MD_E_ARG;
    }
    if (!linalg_all_finite(mu, d) || !linalg_all_finite(r, d * d) || (kf_gain_terms(st, h, d, r, ws) != MD_OK)) {
        return MD_E_NUMERIC;
    }
    const size_t n = st->d_w;
    double xnew[KF_DW_MAX];
    if (kf_mean_update(st, h, d, mu, ws, xnew) != MD_OK) {
        return MD_E_NUMERIC;
    }
    /* eq. 4.17 as Λ' = Λ - P S⁻¹ Pᵀ, expressed in W = orth{v_i, rows of H}. */
    size_t k = 0u;
    kf_span_lowrank(st, ws, &k);
    for (size_t c = 0u; c < d; ++c) {
        kf_gs_append(ws, &k, &h[c * n], n);
    }
    kf_project_lowrank(st, ws, k);
    if (kf_downdate(ws, k, d, n) != MD_OK) {
        return MD_E_NUMERIC;
    }
    kf_state_t old = *st;
    memcpy(st->x, xnew, n * sizeof xnew[0]);
    if (kf_rebuild(st, ws, k) != MD_OK) {
        *st = old;
        return MD_E_NUMERIC;
    }
    return MD_OK;
}

void kf_covariance(const kf_state_t *st, double *lambda)
{
    if ((st == NULL) || (lambda == NULL)) {
        return;
    }
    const size_t n = st->d_w;
    for (size_t i = 0u; i < n; ++i) {
        for (size_t j = 0u; j < n; ++j) {
            double s = (i == j) ? st->a : 0.0;
            for (size_t q = 0u; q < st->rank; ++q) {
                s += st->e[q] * (double)st->v[q][i] * (double)st->v[q][j];
            }
            lambda[i * n + j] = s;
        }
    }
}

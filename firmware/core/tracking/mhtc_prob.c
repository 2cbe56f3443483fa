/// @file mhtc_prob.c
/// P3, A*, the eq. 4.30 normalisation and the P_d rule (see mhtc_prob.h).
#include "tracking/mhtc_prob.h"

#include <math.h>
#include <string.h>

static double mhtc_clamp(double v, double lo, double hi)
{
    return (v < lo) ? lo : ((v > hi) ? hi : v);
}

static double mhtc_q_of_rate(const mhtc_pd_rule_t *rule, double rate_hz)
{
    const double r = (rate_hz > 0.0) && isfinite(rate_hz) ? rate_hz : 0.0;
    return rule->pd_max - 1.0 / (rule->a * r + rule->b); /* q(r) of §4.4.2 */
}

double mhtc_pd_first(const mhtc_pd_rule_t *rule, double rate_hz)
{
    return mhtc_clamp(mhtc_q_of_rate(rule, rate_hz), rule->pd_min, rule->pd_max);
}

double mhtc_pd_next(const mhtc_pd_rule_t *rule, double pd_prev, double rate_hz)
{
    const double p = 0.5 * (mhtc_q_of_rate(rule, rate_hz) + pd_prev);
    return mhtc_clamp(p, rule->pd_min, rule->pd_max);
}

md_status_t mhtc_log_p3(const double *pd, size_t n_t, size_t g, double lambda0, double *log_p3)
{
    if ((log_p3 == NULL) || ((pd == NULL) && (n_t > 0u)) || (n_t > MHTC_PROB_NT_MAX) || !(lambda0 > 0.0) ||
        !isfinite(lambda0)) {
        return MD_E_ARG;
    }
    /* P(N_τ = t): Poisson-binomial over the detection patterns δ (inner sum of eq. 4.32). */
    double p_tau[MHTC_PROB_NT_MAX + 1u];
    memset(p_tau, 0, sizeof p_tau);
    p_tau[0] = 1.0;
    for (size_t j = 0u; j < n_t; ++j) {
        if (!(pd[j] > 0.0) || !(pd[j] < 1.0)) {
            return MD_E_ARG;
        }
        for (size_t t = j + 1u; t > 0u; --t) {
            p_tau[t] = p_tau[t] * (1.0 - pd[j]) + p_tau[t - 1u] * pd[j];
        }
        p_tau[0] *= 1.0 - pd[j];
    }
    double p3 = 0.0;
    double fact = 1.0; /* (g - t)! built up from t = g downwards */
    const size_t t_max = (n_t < g) ? n_t : g;
    for (size_t t = g + 1u; t-- > 0u;) {
        if (t < g) {
            fact *= (double)(g - t);
        }
        if (t <= t_max) {
            /* Poisson(N_ν + N_φ = g - t; λ0) × P(N_τ = t), eq. 4.32 */
            p3 += pow(lambda0, (double)(g - t)) * exp(-lambda0) / fact * p_tau[t];
        }
    }
    if (!(p3 > 0.0)) {
        return MD_E_NUMERIC;
    }
    *log_p3 = log(p3);
    return MD_OK;
}

double mhtc_count_reference(double n_last, const double prev[2])
{
    if (!(prev[1] >= 0.0) || !(prev[0] >= 0.0)) {
        return n_last;
    }
    return fmax(fmin(n_last, prev[0]), fmin(fmax(n_last, prev[0]), prev[1])); /* median of three */
}

/* ln of the count term of cluster r continuing target j (mhtc_count_term_t); 0 when it is off. */
static double mhtc_log_count_weight(const mhtc_count_term_t *count, size_t r, size_t j)
{
    if ((count == NULL) || !(count->sigma > 0.0) || !(count->n_expect[j] > 0.0)) {
        return 0.0;
    }
    const double sigma = count->sigma * ((count->spread != NULL) ? count->spread[j] : 1.0);
    const double ratio = log((fmax(count->n_cluster[r], 0.0) + 1.0) / (count->n_expect[j] + 1.0));
    return -ratio * ratio / (2.0 * sigma * sigma);
}

static bool mhtc_count_term_ok(const mhtc_count_term_t *count, size_t g, size_t n_t)
{
    if (count == NULL) {
        return true;
    }
    if (!(count->sigma >= 0.0) || !isfinite(count->sigma)) {
        return false;
    }
    if (!(count->sigma > 0.0)) {
        return true; /* off */
    }
    if ((count->n_cluster == NULL) || ((count->n_expect == NULL) && (n_t > 0u))) {
        return false;
    }
    for (size_t r = 0u; r < g; ++r) {
        if (!isfinite(count->n_cluster[r])) {
            return false;
        }
    }
    for (size_t j = 0u; j < n_t; ++j) {
        if (!isfinite(count->n_expect[j]) ||
            ((count->spread != NULL) && (!(count->spread[j] >= 1.0) || !isfinite(count->spread[j])))) {
            return false;
        }
    }
    return true;
}

md_status_t mhtc_assoc_costs(const double *zeta, size_t zeta_stride, size_t g, const double *pd, size_t n_t,
                             double lambda_new, double lambda_false, const mhtc_count_term_t *count, double *cost)
{
    if ((zeta == NULL) || (cost == NULL) || ((pd == NULL) && (n_t > 0u)) || (g == 0u) || (g > LAP_MAX_ROWS) ||
        (n_t > MHTC_PROB_NT_MAX) || (zeta_stride < n_t + 1u) || !(lambda_new > 0.0) || !(lambda_false > 0.0) ||
        !mhtc_count_term_ok(count, g, n_t)) {
        return MD_E_ARG;
    }
    const size_t cols = n_t + 2u * g;
    const double l0 = lambda_new + lambda_false;
    for (size_t j = 0u; j < n_t; ++j) {
        if (!(pd[j] > 0.0) || !(pd[j] < 1.0)) {
            return MD_E_ARG;
        }
    }
    for (size_t r = 0u; r < g; ++r) {
        const double *z = &zeta[r * zeta_stride];
        for (size_t c = 0u; c < cols; ++c) {
            double a = 0.0;
            if (c < n_t) {
                a = z[c + 1u] / (1.0 - pd[c]) * exp(mhtc_log_count_weight(count, r, c)); /* a_gj, eq. 4.25 */
            } else if (c == n_t + r) {
                a = lambda_new / l0 * z[0]; /* α^ν_g */
            } else if (c == n_t + g + r) {
                a = lambda_false / l0 * z[0]; /* α^φ_g */
            }
            if (isnan(a)) {
                return MD_E_NUMERIC;
            }
            cost[r * cols + c] = (a > 0.0) ? -log(a) : LAP_FORBIDDEN; /* A* = -log A */
        }
    }
    return MD_OK;
}

double mhtc_log_norm(const double *cost, size_t n)
{
    double m = -cost[0];
    for (size_t i = 1u; i < n; ++i) {
        m = fmax(m, -cost[i]);
    }
    double s = 0.0;
    for (size_t i = 0u; i < n; ++i) {
        s += exp(-cost[i] - m);
    }
    return m + log(s);
}

/// @file snr_curve.c
/// SNR-curve optimiser (thesis §2.2.3, eq. 2.1–2.2); see snr_curve.h and
/// docs/snr-curve.md for the prior and the derivation of the evidence.
#include "control/snr_curve.h"

#include <math.h>
#include <string.h>

#include "numeric/linalg.h"

/* Two depths closer than this count as one for identifiability (the servo's
 * resolution is far coarser). */
#define SC_SAME_DEPTH_UM 1e-3
/* Floor of the least-squares depth scale: keeps the fit's x finite when all
 * depths coincide (then only m = 1 is admissible anyway). */
#define SC_FIT_SCALE_MIN_UM 1.0
/* |H| below this (SNR/µm²) is a straight line for eq. 2.1: the Newton step
 * would exceed any plausible Δmax (|ξ| ~ 1 SNR/µm at most). */
#define SC_H_MIN 1e-9

void sc_config_default(sc_config_t *cfg)
{
    if (cfg == NULL) {
        return;
    }
    cfg->m_max = (uint8_t)SC_M_MAX;
    cfg->k0 = 3u;
    cfg->gain_c = 1.0;
    cfg->tol_um = 2.5;
    cfg->move_max_um = 30.0;
    cfg->move_sample_um = 10.0;
    cfg->depth_scale_um = 50.0;
    cfg->coef_prior_sd = 5.0;
    cfg->noise_prior_sd = 0.5;
    cfg->noise_prior_a0 = 1.0;
    cfg->model_floor = 0.01;
}

static bool sc_pos_finite(double v)
{
    return isfinite(v) && (v > 0.0);
}

md_status_t sc_config_check(const sc_config_t *cfg)
{
    if (cfg == NULL) {
        return MD_E_ARG;
    }
    const bool ok = (cfg->m_max >= 1u) && (cfg->m_max <= SC_M_MAX) && (cfg->k0 >= 2u) && (cfg->k0 <= SC_HIST_MAX) &&
                    sc_pos_finite(cfg->gain_c) && sc_pos_finite(cfg->tol_um) && sc_pos_finite(cfg->move_max_um) &&
                    sc_pos_finite(cfg->move_sample_um) && (cfg->move_sample_um <= cfg->move_max_um) &&
                    sc_pos_finite(cfg->depth_scale_um) && sc_pos_finite(cfg->coef_prior_sd) &&
                    sc_pos_finite(cfg->noise_prior_sd) && sc_pos_finite(cfg->noise_prior_a0) &&
                    isfinite(cfg->model_floor) && (cfg->model_floor >= 0.0) && (cfg->model_floor < 1.0);
    return ok ? MD_OK : MD_E_ARG;
}

void sc_curve_reset(sc_curve_t *curve)
{
    if (curve == NULL) {
        return;
    }
    const uint32_t errors = curve->errors;
    (void)memset(curve, 0, sizeof *curve);
    curve->errors = errors;
    for (size_t m = 0u; m < SC_M_MAX; ++m) {
        curve->post[m] = 1.0 / (double)SC_M_MAX;
    }
}

/* i-th observation counted from the oldest one held. */
static void sc_get(const sc_curve_t *c, size_t i, double *u, double *r)
{
    const size_t start = (c->count < SC_HIST_MAX) ? 0u : (size_t)c->head;
    const size_t k = (start + i) % SC_HIST_MAX;
    *u = c->depth_um[k];
    *r = c->snr[k];
}

static double sc_mean_depth(const sc_curve_t *c)
{
    double s = 0.0;
    for (size_t i = 0u; i < c->count; ++i) {
        double u;
        double r;
        sc_get(c, i, &u, &r);
        s += u;
    }
    return s / (double)c->count;
}

/* Number of distinct depths, i.e. the highest order the data identify. */
static size_t sc_distinct_depths(const sc_curve_t *c)
{
    size_t n = 0u;
    for (size_t i = 0u; i < c->count; ++i) {
        double ui;
        double r;
        sc_get(c, i, &ui, &r);
        bool seen = false;
        for (size_t j = 0u; (j < i) && !seen; ++j) {
            double uj;
            sc_get(c, j, &uj, &r);
            seen = fabs(uj - ui) < SC_SAME_DEPTH_UM;
        }
        n += seen ? 0u : 1u;
    }
    return n;
}

/* Centred design for order m (p = m-1 slope columns x^1..x^p, x = (u-ū)/L):
 * S = X_cᵀX_c (p×p), t = X_cᵀy_c, yy = y_cᵀy_c. Centring integrates out the
 * flat-prior intercept exactly (docs/snr-curve.md). */
static void sc_centred_moments(const sc_curve_t *c, size_t p, double scale, double *s, double *t, double *yy)
{
    const double ubar = sc_mean_depth(c);
    double xbar[SC_M_MAX] = {0.0};
    double ybar = 0.0;
    for (size_t i = 0u; i < c->count; ++i) {
        double u;
        double r;
        sc_get(c, i, &u, &r);
        const double x = (u - ubar) / scale;
        double pw = 1.0;
        for (size_t j = 0u; j < p; ++j) {
            pw *= x;
            xbar[j] += pw;
        }
        ybar += r;
    }
    const double inv_n = 1.0 / (double)c->count;
    for (size_t j = 0u; j < p; ++j) {
        xbar[j] *= inv_n;
    }
    ybar *= inv_n;
    (void)memset(s, 0, p * p * sizeof *s);
    (void)memset(t, 0, p * sizeof *t);
    *yy = 0.0;
    for (size_t i = 0u; i < c->count; ++i) {
        double u;
        double r;
        sc_get(c, i, &u, &r);
        const double x = (u - ubar) / scale;
        double xc[SC_M_MAX];
        double pw = 1.0;
        for (size_t j = 0u; j < p; ++j) {
            pw *= x;
            xc[j] = pw - xbar[j];
        }
        const double yc = r - ybar;
        for (size_t a = 0u; a < p; ++a) {
            t[a] += xc[a] * yc;
            for (size_t b = 0u; b < p; ++b) {
                s[a * p + b] += xc[a] * xc[b];
            }
        }
        *yy += yc * yc;
    }
}

/* log p(y | m) up to terms shared by every order, for the conjugate prior
 * b_slope | σ² ~ N(0, σ²τ² I), σ² ~ IG(a0, a0 σ0²), flat intercept:
 *   ½ log|Λ0| - ½ log|Λn| - a_n log β_n,   Λ0 = I/τ², Λn = X_cᵀX_c + Λ0,
 *   β_n = β0 + ½ (y_cᵀy_c - tᵀ Λn⁻¹ t),    a_n = a0 + (n-1)/2.
 * The dropped terms (-(n-1)/2 log 2π, -½ log n, a0 log β0, lgamma) do not
 * depend on m and cancel in eq. 2.2. */
static md_status_t sc_log_evidence_m(const sc_curve_t *c, const sc_config_t *cfg, size_t m, double *out)
{
    const size_t p = m - 1u;
    double s[(SC_M_MAX - 1u) * (SC_M_MAX - 1u)];
    double t[SC_M_MAX];
    double yy = 0.0;
    sc_centred_moments(c, p, cfg->depth_scale_um, s, t, &yy);
    const double tau2 = cfg->coef_prior_sd * cfg->coef_prior_sd;
    double fit = 0.0;
    double logdet_n = 0.0;
    if (p > 0u) {
        double mu[SC_M_MAX];
        for (size_t a = 0u; a < p; ++a) {
            s[a * p + a] += 1.0 / tau2;
            mu[a] = t[a];
        }
        const md_status_t st = linalg_cholesky(s, p);
        if (st != MD_OK) {
            return MD_E_NUMERIC;
        }
        logdet_n = linalg_cholesky_logdet(s, p);
        if (linalg_cholesky_solve(s, p, mu) != MD_OK) {
            return MD_E_NUMERIC;
        }
        for (size_t a = 0u; a < p; ++a) {
            fit += mu[a] * t[a];
        }
    }
    const double a0 = cfg->noise_prior_a0;
    const double beta0 = a0 * cfg->noise_prior_sd * cfg->noise_prior_sd;
    /* tᵀΛn⁻¹t <= y_cᵀy_c exactly; rounding may not respect it. */
    const double beta_n = beta0 + 0.5 * fmax(yy - fit, 0.0);
    const double a_n = a0 + 0.5 * (double)(c->count - 1u);
    const double v = -0.5 * (double)p * log(tau2) - 0.5 * logdet_n - a_n * log(beta_n);
    if (!isfinite(v)) {
        return MD_E_NUMERIC;
    }
    *out = v;
    return MD_OK;
}

md_status_t sc_curve_log_evidence(const sc_curve_t *curve, const sc_config_t *cfg, double *log_ev)
{
    if ((curve == NULL) || (log_ev == NULL) || (sc_config_check(cfg) != MD_OK)) {
        return MD_E_ARG;
    }
    if (curve->count < 2u) {
        return MD_E_DEGENERATE;
    }
    for (size_t m = 1u; m <= cfg->m_max; ++m) {
        const md_status_t st = sc_log_evidence_m(curve, cfg, m, &log_ev[m - 1u]);
        if (st != MD_OK) {
            return st;
        }
    }
    return MD_OK;
}

/* Eq. 2.2 with the previous posterior as prior. The factor multiplying it is
 * the evidence ratio p(R_1:k | m) / p(R_1:k-1 | m), the predictive density of
 * the new observation, so each observation is counted once and the recursion
 * reproduces Bayes' rule on all the data (docs: why not the full evidence
 * each cycle). At k0 the prior is uniform and the factor is the full
 * evidence. The floor keeps every order reachable when the curve changes. */
static md_status_t sc_update_posterior(sc_curve_t *c, const sc_config_t *cfg)
{
    double log_ev[SC_M_MAX];
    const md_status_t st = sc_curve_log_evidence(c, cfg, log_ev);
    if (st != MD_OK) {
        return st;
    }
    const size_t mm = cfg->m_max;
    double lp[SC_M_MAX];
    double top = -INFINITY;
    for (size_t m = 0u; m < mm; ++m) {
        lp[m] = c->posterior_valid ? (log(c->post[m]) + log_ev[m] - c->log_ev_prev[m]) : log_ev[m];
        top = fmax(top, lp[m]);
    }
    double z = 0.0;
    for (size_t m = 0u; m < mm; ++m) {
        lp[m] = exp(lp[m] - top);
        z += lp[m];
    }
    if (!isfinite(z) || !(z > 0.0)) {
        return MD_E_NUMERIC;
    }
    const double f = cfg->model_floor;
    for (size_t m = 0u; m < SC_M_MAX; ++m) {
        c->post[m] = (m < mm) ? ((1.0 - f) * lp[m] / z + f / (double)mm) : 0.0;
        c->log_ev_prev[m] = (m < mm) ? log_ev[m] : 0.0;
    }
    c->posterior_valid = true;
    return MD_OK;
}

md_status_t sc_curve_observe(sc_curve_t *curve, const sc_config_t *cfg, double depth_um, double snr)
{
    if ((curve == NULL) || (sc_config_check(cfg) != MD_OK) || !isfinite(depth_um) || !isfinite(snr)) {
        return MD_E_ARG;
    }
    curve->depth_um[curve->head] = depth_um;
    curve->snr[curve->head] = snr;
    curve->head = (uint8_t)((curve->head + 1u) % SC_HIST_MAX);
    if (curve->count < SC_HIST_MAX) {
        curve->count++;
    }
    if (curve->n_total < UINT32_MAX) {
        curve->n_total++;
    }
    if (curve->count < cfg->k0) {
        return MD_OK;
    }
    const md_status_t st = sc_update_posterior(curve, cfg);
    if (st != MD_OK) {
        curve->errors++;
        return MD_E_NUMERIC;
    }
    return MD_OK;
}

md_status_t sc_curve_fit(const sc_curve_t *curve, uint8_t m, double *coef, double *centre_um, double *scale_um)
{
    if ((curve == NULL) || (coef == NULL) || (centre_um == NULL) || (scale_um == NULL) || (m < 1u) || (m > SC_M_MAX)) {
        return MD_E_ARG;
    }
    if ((curve->count < m) || (sc_distinct_depths(curve) < m)) {
        return MD_E_DEGENERATE;
    }
    const double ubar = sc_mean_depth(curve);
    double half = 0.0;
    for (size_t i = 0u; i < curve->count; ++i) {
        double u;
        double r;
        sc_get(curve, i, &u, &r);
        half = fmax(half, fabs(u - ubar));
    }
    const double h = fmax(half, SC_FIT_SCALE_MIN_UM);
    double a[SC_M_MAX * SC_M_MAX] = {0.0};
    double b[SC_M_MAX] = {0.0};
    for (size_t i = 0u; i < curve->count; ++i) {
        double u;
        double r;
        sc_get(curve, i, &u, &r);
        const double x = (u - ubar) / h;
        double row[SC_M_MAX];
        row[0] = 1.0;
        for (size_t j = 1u; j < m; ++j) {
            row[j] = row[j - 1u] * x;
        }
        for (size_t j = 0u; j < m; ++j) {
            b[j] += row[j] * r;
            for (size_t l = 0u; l < m; ++l) {
                a[j * m + l] += row[j] * row[l];
            }
        }
    }
    if (linalg_cholesky(a, m) != MD_OK) {
        return MD_E_NUMERIC;
    }
    if (linalg_cholesky_solve(a, m, b) != MD_OK) {
        return MD_E_NUMERIC;
    }
    (void)memcpy(coef, b, m * sizeof *b);
    *centre_um = ubar;
    *scale_um = h;
    return MD_OK;
}

/* Most probable admissible order (eq. 2.2 argmax). Admissible: the
 * least-squares fit exists (m <= distinct depths) and leaves a residual
 * (m < n); an interpolating polynomial has arbitrary derivatives at the
 * newest point and would make eq. 2.1 follow noise. */
static uint8_t sc_best_order(const sc_curve_t *c, const sc_config_t *cfg)
{
    const size_t distinct = sc_distinct_depths(c);
    const size_t limit = (distinct < (size_t)c->count) ? distinct : (size_t)c->count - 1u;
    uint8_t best = 1u;
    for (size_t m = 2u; (m <= cfg->m_max) && (m <= limit); ++m) {
        if (c->post[m - 1u] > c->post[best - 1u]) {
            best = (uint8_t)m;
        }
    }
    return best;
}

static double sc_clamp_abs(double v, double cap)
{
    return fmin(fmax(v, -cap), cap);
}

/* Derivatives of the fitted polynomial at u: M, ξ = M', H = M''. */
static void sc_derivatives(const double *coef, uint8_t m, double centre, double scale, double u, sc_suggestion_t *o)
{
    const double x = (u - centre) / scale;
    double v = 0.0;
    double d1 = 0.0;
    double d2 = 0.0;
    double pw = 1.0; /* x^i */
    for (size_t i = 0u; i < m; ++i) {
        v += coef[i] * pw;
        pw *= x;
    }
    pw = 1.0;
    for (size_t i = 1u; i < m; ++i) {
        d1 += (double)i * coef[i] * pw;
        pw *= x;
    }
    pw = 1.0;
    for (size_t i = 2u; i < m; ++i) {
        d2 += (double)(i * (i - 1u)) * coef[i] * pw;
        pw *= x;
    }
    o->peak_snr = v;
    o->xi = d1 / scale;
    o->h = d2 / (scale * scale);
}

/* Step policy of §2.2.3: eq. 2.1 for m* >= 3, Δmax along the slope for a
 * line (H = 0 makes eq. 2.1 unbounded), Δsample in the search direction for a
 * constant (ξ = 0 stalls eq. 2.1). */
static void sc_step(const sc_config_t *cfg, int search_dir, sc_suggestion_t *o)
{
    const double dir = (search_dir < 0) ? -1.0 : 1.0;
    const bool sloped = fabs(o->xi) > 0.0;
    if ((o->m_star <= 1u) || !sloped) {
        o->move_um = dir * cfg->move_sample_um;
        return;
    }
    if ((o->m_star == 2u) || (fabs(o->h) < SC_H_MIN)) {
        o->move_um = copysign(cfg->move_max_um, o->xi);
        return;
    }
    o->newton_um = cfg->gain_c * o->xi / fabs(o->h); /* eq. 2.1 */
    if (o->h > 0.0) {
        /* Convex: ξ/|H| measures the distance from a minimum, not to a
         * maximum; eq. 2.1's |H| still gives the uphill sign. Never declare
         * convergence here and move at least Δsample uphill. */
        o->move_um = copysign(fmin(fmax(fabs(o->newton_um), cfg->move_sample_um), cfg->move_max_um), o->xi);
        return;
    }
    if (fabs(o->newton_um) < cfg->tol_um) {
        o->converged = true;
        o->move_um = 0.0;
        return;
    }
    o->move_um = sc_clamp_abs(o->newton_um, cfg->move_max_um);
}

md_status_t sc_curve_suggest(const sc_curve_t *curve, const sc_config_t *cfg, double depth_um, int search_dir,
                             sc_suggestion_t *out)
{
    if ((curve == NULL) || (out == NULL) || (sc_config_check(cfg) != MD_OK) || !isfinite(depth_um)) {
        return MD_E_ARG;
    }
    (void)memset(out, 0, sizeof *out);
    if (!curve->posterior_valid || (curve->count < cfg->k0)) {
        return MD_OK;
    }
    uint8_t m = sc_best_order(curve, cfg);
    double coef[SC_M_MAX];
    double centre = 0.0;
    double scale = 1.0;
    md_status_t st = MD_E_NUMERIC;
    /* A singular fit (nearly coincident depths) falls back to a lower order. */
    for (; m >= 1u; --m) {
        st = sc_curve_fit(curve, m, coef, &centre, &scale);
        if (st == MD_OK) {
            break;
        }
    }
    if (st != MD_OK) {
        return st;
    }
    out->ready = true;
    out->m_star = m;
    out->post_m_star = curve->post[m - 1u];
    sc_derivatives(coef, m, centre, scale, depth_um, out);
    sc_step(cfg, search_dir, out);
    if (!isfinite(out->move_um) || !isfinite(out->newton_um) || !isfinite(out->peak_snr)) {
        (void)memset(out, 0, sizeof *out);
        return MD_E_NUMERIC;
    }
    return MD_OK;
}

void sc_table_init(sc_table_t *table)
{
    if (table == NULL) {
        return;
    }
    (void)memset(table, 0, sizeof *table);
    for (size_t i = 0u; i < SC_TABLE_SLOTS; ++i) {
        sc_curve_reset(&table->slot[i].curve);
    }
}

sc_curve_t *sc_table_find(sc_table_t *table, uint32_t track_id)
{
    if (table == NULL) {
        return NULL;
    }
    for (size_t i = 0u; i < SC_TABLE_SLOTS; ++i) {
        if (table->slot[i].used && (table->slot[i].track_id == track_id)) {
            return &table->slot[i].curve;
        }
    }
    return NULL;
}

/* Slot for a new track: the first free one, else the least recently observed. */
static sc_slot_t *sc_table_claim(sc_table_t *table, uint32_t track_id)
{
    size_t pick = 0u;
    bool free_found = false;
    for (size_t i = 0u; (i < SC_TABLE_SLOTS) && !free_found; ++i) {
        if (!table->slot[i].used) {
            pick = i;
            free_found = true;
        } else if (table->slot[i].last_stamp < table->slot[pick].last_stamp) {
            pick = i;
        }
    }
    if (!free_found) {
        table->evictions++;
    }
    sc_slot_t *s = &table->slot[pick];
    s->used = true;
    s->track_id = track_id;
    s->curve.errors = 0u;
    sc_curve_reset(&s->curve);
    return s;
}

md_status_t sc_table_observe(sc_table_t *table, const sc_config_t *cfg, uint32_t track_id, double depth_um, double snr,
                             sc_curve_t **curve_out)
{
    if (table == NULL) {
        return MD_E_ARG;
    }
    if ((sc_config_check(cfg) != MD_OK) || !isfinite(depth_um) || !isfinite(snr)) {
        table->errors++;
        return MD_E_ARG;
    }
    sc_slot_t *s = NULL;
    for (size_t i = 0u; (i < SC_TABLE_SLOTS) && (s == NULL); ++i) {
        if (table->slot[i].used && (table->slot[i].track_id == track_id)) {
            s = &table->slot[i];
        }
    }
    if (s == NULL) {
        s = sc_table_claim(table, track_id);
    }
    table->clock++;
    s->last_stamp = table->clock;
    const md_status_t st = sc_curve_observe(&s->curve, cfg, depth_um, snr);
    if (st != MD_OK) {
        table->errors++;
    }
    if (curve_out != NULL) {
        *curve_out = &s->curve;
    }
    return st;
}

md_status_t sc_table_reset_track(sc_table_t *table, uint32_t track_id)
{
    sc_curve_t *c = sc_table_find(table, track_id);
    if (c == NULL) {
        return (table == NULL) ? MD_E_ARG : MD_E_STATE;
    }
    sc_curve_reset(c);
    return MD_OK;
}

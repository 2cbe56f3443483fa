/// @file cluster.c
/// Model classes G = 1..G_max, evidence and eq. 3.17 (see cluster.h).
#include "cluster/cluster.h"

#include <math.h>
#include <string.h>

#include "cluster/em_modes.h"
#include "numeric/linalg.h"

void cluster_config_default(cluster_config_t *cfg, cluster_method_t method)
{
    if (cfg == NULL) {
        return;
    }
    cfg->method = method;
    cfg->evidence = (method == CLUSTER_MAP) ? CLUSTER_EVIDENCE_LAPLACE : CLUSTER_EVIDENCE_BIC;
    cfg->g_max = EM_G_MAX;
    em_options_default(&cfg->em);
    cfg->lambda_new = EM_LAMBDA_NEW;
    cfg->lambda_false = EM_LAMBDA_FALSE;
    cfg->shape_prior_width = EM_SHAPE_PRIOR_WIDTH;
    cfg->unimodal_ratio = 0.0;
}

md_status_t cluster_model_prior_forget(const double *prev, size_t m_count, double alpha, double *prior)
{
    if ((prev == NULL) || (prior == NULL) || (m_count == 0u) || (m_count > EM_G_MAX) || !(alpha >= 0.0) ||
        (alpha > 1.0)) {
        return MD_E_ARG;
    }
    double sum = 0.0;
    for (size_t m = 0u; m < m_count; ++m) {
        if (!(prev[m] >= 0.0) || !isfinite(prev[m])) {
            return MD_E_ARG;
        }
        sum += prev[m];
    }
    if (!(sum > 0.0)) {
        return MD_E_ARG;
    }
    for (size_t m = 0u; m < m_count; ++m) {
        prior[m] = alpha * prev[m] / sum + (1.0 - alpha) / (double)m_count; /* §3.3.5 */
    }
    return MD_OK;
}

static bool cluster_args_ok(const cluster_config_t *cfg, const cluster_input_t *in, const cluster_workspace_t *ws,
                            const cluster_result_t *out)
{
    if ((cfg == NULL) || (in == NULL) || (ws == NULL) || (out == NULL)) {
        return false;
    }
    const bool method_ok = (cfg->method == CLUSTER_MAP) || (cfg->method == CLUSTER_ML);
    const bool ev_ok = (cfg->evidence == CLUSTER_EVIDENCE_LAPLACE) || (cfg->evidence == CLUSTER_EVIDENCE_BIC);
    return method_ok && ev_ok && (cfg->g_max >= 1u) && (cfg->g_max <= EM_G_MAX) &&
           (cfg->lambda_new + cfg->lambda_false > 0.0) && (cfg->shape_prior_width > 0.0) &&
           (cfg->unimodal_ratio >= 0.0) && (cfg->unimodal_ratio <= 1.0) && (in->data.y != NULL) && (in->data.d >= 1u) &&
           (in->data.d <= EM_D_MAX) && (in->data.n <= EM_N_MAX) && (in->noise_cov != NULL) &&
           (in->n_targets <= EM_J_MAX) && ((in->targets != NULL) || (in->n_targets == 0u)) &&
           linalg_all_finite(in->data.y, in->data.n * in->data.d);
}

/* Marks every model class failed with one reason (input-level failures). */
static md_status_t cluster_fail_all(cluster_result_t *out, size_t g_max, md_status_t st, em_reason_t reason)
{
    for (size_t g = 0u; g < EM_G_MAX; ++g) {
        out->model[g].fit.status = (g < g_max) ? st : MD_E_ARG;
        out->model[g].fit.reason = (g < g_max) ? reason : EM_FAIL_NOT_RUN;
    }
    return st;
}

/* Outlier density, mean prior and (ML) the Ward dendrogram: shared by all G. */
static md_status_t cluster_prepare(const cluster_config_t *cfg, const cluster_input_t *in, cluster_workspace_t *ws,
                                   cluster_result_t *out)
{
    double volume = 0.0;
    if (in->data.n == 0u) {
        return cluster_fail_all(out, cfg->g_max, MD_E_DEGENERATE, EM_FAIL_TOO_FEW_POINTS);
    }
    if (em_bounding_volume(&in->data, &volume) != MD_OK) {
        return cluster_fail_all(out, cfg->g_max, MD_E_DEGENERATE, EM_FAIL_ZERO_VOLUME);
    }
    if ((em_outlier_init(in->data.d, in->noise_cov, volume, &ws->outlier) != MD_OK) ||
        (em_outlier_tabulate(&ws->outlier, &in->data) != MD_OK)) {
        return cluster_fail_all(out, cfg->g_max, MD_E_NUMERIC, EM_FAIL_NOISE_COV);
    }
    const size_t j = (cfg->method == CLUSTER_MAP) ? in->n_targets : 0u;
    const md_status_t st = em_prior_init(in->data.d, in->targets, j, cfg->lambda_new + cfg->lambda_false, volume,
                                         &ws->prior);
    if (st != MD_OK) {
        return cluster_fail_all(out, cfg->g_max, st, (st == MD_E_ARG) ? EM_FAIL_ARG : EM_FAIL_NUMERIC);
    }
    if ((cfg->method == CLUSTER_ML) && (em_hac_ward(&in->data, &ws->hac) != MD_OK)) {
        return cluster_fail_all(out, cfg->g_max, MD_E_NUMERIC, EM_FAIL_SEED);
    }
    return MD_OK;
}

static md_status_t cluster_seed(const cluster_config_t *cfg, const cluster_input_t *in, size_t g,
                                cluster_workspace_t *ws)
{
    if (cfg->method == CLUSTER_ML) {
        return (g <= in->data.n) ? em_hac_cut(&ws->hac, g, ws->seed) : MD_E_DEGENERATE;
    }
    return em_seed_from_targets(&in->data, in->targets, in->n_targets, g, &ws->seed_ws, ws->seed);
}

static void cluster_evidence(const cluster_config_t *cfg, const cluster_input_t *in, cluster_workspace_t *ws,
                             cluster_model_t *m)
{
    const em_params_t *p = &m->fit.params;
    if (cfg->evidence == CLUSTER_EVIDENCE_BIC) {
        m->log_evidence = em_evidence_bic(m->fit.log_lik, p->d, p->g, in->data.n);
        m->usable = isfinite(m->log_evidence);
        return;
    }
    const md_status_t st = em_evidence_laplace(&in->data, &ws->outlier, &ws->prior, p, cfg->shape_prior_width, &ws->ev,
                                               &m->log_evidence);
    m->usable = (st == MD_OK);
    if (!m->usable) {
        m->log_evidence = 0.0;
        m->fit.status = MD_E_NUMERIC;
        m->fit.reason = EM_FAIL_HESSIAN;
    }
}

static void cluster_fit_one(const cluster_config_t *cfg, const cluster_input_t *in, size_t g, cluster_workspace_t *ws,
                            cluster_model_t *m)
{
    const md_status_t st = cluster_seed(cfg, in, g, ws);
    if (st != MD_OK) {
        m->fit.status = st;
        m->fit.reason = (st == MD_E_NUMERIC) ? EM_FAIL_NUMERIC : EM_FAIL_SEED;
        return;
    }
    const md_status_t fs = em_fit(&in->data, &ws->outlier, &ws->prior, ws->seed, g, &cfg->em, ws->z, &m->fit);
    if ((fs != MD_OK) && (fs != MD_E_NOCONVERGE)) {
        return;
    }
    bool one_mode = false;
    if ((cfg->unimodal_ratio > 0.0) &&
        ((em_params_oversplit(&m->fit.params, cfg->unimodal_ratio, &one_mode) != MD_OK) || one_mode)) {
        m->fit.status = MD_E_DEGENERATE;
        m->fit.reason = EM_FAIL_ONE_MODE;
        return;
    }
    em_labels(ws->z, in->data.n, g, m->labels);
    cluster_evidence(cfg, in, ws, m);
}

/* eq. 3.17 over the usable models, normalised in the log domain. */
static void cluster_posterior(const cluster_input_t *in, cluster_result_t *out)
{
    double lse = 0.0;
    bool any = false;
    for (size_t g = 0u; g < out->g_max; ++g) {
        cluster_model_t *m = &out->model[g];
        const double pr = (in->model_prior != NULL) ? in->model_prior[g] : 1.0 / (double)out->g_max;
        m->log_model_prior = (pr > 0.0) ? log(pr) : 0.0;
        m->usable = m->usable && (pr > 0.0);
        if (m->usable) {
            const double lw = m->log_evidence + m->log_model_prior;
            lse = any ? em_logaddexp(lse, lw) : lw;
            any = true;
        }
    }
    double best = -1.0;
    for (size_t g = 0u; g < out->g_max; ++g) {
        cluster_model_t *m = &out->model[g];
        m->post_prob = m->usable ? exp(m->log_evidence + m->log_model_prior - lse) : 0.0;
        if (m->usable && (m->post_prob > best)) {
            best = m->post_prob;
            out->best_g = g + 1u;
        }
    }
}

md_status_t cluster_fit_models(const cluster_config_t *cfg, const cluster_input_t *in, cluster_workspace_t *ws,
                               cluster_result_t *out)
{
    if (out == NULL) {
        return MD_E_ARG;
    }
    memset(out, 0, sizeof *out);
    if (!cluster_args_ok(cfg, in, ws, out)) {
        return cluster_fail_all(out, EM_G_MAX, MD_E_ARG, EM_FAIL_ARG);
    }
    for (size_t g = 0u; (in->model_prior != NULL) && (g < cfg->g_max); ++g) {
        if (!(in->model_prior[g] >= 0.0) || !isfinite(in->model_prior[g])) {
            return cluster_fail_all(out, EM_G_MAX, MD_E_ARG, EM_FAIL_ARG);
        }
    }
    out->g_max = cfg->g_max;
    const md_status_t st = cluster_prepare(cfg, in, ws, out);
    if (st != MD_OK) {
        return st;
    }
    for (size_t g = 0u; g < EM_G_MAX; ++g) {
        if (g >= cfg->g_max) {
            out->model[g].fit.status = MD_E_ARG;
            out->model[g].fit.reason = EM_FAIL_NOT_RUN;
            continue;
        }
        cluster_fit_one(cfg, in, g + 1u, ws, &out->model[g]);
    }
    cluster_posterior(in, out);
    const md_status_t s1 = out->model[0].fit.status;
    return (out->best_g > 0u) ? MD_OK : ((s1 < 0) ? s1 : MD_E_DEGENERATE);
}

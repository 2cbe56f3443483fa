/// @file mhtc.c
/// MHTC steps 1-8 (thesis §4.2.3): prediction, model classes, MAP-EM per
/// parent, data association and the best-L children (see mhtc.h).
#include "tracking/mhtc.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "cluster/em_modes.h"
#include "numeric/linalg.h"
#include "tracking/mhtc_internal.h"

#define MHTC_NO_SLOT SIZE_MAX /* no model slot */
#define MHTC_COV_REG 1e-3     /* ridge (relative to the mean eigenvalue) on a Σ_j mapped into a new basis */

static const mhtc_hyp_t g_root = {0}; /* the empty parent of the first interval */

void mhtc_config_default(mhtc_config_t *cfg, mhtc_tracker_t tracker)
{
    if (cfg == NULL) {
        return;
    }
    memset(cfg, 0, sizeof *cfg);
    cfg->tracker = tracker;
    cfg->L = MHTC_L_MAX;
    cfg->g_max = MHTC_G_MAX;
    cfg->lambda_new = 0.01; /* Table 4.1 */
    cfg->lambda_false = 0.015;
    cfg->lambda_first = MHTC_LAMBDA_FIRST_DEFAULT;
    cfg->pd.pd_max = 0.98;
    cfg->pd.pd_min = 0.75;
    cfg->pd.a = 0.6; /* §4.4.2 */
    cfg->pd.b = 4.0;
    cfg->beta = 0.001;
    cfg->k_miss = 5u;
    cfg->n_scan = MHTC_N_SCAN_DEFAULT;
    cfg->nn_k_miss = 1u;
    cfg->q_process = MHTC_Q_DEFAULT_UV2;
    cfg->init_var = MHTC_Q_DEFAULT_UV2;
    cfg->q_move_per_um = MHTC_Q_MOVE_PER_UM_DEFAULT;
    cfg->evidence = (tracker == MHTC_TRACKER_ML_NN) ? CLUSTER_EVIDENCE_BIC : CLUSTER_EVIDENCE_LAPLACE;
    em_options_default(&cfg->em);
    cfg->shape_prior_width = EM_SHAPE_PRIOR_WIDTH;
    cfg->nn_gate_sigma = 2.0;
    cfg->gnn_gate_chi2 = 9.21;
    cfg->share_jeffreys = MHTC_SHARE_JEFFREYS_DEFAULT;
    cfg->warm_jeffreys = MHTC_WARM_JEFFREYS_DEFAULT;
    cfg->seed_from_others = true;
    cfg->provisional_ids = true;
    cfg->unimodal_ratio = MHTC_UNIMODAL_RATIO_DEFAULT;
    cfg->count_sigma = MHTC_COUNT_SIGMA_DEFAULT;
}

md_status_t mhtc_config_check(const mhtc_config_t *c)
{
    if (c == NULL) {
        return MD_E_ARG;
    }
    const bool tracker_ok = (c->tracker == MHTC_TRACKER_MHTC) || (c->tracker == MHTC_TRACKER_MAP_NN) ||
                            (c->tracker == MHTC_TRACKER_ML_NN) || (c->tracker == MHTC_TRACKER_GNN);
    const bool pd_ok = (c->pd.pd_min > 0.0) && (c->pd.pd_min <= c->pd.pd_max) && (c->pd.pd_max < 1.0) &&
                       (c->pd.a >= 0.0) && (c->pd.b > 0.0);
    const bool ok = tracker_ok && pd_ok && (c->L >= 1u) && (c->L <= MHTC_L_MAX) && (c->g_max >= 1u) &&
                    (c->g_max <= MHTC_G_MAX) && (c->lambda_new > 0.0) && (c->lambda_false > 0.0) &&
                    (c->lambda_first > 0.0) && (c->beta >= 0.0) && (c->beta < 1.0) && (c->k_miss >= 1u) &&
                    (c->k_miss <= MHTC_HIST_MAX) && (c->n_scan < MHTC_HIST_MAX) && (c->nn_k_miss >= 1u) &&
                    (c->nn_k_miss <= MHTC_HIST_MAX) && (c->q_process > 0.0) && isfinite(c->q_process) &&
                    (c->init_var > 0.0) && (c->q_move_per_um >= 0.0) && isfinite(c->q_move_per_um) &&
                    isfinite(c->init_var) && (c->em.max_iter >= 1u) && (c->em.max_iter <= MD_EM_MAX_ITER) &&
                    (c->em.tol > 0.0) && (c->shape_prior_width > 0.0) && (c->nn_gate_sigma > 0.0) &&
                    (c->gnn_gate_chi2 > 0.0) && (c->share_jeffreys >= 0.0) && isfinite(c->share_jeffreys) &&
                    (c->warm_jeffreys >= 0.0) && (c->unimodal_ratio >= 0.0) && (c->unimodal_ratio <= 1.0) &&
                    (c->count_sigma >= 0.0) && isfinite(c->count_sigma) &&
                    ((c->evidence == CLUSTER_EVIDENCE_LAPLACE) || (c->evidence == CLUSTER_EVIDENCE_BIC));
    return ok ? MD_OK : MD_E_ARG;
}

md_status_t mhtc_init(mhtc_state_t *st, const mhtc_config_t *cfg)
{
    if ((st == NULL) || (mhtc_config_check(cfg) != MD_OK)) {
        return MD_E_ARG;
    }
    memset(st, 0, sizeof *st);
    st->cfg = *cfg;
    st->next_id = 1u;
    return MD_OK;
}

const char *mhtc_tracker_name(mhtc_tracker_t tracker)
{
    switch (tracker) {
    case MHTC_TRACKER_MHTC: return "mhtc";
    case MHTC_TRACKER_MAP_NN: return "map-nn";
    case MHTC_TRACKER_ML_NN: return "ml-nn";
    case MHTC_TRACKER_GNN: return "gnn";
    default: return "?";
    }
}

md_status_t mhtc_tracker_parse(const char *name, mhtc_tracker_t *tracker)
{
    if ((name == NULL) || (tracker == NULL)) {
        return MD_E_ARG;
    }
    for (int t = (int)MHTC_TRACKER_MHTC; t <= (int)MHTC_TRACKER_GNN; ++t) {
        if (strcmp(name, mhtc_tracker_name((mhtc_tracker_t)t)) == 0) {
            *tracker = (mhtc_tracker_t)t;
            return MD_OK;
        }
    }
    return MD_E_ARG;
}

const mhtc_hyp_t *mhtc_parent(const mhtc_state_t *st, size_t p)
{
    return (st->n_hyp == 0u) ? &g_root : &st->hyp[p];
}

static bool mhtc_input_ok(const mhtc_state_t *st, const mhtc_input_t *in, const mhtc_workspace_t *ws)
{
    if ((in == NULL) || (ws == NULL) || (in->basis == NULL) || (in->noise_cov == NULL) || (in->n > EM_N_MAX) ||
        ((in->n > 0u) && ((in->y == NULL) || ((in->wave == NULL) && (in->wave_i16 == NULL)))) ||
        ((in->wave == NULL) && (in->n > 0u) && !(in->wave_gain > 0.0 && isfinite(in->wave_gain))) ||
        !(in->duration_s > 0.0) || !isfinite(in->duration_s) || !(in->move_um >= 0.0) || !isfinite(in->move_um)) {
        return false;
    }
    const pca_basis_t *b = in->basis;
    if ((b->d < 1u) || (b->d > EM_D_MAX) || (b->d_w < b->d) || (b->d_w > KF_DW_MAX) || (in->stride < b->d_w) ||
        ((st->d_w != 0u) && (st->d_w != b->d_w))) {
        return false;
    }
    if (!linalg_all_finite(b->b, b->d * b->d_w) || !linalg_all_finite(in->noise_cov, b->d * b->d) ||
        ((in->n > 0u) && !linalg_all_finite(in->y, in->n * b->d))) {
        return false;
    }
    for (size_t i = 0u; (in->wave != NULL) && (i < in->n); ++i) { /* int16 input is finite by type */
        if (!linalg_all_finite(&in->wave[i * in->stride], b->d_w)) {
            return false;
        }
    }
    return true;
}

void mhtc_map_sigma(const mhtc_track_t *t, const double *h, size_t d, size_t dw, double *c)
{
    double hu[KF_D_MAX][KF_D_MAX];
    for (size_t i = 0u; i < t->sigma_rank; ++i) {
        for (size_t r = 0u; r < d; ++r) {
            double s = 0.0;
            for (size_t q = 0u; q < dw; ++q) {
                s += h[r * dw + q] * (double)t->sigma_vec[i][q];
            }
            hu[i][r] = s;
        }
    }
    double tr = 0.0;
    for (size_t i = 0u; i < t->sigma_rank; ++i) {
        tr += t->sigma_val[i];
    }
    const double ridge = MHTC_COV_REG * ((tr > 0.0) ? tr / (double)d : 1.0);
    for (size_t r = 0u; r < d; ++r) {
        for (size_t q = 0u; q < d; ++q) {
            double s = (r == q) ? ridge : 0.0;
            for (size_t i = 0u; i < t->sigma_rank; ++i) {
                s += t->sigma_val[i] * hu[i][r] * hu[i][q];
            }
            c[r * d + q] = s;
        }
    }
}

md_status_t mhtc_predict_record(const mhtc_state_t *st, kf_state_t *kf, double move_um, kf_work_t *ws)
{
    /* Moving the electrode scales a neuron's whole waveform (amplitude law
     * A ∝ 1/(1 + (d/d0)²)): the uncertainty it adds lies along x̂. */
    const double s = st->cfg.q_move_per_um * move_um;
    return kf_predict_scaled(kf, st->cfg.q_process, s * s, ws);
}

/* Step 1: eq. 4.7-4.9 and S_j (eq. 4.13) of every live record, once per record. */
static md_status_t mhtc_predict_pool(const mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws)
{
    const size_t d = in->basis->d;
    const size_t dw = in->basis->d_w;
    for (size_t r = 0u; r < MHTC_POOL; ++r) {
        const mhtc_track_t *t = &st->pool[r];
        if (t->refs == 0u) {
            continue;
        }
        kf_state_t kf = t->kf;
        double hlh[EM_D_MAX * EM_D_MAX];
        if ((mhtc_predict_record(st, &kf, in->move_um, &ws->kf) != MD_OK) ||
            (kf_measure(&kf, in->basis->b, d, ws->pred_mu[r], hlh) != MD_OK)) {
            return MD_E_NUMERIC;
        }
        mhtc_map_sigma(t, in->basis->b, d, dw, ws->pred_c[r]);
        const double n = (t->n_last > 1.0) ? t->n_last : 1.0;
        for (size_t i = 0u; i < d * d; ++i) {
            ws->pred_s[r][i] = hlh[i] + ws->pred_c[r][i] / n; /* S = HΛHᵀ + R_j, R_j = Σ_j/n_j */
        }
    }
    return MD_OK;
}

size_t mhtc_fill_targets(const mhtc_state_t *st, mhtc_workspace_t *ws, size_t p)
{
    const mhtc_hyp_t *h = mhtc_parent(st, p);
    for (size_t j = 0u; j < h->n_tracks; ++j) {
        const size_t r = h->track[j];
        em_target_t *t = &ws->targets[j];
        memcpy(t->mean, ws->pred_mu[r], sizeof t->mean);
        memcpy(t->s_cov, ws->pred_s[r], sizeof t->s_cov);
        memcpy(t->cluster_cov, ws->pred_c[r], sizeof t->cluster_cov);
        t->p_detect = st->pool[r].p_detect;
        ws->n_expect[j] = MHTC_COUNT_MEDIAN ? mhtc_count_reference(st->pool[r].n_last, st->pool[r].n_prev)
                                            : st->pool[r].n_last;
        /* each miss makes the rate less certain (a neuron that pauses may fire again only partly) */
        ws->count_spread[j] = 1.0 + (double)st->pool[r].misses;
    }
    return h->n_tracks;
}

static bool mhtc_priors_within(const mhtc_state_t *st, const mhtc_workspace_t *ws, size_t d, size_t q, size_t p,
                               double jeffreys_max, double pd_max);

/* A fitted model of class g of an earlier parent whose prior is within cfg.warm_jeffreys of
 * parent p's (the first, i.e. the most probable such parent's), or MHTC_NO_SLOT. */
static size_t mhtc_warm_donor(const mhtc_state_t *st, const mhtc_workspace_t *ws, size_t d, size_t g, size_t p)
{
    for (size_t q = 0u; (q < ws->n_models) && (q < sizeof ws->model / sizeof ws->model[0]); ++q) {
        const size_t r = ws->model[q].parent;
        if ((ws->model[q].g == g) && (r != p) && mhtc_priors_within(st, ws, d, r, p, st->cfg.warm_jeffreys, 1.0)) {
            return q;
        }
    }
    return MHTC_NO_SLOT;
}

/* A fit with two clusters that form one mode (em_modes.h) reads one neuron as two; the class
 * with fewer clusters is the reading of that interval. A ratio that cannot be computed drops the
 * fit too (its shapes are not SPD, so its evidence would fail as well). */
static bool mhtc_oversplit(mhtc_state_t *st, const em_params_t *params)
{
    if (!(st->cfg.unimodal_ratio > 0.0) || (params->g < 2u)) {
        return false;
    }
    bool split = false;
    if (em_params_oversplit(params, st->cfg.unimodal_ratio, &split) != MD_OK) {
        return true;
    }
    if (split) {
        st->stats.models_oversplit++;
    }
    return split;
}

/* Seeds of a class without a warm start (§3.3.4). A split class (G > J) is seeded from the
 * targets of the most probable other parent with exactly G tracks, when there is one: its
 * tracks are a reading of this interval's data with G clusters, where the split of this
 * parent's own targets (the widest group cut at its largest gap) carries nothing of the data's
 * structure and EM creeps from it along the split's flat ridge. Either is only a starting
 * point of the same MAP iteration under this parent's prior. ws->targets holds this
 * parent's targets again on return. */
static md_status_t mhtc_seed(mhtc_state_t *st, const em_data_t *data, size_t nt, mhtc_workspace_t *ws,
                             const mhtc_model_t *m)
{
    cluster_workspace_t *c = &ws->cl;
    const size_t parents = (st->n_hyp == 0u) ? 1u : st->n_hyp;
    for (size_t r = 0u; st->cfg.seed_from_others && (m->g > nt) && (r < parents) && (r < MHTC_L_MAX); ++r) {
        if ((r == m->parent) || (mhtc_parent(st, r)->n_tracks != m->g)) {
            continue;
        }
        (void)mhtc_fill_targets(st, ws, r);
        const md_status_t s = em_seed_from_targets(data, ws->targets, m->g, m->g, &c->seed_ws, c->seed);
        (void)mhtc_fill_targets(st, ws, m->parent);
        if (s == MD_OK) {
            st->stats.models_seeded_other++;
            return MD_OK;
        }
    }
    return em_seed_from_targets(data, ws->targets, nt, m->g, &c->seed_ws, c->seed);
}

/* Steps 4-5 for one model class: MAP-EM under this parent's prior (ws->cl.prior); labels.
 * Returns true if the fit was dropped as one mode read as two clusters (counted apart from failures).
 * A class with more clusters than the parent has tracks starts from a warm donor's Θ̂ when
 * there is one: its §3.3.4 seed splits a group at a gap, a heuristic that carries nothing of
 * the parent, and EM then creeps along the split's flat ridge (docs/mhtc.md). A class with at
 * most as many clusters as tracks keeps its seeds: they are the parent's own targets, and
 * warm-starting those too made the interval's hypotheses alike and cost closed-loop ID
 * consistency (docs/tracking-eval.md). */
static bool mhtc_fit_model(mhtc_state_t *st, const em_data_t *data, size_t nt, mhtc_workspace_t *ws, mhtc_model_t *m)
{
    cluster_workspace_t *c = &ws->cl;
    m->usable = false;
    const size_t warm = (m->g > nt) ? mhtc_warm_donor(st, ws, data->d, m->g, m->parent) : MHTC_NO_SLOT;
    const size_t gi = (size_t)m->g - 1u;
    const bool warm_dropped = (warm == MHTC_NO_SLOT) && (m->g > nt) && ws->one_mode_ok[gi] &&
                              mhtc_priors_within(st, ws, data->d, ws->one_mode_parent[gi], m->parent,
                                                 st->cfg.warm_jeffreys, 1.0);
    md_status_t fs = MD_E_ARG;
    if ((warm != MHTC_NO_SLOT) || warm_dropped) {
        const em_params_t *from = warm_dropped ? &ws->one_mode[gi] : &ws->model[warm].fit.params;
        fs = em_fit_from(data, &c->outlier, &c->prior, from, &st->cfg.em, c->z, &m->fit);
        st->stats.models_warm++;
    }
    if ((fs != MD_OK) && (fs != MD_E_NOCONVERGE)) {
        if (mhtc_seed(st, data, nt, ws, m) != MD_OK) {
            return false;
        }
        fs = em_fit(data, &c->outlier, &c->prior, c->seed, m->g, &st->cfg.em, c->z, &m->fit);
    }
    if ((fs != MD_OK) && (fs != MD_E_NOCONVERGE)) {
        return false;
    }
    if (mhtc_oversplit(st, &m->fit.params)) {
        if (m->g > nt) { /* only a split class starts warm from it: a class seeded by its own targets would evict it */
            ws->one_mode[gi] = m->fit.params;
            ws->one_mode_parent[gi] = m->parent;
            ws->one_mode_ok[gi] = true;
        }
        return true;
    }
    em_labels(c->z, data->n, m->g, m->labels);
    m->usable = true; /* P4 follows for every model at once (mhtc_evidence_all) */
    return false;
}

/* BIC/2 instead of a Laplace evidence that does not exist (Hessian not PD,
 * e.g. π_0 at its boundary), counted: the model is kept. Its scale differs
 * from Laplace by O(η) terms: see docs/mhtc.md. */
static void mhtc_evidence_fallback(mhtc_state_t *st, size_t n, mhtc_model_t *m)
{
    st->stats.evidence_fallbacks++;
    m->log_ev = em_evidence_bic(m->fit.log_lik, m->fit.params.d, m->g, n);
}

/* The mean prior of parent p (eq. 3.8-3.10) into ws->cl.prior. */
static md_status_t mhtc_parent_prior(const mhtc_state_t *st, size_t d, double volume, mhtc_workspace_t *ws, size_t p)
{
    const size_t nt = mhtc_fill_targets(st, ws, p);
    return em_prior_init(d, ws->targets, nt, st->cfg.lambda_new + st->cfg.lambda_false, volume, &ws->cl.prior);
}

/* Step 6 for every model that evaluates the fit of slot s: one data part of
 * the Laplace Hessian at that Θ̂, finished under each model's parent prior
 * (the prior enters eq. 3.18 only through log p(μ̂) and the mean blocks). */
static void mhtc_evidence_of_fit(mhtc_state_t *st, const em_data_t *data, double volume, mhtc_workspace_t *ws, size_t s)
{
    em_evidence_work_t *ev = &ws->cl.ev;
    const bool have_data = (em_evidence_data(data, &ws->cl.outlier, &ws->model[s].fit.params, ev) == MD_OK);
    for (size_t t = s; t < ws->n_models; ++t) {
        mhtc_model_t *m = &ws->model[t];
        if (m->ev_src != s) {
            continue;
        }
        if (!have_data || (mhtc_parent_prior(st, data->d, volume, ws, m->parent) != MD_OK) ||
            (em_evidence_finish(&ws->cl.prior, &m->fit.params, st->cfg.shape_prior_width, ev, &m->log_ev) != MD_OK) ||
            !isfinite(m->log_ev)) {
            mhtc_evidence_fallback(st, data->n, m);
        }
    }
}

/* Step 6, P4 of every model hypothesis of the interval (BIC or Laplace). */
static void mhtc_evidence_all(mhtc_state_t *st, const em_data_t *data, double volume, mhtc_workspace_t *ws)
{
    for (size_t s = 0u; s < ws->n_models; ++s) {
        mhtc_model_t *m = &ws->model[s];
        if (st->cfg.evidence == CLUSTER_EVIDENCE_BIC) {
            m->log_ev = em_evidence_bic(m->fit.log_lik, data->d, m->g, data->n);
        } else if (m->ev_src == s) {
            mhtc_evidence_of_fit(st, data, volume, ws, s);
        } else {
            /* evaluated with its source fit, which has a lower slot */
        }
    }
}

/* Step 7: A* of eq. 4.25 from ζ (eq. 4.26) and the L best assignments. */
static bool mhtc_associate(mhtc_state_t *st, mhtc_workspace_t *ws, mhtc_model_t *m, size_t nt)
{
    double pd[MHTC_TARGETS_MAX];
    for (size_t j = 0u; j < nt; ++j) {
        pd[j] = ws->targets[j].p_detect;
    }
    /* in the workspace, not on the stack: this frame lies on the firmware's deepest path */
    ws->count = (mhtc_count_term_t){&m->fit.n_soft[1], ws->n_expect, ws->count_spread, st->cfg.count_sigma};
    const double lambda_new = (st->n_hyp == 0u) ? st->cfg.lambda_first : st->cfg.lambda_new;
    if (mhtc_assoc_costs(&m->fit.zeta[0][0], EM_J_MAX + 1u, m->g, pd, nt, lambda_new, st->cfg.lambda_false, &ws->count,
                         ws->cost) != MD_OK) {
        return false;
    }
    ws->murty.solves = 0u;
    if ((murty_best(ws->cost, m->g, nt + 2u * m->g, st->cfg.L, &ws->murty, m->sol, &m->n_sol) != MD_OK) ||
        (m->n_sol == 0u)) {
        return false;
    }
    st->stats.murty_solves += ws->murty.solves;
    double c[MHTC_L_MAX];
    for (size_t l = 0u; l < m->n_sol; ++l) {
        c[l] = m->sol[l].cost;
    }
    m->log_norm = mhtc_log_norm(c, m->n_sol); /* Remark 4.3: normalise over the L best */
    return true;
}

size_t mhtc_empty_model(mhtc_state_t *st, mhtc_workspace_t *ws, size_t p)
{
    if (ws->n_models >= MHTC_MODELS_MAX) {
        return MHTC_MODELS_MAX;
    }
    const mhtc_hyp_t *h = mhtc_parent(st, p);
    double pd[MHTC_TARGETS_MAX];
    for (size_t j = 0u; j < h->n_tracks; ++j) {
        pd[j] = st->pool[h->track[j]].p_detect;
    }
    mhtc_model_t *m = &ws->model[ws->n_models];
    memset(m, 0, sizeof *m);
    m->parent = (uint8_t)p;
    m->usable = true;
    m->n_sol = 1u;
    if (mhtc_log_p3(pd, h->n_tracks, 0u, st->cfg.lambda_new + st->cfg.lambda_false, &m->log_p3) != MD_OK) {
        m->log_p3 = 0.0;
    }
    return ws->n_models++;
}

/* A fitted model of a parent with a similar prior, re-evaluated under parent p's prior
 * (ws->cl.prior): ζ (eq. 3.14) and log-posterior (eq. 3.4) at the shared Θ̂; P4 follows in
 * mhtc_evidence_all. The parameters stay the donor's MAP estimate (thesis §4.6: one
 * clustering for similar priors). */
static bool mhtc_reuse_model(mhtc_state_t *st, mhtc_workspace_t *ws, size_t donor_slot, mhtc_model_t *m)
{
    const uint8_t parent = m->parent;
    const double lp3 = m->log_p3;
    *m = ws->model[donor_slot];
    m->parent = parent;
    m->log_p3 = lp3;
    m->ev_src = (uint8_t)donor_slot;
    memset(m->fit.zeta, 0, sizeof m->fit.zeta);
    double lp = m->fit.log_lik;
    for (size_t g = 0u; g < m->g; ++g) {
        lp += em_prior_log_mean(&ws->cl.prior, m->fit.params.mean[g], m->fit.zeta[g]);
    }
    m->fit.log_post = lp;
    st->stats.models_reused++;
    return isfinite(lp);
}

/* Slot of the donor model of class g among slots [first, first + count), or MHTC_NO_SLOT. */
static size_t mhtc_donor(const mhtc_workspace_t *ws, size_t first, size_t count, size_t g)
{
    for (size_t m = first; (m < first + count) && (m < sizeof ws->model / sizeof ws->model[0]); ++m) {
        if (ws->model[m].g == g) {
            return m;
        }
    }
    return MHTC_NO_SLOT;
}

/* Steps 2-7 for parent p: P3 pruning (eq. 4.11), prior (eq. 4.12), fits, associations.
 * The first interval has no parent to predict its clusters: eq. 4.32 with no tracks and
 * λ0 = λν + λφ = 0.025 would allow G = 1 only (G = 2 has P3 ≈ 3·10⁻⁴ < β), and a recording that
 * starts with three neurons would need three intervals to admit them, one per interval.
 * There every model class G = 1..g_max gets the same P3 = 1/g_max (no information on the
 * number of neurons), as the clustering of thesis ch. 3 does without tracking.
 * With a donor range (count > 0), a model class the donor fitted is re-evaluated, not refitted. */
static void mhtc_expand_parent(mhtc_state_t *st, const em_data_t *data, double volume, mhtc_workspace_t *ws, size_t p,
                               size_t donor_first, size_t donor_count)
{
    const size_t nt = mhtc_fill_targets(st, ws, p);
    const double l0 = st->cfg.lambda_new + st->cfg.lambda_false;
    double pd[MHTC_TARGETS_MAX];
    for (size_t j = 0u; j < nt; ++j) {
        pd[j] = ws->targets[j].p_detect;
    }
    if (em_prior_init(data->d, ws->targets, nt, l0, volume, &ws->cl.prior) != MD_OK) {
        st->stats.models_failed += (uint32_t)st->cfg.g_max;
        return;
    }
    for (size_t g = 1u; g <= st->cfg.g_max; ++g) {
        double lp3 = 0.0;
        if (st->n_hyp == 0u) {
            lp3 = -log((double)st->cfg.g_max); /* first interval: every class alike (above) */
        } else if ((mhtc_log_p3(pd, nt, g, l0, &lp3) != MD_OK) || !(exp(lp3) > st->cfg.beta)) {
            st->stats.models_pruned++; /* eq. 4.11 */
            continue;
        } else {
            /* a later interval whose class passed eq. 4.11 */
        }
        mhtc_model_t *m = &ws->model[ws->n_models];
        memset(m, 0, sizeof *m);
        m->g = (uint8_t)g;
        m->parent = (uint8_t)p;
        m->log_p3 = lp3;
        m->ev_src = (uint8_t)ws->n_models;
        const size_t donor = mhtc_donor(ws, donor_first, donor_count, g);
        bool oversplit = false;
        if (donor != MHTC_NO_SLOT) {
            m->usable = mhtc_reuse_model(st, ws, donor, m);
        } else {
            oversplit = mhtc_fit_model(st, data, nt, ws, m);
        }
        m->usable = m->usable && mhtc_associate(st, ws, m, nt);
        if (!m->usable) {
            st->stats.models_failed += oversplit ? 0u : 1u;
            continue;
        }
        ws->n_models++;
    }
}

/* Step 8: every child of every model, scored by eq. 4.30, offered to the best-L list. */
static void mhtc_collect(mhtc_state_t *st, mhtc_workspace_t *ws)
{
    ws->n_cand = 0u;
    for (size_t m = 0u; m < ws->n_models; ++m) {
        const mhtc_model_t *mod = &ws->model[m];
        const double base = mod->log_p3 + mod->log_ev + mhtc_parent(st, mod->parent)->log_prob;
        for (size_t s = 0u; s < mod->n_sol; ++s) {
            if (mhtc_child_track_count(st, ws, m, s, st->cfg.k_miss) > MHTC_TARGETS_MAX) {
                st->stats.target_overflow++;
                continue;
            }
            mhtc_cand_t c;
            memset(&c, 0, sizeof c);
            c.model = (uint8_t)m;
            c.sol = (uint8_t)s;
            c.log_assoc = (mod->g > 0u) ? -mod->sol[s].cost - mod->log_norm : 0.0; /* eq. 4.30 ratio */
            c.score = c.log_assoc + base;                                          /* × P3 P4 P5 */
            mhtc_solution_tags(st, ws, m, s, c.tag);
            mhtc_offer(st, ws, &c);
        }
    }
}

/* The first parent q < p whose track list names the same pool records in the same order, else p.
 * Such parents have bit-identical targets (mhtc_fill_targets reads only the records), hence the
 * same prior (eq. 3.8-3.10), seeds (eq. 3.16), P3 (eq. 4.11), fits and associations. */
static size_t mhtc_same_prior(const mhtc_state_t *st, size_t p)
{
    const mhtc_hyp_t *h = mhtc_parent(st, p);
    for (size_t q = 0u; q < p; ++q) {
        const mhtc_hyp_t *o = mhtc_parent(st, q);
        if ((o->n_tracks == h->n_tracks) && (memcmp(o->track, h->track, h->n_tracks * sizeof h->track[0]) == 0)) {
            return q;
        }
    }
    return p;
}

/* Jeffreys divergence (symmetric KL) of N(μa, Sa) and N(μb, Sb), d ≤ EM_D_MAX:
 * ½ tr(Sb⁻¹Sa + Sa⁻¹Sb) - d + ½ δᵀ(Sa⁻¹ + Sb⁻¹)δ. +inf if either S is not SPD. */
static double mhtc_jeffreys(const double *ma, const double *sa, const double *mb, const double *sb, size_t d)
{
    double ia[EM_D_MAX * EM_D_MAX];
    double ib[EM_D_MAX * EM_D_MAX];
    double work[EM_D_MAX * EM_D_MAX];
    if ((linalg_spd_inverse(sa, d, ia, work, NULL) != MD_OK) || (linalg_spd_inverse(sb, d, ib, work, NULL) != MD_OK)) {
        return HUGE_VAL;
    }
    double j = -(double)d;
    for (size_t r = 0u; r < d; ++r) {
        for (size_t c = 0u; c < d; ++c) {
            j += 0.5 * (ib[r * d + c] * sa[c * d + r] + ia[r * d + c] * sb[c * d + r]);
            j += 0.5 * (ma[r] - mb[r]) * (ia[r * d + c] + ib[r * d + c]) * (ma[c] - mb[c]);
        }
    }
    return j;
}

/* Parents q and p have the same number of targets and each of p's targets has its own target
 * of q (in any order: target order only labels ζ's columns, which are recomputed) whose
 * prediction is within cfg.share_jeffreys and whose P_d is within MHTC_SHARE_PD: the thesis'
 * "similar priors" (§4.6). Greedy one-to-one matching; O(J^2 d^3). */
static bool mhtc_priors_within(const mhtc_state_t *st, const mhtc_workspace_t *ws, size_t d, size_t q, size_t p,
                               double jeffreys_max, double pd_max)
{
    const mhtc_hyp_t *a = mhtc_parent(st, q);
    const mhtc_hyp_t *b = mhtc_parent(st, p);
    if ((a->n_tracks != b->n_tracks) || !(jeffreys_max > 0.0) || (a->n_tracks > MHTC_TARGETS_MAX)) {
        return false;
    }
    bool used[MHTC_TARGETS_MAX] = {false};
    for (size_t j = 0u; j < b->n_tracks; ++j) {
        const size_t rb = b->track[j];
        bool found = false;
        for (size_t k = 0u; (k < a->n_tracks) && !found; ++k) {
            const size_t ra = a->track[k];
            found = !used[k] && (ra < MHTC_POOL) && (rb < MHTC_POOL) &&
                    ((ra == rb) || ((fabs(st->pool[ra].p_detect - st->pool[rb].p_detect) <= pd_max) &&
                                    (mhtc_jeffreys(ws->pred_mu[ra], ws->pred_s[ra], ws->pred_mu[rb], ws->pred_s[rb],
                                                   d) <= jeffreys_max)));
            used[k] = used[k] || found;
        }
        if (!found) {
            return false;
        }
    }
    return true;
}

/* Parent p gets copies of the model hypotheses slots [first, first + count) fitted for an
 * identical prior: exact sharing, the EM is deterministic in its inputs. */
static void mhtc_share_models(mhtc_state_t *st, mhtc_workspace_t *ws, size_t first, size_t count, size_t p)
{
    for (size_t m = first; (m < first + count) && (ws->n_models < sizeof ws->model / sizeof ws->model[0]); ++m) {
        ws->model[ws->n_models] = ws->model[m];
        ws->model[ws->n_models].parent = (uint8_t)p;
        ws->n_models++;
        st->stats.models_shared++;
    }
}

/* Steps 2-7 for every parent, fitting once per distinct set of predicted targets. */
static void mhtc_expand_all(mhtc_state_t *st, const em_data_t *data, double volume, mhtc_workspace_t *ws,
                            size_t parents)
{
    uint8_t *first = ws->parent_first; /* model slots and counts: ≤ MHTC_MODELS_MAX ≤ 255 */
    uint8_t *count = ws->parent_count;
    uint8_t *pruned = ws->parent_pruned; /* per parent ≤ MHTC_G_MAX */
    uint8_t *failed = ws->parent_failed;
    bool *fitted = ws->parent_fitted; /* parents whose models came from their own EM fits */
    memset(ws->parent_first, 0, sizeof ws->parent_first);
    memset(ws->parent_count, 0, sizeof ws->parent_count);
    memset(ws->parent_pruned, 0, sizeof ws->parent_pruned);
    memset(ws->parent_failed, 0, sizeof ws->parent_failed);
    memset(ws->parent_fitted, 0, sizeof ws->parent_fitted);
    for (size_t p = 0u; (p < parents) && (p < MHTC_L_MAX); ++p) {
        const size_t q = mhtc_same_prior(st, p);
        if (q < p) {
            mhtc_share_models(st, ws, first[q], count[q], p);
            st->stats.models_pruned += pruned[q];
            st->stats.models_failed += failed[q];
            first[p] = first[q];
            count[p] = 0u;
            continue;
        }
        size_t donor = p;
        for (size_t r = 0u; (r < p) && (donor == p); ++r) {
            donor = (fitted[r] && mhtc_priors_within(st, ws, data->d, r, p, st->cfg.share_jeffreys, MHTC_SHARE_PD)) ? r
                                                                                                                    : p;
        }
        fitted[p] = (donor == p);
        const uint32_t pruned0 = st->stats.models_pruned;
        const uint32_t failed0 = st->stats.models_failed;
        first[p] = (uint8_t)ws->n_models;
        mhtc_expand_parent(st, data, volume, ws, p, first[donor], (donor < p) ? count[donor] : 0u);
        count[p] = (uint8_t)(ws->n_models - first[p]);
        pruned[p] = (uint8_t)(st->stats.models_pruned - pruned0);
        failed[p] = (uint8_t)(st->stats.models_failed - failed0);
    }
}

static md_status_t mhtc_run_mhtc(mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws)
{
    const em_data_t data = {in->y, in->n, in->basis->d};
    const size_t parents = (st->n_hyp == 0u) ? 1u : st->n_hyp;
    double volume = 0.0;
    ws->n_models = 0u;
    memset(ws->one_mode_ok, 0, sizeof ws->one_mode_ok);
    const bool data_ok = (in->n > 0u) && (em_bounding_volume(&data, &volume) == MD_OK) &&
                         (em_outlier_init(data.d, in->noise_cov, volume, &ws->cl.outlier) == MD_OK) &&
                         (em_outlier_tabulate(&ws->cl.outlier, &data) == MD_OK);
    if (data_ok) {
        mhtc_expand_all(st, &data, volume, ws, parents);
        mhtc_evidence_all(st, &data, volume, ws);
    }
    if (ws->n_models == 0u) {
        st->stats.empty_intervals++; /* nothing clusterable: every parent continues with all tracks missed */
        for (size_t p = 0u; p < parents; ++p) {
            (void)mhtc_empty_model(st, ws, p);
        }
    }
    mhtc_collect(st, ws);
    return (ws->n_cand > 0u) ? MD_OK : MD_E_DEGENERATE;
}

md_status_t mhtc_update(mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws, mhtc_result_t *out)
{
    if ((st == NULL) || (out == NULL)) {
        return MD_E_ARG;
    }
    if (!mhtc_input_ok(st, in, ws) || (mhtc_config_check(&st->cfg) != MD_OK)) {
        st->stats.update_errors++;
        return MD_E_ARG;
    }
    memset(out, 0, sizeof *out);
    md_status_t rc = mhtc_predict_pool(st, in, ws);
    if (rc == MD_OK) {
        rc = (st->cfg.tracker == MHTC_TRACKER_MHTC) ? mhtc_run_mhtc(st, in, ws) : mhtc_baseline(st, in, ws);
    }
    if (rc == MD_OK) {
        rc = mhtc_commit(st, in, ws, out);
    }
    if (rc != MD_OK) {
        st->stats.update_errors++;
    }
    return rc;
}

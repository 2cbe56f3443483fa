/// @file mhtc_baseline.c
/// Single-hypothesis baselines behind the MHTC interface (see mhtc.h):
/// MAP-NN (argmax ζ, thesis §3.4), ML-NN (nearest neighbour within 2 σ,
/// §3.5 footnote 12) and a gated GNN (one lap_solve on A*).
#include <math.h>
#include <string.h>

#include "numeric/linalg.h"
#include "tracking/mhtc_internal.h"

/* Squared Mahalanobis distance of μ_g from target j's prediction under S_j into
 * *d2; +inf (outside every gate) when S_j is not positive definite. */
static md_status_t mhtc_d2(const mhtc_workspace_t *ws, size_t j, const double *mu, size_t d, double *d2)
{
    double l[EM_D_MAX * EM_D_MAX], work[EM_D_MAX];
    memcpy(l, ws->targets[j].s_cov, d * d * sizeof l[0]);
    if (linalg_cholesky(l, d) != MD_OK) {
        *d2 = INFINITY;
        return MD_OK;
    }
    return linalg_mahalanobis2(l, d, mu, ws->targets[j].mean, work, d2);
}

/* MAP-NN: each cluster to argmax_j ζ_gj, clusters in decreasing ζ; a taken target or j = 0 → new. */
static void mhtc_assign_map_nn(const mhtc_model_t *m, size_t nt, lap_solution_t *s)
{
    bool done[MHTC_G_MAX] = {false};
    bool taken[MHTC_TARGETS_MAX] = {false};
    for (size_t round = 0u; round < m->g; ++round) {
        size_t bg = 0u, bj = 0u;
        double bz = -1.0;
        for (size_t g = 0u; g < m->g; ++g) {
            for (size_t j = 0u; (j <= nt) && !done[g]; ++j) {
                const bool free_j = (j == 0u) || !taken[j - 1u];
                if (free_j && (m->fit.zeta[g][j] > bz)) {
                    bz = m->fit.zeta[g][j];
                    bg = g;
                    bj = j;
                }
            }
        }
        done[bg] = true;
        if (bj > 0u) {
            taken[bj - 1u] = true;
        }
        s->col_of_row[bg] = (int8_t)((bj > 0u) ? bj - 1u : nt + bg); /* j = 0: new track */
    }
}

/* ML-NN: closest (cluster, target) pairs first, within gate²; the rest are new tracks. */
static md_status_t mhtc_assign_ml_nn(const mhtc_workspace_t *ws, const mhtc_model_t *m, size_t nt, double gate2,
                                     lap_solution_t *s)
{
    double d2[MHTC_G_MAX][MHTC_TARGETS_MAX];
    for (size_t g = 0u; g < m->g; ++g) {
        s->col_of_row[g] = (int8_t)(nt + g);
        for (size_t j = 0u; j < nt; ++j) {
            const md_status_t rc = mhtc_d2(ws, j, m->fit.params.mean[g], m->fit.params.d, &d2[g][j]);
            if (rc != MD_OK) {
                return rc;
            }
        }
    }
    bool done[MHTC_G_MAX] = {false};
    bool taken[MHTC_TARGETS_MAX] = {false};
    for (size_t round = 0u; round < m->g; ++round) {
        size_t bg = MHTC_G_MAX, bj = 0u;
        for (size_t g = 0u; g < m->g; ++g) {
            for (size_t j = 0u; j < nt; ++j) {
                if (!done[g] && !taken[j] && (d2[g][j] <= gate2) && ((bg == MHTC_G_MAX) || (d2[g][j] < d2[bg][bj]))) {
                    bg = g;
                    bj = j;
                }
            }
        }
        if (bg == MHTC_G_MAX) {
            break;
        }
        done[bg] = true;
        taken[bj] = true;
        s->col_of_row[bg] = (int8_t)bj;
    }
    return MD_OK;
}

/* GNN: the single best assignment of A* with pairs outside the gate forbidden. */
static md_status_t mhtc_assign_gnn(const mhtc_state_t *st, mhtc_workspace_t *ws, const mhtc_model_t *m, size_t nt,
                                   lap_solution_t *s)
{
    double pd[MHTC_TARGETS_MAX];
    for (size_t j = 0u; j < nt; ++j) {
        pd[j] = ws->targets[j].p_detect;
    }
    /* eq. 4.25 alone: with the count term GNN's single assignment lost more IDs than it kept (docs/mhtc.md) */
    md_status_t rc = mhtc_assoc_costs(&m->fit.zeta[0][0], EM_J_MAX + 1u, m->g, pd, nt, st->cfg.lambda_new,
                                      st->cfg.lambda_false, NULL, ws->cost);
    const size_t cols = nt + 2u * m->g;
    for (size_t g = 0u; (rc == MD_OK) && (g < m->g); ++g) {
        for (size_t j = 0u; (rc == MD_OK) && (j < nt); ++j) {
            double d2 = 0.0;
            rc = mhtc_d2(ws, j, m->fit.params.mean[g], m->fit.params.d, &d2);
            if ((rc == MD_OK) && (d2 > st->cfg.gnn_gate_chi2)) {
                ws->cost[g * cols + j] = LAP_FORBIDDEN;
            }
        }
    }
    lap_problem_t p;
    if (rc == MD_OK) {
        rc = lap_problem_init(&p, ws->cost, m->g, cols);
    }
    if (rc == MD_OK) {
        rc = lap_solve(&p, s);
    }
    /* GNN track initiation: every cluster left unassigned starts a tentative track (a single
     * hypothesis cannot defer the new-vs-false decision, and λφ > λν would never start one). */
    for (size_t g = 0u; (rc == MD_OK) && (g < m->g); ++g) {
        if ((size_t)s->col_of_row[g] >= nt) {
            s->col_of_row[g] = (int8_t)(nt + g);
        }
    }
    return rc;
}

/* Clusters the interval with cluster.h (MAP with the tracks' prior, or ML) into model slot 0. */
static md_status_t mhtc_baseline_cluster(const mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws,
                                         size_t nt, mhtc_model_t *m)
{
    cluster_config_t cc;
    const bool ml = (st->cfg.tracker == MHTC_TRACKER_ML_NN);
    cluster_config_default(&cc, ml ? CLUSTER_ML : CLUSTER_MAP);
    cc.g_max = st->cfg.g_max;
    cc.em = st->cfg.em;
    cc.lambda_new = st->cfg.lambda_new;
    cc.lambda_false = st->cfg.lambda_false;
    cc.shape_prior_width = st->cfg.shape_prior_width;
    cc.evidence = ml ? CLUSTER_EVIDENCE_BIC : st->cfg.evidence;
    cc.unimodal_ratio = st->cfg.unimodal_ratio;
    const cluster_input_t ci = {{in->y, in->n, in->basis->d}, in->noise_cov, ws->targets, nt, NULL};
    const md_status_t rc = cluster_fit_models(&cc, &ci, &ws->cl, &ws->clr);
    if ((rc != MD_OK) || (ws->clr.best_g == 0u)) {
        return MD_E_DEGENERATE;
    }
    const cluster_model_t *best = &ws->clr.model[ws->clr.best_g - 1u];
    memset(m, 0, sizeof *m);
    m->fit = best->fit;
    m->g = (uint8_t)ws->clr.best_g;
    m->log_ev = best->log_evidence;
    m->usable = true;
    m->n_sol = 1u;
    memcpy(m->labels, best->labels, in->n * sizeof m->labels[0]);
    return MD_OK;
}

/* Beyond MHTC_TARGETS_MAX tracks, the last new tracks become false clusters (counted). */
static void mhtc_cap_new_tracks(mhtc_state_t *st, mhtc_workspace_t *ws, size_t nt)
{
    mhtc_model_t *m = &ws->model[0];
    const bool nn = (st->cfg.tracker == MHTC_TRACKER_MAP_NN) || (st->cfg.tracker == MHTC_TRACKER_ML_NN);
    const uint32_t k_miss = nn ? st->cfg.nn_k_miss : st->cfg.k_miss;
    for (size_t r = m->g; r-- > 0u;) {
        if (mhtc_child_track_count(st, ws, 0u, 0u, k_miss) <= MHTC_TARGETS_MAX) {
            return;
        }
        const size_t col = (size_t)m->sol[0].col_of_row[r];
        if ((col >= nt) && (col < nt + m->g)) {
            m->sol[0].col_of_row[r] = (int8_t)(nt + m->g + r);
            st->stats.target_overflow++;
        }
    }
}

md_status_t mhtc_baseline(mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws)
{
    const size_t nt = mhtc_fill_targets(st, ws, 0u);
    ws->n_models = 0u;
    ws->n_cand = 0u;
    mhtc_model_t *m = &ws->model[0];
    md_status_t rc = (in->n > 0u) ? mhtc_baseline_cluster(st, in, ws, nt, m) : MD_E_DEGENERATE;
    if (rc != MD_OK) {
        st->stats.empty_intervals++;
        (void)mhtc_empty_model(st, ws, 0u);
    } else {
        ws->n_models = 1u;
        lap_solution_t *s = &m->sol[0];
        memset(s, 0, sizeof *s);
        if (st->cfg.tracker == MHTC_TRACKER_MAP_NN) {
            mhtc_assign_map_nn(m, nt, s);
        } else if (st->cfg.tracker == MHTC_TRACKER_ML_NN) {
            rc = mhtc_assign_ml_nn(ws, m, nt, st->cfg.nn_gate_sigma * st->cfg.nn_gate_sigma, s);
        } else {
            rc = mhtc_assign_gnn(st, ws, m, nt, s);
        }
        if (rc != MD_OK) {
            return rc;
        }
    }
    mhtc_cap_new_tracks(st, ws, nt);
    mhtc_cand_t c;
    memset(&c, 0, sizeof c);
    c.model = 0u;
    c.sol = 0u;
    mhtc_solution_tags(st, ws, 0u, 0u, c.tag);
    ws->cand[0] = c;
    ws->n_cand = 1u;
    return MD_OK;
}

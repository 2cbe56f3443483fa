/// @file mhtc_commit.c
/// MHTC step 8 (best L with duplicate pruning, §4.4.1) and step 9 (Kalman
/// update, new tracks, deletion after K_miss misses, P_d rule) on the shared,
/// reference-counted track pool (see mhtc.h).
#include <math.h>
#include <string.h>

#include "cluster/em_modes.h"
#include "numeric/linalg.h"
#include "tracking/mhtc_internal.h"

#define MHTC_SRC_NEW (-1)
#define MHTC_MODEL_MISS (-1)

static uint32_t mhtc_kmiss(const mhtc_state_t *st)
{
    const bool nn = (st->cfg.tracker == MHTC_TRACKER_MAP_NN) || (st->cfg.tracker == MHTC_TRACKER_ML_NN);
    return nn ? st->cfg.nn_k_miss : st->cfg.k_miss;
}

/* Row of model m's solution s that takes parent target j, or -1 (missed). */
static int mhtc_row_of_target(const mhtc_model_t *m, size_t s, size_t j)
{
    for (size_t r = 0u; r < m->g; ++r) {
        if (m->sol[s].col_of_row[r] == (int8_t)j) {
            return (int)r;
        }
    }
    return -1;
}

void mhtc_solution_tags(const mhtc_state_t *st, const mhtc_workspace_t *ws, size_t m, size_t s, int32_t *tag)
{
    const mhtc_model_t *mod = &ws->model[m];
    const mhtc_hyp_t *par = mhtc_parent(st, mod->parent);
    const size_t nt = par->n_tracks;
    for (size_t r = 0u; r < MHTC_G_MAX; ++r) {
        tag[r] = MHTC_ID_FALSE;
    }
    for (size_t r = 0u; r < mod->g; ++r) {
        const size_t col = (size_t)mod->sol[s].col_of_row[r];
        if (col < nt) {
            tag[r] = (int32_t)st->pool[par->track[col]].id;
        } else if (col < nt + mod->g) {
            tag[r] = MHTC_TAG_NEW(m, r + 1u);
        }
    }
}

size_t mhtc_child_track_count(const mhtc_state_t *st, const mhtc_workspace_t *ws, size_t m, size_t s, uint32_t k_miss)
{
    const mhtc_model_t *mod = &ws->model[m];
    const mhtc_hyp_t *par = mhtc_parent(st, mod->parent);
    size_t n = 0u;
    for (size_t j = 0u; j < par->n_tracks; ++j) {
        const bool hit = (mod->g > 0u) && (mhtc_row_of_target(mod, s, j) >= 0);
        n += (hit || ((uint32_t)st->pool[par->track[j]].misses + 1u < k_miss)) ? 1u : 0u;
    }
    for (size_t r = 0u; r < mod->g; ++r) {
        const size_t col = (size_t)mod->sol[s].col_of_row[r];
        n += ((col >= par->n_tracks) && (col < par->n_tracks + mod->g)) ? 1u : 0u;
    }
    return n;
}

/* §4.4.1: equal assignments over the most recent K_miss intervals (this one included). */
static bool mhtc_is_duplicate(const mhtc_state_t *st, const mhtc_workspace_t *ws, const mhtc_cand_t *a,
                              const mhtc_cand_t *b)
{
    const mhtc_model_t *ma = &ws->model[a->model];
    const mhtc_model_t *mb = &ws->model[b->model];
    if ((ma->g != mb->g) || (memcmp(a->tag, b->tag, sizeof a->tag) != 0)) {
        return false;
    }
    const mhtc_hyp_t *pa = mhtc_parent(st, ma->parent);
    const mhtc_hyp_t *pb = mhtc_parent(st, mb->parent);
    const size_t depth = (st->cfg.k_miss > 0u) ? st->cfg.k_miss - 1u : 0u;
    for (size_t t = 0u; (t < depth) && (t < pa->hist_len) && (t < pb->hist_len); ++t) {
        if ((pa->hist_g[t] != pb->hist_g[t]) || (memcmp(pa->hist_id[t], pb->hist_id[t], sizeof pa->hist_id[t]) != 0)) {
            return false;
        }
    }
    return true;
}

void mhtc_offer(mhtc_state_t *st, mhtc_workspace_t *ws, const mhtc_cand_t *c)
{
    for (size_t i = 0u; i < ws->n_cand; ++i) {
        if (!mhtc_is_duplicate(st, ws, &ws->cand[i], c)) {
            continue;
        }
        st->stats.dup_pruned++;
        if (!(c->score > ws->cand[i].score)) {
            return; /* the kept one is at least as probable */
        }
        memmove(&ws->cand[i], &ws->cand[i + 1u], (ws->n_cand - i - 1u) * sizeof ws->cand[0]);
        ws->n_cand--;
        break;
    }
    size_t pos = ws->n_cand;
    while ((pos > 0u) && (c->score > ws->cand[pos - 1u].score)) {
        --pos; /* ties keep first-come order: deterministic */
    }
    if (pos >= st->cfg.L) {
        return;
    }
    const size_t keep = (ws->n_cand < st->cfg.L) ? ws->n_cand : st->cfg.L - 1u;
    memmove(&ws->cand[pos + 1u], &ws->cand[pos], (keep - pos) * sizeof ws->cand[0]);
    ws->cand[pos] = *c;
    ws->n_cand = keep + 1u;
}

/* Staged record with key (src, model, g), or n_staged if none. */
static size_t mhtc_find_staged(const mhtc_workspace_t *ws, int src, int model, size_t g)
{
    for (size_t i = 0u; i < ws->n_staged; ++i) {
        if ((ws->staged_src[i] == src) && (ws->staged_model[i] == model) && (ws->staged_g[i] == g)) {
            return i;
        }
    }
    return ws->n_staged;
}

/* The record keys a candidate needs: detected/missed parent tracks, then its new tracks. */
static size_t mhtc_cand_keys(const mhtc_state_t *st, const mhtc_workspace_t *ws, const mhtc_cand_t *c, int *src,
                             int *model, uint8_t *g)
{
    const mhtc_model_t *m = &ws->model[c->model];
    const mhtc_hyp_t *par = mhtc_parent(st, m->parent);
    const uint32_t k_miss = mhtc_kmiss(st);
    size_t n = 0u;
    for (size_t j = 0u; j < par->n_tracks; ++j) {
        const int row = (m->g > 0u) ? mhtc_row_of_target(m, c->sol, j) : -1;
        if ((row < 0) && ((uint32_t)st->pool[par->track[j]].misses + 1u >= k_miss)) {
            continue; /* deleted after K_miss consecutive misses (§4.4.1) */
        }
        src[n] = par->track[j];
        model[n] = (row < 0) ? MHTC_MODEL_MISS : (int)c->model;
        g[n] = (uint8_t)((row < 0) ? 0 : row + 1);
        ++n;
    }
    for (size_t r = 0u; r < m->g; ++r) {
        const size_t col = (size_t)m->sol[c->sol].col_of_row[r];
        if ((col >= par->n_tracks) && (col < par->n_tracks + m->g)) {
            src[n] = MHTC_SRC_NEW;
            model[n] = (int)c->model;
            g[n] = (uint8_t)(r + 1u);
            ++n;
        }
    }
    return n;
}

/* Σ_g = λ C_g of a fitted cluster, stored as waveform-space eigenpairs u_i = Hᵀ w_i. */
static void mhtc_store_sigma(mhtc_track_t *t, const em_params_t *p, size_t g, const pca_basis_t *b)
{
    const size_t d = p->d;
    double s[KF_D_MAX * KF_D_MAX], vec[KF_D_MAX * KF_D_MAX], val[KF_D_MAX];
    for (size_t i = 0u; i < d * d; ++i) {
        s[i] = p->lambda * p->shape[g - 1u][i];
    }
    t->sigma_rank = 0u;
    if (linalg_sym_eigen(s, d, val, vec, KF_JACOBI_SWEEPS) != MD_OK) {
        return;
    }
    for (size_t i = 0u; i < d; ++i) {
        for (size_t q = 0u; q < b->d_w; ++q) {
            double acc = 0.0;
            for (size_t r = 0u; r < d; ++r) {
                acc += b->b[r * b->d_w + q] * vec[r * d + i];
            }
            t->sigma_vec[i][q] = (float)acc;
        }
        t->sigma_val[i] = (val[i] > 0.0) ? val[i] : 0.0;
    }
    t->sigma_rank = (uint8_t)d;
}

/* Mean waveform of the cluster's hard members (the new track's x0); Bᵀμ if it has none. */
static void mhtc_member_mean(const mhtc_input_t *in, const mhtc_model_t *m, size_t g, mhtc_workspace_t *ws)
{
    const size_t dw = in->basis->d_w;
    const size_t d = in->basis->d;
    size_t cnt = 0u;
    memset(ws->wsum, 0, sizeof ws->wsum);
    for (size_t i = 0u; i < in->n; ++i) {
        if (m->labels[i] == g) {
            for (size_t q = 0u; q < dw; ++q) {
                ws->wsum[q] += mhtc_input_wave(in, i, q);
            }
            ++cnt;
        }
    }
    for (size_t q = 0u; q < dw; ++q) {
        if (cnt > 0u) {
            ws->wsum[q] /= (double)cnt;
            continue;
        }
        double acc = 0.0;
        for (size_t r = 0u; r < d; ++r) {
            acc += in->basis->b[r * dw + q] * m->fit.params.mean[g - 1u][r];
        }
        ws->wsum[q] = acc;
    }
}

/* R_g = Σ_g / n_g in feature space (measurement noise of eq. 4.15). */
static void mhtc_meas_noise(const em_fit_t *f, size_t g, double *r)
{
    const size_t d = f->params.d;
    const double n = (f->n_soft[g] > 1.0) ? f->n_soft[g] : 1.0;
    for (size_t i = 0u; i < d * d; ++i) {
        r[i] = f->params.lambda * f->params.shape[g - 1u][i] / n;
    }
}

/* Creates the staged record of one key (step 9). */
static void mhtc_make_record(mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws, int src, int model,
                             size_t g, uint32_t *next_id)
{
    mhtc_track_t *t = &ws->staged[ws->n_staged];
    const pca_basis_t *b = in->basis;
    const mhtc_config_t *cfg = &st->cfg;
    if (src >= 0) {
        *t = st->pool[src];
        /* eq. 4.7-4.8; the same prediction succeeded in step 1 */
        (void)mhtc_predict_record(st, &t->kf, in->move_um, &ws->kf);
    } else {
        memset(t, 0, sizeof *t);
    }
    t->refs = 0u;
    if (model == MHTC_MODEL_MISS) {
        t->misses++;
        t->rate_hz = 0.0;
        t->cluster = 0u;
        t->p_detect = mhtc_pd_next(&cfg->pd, t->p_detect, 0.0);
    } else {
        const mhtc_model_t *m = &ws->model[model];
        double r[KF_D_MAX * KF_D_MAX];
        mhtc_meas_noise(&m->fit, g, r);
        t->rate_hz = m->fit.n_soft[g] / in->duration_s;
        if (src >= 0) {
            if (kf_update(&t->kf, b->b, b->d, m->fit.params.mean[g - 1u], r, &ws->kf) != MD_OK) {
                st->stats.kf_failures++; /* keep the prediction */
            }
            t->p_detect = mhtc_pd_next(&cfg->pd, t->p_detect, t->rate_hz);
        } else {
            mhtc_member_mean(in, m, g, ws);
            if (kf_init(&t->kf, b->d_w, ws->wsum, cfg->init_var, b->b, b->d, r, &ws->kf) != MD_OK) {
                st->stats.kf_failures++;
                (void)kf_init(&t->kf, b->d_w, ws->wsum, cfg->init_var, NULL, 0u, NULL, &ws->kf);
            }
            t->p_detect = mhtc_pd_first(&cfg->pd, t->rate_hz);
            t->id = (*next_id)++;
            t->born = st->interval + 1u;
        }
        mhtc_store_sigma(t, &m->fit.params, g, b);
        t->n_prev[1] = (src >= 0) ? t->n_prev[0] : -1.0;
        t->n_prev[0] = (src >= 0) ? t->n_last : -1.0;
        t->n_last = m->fit.n_soft[g];
        t->misses = 0u;
        t->cluster = (uint8_t)g;
    }
    ws->staged_src[ws->n_staged] = (int16_t)src;
    ws->staged_model[ws->n_staged] = (int16_t)model;
    ws->staged_g[ws->n_staged] = (uint8_t)g;
    ws->n_staged++;
}

/* Mean (B^k x̂) and cluster covariance (Σ_j through B^k) of a staged record; its weight n_last. */
static void mhtc_record_view(const mhtc_track_t *t, const pca_basis_t *b, double *mean, double *cov)
{
    for (size_t c = 0u; c < b->d; ++c) {
        double acc = 0.0;
        for (size_t q = 0u; q < b->d_w; ++q) {
            acc += b->b[c * b->d_w + q] * t->kf.x[q];
        }
        mean[c] = acc;
    }
    mhtc_map_sigma(t, b->b, b->d, b->d_w, cov);
}

/* Whether missed staged record `missed` and detected staged record `det` of one hypothesis form
 * one mode (cfg.unimodal_ratio), both seen through B^k. When `det` is a track started in this
 * interval, the missed one is seen with its predicted state's spread added, Σ_j + HΛHᵀ (eq. 4.13
 * without R_j): where its neuron's cluster lies now is known only that well (after a move the
 * gain uncertainty along x̂ is wide), and a lineage that calls the track missed and starts a new
 * one on a cluster within that spread holds the neuron twice. Two tracks that both lived before
 * this interval are compared by their clusters alone: two neurons passing close by each other
 * are within each other's spread. */
static bool mhtc_same_mode(const mhtc_state_t *st, const pca_basis_t *b, mhtc_workspace_t *ws, size_t missed,
                           size_t det)
{
    const mhtc_track_t *a = &ws->staged[missed];
    const mhtc_track_t *o = &ws->staged[det];
    mhtc_record_view(a, b, ws->pair_mean[0], ws->pair_cov[0]);
    if ((MHTC_MISSED_SPREAD != 0) && (ws->staged_src[det] < 0) &&
        (kf_measure(&a->kf, b->b, b->d, ws->pair_mean[1], ws->pair_cov[1]) == MD_OK)) {
        for (size_t i = 0u; i < b->d * b->d; ++i) {
            ws->pair_cov[0][i] += ws->pair_cov[1][i];
        }
    }
    mhtc_record_view(o, b, ws->pair_mean[1], ws->pair_cov[1]);
    const double wa = (a->n_last > 1.0) ? a->n_last : 1.0;
    const double wb = (o->n_last > 1.0) ? o->n_last : 1.0;
    double r = 0.0;
    return (em_gauss_ridge_ratio(b->d, wa, ws->pair_mean[0], ws->pair_cov[0], wb, ws->pair_mean[1], ws->pair_cov[1],
                                 &r) == MD_OK) &&
           (r >= st->cfg.unimodal_ratio);
}

/* Whether the detected cluster's count says it holds one neuron, not the missed track's neuron
 * as well: two neurons crossing in feature space make one cluster of both (their counts add up)
 * for a few intervals, and the missed one must survive to take its own cluster back after. The
 * reference is the detected track's previous count, or for a new track the missed one's (a new
 * track of the same neuron has about its count). One neuron: below reference + ½ the missed
 * track's count. */
static bool mhtc_one_neuron_count(const mhtc_state_t *st, const mhtc_workspace_t *ws, size_t missed, size_t det)
{
    const int src = ws->staged_src[det];
    const double n_miss = ws->staged[missed].n_last;
    const double ref = (src >= 0) ? st->pool[src].n_last : n_miss;
    return ws->staged[det].n_last < ref + 0.5 * n_miss;
}

/* Track h->track[q] (detected, cluster g of model m) replaced by the update of the older
 * missed track's source record with that cluster: the neuron keeps its older ID in every
 * lineage that makes this merge. False if the pool has no room (the caller only drops). */
static bool mhtc_merge_into_older(mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws, mhtc_hyp_t *h,
                                  size_t q, size_t older, int32_t *tag, uint32_t *next_id)
{
    const size_t o = h->track[q];
    const int src = ws->staged_src[older];
    const int model = ws->staged_model[o];
    const size_t g = ws->staged_g[o];
    size_t r = mhtc_find_staged(ws, src, model, g);
    if (r == ws->n_staged) {
        if (ws->n_staged >= MHTC_POOL) {
            return false;
        }
        mhtc_make_record(st, in, ws, src, model, g, next_id);
    }
    ws->staged[o].refs--;
    ws->staged[r].refs++;
    h->track[q] = (uint8_t)r;
    tag[g - 1u] = (int32_t)ws->staged[r].id;
    return true;
}

/* A missed track of hypothesis h that forms one mode with one of h's detected tracks is a
 * second track of the same neuron: while it lives (K_miss) the association between the two is
 * decided by noise, and the neuron's ID alternates between them. The pair becomes one track:
 * the older ID, updated with the detected cluster (mhtc_merge_into_older), or the detected
 * track alone if it is the older one. Counted; a record no child keeps dies with the
 * generation. */
static void mhtc_drop_second_tracks(mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws, mhtc_hyp_t *h,
                                    int32_t *tag, uint32_t *next_id)
{
    if (!(st->cfg.unimodal_ratio > 0.0)) {
        return;
    }
    uint32_t drop = 0u;                         /* bit j: entry j leaves h */
    for (size_t j = 0u; j < h->n_tracks; ++j) { /* merges rewrite entries in place; drops are compacted after */
        const size_t t = h->track[j];
        size_t twin = MHTC_POOL;
        for (size_t q = 0u; (q < h->n_tracks) && (twin == MHTC_POOL) && (ws->staged[t].cluster == 0u); ++q) {
            const mhtc_track_t *o = &ws->staged[h->track[q]];
            twin = ((o->cluster > 0u) && mhtc_same_mode(st, in->basis, ws, t, h->track[q]) &&
                    mhtc_one_neuron_count(st, ws, t, h->track[q]))
                       ? q
                       : MHTC_POOL;
        }
        if (twin == MHTC_POOL) {
            continue;
        }
        if (ws->staged[t].born < ws->staged[h->track[twin]].born) {
            (void)mhtc_merge_into_older(st, in, ws, h, twin, t, tag, next_id);
        }
        ws->staged[t].refs--;
        st->stats.tracks_merged++;
        drop |= (uint32_t)1u << (uint32_t)j;
    }
    size_t kept = 0u;
    for (size_t j = 0u; j < h->n_tracks; ++j) {
        if ((drop & ((uint32_t)1u << (uint32_t)j)) == 0u) {
            h->track[kept++] = h->track[j];
        }
    }
    h->n_tracks = (uint8_t)kept;
}

/* Builds next hypothesis i from candidate c whose keys are staged; resolves new-track tags to IDs. */
static void mhtc_build_child(mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws, const mhtc_cand_t *c,
                             size_t i, const int *src, const int *model, const uint8_t *g, size_t nk, uint32_t *next_id)
{
    const mhtc_model_t *m = &ws->model[c->model];
    const mhtc_hyp_t *par = mhtc_parent(st, m->parent);
    mhtc_hyp_t *h = &ws->next[i];
    memset(h, 0, sizeof *h);
    h->log_prob = c->score;
    h->log_assoc = c->log_assoc;
    h->log_p3 = m->log_p3;
    h->log_p4 = m->log_ev;
    h->g = m->g;
    h->parent = m->parent;
    h->model = c->model;
    int32_t tag[MHTC_G_MAX];
    memcpy(tag, c->tag, sizeof tag);
    for (size_t k = 0u; k < nk; ++k) {
        const size_t rec = mhtc_find_staged(ws, src[k], model[k], g[k]);
        h->track[h->n_tracks++] = (uint8_t)rec;
        ws->staged[rec].refs++;
        if (src[k] == MHTC_SRC_NEW) {
            tag[g[k] - 1u] = (int32_t)ws->staged[rec].id;
        }
    }
    mhtc_drop_second_tracks(st, in, ws, h, tag, next_id);
    /* history: this interval first, then the parent's, truncated to MHTC_HIST_MAX */
    const size_t keep = (par->hist_len < MHTC_HIST_MAX) ? par->hist_len : MHTC_HIST_MAX - 1u;
    h->hist_len = (uint8_t)(keep + 1u);
    h->hist_g[0] = m->g;
    memcpy(h->hist_id[0], tag, sizeof tag);
    memcpy(&h->hist_g[1], par->hist_g, keep * sizeof par->hist_g[0]);
    memcpy(&h->hist_id[1], par->hist_id, keep * sizeof par->hist_id[0]);
    h->rank_hist[0] = (uint8_t)(i + 1u);
    memcpy(&h->rank_hist[1], par->rank_hist, keep * sizeof par->rank_hist[0]);
}

/* Stages the records of the candidates best first; a candidate whose new records do not
 * fit in the pool is dropped (the least probable go first). Returns children built. */
static size_t mhtc_stage(mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws, uint32_t *next_id,
                         uint8_t *cand_of_child)
{
    size_t n_next = 0u;
    ws->n_staged = 0u;
    for (size_t ci = 0u; ci < ws->n_cand; ++ci) {
        int *src = ws->key_src; /* the candidate's record keys: in the workspace, off the deepest stack path */
        int *model = ws->key_model;
        uint8_t *g = ws->key_g;
        const size_t nk = mhtc_cand_keys(st, ws, &ws->cand[ci], src, model, g);
        size_t need = 0u;
        for (size_t k = 0u; k < nk; ++k) {
            need += (mhtc_find_staged(ws, src[k], model[k], g[k]) == ws->n_staged) ? 1u : 0u;
        }
        if ((nk > MHTC_TARGETS_MAX) || (ws->n_staged + need > MHTC_POOL)) {
            st->stats.pool_drops++;
            continue;
        }
        for (size_t k = 0u; k < nk; ++k) {
            if (mhtc_find_staged(ws, src[k], model[k], g[k]) == ws->n_staged) {
                mhtc_make_record(st, in, ws, src[k], model[k], g[k], next_id);
            }
        }
        mhtc_build_child(st, in, ws, &ws->cand[ci], n_next, src, model, g, nk, next_id);
        cand_of_child[n_next++] = (uint8_t)ci;
    }
    return n_next;
}

/* Records referenced now but by no child: deleted tracks (counted once each). */
static void mhtc_count_deleted(mhtc_state_t *st, const mhtc_workspace_t *ws)
{
    for (size_t r = 0u; r < MHTC_POOL; ++r) {
        if (st->pool[r].refs == 0u) {
            continue;
        }
        bool kept = false;
        for (size_t i = 0u; (i < ws->n_staged) && !kept; ++i) {
            kept = (ws->staged_src[i] == (int16_t)r);
        }
        st->stats.tracks_deleted += kept ? 0u : 1u;
    }
}

/* A cluster the leading hypothesis calls false is labelled with the ID of the new track that the
 * most probable other hypothesis of the same model (same clusters) starts from it, if one does.
 * With λφ > λν a new neuron is false at first sight and enters the leading hypothesis one interval
 * later under that lineage's ID (the delayed decision, docs/mhtc.md), so its first interval gets the
 * ID it keeps instead of none. Only labels change: the leading hypothesis' tracks are as decided. */
static void mhtc_provisional_ids(const mhtc_state_t *st, uint32_t first_new_id, int32_t *cluster_track)
{
    const mhtc_hyp_t *lead = &st->hyp[0];
    for (size_t g = 0u; g < lead->g; ++g) {
        for (size_t i = 1u; (i < st->n_hyp) && (cluster_track[g] == MHTC_ID_FALSE); ++i) {
            const int32_t id = st->hyp[i].hist_id[0][g];
            if ((st->hyp[i].model == lead->model) && (id >= (int32_t)first_new_id)) {
                cluster_track[g] = id;
            }
        }
    }
}

static void mhtc_report(const mhtc_state_t *st, const mhtc_input_t *in, const mhtc_workspace_t *ws, size_t cand0,
                        uint32_t first_new_id, mhtc_result_t *out)
{
    const mhtc_hyp_t *h = &st->hyp[0];
    const mhtc_model_t *m = &ws->model[ws->cand[cand0].model];
    out->n_hyp = st->n_hyp;
    out->hyp_hist_len = h->hist_len;
    for (size_t i = 0u; i < st->n_hyp; ++i) {
        out->hyp_prob[i] = exp(st->hyp[i].log_prob);
        memcpy(out->hyp_rank_hist[i], st->hyp[i].rank_hist, sizeof out->hyp_rank_hist[i]);
    }
    out->g = m->g;
    out->params = m->fit.params;
    memcpy(out->n_soft, m->fit.n_soft, sizeof out->n_soft);
    memcpy(out->cluster_track, h->hist_id[0], sizeof out->cluster_track);
    if (st->cfg.provisional_ids) {
        mhtc_provisional_ids(st, first_new_id, out->cluster_track);
    }
    if (m->g > 0u) {
        memcpy(out->labels, m->labels, in->n * sizeof out->labels[0]);
    }
    out->log_p3 = h->log_p3;
    out->log_p4 = h->log_p4;
    out->log_assoc = h->log_assoc;
    out->models_fitted = ws->n_models;
    out->n_tracks = h->n_tracks;
    for (size_t j = 0u; j < h->n_tracks; ++j) {
        const mhtc_track_t *t = &st->pool[h->track[j]];
        mhtc_track_report_t *r = &out->track[j];
        r->id = t->id;
        r->cluster = t->cluster;
        r->misses = t->misses;
        r->p_detect = t->p_detect;
        r->rate_hz = t->rate_hz;
        for (size_t c = 0u; c < in->basis->d; ++c) {
            double acc = 0.0;
            for (size_t q = 0u; q < in->basis->d_w; ++q) {
                acc += in->basis->b[c * in->basis->d_w + q] * t->kf.x[q];
            }
            r->mean_feat[c] = acc;
        }
    }
}

/* N-scan pruning: only the hypotheses whose ancestor of n_scan intervals ago is the leading
 * hypothesis' stay (rank_hist[j] names the ancestor j intervals back uniquely within its
 * generation); their tracks' references go with them, and the survivors are renormalised. A
 * lineage that parted from the leader's earlier than that can no longer take the lead and
 * relabel a neuron it has been holding under another ID. */
static void mhtc_nscan(mhtc_state_t *st)
{
    const uint32_t n = st->cfg.n_scan;
    if ((n == 0u) || (st->n_hyp < 2u) || (st->hyp[0].hist_len <= n)) {
        return;
    }
    const uint8_t anc = st->hyp[0].rank_hist[n];
    size_t kept = 0u;
    double lse = -HUGE_VAL;
    for (size_t i = 0u; i < st->n_hyp; ++i) {
        const mhtc_hyp_t h = st->hyp[i];
        if ((h.hist_len > n) && (h.rank_hist[n] != anc)) {
            for (size_t j = 0u; j < h.n_tracks; ++j) {
                st->pool[h.track[j]].refs--;
            }
            st->stats.nscan_pruned++;
            continue;
        }
        const double a = fmax(lse, h.log_prob);
        lse = a + log(exp(lse - a) + exp(h.log_prob - a));
        st->hyp[kept++] = h;
    }
    for (size_t i = 0u; i < kept; ++i) {
        st->hyp[i].log_prob -= lse;
    }
    st->n_hyp = kept;
}

md_status_t mhtc_commit(mhtc_state_t *st, const mhtc_input_t *in, mhtc_workspace_t *ws, mhtc_result_t *out)
{
    uint32_t next_id = st->next_id;
    const uint32_t first_new_id = next_id;
    uint8_t cand_of_child[MHTC_L_MAX];
    const size_t n_next = mhtc_stage(st, in, ws, &next_id, cand_of_child);
    if (n_next == 0u) {
        return MD_E_CAPACITY;
    }
    double lse = ws->next[0].log_prob; /* footnote 5: normalise over the survivors */
    for (size_t i = 1u; i < n_next; ++i) {
        const double a = fmax(lse, ws->next[i].log_prob);
        lse = a + log(exp(lse - a) + exp(ws->next[i].log_prob - a));
    }
    mhtc_count_deleted(st, ws);
    memset(st->pool, 0, sizeof st->pool);
    memcpy(st->pool, ws->staged, ws->n_staged * sizeof ws->staged[0]);
    for (size_t i = 0u; i < n_next; ++i) {
        st->hyp[i] = ws->next[i];
        st->hyp[i].log_prob -= lse;
    }
    st->n_hyp = n_next;
    mhtc_nscan(st);
    st->next_id = next_id;
    st->d_w = in->basis->d_w;
    st->interval++;
    st->stats.steps++;
    mhtc_report(st, in, ws, cand_of_child[0], first_new_id, out);
    return MD_OK;
}

md_status_t mhtc_hyp_labels(const mhtc_state_t *st, const mhtc_workspace_t *ws, size_t h, size_t n, uint8_t *labels,
                            int32_t *cluster_track, size_t *g)
{
    if ((st == NULL) || (ws == NULL) || (labels == NULL) || (cluster_track == NULL) || (g == NULL) ||
        (h >= st->n_hyp) || (n > EM_N_MAX) || (st->hyp[h].model >= ws->n_models)) {
        return MD_E_ARG;
    }
    const mhtc_model_t *m = &ws->model[st->hyp[h].model];
    *g = m->g;
    memcpy(cluster_track, st->hyp[h].hist_id[0], MHTC_G_MAX * sizeof cluster_track[0]);
    if (m->g == 0u) {
        memset(labels, 0, n * sizeof labels[0]);
    } else {
        memcpy(labels, m->labels, n * sizeof labels[0]);
    }
    return MD_OK;
}

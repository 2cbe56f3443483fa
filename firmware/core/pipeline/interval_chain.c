/// @file interval_chain.c
/// One interval: detection, extraction, PCA, Ξ, tracker step, SNR and
/// isolation. See interval_chain.h.
#include "pipeline/interval_chain.h"

#include <math.h>
#include <string.h>

#include "control/approach_guard.h"

#define D IC_D

/* The window at the fastest supported rate (32768 Hz: 1.15 ms is 38 samples,
 * sx_config_default) with the alignment's margin on both sides fits a row. */
_Static_assert((115u * 32768u + 50000u) / 100000u + 2u * SA_MARGIN <= MD_WAVE_LEN_MAX,
               "a raw window and its alignment margin fit MD_WAVE_LEN_MAX");

/* The last stage completed (ic_workspace_t.stage). A stage needs the one
 * before it; those after IC_ENDED keep their inputs out of the shared union,
 * so they may run again. */
#define IC_IDLE 0
#define IC_RECORDING 1
#define IC_ENDED 2
#define IC_FEATURES 3
#define IC_TRACKED 4
#define IC_SCORED 5

/* A stage's outcome: on failure counted in *errors and the chain back to idle
 * (the next interval starts with ic_begin); on success `next` is reached. */
static md_status_t stage_done(ic_workspace_t *ws, md_status_t st, uint32_t *errors, int next)
{
    if (st != MD_OK) {
        (*errors)++;
        ws->stage = IC_IDLE;
        return st;
    }
    ws->stage = next;
    return MD_OK;
}

md_status_t ic_begin(ic_workspace_t *ws, const ic_config_t *cfg)
{
    if (ws == NULL) {
        return MD_E_ARG;
    }
    ws->stage = IC_IDLE;
    if (cfg == NULL || cfg->sample_rate_hz == 0u || !(cfg->gain_uv > 0.0) || !isfinite(cfg->gain_uv) ||
        cfg->num_samples == 0u || cfg->guard_top_k < 1u || cfg->guard_top_k > AG_TOP_K_MAX) {
        ws->stats.begin_errors++;
        return MD_E_ARG;
    }
    sd_config_t dcfg;
    sx_config_t xcfg;
    sd_config_default(&dcfg, SD_METHOD_WAVELET, cfg->sample_rate_hz);
    dcfg.interval_s = (double)cfg->num_samples / (double)cfg->sample_rate_hz;
    sx_config_default(&xcfg, cfg->sample_rate_hz);
    xcfg.gain = cfg->gain_uv;
    xcfg.subsample = false; /* raw windows with a margin, aligned on their template by ic_end */
    xcfg.margin = SA_MARGIN;
    const uint32_t spacing = cfg->num_samples / (IC_SNIPPET_CANDIDATES * (uint32_t)xcfg.n_noise);
    xcfg.spacing = (spacing > 0u) ? spacing : 1u;
    const md_status_t st = sp_init(&ws->u.sp, &dcfg, &xcfg, &ws->win, &ws->noise);
    if (st != MD_OK) {
        ws->stats.begin_errors++;
        return st;
    }
    ws->cfg = *cfg;
    ws->n_pushed = 0u;
    ws->n_spikes = 0u;
    ws->noise_rms_uv = 0.0;
    ws->amp = 0.0;
    memset(&ws->res, 0, sizeof ws->res);
    memset(ws->track_snr, 0, sizeof ws->track_snr);
    ws->stage = IC_RECORDING;
    ws->stats.intervals++;
    return MD_OK;
}

md_status_t ic_push(ic_workspace_t *ws, const int16_t *x, size_t n)
{
    if (ws == NULL) {
        return MD_E_ARG;
    }
    md_status_t st = MD_E_STATE;
    if (ws->stage == IC_RECORDING) {
        st = sp_push(&ws->u.sp, x, n);
    }
    if (st != MD_OK) {
        ws->stats.push_errors++;
        ws->stage = IC_IDLE;
        return st;
    }
    ws->n_pushed += (uint32_t)n; /* sp_push refuses more than SD_MAX_INTERVAL_SAMPLES < 2^32 */
    return MD_OK;
}

md_status_t ic_end(ic_workspace_t *ws)
{
    if (ws == NULL) {
        return MD_E_ARG;
    }
    md_status_t st = MD_E_STATE;
    if (ws->stage == IC_RECORDING) {
        st = sp_finish(&ws->u.sp);
    }
    /* MD_E_DEGENERATE (a short or flat interval): the outputs are valid all the same */
    st = (st == MD_E_DEGENERATE) ? MD_OK : st;
    if (st == MD_OK) {
        st = sa_align_windows(&ws->win, &ws->u.align); /* the detector and extractor are done with u */
    }
    return stage_done(ws, st, &ws->stats.end_errors, IC_ENDED);
}

/* Basis B^k from the windows (or, without spikes, from the noise so that H^k
 * stays defined and every track is missed); features, Ξ, noise RMS. */
static md_status_t features(ic_workspace_t *ws)
{
    const sx_windows_t *w = &ws->win;
    const sx_snippets_t *z = &ws->noise;
    if (z->n <= D || w->d_w < D || !(w->gain > 0.0)) {
        return MD_E_DEGENERATE; /* Ξ needs more than d snippets */
    }
    ws->n_spikes = (w->n >= 2u) ? (uint32_t)w->n : 0u;
    const bool spikes = ws->n_spikes > 0u;
    md_status_t st = pca_fit_i16(spikes ? &w->wave[0][0] : &z->wave[0][0], spikes ? w->n : z->n, MD_WAVE_LEN_MAX,
                                 w->d_w, w->gain, D, &ws->u.pca, &ws->basis);
    if (st == MD_OK && spikes) {
        st = pca_project_all_i16(&ws->basis, &w->wave[0][0], w->n, MD_WAVE_LEN_MAX, w->gain, ws->y);
    }
    if (st == MD_OK) {
        st = pca_project_all_i16(&ws->basis, &z->wave[0][0], z->n, MD_WAVE_LEN_MAX, z->gain, ws->noise_y);
    }
    if (st == MD_OK) {
        st = qm_noise_feature_cov_i16(&ws->basis, &z->wave[0][0], z->n, MD_WAVE_LEN_MAX, z->gain, ws->xi);
    }
    if (st == MD_OK) {
        st = qm_noise_rms_i16(&z->wave[0][0], z->n, MD_WAVE_LEN_MAX, z->d_w, z->gain, &ws->noise_rms_uv);
    }
    if (st == MD_OK) {
        /* Every window, outliers included: the approach guard must not depend
         * on the tracker. Before the tracker, which a failure leaves untouched. */
        st = ag_robust_amplitude_i16(&w->wave[0][0], w->n, MD_WAVE_LEN_MAX, w->d_w, w->gain, ws->noise_rms_uv,
                                     ws->cfg.guard_top_k, &ws->amp);
    }
    return st;
}

md_status_t ic_features(ic_workspace_t *ws)
{
    if (ws == NULL) {
        return MD_E_ARG;
    }
    const md_status_t st = (ws->stage >= IC_ENDED) ? features(ws) : MD_E_STATE;
    return stage_done(ws, st, &ws->stats.feature_errors, IC_FEATURES);
}

md_status_t ic_track(ic_workspace_t *ws, mhtc_state_t *tracker, double move_um)
{
    if (ws == NULL || tracker == NULL) {
        return MD_E_ARG;
    }
    md_status_t st = MD_E_STATE;
    if (ws->stage >= IC_FEATURES) {
        /* The tracker reads the int16 windows through the gain: no double
         * copy of them. Firing rates over the samples actually pushed. */
        const mhtc_input_t in = {ws->y,
                                 ws->n_spikes,
                                 NULL,
                                 MD_WAVE_LEN_MAX,
                                 &ws->basis,
                                 ws->xi,
                                 (double)ws->n_pushed / (double)ws->cfg.sample_rate_hz,
                                 &ws->win.wave[0][0],
                                 ws->win.gain,
                                 move_um};
        st = mhtc_update(tracker, &in, &ws->u.mhtc, &ws->res);
    }
    return stage_done(ws, st, &ws->stats.track_errors, IC_TRACKED);
}

md_status_t ic_isolation(ic_workspace_t *ws, uint8_t cluster, qm_isolation_t *iso)
{
    if (ws == NULL || iso == NULL) {
        return MD_E_ARG;
    }
    if (ws->stage < IC_TRACKED) {
        return MD_E_STATE;
    }
    const mhtc_result_t *r = &ws->res;
    if (cluster == 0u || cluster > r->g || cluster > MHTC_G_MAX) {
        return MD_E_ARG;
    }
    const size_t g = (size_t)cluster - 1u;
    double cov[D * D];
    for (size_t i = 0u; i < (size_t)D * D; ++i) {
        cov[i] = r->params.lambda * r->params.shape[g][i]; /* Σ_g = λ C_g */
    }
    memset(iso, 0, sizeof *iso);
    return qm_isolation_distance(ws->y, ws->n_spikes, D, r->labels, cluster, ws->noise_y, ws->noise.n,
                                 r->params.mean[g], cov, ws->u.qm_work, sizeof ws->u.qm_work / sizeof ws->u.qm_work[0],
                                 iso);
}

/* SNR of every detected track; the dominant one is the highest (thesis §2.2.2.4). */
static void score_tracks(ic_workspace_t *ws, ic_out_t *out)
{
    const mhtc_result_t *r = &ws->res;
    const sx_windows_t *w = &ws->win;
    double best = -1.0;
    for (size_t j = 0u; j < r->n_tracks && j < MHTC_TARGETS_MAX; ++j) {
        double snr = 0.0;
        const uint8_t cl = r->track[j].cluster;
        if (cl > 0u && ws->n_spikes > 0u &&
            qm_snr_i16(&w->wave[0][0], ws->n_spikes, MD_WAVE_LEN_MAX, w->d_w, w->gain, r->labels, cl, ws->noise_rms_uv,
                       &snr, NULL) != MD_OK) {
            snr = 0.0;
            ws->stats.snr_undefined++;
        }
        if (!isfinite(snr)) {
            snr = 0.0;
            ws->stats.snr_undefined++;
        }
        ws->track_snr[j] = snr;
        if (cl > 0u && snr > best) {
            best = snr;
            out->has_dominant = true;
            out->dominant = r->track[j].id;
            out->dominant_cluster = cl;
            out->snr = snr;
        }
    }
}

md_status_t ic_score(ic_workspace_t *ws, ic_out_t *out)
{
    if (ws == NULL || out == NULL) {
        return MD_E_ARG;
    }
    if (ws->stage < IC_TRACKED) {
        return MD_E_STATE;
    }
    memset(out, 0, sizeof *out);
    memset(ws->track_snr, 0, sizeof ws->track_snr);
    out->n_windows = (uint32_t)ws->win.n;
    out->n_spikes = ws->n_spikes;
    out->amp = ws->amp;
    score_tracks(ws, out);
    if (out->has_dominant) {
        /* ID_g of the dominant cluster (§2.2.2.4); undefined → 0 (not isolated). */
        qm_isolation_t iso;
        const md_status_t st = ic_isolation(ws, out->dominant_cluster, &iso);
        const bool ok = st == MD_OK && iso.defined != 0 && isfinite(iso.id);
        out->iqm = ok ? iso.id : 0.0;
        ws->stats.iso_undefined += ok ? 0u : 1u;
    }
    ws->stage = IC_SCORED;
    return MD_OK;
}

md_status_t ic_run(ic_workspace_t *ws, mhtc_state_t *tracker, double move_um, ic_out_t *out)
{
    if (ws == NULL || tracker == NULL || out == NULL) {
        return MD_E_ARG;
    }
    md_status_t st = ic_end(ws);
    if (st == MD_OK) {
        st = ic_features(ws);
    }
    if (st == MD_OK) {
        st = ic_track(ws, tracker, move_um);
    }
    if (st == MD_OK) {
        st = ic_score(ws, out);
    }
    return st;
}

/// @file md_process.c
/// One interval: signal chain, PCA, Ξ, MHTC step, SNR and isolation. See md_process.h.
#include "md_process.h"

#include <math.h>
#include <string.h>

#include "metrics/quality.h"

#define D MD_CYCLE_D
#define SNIPPET_CANDIDATES_PER_WANTED 4u /* spike_extract.h: spacing for four candidates per wanted snippet */

mhtc_tracker_t md_process_tracker(const md_params_t *p)
{
    /* Baselines of thesis §4.5 behind the MHTC interface: the cycle, SNR and
     * isolation below read the same mhtc_result_t whichever tracker runs. */
    switch (md_params_get_u32(p, MD_P_TRACKER)) {
    case 1u: return MHTC_TRACKER_MAP_NN;
    case 2u: return MHTC_TRACKER_ML_NN;
    case 3u: return MHTC_TRACKER_GNN;
    default: return MHTC_TRACKER_MHTC;
    }
}

md_status_t md_process_begin(md_workspace_t *ws, const md_electrode_t *el, uint32_t num_samples)
{
    if (ws == NULL || el == NULL || !el->fe_info || el->sample_rate_hz == 0u || !(el->gain_uv > 0.0) ||
        num_samples == 0u) {
        return MD_E_ARG;
    }
    sd_config_t dcfg;
    sx_config_t xcfg;
    sd_config_default(&dcfg, SD_METHOD_WAVELET, el->sample_rate_hz);
    dcfg.interval_s = (double)num_samples / (double)el->sample_rate_hz;
    sx_config_default(&xcfg, el->sample_rate_hz);
    xcfg.gain = el->gain_uv;
    const uint32_t spacing = num_samples / (SNIPPET_CANDIDATES_PER_WANTED * (uint32_t)xcfg.n_noise);
    xcfg.spacing = (spacing > 0u) ? spacing : 1u;
    return sp_init(&ws->u.sp, &dcfg, &xcfg, &ws->win, &ws->noise);
}

md_status_t md_process_push(md_workspace_t *ws, const int16_t *x, size_t n)
{
    return (ws == NULL) ? MD_E_ARG : sp_push(&ws->u.sp, x, n);
}

/* Detection flushed; basis B^k from the spikes (or, without spikes, from the
 * noise so that H^k stays defined and every track is missed); features, Ξ. */
static md_status_t chain(md_workspace_t *ws)
{
    md_status_t st = sp_finish(&ws->u.sp);
    if (st != MD_OK && st != MD_E_DEGENERATE) {
        return st;
    }
    const sx_windows_t *w = &ws->win;
    const sx_snippets_t *z = &ws->noise;
    if (z->n <= D || w->d_w < D || !(w->gain > 0.0)) {
        return MD_E_DEGENERATE; /* Ξ needs more than d snippets */
    }
    ws->n_spikes = (w->n >= 2u) ? (uint32_t)w->n : 0u;
    const bool spikes = ws->n_spikes > 0u;
    st = pca_fit_i16(spikes ? &w->wave[0][0] : &z->wave[0][0], spikes ? w->n : z->n, MD_WAVE_LEN_MAX, w->d_w, w->gain,
                     D, &ws->u.pca, &ws->basis);
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
    return st;
}

/* SNR of every detected track; the dominant one is the highest (thesis §2.2.2.4). */
static void score_tracks(md_workspace_t *ws, md_process_out_t *out)
{
    const mhtc_result_t *r = &ws->res;
    const sx_windows_t *w = &ws->win;
    double best = -1.0;
    for (size_t j = 0u; j < r->n_tracks && j < MHTC_TARGETS_MAX; ++j) {
        double snr = 0.0;
        const uint8_t cl = r->track[j].cluster;
        if (cl > 0u && ws->n_spikes > 0u &&
            qm_snr_i16(&w->wave[0][0], ws->n_spikes, MD_WAVE_LEN_MAX, w->d_w, w->gain, r->labels, cl,
                       ws->noise_rms_uv, &snr, NULL) != MD_OK) {
            snr = 0.0;
        }
        ws->track_snr[j] = isfinite(snr) ? snr : 0.0;
        if (cl > 0u && ws->track_snr[j] > best) {
            best = ws->track_snr[j];
            out->has_dominant = true;
            out->dominant = r->track[j].id;
            out->dominant_cluster = cl;
            out->snr = ws->track_snr[j];
        }
    }
}

/* ID_g of the dominant cluster under its fitted Σ_g = λ C_g, noise snippets
 * counting as non-members (§2.2.2.4); undefined → 0 (not isolated). */
static void isolation(md_workspace_t *ws, md_process_out_t *out)
{
    const mhtc_result_t *r = &ws->res;
    if (!out->has_dominant || out->dominant_cluster == 0u || out->dominant_cluster > r->g) {
        return;
    }
    const size_t g = (size_t)out->dominant_cluster - 1u;
    double cov[D * D];
    for (size_t i = 0u; i < D * D; ++i) {
        cov[i] = r->params.lambda * r->params.shape[g][i];
    }
    qm_isolation_t iso;
    memset(&iso, 0, sizeof iso);
    const md_status_t st = qm_isolation_distance(ws->y, ws->n_spikes, D, r->labels, out->dominant_cluster,
                                                 ws->noise_y, ws->noise.n, r->params.mean[g], cov, ws->qm_work,
                                                 sizeof ws->qm_work / sizeof ws->qm_work[0], &iso);
    out->iqm = (st == MD_OK && iso.defined != 0 && isfinite(iso.id)) ? iso.id : 0.0;
}

md_status_t md_process_interval(md_workspace_t *ws, md_electrode_t *el, double duration_s, double min_rate_hz,
                                md_process_out_t *out)
{
    if (ws == NULL || el == NULL || out == NULL || !(duration_s > 0.0)) {
        return MD_E_ARG;
    }
    memset(out, 0, sizeof *out);
    memset(ws->track_snr, 0, sizeof ws->track_snr);
    md_status_t st = chain(ws);
    if (st == MD_OK) {
        /* Every window, outliers included: the approach guard must not depend
         * on the tracker. Before the tracker, which a failure leaves untouched. */
        st = ag_robust_amplitude_i16(&ws->win.wave[0][0], ws->win.n, MD_WAVE_LEN_MAX, ws->win.d_w, ws->win.gain,
                                     ws->noise_rms_uv, el->guard.cfg.top_k, &out->amp);
    }
    if (st != MD_OK) {
        return st;
    }
    /* The tracker reads the int16 windows through the gain: no double copy of them. */
    const mhtc_input_t in = {ws->y, ws->n_spikes, NULL, MD_WAVE_LEN_MAX, &ws->basis, ws->xi, duration_s,
                             &ws->win.wave[0][0], ws->win.gain, el->move_um};
    st = mhtc_step(&el->mhtc, &in, &ws->u.mhtc, &ws->res);
    if (st != MD_OK) {
        return st;
    }
    out->n_spikes = ws->n_spikes;
    out->spikes_seen = (double)ws->win.n / duration_s >= min_rate_hz && ws->win.n > 0u;
    score_tracks(ws, out);
    isolation(ws, out);
    return MD_OK;
}

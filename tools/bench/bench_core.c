/// @file bench_core.c
/// One electrode cycle as separately runnable stages. See bench_core.h.
/// The stage bodies follow firmware/app/md_process.c and md_cycle.c (decide)
/// so that the measured work is the controller's.
#include "bench_core.h"

#include <math.h>
#include <string.h>

#include "cluster/cluster.h"
#include "control/sfsm.h"
#include "control/snr_curve.h"
#include "features/pca.h"
#include "metrics/quality.h"
#include "signal/spike_pipeline.h"
#include "signal/spike_synth.h"
#include "tracking/mhtc.h"

#define GAIN_UV 0.5           /* µV per ADC count */
#define NOISE_COUNTS 20.0     /* noise RMS: 10 µV */
#define N_NEURONS 3u
#define PEAKS_CAP 1024u
#define SILENT_RMS 1e-3       /* a neuron-only trace: noise rounds to 0 counts */
#define DEPTH_STEP_UM 10.0
#define CANDIDATES_PER_WANTED 4u

/* SNR (peak-to-peak / noise RMS) and rate of the three neurons: 150+100+50 = 300 spikes in 10 s. */
static const double NEURON_SNR[N_NEURONS] = {10.0, 7.0, 5.0};
static const double NEURON_RATE_HZ[N_NEURONS] = {15.0, 10.0, 5.0};

static int16_t g_trace[BENCH_SAMPLES];
static int16_t g_scratch[BENCH_SAMPLES];
static uint32_t g_peaks[PEAKS_CAP];

static sp_channel_t g_sp;
static sx_windows_t g_win;
static sx_snippets_t g_noise;
static pca_work_t g_pca;
static pca_basis_t g_basis;
static double g_y[MD_MAX_SPIKES * BENCH_D];
static double g_noise_y[MD_MAX_NOISE_SNIPPETS * BENCH_D];
static double g_qm_work[(MD_MAX_SPIKES + MD_MAX_NOISE_SNIPPETS) * BENCH_D];
static double g_xi[BENCH_D * BENCH_D];
static double g_noise_rms_uv;
static double g_wave[MD_MAX_SPIKES * MD_WAVE_LEN_MAX];
static size_t g_n_spikes;

static cluster_workspace_t g_cl_ws;
static cluster_result_t g_cl_res;

static mhtc_state_t g_mh;
static mhtc_state_t g_mh_saved;
static mhtc_workspace_t g_mh_ws;
static mhtc_result_t g_mh_res;

static sc_table_t g_curves;
static sc_table_t g_curves_saved;
static sfsm_t g_sfsm;
static sfsm_t g_sfsm_saved;
static double g_depth_um;

/* What quality hands to control (md_process_out_t's fields). */
static bool g_has_dominant;
static uint32_t g_dominant;
static uint8_t g_dominant_cluster;
static double g_snr;
static double g_iqm;

static bench_info_t g_info;
static int g_ready;

static const char *const STAGE_NAMES[BENCH_ST_COUNT] = {"detect", "pca", "cluster", "mhtc", "quality", "control"};

const char *bench_stage_name(bench_stage_t s)
{
    return ((unsigned)s < (unsigned)BENCH_ST_COUNT) ? STAGE_NAMES[s] : "?";
}

int bench_stage_in_cycle(bench_stage_t s)
{
    return ((unsigned)s < (unsigned)BENCH_ST_COUNT && s != BENCH_ST_CLUSTER) ? 1 : 0;
}

/* Interval k: background noise with the first neuron, plus the other two
 * neurons synthesised without noise and added (saturating). */
static md_status_t synth_interval(uint32_t k)
{
    uint32_t total = 0u;
    for (uint32_t u = 0u; u < N_NEURONS; ++u) {
        synth_config_t c;
        memset(&c, 0, sizeof c);
        c.sample_rate_hz = BENCH_FS_HZ;
        c.noise_rms = (u == 0u) ? NOISE_COUNTS : SILENT_RMS;
        c.band_limited = 1;
        c.snr = NEURON_SNR[u] * NOISE_COUNTS / c.noise_rms;
        c.rate_hz = NEURON_RATE_HZ[u];
        c.refractory_ms = 2.0;
        c.seed = 1000u + 10u * (uint64_t)k + u;
        size_t n_peaks = 0u;
        int16_t *dst = (u == 0u) ? g_trace : g_scratch;
        const md_status_t st = synth_trace(&c, dst, BENCH_SAMPLES, g_peaks, PEAKS_CAP, &n_peaks);
        if (st != MD_OK) {
            return st;
        }
        total += (uint32_t)n_peaks;
        for (size_t i = 0u; u > 0u && i < BENCH_SAMPLES; ++i) {
            const int32_t v = (int32_t)g_trace[i] + (int32_t)g_scratch[i];
            g_trace[i] = (int16_t)((v > 32767) ? 32767 : ((v < -32768) ? -32768 : v));
        }
    }
    g_info.true_spikes = total;
    return MD_OK;
}

/* As md_process_begin + md_process_push + sp_finish. */
static md_status_t stage_detect(void)
{
    sd_config_t dcfg;
    sx_config_t xcfg;
    sd_config_default(&dcfg, SD_METHOD_WAVELET, BENCH_FS_HZ);
    dcfg.interval_s = (double)BENCH_SECONDS;
    sx_config_default(&xcfg, BENCH_FS_HZ);
    xcfg.gain = GAIN_UV;
    const uint32_t spacing = BENCH_SAMPLES / (CANDIDATES_PER_WANTED * (uint32_t)xcfg.n_noise);
    xcfg.spacing = (spacing > 0u) ? spacing : 1u;
    md_status_t st = sp_init(&g_sp, &dcfg, &xcfg, &g_win, &g_noise);
    for (size_t i = 0u; st == MD_OK && i < BENCH_SAMPLES; i += BENCH_CHUNK) {
        const size_t n = (BENCH_SAMPLES - i < BENCH_CHUNK) ? (BENCH_SAMPLES - i) : BENCH_CHUNK;
        st = sp_push(&g_sp, &g_trace[i], n);
    }
    if (st == MD_OK) {
        st = sp_finish(&g_sp);
    }
    return (st == MD_E_DEGENERATE) ? MD_OK : st;
}

/* As md_process.c chain(): basis, features, Ξ, noise RMS, waveforms for the tracker. */
static md_status_t stage_pca(void)
{
    const sx_windows_t *w = &g_win;
    const sx_snippets_t *z = &g_noise;
    if (z->n <= BENCH_D || w->d_w < BENCH_D || w->n < 2u) {
        return MD_E_DEGENERATE;
    }
    g_n_spikes = w->n;
    md_status_t st = pca_fit_i16(&w->wave[0][0], w->n, MD_WAVE_LEN_MAX, w->d_w, w->gain, BENCH_D, &g_pca, &g_basis);
    if (st == MD_OK) {
        st = pca_project_all_i16(&g_basis, &w->wave[0][0], w->n, MD_WAVE_LEN_MAX, w->gain, g_y);
    }
    if (st == MD_OK) {
        st = pca_project_all_i16(&g_basis, &z->wave[0][0], z->n, MD_WAVE_LEN_MAX, z->gain, g_noise_y);
    }
    if (st == MD_OK) {
        st = qm_noise_feature_cov_i16(&g_basis, &z->wave[0][0], z->n, MD_WAVE_LEN_MAX, z->gain, g_xi);
    }
    if (st == MD_OK) {
        st = qm_noise_rms_i16(&z->wave[0][0], z->n, MD_WAVE_LEN_MAX, z->d_w, z->gain, &g_noise_rms_uv);
    }
    for (size_t i = 0u; st == MD_OK && i < g_n_spikes; ++i) {
        for (size_t q = 0u; q < w->d_w; ++q) {
            g_wave[i * w->d_w + q] = w->gain * (double)w->wave[i][q];
        }
    }
    return st;
}

static md_status_t stage_cluster(void)
{
    cluster_config_t cfg;
    cluster_config_default(&cfg, CLUSTER_MAP);
    cfg.evidence = CLUSTER_EVIDENCE_LAPLACE;
    cfg.g_max = 4u;
    cluster_input_t in;
    memset(&in, 0, sizeof in);
    in.data.y = g_y;
    in.data.n = g_n_spikes;
    in.data.d = BENCH_D;
    in.noise_cov = g_xi;
    return cluster_fit_models(&cfg, &in, &g_cl_ws, &g_cl_res);
}

static md_status_t stage_mhtc(void)
{
    mhtc_input_t in; /* by field: the struct may grow (e.g. int16 waveforms) */
    memset(&in, 0, sizeof in);
    in.y = g_y;
    in.n = g_n_spikes;
    in.wave = g_wave;
    in.stride = g_win.d_w;
    in.basis = &g_basis;
    in.noise_cov = g_xi;
    in.duration_s = (double)BENCH_SECONDS;
    return mhtc_step(&g_mh, &in, &g_mh_ws, &g_mh_res);
}

/* As md_process.c score_tracks() and isolation(). */
static md_status_t stage_quality(void)
{
    const mhtc_result_t *r = &g_mh_res;
    double best = -1.0;
    g_has_dominant = false;
    g_dominant_cluster = 0u;
    g_snr = 0.0;
    g_iqm = 0.0;
    for (size_t j = 0u; j < r->n_tracks && j < MHTC_TARGETS_MAX; ++j) {
        double snr = 0.0;
        const uint8_t cl = r->track[j].cluster;
        if (cl > 0u && qm_snr_i16(&g_win.wave[0][0], g_n_spikes, MD_WAVE_LEN_MAX, g_win.d_w, g_win.gain, r->labels,
                                  cl, g_noise_rms_uv, &snr, NULL) != MD_OK) {
            snr = 0.0;
        }
        if (cl > 0u && isfinite(snr) && snr > best) {
            best = snr;
            g_has_dominant = true;
            g_dominant = r->track[j].id;
            g_dominant_cluster = cl;
            g_snr = snr;
        }
    }
    if (!g_has_dominant || g_dominant_cluster > r->g) {
        return MD_OK;
    }
    const size_t g = (size_t)g_dominant_cluster - 1u;
    double cov[BENCH_D * BENCH_D];
    for (size_t i = 0u; i < BENCH_D * BENCH_D; ++i) {
        cov[i] = r->params.lambda * r->params.shape[g][i];
    }
    qm_isolation_t iso;
    memset(&iso, 0, sizeof iso);
    const md_status_t st = qm_isolation_distance(g_y, g_n_spikes, BENCH_D, r->labels, g_dominant_cluster, g_noise_y,
                                                 g_noise.n, r->params.mean[g], cov, g_qm_work,
                                                 sizeof g_qm_work / sizeof g_qm_work[0], &iso);
    g_iqm = (st == MD_OK && iso.defined != 0 && isfinite(iso.id)) ? iso.id : 0.0;
    return MD_OK;
}

/* As md_cycle.c decide() with default parameters and a 0..5000 µm window. */
static md_status_t stage_control(void)
{
    sc_config_t scc;
    sc_config_default(&scc);
    sfsm_input_t in;
    memset(&in, 0, sizeof in);
    in.has_dominant = g_has_dominant;
    in.dominant_track = g_dominant;
    in.snr = g_snr;
    in.iqm = g_iqm;
    in.spikes_seen = g_n_spikes > 0u;
    in.depth_um = g_depth_um;
    in.depth_min_um = 0.0;
    in.depth_max_um = 5000.0;
    if (g_has_dominant) {
        sc_curve_t *curve = NULL;
        if (sc_table_observe(&g_curves, &scc, g_dominant, g_depth_um, g_snr, &curve) == MD_OK && curve != NULL) {
            (void)sc_curve_suggest(curve, &scc, g_depth_um, g_sfsm.search_dir, &in.suggestion);
        }
    }
    sfsm_output_t out;
    memset(&out, 0, sizeof out);
    const md_status_t st = sfsm_step(&g_sfsm, &in, &out);
    if (st == MD_OK && out.reset_curve) {
        (void)sc_table_reset_track(&g_curves, out.reset_track);
    }
    return st;
}

static md_status_t run_raw(bench_stage_t s)
{
    switch (s) {
    case BENCH_ST_DETECT:
        return stage_detect();
    case BENCH_ST_PCA:
        return stage_pca();
    case BENCH_ST_CLUSTER:
        return stage_cluster();
    case BENCH_ST_MHTC:
        return stage_mhtc();
    case BENCH_ST_QUALITY:
        return stage_quality();
    case BENCH_ST_CONTROL:
        return stage_control();
    case BENCH_ST_COUNT:
    default:
        return MD_E_ARG;
    }
}

/* One whole cycle on interval k (warm-up). */
static md_status_t warm_cycle(uint32_t k)
{
    md_status_t st = synth_interval(k);
    for (unsigned s = 0u; st == MD_OK && s < (unsigned)BENCH_ST_COUNT; ++s) {
        if (bench_stage_in_cycle((bench_stage_t)s) != 0) {
            st = run_raw((bench_stage_t)s);
        }
    }
    g_depth_um += DEPTH_STEP_UM;
    return st;
}

md_status_t bench_setup(void)
{
    g_ready = 0;
    memset(&g_info, 0, sizeof g_info);
    mhtc_config_t mc;
    mhtc_config_default(&mc, MHTC_TRACKER_MHTC);
    mc.L = 8u;
    mc.g_max = 4u;
    mc.evidence = CLUSTER_EVIDENCE_LAPLACE;
    sfsm_config_t sc;
    sfsm_config_default(&sc);
    md_status_t st = mhtc_init(&g_mh, &mc);
    st = (st == MD_OK) ? sfsm_init(&g_sfsm, &sc) : st;
    sc_table_init(&g_curves);
    g_depth_um = 1000.0;
    for (uint32_t k = 0u; st == MD_OK && k < BENCH_WARMUP; ++k) {
        st = warm_cycle(k);
    }
    /* The measured interval: its trace, windows and features stay; the
     * stateful stages keep a copy of their state from before it. */
    st = (st == MD_OK) ? synth_interval(BENCH_WARMUP) : st;
    st = (st == MD_OK) ? stage_detect() : st;
    st = (st == MD_OK) ? stage_pca() : st;
    g_mh_saved = g_mh;
    g_curves_saved = g_curves;
    g_sfsm_saved = g_sfsm;
    st = (st == MD_OK) ? stage_cluster() : st;
    st = (st == MD_OK) ? stage_mhtc() : st;
    st = (st == MD_OK) ? stage_quality() : st;
    if (st != MD_OK) {
        return st;
    }
    g_info.detected = (uint32_t)g_win.n;
    g_info.noise = (uint32_t)g_noise.n;
    g_info.d_w = (uint32_t)g_win.d_w;
    g_info.hyp = (uint32_t)g_mh_res.n_hyp;
    g_info.tracks = (uint32_t)g_mh_res.n_tracks;
    g_info.models = (uint32_t)g_mh_res.models_fitted;
    g_info.reused = g_mh.stats.models_reused - g_mh_saved.stats.models_reused;
    g_info.shared = g_mh.stats.models_shared - g_mh_saved.stats.models_shared;
    g_info.warm = g_mh.stats.models_warm - g_mh_saved.stats.models_warm;
    g_info.cluster_best_g = (uint32_t)g_cl_res.best_g;
    g_ready = 1;
    return MD_OK;
}

md_status_t bench_run_stage(bench_stage_t s)
{
    if (g_ready == 0 || (unsigned)s >= (unsigned)BENCH_ST_COUNT) {
        return MD_E_ARG;
    }
    /* Restore what a stage changes so that every run repeats the same work. */
    if (s == BENCH_ST_MHTC) {
        g_mh = g_mh_saved;
    } else if (s == BENCH_ST_CONTROL) {
        g_curves = g_curves_saved;
        g_sfsm = g_sfsm_saved;
    } else {
        /* detect, pca, cluster and quality are functions of the interval */
    }
    return run_raw(s);
}

void bench_info(bench_info_t *info)
{
    if (info != NULL) {
        *info = g_info;
    }
}

const double *bench_features(size_t *n)
{
    if (n != NULL) {
        *n = g_n_spikes;
    }
    return g_y;
}

size_t bench_static_bytes(void)
{
    return sizeof g_trace + sizeof g_scratch + sizeof g_peaks + sizeof g_sp + sizeof g_win + sizeof g_noise +
           sizeof g_pca + sizeof g_basis + sizeof g_y + sizeof g_noise_y + sizeof g_qm_work + sizeof g_wave +
           sizeof g_cl_ws + sizeof g_cl_res + 2u * sizeof g_mh + sizeof g_mh_ws + sizeof g_mh_res +
           2u * sizeof g_curves + 2u * sizeof g_sfsm;
}

/// @file bench_core.c
/// One electrode cycle as separately runnable stages. See bench_core.h.
/// The signal chain, tracker and quality stages are the controller's own
/// unit (pipeline/interval_chain.h, which firmware/app/md_interval.c runs),
/// called stage by stage; control follows md_cycle.c (decide), so that the
/// measured work is the controller's.
#include "bench_core.h"

#include <math.h>
#include <stdbool.h>
#include <string.h>

#include "cluster/cluster.h"
#include "control/approach_guard.h"
#include "control/sfsm.h"
#include "control/snr_curve.h"
#include "pipeline/interval_chain.h"
#include "signal/spike_synth.h"
#include "tracking/mhtc.h"

#define GAIN_UV 0.5       /* µV per ADC count */
#define NOISE_COUNTS 20.0 /* noise RMS: 10 µV */
#define N_NEURONS 3u
#define PEAKS_CAP 1024u
#define SILENT_RMS 1e-3 /* a neuron-only trace: noise rounds to 0 counts */
#define DEPTH_STEP_UM 10.0

/* SNR (peak-to-peak / noise RMS) and rate of the three neurons: 150+100+50 = 300 spikes in 10 s. */
static const double NEURON_SNR[N_NEURONS] = {10.0, 7.0, 5.0};
static const double NEURON_RATE_HZ[N_NEURONS] = {15.0, 10.0, 5.0};

static int16_t g_trace[BENCH_SAMPLES];
static int16_t g_scratch[BENCH_SAMPLES];
static uint32_t g_peaks[PEAKS_CAP];

static ic_workspace_t g_ws; /* the controller's md_workspace_t */
static ic_out_t g_out;      /* what quality hands to control (md_interval_out_t's fields) */

static cluster_workspace_t g_cl_ws;
static cluster_result_t g_cl_res;

static mhtc_state_t g_mh;
static mhtc_state_t g_mh_saved;

static sc_table_t g_curves;
static sc_table_t g_curves_saved;
static sfsm_t g_sfsm;
static sfsm_t g_sfsm_saved;
static double g_depth_um;

static bench_info_t g_info;
static int g_ready;
static int g_rp_ready; /* replay mode set up (bench_replay_setup) */

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

/* As md_interval_begin + md_interval_push (REC_DATA frames) + the end of the interval. */
static md_status_t stage_detect(void)
{
    ag_config_t ag;
    ag_config_default(&ag);
    const ic_config_t cfg = {BENCH_FS_HZ, GAIN_UV, BENCH_SAMPLES, ag.top_k};
    md_status_t st = ic_begin(&g_ws, &cfg);
    for (size_t i = 0u; st == MD_OK && i < BENCH_SAMPLES; i += BENCH_CHUNK) {
        const size_t n = (BENCH_SAMPLES - i < BENCH_CHUNK) ? (BENCH_SAMPLES - i) : BENCH_CHUNK;
        st = ic_push(&g_ws, &g_trace[i], n);
    }
    return (st == MD_OK) ? ic_end(&g_ws) : st;
}

/* Basis, features, Ξ, noise RMS, robust amplitude. */
static md_status_t stage_pca(void)
{
    return ic_features(&g_ws);
}

static md_status_t stage_cluster(void)
{
    cluster_config_t cfg;
    cluster_config_default(&cfg, CLUSTER_MAP);
    cfg.evidence = CLUSTER_EVIDENCE_LAPLACE;
    cfg.g_max = 4u;
    cluster_input_t in;
    memset(&in, 0, sizeof in);
    in.data.y = g_ws.y;
    in.data.n = g_ws.n_spikes;
    in.data.d = BENCH_D;
    in.noise_cov = g_ws.xi;
    return cluster_fit_models(&cfg, &in, &g_cl_ws, &g_cl_res);
}

/* One tracker step on the int16 windows, as the controller runs it. */
static md_status_t stage_mhtc(void)
{
    return ic_track(&g_ws, &g_mh, 0.0); /* no travel: the interval is the same every run */
}

/* SNR of every track, the dominant one and its isolation distance. */
static md_status_t stage_quality(void)
{
    return ic_score(&g_ws, &g_out);
}

/* md_cycle.c decide() with the library defaults: the SFSM's input from the interval's result at depth_um
 * in the window [depth_min_um, depth_max_um], the SNR curve of the dominant track observed and its
 * suggestion, one SFSM step (*out); the curve of a track the SFSM resets is dropped. */
static md_status_t bench_decide(double depth_um, double depth_min_um, double depth_max_um, bool spikes_seen,
                                sfsm_output_t *out)
{
    sc_config_t scc;
    sc_config_default(&scc);
    sfsm_input_t in;
    memset(&in, 0, sizeof in);
    in.has_dominant = g_out.has_dominant;
    in.dominant_track = g_out.dominant;
    in.snr = g_out.snr;
    in.iqm = g_out.iqm;
    in.spikes_seen = spikes_seen;
    in.depth_um = depth_um;
    in.depth_min_um = depth_min_um;
    in.depth_max_um = depth_max_um;
    if (g_out.has_dominant) {
        sc_curve_t *curve = NULL;
        if (sc_table_observe(&g_curves, &scc, g_out.dominant, depth_um, g_out.snr, &curve) == MD_OK && curve != NULL) {
            (void)sc_curve_suggest(curve, &scc, depth_um, g_sfsm.search_dir, &in.suggestion);
        }
    }
    memset(out, 0, sizeof *out);
    const md_status_t st = sfsm_decide(&g_sfsm, &in, out);
    if (st == MD_OK && out->reset_curve) {
        (void)sc_table_reset_track(&g_curves, out->reset_track);
    }
    return st;
}

/* As md_cycle.c decide() with default parameters and a 0..5000 µm window. */
static md_status_t stage_control(void)
{
    sfsm_output_t out;
    return bench_decide(g_depth_um, 0.0, 5000.0, g_out.n_spikes > 0u, &out);
}

static md_status_t run_raw(bench_stage_t s)
{
    switch (s) {
    case BENCH_ST_DETECT: return stage_detect();
    case BENCH_ST_PCA: return stage_pca();
    case BENCH_ST_CLUSTER: return stage_cluster();
    case BENCH_ST_MHTC: return stage_mhtc();
    case BENCH_ST_QUALITY: return stage_quality();
    case BENCH_ST_CONTROL: return stage_control();
    case BENCH_ST_COUNT:
    default: return MD_E_ARG;
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
    g_rp_ready = 0; /* the replay's state is overwritten below */
    memset(&g_info, 0, sizeof g_info);
    mhtc_config_t mc;
    mhtc_config_default(&mc, MHTC_TRACKER_MHTC);
    mc.L = 8u;
    mc.g_max = 4u;
    mc.evidence = CLUSTER_EVIDENCE_LAPLACE;
    /* The busy case: with the first interval's own rate of new neurons (λν,1) the three
     * neurons are tracks from the first interval on and the hypotheses agree by the measured
     * step (two model hypotheses); with λν there they still disagree (twelve), as they do
     * while a neuron appears. The budget is for the busy step. */
    mc.lambda_first = mc.lambda_new;
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
    g_info.detected = (uint32_t)g_ws.win.n;
    g_info.noise = (uint32_t)g_ws.noise.n;
    g_info.d_w = (uint32_t)g_ws.win.d_w;
    g_info.hyp = (uint32_t)g_ws.res.n_hyp;
    g_info.tracks = (uint32_t)g_ws.res.n_tracks;
    g_info.models = (uint32_t)g_ws.res.models_fitted;
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
        /* detect, pca, cluster and quality are functions of the interval (and of
         * the stages before them, which the drivers run in cycle order) */
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
        *n = g_ws.n_spikes;
    }
    return g_ws.y;
}

size_t bench_static_bytes(void)
{
    return sizeof g_trace + sizeof g_scratch + sizeof g_peaks + sizeof g_ws + sizeof g_out + sizeof g_cl_ws +
           sizeof g_cl_res + 2u * sizeof g_mh + 2u * sizeof g_curves + 2u * sizeof g_sfsm;
}

/* ------------------------------------------------------------------ */
/* Replay of recorded intervals                                        */
/* ------------------------------------------------------------------ */

#define RP_DEPTH_MIN_UM 0.0 /* md_params: depth_min_um, depth_max_um, min_rate_hz defaults */
#define RP_DEPTH_MAX_UM 5000.0
#define RP_MIN_RATE_HZ 0.5

static const char *const REPLAY_NAMES[BENCH_RP_COUNT] = {"push", "end", "pca", "mhtc", "quality", "control"};

static ag_state_t g_guard;
static double g_guard_time_s; /* the replay's clock: one interval per control stage */
static uint32_t g_rp_fs_hz;
static double g_rp_gain_uv;
static size_t g_rp_n;          /* samples of the current interval */
static double g_rp_depth_um;   /* its depth (NaN: unknown) */
static double g_rp_tracked_um; /* depth of the last tracked interval (NaN: none yet) */
static int g_rp_next;          /* next stage to run; BENCH_RP_COUNT: none (done, failed or not begun) */
static bench_replay_info_t g_rp_info;

const char *bench_replay_stage_name(bench_replay_stage_t s)
{
    return ((unsigned)s < (unsigned)BENCH_RP_COUNT) ? REPLAY_NAMES[s] : "?";
}

md_status_t bench_replay_setup(uint32_t fs_hz, double gain_uv)
{
    g_ready = 0;
    g_rp_ready = 0;
    g_rp_next = (int)BENCH_RP_COUNT;
    if (!(gain_uv > 0.0) || !isfinite(gain_uv)) {
        return MD_E_ARG;
    }
    mhtc_config_t mc;
    mhtc_config_default(&mc, MHTC_TRACKER_MHTC);
    sfsm_config_t sc;
    sfsm_config_default(&sc);
    ag_config_t ag;
    ag_config_default(&ag);
    md_status_t st = mhtc_init(&g_mh, &mc);
    st = (st == MD_OK) ? sfsm_init(&g_sfsm, &sc) : st;
    st = (st == MD_OK) ? ag_init(&g_guard, &ag) : st;
    sc_table_init(&g_curves);
    /* the chain's check of the sample rate: a probe interval of one second */
    const ic_config_t probe = {fs_hz, gain_uv, fs_hz, ag.top_k};
    st = (st == MD_OK) ? ic_begin(&g_ws, &probe) : st;
    if (st != MD_OK) {
        return st;
    }
    memset(&g_ws.stats, 0, sizeof g_ws.stats);
    memset(&g_rp_info, 0, sizeof g_rp_info);
    g_rp_fs_hz = fs_hz;
    g_rp_gain_uv = gain_uv;
    g_rp_tracked_um = NAN;
    g_guard_time_s = 0.0;
    g_rp_ready = 1;
    return MD_OK;
}

int16_t *bench_replay_samples(size_t *cap)
{
    if (cap != NULL) {
        *cap = BENCH_SAMPLES;
    }
    return g_trace;
}

md_status_t bench_replay_interval(size_t n, double depth_um)
{
    g_rp_next = (int)BENCH_RP_COUNT;
    if (g_rp_ready == 0 || n == 0u || n > BENCH_SAMPLES) {
        return MD_E_ARG;
    }
    ag_config_t ag;
    ag_config_default(&ag);
    const ic_config_t cfg = {g_rp_fs_hz, g_rp_gain_uv, (uint32_t)n, ag.top_k};
    const md_status_t st = ic_begin(&g_ws, &cfg);
    if (st != MD_OK) {
        return st;
    }
    memset(&g_rp_info, 0, sizeof g_rp_info);
    memset(&g_out, 0, sizeof g_out);
    g_rp_n = n;
    g_rp_depth_um = depth_um;
    g_rp_next = (int)BENCH_RP_PUSH;
    return MD_OK;
}

static md_status_t rp_push(void)
{
    md_status_t st = MD_OK;
    for (size_t i = 0u; st == MD_OK && i < g_rp_n; i += BENCH_CHUNK) {
        const size_t n = (g_rp_n - i < BENCH_CHUNK) ? (g_rp_n - i) : BENCH_CHUNK;
        st = ic_push(&g_ws, &g_trace[i], n);
    }
    return st;
}

static md_status_t rp_track(void)
{
    /* md_cycle.c process(): the travel since the last interval the tracker took */
    const double move = (isfinite(g_rp_depth_um) && isfinite(g_rp_tracked_um)) ? fabs(g_rp_depth_um - g_rp_tracked_um)
                                                                               : 0.0;
    return ic_track(&g_ws, &g_mh, move);
}

static md_status_t rp_score(void)
{
    const md_status_t st = ic_score(&g_ws, &g_out);
    if (st == MD_OK) {
        g_rp_tracked_um = g_rp_depth_um;
        g_rp_info.n_spikes = g_out.n_spikes;
        g_rp_info.dominant = g_out.has_dominant ? g_out.dominant : 0u;
        g_rp_info.n_tracks = (g_mh.n_hyp > 0u) ? (uint32_t)g_mh.hyp[0].n_tracks : 0u;
        g_rp_info.n_hyp = (uint32_t)g_mh.n_hyp;
        g_rp_info.models = (uint32_t)g_ws.res.models_fitted;
        g_rp_info.snr = g_out.has_dominant ? (float)g_out.snr : 0.0f;
    }
    return st;
}

/* md_cycle.c decide() then guard() (guard_units: the robust amplitude and
 * every detected track's SNR), with the library defaults. */
static md_status_t rp_control(void)
{
    const double depth = isfinite(g_rp_depth_um) ? g_rp_depth_um : 0.0;
    const bool spikes_seen = ((double)g_out.n_windows / ((double)g_rp_n / (double)g_rp_fs_hz) >= RP_MIN_RATE_HZ) &&
                             (g_out.n_windows > 0u);
    sfsm_output_t out;
    if (bench_decide(depth, RP_DEPTH_MIN_UM, RP_DEPTH_MAX_UM, spikes_seen, &out) != MD_OK) {
        return MD_OK; /* the controller holds: HALTED asks for nothing */
    }
    ag_unit_t unit[AG_UNITS_MAX];
    size_t n = 0u;
    unit[n++] = (ag_unit_t){AG_UNIT_RAW, g_out.amp};
    for (size_t j = 0u; j < g_ws.res.n_tracks && j < MHTC_TARGETS_MAX && n < AG_UNITS_MAX; ++j) {
        if (g_ws.res.track[j].cluster > 0u && g_ws.track_snr[j] > 0.0) {
            unit[n++] = (ag_unit_t){g_ws.res.track[j].id, g_ws.track_snr[j]};
        }
    }
    const ag_input_t gin = {unit, n, depth, g_guard_time_s, out.move_um, false};
    g_guard_time_s += (double)g_rp_n / (double)g_rp_fs_hz;
    ag_output_t gout;
    (void)ag_apply(&g_guard, &gin, &gout); /* a refusal holds the electrode: no error of the cycle */
    return MD_OK;
}

md_status_t bench_replay_run(bench_replay_stage_t s)
{
    if ((unsigned)s >= (unsigned)BENCH_RP_COUNT || (int)s != g_rp_next) {
        return MD_E_STATE;
    }
    md_status_t st = MD_E_ARG;
    switch (s) {
    case BENCH_RP_PUSH: st = rp_push(); break;
    case BENCH_RP_END: st = ic_end(&g_ws); break;
    case BENCH_RP_PCA: st = ic_features(&g_ws); break;
    case BENCH_RP_MHTC: st = rp_track(); break;
    case BENCH_RP_QUALITY: st = rp_score(); break;
    case BENCH_RP_CONTROL: st = rp_control(); break;
    case BENCH_RP_COUNT:
    default: break;
    }
    g_rp_next = (st == MD_OK) ? (int)s + 1 : (int)BENCH_RP_COUNT;
    return st;
}

void bench_replay_info(bench_replay_info_t *info)
{
    if (info != NULL) {
        *info = g_rp_info;
    }
}

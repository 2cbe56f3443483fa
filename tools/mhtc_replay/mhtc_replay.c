/// @file mhtc_replay.c
/// mhtc-replay: the firmware's interval pipeline run offline over a recorded
/// signal (thesis ch. 4 ran MHTC offline the same way). Per interval of one
/// channel: wavelet spike detection, min-aligned windows and noise snippets,
/// d = 2 PCA basis (H^k), Ξ, one tracker step (mhtc.h; MHTC or a baseline),
/// then SNR and isolation distance of every track of the leading hypothesis.
///
/// usage: mhtc-replay --recording DIR/recording.json --out OUT
///          [--tracker mhtc|map-nn|ml-nn|gnn] [--interval SECONDS] [--channel K]
///          [--q-uv Q] [--init-uv A] [--L N] [--g-max G] [--evidence laplace|bic] [--em-tol T]
///          [--warm-jeffreys J | --no-warm-start] [--unimodal-ratio R] [--n-scan N] [--q-move K] [--k-miss N] [--quiet]
/// Writes OUT/labels.csv, OUT/intervals.jsonl, OUT/summary.json (see docs/mhtc.md).
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "features/pca.h"
#include "metrics/quality.h"
#include "recording.h"
#include "signal/spike_detect.h"
#include "signal/spike_extract.h"
#include "tracking/mhtc.h"

#define RP_D 2u               ///< feature dimension (thesis: 2-D PCA)
#define RP_Q_UV_DEFAULT 10.0  ///< process-noise std per waveform sample and interval (µV)
#define RP_MAX_IDS 4096u      ///< distinct track IDs summarised
#define RP_PATH_MAX REC_PATH_MAX ///< longest output path

typedef struct {
    const char *recording;
    const char *out;
    mhtc_tracker_t tracker;
    double interval_s;
    uint32_t channel;
    double q_uv;
    double init_uv;
    size_t L;
    size_t g_max;
    cluster_evidence_t evidence;
    double em_tol;
    int quiet;
    double warm_jeffreys;
    double unimodal_ratio;
    double n_scan;
    double q_move;
    double k_miss;
} rp_options_t;

/* Large state lives in static storage, as on the controller. */
static rec_recording_t g_rec;
static size_t g_cap;              ///< samples of the longest interval (room in x)
static rec_conversion_t g_conv;   ///< float32 samples clipped / non-finite so far
static sd_detector_t g_det;
static sd_events_t g_ev;
static sx_spikes_t g_spk;
static sx_noise_t g_noise;
static pca_work_t g_pw;
static pca_basis_t g_basis;
static double g_y[EM_N_MAX * RP_D];
static double g_noise_y[MD_MAX_NOISE_SNIPPETS * RP_D];
static double g_qm_work[(EM_N_MAX + MD_MAX_NOISE_SNIPPETS) * RP_D];
static double g_xi[RP_D * RP_D];
static mhtc_state_t g_st;
static mhtc_workspace_t g_ws;
static mhtc_result_t g_res;
static uint32_t g_id_intervals[RP_MAX_IDS];

/// What one interval's survivors said, kept to relabel by the final best lineage.
typedef struct {
    uint32_t k;
    uint64_t start;
    size_t n;
    uint32_t *t;                                  ///< spike times (heap)
    size_t n_hyp;
    uint8_t parent[MHTC_L_MAX];
    int32_t ct[MHTC_L_MAX][MHTC_G_MAX];
    uint8_t *labels;                              ///< n_hyp × n (heap)
} rp_lineage_t;

static rp_lineage_t g_lin[REC_MAX_INTERVALS];
static double g_step_ms[REC_MAX_INTERVALS];

static int rp_usage(const char *msg)
{
    (void)fprintf(stderr,
                  "mhtc-replay: %s\nusage: mhtc-replay --recording DIR/recording.json --out OUT "
                  "[--tracker mhtc|map-nn|ml-nn|gnn] [--interval SECONDS] [--channel K] [--q-uv Q] [--init-uv A] "
                  "[--L N] [--g-max G] [--evidence laplace|bic] [--em-tol T] [--warm-jeffreys J | --no-warm-start] [--unimodal-ratio R] [--n-scan N] [--q-move K] [--k-miss N] [--quiet]\n",
                  msg);
    return 2;
}

static int rp_num(const char *s, double lo, double hi, double *v)
{
    char *end = NULL;
    errno = 0;
    const double x = strtod(s, &end);
    if ((errno != 0) || (end == s) || (*end != '\0') || !(x >= lo) || !(x <= hi)) {
        return -1;
    }
    *v = x;
    return 0;
}

static int rp_parse_args(int argc, char **argv, rp_options_t *o)
{
    memset(o, 0, sizeof *o);
    o->interval_s = 10.0;
    o->q_uv = RP_Q_UV_DEFAULT;
    o->init_uv = RP_Q_UV_DEFAULT;
    o->L = MHTC_L_MAX;
    o->g_max = MHTC_G_MAX;
    o->evidence = CLUSTER_EVIDENCE_LAPLACE;
    o->em_tol = 0.0; /* 0: the clustering default */
    o->warm_jeffreys = MHTC_WARM_JEFFREYS_DEFAULT;
    o->unimodal_ratio = MHTC_UNIMODAL_RATIO_DEFAULT;
    o->n_scan = (double)MHTC_N_SCAN_DEFAULT;
    o->q_move = MHTC_Q_MOVE_PER_UM_DEFAULT;
    o->k_miss = 0.0; /* 0: the tracker's default */
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        const char *v = (i + 1 < argc) ? argv[i + 1] : NULL;
        double x = 0.0;
        int bad = 0;
        if (strcmp(a, "--quiet") == 0) {
            o->quiet = 1;
            continue;
        }
        if (strcmp(a, "--no-warm-start") == 0) {
            o->warm_jeffreys = 0.0; /* every fit from the §3.3.4 seeds (docs/mhtc.md) */
            continue;
        }
        if (v == NULL) {
            return rp_usage("missing value after an option");
        }
        ++i;
        if (strcmp(a, "--recording") == 0) {
            o->recording = v;
        } else if (strcmp(a, "--out") == 0) {
            o->out = v;
        } else if (strcmp(a, "--tracker") == 0) {
            bad = (mhtc_tracker_parse(v, &o->tracker) != MD_OK);
        } else if (strcmp(a, "--interval") == 0) {
            bad = rp_num(v, 0.1, 3600.0, &o->interval_s);
        } else if (strcmp(a, "--channel") == 0) {
            bad = rp_num(v, 0.0, 1023.0, &x);
            o->channel = (uint32_t)x;
        } else if (strcmp(a, "--q-uv") == 0) {
            bad = rp_num(v, 1e-6, 1e6, &o->q_uv);
        } else if (strcmp(a, "--init-uv") == 0) {
            bad = rp_num(v, 1e-6, 1e6, &o->init_uv);
        } else if (strcmp(a, "--L") == 0) {
            bad = rp_num(v, 1.0, (double)MHTC_L_MAX, &x);
            o->L = (size_t)x;
        } else if (strcmp(a, "--g-max") == 0) {
            bad = rp_num(v, 1.0, (double)MHTC_G_MAX, &x);
            o->g_max = (size_t)x;
        } else if (strcmp(a, "--warm-jeffreys") == 0) {
            bad = rp_num(v, 0.0, 1e300, &o->warm_jeffreys);
        } else if (strcmp(a, "--k-miss") == 0) {
            bad = rp_num(v, 1.0, (double)MHTC_HIST_MAX, &o->k_miss) || (fabs(o->k_miss - floor(o->k_miss)) > 0.0);
        } else if (strcmp(a, "--q-move") == 0) {
            bad = rp_num(v, 0.0, 1.0, &o->q_move);
        } else if (strcmp(a, "--n-scan") == 0) {
            bad = rp_num(v, 0.0, (double)(MHTC_HIST_MAX - 1u), &o->n_scan) || (fabs(o->n_scan - floor(o->n_scan)) > 0.0);
        } else if (strcmp(a, "--unimodal-ratio") == 0) {
            bad = rp_num(v, 0.0, 1.0, &o->unimodal_ratio);
        } else if (strcmp(a, "--em-tol") == 0) {
            bad = rp_num(v, 1e-15, 1e-2, &o->em_tol);
        } else if (strcmp(a, "--evidence") == 0) {
            bad = (strcmp(v, "laplace") != 0) && (strcmp(v, "bic") != 0);
            o->evidence = (strcmp(v, "bic") == 0) ? CLUSTER_EVIDENCE_BIC : CLUSTER_EVIDENCE_LAPLACE;
        } else {
            return rp_usage("unknown option");
        }
        if (bad) {
            (void)fprintf(stderr, "mhtc-replay: %s %s: invalid value\n", a, v);
            return 2;
        }
    }
    if ((o->recording == NULL) || (o->out == NULL)) {
        return rp_usage("--recording and --out are required");
    }
    return 0;
}

/* Signal chain of one interval: events, windows, noise, PCA, features, Ξ. 0 if usable. */
static int rp_chain(const int16_t *x, size_t n, double fs, double gain)
{
    g_spk.n = 0u;
    md_status_t st = sd_restart(&g_det);
    if (st == MD_OK) {
        (void)sd_push(&g_det, x, n);
        st = sd_finish(&g_det, &g_ev);
    }
    sx_config_t sx;
    sx_config_default(&sx, (uint32_t)fs);
    sx.gain = gain;
    if (st == MD_OK) {
        st = sx_extract_spikes(x, n, &g_ev, &sx, &g_spk);
    }
    if (st == MD_OK) {
        st = sx_extract_noise(x, n, &g_ev, &sx, &g_noise);
    }
    if ((st == MD_OK) && (g_noise.n > RP_D)) {
        /* no spikes: a basis from the noise keeps the tracker's H defined; all tracks are missed */
        const int spikes = (g_spk.n >= 2u);
        st = pca_fit(spikes ? &g_spk.wave[0][0] : &g_noise.wave[0][0], spikes ? g_spk.n : g_noise.n,
                     MD_WAVE_LEN_MAX, sx.d_w, RP_D, &g_pw, &g_basis);
        if (!spikes) {
            g_spk.n = 0u;
        }
    } else if (st == MD_OK) {
        st = MD_E_DEGENERATE;
    }
    if ((st == MD_OK) && (g_spk.n > 0u)) {
        st = pca_project_all(&g_basis, &g_spk.wave[0][0], g_spk.n, MD_WAVE_LEN_MAX, g_y);
    }
    if (st == MD_OK) {
        st = pca_project_all(&g_basis, &g_noise.wave[0][0], g_noise.n, MD_WAVE_LEN_MAX, g_noise_y);
    }
    if (st == MD_OK) {
        st = qm_noise_feature_cov(&g_basis, &g_noise.wave[0][0], g_noise.n, MD_WAVE_LEN_MAX, g_xi);
    }
    return (st == MD_OK) ? 0 : -1;
}

static void rp_json_params(FILE *f, const mhtc_result_t *r)
{
    (void)fprintf(f, "\"clusters\":[");
    for (size_t g = 1u; g <= r->g; ++g) {
        const double *m = r->params.mean[g - 1u];
        const double *c = r->params.shape[g - 1u];
        const double l = r->params.lambda;
        (void)fprintf(f, "%s{\"cluster\":%zu,\"track_id\":%d,\"count\":%.3f,\"weight\":%.6f,\"mean\":[%.6g,%.6g],"
                         "\"covariance\":[[%.6g,%.6g],[%.6g,%.6g]]}",
                      (g > 1u) ? "," : "", g, (int)r->cluster_track[g - 1u], r->n_soft[g], r->params.pi[g - 1u], m[0],
                      m[1], l * c[0], l * c[1], l * c[2], l * c[3]);
    }
    (void)fprintf(f, "]");
}

/* Ranks of the surviving hypotheses that hold track `id`, and their summed probability
 * (the track's marginal probability of existing). */
static void rp_json_track_hyps(FILE *f, const mhtc_result_t *r, uint32_t id)
{
    double p = 0.0;
    int first = 1;
    (void)fprintf(f, "\"hypothesis_ranks\":[");
    for (size_t h = 0u; h < g_st.n_hyp; ++h) {
        for (size_t j = 0u; j < g_st.hyp[h].n_tracks; ++j) {
            if (g_st.pool[g_st.hyp[h].track[j]].id == id) {
                (void)fprintf(f, "%s%zu", first ? "" : ",", h + 1u);
                p += r->hyp_prob[h];
                first = 0;
                break;
            }
        }
    }
    (void)fprintf(f, "],\"probability\":%.6g", p);
}

static void rp_json_tracks(FILE *f, const mhtc_result_t *r, double noise_rms)
{
    (void)fprintf(f, ",\"tracks\":[");
    for (size_t j = 0u; j < r->n_tracks; ++j) {
        const mhtc_track_report_t *t = &r->track[j];
        double snr = 0.0;
        qm_isolation_t iso;
        memset(&iso, 0, sizeof iso);
        if (t->cluster > 0u) {
            (void)qm_snr(&g_spk.wave[0][0], g_spk.n, MD_WAVE_LEN_MAX, g_spk.d_w, r->labels, t->cluster, noise_rms,
                         &snr, NULL);
            double cov[RP_D * RP_D];
            for (size_t i = 0u; i < RP_D * RP_D; ++i) {
                cov[i] = r->params.lambda * r->params.shape[t->cluster - 1u][i];
            }
            (void)qm_isolation_distance(g_y, g_spk.n, RP_D, r->labels, t->cluster, g_noise_y, g_noise.n,
                                        r->params.mean[t->cluster - 1u], cov, g_qm_work,
                                        sizeof g_qm_work / sizeof g_qm_work[0], &iso);
        }
        (void)fprintf(f, "%s{\"id\":%u,\"cluster\":%u,\"misses\":%u,\"p_detect\":%.4f,\"rate_hz\":%.3f,\"snr\":%.4f,"
                         "\"iqm\":%.4f,\"iqm_defined\":%s,\"mean_feat\":[%.6g,%.6g],",
                      (j > 0u) ? "," : "", t->id, t->cluster, t->misses, t->p_detect, t->rate_hz, snr, iso.id,
                      iso.defined ? "true" : "false", t->mean_feat[0], t->mean_feat[1]);
        rp_json_track_hyps(f, r, t->id);
        (void)fprintf(f, "}");
    }
    (void)fprintf(f, "]");
}

static void rp_json_hyps(FILE *f, const mhtc_result_t *r)
{
    (void)fprintf(f, ",\"hypotheses\":[");
    for (size_t h = 0u; h < r->n_hyp; ++h) {
        (void)fprintf(f, "%s{\"rank\":%zu,\"probability\":%.6g,\"rank_history\":[", (h > 0u) ? "," : "", h + 1u,
                      r->hyp_prob[h]);
        for (size_t t = 0u; t < r->hyp_hist_len; ++t) {
            (void)fprintf(f, "%s%u", (t > 0u) ? "," : "", r->hyp_rank_hist[h][t]);
        }
        (void)fprintf(f, "]}");
    }
    (void)fprintf(f, "],\"log_p3\":%.6g,\"log_p4\":%.6g,\"log_assoc\":%.6g,\"models_fitted\":%zu", r->log_p3,
                  r->log_p4, r->log_assoc, r->models_fitted);
}

static void rp_write_interval(FILE *jl, FILE *lab, uint32_t k, const rec_interval_t *iv, double ms)
{
    double noise_rms = 0.0;
    (void)qm_noise_rms(&g_noise.wave[0][0], g_noise.n, MD_WAVE_LEN_MAX, g_noise.d_w, &noise_rms);
    (void)fprintf(jl, "{\"interval\":%u,\"start_sample\":%llu,\"duration_s\":%.6f,", k,
                  (unsigned long long)iv->start_sample, iv->duration_s);
    if (isfinite(iv->depth_um)) {
        (void)fprintf(jl, "\"depth_um\":%.4f,", iv->depth_um);
    }
    if (isfinite(iv->hall_code)) {
        (void)fprintf(jl, "\"hall_code\":%.0f,", iv->hall_code);
    }
    (void)fprintf(jl, "\"n_spikes\":%zu,\"n_noise\":%zu,\"noise_rms_uv\":%.4f,\"step_ms\":%.3f,", g_spk.n, g_noise.n,
                  noise_rms, ms);
    rp_json_params(jl, &g_res);
    rp_json_tracks(jl, &g_res, (noise_rms > 0.0) ? noise_rms : 1.0);
    rp_json_hyps(jl, &g_res);
    (void)fprintf(jl, "}\n");
    for (size_t i = 0u; i < g_spk.n; ++i) { /* online: the leading hypothesis of interval k */
        const uint8_t c = g_res.labels[i];
        const int id = (c > 0u) ? (int)g_res.cluster_track[c - 1u] : -1;
        (void)fprintf(lab, "%llu,%u,%u,%d\n", (unsigned long long)(iv->start_sample + g_spk.t[i]), k, c,
                      (id > 0) ? id : -1);
    }
    for (size_t j = 0u; j < g_res.n_tracks; ++j) {
        if ((g_res.track[j].cluster > 0u) && (g_res.track[j].id < RP_MAX_IDS)) {
            g_id_intervals[g_res.track[j].id]++;
        }
    }
}

/* Keeps every survivor's labels of this step (0 on success). */
static int rp_keep_lineage(rp_lineage_t *l, uint32_t k, uint64_t start)
{
    l->k = k;
    l->start = start;
    l->n = g_spk.n;
    l->n_hyp = g_st.n_hyp;
    l->t = malloc((g_spk.n + 1u) * sizeof *l->t);
    l->labels = malloc((l->n_hyp * g_spk.n + 1u) * sizeof *l->labels);
    if ((l->t == NULL) || (l->labels == NULL)) {
        return -1;
    }
    memcpy(l->t, g_spk.t, g_spk.n * sizeof *l->t);
    for (size_t h = 0u; h < l->n_hyp; ++h) {
        size_t g = 0u;
        l->parent[h] = g_st.hyp[h].parent;
        if (mhtc_hyp_labels(&g_st, &g_ws, h, g_spk.n, &l->labels[h * g_spk.n], l->ct[h], &g) != MD_OK) {
            return -1;
        }
    }
    return 0;
}

/* labels.csv by the final best hypothesis: follow parents back from the last leader (§4.5, Fig. 4.4). */
static void rp_write_final_labels(FILE *lab, uint32_t done)
{
    size_t h = 0u;
    static size_t chosen[REC_MAX_INTERVALS];
    for (uint32_t i = done; i-- > 0u;) {
        chosen[i] = (h < g_lin[i].n_hyp) ? h : 0u;
        h = g_lin[i].parent[chosen[i]];
    }
    for (uint32_t i = 0u; i < done; ++i) {
        const rp_lineage_t *l = &g_lin[i];
        for (size_t s = 0u; s < l->n; ++s) {
            const uint8_t c = l->labels[chosen[i] * l->n + s];
            const int id = (c > 0u) ? (int)l->ct[chosen[i]][c - 1u] : -1;
            (void)fprintf(lab, "%llu,%u,%u,%d\n", (unsigned long long)(l->start + l->t[s]), l->k, c,
                          (id > 0) ? id : -1);
        }
        free(l->t);
        free(l->labels);
    }
}

static double rp_now_ms(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

static int rp_cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x < y) ? -1 : ((x > y) ? 1 : 0);
}

static void rp_write_summary(FILE *f, const rp_options_t *o, uint32_t done, size_t spikes)
{
    const mhtc_stats_t *s = &g_st.stats;
    qsort(g_step_ms, done, sizeof g_step_ms[0], rp_cmp_double);
    (void)fprintf(f, "{\n  \"recording\": \"%s\",\n  \"tracker\": \"%s\",\n  \"channel\": %u,\n", o->recording,
                  mhtc_tracker_name(o->tracker), o->channel);
    (void)fprintf(f, "  \"dtype\": \"%s\",\n  \"gain_uV\": %g,\n  \"count_uV\": %g,\n  \"samples_clipped\": %llu,\n"
                     "  \"samples_non_finite\": %llu,\n",
                  rec_dtype_name(g_rec.dtype), g_rec.gain_uv, g_rec.count_uv, (unsigned long long)g_conv.clipped,
                  (unsigned long long)g_conv.non_finite);
    (void)fprintf(f, "  \"intervals\": %u,\n  \"spikes\": %zu,\n  \"q_uv\": %g,\n  \"init_uv\": %g,\n  \"L\": %zu,\n",
                  done, spikes, o->q_uv, o->init_uv, o->L);
    (void)fprintf(f, "  \"unimodal_ratio\": %g,\n", o->unimodal_ratio);
    (void)fprintf(f, "  \"step_ms_median\": %.3f,\n  \"step_ms_max\": %.3f,\n", (done > 0u) ? g_step_ms[done / 2u] : 0.0,
                  (done > 0u) ? g_step_ms[done - 1u] : 0.0);
    (void)fprintf(f,
                  "  \"stats\": {\"steps\": %u, \"step_errors\": %u, \"models_pruned\": %u, \"models_failed\": %u, "
                  "\"evidence_fallbacks\": %u, \"empty_intervals\": %u, \"dup_pruned\": %u, \"target_overflow\": %u, "
                  "\"pool_drops\": %u, \"kf_failures\": %u, \"tracks_deleted\": %u, \"murty_solves\": %u, "
                  "\"models_oversplit\": %u, \"tracks_merged\": %u, \"nscan_pruned\": %u},\n",
                  s->steps, s->step_errors, s->models_pruned, s->models_failed, s->evidence_fallbacks,
                  s->empty_intervals, s->dup_pruned, s->target_overflow, s->pool_drops, s->kf_failures,
                  s->tracks_deleted, s->murty_solves, s->models_oversplit, s->tracks_merged, s->nscan_pruned);
    (void)fprintf(f, "  \"track_ids_issued\": %u,\n  \"tracks\": [", g_st.next_id - 1u);
    int first = 1;
    for (uint32_t id = 1u; id < RP_MAX_IDS; ++id) {
        if (g_id_intervals[id] > 0u) {
            (void)fprintf(f, "%s{\"id\": %u, \"intervals_detected\": %u}", first ? "" : ", ", id, g_id_intervals[id]);
            first = 0;
        }
    }
    (void)fprintf(f, "]\n}\n");
}

static FILE *rp_open_out(const char *dir, const char *name)
{
    char path[RP_PATH_MAX + 64u];
    (void)snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    if (f == NULL) {
        (void)fprintf(stderr, "mhtc-replay: %s: cannot write: %s\n", path, strerror(errno));
    }
    return f;
}

/* mkdir -p */
static int rp_mkdirs(const char *path)
{
    char buf[RP_PATH_MAX];
    const size_t n = strlen(path);
    if ((n == 0u) || (n >= sizeof buf)) {
        errno = ENAMETOOLONG;
        return -1;
    }
    memcpy(buf, path, n + 1u);
    for (size_t i = 1u; i <= n; ++i) {
        if ((buf[i] == '/') || (buf[i] == '\0')) {
            const char c = buf[i];
            buf[i] = '\0';
            if ((mkdir(buf, 0777) != 0) && (errno != EEXIST)) {
                return -1;
            }
            buf[i] = c;
        }
    }
    return 0;
}

static int rp_setup(const rp_options_t *o, int16_t **x, int16_t **det_buf)
{
    char err[REC_ERR_MAX];
    const rec_options_t ro = {o->interval_s, o->channel};
    if (rec_read_sidecar(o->recording, &ro, &g_rec, err, sizeof err) != MD_OK) {
        (void)fprintf(stderr, "mhtc-replay: %s\n", err);
        return 1;
    }
    uint64_t cap = 0u;
    for (uint32_t k = 0u; k < g_rec.n_intervals; ++k) {
        cap = (g_rec.iv[k].num_samples > cap) ? g_rec.iv[k].num_samples : cap;
    }
    sd_config_t sdc;
    sd_config_default(&sdc, SD_METHOD_WAVELET, (uint32_t)g_rec.fs_hz);
    g_cap = (cap <= SD_MAX_INTERVAL_SAMPLES) ? (size_t)cap : 0u;
    *x = (g_cap > 0u) ? malloc(g_cap * sizeof **x) : NULL;
    *det_buf = (g_cap > 0u) ? malloc(g_cap * sizeof **det_buf) : NULL;
    if ((*x == NULL) || (*det_buf == NULL) || (sd_init(&g_det, &sdc, *det_buf, g_cap) != MD_OK)) {
        (void)fprintf(stderr, "mhtc-replay: %s: interval of %llu samples exceeds the detector (max %u)\n",
                      o->recording, (unsigned long long)cap, (unsigned)SD_MAX_INTERVAL_SAMPLES);
        return 1;
    }
    mhtc_config_t cfg;
    mhtc_config_default(&cfg, o->tracker);
    cfg.L = o->L;
    cfg.g_max = o->g_max;
    cfg.q_process = o->q_uv * o->q_uv;
    cfg.init_var = o->init_uv * o->init_uv;
    if (o->tracker != MHTC_TRACKER_ML_NN) {
        cfg.evidence = o->evidence;
    }
    if (o->em_tol > 0.0) {
        cfg.em.tol = o->em_tol;
    }
    cfg.warm_jeffreys = o->warm_jeffreys;
    cfg.unimodal_ratio = o->unimodal_ratio;
    cfg.n_scan = (uint32_t)o->n_scan;
    cfg.q_move_per_um = o->q_move;
    if (o->k_miss > 0.0) {
        cfg.k_miss = (uint32_t)o->k_miss;
    }
    if (rp_mkdirs(o->out) != 0) {
        (void)fprintf(stderr, "mhtc-replay: %s: cannot create: %s\n", o->out, strerror(errno));
        return 1;
    }
    return (mhtc_init(&g_st, &cfg) == MD_OK) ? 0 : 1;
}

static int rp_run(const rp_options_t *o, int16_t *x, FILE *jl, FILE *lab, uint32_t *done, size_t *spikes)
{
    char err[REC_ERR_MAX];
    double tracked_depth = NAN; /* depth of the last interval the tracker processed (sidecar depth_um) */
    for (uint32_t k = 0u; k < g_rec.n_intervals; ++k) {
        const rec_interval_t *iv = &g_rec.iv[k];
        const rec_conversion_t before = g_conv;
        if (rec_read_interval(&g_rec, k, o->channel, x, g_cap, &g_conv, err, sizeof err) != MD_OK) {
            (void)fprintf(stderr, "mhtc-replay: %s\n", err);
            return 1;
        }
        if ((g_conv.clipped > before.clipped) || (g_conv.non_finite > before.non_finite)) {
            (void)fprintf(stderr, "mhtc-replay: %s: interval %u, channel %u: %llu float32 sample(s) clipped to int16 "
                                  "counts of %g uV, %llu NaN/inf set to 0\n", g_rec.bin_path, k, o->channel,
                          (unsigned long long)(g_conv.clipped - before.clipped), g_rec.count_uv,
                          (unsigned long long)(g_conv.non_finite - before.non_finite));
        }
        if (rp_chain(x, (size_t)iv->num_samples, g_rec.fs_hz, g_rec.count_uv) != 0) {
            (void)fprintf(stderr, "mhtc-replay: interval %u: signal chain failed (no noise snippets or basis); "
                                  "skipped\n", k);
            continue;
        }
        /* electrode travel since the last tracked interval, as the controller measures it */
        const double move = (isfinite(iv->depth_um) && isfinite(tracked_depth)) ? fabs(iv->depth_um - tracked_depth) : 0.0;
        const mhtc_input_t in = {g_y, g_spk.n, &g_spk.wave[0][0], MD_WAVE_LEN_MAX, &g_basis, g_xi, iv->duration_s,
                                 NULL, 0.0, move};
        const double t0 = rp_now_ms();
        const md_status_t st = mhtc_step(&g_st, &in, &g_ws, &g_res);
        const double ms = rp_now_ms() - t0;
        if (st != MD_OK) {
            (void)fprintf(stderr, "mhtc-replay: interval %u: tracker step failed: %s\n", k, md_status_name(st));
            continue;
        }
        if (rp_keep_lineage(&g_lin[*done], k, iv->start_sample) != 0) {
            (void)fprintf(stderr, "mhtc-replay: out of memory\n");
            return 1;
        }
        g_step_ms[*done] = ms;
        tracked_depth = iv->depth_um;
        (*done)++;
        *spikes += g_spk.n;
        rp_write_interval(jl, lab, k, iv, ms);
        if (!o->quiet) {
            (void)fprintf(stderr, "[%u/%u] spikes %zu clusters %zu tracks %zu hyps %zu (%.1f ms)\n", k + 1u,
                          g_rec.n_intervals, g_spk.n, g_res.g, g_res.n_tracks, g_res.n_hyp, ms);
        }
    }
    return 0;
}

int main(int argc, char **argv)
{
    rp_options_t o;
    const int pa = rp_parse_args(argc, argv, &o);
    if (pa != 0) {
        return pa;
    }
    int16_t *x = NULL;
    int16_t *det_buf = NULL;
    int rc = rp_setup(&o, &x, &det_buf);
    FILE *jl = (rc == 0) ? rp_open_out(o.out, "intervals.jsonl") : NULL;
    FILE *lab = (jl != NULL) ? rp_open_out(o.out, "labels_online.csv") : NULL;
    rc = (lab == NULL) ? 1 : rc;
    uint32_t done = 0u;
    size_t spikes = 0u;
    if (rc == 0) {
        (void)fprintf(lab, "sample_index,interval,cluster,track_id\n");
        rc = rp_run(&o, x, jl, lab, &done, &spikes);
    }
    FILE *fin = (rc == 0) ? rp_open_out(o.out, "labels.csv") : NULL;
    if (fin != NULL) {
        (void)fprintf(fin, "sample_index,interval,cluster,track_id\n");
        rp_write_final_labels(fin, done);
        (void)fclose(fin);
    }
    rc = ((rc == 0) && (fin == NULL)) ? 1 : rc;
    FILE *sum = (rc == 0) ? rp_open_out(o.out, "summary.json") : NULL;
    if (sum != NULL) {
        rp_write_summary(sum, &o, done, spikes);
        (void)fclose(sum);
    }
    rc = ((rc == 0) && (sum == NULL)) ? 1 : rc;
    if (jl != NULL) {
        (void)fclose(jl);
    }
    if (lab != NULL) {
        (void)fclose(lab);
    }
    free(x);
    free(det_buf);
    return rc;
}

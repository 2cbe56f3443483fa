/// @file mhtc_replay.c
/// mhtc-replay: the controller's interval chain run offline over a recorded
/// signal (thesis ch. 4 ran MHTC offline the same way). Each interval of one
/// channel goes, as int16 counts, through pipeline/interval_chain.h, the unit
/// the controller runs: streaming wavelet detection, min-aligned int16
/// windows and noise snippets, d = 2 PCA basis (H^k), Ξ, one tracker step
/// (mhtc.h; MHTC or a baseline), then SNR and isolation distance of every
/// track of the leading hypothesis. With the controller's tracker parameters
/// (the defaults) its labels are the controller's.
///
/// usage: mhtc-replay --recording DIR/recording.json --out OUT
///          [--tracker mhtc|map-nn|ml-nn|gnn] [--interval SECONDS] [--channel K]
///          [--q-uv Q] [--init-uv A] [--L N] [--g-max G] [--evidence laplace|bic] [--em-tol T]
///          [--warm-jeffreys J | --no-warm-start] [--no-provisional-ids] [--unimodal-ratio R] [--count-sigma S]
///          [--lambda-first F] [--n-scan N] [--q-move K] [--k-miss N] [--quiet]
/// Writes OUT/labels.csv, OUT/labels_online.csv, OUT/intervals.jsonl, OUT/summary.json (see docs/mhtc.md).
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "control/approach_guard.h"
#include "pipeline/interval_chain.h"
#include "recording.h"
#include "tool_time.h"
#include "tracking/mhtc.h"

#define RP_Q_UV_DEFAULT 10.0      ///< process-noise std per waveform sample and interval (µV)
#define RP_MAX_IDS 4096u          ///< distinct track IDs summarised
#define RP_PATH_MAX REC_PATH_MAX  ///< longest output path

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
    int no_provisional_ids;
    double count_sigma;
    double lambda_first;
    double n_scan;
    double q_move;
    double k_miss;
} rp_options_t;

/* Large state lives in static storage, as on the controller. */
static rec_recording_t g_rec;
static size_t g_cap;             ///< samples of the longest interval (room in x)
static rec_conversion_t g_conv;  ///< float32 samples clipped / non-finite so far
static uint32_t g_fs_hz;         ///< the chain's sample rate: the recording's, in whole Hz
static uint8_t g_top_k;          ///< robust amplitude's k (the approach guard's default)
static uint64_t g_not_kept;      ///< detections beyond the chain's window capacity, all intervals
static ic_workspace_t g_ws;      ///< the interval chain (as the controller's md_workspace_t)
static ic_out_t g_out;
static mhtc_state_t g_st;
static uint32_t g_id_intervals[RP_MAX_IDS];

/// What one interval's survivors said, kept to relabel by the final best lineage.
typedef struct {
    uint32_t k;
    uint64_t start;
    size_t n;
    uint32_t *t;  ///< spike times (heap)
    size_t n_hyp;
    uint8_t parent[MHTC_L_MAX];
    int32_t ct[MHTC_L_MAX][MHTC_G_MAX];
    uint8_t *labels;  ///< n_hyp × n (heap)
} rp_lineage_t;

static rp_lineage_t g_lin[REC_MAX_INTERVALS];
static double g_step_ms[REC_MAX_INTERVALS];

static int rp_usage(const char *msg)
{
    (void)fprintf(
        stderr,
        "mhtc-replay: %s\nusage: mhtc-replay --recording DIR/recording.json --out OUT "
        "[--tracker mhtc|map-nn|ml-nn|gnn] [--interval SECONDS] [--channel K] [--q-uv Q] [--init-uv A] "
        "[--L N] [--g-max G] [--evidence laplace|bic] [--em-tol T] [--warm-jeffreys J | --no-warm-start] "
        "[--no-provisional-ids] "
        "[--unimodal-ratio R] [--count-sigma S] [--lambda-first F] [--n-scan N] [--q-move K] [--k-miss N] [--quiet]\n",
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

#define RP_NOT_MINE 2 /* an option helper's answer for an option it does not know */

/* --recording, --out, --tracker, --interval, --channel, --q-uv, --init-uv, --evidence: 0, 1 for a bad
 * value, RP_NOT_MINE. */
static int rp_option_chain(rp_options_t *o, const char *a, const char *v)
{
    double x = 0.0;
    int bad = 0;
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
    } else if (strcmp(a, "--evidence") == 0) {
        bad = (strcmp(v, "laplace") != 0) && (strcmp(v, "bic") != 0);
        o->evidence = (strcmp(v, "bic") == 0) ? CLUSTER_EVIDENCE_BIC : CLUSTER_EVIDENCE_LAPLACE;
    } else {
        return RP_NOT_MINE;
    }
    return bad != 0;
}

/* The tracker's own options (--L, --g-max, --warm-jeffreys, --k-miss, --q-move, --n-scan,
 * --unimodal-ratio, --em-tol): 0, 1 for a bad value, RP_NOT_MINE. */
static int rp_option_mhtc(rp_options_t *o, const char *a, const char *v)
{
    double x = 0.0;
    int bad = 0;
    if (strcmp(a, "--L") == 0) {
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
    } else if (strcmp(a, "--count-sigma") == 0) {
        bad = rp_num(v, 0.0, 100.0, &o->count_sigma);
    } else if (strcmp(a, "--lambda-first") == 0) {
        bad = rp_num(v, 1e-4, 1.0, &o->lambda_first);
    } else if (strcmp(a, "--em-tol") == 0) {
        bad = rp_num(v, 1e-15, 1e-2, &o->em_tol);
    } else {
        return RP_NOT_MINE;
    }
    return bad != 0;
}

static void rp_defaults(rp_options_t *o)
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
    o->count_sigma = MHTC_COUNT_SIGMA_DEFAULT;
    o->lambda_first = MHTC_LAMBDA_FIRST_DEFAULT;
    o->n_scan = (double)MHTC_N_SCAN_DEFAULT;
    o->q_move = MHTC_Q_MOVE_PER_UM_DEFAULT;
    o->k_miss = 0.0; /* 0: the tracker's default */
}

static int rp_parse_args(int argc, char **argv, rp_options_t *o)
{
    rp_defaults(o);
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        const char *v = (i + 1 < argc) ? argv[i + 1] : NULL;
        if (strcmp(a, "--quiet") == 0) {
            o->quiet = 1;
            continue;
        }
        if (strcmp(a, "--no-provisional-ids") == 0) {
            o->no_provisional_ids = 1; /* online labels exactly as the leading hypothesis called them */
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
        int r = rp_option_chain(o, a, v);
        if (r == RP_NOT_MINE) {
            r = rp_option_mhtc(o, a, v);
        }
        if (r == RP_NOT_MINE) {
            return rp_usage("unknown option");
        }
        if (r != 0) {
            (void)fprintf(stderr, "mhtc-replay: %s %s: invalid value\n", a, v);
            return 2;
        }
    }
    if ((o->recording == NULL) || (o->out == NULL)) {
        return rp_usage("--recording and --out are required");
    }
    return 0;
}

/* Detections the chain had no room for (window capacity, delay line): reported, never dropped silently. */
static void rp_report_not_kept(uint32_t k)
{
    const uint64_t n = (uint64_t)g_ws.win.n_overflow + (uint64_t)g_ws.win.n_lost;
    if (n > 0u) {
        (void)fprintf(stderr,
                      "mhtc-replay: %s: interval %u: %llu detection(s) not kept: %u beyond the capacity of %u "
                      "windows per interval (MD_MAX_SPIKES), %u no longer in the delay line; the controller "
                      "drops the same\n",
                      g_rec.json_path, k, (unsigned long long)n, g_ws.win.n_overflow, (unsigned)MD_MAX_SPIKES,
                      g_ws.win.n_lost);
        g_not_kept += n;
    }
}

/* Interval k through the chain up to its features (ic_begin .. ic_features), as
 * the controller streams it. MD_OK if the tracker can take it; else says why. */
static md_status_t rp_chain(const int16_t *x, size_t n, uint32_t k)
{
    const ic_config_t cfg = {g_fs_hz, g_rec.count_uv, (uint32_t)n, g_top_k};
    md_status_t st = ic_begin(&g_ws, &cfg);
    if (st == MD_OK) {
        st = ic_push(&g_ws, x, n);
        if (st != MD_OK) {
            (void)fprintf(stderr, "mhtc-replay: interval %u: detection failed: %s; skipped\n", k, md_status_name(st));
            return st;
        }
    }
    st = (st == MD_OK) ? ic_end(&g_ws) : st;
    if (st == MD_OK) {
        rp_report_not_kept(k);
        st = ic_features(&g_ws);
    }
    if (st != MD_OK) {
        (void)fprintf(stderr,
                      "mhtc-replay: interval %u: signal chain failed (%s: no noise snippets or basis); "
                      "skipped\n",
                      k, md_status_name(st));
    }
    return st;
}

static void rp_json_params(FILE *f, const mhtc_result_t *r)
{
    (void)fprintf(f, "\"clusters\":[");
    for (size_t g = 1u; g <= r->g; ++g) {
        const double *m = r->params.mean[g - 1u];
        const double *c = r->params.shape[g - 1u];
        const double l = r->params.lambda;
        (void)fprintf(f,
                      "%s{\"cluster\":%zu,\"track_id\":%d,\"count\":%.3f,\"weight\":%.6f,\"mean\":[%.6g,%.6g],"
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

/* Every track of the leading hypothesis: the chain's SNR (ic_score) and isolation distance (ic_isolation). */
static void rp_json_tracks(FILE *f, const mhtc_result_t *r)
{
    (void)fprintf(f, ",\"tracks\":[");
    for (size_t j = 0u; j < r->n_tracks; ++j) {
        const mhtc_track_report_t *t = &r->track[j];
        const double snr = g_ws.track_snr[j];
        qm_isolation_t iso;
        memset(&iso, 0, sizeof iso);
        if ((t->cluster > 0u) && (ic_isolation(&g_ws, t->cluster, &iso) != MD_OK)) {
            memset(&iso, 0, sizeof iso);
        }
        (void)fprintf(f,
                      "%s{\"id\":%u,\"cluster\":%u,\"misses\":%u,\"p_detect\":%.4f,\"rate_hz\":%.3f,\"snr\":%.4f,"
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
    (void)fprintf(f, "],\"log_p3\":%.6g,\"log_p4\":%.6g,\"log_assoc\":%.6g,\"models_fitted\":%zu", r->log_p3, r->log_p4,
                  r->log_assoc, r->models_fitted);
}

static void rp_write_interval(FILE *jl, FILE *lab, uint32_t k, const rec_interval_t *iv, double ms)
{
    const mhtc_result_t *r = &g_ws.res;
    (void)fprintf(jl, "{\"interval\":%u,\"start_sample\":%llu,\"duration_s\":%.6f,", k,
                  (unsigned long long)iv->start_sample, iv->duration_s);
    if (isfinite(iv->depth_um)) {
        (void)fprintf(jl, "\"depth_um\":%.4f,", iv->depth_um);
    }
    if (isfinite(iv->hall_code)) {
        (void)fprintf(jl, "\"hall_code\":%.0f,", iv->hall_code);
    }
    (void)fprintf(jl, "\"n_spikes\":%u,\"n_noise\":%zu,\"noise_rms_uv\":%.4f,\"step_ms\":%.3f,", g_ws.n_spikes,
                  g_ws.noise.n, g_ws.noise_rms_uv, ms);
    rp_json_params(jl, r);
    rp_json_tracks(jl, r);
    rp_json_hyps(jl, r);
    (void)fprintf(jl, "}\n");
    for (size_t i = 0u; i < g_ws.n_spikes; ++i) { /* online: the leading hypothesis of interval k */
        const uint8_t c = r->labels[i];
        const int id = (c > 0u) ? (int)r->cluster_track[c - 1u] : -1;
        (void)fprintf(lab, "%llu,%u,%u,%d\n", (unsigned long long)(iv->start_sample + g_ws.win.t[i]), k, c,
                      (id > 0) ? id : -1);
    }
    for (size_t j = 0u; j < r->n_tracks; ++j) {
        if ((r->track[j].cluster > 0u) && (r->track[j].id < RP_MAX_IDS)) {
            g_id_intervals[r->track[j].id]++;
        }
    }
}

/* Keeps every survivor's labels of this step (0 on success). Between ic_track and ic_score:
 * mhtc_hyp_labels reads the tracker's scratch, which the scoring reuses. */
static int rp_keep_lineage(rp_lineage_t *l, uint32_t k, uint64_t start)
{
    const size_t n = g_ws.n_spikes;
    l->k = k;
    l->start = start;
    l->n = n;
    l->n_hyp = g_st.n_hyp;
    l->t = malloc((n + 1u) * sizeof *l->t);
    l->labels = malloc((l->n_hyp * n + 1u) * sizeof *l->labels);
    if ((l->t == NULL) || (l->labels == NULL)) {
        return -1;
    }
    memcpy(l->t, g_ws.win.t, n * sizeof *l->t);
    for (size_t h = 0u; h < l->n_hyp; ++h) {
        size_t g = 0u;
        l->parent[h] = g_st.hyp[h].parent;
        if (mhtc_hyp_labels(&g_st, &g_ws.u.mhtc, h, n, &l->labels[h * n], l->ct[h], &g) != MD_OK) {
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

static void rp_write_summary(FILE *f, const rp_options_t *o, uint32_t done, size_t spikes)
{
    const mhtc_stats_t *s = &g_st.stats;
    qsort(g_step_ms, done, sizeof g_step_ms[0], tool_cmp_double);
    (void)fprintf(f, "{\n  \"recording\": \"%s\",\n  \"tracker\": \"%s\",\n  \"channel\": %u,\n", o->recording,
                  mhtc_tracker_name(o->tracker), o->channel);
    (void)fprintf(f,
                  "  \"dtype\": \"%s\",\n  \"gain_uV\": %g,\n  \"count_uV\": %g,\n  \"samples_clipped\": %llu,\n"
                  "  \"samples_non_finite\": %llu,\n",
                  rec_dtype_name(g_rec.dtype), g_rec.gain_uv, g_rec.count_uv, (unsigned long long)g_conv.clipped,
                  (unsigned long long)g_conv.non_finite);
    (void)fprintf(f, "  \"intervals\": %u,\n  \"spikes\": %zu,\n  \"q_uv\": %g,\n  \"init_uv\": %g,\n  \"L\": %zu,\n",
                  done, spikes, o->q_uv, o->init_uv, o->L);
    (void)fprintf(f, "  \"unimodal_ratio\": %g,\n", o->unimodal_ratio);
    (void)fprintf(f, "  \"provisional_ids\": %s,\n", (o->no_provisional_ids == 0) ? "true" : "false");
    (void)fprintf(f, "  \"count_sigma\": %g,\n  \"lambda_first\": %g,\n", o->count_sigma, o->lambda_first);
    const ic_stats_t *c = &g_ws.stats;
    (void)fprintf(f, "  \"sample_rate_hz\": %u,\n  \"detections_not_kept\": %llu,\n", g_fs_hz,
                  (unsigned long long)g_not_kept);
    (void)fprintf(f,
                  "  \"chain\": {\"intervals\": %u, \"push_errors\": %u, \"end_errors\": %u, \"feature_errors\": %u, "
                  "\"track_errors\": %u, \"snr_undefined\": %u, \"iso_undefined\": %u},\n",
                  c->intervals, c->push_errors, c->end_errors, c->feature_errors, c->track_errors, c->snr_undefined,
                  c->iso_undefined);
    (void)fprintf(f, "  \"step_ms_median\": %.3f,\n  \"step_ms_max\": %.3f,\n",
                  (done > 0u) ? g_step_ms[done / 2u] : 0.0, (done > 0u) ? g_step_ms[done - 1u] : 0.0);
    (void)fprintf(f,
                  "  \"stats\": {\"steps\": %u, \"update_errors\": %u, \"models_pruned\": %u, \"models_failed\": %u, "
                  "\"evidence_fallbacks\": %u, \"empty_intervals\": %u, \"dup_pruned\": %u, \"target_overflow\": %u, "
                  "\"pool_drops\": %u, \"kf_failures\": %u, \"tracks_deleted\": %u, \"murty_solves\": %u, "
                  "\"models_oversplit\": %u, \"tracks_merged\": %u, \"nscan_pruned\": %u},\n",
                  s->steps, s->update_errors, s->models_pruned, s->models_failed, s->evidence_fallbacks,
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

/* The chain's sample rate and interval lengths: what it cannot take is said (file, interval, reason). 0 if fine. */
static int rp_check_chain(void)
{
    const double fs = g_rec.fs_hz; /* 1000..200000 (recording.h) */
    g_fs_hz = (uint32_t)llround(fs);
    if ((fs < (double)g_fs_hz) || (fs > (double)g_fs_hz)) {
        (void)fprintf(stderr,
                      "mhtc-replay: %s: sampling_frequency %.17g Hz: the chain runs at whole Hz (the "
                      "controller's FE_INFO carries whole Hz): %u Hz\n",
                      g_rec.json_path, fs, g_fs_hz);
    }
    ag_config_t ag;
    ag_config_default(&ag);
    g_top_k = ag.top_k;
    for (uint32_t k = 0u; k < g_rec.n_intervals; ++k) {
        const uint64_t n = g_rec.iv[k].num_samples;
        if ((n == 0u) || (n > SD_MAX_INTERVAL_SAMPLES)) {
            (void)fprintf(stderr,
                          "mhtc-replay: %s: interval %u: %llu samples: the streaming chain takes 1..%u "
                          "samples per interval (SD_MAX_INTERVAL_SAMPLES)\n",
                          g_rec.json_path, k, (unsigned long long)n, (unsigned)SD_MAX_INTERVAL_SAMPLES);
            return 1;
        }
        g_cap = ((size_t)n > g_cap) ? (size_t)n : g_cap;
    }
    const ic_config_t probe = {g_fs_hz, g_rec.count_uv, (uint32_t)((g_cap > 0u) ? g_cap : 1u), g_top_k};
    if (ic_begin(&g_ws, &probe) != MD_OK) {
        (void)fprintf(stderr,
                      "mhtc-replay: %s: interval 0: sampling_frequency %u Hz is not supported by the "
                      "firmware's streaming chain, which takes 7500..32768 Hz (spike_detect.h: the narrowest "
                      "wavelet scale, 0.5 ms, needs a box of 2 samples; the 250 ms statistics warm-up must fit "
                      "SD_WARMUP_MAX = %u samples)\n",
                      g_rec.json_path, g_fs_hz, (unsigned)SD_WARMUP_MAX);
        return 1;
    }
    memset(&g_ws.stats, 0, sizeof g_ws.stats); /* the probe is no interval */
    return 0;
}

static int rp_setup(const rp_options_t *o, int16_t **x)
{
    char err[REC_ERR_MAX];
    const rec_options_t ro = {o->interval_s, o->channel};
    if (rec_read_sidecar(o->recording, &ro, &g_rec, err, sizeof err) != MD_OK) {
        (void)fprintf(stderr, "mhtc-replay: %s\n", err);
        return 1;
    }
    if (rp_check_chain() != 0) {
        return 1;
    }
    *x = (g_cap > 0u) ? malloc(g_cap * sizeof **x) : NULL;
    if ((*x == NULL) && (g_cap > 0u)) {
        (void)fprintf(stderr, "mhtc-replay: out of memory\n");
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
    cfg.provisional_ids = (o->no_provisional_ids == 0);
    cfg.count_sigma = o->count_sigma;
    cfg.lambda_first = o->lambda_first;
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

/* Reads interval k as int16 counts (float32 converted, clipping and non-finite values reported). 0 if read. */
static int rp_read(const rp_options_t *o, uint32_t k, int16_t *x)
{
    char err[REC_ERR_MAX];
    const rec_conversion_t before = g_conv;
    if (rec_read_interval(&g_rec, k, o->channel, x, g_cap, &g_conv, err, sizeof err) != MD_OK) {
        (void)fprintf(stderr, "mhtc-replay: %s\n", err);
        return 1;
    }
    if ((g_conv.clipped > before.clipped) || (g_conv.non_finite > before.non_finite)) {
        (void)fprintf(stderr,
                      "mhtc-replay: %s: interval %u, channel %u: %llu float32 sample(s) clipped to int16 "
                      "counts of %g uV, %llu NaN/inf set to 0\n",
                      g_rec.bin_path, k, o->channel, (unsigned long long)(g_conv.clipped - before.clipped),
                      g_rec.count_uv, (unsigned long long)(g_conv.non_finite - before.non_finite));
    }
    return 0;
}

static int rp_run(const rp_options_t *o, int16_t *x, FILE *jl, FILE *lab, uint32_t *done, size_t *spikes)
{
    double tracked_depth = NAN; /* depth of the last interval the tracker processed (sidecar depth_um) */
    for (uint32_t k = 0u; k < g_rec.n_intervals; ++k) {
        const rec_interval_t *iv = &g_rec.iv[k];
        if (rp_read(o, k, x) != 0) {
            return 1;
        }
        if (rp_chain(x, (size_t)iv->num_samples, k) != MD_OK) {
            continue; /* as the controller: the tracker does not see the interval */
        }
        /* electrode travel since the last tracked interval, as the controller measures it */
        const double move = (isfinite(iv->depth_um) && isfinite(tracked_depth)) ? fabs(iv->depth_um - tracked_depth)
                                                                                : 0.0;
        const double t0 = tool_now_ms();
        const md_status_t st = ic_track(&g_ws, &g_st, move);
        const double ms = tool_now_ms() - t0;
        if (st != MD_OK) {
            (void)fprintf(stderr, "mhtc-replay: interval %u: tracker step failed: %s\n", k, md_status_name(st));
            continue;
        }
        if (rp_keep_lineage(&g_lin[*done], k, iv->start_sample) != 0) {
            (void)fprintf(stderr, "mhtc-replay: out of memory\n");
            return 1;
        }
        (void)ic_score(&g_ws, &g_out); /* after ic_track it cannot fail */
        g_step_ms[*done] = ms;
        tracked_depth = iv->depth_um;
        (*done)++;
        *spikes += g_ws.n_spikes;
        rp_write_interval(jl, lab, k, iv, ms);
        if (!o->quiet) {
            (void)fprintf(stderr, "[%u/%u] spikes %u clusters %zu tracks %zu hyps %zu (%.1f ms)\n", k + 1u,
                          g_rec.n_intervals, g_ws.n_spikes, g_ws.res.g, g_ws.res.n_tracks, g_ws.res.n_hyp, ms);
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
    int rc = rp_setup(&o, &x);
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
    return rc;
}

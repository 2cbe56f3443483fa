/// @file cluster_consistency.c
/// Clustering-consistency experiment of thesis §3.5.2 on a simulator export:
/// every interval of one channel goes through the controller's signal chain
/// (pipeline/interval_chain.h up to its features: streaming wavelet
/// detection, min-aligned int16 windows, noise snippets, d = 2 PCA, Ξ) and
/// is clustered twice with cluster_fit_models():
///  - MAP (§3.3): mean prior and seeds from the clusters chosen in interval
///    k-1, model prior = that interval's model posterior with forgetting
///    (§3.3.5, α = 0.95), Laplace evidence (eq. 3.18);
///  - ML (§3.5): no prior, Ward seeds, BIC.
/// How the k-1 clusters become the prior of interval k (Remark 3.5 / 4.1):
/// the member waveforms of cluster j (hard labels of the chosen model) stay in
/// full waveform space and are projected with interval k's basis B^k; their
/// mean is μ̂_j (= B^k times the mean waveform), their sample covariance is
/// Σ_j^{k-1}, R_j = Σ_j / n_j, S_j = R_j + Q with Q = q² I_d (B^k Q_w B^kᵀ for
/// an isotropic waveform-space Q_w = q² I), and P_d,j = q(r_j) of §4.4.2 from
/// the cluster's firing rate r_j = n_j / interval duration, clamped to
/// [P_d,min, P_d,max] of Table 4.1.
///
/// Output (stdout): one CSV row per interval with Ĝ of both methods, the
/// truth count and the classification accuracy. With --drift, instead one
/// row per (neuron, interval) with the squared change of the neuron's true
/// mean waveform projected into B^k: the data to calibrate q on held-out seeds.
///
/// usage: cluster-consistency DIR [--channel C] [--q-uv Q] [--map-evidence laplace|bic]
///                            [--drift] [--clusters] [--no-header]
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cc_io.h"
#include "cluster/cluster.h"
#include "numeric/linalg.h"
#include "control/approach_guard.h"
#include "features/pca.h"
#include "metrics/quality.h"
#include "pipeline/interval_chain.h"
#include "recording.h"

#define CC_D 2u                   ///< feature dimension (thesis §3.5: 2-D PCA)
#define CC_MAX_NEURONS 64u        ///< truth neurons per channel
#define CC_TRUE_MIN_SPIKES 10u    ///< a neuron is "in range" with at least this many detected spikes...
#define CC_TRUE_MIN_FRACTION 0.5  ///< ...and at least this fraction of its spikes detected
#define CC_MATCH_MS 0.5           ///< a detection within this of a truth trough is that spike
#define CC_PD_MAX 0.98            ///< Table 4.1
#define CC_PD_MIN 0.75            ///< Table 4.1
#define CC_PD_A 0.6               ///< §4.4.2
#define CC_PD_B 4.0               ///< §4.4.2
#define CC_Q_UV_DEFAULT 10.0      ///< q when --q-uv is not given (docs/clustering-consistency.md)

typedef struct {
    const char *dir;
    uint32_t channel;
    double q_uv;
    int drift;
    int header;
    int clusters;  ///< --clusters: composition of every chosen cluster on stderr
    int map_bic;   ///< --map-evidence bic: MAP with BIC instead of Laplace (diagnostic)
} cc_options_t;

/// One processed interval (signal chain output plus truth labels).
typedef struct {
    sx_windows_t win;  ///< the interval's windows (int16 counts, gain: µV per count)
    double y[EM_N_MAX * CC_D];
    int32_t truth_of[EM_N_MAX];  ///< truth neuron of each detected spike, -1 if none
    uint32_t n_all[CC_MAX_NEURONS];
    uint32_t n_det[CC_MAX_NEURONS];
    double duration_s;
    int valid;  ///< the chain produced features (≥ 2 spikes, Ξ SPD)
} cc_interval_data_t;

/// What the MAP method carries from interval k-1 to k.
typedef struct {
    int have;
    size_t g;
    uint8_t labels[EM_N_MAX];
    double post[EM_G_MAX];  ///< model posterior P(M_m | Y^{1:k-1})
    int have_post;
} cc_map_state_t;

static ic_workspace_t chain;  ///< the controller's interval chain
static uint32_t chain_fs_hz;  ///< its sample rate: the recording's, in whole Hz
static uint8_t chain_top_k;   ///< robust amplitude's k (the approach guard's default; not used here)
static pca_basis_t basis;
static cc_interval_data_t ivd[2];
static cluster_workspace_t cws;
static cluster_result_t res_map;
static cluster_result_t res_ml;
static double xi[CC_D * CC_D];

/* ---------------------------------------------------------------- truth */

static void label_truth(const cc_truth_t *truth, uint64_t start, double fs, cc_interval_data_t *d)
{
    memset(d->n_all, 0, sizeof d->n_all);
    memset(d->n_det, 0, sizeof d->n_det);
    const uint64_t tol = (uint64_t)llround(CC_MATCH_MS * 1e-3 * fs);
    const size_t lo = cc_truth_lower_bound(truth, start);
    const size_t hi = cc_truth_lower_bound(truth, start + (uint64_t)llround(d->duration_s * fs));
    for (size_t j = lo; j < hi; ++j) {
        if ((uint32_t)truth->neuron[j] < CC_MAX_NEURONS) {
            d->n_all[truth->neuron[j]]++;
        }
    }
    size_t last = SIZE_MAX;
    for (size_t i = 0u; i < d->win.n; ++i) {
        d->truth_of[i] = -1;
        const uint64_t t = start + d->win.t[i];
        size_t j = cc_truth_lower_bound(truth, (t > tol) ? t - tol : 0u);
        size_t best = SIZE_MAX;
        uint64_t best_dist = tol + 1u;
        for (; (j < truth->n) && (truth->sample[j] <= t + tol); ++j) {
            const uint64_t dist = (truth->sample[j] > t) ? truth->sample[j] - t : t - truth->sample[j];
            if (dist < best_dist) {
                best_dist = dist;
                best = j;
            }
        }
        if ((best != SIZE_MAX) && (best != last) && ((uint32_t)truth->neuron[best] < CC_MAX_NEURONS)) {
            d->truth_of[i] = truth->neuron[best];
            d->n_det[truth->neuron[best]]++;
            last = best;
        }
    }
}

static uint32_t true_count(const cc_interval_data_t *d, char *ids, size_t idlen)
{
    uint32_t n = 0u;
    size_t pos = 0u;
    ids[0] = '\0';
    for (uint32_t u = 0u; u < CC_MAX_NEURONS; ++u) {
        if ((d->n_det[u] >= CC_TRUE_MIN_SPIKES) &&
            ((double)d->n_det[u] >= CC_TRUE_MIN_FRACTION * (double)d->n_all[u])) {
            const int w = snprintf(ids + pos, idlen - pos, "%s%u", (n > 0u) ? ";" : "", u);
            if ((w > 0) && ((size_t)w < idlen - pos)) {
                pos += (size_t)w;
            }
            n++;
        }
    }
    return n;
}

/// Thesis §3.5.1: each cluster is matched to the truth neuron it shares most
/// spikes with; those spikes are correct. Fraction of the true spikes detected.
static double accuracy(const cc_interval_data_t *d, const uint8_t *labels, size_t g)
{
    static uint32_t conf[EM_G_MAX + 1u][CC_MAX_NEURONS];
    memset(conf, 0, sizeof conf);
    uint32_t n_true = 0u;
    for (size_t i = 0u; i < d->win.n; ++i) {
        if (d->truth_of[i] >= 0) {
            n_true++;
            if (labels[i] <= g) {
                conf[labels[i]][d->truth_of[i]]++;
            }
        }
    }
    uint32_t correct = 0u;
    for (size_t c = 1u; c <= g; ++c) {
        uint32_t best = 0u;
        for (uint32_t u = 0u; u < CC_MAX_NEURONS; ++u) {
            best = (conf[c][u] > best) ? conf[c][u] : best;
        }
        correct += best;
    }
    return (n_true > 0u) ? (double)correct / (double)n_true : 0.0;
}

/* --------------------------------------------------------- signal chain */

/* The controller's chain up to its features (ic_begin .. ic_features); the
 * windows, features, basis and Ξ are kept (the next interval's prior projects
 * these windows into its basis). */
static md_status_t run_chain(const int16_t *x, size_t n, double gain, cc_interval_data_t *d)
{
    d->valid = 0;
    d->win.n = 0u;
    const ic_config_t cfg = {chain_fs_hz, gain, (uint32_t)n, chain_top_k};
    md_status_t st = ic_begin(&chain, &cfg);
    st = (st == MD_OK) ? ic_push(&chain, x, n) : st;
    st = (st == MD_OK) ? ic_end(&chain) : st;
    if (st != MD_OK) {
        return st;
    }
    d->win = chain.win;
    st = ic_features(&chain);
    if ((st != MD_OK) || (chain.n_spikes < 2u)) {
        return st;
    }
    memcpy(d->y, chain.y, (size_t)chain.n_spikes * CC_D * sizeof d->y[0]);
    basis = chain.basis;
    memcpy(xi, chain.xi, sizeof xi);
    d->valid = 1;
    return MD_OK;
}

/* ------------------------------------------------------------ MAP prior */

static double p_detect(double rate_hz)
{
    const double q = CC_PD_MAX - 1.0 / (CC_PD_A * rate_hz + CC_PD_B); /* q(r), §4.4.2 */
    return (q < CC_PD_MIN) ? CC_PD_MIN : ((q > CC_PD_MAX) ? CC_PD_MAX : q);
}

/// Target j from the k-1 members of cluster `label`, in interval k's basis
/// (Remark 3.5): 0 on success, -1 if the cluster is too small or its
/// projected covariance is not SPD (then it is left out of the prior).
static int make_target(const cc_interval_data_t *prev, const uint8_t *labels, uint8_t label, double q_uv,
                       em_target_t *tg)
{
    static double py[EM_N_MAX * CC_D];
    size_t m = 0u;
    for (size_t i = 0u; i < prev->win.n; ++i) {
        if ((labels[i] == label) &&
            (pca_project_i16(&basis, prev->win.wave[i], prev->win.gain, &py[m * CC_D]) == MD_OK)) {
            m++;
        }
    }
    memset(tg, 0, sizeof *tg);
    if ((m < (size_t)EM_MIN_POINTS_PER_CLUSTER(CC_D)) ||
        (qm_feature_cov(py, m, CC_D, tg->mean, tg->cluster_cov) != MD_OK)) {
        return -1;
    }
    double chol[CC_D * CC_D];
    memcpy(chol, tg->cluster_cov, sizeof chol);
    if (linalg_cholesky(chol, CC_D) != MD_OK) {
        return -1;
    }
    for (size_t r = 0u; r < CC_D; ++r) {
        for (size_t c = 0u; c < CC_D; ++c) {
            /* S_j = Σ_j / n_j + Q (eq. 3.8, S = R + Q) */
            tg->s_cov[r * CC_D + c] = tg->cluster_cov[r * CC_D + c] / (double)m + ((r == c) ? q_uv * q_uv : 0.0);
        }
    }
    tg->p_detect = p_detect((double)m / prev->duration_s);
    return 0;
}

static size_t make_targets(const cc_interval_data_t *prev, const cc_map_state_t *ms, double q_uv, em_target_t *tg)
{
    size_t n = 0u;
    for (size_t g = 1u; (g <= ms->g) && (n < EM_J_MAX); ++g) {
        if (make_target(prev, ms->labels, (uint8_t)g, q_uv, &tg[n]) == 0) {
            n++;
        }
    }
    return n;
}

/* ------------------------------------------------------------ one interval */

typedef struct {
    size_t g;
    double p;
    double acc;
} cc_choice_t;

/// stderr rows `k,method,g,n,mean_y0,mean_y1,false,top_neuron,top_count`:
/// what each chosen cluster is made of (detections matching no truth spike = false).
static void print_clusters(uint32_t k, const char *method, const cluster_result_t *r, const cc_interval_data_t *d)
{
    static uint32_t cnt[EM_G_MAX + 1u][CC_MAX_NEURONS + 1u];
    if (r->best_g == 0u) {
        return;
    }
    const cluster_model_t *m = &r->model[r->best_g - 1u];
    memset(cnt, 0, sizeof cnt);
    for (size_t i = 0u; i < d->win.n; ++i) {
        const uint32_t u = (d->truth_of[i] >= 0) ? (uint32_t)d->truth_of[i] : CC_MAX_NEURONS;
        cnt[m->labels[i]][u]++;
    }
    for (size_t g = 0u; g <= r->best_g; ++g) {
        uint32_t n = 0u;
        uint32_t top = 0u;
        uint32_t top_u = 0u;
        for (uint32_t u = 0u; u <= CC_MAX_NEURONS; ++u) {
            n += cnt[g][u];
            if ((u < CC_MAX_NEURONS) && (cnt[g][u] > top)) {
                top = cnt[g][u];
                top_u = u;
            }
        }
        const double y0 = (g > 0u) ? m->fit.params.mean[g - 1u][0] : 0.0;
        const double y1 = (g > 0u) ? m->fit.params.mean[g - 1u][1] : 0.0;
        (void)fprintf(stderr, "%u,%s,%zu,%u,%.1f,%.1f,%u,%u,%u\n", k, method, g, n, y0, y1, cnt[g][CC_MAX_NEURONS],
                      top_u, top);
    }
}

static cc_choice_t choose(const cluster_result_t *r, const cc_interval_data_t *d)
{
    cc_choice_t c = {0u, 0.0, 0.0};
    if (r->best_g > 0u) {
        c.g = r->best_g;
        c.p = r->model[r->best_g - 1u].post_prob;
        c.acc = accuracy(d, r->model[r->best_g - 1u].labels, r->best_g);
    }
    return c;
}

static void cluster_interval(const cc_options_t *o, const cc_interval_data_t *cur, const cc_interval_data_t *prev,
                             cc_map_state_t *ms, cc_choice_t *map, cc_choice_t *ml, size_t *n_targets)
{
    static em_target_t tg[EM_J_MAX];
    cluster_config_t cfg;
    *n_targets = 0u;
    map->g = ml->g = 0u;
    map->p = ml->p = map->acc = ml->acc = 0.0;
    double prior[EM_G_MAX];
    const int have_prior = ms->have_post &&
                           (cluster_model_prior_forget(ms->post, EM_G_MAX, CLUSTER_ALPHA_FORGET, prior) == MD_OK);
    if (!cur->valid) {
        if (have_prior) { /* no data: the model prior only forgets */
            memcpy(ms->post, prior, sizeof prior);
        }
        ms->have = 0;
        return;
    }
    *n_targets = ms->have ? make_targets(prev, ms, o->q_uv, tg) : 0u;
    cluster_input_t in = {{cur->y, cur->win.n, CC_D}, xi, tg, *n_targets, have_prior ? prior : NULL};
    cluster_config_default(&cfg, CLUSTER_MAP);
    cfg.evidence = o->map_bic ? CLUSTER_EVIDENCE_BIC : CLUSTER_EVIDENCE_LAPLACE;
    (void)cluster_fit_models(&cfg, &in, &cws, &res_map);
    *map = choose(&res_map, cur);
    if (res_map.best_g > 0u) {
        ms->have = 1;
        ms->g = res_map.best_g;
        memcpy(ms->labels, res_map.model[res_map.best_g - 1u].labels, cur->win.n);
        for (size_t g = 0u; g < EM_G_MAX; ++g) {
            ms->post[g] = res_map.model[g].post_prob;
        }
        ms->have_post = 1;
    } else {
        ms->have = 0;
        if (have_prior) {
            memcpy(ms->post, prior, sizeof prior);
        }
    }
    const cluster_input_t in_ml = {{cur->y, cur->win.n, CC_D}, xi, NULL, 0u, NULL};
    cluster_config_default(&cfg, CLUSTER_ML);
    (void)cluster_fit_models(&cfg, &in_ml, &cws, &res_ml);
    *ml = choose(&res_ml, cur);
}

/* ----------------------------------------------------------------- drift */

static int mean_wave(const cc_interval_data_t *d, int32_t nid, double *mean)
{
    size_t m = 0u;
    memset(mean, 0, MD_WAVE_LEN_MAX * sizeof *mean);
    for (size_t i = 0u; i < d->win.n; ++i) {
        if (d->truth_of[i] == nid) {
            for (size_t s = 0u; s < d->win.d_w; ++s) {
                mean[s] += d->win.gain * (double)d->win.wave[i][s];
            }
            m++;
        }
    }
    for (size_t s = 0u; (m > 0u) && (s < d->win.d_w); ++s) {
        mean[s] /= (double)m;
    }
    return (m >= CC_TRUE_MIN_SPIKES) ? 0 : -1;
}

/// Rows `k,neuron,dq2`: |B^k (x̄^k - x̄^{k-1})|² / d for every truth neuron
/// with enough detected spikes in both intervals (the per-axis variance of
/// the true mean's move between intervals: what Q stands for).
static void print_drift(uint32_t k, const cc_interval_data_t *cur, const cc_interval_data_t *prev)
{
    double a[MD_WAVE_LEN_MAX];
    double b[MD_WAVE_LEN_MAX];
    for (int32_t u = 0; u < (int32_t)CC_MAX_NEURONS; ++u) {
        if ((mean_wave(cur, u, a) != 0) || (mean_wave(prev, u, b) != 0)) {
            continue;
        }
        for (size_t s = 0u; s < MD_WAVE_LEN_MAX; ++s) {
            a[s] -= b[s];
        }
        double y[CC_D];
        if (pca_project(&basis, a, y) == MD_OK) {
            printf("%u,%d,%.6f\n", k, u, (y[0] * y[0] + y[1] * y[1]) / (double)CC_D);
        }
    }
}

/* ------------------------------------------------------------------ main */

static int parse_args(int argc, char **argv, cc_options_t *o)
{
    memset(o, 0, sizeof *o);
    o->q_uv = CC_Q_UV_DEFAULT;
    o->header = 1;
    if (argc < 2) {
        return -1;
    }
    o->dir = argv[1];
    for (int i = 2; i < argc; ++i) {
        char *end = NULL;
        if ((strcmp(argv[i], "--channel") == 0) && (i + 1 < argc)) {
            o->channel = (uint32_t)strtoul(argv[++i], &end, 10);
        } else if ((strcmp(argv[i], "--q-uv") == 0) && (i + 1 < argc)) {
            o->q_uv = strtod(argv[++i], &end);
            if (!(o->q_uv > 0.0)) {
                return -1;
            }
        } else if (strcmp(argv[i], "--drift") == 0) {
            o->drift = 1;
        } else if ((strcmp(argv[i], "--map-evidence") == 0) && (i + 1 < argc)) {
            o->map_bic = (strcmp(argv[++i], "bic") == 0);
            if (!o->map_bic && (strcmp(argv[i], "laplace") != 0)) {
                return -1;
            }
        } else if (strcmp(argv[i], "--clusters") == 0) {
            o->clusters = 1;
        } else if (strcmp(argv[i], "--no-header") == 0) {
            o->header = 0;
        } else {
            return -1;
        }
        if ((end != NULL) && (*end != '\0')) {
            return -1;
        }
    }
    return 0;
}

static void print_row(const rec_recording_t *rec, const cc_options_t *o, uint32_t k, const cc_interval_data_t *d,
                      const cc_choice_t *map, const cc_choice_t *ml, size_t n_targets)
{
    char ids[256];
    const uint32_t n_true = true_count(d, ids, sizeof ids);
    size_t n_false = 0u;
    for (size_t i = 0u; i < d->win.n; ++i) {
        n_false += (d->truth_of[i] < 0) ? 1u : 0u;
    }
    printf("%s,%llu,%u,%u,%.2f,%zu,%zu,%zu,%u,%s,%zu,%zu,%.4f,%.4f,%zu,%.4f,%.4f,%u\n", rec->scenario,
           (unsigned long long)rec->seed, o->channel, k, rec->iv[k].depth_um, d->win.n, n_false, chain.noise.n, n_true,
           ids, n_targets, map->g, map->p, map->acc, ml->g, ml->p, ml->acc, d->win.n_overflow);
}

static int run(const cc_options_t *o, const rec_recording_t *rec, const cc_truth_t *truth, int16_t *x, size_t cap)
{
    static cc_map_state_t ms;
    char err[REC_ERR_MAX];
    rec_conversion_t conv = {0u, 0u};
    memset(&ms, 0, sizeof ms);
    long psi_map = 0;
    long psi_ml = 0;
    size_t g_prev_map = 0u;
    size_t g_prev_ml = 0u;
    for (uint32_t k = 0u; k < rec->n_intervals; ++k) {
        cc_interval_data_t *cur = &ivd[k % 2u];
        const cc_interval_data_t *prev = &ivd[(k + 1u) % 2u];
        const rec_conversion_t before = conv;
        if (rec_read_interval(rec, k, o->channel, x, cap, &conv, err, sizeof err) != MD_OK) {
            (void)fprintf(stderr, "cluster-consistency: %s\n", err);
            return 1;
        }
        if ((conv.clipped > before.clipped) || (conv.non_finite > before.non_finite)) {
            (void)fprintf(stderr,
                          "cluster-consistency: %s: interval %u, channel %u: %llu float32 sample(s) clipped to "
                          "int16 counts of %g uV, %llu NaN/inf set to 0\n",
                          rec->bin_path, k, o->channel, (unsigned long long)(conv.clipped - before.clipped),
                          rec->count_uv, (unsigned long long)(conv.non_finite - before.non_finite));
        }
        cur->duration_s = (double)rec->iv[k].num_samples / rec->fs_hz;
        (void)run_chain(x, (size_t)rec->iv[k].num_samples, rec->count_uv, cur);
        label_truth(truth, rec->iv[k].start_sample, rec->fs_hz, cur);
        if (o->drift) {
            if ((k > 0u) && cur->valid && prev->valid) {
                print_drift(k, cur, prev);
            }
            continue;
        }
        cc_choice_t map;
        cc_choice_t ml;
        size_t n_targets = 0u;
        cluster_interval(o, cur, prev, &ms, &map, &ml, &n_targets);
        if (o->clusters) {
            print_clusters(k, "map", &res_map, cur);
            print_clusters(k, "ml", &res_ml, cur);
        }
        print_row(rec, o, k, cur, &map, &ml, n_targets);
        if (k > 0u) { /* Ψ of §3.5.2 */
            psi_map += labs((long)map.g - (long)g_prev_map);
            psi_ml += labs((long)ml.g - (long)g_prev_ml);
        }
        g_prev_map = map.g;
        g_prev_ml = ml.g;
    }
    if (!o->drift) {
        (void)fprintf(stderr, "cluster-consistency: %s seed %llu ch %u: Psi MAP %ld, ML %ld\n", rec->scenario,
                      (unsigned long long)rec->seed, o->channel, psi_map, psi_ml);
    }
    return 0;
}

int main(int argc, char **argv)
{
    cc_options_t o;
    if (parse_args(argc, argv, &o) != 0) {
        (void)fprintf(stderr, "usage: cluster-consistency DIR [--channel C] [--q-uv Q] [--map-evidence laplace|bic]\n"
                              "                           [--drift] [--clusters] [--no-header]\n");
        return 2;
    }
    static rec_recording_t rec;
    char err[REC_ERR_MAX];
    char path[REC_PATH_MAX + 32u];
    (void)snprintf(path, sizeof path, "%s/recording.json", o.dir);
    const rec_options_t ro = {0.0, o.channel}; /* the export's interval list is required */
    const md_status_t st = rec_read_sidecar(path, &ro, &rec, err, sizeof err);
    if (st != MD_OK) {
        (void)fprintf(stderr, "cluster-consistency: %s\n", err);
        return (st == MD_E_ARG) ? 2 : 1; /* MD_E_ARG: a --channel the recording lacks */
    }
    cc_truth_t truth;
    char why[4400];
    if (cc_read_truth(o.dir, o.channel, &truth, why, sizeof why) != MD_OK) {
        (void)fprintf(stderr, "cluster-consistency: %s\n", why);
        return 1;
    }
    size_t cap = 0u;
    for (uint32_t k = 0u; k < rec.n_intervals; ++k) {
        cap = (rec.iv[k].num_samples > cap) ? (size_t)rec.iv[k].num_samples : cap;
    }
    ag_config_t ag;
    ag_config_default(&ag);
    chain_top_k = ag.top_k;
    chain_fs_hz = (uint32_t)llround(rec.fs_hz);
    const ic_config_t probe = {chain_fs_hz, rec.count_uv, (uint32_t)((cap > 0u) ? cap : 1u), chain_top_k};
    int16_t *x = malloc(cap * sizeof *x);
    if ((x == NULL) || (cap == 0u) || (cap > SD_MAX_INTERVAL_SAMPLES) || (ic_begin(&chain, &probe) != MD_OK)) {
        (void)fprintf(stderr,
                      "cluster-consistency: %s: the firmware's streaming chain cannot take %u Hz (7500..32768) "
                      "or intervals of %zu samples (at most %u)\n",
                      path, chain_fs_hz, cap, (unsigned)SD_MAX_INTERVAL_SAMPLES);
        free(x);
        cc_truth_free(&truth);
        return 1;
    }
    if (o.header) {
        printf(o.drift
                   ? "k,neuron,dq2_uv2\n"
                   : "scenario,seed,channel,k,depth_um,n_spikes,n_false,n_noise,n_true,true_ids,n_targets,g_map,p_map,"
                     "acc_map,g_ml,p_ml,acc_ml,det_overflow\n");
    }
    const int rc = run(&o, &rec, &truth, x, cap);
    free(x);
    cc_truth_free(&truth);
    return rc;
}

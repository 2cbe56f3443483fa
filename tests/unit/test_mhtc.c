/// @file test_mhtc.c
/// Scripted MHTC scenarios on synthetic clustered intervals (thesis §4.2.3,
/// §4.4.1): a silent neuron keeps its ID, a new neuron gets a new ID, a
/// one-interval false cluster is not made a track, the best hypothesis was
/// ranked below first when it was born (delayed decision), and memory
/// sharing/limits hold. Small enough for the QEMU target.
#include <math.h>
#include <string.h>

#include "numeric/md_rng.h"
#include "features/pca.h"
#include "metrics/quality.h"
#include "tracking/mhtc.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define DW 16u
#define D 2u
#define N_MAX 200u
#define N_NOISE 64u
#define NOISE_SD 1.0

static mhtc_state_t g_st;
static mhtc_workspace_t g_ws;
static mhtc_result_t g_out;
static pca_work_t g_pw;
static pca_basis_t g_basis;
static double g_wave[N_MAX][DW];
static double g_noise[N_NOISE][DW];
static double g_y[N_MAX * D];
static double g_xi[D * D];
static uint8_t g_truth[N_MAX]; /* generating neuron per spike (0 = outlier) */
static size_t g_n;
static double g_move_um; /* electrode travel before the next interval */
static md_rng_t g_rng;

/* Neuron templates: a negative peak and a positive rebound, shape set by (centre, width, amplitude). */
static double template_at(int neuron, size_t i)
{
    const double c[4] = {0.0, 5.0, 7.0, 4.0};
    const double a[4] = {0.0, -12.0, -7.0, 9.0};
    const double w[4] = {1.0, 1.2, 2.5, 1.0};
    const double t = ((double)i - c[neuron]) / w[neuron];
    return a[neuron] * exp(-0.5 * t * t) - 0.4 * a[neuron] * exp(-0.5 * (t - 3.0) * (t - 3.0) / 4.0);
}

static void add_spikes(int neuron, size_t count)
{
    for (size_t k = 0u; (k < count) && (g_n < N_MAX); ++k, ++g_n) {
        for (size_t i = 0u; i < DW; ++i) {
            g_wave[g_n][i] = template_at(neuron, i) + NOISE_SD * md_rng_gauss(&g_rng);
        }
        g_truth[g_n] = (uint8_t)neuron;
    }
}

/* A tight transient group (a "false cluster"): one random waveform plus small jitter. */
static void add_transient(size_t count)
{
    double base[DW];
    for (size_t i = 0u; i < DW; ++i) {
        base[i] = 6.0 * sin(0.7 * (double)i);
    }
    for (size_t k = 0u; (k < count) && (g_n < N_MAX); ++k, ++g_n) {
        for (size_t i = 0u; i < DW; ++i) {
            g_wave[g_n][i] = base[i] + NOISE_SD * md_rng_gauss(&g_rng);
        }
        g_truth[g_n] = 9u;
    }
}

/* PCA, features and Ξ of the interval built so far, then one tracker step. */
static md_status_t run_interval(void)
{
    for (size_t k = 0u; k < N_NOISE; ++k) {
        for (size_t i = 0u; i < DW; ++i) {
            g_noise[k][i] = NOISE_SD * md_rng_gauss(&g_rng);
        }
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_fit(&g_wave[0][0], g_n, DW, DW, D, &g_pw, &g_basis));
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_project_all(&g_basis, &g_wave[0][0], g_n, DW, g_y));
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_noise_feature_cov(&g_basis, &g_noise[0][0], N_NOISE, DW, g_xi));
    const mhtc_input_t in = {g_y, g_n, &g_wave[0][0], DW, &g_basis, g_xi, 10.0, NULL, 0.0, g_move_um};
    const md_status_t rc = mhtc_update(&g_st, &in, &g_ws, &g_out);
    g_n = 0u;
    return rc;
}

/* Track ID the leading hypothesis gives to the majority of `neuron`'s spikes (-2 if none). */
static int32_t id_of(int neuron)
{
    size_t votes[MHTC_G_MAX + 1u] = {0};
    size_t total = 0u;
    for (size_t i = 0u; i < N_MAX; ++i) {
        if (g_truth[i] == (uint8_t)neuron) {
            votes[g_out.labels[i]]++;
            total++;
        }
    }
    size_t best = 0u;
    for (size_t g = 1u; g <= g_out.g; ++g) {
        best = (votes[g] > votes[best]) ? g : best;
    }
    if ((total == 0u) || (best == 0u)) {
        return -2;
    }
    return g_out.cluster_track[best - 1u];
}

static void start(mhtc_tracker_t tracker, uint64_t seed)
{
    mhtc_config_t cfg;
    mhtc_config_default(&cfg, tracker);
    cfg.g_max = 3u;
    cfg.q_process = 0.05;
    cfg.init_var = 0.1;
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_init(&g_st, &cfg));
    md_rng_seed(&g_rng, seed);
    g_n = 0u;
    g_move_um = 0.0;
}

/* Runs one interval with the given neurons present; keeps truth labels for id_of(). */
static void add_outliers(size_t count)
{
    for (size_t k = 0u; (k < count) && (g_n < N_MAX); ++k, ++g_n) {
        for (size_t i = 0u; i < DW; ++i) {
            g_wave[g_n][i] = 6.0 * md_rng_gauss(&g_rng);
        }
        g_truth[g_n] = 0u;
    }
}

static void interval_with(bool a, bool b, bool c)
{
    memset(g_truth, 0, sizeof g_truth);
    add_outliers(4u);
    if (a) {
        add_spikes(1, 60u);
    }
    if (b) {
        add_spikes(2, 50u);
    }
    if (c) {
        add_spikes(3, 50u);
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, run_interval());
}

static void test_silent_neuron_keeps_id(void)
{
    start(MHTC_TRACKER_MHTC, 1u);
    int32_t id_a = -2, id_b = -2;
    for (int k = 0; k < 3; ++k) {
        interval_with(true, true, false);
        id_a = id_of(1);
        id_b = id_of(2);
    }
    TEST_ASSERT_TRUE(id_a > 0);
    TEST_ASSERT_TRUE(id_b > 0);
    TEST_ASSERT_TRUE(id_a != id_b);
    for (int k = 0; k < 3; ++k) { /* B silent for 3 intervals (< K_miss = 5) */
        interval_with(true, false, false);
        TEST_ASSERT_EQUAL_INT32(id_a, id_of(1));
    }
    interval_with(true, true, false);
    TEST_ASSERT_EQUAL_INT32(id_a, id_of(1));
    TEST_ASSERT_EQUAL_INT32(id_b, id_of(2));
}

static void test_new_neuron_new_id_and_delayed_decision(void)
{
    start(MHTC_TRACKER_MHTC, 2u);
    interval_with(true, false, false);
    interval_with(true, false, false);
    const int32_t id_a = id_of(1);
    TEST_ASSERT_TRUE(id_a > 0);
    interval_with(true, false, true); /* C appears at interval 3 */
    interval_with(true, false, true);
    interval_with(true, false, true);
    const int32_t id_c = id_of(3);
    TEST_ASSERT_EQUAL_INT32(id_a, id_of(1));
    TEST_ASSERT_TRUE(id_c > 0);
    TEST_ASSERT_TRUE(id_c != id_a);
    /* An unmatched cluster is first ranked false (λφ > λν), so the lineage that started C's
     * track was not the leading hypothesis when C appeared, two intervals ago (rank history
     * newest first: index 2 is interval 3). */
    TEST_ASSERT_TRUE(g_out.hyp_hist_len >= 3u);
    TEST_ASSERT_GREATER_THAN_UINT(1u, g_out.hyp_rank_hist[0][2]);
    TEST_ASSERT_EQUAL_UINT(1u, g_out.hyp_rank_hist[0][0]);
}

/* A new neuron's first interval, where the leading hypothesis still calls its cluster false:
 * with provisional IDs its spikes carry the ID that its track keeps once the delayed decision is
 * made; without them, none. Either way the leading hypothesis has no track for it yet. */
static int32_t first_sight_id(bool provisional, int32_t *kept, size_t *tracks_then)
{
    start(MHTC_TRACKER_MHTC, 2u);
    g_st.cfg.provisional_ids = provisional;
    interval_with(true, false, false);
    interval_with(true, false, false);
    interval_with(true, false, true); /* C appears */
    const int32_t first = id_of(3);
    *tracks_then = g_out.n_tracks;
    interval_with(true, false, true);
    interval_with(true, false, true);
    *kept = id_of(3);
    return first;
}

static void test_new_neuron_provisional_id_is_the_one_it_keeps(void)
{
    int32_t kept_on = 0, kept_off = 0;
    size_t tracks_on = 0u, tracks_off = 0u;
    const int32_t on = first_sight_id(true, &kept_on, &tracks_on);
    const int32_t off = first_sight_id(false, &kept_off, &tracks_off);
    TEST_ASSERT_EQUAL_INT32(MHTC_ID_FALSE, off);
    TEST_ASSERT_TRUE(kept_on > 0);
    TEST_ASSERT_EQUAL_INT32(kept_on, on);
    TEST_ASSERT_EQUAL_INT32(kept_off, kept_on); /* the tracks themselves are the same */
    TEST_ASSERT_EQUAL_size_t(1u, tracks_on);    /* A only: C's track is not in the lead yet */
    TEST_ASSERT_EQUAL_size_t(tracks_off, tracks_on);
}

/* Neurons present when tracking starts: with the first interval's own rate of new neurons
 * (λν,1 > λφ) the leading hypothesis holds a track for each of them at once; with the steady
 * rate λν < λφ it calls every cluster false and the tracks enter the lead only later. */
static size_t tracks_after_first_interval(double lambda_first, int32_t ids[3])
{
    start(MHTC_TRACKER_MHTC, 4u);
    g_st.cfg.lambda_first = lambda_first;
    interval_with(true, true, true);
    for (int k = 0; k < 3; ++k) {
        ids[k] = id_of(k + 1);
    }
    return g_out.n_tracks;
}

static void test_neurons_present_at_start_are_tracks_at_once(void)
{
    mhtc_config_t steady;
    mhtc_config_default(&steady, MHTC_TRACKER_MHTC);
    int32_t ids[3];
    TEST_ASSERT_EQUAL_size_t(0u, tracks_after_first_interval(steady.lambda_new, ids));
    TEST_ASSERT_EQUAL_size_t(3u, tracks_after_first_interval(MHTC_LAMBDA_FIRST_DEFAULT, ids));
    TEST_ASSERT_TRUE((ids[0] > 0) && (ids[1] > 0) && (ids[2] > 0));
    TEST_ASSERT_TRUE((ids[0] != ids[1]) && (ids[1] != ids[2]) && (ids[0] != ids[2]));
    int32_t later[3] = {0};
    for (int k = 0; k < 3; ++k) { /* the IDs given at the first interval are the ones kept */
        interval_with(true, true, true);
    }
    for (int k = 0; k < 3; ++k) {
        later[k] = id_of(k + 1);
    }
    TEST_ASSERT_EQUAL_INT32_ARRAY(ids, later, 3);
}

static void test_false_cluster_not_a_track(void)
{
    start(MHTC_TRACKER_MHTC, 3u);
    interval_with(true, false, false);
    interval_with(true, false, false);
    memset(g_truth, 0, sizeof g_truth);
    add_spikes(1, 60u);
    add_transient(14u); /* a one-off tight group */
    TEST_ASSERT_EQUAL_INT(MD_OK, run_interval());
    for (int k = 0; k < 4; ++k) {
        interval_with(true, false, false);
    }
    TEST_ASSERT_EQUAL_size_t(1u, g_out.n_tracks); /* only neuron A's track in the leading hypothesis */
    TEST_ASSERT_EQUAL_UINT32(1u, g_out.track[0].id);
}

static void test_ids_monotonic_and_pool_shared(void)
{
    start(MHTC_TRACKER_MHTC, 4u);
    for (int k = 0; k < 4; ++k) {
        interval_with(true, true, false);
    }
    /* records are shared: far fewer than L × tracks */
    size_t live = 0u, refs = 0u;
    for (size_t r = 0u; r < MHTC_POOL; ++r) {
        live += (g_st.pool[r].refs > 0u) ? 1u : 0u;
        refs += g_st.pool[r].refs;
    }
    size_t tracks = 0u;
    for (size_t h = 0u; h < g_st.n_hyp; ++h) {
        tracks += g_st.hyp[h].n_tracks;
    }
    TEST_ASSERT_EQUAL_size_t(tracks, refs);
    TEST_ASSERT_TRUE(live < tracks);
    /* probabilities of the survivors are normalised and sorted */
    double sum = 0.0;
    for (size_t h = 0u; h < g_out.n_hyp; ++h) {
        sum += g_out.hyp_prob[h];
        if (h > 0u) {
            TEST_ASSERT_TRUE(g_out.hyp_prob[h] <= g_out.hyp_prob[h - 1u]);
        }
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1.0, sum);
    TEST_ASSERT_TRUE(g_st.next_id > 2u);
    /* the leading hypothesis' labels are retrievable like any survivor's, and parents are valid */
    static uint8_t lab[N_MAX];
    int32_t ct[MHTC_G_MAX];
    size_t g = 0u;
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_hyp_labels(&g_st, &g_ws, 0u, 114u, lab, ct, &g));
    TEST_ASSERT_EQUAL_size_t(g_out.g, g);
    TEST_ASSERT_EQUAL_MEMORY(g_out.labels, lab, 114u);
    TEST_ASSERT_EQUAL_MEMORY(g_out.cluster_track, ct, sizeof ct);
    for (size_t h = 0u; h < g_st.n_hyp; ++h) {
        TEST_ASSERT_TRUE(g_st.hyp[h].parent < MHTC_L_MAX);
    }
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_hyp_labels(&g_st, &g_ws, g_st.n_hyp, 114u, lab, ct, &g));
    TEST_MESSAGE("pool sharing verified");
}

/* Two parents naming the same track records have bit-identical priors: their
 * model hypotheses are fitted once and copied (stats.models_shared), and the
 * copies equal a fresh fit of that parent alone on the same interval. */
static mhtc_state_t g_st_one;
static mhtc_model_t g_fresh[MHTC_MODELS_MAX];

static void make_twin_parents(void)
{
    g_st.hyp[1] = g_st.hyp[0];
    g_st.hyp[1].log_prob = g_st.hyp[0].log_prob - 1.0;
    g_st.n_hyp = 2u;
    for (size_t r = 0u; r < MHTC_POOL; ++r) {
        g_st.pool[r].refs = 0u;
    }
    for (size_t h = 0u; h < g_st.n_hyp; ++h) {
        for (size_t j = 0u; j < g_st.hyp[h].n_tracks; ++j) {
            g_st.pool[g_st.hyp[h].track[j]].refs++;
        }
    }
}

/* Field by field, exactly (struct padding is not compared). */
static void same_model(const mhtc_model_t *a, const mhtc_model_t *b)
{
    TEST_ASSERT_EQUAL_UINT32(a->fit.iterations, b->fit.iterations);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, a->fit.log_post, b->fit.log_post);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, a->log_ev, b->log_ev);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, a->log_norm, b->log_norm);
    TEST_ASSERT_EQUAL_MEMORY(a->fit.params.mean, b->fit.params.mean, sizeof a->fit.params.mean);
    TEST_ASSERT_EQUAL_MEMORY(a->fit.zeta, b->fit.zeta, sizeof a->fit.zeta);
    TEST_ASSERT_EQUAL_MEMORY(a->labels, b->labels, sizeof a->labels);
    TEST_ASSERT_EQUAL_size_t(a->n_sol, b->n_sol);
}

static void test_identical_priors_fitted_once(void)
{
    start(MHTC_TRACKER_MHTC, 6u);
    for (int k = 0; k < 3; ++k) {
        interval_with(true, true, false);
    }
    TEST_ASSERT_TRUE(g_st.hyp[0].n_tracks > 0u);
    make_twin_parents();
    g_st_one = g_st;
    g_st_one.n_hyp = 1u;
    for (size_t j = 0u; j < g_st.hyp[1].n_tracks; ++j) {
        g_st_one.pool[g_st.hyp[1].track[j]].refs--;
    }
    const md_rng_t rng = g_rng;
    g_st_one.stats.models_shared = 0u;
    const mhtc_state_t twin = g_st;
    g_st = g_st_one; /* fresh fit of parent 0 alone */
    interval_with(true, true, false);
    const size_t n_fresh = g_ws.n_models;
    TEST_ASSERT_TRUE(n_fresh > 0u);
    TEST_ASSERT_EQUAL_UINT32(0u, g_st.stats.models_shared);
    memcpy(g_fresh, g_ws.model, n_fresh * sizeof g_fresh[0]);
    g_st = twin; /* both parents, same interval */
    g_rng = rng;
    const uint32_t shared0 = g_st.stats.models_shared;
    interval_with(true, true, false);
    TEST_ASSERT_EQUAL_size_t(2u * n_fresh, g_ws.n_models);
    TEST_ASSERT_EQUAL_UINT32((uint32_t)n_fresh, g_st.stats.models_shared - shared0);
    for (size_t m = 0u; m < n_fresh; ++m) {
        const mhtc_model_t *a = &g_ws.model[m];
        const mhtc_model_t *b = &g_ws.model[n_fresh + m];
        TEST_ASSERT_EQUAL_UINT8(0u, a->parent);
        TEST_ASSERT_EQUAL_UINT8(1u, b->parent);
        TEST_ASSERT_EQUAL_UINT8(g_fresh[m].g, b->g);
        same_model(&g_fresh[m], b);
        same_model(a, b);
    }
}

/* Thesis §4.6: parents with similar priors reuse one EM fit, re-evaluated
 * under each parent's own prior. On a scripted two-neuron run it must be used,
 * and give the same leading tracks and labels as fitting every parent. */
static uint8_t g_labels_ref[N_MAX];

static void run_two_neurons(double share, uint64_t seed)
{
    start(MHTC_TRACKER_MHTC, seed);
    g_st.cfg.share_jeffreys = share;
    g_st.cfg.unimodal_ratio = 0.0;
    for (int k = 0; k < 5; ++k) {
        interval_with(true, k != 2, false);
    }
}

/* The leading tracks and labels of this run equal ref's. */
static void assert_same_leading(const mhtc_result_t *ref)
{
    TEST_ASSERT_EQUAL_size_t(ref->n_tracks, g_out.n_tracks);
    for (size_t j = 0u; j < ref->n_tracks; ++j) {
        TEST_ASSERT_EQUAL_UINT32(ref->track[j].id, g_out.track[j].id);
    }
    TEST_ASSERT_EQUAL_size_t(ref->g, g_out.g);
    TEST_ASSERT_EQUAL_MEMORY(g_labels_ref, g_out.labels, sizeof g_labels_ref);
}

static void test_similar_priors_reuse_fits(void)
{
    /* reuse between parents is what is tested: models are kept whatever their modes */
    run_two_neurons(0.0, 10u);
    TEST_ASSERT_EQUAL_UINT32(0u, g_st.stats.models_reused);
    const mhtc_result_t ref = g_out;
    memcpy(g_labels_ref, g_out.labels, sizeof g_labels_ref);
    run_two_neurons(MHTC_SHARE_JEFFREYS_DEFAULT, 10u);
    TEST_ASSERT_GREATER_THAN_UINT(0u, g_st.stats.models_reused);
    assert_same_leading(&ref);
}

/* Two neurons, one silent in the third interval; every parent fits (no reuse), with the
 * warm start and the split seeds from other parents as given. */
static void run_two_neurons_fitted(double warm_jeffreys, bool seed_from_others, uint64_t seed)
{
    start(MHTC_TRACKER_MHTC, seed);
    g_st.cfg.share_jeffreys = 0.0;
    g_st.cfg.warm_jeffreys = warm_jeffreys;
    g_st.cfg.seed_from_others = seed_from_others;
    for (int k = 0; k < 5; ++k) {
        interval_with(true, k != 2, false);
    }
}

/* Warm start (docs/mhtc.md): later parents' fits start from an earlier parent's
 * fit of the same class. On the scripted run it must be used and leave the
 * leading tracks and labels as fitting every parent from its own seeds. */
static void test_warm_start_same_leading_hypothesis(void)
{
    run_two_neurons_fitted(0.0, false, 11u);
    TEST_ASSERT_EQUAL_UINT32(0u, g_st.stats.models_warm);
    const mhtc_result_t ref = g_out;
    memcpy(g_labels_ref, g_out.labels, sizeof g_labels_ref);
    run_two_neurons_fitted(MHTC_WARM_JEFFREYS_DEFAULT, false, 11u);
    TEST_ASSERT_GREATER_THAN_UINT(0u, g_st.stats.models_warm);
    assert_same_leading(&ref);
    TEST_ASSERT_DOUBLE_WITHIN(1e-3, ref.log_p4, g_out.log_p4);
}

/* Seeds of a split class from another parent's targets (docs/mhtc.md): used on the
 * scripted run (without warm starts, so that every split class seeds), and the same
 * leading tracks and labels as from the split of each parent's own targets. */
static void test_split_class_seeded_from_another_parent(void)
{
    run_two_neurons_fitted(0.0, false, 11u);
    TEST_ASSERT_EQUAL_UINT32(0u, g_st.stats.models_seeded_other);
    const mhtc_result_t ref = g_out;
    memcpy(g_labels_ref, g_out.labels, sizeof g_labels_ref);
    run_two_neurons_fitted(0.0, true, 11u);
    TEST_ASSERT_GREATER_THAN_UINT(0u, g_st.stats.models_seeded_other);
    assert_same_leading(&ref);
}

/* Neuron 1 as a real one fires: amplitude jitter of 8 % and, in one spike of
 * four, a burst spike at 0.6 to 0.9 of the amplitude (a tail towards the
 * origin along the neuron's own waveform). */
static void add_varying_spikes(size_t count)
{
    for (size_t k = 0u; (k < count) && (g_n < N_MAX); ++k, ++g_n) {
        const double u = md_rng_uniform(&g_rng);
        const double burst = (u < 0.25) ? (0.6 + 1.2 * u) : 1.0;
        const double scale = burst * (1.0 + 0.08 * md_rng_gauss(&g_rng));
        for (size_t i = 0u; i < DW; ++i) {
            g_wave[g_n][i] = scale * template_at(1, i) + NOISE_SD * md_rng_gauss(&g_rng);
        }
        g_truth[g_n] = 1u;
    }
}

/* Track IDs the leading hypothesis gave to clusters over 8 intervals of a varying neuron 1 and a
 * steady neuron 2. */
static size_t tracks_of_varying_neuron(double unimodal_ratio, uint32_t *oversplit)
{
    start(MHTC_TRACKER_MHTC, 21u);
    g_st.cfg.g_max = 4u;
    g_st.cfg.unimodal_ratio = unimodal_ratio;
    int32_t ids[8];
    size_t distinct = 0u;
    for (size_t k = 0u; k < 8u; ++k) {
        memset(g_truth, 0, sizeof g_truth);
        add_outliers(4u);
        add_spikes(2, 40u); /* a steady neuron: the clusters share its (small) volume */
        add_varying_spikes(150u);
        TEST_ASSERT_EQUAL_INT(MD_OK, run_interval());
        for (size_t g = 0u; g < g_out.g; ++g) {
            const int32_t id = g_out.cluster_track[g];
            bool seen = (id == MHTC_ID_FALSE);
            for (size_t j = 0u; j < distinct; ++j) {
                seen = seen || (ids[j] == id);
            }
            if (!seen && (distinct < 8u)) {
                ids[distinct++] = id;
            }
        }
    }
    *oversplit = g_st.stats.models_oversplit;
    return distinct;
}

/* A neuron whose spikes vary in amplitude is one track: a model that covers it
 * with two overlapping clusters (one mode) is dropped. Without the rule the same
 * intervals give it several tracks (the test can tell the two apart). The
 * clusters share one volume (§3.3), set by the steady neuron. */
static void test_one_mode_is_one_track(void)
{
    uint32_t oversplit = 0u;
    TEST_ASSERT_GREATER_THAN_size_t(2u, tracks_of_varying_neuron(0.0, &oversplit));
    TEST_ASSERT_EQUAL_UINT32(0u, oversplit);
    TEST_ASSERT_EQUAL_size_t(2u, tracks_of_varying_neuron(MHTC_UNIMODAL_RATIO_DEFAULT, &oversplit));
    TEST_ASSERT_GREATER_THAN_UINT32(0u, oversplit);
}

/* Neuron 1 at a fixed amplitude scale (no jitter beyond the noise). */
static void add_scaled_spikes(double scale, size_t count)
{
    for (size_t k = 0u; (k < count) && (g_n < N_MAX); ++k, ++g_n) {
        for (size_t i = 0u; i < DW; ++i) {
            g_wave[g_n][i] = scale * template_at(1, i) + NOISE_SD * md_rng_gauss(&g_rng);
        }
        g_truth[g_n] = 1u;
    }
}

/* Neuron 1 shows as two separate groups for two intervals (at 1 and 0.75 of its amplitude:
 * two modes, two tracks), then as one group between them (0.875). Returns the leading hypothesis' track count at the end and
 * neuron 1's ID before the split and at the end. */
static size_t split_then_rejoin(double unimodal_ratio, int32_t *id_before, int32_t *id_after)
{
    start(MHTC_TRACKER_MHTC, 31u);
    g_st.cfg.unimodal_ratio = unimodal_ratio;
    for (size_t k = 0u; k < 9u; ++k) {
        memset(g_truth, 0, sizeof g_truth);
        add_outliers(4u);
        add_spikes(2, 50u);
        if ((k == 3u) || (k == 4u)) {
            add_scaled_spikes(1.0, 50u);
            add_scaled_spikes(0.75, 50u);
        } else {
            add_scaled_spikes((k < 3u) ? 1.0 : 0.875, 100u);
        }
        TEST_ASSERT_EQUAL_INT(MD_OK, run_interval());
        *id_before = (k == 2u) ? id_of(1) : *id_before;
    }
    *id_after = id_of(1);
    return g_out.n_tracks;
}

/* A missed track that forms one mode with a detected track of its hypothesis is the same
 * neuron's second track: it leaves the hypothesis and the neuron keeps its older ID. Without
 * the rule the neuron ends with a stale second track still there (K_miss = 5) or under the
 * newer track's ID once the older one was missed K_miss times. */
static void test_second_track_of_a_neuron_merges_into_the_older(void)
{
    int32_t before = -2, after = -2;
    const size_t without = split_then_rejoin(0.0, &before, &after);
    TEST_ASSERT_TRUE(before > 0);
    TEST_ASSERT_TRUE((without == 3u) || (after != before));
    const uint32_t merged0 = g_st.stats.tracks_merged;
    TEST_ASSERT_EQUAL_UINT32(0u, merged0);
    TEST_ASSERT_EQUAL_size_t(2u, split_then_rejoin(MHTC_UNIMODAL_RATIO_DEFAULT, &before, &after));
    TEST_ASSERT_TRUE(before > 0);
    TEST_ASSERT_EQUAL_INT32(before, after);
    TEST_ASSERT_GREATER_THAN_UINT32(0u, g_st.stats.tracks_merged);
}

/* A move scales a neuron's waveform by an uncertain gain: its cluster lands far from the
 * prediction in units of its own spread but within the gain's. A lineage that calls the track
 * missed there and starts a new one on the cluster holds the neuron twice; with the missed
 * track's predicted spread in the one-mode test that pair is one track, the older ID. */
static void test_new_track_within_a_missed_tracks_spread_is_the_same_neuron(void)
{
    start(MHTC_TRACKER_MHTC, 41u);
    for (int k = 0; k < 3; ++k) {
        memset(g_truth, 0, sizeof g_truth);
        add_outliers(4u);
        add_scaled_spikes(1.0, 100u);
        TEST_ASSERT_EQUAL_INT(MD_OK, run_interval());
    }
    const int32_t id = id_of(1);
    TEST_ASSERT_TRUE(id > 0);
    g_move_um = 20.0; /* gain spread 0.02/µm · 20 µm = 40 % (1 σ) */
    memset(g_truth, 0, sizeof g_truth);
    add_outliers(4u);
    add_scaled_spikes(1.3, 100u);
    TEST_ASSERT_EQUAL_INT(MD_OK, run_interval());
    TEST_ASSERT_EQUAL_INT32(id, id_of(1));
    TEST_ASSERT_GREATER_THAN_UINT32(0u, g_st.stats.tracks_merged);
    for (size_t i = 0u; i < g_st.n_hyp; ++i) { /* no hypothesis holds the neuron twice */
        TEST_ASSERT_EQUAL_UINT8(1u, g_st.hyp[i].n_tracks);
        TEST_ASSERT_EQUAL_UINT32((uint32_t)id, g_st.pool[g_st.hyp[i].track[0]].id);
    }
}

/* The leading hypothesis' record of track `id` (NULL if it holds none). */
static const mhtc_track_t *leading_record(int32_t id)
{
    const mhtc_hyp_t *h = &g_st.hyp[0];
    for (size_t j = 0u; j < h->n_tracks; ++j) {
        if (g_st.pool[h->track[j]].id == (uint32_t)id) {
            return &g_st.pool[h->track[j]];
        }
    }
    return NULL;
}

static void interval_of_neuron(size_t spikes)
{
    memset(g_truth, 0, sizeof g_truth);
    add_outliers(4u);
    add_spikes(1, spikes);
    TEST_ASSERT_EQUAL_INT(MD_OK, run_interval());
}

/* A record keeps the counts of its last three detections (a missed interval adds none), so the
 * count term's reference after counts 100, 100, 40 is the neuron's 100, not the dip's 40. */
static void test_count_reference_follows_the_detections(void)
{
    start(MHTC_TRACKER_MHTC, 43u);
    interval_of_neuron(100u);
    const int32_t id = id_of(1);
    TEST_ASSERT_TRUE(id > 0);
    const mhtc_track_t *t = leading_record(id);
    TEST_ASSERT_NOT_NULL(t);
    TEST_ASSERT_TRUE((t->n_prev[0] < 0.0) && (t->n_prev[1] < 0.0)); /* a new track has no history */
    interval_of_neuron(100u);
    interval_of_neuron(100u);
    interval_of_neuron(40u);
    TEST_ASSERT_EQUAL_INT32(id, id_of(1));
    t = leading_record(id);
    TEST_ASSERT_NOT_NULL(t);
    TEST_ASSERT_DOUBLE_WITHIN(6.0, 40.0, t->n_last);
    TEST_ASSERT_DOUBLE_WITHIN(6.0, 100.0, t->n_prev[0]);
    TEST_ASSERT_DOUBLE_WITHIN(6.0, 100.0, t->n_prev[1]);
    TEST_ASSERT_DOUBLE_WITHIN(6.0, 100.0, mhtc_count_reference(t->n_last, t->n_prev));
    interval_of_neuron(0u); /* the neuron silent: its record is missed, not detected */
    t = leading_record(id);
    TEST_ASSERT_NOT_NULL(t);
    TEST_ASSERT_EQUAL_UINT8(1u, t->misses);
    TEST_ASSERT_DOUBLE_WITHIN(6.0, 40.0, t->n_last);
    TEST_ASSERT_DOUBLE_WITHIN(6.0, 100.0, t->n_prev[1]);
}

static void test_empty_interval_and_bad_input(void)
{
    start(MHTC_TRACKER_MHTC, 5u);
    interval_with(true, false, false);
    interval_with(true, false, false);
    const int32_t id_a = id_of(1);
    /* too few spikes for any model: all tracks missed, not an error */
    add_spikes(1, 2u);
    TEST_ASSERT_EQUAL_INT(MD_OK, run_interval());
    TEST_ASSERT_EQUAL_size_t(0u, g_out.g);
    TEST_ASSERT_EQUAL_UINT32(1u, g_st.stats.empty_intervals);
    /* with no cluster at all, hypotheses with fewer tracks lead (P3 = Π(1 - P_d) e^{-λ0}),
     * but A's track survives, missed once, in another hypothesis */
    bool kept = false;
    for (size_t h = 0u; h < g_st.n_hyp; ++h) {
        for (size_t j = 0u; j < g_st.hyp[h].n_tracks; ++j) {
            const mhtc_track_t *t = &g_st.pool[g_st.hyp[h].track[j]];
            kept = kept || ((t->id == (uint32_t)id_a) && (t->misses == 1u));
        }
    }
    TEST_ASSERT_TRUE(kept);
    interval_with(true, false, false);
    TEST_ASSERT_EQUAL_INT32(id_a, id_of(1));
    /* bad input is rejected and counted, state untouched */
    const uint32_t steps = g_st.stats.steps;
    mhtc_input_t in = {g_y, 10u, &g_wave[0][0], DW, &g_basis, g_xi, 0.0, NULL, 0.0, 0.0};
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_update(&g_st, &in, &g_ws, &g_out));
    in.duration_s = 10.0;
    g_y[0] = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_update(&g_st, &in, &g_ws, &g_out));
    TEST_ASSERT_EQUAL_UINT32(steps, g_st.stats.steps);
    TEST_ASSERT_EQUAL_UINT32(2u, g_st.stats.update_errors);
    mhtc_config_t bad;
    mhtc_config_default(&bad, MHTC_TRACKER_MHTC);
    bad.L = MHTC_L_MAX + 1u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_init(&g_st, &bad));
}

static void test_baselines_run_and_nn_loses_silent_neuron(void)
{
    const mhtc_tracker_t t[3] = {MHTC_TRACKER_MAP_NN, MHTC_TRACKER_ML_NN, MHTC_TRACKER_GNN};
    for (size_t k = 0u; k < 3u; ++k) {
        start(t[k], 6u);
        interval_with(true, true, false);
        interval_with(true, true, false);
        const int32_t id_a = id_of(1), id_b = id_of(2);
        TEST_ASSERT_TRUE(id_a > 0);
        TEST_ASSERT_TRUE(id_b > 0);
        interval_with(true, false, false);
        TEST_ASSERT_EQUAL_INT32(id_a, id_of(1));
        interval_with(true, true, false);
        TEST_ASSERT_EQUAL_INT32(id_a, id_of(1));
        if (t[k] != MHTC_TRACKER_GNN) {
            /* NN baselines keep a track one interval only (thesis §3.4): B comes back as a new ID */
            TEST_ASSERT_TRUE(id_of(2) != id_b);
        } else {
            TEST_ASSERT_EQUAL_INT32(id_b, id_of(2));
        }
        TEST_ASSERT_EQUAL_size_t(1u, g_out.n_hyp);
    }
}

/* The controller hands the tracker int16 windows plus a gain instead of a
 * double copy; both forms of the same waveforms must give the same tracks. */
static mhtc_state_t g_st_i16;
static mhtc_result_t g_out_i16;
static int16_t g_wave_i16[N_MAX][DW];

static void test_int16_input_equals_double_input(void)
{
    const double gain = 0.125; /* waveform units per ADC count: exact in binary */
    mhtc_config_t cfg;
    mhtc_config_default(&cfg, MHTC_TRACKER_MHTC);
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_init(&g_st, &cfg));
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_init(&g_st_i16, &cfg));
    for (unsigned k = 0u; k < 3u; ++k) {
        g_n = 0u;
        add_spikes(1, 60u);
        add_spikes(2, 50u);
        for (size_t i = 0u; i < g_n; ++i) { /* quantise, then use the exact quantised values in both forms */
            for (size_t q = 0u; q < DW; ++q) {
                g_wave_i16[i][q] = (int16_t)lround(g_wave[i][q] / gain);
                g_wave[i][q] = gain * (double)g_wave_i16[i][q];
            }
        }
        TEST_ASSERT_EQUAL_INT(MD_OK, pca_fit(&g_wave[0][0], g_n, DW, DW, D, &g_pw, &g_basis));
        TEST_ASSERT_EQUAL_INT(MD_OK, pca_project_all(&g_basis, &g_wave[0][0], g_n, DW, g_y));
        for (size_t j = 0u; j < N_NOISE; ++j) {
            for (size_t q = 0u; q < DW; ++q) {
                g_noise[j][q] = NOISE_SD * md_rng_gauss(&g_rng);
            }
        }
        TEST_ASSERT_EQUAL_INT(MD_OK, qm_noise_feature_cov(&g_basis, &g_noise[0][0], N_NOISE, DW, g_xi));
        const mhtc_input_t in_d = {g_y, g_n, &g_wave[0][0], DW, &g_basis, g_xi, 10.0, NULL, 0.0, 0.0};
        const mhtc_input_t in_i = {g_y, g_n, NULL, DW, &g_basis, g_xi, 10.0, &g_wave_i16[0][0], gain, 0.0};
        TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_update(&g_st, &in_d, &g_ws, &g_out));
        TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_update(&g_st_i16, &in_i, &g_ws, &g_out_i16));
        TEST_ASSERT_EQUAL_UINT(g_out.n_tracks, g_out_i16.n_tracks);
        TEST_ASSERT_EQUAL_MEMORY(g_out.labels, g_out_i16.labels, g_n);
        for (size_t t = 0u; t < g_out.n_tracks; ++t) {
            TEST_ASSERT_EQUAL_UINT(g_out.track[t].id, g_out_i16.track[t].id);
            for (size_t c = 0u; c < D; ++c) {
                TEST_ASSERT_DOUBLE_WITHIN(1e-12, g_out.track[t].mean_feat[c], g_out_i16.track[t].mean_feat[c]);
            }
        }
    }
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(2u, g_out.n_tracks);
    /* An int16 input without a valid gain is refused. */
    const mhtc_input_t bad = {g_y, g_n, NULL, DW, &g_basis, g_xi, 10.0, &g_wave_i16[0][0], 0.0, 0.0};
    TEST_ASSERT_TRUE(mhtc_update(&g_st_i16, &bad, &g_ws, &g_out_i16) < 0);
    g_n = 0u;
}

static void test_tracker_names(void)
{
    mhtc_tracker_t t;
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_tracker_parse("ml-nn", &t));
    TEST_ASSERT_EQUAL_INT(MHTC_TRACKER_ML_NN, t);
    TEST_ASSERT_EQUAL_STRING("gnn", mhtc_tracker_name(MHTC_TRACKER_GNN));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, mhtc_tracker_parse("kalman", &t));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_silent_neuron_keeps_id);
    RUN_TEST(test_new_neuron_new_id_and_delayed_decision);
    RUN_TEST(test_new_neuron_provisional_id_is_the_one_it_keeps);
    RUN_TEST(test_neurons_present_at_start_are_tracks_at_once);
    RUN_TEST(test_false_cluster_not_a_track);
    RUN_TEST(test_ids_monotonic_and_pool_shared);
    RUN_TEST(test_identical_priors_fitted_once);
    RUN_TEST(test_similar_priors_reuse_fits);
    RUN_TEST(test_warm_start_same_leading_hypothesis);
    RUN_TEST(test_split_class_seeded_from_another_parent);
    RUN_TEST(test_one_mode_is_one_track);
    RUN_TEST(test_second_track_of_a_neuron_merges_into_the_older);
    RUN_TEST(test_new_track_within_a_missed_tracks_spread_is_the_same_neuron);
    RUN_TEST(test_count_reference_follows_the_detections);
    RUN_TEST(test_empty_interval_and_bad_input);
    RUN_TEST(test_baselines_run_and_nn_loses_silent_neuron);
    RUN_TEST(test_int16_input_equals_double_input);
    RUN_TEST(test_tracker_names);
    return UNITY_END();
}

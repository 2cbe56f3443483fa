/* Unit: interval_chain (one interval from samples to the tracker's answer).
 * Results independent of the chunk sizes (windows, labels, tracks, scores),
 * a tracker followed over intervals with its SNR and isolation, a
 * spike-free interval (every track missed), stages out of order refused,
 * configurations the chain cannot take refused, failures counted and the
 * tracker left unchanged by them. */
#include <string.h>

#include "pipeline/interval_chain.h"
#include "signal/spike_synth.h"
#include "unity.h"

#define FS_HZ 20000u
#define N_SAMPLES 60000u /* 3 s */
#define GAIN_UV 0.5
#define TRUTH_MAX 512u

static int16_t g_x[N_SAMPLES];
static uint32_t g_truth[TRUTH_MAX];
static ic_workspace_t g_ws[2];
static mhtc_state_t g_mh[2];
static mhtc_state_t g_saved;

void setUp(void)
{
    memset(g_ws, 0, sizeof g_ws);
}
void tearDown(void) {}

static void synth(double snr, double rate_hz, uint64_t seed)
{
    size_t n_truth = 0u;
    const synth_config_t syn = {FS_HZ, 20.0, 1, snr, rate_hz, 3.0, seed};
    TEST_ASSERT_EQUAL_INT(MD_OK, synth_trace(&syn, g_x, N_SAMPLES, g_truth, TRUTH_MAX, &n_truth));
}

static ic_config_t config(void)
{
    const ic_config_t c = {FS_HZ, GAIN_UV, N_SAMPLES, 5u};
    return c;
}

static void init_tracker(unsigned slot)
{
    mhtc_config_t mc;
    mhtc_config_default(&mc, MHTC_TRACKER_MHTC);
    TEST_ASSERT_EQUAL_INT(MD_OK, mhtc_init(&g_mh[slot], &mc));
}

/* One interval of g_x into workspace `slot`, pushed `chunk` samples at a time. */
static md_status_t run(unsigned slot, size_t chunk, ic_out_t *out)
{
    const ic_config_t c = config();
    md_status_t st = ic_begin(&g_ws[slot], &c);
    for (size_t i = 0u; st == MD_OK && i < N_SAMPLES; i += chunk) {
        st = ic_push(&g_ws[slot], &g_x[i], (N_SAMPLES - i < chunk) ? (N_SAMPLES - i) : chunk);
    }
    return (st == MD_OK) ? ic_run(&g_ws[slot], &g_mh[slot], 0.0, out) : st;
}

/* 30 samples (one CAN FD frame) or the whole interval at once: the same
 * windows, features, labels, tracks and scores, interval after interval. */
static void test_chunk_size_does_not_matter(void)
{
    init_tracker(0u);
    init_tracker(1u);
    for (uint64_t k = 0u; k < 3u; ++k) {
        synth(8.0, 40.0, 11u + k);
        ic_out_t a, b;
        TEST_ASSERT_EQUAL_INT(MD_OK, run(0u, 30u, &a));
        TEST_ASSERT_EQUAL_INT(MD_OK, run(1u, N_SAMPLES, &b));
        const ic_workspace_t *x = &g_ws[0], *y = &g_ws[1];
        TEST_ASSERT_EQUAL_size_t(x->win.n, y->win.n);
        TEST_ASSERT_GREATER_THAN(50, (int)x->win.n);
        TEST_ASSERT_EQUAL_MEMORY(x->win.t, y->win.t, x->win.n * sizeof x->win.t[0]);
        TEST_ASSERT_EQUAL_MEMORY(x->y, y->y, x->n_spikes * IC_D * sizeof x->y[0]);
        TEST_ASSERT_EQUAL_MEMORY(x->res.labels, y->res.labels, x->n_spikes);
        TEST_ASSERT_EQUAL_MEMORY(x->res.cluster_track, y->res.cluster_track, sizeof x->res.cluster_track);
        TEST_ASSERT_EQUAL_MEMORY(x->track_snr, y->track_snr, sizeof x->track_snr);
        TEST_ASSERT_EQUAL_MEMORY(&a, &b, sizeof a);
        TEST_ASSERT_EQUAL_UINT32(N_SAMPLES, x->n_pushed);
    }
}

/* One neuron over four intervals: one track, kept, dominant, with the SNR of
 * the synthesised waveform and an isolation distance; nothing counted. */
static void test_tracks_one_neuron(void)
{
    init_tracker(0u);
    uint32_t id = 0u;
    for (uint64_t k = 0u; k < 4u; ++k) {
        synth(10.0, 30.0, 21u + k);
        ic_out_t o;
        TEST_ASSERT_EQUAL_INT(MD_OK, run(0u, 30u, &o));
        TEST_ASSERT_EQUAL_UINT32(o.n_windows, o.n_spikes);
        if (k == 0u) {
            continue; /* here the first leading hypothesis takes the cluster for a false one (λφ > λν) */
        }
        TEST_ASSERT_TRUE(o.has_dominant);
        TEST_ASSERT_DOUBLE_WITHIN(3.0, 10.0, o.snr);
        TEST_ASSERT_GREATER_THAN(0, (int)(o.iqm * 100.0));
        TEST_ASSERT_GREATER_THAN(0, (int)(o.amp * 100.0));
        TEST_ASSERT_DOUBLE_WITHIN(0.2 * 20.0 * GAIN_UV, 20.0 * GAIN_UV, g_ws[0].noise_rms_uv);
        id = (k == 1u) ? o.dominant : id;
        TEST_ASSERT_EQUAL_UINT32(id, o.dominant);
        qm_isolation_t iso;
        TEST_ASSERT_EQUAL_INT(MD_OK, ic_isolation(&g_ws[0], o.dominant_cluster, &iso));
        TEST_ASSERT_EQUAL_DOUBLE(o.iqm, iso.id);
    }
    const ic_stats_t *s = &g_ws[0].stats;
    TEST_ASSERT_EQUAL_UINT32(4u, s->intervals);
    TEST_ASSERT_EQUAL_UINT32(0u, s->begin_errors + s->push_errors + s->end_errors + s->feature_errors +
                                     s->track_errors + s->snr_undefined + s->iso_undefined);
}

/* Noise only: no spikes for the tracker (the basis comes from the noise),
 * the step succeeds, every track is missed, no dominant. */
static void test_spike_free_interval(void)
{
    init_tracker(0u);
    ic_out_t o;
    for (uint64_t k = 0u; k < 2u; ++k) {
        synth(10.0, 30.0, 31u + k);
        TEST_ASSERT_EQUAL_INT(MD_OK, run(0u, 30u, &o));
    }
    TEST_ASSERT_TRUE(o.has_dominant);
    synth(0.0, 0.0, 33u);
    TEST_ASSERT_EQUAL_INT(MD_OK, run(0u, 30u, &o));
    TEST_ASSERT_EQUAL_UINT32(0u, o.n_spikes);
    TEST_ASSERT_FALSE(o.has_dominant);
    TEST_ASSERT_EQUAL_DOUBLE(0.0, o.snr);
    for (size_t j = 0u; j < g_ws[0].res.n_tracks; ++j) {
        TEST_ASSERT_EQUAL_UINT8(0u, g_ws[0].res.track[j].cluster);
        TEST_ASSERT_EQUAL_DOUBLE(0.0, g_ws[0].track_snr[j]);
    }
}

/* A stage out of order is MD_E_STATE and counted; nothing ran. */
static void test_stages_in_order(void)
{
    init_tracker(0u);
    ic_workspace_t *ws = &g_ws[0];
    ic_out_t o;
    qm_isolation_t iso;
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, ic_push(ws, g_x, 30u));
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, ic_end(ws));
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, ic_features(ws));
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, ic_track(ws, &g_mh[0], 0.0));
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, ic_score(ws, &o));
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, ic_isolation(ws, 1u, &iso));
    synth(10.0, 30.0, 41u);
    const ic_config_t c = config();
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_begin(ws, &c));
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_push(ws, g_x, N_SAMPLES));
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, ic_track(ws, &g_mh[0], 0.0)); /* features first */
    TEST_ASSERT_EQUAL_UINT32(0u, g_mh[0].stats.steps);
    TEST_ASSERT_EQUAL_UINT32(1u, ws->stats.push_errors);
    TEST_ASSERT_EQUAL_UINT32(1u, ws->stats.end_errors);
    TEST_ASSERT_EQUAL_UINT32(1u, ws->stats.feature_errors);
    TEST_ASSERT_EQUAL_UINT32(2u, ws->stats.track_errors);
    /* after a failure a new interval starts cleanly */
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_begin(ws, &c));
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_push(ws, g_x, N_SAMPLES));
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_run(ws, &g_mh[0], 0.0, &o));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ic_isolation(ws, 0u, &iso));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ic_isolation(ws, (uint8_t)(ws->res.g + 1u), &iso));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ic_begin(NULL, &c));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ic_track(ws, NULL, 0.0));
}

/* Stages 3-5 run again on the same interval give the same result (what a
 * benchmark of one stage relies on); the tracker is restored by the caller. */
static void test_stages_repeat(void)
{
    init_tracker(0u);
    synth(10.0, 30.0, 61u);
    ic_out_t a, b;
    TEST_ASSERT_EQUAL_INT(MD_OK, run(0u, 30u, &a));
    synth(10.0, 30.0, 62u);
    const ic_config_t c = config();
    ic_workspace_t *ws = &g_ws[0];
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_begin(ws, &c));
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_push(ws, g_x, N_SAMPLES));
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_end(ws));
    g_saved = g_mh[0];
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_features(ws));
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_track(ws, &g_mh[0], 0.0));
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_score(ws, &a));
    g_ws[1] = *ws;
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_score(ws, &b));
    TEST_ASSERT_EQUAL_MEMORY(&a, &b, sizeof a);
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_features(ws));
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, ic_score(ws, &b)); /* features again: the tracker's step is needed again */
    g_mh[0] = g_saved;
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_track(ws, &g_mh[0], 0.0));
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_score(ws, &b));
    TEST_ASSERT_EQUAL_MEMORY(&a, &b, sizeof a);
    TEST_ASSERT_EQUAL_MEMORY(g_ws[1].y, ws->y, sizeof ws->y);
    TEST_ASSERT_EQUAL_MEMORY(g_ws[1].res.labels, ws->res.labels, sizeof ws->res.labels);
    TEST_ASSERT_EQUAL_MEMORY(g_ws[1].track_snr, ws->track_snr, sizeof ws->track_snr);
}

/* What the chain cannot take is refused at ic_begin and counted. */
static void test_configurations_refused(void)
{
    ic_workspace_t *ws = &g_ws[0];
    ic_config_t bad[8];
    for (size_t i = 0u; i < 8u; ++i) {
        bad[i] = config();
    }
    bad[0].sample_rate_hz = 0u;
    bad[1].gain_uv = 0.0;
    bad[2].num_samples = 0u;
    bad[3].guard_top_k = 0u;
    bad[4].guard_top_k = 17u;
    bad[5].sample_rate_hz = 32769u; /* the 250 ms warm-up exceeds SD_WARMUP_MAX samples */
    bad[6].sample_rate_hz = 7499u;  /* the narrowest wavelet scale's box is under 2 samples */
    bad[7].sample_rate_hz = 500u;   /* below the detector's range */
    for (size_t i = 0u; i < 8u; ++i) {
        TEST_ASSERT_EQUAL_INT_MESSAGE(MD_E_ARG, ic_begin(ws, &bad[i]), "configuration accepted");
    }
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ic_begin(ws, NULL));
    TEST_ASSERT_EQUAL_UINT32(9u, ws->stats.begin_errors);
    TEST_ASSERT_EQUAL_UINT32(0u, ws->stats.intervals);
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, ic_push(ws, g_x, 1u));
    const ic_config_t edge[2] = {{7500u, GAIN_UV, N_SAMPLES, 1u}, {32768u, GAIN_UV, N_SAMPLES, 16u}};
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_begin(ws, &edge[0]));
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_begin(ws, &edge[1]));
}

/* A flat interval (detection fails) and an interval at another sample rate
 * (the tracker refuses its window length): the error is returned and
 * counted, and the tracker is as before but for its update_errors counter. */
static void test_failures_leave_the_tracker(void)
{
    init_tracker(0u);
    synth(10.0, 30.0, 51u);
    ic_out_t o;
    TEST_ASSERT_EQUAL_INT(MD_OK, run(0u, 30u, &o));
    g_saved = g_mh[0];
    ic_workspace_t *ws = &g_ws[0];
    memset(g_x, 0, sizeof g_x);
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, run(0u, 30u, &o));
    TEST_ASSERT_EQUAL_UINT32(1u, ws->stats.push_errors);
    TEST_ASSERT_EQUAL_MEMORY(&g_saved, &g_mh[0], sizeof g_saved);
    const synth_config_t syn = {30000u, 20.0, 1, 10.0, 30.0, 3.0, 52u};
    size_t n_truth = 0u;
    TEST_ASSERT_EQUAL_INT(MD_OK, synth_trace(&syn, g_x, N_SAMPLES, g_truth, TRUTH_MAX, &n_truth));
    const ic_config_t c = {30000u, GAIN_UV, N_SAMPLES, 5u}; /* windows of 35 samples, not 23 */
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_begin(ws, &c));
    TEST_ASSERT_EQUAL_INT(MD_OK, ic_push(ws, g_x, N_SAMPLES));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, ic_run(ws, &g_mh[0], 0.0, &o));
    TEST_ASSERT_EQUAL_UINT32(1u, ws->stats.track_errors);
    TEST_ASSERT_EQUAL_UINT32(g_saved.stats.update_errors + 1u, g_mh[0].stats.update_errors);
    g_saved.stats.update_errors++;
    TEST_ASSERT_EQUAL_MEMORY(&g_saved, &g_mh[0], sizeof g_saved);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_chunk_size_does_not_matter);
    RUN_TEST(test_tracks_one_neuron);
    RUN_TEST(test_spike_free_interval);
    RUN_TEST(test_stages_in_order);
    RUN_TEST(test_stages_repeat);
    RUN_TEST(test_configurations_refused);
    RUN_TEST(test_failures_leave_the_tracker);
    return UNITY_END();
}

/* Unit: spike_pipeline (streaming detector + extractor) — the streaming
 * specifics: results independent of the chunk sizes, spikes inside the
 * warm-up and across chunk boundaries, edge windows counted, noise snippets
 * clear of every detection, overflow counted, and agreement with the
 * offline convenience path (sd_detector_t + sx_extract_*). */
#include <string.h>

#include "features/pca.h"
#include "metrics/quality.h"
#include "signal/spike_detect_offline.h"
#include "signal/spike_pipeline.h"
#include "signal/spike_synth.h"
#include "unity.h"

#define FS_HZ 20000u
#define N_MAX 24000u
#define TRUTH_MAX 256u
#define TOL_SAMPLES 10u /* 0.5 ms */

static int16_t g_x[N_MAX];
static int16_t g_buf[N_MAX];
static uint32_t g_truth[TRUTH_MAX];
static sp_channel_t g_ch;
static sx_windows_t g_win[2];
static sx_snippets_t g_noise[2];
static sd_events_t g_ev[2];
static sd_detector_t g_det;
static sx_spikes_t g_sp;
static sx_noise_t g_nz;
static pca_work_t g_work;
static pca_basis_t g_basis[2];

void setUp(void) {}
void tearDown(void) {}

static md_status_t run(const sd_config_t *d, const sx_config_t *x, size_t n, size_t chunk, unsigned slot)
{
    md_status_t r = sp_init(&g_ch, d, x, &g_win[slot], &g_noise[slot]);
    for (size_t i = 0u; (r == MD_OK) && (i < n); i += chunk) {
        r = sp_push(&g_ch, &g_x[i], (n - i < chunk) ? (n - i) : chunk);
    }
    if (r == MD_OK) {
        r = sp_finish(&g_ch);
    }
    g_ev[slot] = *sp_events(&g_ch);
    return r;
}

static void synth(double snr, double rate_hz, int band, uint64_t seed, size_t n, size_t *n_truth)
{
    const synth_config_t syn = {FS_HZ, 20.0, band, snr, rate_hz, 3.0, seed};
    TEST_ASSERT_EQUAL_INT(MD_OK, synth_trace(&syn, g_x, n, g_truth, TRUTH_MAX, n_truth));
}

static void configs(sd_method_t m, sd_config_t *d, sx_config_t *x)
{
    sd_config_default(d, m, FS_HZ);
    sx_config_default(x, FS_HZ);
    x->spacing = 60u;
    x->realign = 2u;
}

static void assert_same(unsigned a, unsigned b)
{
    TEST_ASSERT_EQUAL_size_t(g_ev[a].n, g_ev[b].n);
    TEST_ASSERT_EQUAL_MEMORY(g_ev[a].t, g_ev[b].t, g_ev[a].n * sizeof g_ev[a].t[0]);
    TEST_ASSERT_EQUAL_UINT32(g_ev[a].n_merged, g_ev[b].n_merged);
    TEST_ASSERT_EQUAL_size_t(g_win[a].n, g_win[b].n);
    TEST_ASSERT_EQUAL_MEMORY(g_win[a].t, g_win[b].t, g_win[a].n * sizeof g_win[a].t[0]);
    TEST_ASSERT_EQUAL_MEMORY(g_win[a].wave, g_win[b].wave, g_win[a].n * sizeof g_win[a].wave[0]);
    TEST_ASSERT_EQUAL_UINT32(g_win[a].n_edge_skipped, g_win[b].n_edge_skipped);
    TEST_ASSERT_EQUAL_size_t(g_noise[a].n, g_noise[b].n);
    TEST_ASSERT_EQUAL_MEMORY(g_noise[a].start, g_noise[b].start, g_noise[a].n * sizeof g_noise[a].start[0]);
    TEST_ASSERT_EQUAL_MEMORY(g_noise[a].wave, g_noise[b].wave, g_noise[a].n * sizeof g_noise[a].wave[0]);
    TEST_ASSERT_EQUAL_UINT32(g_noise[a].n_confirmed, g_noise[b].n_confirmed);
    TEST_ASSERT_EQUAL_UINT32(g_noise[a].n_rejected, g_noise[b].n_rejected);
}

/* 1, 30 (one CAN FD frame) and 4096 samples per chunk give bit-identical
 * events, windows, snippets and counters, for both detectors. */
static void test_chunk_size_does_not_matter(void)
{
    size_t n_truth = 0u;
    synth(6.0, 60.0, 1, 5u, N_MAX, &n_truth);
    const size_t chunks[3] = {1u, 30u, 4096u};
    for (int m = 0; m < 2; ++m) {
        sd_config_t d;
        sx_config_t x;
        configs((m == 0) ? SD_METHOD_WAVELET : SD_METHOD_THRESHOLD, &d, &x);
        TEST_ASSERT_EQUAL_INT(MD_OK, run(&d, &x, N_MAX, chunks[0], 0u));
        TEST_ASSERT_GREATER_THAN(20, (int)g_ev[0].n);
        TEST_ASSERT_GREATER_THAN(20, (int)g_noise[0].n);
        for (size_t c = 1u; c < 3u; ++c) {
            TEST_ASSERT_EQUAL_INT(MD_OK, run(&d, &x, N_MAX, chunks[c], 1u));
            assert_same(0u, 1u);
        }
    }
}

/* Spikes inside the warm-up (the first 250 ms = 5000 samples) are found:
 * the warm-up is replayed through the online detector. */
static void test_spikes_in_warmup_are_found(void)
{
    size_t n_truth = 0u;
    synth(8.0, 60.0, 0, 9u, N_MAX, &n_truth);
    sd_config_t d;
    sx_config_t x;
    configs(SD_METHOD_WAVELET, &d, &x);
    TEST_ASSERT_EQUAL_INT(MD_OK, run(&d, &x, N_MAX, 30u, 0u));
    TEST_ASSERT_EQUAL_UINT32(5000u, g_ev[0].warmup_samples);
    size_t in_warm = 0u, found = 0u;
    for (size_t k = 0u; k < n_truth; ++k) {
        if (g_truth[k] >= 5000u) {
            break;
        }
        in_warm++;
        for (size_t e = 0u; e < g_ev[0].n; ++e) {
            const uint32_t t = g_ev[0].t[e];
            found += ((t + TOL_SAMPLES >= g_truth[k]) && (t <= g_truth[k] + TOL_SAMPLES)) ? 1u : 0u;
        }
    }
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(10u, (unsigned)in_warm);
    TEST_ASSERT_EQUAL_size_t(in_warm, found);
}

/* Hand-placed troughs straddling the 30-sample frames and the 32-sample
 * steps, at the very start and end of the interval: every one is detected
 * at its sample, interior windows are cut, the two edge ones are counted. */
static void test_boundaries_and_edges(void)
{
    const size_t n = 9000u;
    for (size_t i = 0u; i < n; ++i) {
        g_x[i] = (int16_t)(((i * 7u) % 3u == 0u) ? -2 : 2);
    }
    const uint32_t at[6] = {3u, 59u, 60u + 2000u, 4095u + 2u * 32u, 6000u + 31u, 8996u};
    for (size_t k = 0u; k < 6u; ++k) {
        g_x[at[k] - 1u] = -40;
        g_x[at[k]] = -90; /* the trough spans the boundary */
        g_x[at[k] + 1u] = -40;
    }
    sd_config_t d;
    sx_config_t x;
    configs(SD_METHOD_THRESHOLD, &d, &x);
    x.realign = 0u;
    TEST_ASSERT_EQUAL_INT(MD_OK, run(&d, &x, n, 30u, 0u));
    TEST_ASSERT_EQUAL_size_t(6u, g_ev[0].n);
    TEST_ASSERT_EQUAL_MEMORY(at, g_ev[0].t, sizeof at);
    TEST_ASSERT_EQUAL_size_t(4u, g_win[0].n);
    TEST_ASSERT_EQUAL_UINT32(2u, g_win[0].n_edge_skipped); /* t = 3 < pre_peak; t = 8996: window leaves the end */
    const int32_t off = g_win[0].offset;
    for (size_t i = 0u; i < g_win[0].n; ++i) {
        TEST_ASSERT_EQUAL_INT(-90 - off, g_win[0].wave[i][x.pre_peak]);
        TEST_ASSERT_EQUAL_INT(-40 - off, g_win[0].wave[i][x.pre_peak + 1u]);
    }
}

/* Every snippet keeps guard samples clear of every detection, snippets never
 * overlap, and the streaming snippets equal the offline picker's. */
static void test_snippets_clear_of_detections(void)
{
    size_t n_truth = 0u;
    synth(5.0, 120.0, 0, 13u, N_MAX, &n_truth);
    sd_config_t d;
    sx_config_t x;
    configs(SD_METHOD_WAVELET, &d, &x);
    x.guard = 40u;
    TEST_ASSERT_EQUAL_INT(MD_OK, run(&d, &x, N_MAX, 30u, 0u));
    const sx_snippets_t *z = &g_noise[0];
    TEST_ASSERT_GREATER_THAN(50, (int)z->n);
    TEST_ASSERT_GREATER_THAN(0, (int)z->n_rejected);
    TEST_ASSERT_EQUAL_UINT32(0u, z->n_expired);
    TEST_ASSERT_EQUAL_UINT32(0u, z->n_queue_full);
    for (size_t i = 0u; i < z->n; ++i) {
        for (size_t k = 0u; k < g_ev[0].n; ++k) {
            const long s = (long)z->start[i];
            const long t = (long)g_ev[0].t[k];
            TEST_ASSERT_TRUE((t < s - 40) || (t >= s + (long)x.d_w + 40));
        }
        for (size_t j = 0u; j < i; ++j) {
            TEST_ASSERT_TRUE((z->start[i] >= z->start[j] + x.d_w) || (z->start[j] >= z->start[i] + x.d_w));
        }
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, sx_extract_noise(g_x, N_MAX, &g_ev[0], &x, &g_nz));
    TEST_ASSERT_EQUAL_size_t(z->n, g_nz.n);
    TEST_ASSERT_EQUAL_MEMORY(z->start, g_nz.start, z->n * sizeof z->start[0]);
    double row[MD_WAVE_LEN_MAX];
    TEST_ASSERT_EQUAL_INT(MD_OK, sx_snippet_to_double(z, z->n - 1u, row));
    TEST_ASSERT_EQUAL_MEMORY(g_nz.wave[z->n - 1u], row, x.d_w * sizeof row[0]);
}

/* The offline convenience path is the same detector: identical events and
 * windows (as doubles) to the streaming pipeline. */
static void test_offline_wrapper_agrees(void)
{
    size_t n_truth = 0u;
    synth(6.0, 60.0, 0, 17u, N_MAX, &n_truth);
    sd_config_t d;
    sx_config_t x;
    configs(SD_METHOD_WAVELET, &d, &x);
    x.gain = 0.25;
    TEST_ASSERT_EQUAL_INT(MD_OK, run(&d, &x, N_MAX, 30u, 0u));
    TEST_ASSERT_EQUAL_INT(MD_OK, sd_init(&g_det, &d, g_buf, N_MAX));
    TEST_ASSERT_EQUAL_INT(MD_OK, sd_push(&g_det, g_x, N_MAX));
    TEST_ASSERT_EQUAL_INT(MD_OK, sd_finish(&g_det, &g_ev[1]));
    TEST_ASSERT_EQUAL_size_t(g_ev[0].n, g_ev[1].n);
    TEST_ASSERT_EQUAL_MEMORY(g_ev[0].t, g_ev[1].t, g_ev[0].n * sizeof g_ev[0].t[0]);
    size_t n = 0u;
    const int16_t *buf = sd_samples(&g_det, &n);
    TEST_ASSERT_EQUAL_INT(MD_OK, sx_extract_spikes(buf, n, &g_ev[1], &x, &g_sp));
    TEST_ASSERT_EQUAL_size_t(g_win[0].n, g_sp.n);
    double row[MD_WAVE_LEN_MAX];
    for (size_t i = 0u; i < g_sp.n; ++i) {
        TEST_ASSERT_EQUAL_UINT32(g_win[0].t[i], g_sp.t[i]);
        TEST_ASSERT_EQUAL_INT(MD_OK, sx_window_to_double(&g_win[0], i, row));
        TEST_ASSERT_EQUAL_MEMORY(g_sp.wave[i], row, x.d_w * sizeof row[0]);
    }
}

/* A margin keeps that many raw samples on each side of every window: the
 * window without sub-sample alignment sits inside it unchanged, and the
 * events and snippets are the same. Margins the rows cannot hold, a margin
 * with the extractor's own resampling, or one on the offline path are refused. */
static void test_margin_keeps_raw_samples_around_each_window(void)
{
    size_t n_truth = 0u;
    synth(6.0, 60.0, 0, 17u, N_MAX, &n_truth);
    sd_config_t d;
    sx_config_t x;
    configs(SD_METHOD_WAVELET, &d, &x);
    x.subsample = false;
    TEST_ASSERT_EQUAL_INT(MD_OK, run(&d, &x, N_MAX, 30u, 0u));
    x.margin = 2u;
    TEST_ASSERT_EQUAL_INT(MD_OK, run(&d, &x, N_MAX, 30u, 1u));
    TEST_ASSERT_EQUAL_size_t(2u, g_win[1].margin);
    TEST_ASSERT_EQUAL_size_t(x.pre_peak, g_win[1].pre_peak);
    TEST_ASSERT_EQUAL_size_t(g_ev[0].n, g_ev[1].n);
    TEST_ASSERT_TRUE(g_win[0].n > 10u);
    TEST_ASSERT_EQUAL_size_t(g_win[0].n, g_win[1].n); /* no event this close to an edge here */
    for (size_t i = 0u; i < g_win[0].n; ++i) {
        TEST_ASSERT_EQUAL_UINT32(g_win[0].t[i], g_win[1].t[i]);
        TEST_ASSERT_EQUAL_INT16_ARRAY(g_win[0].wave[i], &g_win[1].wave[i][2], x.d_w);
    }
    TEST_ASSERT_EQUAL_size_t(g_noise[0].n, g_noise[1].n);
    TEST_ASSERT_EQUAL_MEMORY(g_noise[0].wave, g_noise[1].wave, g_noise[0].n * sizeof g_noise[0].wave[0]);
    x.margin = SX_MARGIN_MAX + 1u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sp_init(&g_ch, &d, &x, &g_win[0], &g_noise[0]));
    x.margin = 2u;
    x.subsample = true;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sp_init(&g_ch, &d, &x, &g_win[0], &g_noise[0]));
    x.subsample = false;
    x.d_w = MD_WAVE_LEN_MAX - 3u; /* d_w + 2 margin above the row */
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sp_init(&g_ch, &d, &x, &g_win[0], &g_noise[0]));
    configs(SD_METHOD_WAVELET, &d, &x);
    x.subsample = false;
    x.margin = 2u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sx_extract_spikes(g_x, 1000u, &g_ev[0], &x, &g_sp));
}

/* More events than MD_MAX_SPIKES: the rest are counted, flagged on the
 * windows and snippets, and snippets stay before the last stored event. */
static void test_overflow_is_counted(void)
{
    const size_t n = MD_MAX_SPIKES * 40u + 2000u;
    TEST_ASSERT_TRUE(n <= N_MAX);
    for (size_t i = 0u; i < n; ++i) {
        g_x[i] = (int16_t)((i % 2u) ? 3 : -3);
    }
    for (size_t k = 0u; k < MD_MAX_SPIKES + 5u; ++k) {
        g_x[100u + k * 40u] = -100; /* 2 ms apart: all distinct events */
    }
    sd_config_t d;
    sx_config_t x;
    configs(SD_METHOD_THRESHOLD, &d, &x);
    x.guard = 5u;
    TEST_ASSERT_EQUAL_INT(MD_OK, run(&d, &x, n, 30u, 0u));
    TEST_ASSERT_EQUAL_size_t(MD_MAX_SPIKES, g_ev[0].n);
    TEST_ASSERT_EQUAL_UINT32(5u, g_ev[0].n_overflow);
    TEST_ASSERT_EQUAL_UINT32(SX_FLAG_OVERFLOW, g_win[0].flags & SX_FLAG_OVERFLOW);
    TEST_ASSERT_EQUAL_UINT32(5u, g_win[0].n_overflow);
    TEST_ASSERT_EQUAL_UINT32(SX_FLAG_OVERFLOW, g_noise[0].flags & SX_FLAG_OVERFLOW);
    const uint32_t last = g_ev[0].t[MD_MAX_SPIKES - 1u];
    for (size_t i = 0u; i < g_noise[0].n; ++i) {
        TEST_ASSERT_TRUE(g_noise[0].start[i] + x.d_w <= last);
    }
}

/* A flat warm-up is reported, a short interval is flagged, misuse is refused. */
static void test_states_and_degenerate_input(void)
{
    sd_config_t d;
    sx_config_t x;
    configs(SD_METHOD_WAVELET, &d, &x);
    memset(g_x, 0, sizeof g_x);
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, run(&d, &x, 6000u, 30u, 0u));
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, sp_push(&g_ch, g_x, 64u)); /* still flat: reported at the next step */
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, sp_finish(&g_ch));
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, sp_push(&g_ch, g_x, 1u));
    TEST_ASSERT_EQUAL_INT(MD_OK, sp_restart(&g_ch));
    size_t n_truth = 0u;
    synth(8.0, 60.0, 0, 3u, 3000u, &n_truth); /* shorter than the warm-up */
    for (size_t i = 0u; i < 3000u; i += 30u) {
        TEST_ASSERT_EQUAL_INT(MD_OK, sp_push(&g_ch, &g_x[i], 30u));
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, sp_finish(&g_ch));
    TEST_ASSERT_EQUAL_UINT32(SD_FLAG_SHORT, sp_events(&g_ch)->flags & SD_FLAG_SHORT);
    TEST_ASSERT_GREATER_THAN(0, (int)sp_events(&g_ch)->n);
    d.warmup_ms = 1000.0; /* 20000 samples > SD_WARMUP_MAX */
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sp_init(&g_ch, &d, &x, &g_win[0], &g_noise[0]));
    configs(SD_METHOD_WAVELET, &d, &x);
    x.guard = 1900u; /* the guard zone would not fit the delay line */
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sp_init(&g_ch, &d, &x, &g_win[0], &g_noise[0]));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sp_push(NULL, g_x, 1u));
}

/* PCA and metrics straight from the compact int16 outputs equal the double
 * entry points on the converted rows (no 200 kB double copy needed). */
static void test_compact_outputs_feed_pca_and_metrics(void)
{
    size_t n_truth = 0u;
    synth(7.0, 60.0, 0, 21u, N_MAX, &n_truth);
    sd_config_t d;
    sx_config_t x;
    configs(SD_METHOD_WAVELET, &d, &x);
    x.gain = 0.195; /* e.g. microvolts per count */
    TEST_ASSERT_EQUAL_INT(MD_OK, run(&d, &x, N_MAX, 30u, 0u));
    const sx_windows_t *w = &g_win[0];
    const sx_snippets_t *z = &g_noise[0];
    for (size_t i = 0u; i < w->n; ++i) {
        TEST_ASSERT_EQUAL_INT(MD_OK, sx_window_to_double(w, i, g_sp.wave[i]));
    }
    for (size_t i = 0u; i < z->n; ++i) {
        TEST_ASSERT_EQUAL_INT(MD_OK, sx_snippet_to_double(z, i, g_nz.wave[i]));
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_fit(&g_sp.wave[0][0], w->n, MD_WAVE_LEN_MAX, w->d_w, 2u, &g_work, &g_basis[0]));
    TEST_ASSERT_EQUAL_INT(
        MD_OK, pca_fit_i16(&w->wave[0][0], w->n, MD_WAVE_LEN_MAX, w->d_w, w->gain, 2u, &g_work, &g_basis[1]));
    for (size_t j = 0u; j < 2u * w->d_w; ++j) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, g_basis[0].b[j], g_basis[1].b[j]);
    }
    double r0 = 0.0, r1 = 0.0, s0 = 0.0, s1 = 0.0, xi0[4], xi1[4];
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_noise_rms(&g_nz.wave[0][0], z->n, MD_WAVE_LEN_MAX, z->d_w, &r0));
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_noise_rms_i16(&z->wave[0][0], z->n, MD_WAVE_LEN_MAX, z->d_w, z->gain, &r1));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9 * r0, r0, r1);
    TEST_ASSERT_DOUBLE_WITHIN(0.1 * 20.0 * x.gain, 20.0 * x.gain, r1); /* the synthetic noise RMS, in gain units */
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_snr(&g_sp.wave[0][0], w->n, MD_WAVE_LEN_MAX, w->d_w, NULL, 0u, r0, &s0, NULL));
    TEST_ASSERT_EQUAL_INT(MD_OK,
                          qm_snr_i16(&w->wave[0][0], w->n, MD_WAVE_LEN_MAX, w->d_w, w->gain, NULL, 0u, r1, &s1, NULL));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9 * s0, s0, s1);
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_noise_feature_cov(&g_basis[0], &g_nz.wave[0][0], z->n, MD_WAVE_LEN_MAX, xi0));
    TEST_ASSERT_EQUAL_INT(MD_OK,
                          qm_noise_feature_cov_i16(&g_basis[1], &z->wave[0][0], z->n, MD_WAVE_LEN_MAX, z->gain, xi1));
    for (size_t j = 0u; j < 4u; ++j) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-9 * xi0[0], xi0[j], xi1[j]);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_chunk_size_does_not_matter);
    RUN_TEST(test_spikes_in_warmup_are_found);
    RUN_TEST(test_boundaries_and_edges);
    RUN_TEST(test_snippets_clear_of_detections);
    RUN_TEST(test_offline_wrapper_agrees);
    RUN_TEST(test_margin_keeps_raw_samples_around_each_window);
    RUN_TEST(test_overflow_is_counted);
    RUN_TEST(test_states_and_degenerate_input);
    RUN_TEST(test_compact_outputs_feed_pca_and_metrics);
    return UNITY_END();
}

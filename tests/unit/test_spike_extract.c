/* Unit: spike_extract — windows aligned on known minima, edges, noise
 * snippets that never touch a detection, and the whole chain
 * detect -> extract -> PCA -> SNR on a synthetic interval of known SNR. */
#include <math.h>
#include <string.h>

#include "features/pca.h"
#include "metrics/quality.h"
#include "signal/spike_detect_offline.h"
#include "signal/spike_extract.h"
#include "signal/spike_synth.h"
#include "unity.h"

#define FS_HZ 20000u
#define N_SAMPLES 40000u

static int16_t g_x[N_SAMPLES];
static int16_t g_buf[N_SAMPLES];
static uint32_t g_truth[256];
static sd_events_t g_ev;
static sx_spikes_t g_sp;
static sx_noise_t g_noise;
static sd_detector_t g_det;
static pca_work_t g_work;
static pca_basis_t g_basis;

void setUp(void) {}
void tearDown(void) {}

static void test_windows_are_aligned_and_edges_counted(void)
{
    for (size_t i = 0u; i < 1000u; ++i) {
        g_x[i] = 10;
    }
    g_x[3] = -50;   /* too close to the start for pre_peak = 8 */
    g_x[400] = -90; /* event given at 398; realign moves it to 400 */
    g_x[401] = -40;
    g_x[995] = -70; /* too close to the end */
    memset(&g_ev, 0, sizeof g_ev);
    g_ev.offset = 10;
    g_ev.n = 3u;
    g_ev.t[0] = 3u;
    g_ev.t[1] = 398u;
    g_ev.t[2] = 995u;
    sx_config_t cfg;
    sx_config_default(&cfg, FS_HZ);
    TEST_ASSERT_EQUAL_size_t(23u, cfg.d_w);
    TEST_ASSERT_EQUAL_size_t(8u, cfg.pre_peak);
    cfg.realign = 3u;
    cfg.gain = 0.5;
    cfg.subsample = false; /* the thesis' alignment on the sample of the minimum */
    TEST_ASSERT_EQUAL_INT(MD_OK, sx_extract_spikes(g_x, 1000u, &g_ev, &cfg, &g_sp));
    TEST_ASSERT_EQUAL_size_t(1u, g_sp.n);
    TEST_ASSERT_EQUAL_UINT32(2u, g_sp.n_edge_skipped);
    TEST_ASSERT_EQUAL_UINT32(400u, g_sp.t[0]);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.5 * (-90.0 - 10.0), g_sp.wave[0][8]); /* minimum at pre_peak */
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.5 * (-40.0 - 10.0), g_sp.wave[0][9]);
    TEST_ASSERT_DOUBLE_WITHIN(0.0, 0.0, g_sp.wave[0][0]);
    cfg.d_w = MD_WAVE_LEN_MAX + 1u;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, sx_extract_spikes(g_x, 1000u, &g_ev, &cfg, &g_sp));
}

static void test_noise_snippets_avoid_detections(void)
{
    /* 12000 samples, a detection every 100: with guard 20 and d_w 23, 37 % of
     * the start positions are free; candidates come every 32 samples. */
    for (size_t i = 0u; i < 12000u; ++i) {
        g_x[i] = (int16_t)((i % 5u) - 2u);
    }
    memset(&g_ev, 0, sizeof g_ev);
    for (size_t k = 0u; k < 120u; ++k) { /* a detection every 100 samples */
        g_ev.t[k] = (uint32_t)(50u + 100u * k);
    }
    g_ev.n = 120u;
    sx_config_t cfg;
    sx_config_default(&cfg, FS_HZ);
    cfg.guard = 20u;
    cfg.n_noise = 100u;
    cfg.spacing = SX_MIN_SPACING;
    TEST_ASSERT_EQUAL_INT(MD_OK, sx_extract_noise(g_x, 12000u, &g_ev, &cfg, &g_noise));
    TEST_ASSERT_EQUAL_size_t(100u, g_noise.n);
    TEST_ASSERT_TRUE(g_noise.n_rejected > 0u);
    for (size_t i = 0u; i < g_noise.n; ++i) {
        for (size_t k = 0u; k < g_ev.n; ++k) { /* window +- guard never reaches an event */
            const long s = (long)g_noise.start[i];
            const long t = (long)g_ev.t[k];
            TEST_ASSERT_TRUE((t < s - 20) || (t >= s + 23 + 20));
        }
        for (size_t j = 0u; j < i; ++j) { /* snippets never overlap each other */
            const long a = (long)g_noise.start[i];
            const long b = (long)g_noise.start[j];
            TEST_ASSERT_TRUE((a >= b + 23) || (b >= a + 23));
        }
    }
    /* same seed, same snippets */
    const uint32_t first = g_noise.start[0];
    TEST_ASSERT_EQUAL_INT(MD_OK, sx_extract_noise(g_x, 12000u, &g_ev, &cfg, &g_noise));
    TEST_ASSERT_EQUAL_UINT32(first, g_noise.start[0]);
    /* no room at all: every candidate rejected, reported */
    cfg.guard = 100u;
    TEST_ASSERT_EQUAL_INT(MD_E_DEGENERATE, sx_extract_noise(g_x, 12000u, &g_ev, &cfg, &g_noise));
    TEST_ASSERT_EQUAL_UINT32(SX_FLAG_NOISE_SHORT, g_noise.flags & SX_FLAG_NOISE_SHORT);
}

static void test_chain_measures_the_synthetic_snr(void)
{
    /* SNR 8 spikes in white noise of RMS 20. The metric's peak-to-peak of a
     * noisy window is biased upwards (the window's extremes pick up noise
     * extremes, ~+2 at this SNR), so the chain is compared with the metric on
     * windows cut at the true spike times: they must agree within 3 %. */
    const synth_config_t syn = {FS_HZ, 20.0, 0, 8.0, 30.0, 3.0, 99u};
    size_t n_truth = 0u;
    TEST_ASSERT_EQUAL_INT(MD_OK, synth_trace(&syn, g_x, N_SAMPLES, g_truth, 256u, &n_truth));
    sd_config_t dcfg;
    sd_config_default(&dcfg, SD_METHOD_WAVELET, FS_HZ);
    TEST_ASSERT_EQUAL_INT(MD_OK, sd_init(&g_det, &dcfg, g_buf, N_SAMPLES));
    TEST_ASSERT_EQUAL_INT(MD_OK, sd_push(&g_det, g_x, N_SAMPLES));
    TEST_ASSERT_EQUAL_INT(MD_OK, sd_finish(&g_det, &g_ev));
    sx_config_t cfg;
    sx_config_default(&cfg, FS_HZ);
    cfg.spacing = 80u; /* a 2 s interval: enough candidates for 128 snippets */
    size_t n = 0u;
    const int16_t *x = sd_samples(&g_det, &n);
    TEST_ASSERT_EQUAL_INT(MD_OK, sx_extract_spikes(x, n, &g_ev, &cfg, &g_sp));
    TEST_ASSERT_EQUAL_INT(MD_OK, sx_extract_noise(x, n, &g_ev, &cfg, &g_noise));
    TEST_ASSERT_GREATER_OR_EQUAL_UINT((unsigned)(n_truth - 2u), (unsigned)g_sp.n);
    double rms = 0.0, snr = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_noise_rms(&g_noise.wave[0][0], g_noise.n, MD_WAVE_LEN_MAX, cfg.d_w, &rms));
    TEST_ASSERT_DOUBLE_WITHIN(2.0, 20.0, rms);
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_snr(&g_sp.wave[0][0], g_sp.n, MD_WAVE_LEN_MAX, cfg.d_w, NULL, 0u, rms, &snr, NULL));
    static sd_events_t truth_ev;
    static sx_spikes_t truth_sp;
    memset(&truth_ev, 0, sizeof truth_ev);
    truth_ev.offset = g_ev.offset;
    truth_ev.n = n_truth;
    memcpy(truth_ev.t, g_truth, n_truth * sizeof g_truth[0]);
    TEST_ASSERT_EQUAL_INT(MD_OK, sx_extract_spikes(x, n, &truth_ev, &cfg, &truth_sp));
    double snr_truth = 0.0;
    TEST_ASSERT_EQUAL_INT(
        MD_OK, qm_snr(&truth_sp.wave[0][0], truth_sp.n, MD_WAVE_LEN_MAX, cfg.d_w, NULL, 0u, rms, &snr_truth, NULL));
    TEST_ASSERT_TRUE(snr_truth > 8.0);
    TEST_ASSERT_DOUBLE_WITHIN(0.03 * snr_truth, snr_truth, snr);
    TEST_ASSERT_EQUAL_INT(MD_OK, pca_fit(&g_sp.wave[0][0], g_sp.n, MD_WAVE_LEN_MAX, cfg.d_w, 2u, &g_work, &g_basis));
    double xi[4];
    TEST_ASSERT_EQUAL_INT(MD_OK, qm_noise_feature_cov(&g_basis, &g_noise.wave[0][0], g_noise.n, MD_WAVE_LEN_MAX, xi));
    /* projections of white noise on unit vectors have the noise variance */
    TEST_ASSERT_DOUBLE_WITHIN(0.25 * 400.0, 400.0, xi[0]);
    TEST_ASSERT_DOUBLE_WITHIN(0.25 * 400.0, 400.0, xi[3]);
}

/* A smooth spike (trough width ~3 samples at 30 kHz) whose true trough lies
 * `phase` samples after sample 500. */
static void phased_spike(double phase)
{
    for (size_t i = 0u; i < 1000u; ++i) {
        const double t = ((double)i - 500.0 - phase) / 3.0;
        const double v = -400.0 * exp(-0.5 * t * t) + 120.0 * exp(-0.5 * (t - 2.5) * (t - 2.5));
        g_x[i] = (int16_t)lround(v);
    }
}

/* Largest difference over the window between the spike cut at `phase` and at 0. */
static double window_spread(double phase, bool subsample)
{
    sx_config_t cfg;
    sx_config_default(&cfg, 30000u);
    cfg.subsample = subsample;
    memset(&g_ev, 0, sizeof g_ev);
    g_ev.n = 1u;
    double ref[MD_WAVE_LEN_MAX];
    phased_spike(0.0);
    g_ev.t[0] = 500u;
    TEST_ASSERT_EQUAL_INT(MD_OK, sx_extract_spikes(g_x, 1000u, &g_ev, &cfg, &g_sp));
    TEST_ASSERT_EQUAL_size_t(1u, g_sp.n);
    memcpy(ref, g_sp.wave[0], sizeof ref);
    phased_spike(phase);
    g_ev.t[0] = (phase > 0.5) ? 501u : 500u; /* the sample of the minimum */
    TEST_ASSERT_EQUAL_INT(MD_OK, sx_extract_spikes(g_x, 1000u, &g_ev, &cfg, &g_sp));
    TEST_ASSERT_EQUAL_size_t(1u, g_sp.n);
    double worst = 0.0;
    for (size_t j = 0u; j < cfg.d_w; ++j) {
        worst = fmax(worst, fabs(g_sp.wave[0][j] - ref[j]));
    }
    return worst;
}

/* The same spike cut anywhere between two samples gives the same window with
 * sub-sample alignment (within the cubic's error, 2 % of the 400-count
 * trough); without it they differ by a tenth of the trough (44 counts at 0.45). */
static void test_subsample_alignment_removes_the_sampling_phase(void)
{
    const double phases[] = {-0.45, -0.25, 0.2, 0.45, 0.7};
    for (size_t k = 0u; k < sizeof phases / sizeof phases[0]; ++k) {
        TEST_ASSERT_LESS_THAN_DOUBLE(8.0, window_spread(phases[k], true));
    }
    TEST_ASSERT_GREATER_THAN_DOUBLE(30.0, window_spread(0.45, false));
    /* t stays the sample of the minimum; edges keep room for the resampling */
    sx_config_t cfg;
    sx_config_default(&cfg, 30000u);
    memset(&g_ev, 0, sizeof g_ev);
    g_ev.n = 2u;
    g_ev.t[0] = (uint32_t)cfg.pre_peak + 1u; /* room for the window, not for the margin */
    g_ev.t[1] = 1000u - (uint32_t)(cfg.d_w - cfg.pre_peak) - 1u;
    TEST_ASSERT_EQUAL_INT(MD_OK, sx_extract_spikes(g_x, 1000u, &g_ev, &cfg, &g_sp));
    TEST_ASSERT_EQUAL_size_t(0u, g_sp.n);
    TEST_ASSERT_EQUAL_UINT32(2u, g_sp.n_edge_skipped);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_windows_are_aligned_and_edges_counted);
    RUN_TEST(test_noise_snippets_avoid_detections);
    RUN_TEST(test_chain_measures_the_synthetic_snr);
    RUN_TEST(test_subsample_alignment_removes_the_sampling_phase);
    return UNITY_END();
}

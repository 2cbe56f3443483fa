/* Host unit: neuron model — amplitude fall-off with distance, one SNR peak
 * per neuron along the track, shape change with relative position, firing
 * rate, refractory period, bursts, silent stretches, appearance. */
#include <math.h>
#include <stdlib.h>

#include "model/electrode.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static neuron_t nrn;
static sim_electrode_t el;

static void make(const neuron_params_t *p, uint64_t seed)
{
    neuron_model_params_t m;
    neuron_default_model_params(&m);
    TEST_ASSERT_EQUAL_INT(MD_OK, neuron_init(&nrn, p, &m, 0u, 30000.0, seed, 0u));
}

static void test_amplitude_falls_with_distance_and_reach_is_100_to_140_um(void)
{
    neuron_model_params_t m;
    neuron_default_model_params(&m);
    neuron_params_t p;
    neuron_default_params(&p);
    make(&p, 1u);
    signal_params_t sp;
    signal_default_params(&sp);
    const double bg = sim_background_rms_uv(&sp);
    double prev = 1e9;
    for (double d = 0.0; d <= 300.0; d += 1.0) {
        const double a = neuron_amplitude_uv(&m, &nrn, d);
        TEST_ASSERT_TRUE(a < prev);
        prev = a;
    }
    /* a default neuron is detectable (SNR >= 3) at 100 um, not beyond 140 um */
    TEST_ASSERT_TRUE(neuron_amplitude_uv(&m, &nrn, 100.0) / bg >= 3.0);
    TEST_ASSERT_TRUE(neuron_amplitude_uv(&m, &nrn, 140.0) / bg < 3.0);
}

/* Template ptp equals A(d); the shape differs above vs below the soma. */
static void test_shape_changes_with_position_but_ptp_follows_distance(void)
{
    neuron_model_params_t m;
    neuron_default_model_params(&m);
    neuron_params_t p;
    neuron_default_params(&p);
    make(&p, 2u);
    double above[SIM_WAVE_MAX], below[SIM_WAVE_MAX];
    neuron_template(&m, &nrn, 20.0, -40.0, above);
    neuron_template(&m, &nrn, 20.0, 40.0, below);
    double lo = 0, hi = 0, dot = 0, na = 0, nb = 0;
    for (uint32_t i = 0u; i < nrn.wave_len; ++i) {
        lo = fmin(lo, above[i]);
        hi = fmax(hi, above[i]);
        dot += above[i] * below[i];
        na += above[i] * above[i];
        nb += below[i] * below[i];
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, neuron_amplitude_uv(&m, &nrn, hypot(20.0, 40.0)), hi - lo);
    const double corr = dot / sqrt(na * nb);
    TEST_ASSERT_TRUE(corr < 0.97); /* features move between the two positions */
    TEST_ASSERT_TRUE(corr > 0.5);  /* ... but it is still the same kind of spike */
}

/* SNR along the track: exactly one local maximum, at the neuron's depth. */
static void test_single_snr_peak_along_track(void)
{
    sim_electrode_config_t c;
    sim_electrode_default_config(&c);
    c.n_neurons = 3u;
    const double depths[3] = {1200.0, 1260.0, 1500.0};
    const double xs[3] = {25.0, 60.0, 15.0};
    for (uint32_t k = 0u; k < 3u; ++k) {
        neuron_default_params(&c.neurons[k]);
        c.neurons[k].depth_um = depths[k];
        c.neurons[k].x_um = xs[k];
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&el, &c, 5u, 0u));
    sim_neuron_truth_t tr[3];
    TEST_ASSERT_EQUAL_size_t(3u, sim_electrode_truth(&el, tr, 3u));
    for (uint32_t k = 0u; k < 3u; ++k) {
        int peaks = 0;
        double arg = 0.0;
        for (double z = 800.0; z <= 2000.0; z += 0.5) {
            const double a = sim_electrode_snr_at(&el, k, z - 0.5), b = sim_electrode_snr_at(&el, k, z),
                         cc = sim_electrode_snr_at(&el, k, z + 0.5);
            if (b > a && b >= cc) {
                peaks++;
                arg = z;
            }
        }
        TEST_ASSERT_EQUAL_INT(1, peaks);
        TEST_ASSERT_DOUBLE_WITHIN(0.5, tr[k].snr_peak_depth_um, arg);
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, tr[k].snr_peak, sim_electrode_snr_at(&el, k, tr[k].snr_peak_depth_um));
    }
}

/* Long-run rate and the refractory period, with bursts on. */
static void test_rate_and_refractory_period(void)
{
    neuron_params_t p;
    neuron_default_params(&p);
    p.rate_hz = 20.0;
    p.burst_prob = 0.2;
    make(&p, 3u);
    const double T = 2000.0;
    double last = -1.0, min_isi = 1e9;
    uint32_t n = 0u;
    for (uint32_t guard = 0u; nrn.next_s < T && guard < 1000000u; ++guard) {
        if (last >= 0.0) {
            min_isi = fmin(min_isi, nrn.next_s - last);
        }
        last = nrn.next_s;
        n++;
        neuron_pop_spike(&nrn);
    }
    const double rate = (double)n / T; /* expected 20 +- 0.5 (Poisson-ish SE ~0.15) */
    TEST_ASSERT_DOUBLE_WITHIN(0.6, 20.0, rate);
    TEST_ASSERT_TRUE(min_isi >= p.refractory_ms * 1e-3);
}

/* ISIs of a burst-free neuron: refractory + exponential (CV near 1). */
static void test_poisson_isi_shape(void)
{
    neuron_params_t p;
    neuron_default_params(&p);
    p.rate_hz = 5.0;
    p.burst_prob = 0.0;
    make(&p, 4u);
    double s = 0, s2 = 0, last = nrn.next_s;
    int n = 0;
    for (int i = 0; i < 20000; ++i) {
        neuron_pop_spike(&nrn);
        const double isi = nrn.next_s - last - p.refractory_ms * 1e-3;
        last = nrn.next_s;
        s += isi;
        s2 += isi * isi;
        n++;
    }
    const double mean = s / n, sd = sqrt(s2 / n - mean * mean);
    TEST_ASSERT_DOUBLE_WITHIN(0.05, 1.0, sd / mean);
}

/* Silent stretches: the fraction of time silent ~ silent/(active+silent). */
static void test_intermittent_silences(void)
{
    neuron_params_t p;
    neuron_default_params(&p);
    p.rate_hz = 20.0;
    p.active_mean_s = 30.0;
    p.silent_mean_s = 30.0;
    make(&p, 6u);
    const double T = 20000.0;
    uint32_t n = 0u, long_gaps = 0u;
    double last = 0.0;
    for (uint32_t guard = 0u; nrn.next_s < T && guard < 10000000u; ++guard) {
        if (nrn.next_s - last > 5.0) {
            long_gaps++; /* at 20 Hz a 5 s gap only happens in a silence */
        }
        last = nrn.next_s;
        n++;
        neuron_pop_spike(&nrn);
    }
    const double rate = (double)n / T;
    TEST_ASSERT_DOUBLE_WITHIN(2.0, 10.0, rate);
    TEST_ASSERT_TRUE(long_gaps > 200u); /* ~333 silences expected */
}

static void test_appearance_and_disappearance(void)
{
    neuron_params_t p;
    neuron_default_params(&p);
    p.appear_s = 100.0;
    p.disappear_s = 200.0;
    make(&p, 7u);
    TEST_ASSERT_TRUE(nrn.next_s >= 100.0);
    double last = 0.0;
    for (uint32_t guard = 0u; isfinite(nrn.next_s) && guard < 100000u; ++guard) {
        last = nrn.next_s;
        neuron_pop_spike(&nrn);
    }
    TEST_ASSERT_TRUE(last < 200.0);
    TEST_ASSERT_TRUE(last > 190.0);
}

/* A neuron's own drift moves it (and its SNR peak) after drift_start_s. */
static void test_neuron_drift_moves_snr_peak(void)
{
    sim_electrode_config_t c;
    sim_electrode_default_config(&c);
    c.tissue.drift_um_per_min = 0.0;
    c.tissue.insert_relax_um = 0.0;
    c.n_neurons = 1u;
    neuron_default_params(&c.neurons[0]);
    c.neurons[0].depth_um = 1200.0;
    c.neurons[0].drift_um_per_min = 4.0;
    c.neurons[0].drift_start_s = 60.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&el, &c, 8u, 0u));
    sim_neuron_truth_t tr;
    sim_electrode_advance(&el, 30000u * 60u);
    TEST_ASSERT_EQUAL_size_t(1u, sim_electrode_truth(&el, &tr, 1u));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 1200.0, tr.snr_peak_depth_um);
    const double snr0 = tr.snr;
    sim_electrode_advance(&el, 30000u * 300u); /* 5 min of drift: 20 um deeper */
    TEST_ASSERT_EQUAL_size_t(1u, sim_electrode_truth(&el, &tr, 1u));
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 1220.0, tr.snr_peak_depth_um);
    TEST_ASSERT_TRUE(tr.snr < snr0); /* the tip (at 1000 um) is now farther away */
}

static void test_bad_parameters_are_named(void)
{
    neuron_params_t p;
    neuron_default_params(&p);
    const char *why = NULL;
    p.rate_hz = 190.0;
    p.refractory_ms = 10.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, neuron_params_check(&p, &why));
    TEST_ASSERT_NOT_NULL(why);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_amplitude_falls_with_distance_and_reach_is_100_to_140_um);
    RUN_TEST(test_shape_changes_with_position_but_ptp_follows_distance);
    RUN_TEST(test_single_snr_peak_along_track);
    RUN_TEST(test_rate_and_refractory_period);
    RUN_TEST(test_poisson_isi_shape);
    RUN_TEST(test_intermittent_silences);
    RUN_TEST(test_appearance_and_disappearance);
    RUN_TEST(test_neuron_drift_moves_snr_peak);
    RUN_TEST(test_bad_parameters_are_named);
    return UNITY_END();
}

/* Host unit: a whole simulated electrode — recorded signal statistics,
 * ground truth, damage when the tip gets too close, determinism and
 * independence from chunking and from other components' streams. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "model/electrode.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static sim_electrode_t a, b;
static int16_t buf_a[60000], buf_b[60000];
static sim_gt_spike_t gt_a[4096], gt_b[4096];

static void one_neuron(sim_electrode_config_t *c, double depth, double x)
{
    sim_electrode_default_config(c);
    c->n_neurons = 1u;
    neuron_default_params(&c->neurons[0]);
    c->neurons[0].depth_um = depth;
    c->neurons[0].x_um = x;
    c->neurons[0].rate_hz = 20.0;
}

/* Empty tissue, no artifacts: the recorded RMS is the background RMS. */
static void test_background_rms_matches_model(void)
{
    sim_electrode_config_t c;
    sim_electrode_default_config(&c);
    c.signal.large_artifact_rate_hz = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&a, &c, 1u, 0u));
    double s2 = 0.0, s = 0.0;
    for (int k = 0; k < 10; ++k) {
        TEST_ASSERT_EQUAL_size_t(0u, sim_electrode_generate(&a, buf_a, 60000u, gt_a, 4096u));
        for (int i = 0; i < 60000; ++i) {
            const double v = buf_a[i] * c.signal.adc_gain_uv;
            s += v;
            s2 += v * v;
        }
    }
    const double n = 600000.0;
    const double rms = sqrt(s2 / n - (s / n) * (s / n));
    TEST_ASSERT_DOUBLE_WITHIN(0.05 * a.bg_rms_uv, a.bg_rms_uv, rms);
    TEST_ASSERT_DOUBLE_WITHIN(0.3, 0.0, s / n); /* band-pass: no DC */
}

/* Ground truth: each reported spike is in the chunk, and the signal there
 * shows a trough of about the reported amplitude. */
static void test_ground_truth_spikes_are_in_the_signal(void)
{
    sim_electrode_config_t c;
    one_neuron(&c, 1040.0, 20.0);
    c.signal.large_artifact_rate_hz = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&a, &c, 2u, 0u));
    const uint64_t c0 = a.cursor;
    const size_t n = sim_electrode_generate(&a, buf_a, 60000u, gt_a, 4096u);
    TEST_ASSERT_TRUE(n > 20u && n < 80u); /* 20 Hz over 2 s */
    for (size_t k = 0u; k < n; ++k) {
        TEST_ASSERT_TRUE(gt_a[k].sample >= c0 && gt_a[k].sample < c0 + 60000u);
        TEST_ASSERT_EQUAL_INT32(0, gt_a[k].neuron_id);
        const size_t i = (size_t)(gt_a[k].sample - c0);
        int16_t lo = 0;
        for (size_t j = (i > 3u ? i - 3u : 0u); j < i + 4u && j < 60000u; ++j) {
            lo = (buf_a[j] < lo) ? buf_a[j] : lo;
        }
        TEST_ASSERT_TRUE(lo * c.signal.adc_gain_uv < -0.4 * gt_a[k].amp_uv);
        if (k > 0u) {
            TEST_ASSERT_TRUE(gt_a[k].sample >= gt_a[k - 1u].sample);
        }
    }
}

/* The samples do not depend on how the recording is cut into calls. */
static void test_output_independent_of_chunking(void)
{
    sim_electrode_config_t c;
    one_neuron(&c, 1030.0, 20.0);
    c.signal.large_artifact_rate_hz = 5.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&a, &c, 3u, 0u));
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&b, &c, 3u, 0u));
    (void)sim_electrode_command(&a, 300u, 1, 1000.0);
    (void)sim_electrode_command(&b, 300u, 1, 1000.0);
    const size_t na = sim_electrode_generate(&a, buf_a, 60000u, gt_a, 4096u);
    size_t nb = 0u;
    static sim_gt_spike_t part[4096];
    for (size_t done = 0u; done < 60000u;) {
        const size_t m = (60000u - done < 333u) ? 60000u - done : 333u;
        const size_t g = sim_electrode_generate(&b, buf_b + done, m, part, 4096u);
        memcpy(gt_b + nb, part, g * sizeof part[0]);
        nb += g;
        done += m;
    }
    TEST_ASSERT_EQUAL_MEMORY(buf_a, buf_b, sizeof buf_a);
    TEST_ASSERT_EQUAL_size_t(na, nb);
    for (size_t k = 0u; k < na; ++k) {
        TEST_ASSERT_EQUAL_UINT64(gt_a[k].sample, gt_b[k].sample);
        TEST_ASSERT_EQUAL_INT32(gt_a[k].neuron_id, gt_b[k].neuron_id);
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, sim_electrode_tip_um(&a), sim_electrode_tip_um(&b));
}

/* Adding a neuron changes neither the actuator's nor the noise's numbers. */
static void test_streams_are_independent_per_component(void)
{
    sim_electrode_config_t c1, c2;
    one_neuron(&c1, 3000.0, 20.0); /* far away: not rendered */
    c1.signal.large_artifact_rate_hz = 0.0;
    c2 = c1;
    c2.n_neurons = 2u;
    c2.neurons[1] = c1.neurons[0];
    c2.neurons[1].depth_um = 4000.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&a, &c1, 4u, 0u));
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&b, &c2, 4u, 0u));
    (void)sim_electrode_command(&a, 2000u, 1, 2000.0);
    (void)sim_electrode_command(&b, 2000u, 1, 2000.0);
    (void)sim_electrode_generate(&a, buf_a, 60000u, gt_a, 4096u);
    (void)sim_electrode_generate(&b, buf_b, 60000u, gt_b, 4096u);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, a.act.position_um, b.act.position_um);
    TEST_ASSERT_EQUAL_MEMORY(buf_a, buf_b, sizeof buf_a);
    TEST_ASSERT_EQUAL_UINT32(a.neurons[0].rng.s[0] == b.neurons[0].rng.s[0], 1u);
}

/* Driving the tip through a neuron kills it (truth event), a neuron 30 um
 * to the side survives; a dead neuron stops spiking. */
static void test_damage_when_tip_too_close(void)
{
    sim_electrode_config_t c;
    one_neuron(&c, 1100.0, 5.0);
    c.n_neurons = 2u;
    c.neurons[1] = c.neurons[0];
    c.neurons[1].x_um = 30.0;
    c.tissue.drift_um_per_min = 0.0;
    c.tissue.insert_relax_um = 0.0;
    c.tissue.drag_advance = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&a, &c, 5u, 0u));
    FILE *sink = tmpfile();
    TEST_ASSERT_NOT_NULL(sink);
    a.truth = sink;
    /* 200 um in one command at 2 kHz: 2.5 s; passes depth 1100 */
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_command(&a, actuator_steps_for(&a.act.p, 200.0), 1, 2000.0));
    sim_electrode_advance(&a, 30000u * 4u);
    TEST_ASSERT_TRUE(sim_electrode_tip_um(&a) > 1150.0);
    sim_neuron_truth_t tr[2];
    TEST_ASSERT_EQUAL_size_t(2u, sim_electrode_truth(&a, tr, 2u));
    TEST_ASSERT_FALSE(tr[0].alive);
    TEST_ASSERT_TRUE(tr[0].died_s > 0.5 && tr[0].died_s < 2.5);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.0, tr[0].snr);
    TEST_ASSERT_TRUE(tr[1].alive);
    TEST_ASSERT_TRUE(tr[1].snr > 1.0);
    /* no spikes of the dead neuron afterwards */
    const size_t n = sim_electrode_generate(&a, buf_a, 60000u, gt_a, 4096u);
    for (size_t k = 0u; k < n; ++k) {
        TEST_ASSERT_TRUE(gt_a[k].neuron_id != 0);
    }
    rewind(sink);
    char line[512];
    int deaths = 0;
    while (fgets(line, sizeof line, sink) != NULL) {
        deaths += (strstr(line, "\"type\":\"death\"") != NULL && strstr(line, "\"neuron\":0,") != NULL);
    }
    TEST_ASSERT_EQUAL_INT(1, deaths);
    (void)fclose(sink);
}

/* After a move the signal rings (motion artifact), then settles. */
static void test_motion_artifact_after_move(void)
{
    sim_electrode_config_t c;
    sim_electrode_default_config(&c);
    c.signal.large_artifact_rate_hz = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&a, &c, 6u, 0u));
    (void)sim_electrode_command(&a, 20u, 1, 2000.0);
    sim_electrode_advance(&a, 300u); /* the 20 steps take 10 ms */
    (void)sim_electrode_generate(&a, buf_a, 60000u, gt_a, 4096u);
    double early = 0.0, late = 0.0;
    for (int i = 0; i < 3000; ++i) {
        early = fmax(early, fabs(buf_a[i] * c.signal.adc_gain_uv));
        late = fmax(late, fabs(buf_a[57000 + i] * c.signal.adc_gain_uv));
    }
    TEST_ASSERT_TRUE(early > 100.0);
    TEST_ASSERT_TRUE(late < 60.0);
}

/* Large artifacts appear in the ground truth as neuron_id -1. */
static void test_large_artifacts_are_marked(void)
{
    sim_electrode_config_t c;
    sim_electrode_default_config(&c);
    c.signal.large_artifact_rate_hz = 20.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&a, &c, 7u, 0u));
    const size_t n = sim_electrode_generate(&a, buf_a, 60000u, gt_a, 4096u);
    TEST_ASSERT_TRUE(n > 15u && n < 70u);
    for (size_t k = 0u; k < n; ++k) {
        TEST_ASSERT_EQUAL_INT32(-1, gt_a[k].neuron_id);
        TEST_ASSERT_TRUE(gt_a[k].amp_uv >= 0.6 * 800.0);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_background_rms_matches_model);
    RUN_TEST(test_ground_truth_spikes_are_in_the_signal);
    RUN_TEST(test_output_independent_of_chunking);
    RUN_TEST(test_streams_are_independent_per_component);
    RUN_TEST(test_damage_when_tip_too_close);
    RUN_TEST(test_motion_artifact_after_move);
    RUN_TEST(test_large_artifacts_are_marked);
    return UNITY_END();
}

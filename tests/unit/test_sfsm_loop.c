/* Unit: the closed loop of the control units together — per-track SNR-curve
 * table + optimiser + SFSM — on a synthetic neuron (no signal chain): the
 * dominant track's SNR is a noisy Gaussian bump of the depth, its IQM grows
 * with the SNR. The SFSM must search, isolate near the peak, and after the
 * neuron drifts up re-isolate it by retracting. */
#include <math.h>
#include <string.h>

#include "numeric/md_rng.h"
#include "control/sfsm.h"
#include "control/snr_curve.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static sfsm_config_t scfg;
static sc_config_t ccfg;
static sfsm_t sm;
static sc_table_t table;

/* One interval at `depth` with the neuron's peak at `peak`; returns the step. */
static sfsm_output_t interval(md_rng_t *rng, double depth, double peak)
{
    const double d = (depth - peak) / 40.0;
    const double snr = 1.0 + 8.0 * exp(-0.5 * d * d) + 0.3 * md_rng_gauss(rng);
    sfsm_input_t in;
    (void)memset(&in, 0, sizeof in);
    in.has_dominant = snr > 2.5;
    in.spikes_seen = in.has_dominant;
    in.dominant_track = 1u;
    in.snr = snr;
    in.iqm = 0.45 * snr; /* Ω2 from SNR 6.7, Ω3 needs SNR 11: never */
    in.depth_um = depth;
    in.depth_min_um = 0.0;
    in.depth_max_um = 2000.0;
    if (in.has_dominant) {
        sc_curve_t *c = NULL;
        TEST_ASSERT_EQUAL_INT(MD_OK, sc_table_observe(&table, &ccfg, 1u, depth, snr, &c));
        TEST_ASSERT_EQUAL_INT(MD_OK, sc_curve_suggest(c, &ccfg, depth, sm.search_dir, &in.suggestion));
    }
    sfsm_output_t out;
    TEST_ASSERT_EQUAL_INT(MD_OK, sfsm_decide(&sm, &in, &out));
    if (out.reset_curve) {
        TEST_ASSERT_EQUAL_INT(MD_OK, sc_table_reset_track(&table, out.reset_track));
    }
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(scfg.move_max_um, fabs(out.move_um));
    return out;
}

static void test_search_isolate_drift_reisolate(void)
{
    unsigned isolated_runs = 0u;
    unsigned reisolated_runs = 0u;
    for (uint64_t seed = 1u; seed <= 20u; ++seed) {
        md_rng_t rng;
        md_rng_seed(&rng, seed);
        sfsm_config_default(&scfg);
        scfg.snr_min = 2.5; /* this model's noise floor: no track below SNR 2.5 */
        sc_config_default(&ccfg);
        TEST_ASSERT_EQUAL_INT(MD_OK, sfsm_init(&sm, &scfg));
        sc_table_init(&table);
        double depth = 100.0;
        double peak = 300.0;
        unsigned k = 0u;
        for (; (k < 80u) && (sm.state != SFSM_NEURON_ISOLATED); ++k) {
            depth += interval(&rng, depth, peak).move_um;
        }
        if ((sm.state == SFSM_NEURON_ISOLATED) && (fabs(depth - peak) <= 20.0)) {
            isolated_runs++;
        }
        /* decompression: the neuron moves 40 µm towards the surface */
        peak -= 40.0;
        bool left = false;
        for (k = 0u; (k < 80u) && !(left && (sm.state == SFSM_NEURON_ISOLATED)); ++k) {
            depth += interval(&rng, depth, peak).move_um;
            left = left || (sm.state == SFSM_REESTIMATE_GRADIENT);
        }
        if (left && (sm.state == SFSM_NEURON_ISOLATED) && (fabs(depth - peak) <= 20.0)) {
            reisolated_runs++;
        }
    }
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(18u, isolated_runs);   /* >= 90 % isolate within 20 µm */
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(16u, reisolated_runs); /* >= 80 % re-isolate within 20 µm */
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_search_isolate_drift_reisolate);
    return UNITY_END();
}

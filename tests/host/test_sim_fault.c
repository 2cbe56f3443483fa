/// Host tests of the injected plant faults (host_sim/model/sim_fault.h) and
/// of the scenario `faults:` section: each model fault does what it claims
/// inside its window and nothing outside it (sample-identical to a healthy
/// model), and the parser reports bad fault entries as file:line.
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model/electrode.h"
#include "model/sim_fault.h"
#include "scenario/scenario.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static sim_electrode_t g_a, g_b; /* large: static */
static int16_t g_xa[30000], g_xb[30000];

static void two_electrodes(const sim_model_faults_t *f)
{
    sim_electrode_config_t cfg;
    sim_electrode_default_config(&cfg);
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&g_a, &cfg, 5u, 0u));
    cfg.faults = *f;
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_init(&g_b, &cfg, 5u, 0u));
}

static void test_hall_glitch_jumps_inside_window_only(void)
{
    sim_model_faults_t f;
    sim_model_faults_default(&f);
    f.hall_glitch = (sim_window_t){1.0, 2.0};
    f.hall_glitch_prob = 0.5;
    f.hall_glitch_codes = 3000.0;
    sim_hall_fault_state_t s;
    sim_hall_fault_init(&s, 1u, 0u);
    uint32_t jumps = 0;
    for (uint32_t i = 0; i < 300; ++i) {
        const double t = (double)i * 0.01;
        const uint32_t out = sim_fault_hall_apply(&f, &s, t, 30000u, 65535u);
        if (t < 1.0 || t >= 2.0) {
            TEST_ASSERT_EQUAL_UINT32(30000u, out);
        } else if (out != 30000u) {
            TEST_ASSERT_TRUE(out == 33000u || out == 27000u);
            jumps++;
        }
    }
    TEST_ASSERT_EQUAL_UINT64(jumps, s.glitches);
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(25u, jumps); /* binomial(100, 0.5): mean 50, sd 5 */
    TEST_ASSERT_LESS_OR_EQUAL_UINT(75u, jumps);
    /* clamped to the ADC range */
    f.hall_glitch_prob = 1.0;
    const uint32_t hi = sim_fault_hall_apply(&f, &s, 1.5, 65000u, 65535u);
    TEST_ASSERT_TRUE(hi == 65535u || hi == 62000u);
}

static void test_hall_stuck_repeats_last_reading(void)
{
    sim_model_faults_t f;
    sim_model_faults_default(&f);
    f.hall_stuck = (sim_window_t){1.0, 2.0};
    sim_hall_fault_state_t s;
    sim_hall_fault_init(&s, 1u, 0u);
    TEST_ASSERT_EQUAL_UINT32(100u, sim_fault_hall_apply(&f, &s, 0.5, 100u, 65535u));
    TEST_ASSERT_EQUAL_UINT32(100u, sim_fault_hall_apply(&f, &s, 1.0, 5000u, 65535u));
    TEST_ASSERT_EQUAL_UINT32(100u, sim_fault_hall_apply(&f, &s, 1.9, 7000u, 65535u));
    TEST_ASSERT_EQUAL_UINT32(7100u, sim_fault_hall_apply(&f, &s, 2.0, 7100u, 65535u));
    TEST_ASSERT_EQUAL_UINT64(2u, s.stuck_reads);
}

static void test_actuator_stall_stops_motion_and_reports_stalled(void)
{
    actuator_params_t p;
    actuator_default_params(&p);
    p.miss_prob = 0.0;
    p.slip_prob = 0.0;
    actuator_t a;
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_init(&a, &p, 1000.0, 3u, 0u));
    sim_model_faults_t f;
    sim_model_faults_default(&f);
    f.act_stall = (sim_window_t){10.0, 20.0};
    actuator_set_faults(&a, &f, 3u, 0u);
    /* before the window: moves */
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&a, 0.0, 100u, 1, 1000.0));
    TEST_ASSERT_GREATER_THAN_DOUBLE(3.0, actuator_advance_to(&a, 1.0));
    /* inside: the first step stalls, the carrier stays */
    const double before = a.position_um;
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&a, 12.0, 100u, 1, 1000.0));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.0, actuator_advance_to(&a, 13.0));
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, before, a.position_um);
    TEST_ASSERT_EQUAL_INT(ACTUATOR_STALLED, actuator_status(&a).state);
    TEST_ASSERT_EQUAL_UINT32(0u, actuator_status(&a).steps_done);
    TEST_ASSERT_EQUAL_UINT64(1u, a.fault_stalls);
    /* after: moves again */
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&a, 21.0, 100u, 1, 1000.0));
    TEST_ASSERT_GREATER_THAN_DOUBLE(3.0, actuator_advance_to(&a, 22.0));
}

static void test_actuator_slip_moves_back(void)
{
    actuator_params_t p;
    actuator_default_params(&p);
    p.miss_prob = 0.0;
    p.slip_prob = 0.0;
    p.step_cv = 0.0;
    actuator_t a;
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_init(&a, &p, 1000.0, 3u, 0u));
    sim_model_faults_t f;
    sim_model_faults_default(&f);
    f.act_slip = (sim_window_t){0.0, 100.0};
    f.act_slip_prob = 1.0;
    f.act_slip_um = 2.0;
    actuator_set_faults(&a, &f, 3u, 0u);
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&a, 0.0, 10u, 1, 1000.0));
    /* commanded +0.4 um deeper; every step slipped 2 um back instead */
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, -20.0, actuator_advance_to(&a, 1.0));
    TEST_ASSERT_EQUAL_UINT64(10u, a.fault_slips);
    TEST_ASSERT_EQUAL_UINT32(10u, actuator_status(&a).steps_done); /* the driver believes they were done */
}

static void test_adc_saturation_pins_samples_to_the_rails(void)
{
    sim_model_faults_t f;
    sim_model_faults_default(&f);
    f.adc_saturation = (sim_window_t){0.2, 0.4};
    two_electrodes(&f);
    (void)sim_electrode_generate(&g_a, g_xa, 30000u, NULL, 0u);
    (void)sim_electrode_generate(&g_b, g_xb, 30000u, NULL, 0u);
    for (uint32_t i = 0; i < 30000u; ++i) {
        if (i < 6000u || i >= 12000u) {
            TEST_ASSERT_EQUAL_INT(g_xa[i], g_xb[i]); /* outside: sample-identical */
        } else {
            TEST_ASSERT_TRUE(g_xb[i] == 32767 || g_xb[i] == -32768);
        }
    }
    TEST_ASSERT_EQUAL_UINT64(6000u, g_b.sig_fault.saturated_samples);
}

static void test_artifact_storm_adds_large_transients_in_window(void)
{
    sim_model_faults_t f;
    sim_model_faults_default(&f);
    f.artifact_storm = (sim_window_t){0.5, 1.0};
    f.storm_rate_hz = 100.0;
    f.storm_amp_uv = 3000.0;
    two_electrodes(&f);
    (void)sim_electrode_generate(&g_a, g_xa, 30000u, NULL, 0u);
    (void)sim_electrode_generate(&g_b, g_xb, 30000u, NULL, 0u);
    uint32_t big = 0;
    for (uint32_t i = 0; i < 30000u; ++i) {
        const int d = (int)g_xb[i] - (int)g_xa[i];
        if (i < 15000u) {
            TEST_ASSERT_EQUAL_INT(0, d);
        }
        /* 0.6*3000 uV ptp transient: well above 500 uV (2564 LSB at 0.195 uV) */
        big += (abs(d) > 2564) ? 1u : 0u;
    }
    /* Poisson(50) events in 0.5 s: at least 20 */
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(20u, (unsigned)g_b.sig_fault.storm_events);
    TEST_ASSERT_GREATER_OR_EQUAL_UINT(20u, big);
    /* the healthy run's truth is untouched: same model state */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, sim_electrode_tip_um(&g_a), sim_electrode_tip_um(&g_b));
}

static void test_hall_fault_through_the_electrode(void)
{
    sim_model_faults_t f;
    sim_model_faults_default(&f);
    f.hall_stuck = (sim_window_t){0.1, 10.0};
    two_electrodes(&f);
    const uint32_t first = sim_electrode_hall_read(&g_b); /* t = 0: healthy */
    TEST_ASSERT_EQUAL_UINT32(sim_electrode_hall_read(&g_a), first);
    sim_electrode_advance(&g_b, 6000u); /* 0.2 s */
    TEST_ASSERT_EQUAL_INT(MD_OK, sim_electrode_command(&g_b, 2000u, 1, 2000.0));
    sim_electrode_advance(&g_b, 60000u); /* +2 s: moved ~80 um */
    TEST_ASSERT_GREATER_THAN_DOUBLE(1050.0, sim_electrode_tip_um(&g_b));
    TEST_ASSERT_EQUAL_UINT32(first, sim_electrode_hall_read(&g_b));
}

/* ---- scenario faults: section -------------------------------------------- */

static scenario_t g_sc;
static char g_err[4096];

static int parse(const char *y)
{
    return scenario_parse(&g_sc, y, strlen(y), "f.yaml", g_err, sizeof g_err);
}

static void test_scenario_faults_parsed(void)
{
    const char *y = "electrodes:\n"
                    "  - start_um: 1000\n"
                    "  - start_um: 1200\n"
                    "faults:\n"
                    "  - {kind: hall_glitch, electrode: 1, from_s: 30, to_s: 60, prob: 0.2, codes: 1500}\n"
                    "  - {kind: actuator_stall, from_s: 5, to_s: 6}\n"
                    "  - {kind: actuator_slip, electrode: 0, prob: 0.3, slip_um: 4}\n"
                    "  - {kind: adc_saturation, electrode: 0, from_s: 1, to_s: 2}\n"
                    "  - {kind: artifact_storm, electrode: 1, rate_hz: 50, amp_uv: 2000, from_s: 3, to_s: 4}\n"
                    "  - {kind: hall_stuck, electrode: 0, from_s: 7, to_s: 8}\n"
                    "  - {kind: bus_loss, prob: 0.05, direction: rx, can_id: 528}\n"
                    "  - {kind: bus_delay, prob: 0.1, frames: 6, from_s: 10, to_s: 20}\n"
                    "  - {kind: node_silent, node: hall, from_s: 40, to_s: 55}\n"
                    "  - {kind: controller_restart, at_s: 120}\n";
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, parse(y), g_err);
    const sim_model_faults_t *f0 = &g_sc.electrodes[0].faults, *f1 = &g_sc.electrodes[1].faults;
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 30.0, f1->hall_glitch.from_s);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1500.0, f1->hall_glitch_codes);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.2, f1->hall_glitch_prob);
    TEST_ASSERT_FALSE(f0->hall_glitch.to_s > f0->hall_glitch.from_s);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 6.0, f0->act_stall.to_s); /* both electrodes */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 6.0, f1->act_stall.to_s);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 4.0, f0->act_slip_um);
    TEST_ASSERT_TRUE(f0->act_slip.to_s > 1e100); /* forever */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 2000.0, f1->storm_amp_uv);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 7.0, f0->hall_stuck.from_s);
    TEST_ASSERT_EQUAL_UINT32(2u, g_sc.faults.n_bus);
    TEST_ASSERT_EQUAL_UINT32(0u, g_sc.faults.bus[0].kind);
    TEST_ASSERT_EQUAL_UINT32(2u, g_sc.faults.bus[0].directions);
    TEST_ASSERT_EQUAL_UINT32(1u, g_sc.faults.bus[0].has_id);
    TEST_ASSERT_EQUAL_UINT32(528u, g_sc.faults.bus[0].can_id);
    TEST_ASSERT_EQUAL_UINT32(3u, g_sc.faults.bus[1].kind);
    TEST_ASSERT_EQUAL_UINT32(6u, g_sc.faults.bus[1].frames);
    TEST_ASSERT_EQUAL_UINT32(3u, g_sc.faults.bus[1].directions);
    TEST_ASSERT_TRUE(scenario_node_silent(&g_sc, 3u, 40.0));
    TEST_ASSERT_TRUE(scenario_node_silent(&g_sc, 3u, 54.9));
    TEST_ASSERT_FALSE(scenario_node_silent(&g_sc, 3u, 55.0));
    TEST_ASSERT_FALSE(scenario_node_silent(&g_sc, 2u, 45.0));
    TEST_ASSERT_EQUAL_UINT32(1u, scenario_restarts_due(&g_sc, 119.9, 120.0));
    TEST_ASSERT_EQUAL_UINT32(0u, scenario_restarts_due(&g_sc, 120.0, 130.0));
    TEST_ASSERT_TRUE(scenario_has_faults(&g_sc));
    TEST_ASSERT_EQUAL_INT(0, parse("electrodes: [{start_um: 1000}]\n"));
    TEST_ASSERT_FALSE(scenario_has_faults(&g_sc));
}

static void expect_error(const char *y, const char *needle)
{
    TEST_ASSERT_GREATER_THAN_INT(0, parse(y));
    TEST_ASSERT_MESSAGE(strstr(g_err, needle) != NULL, g_err);
}

static void test_scenario_fault_errors_name_file_and_line(void)
{
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n  - {kind: meteor}\n",
                 "f.yaml:3: unknown fault kind 'meteor'");
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n  - {prob: 0.1}\n",
                 "f.yaml:3: missing required field 'kind'");
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n  - {kind: bus_loss}\n",
                 "f.yaml:3: fault kind bus_loss needs 'prob'");
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n\n  - {kind: bus_loss, prob: 2}\n",
                 "f.yaml:4: 'prob' = 2 out of range");
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n  - {kind: hall_stuck, prob: 0.5}\n",
                 "f.yaml:3: 'prob' does not apply to fault kind hall_stuck");
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n  - {kind: hall_stuck, electrode: 1}\n",
                 "f.yaml:3: fault electrode 1 but the scenario has 1");
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n  - {kind: act_stall}\n", "unknown fault kind 'act_stall'");
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n  - {kind: actuator_stall, from_s: 5, to_s: 5}\n",
                 "f.yaml:3: fault window needs from_s < to_s");
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n  - {kind: node_silent, node: brain}\n",
                 "f.yaml:3: 'node' must be act, hall or fe, got 'brain'");
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n  - {kind: node_silent}\n", "needs 'node'");
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n  - {kind: adc_saturation}\n  - {kind: adc_saturation}\n",
                 "f.yaml:4: a second adc_saturation fault on one electrode");
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n  - {kind: controller_restart, at_s: 9}\n"
                 "  - {kind: controller_restart, at_s: 3}\n",
                 "f.yaml:4: controller restarts");
    expect_error("electrodes: [{start_um: 1000}]\nfaults: {kind: bus_loss}\n", "f.yaml:2: faults must be a sequence");
    expect_error("electrodes: [{start_um: 1000}]\nfaults:\n  - {kind: bus_dup, prob: 0.1, wobble: 1}\n",
                 "f.yaml:3: unknown key 'wobble' in fault");
}

static void test_shipped_fault_scenarios_load(void)
{
    static const char *const names[] = {"bus_loss",       "bus_corrupt",      "bus_dup",           "bus_delay",
                                        "bus_reorder",    "node_silent_hall", "node_silent_act",   "node_silent_fe",
                                        "hall_glitch",    "hall_stuck",       "actuator_stall",    "actuator_slip",
                                        "adc_saturation", "artifact_storm",   "controller_restart"};
    char dir[512];
    (void)snprintf(dir, sizeof dir, "%s", __FILE__);
    char *slash = strrchr(dir, '/');
    TEST_ASSERT_NOT_NULL(slash);
    *slash = '\0';
    for (size_t i = 0; i < sizeof names / sizeof names[0]; ++i) {
        char path[700];
        (void)snprintf(path, sizeof path, "%s/../../scenarios/faults/%s.yaml", dir, names[i]);
        TEST_ASSERT_EQUAL_INT_MESSAGE(0, scenario_load(&g_sc, path, g_err, sizeof g_err), g_err);
        TEST_ASSERT_TRUE_MESSAGE(scenario_has_faults(&g_sc), names[i]);
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_hall_glitch_jumps_inside_window_only);
    RUN_TEST(test_hall_stuck_repeats_last_reading);
    RUN_TEST(test_actuator_stall_stops_motion_and_reports_stalled);
    RUN_TEST(test_actuator_slip_moves_back);
    RUN_TEST(test_adc_saturation_pins_samples_to_the_rails);
    RUN_TEST(test_artifact_storm_adds_large_transients_in_window);
    RUN_TEST(test_hall_fault_through_the_electrode);
    RUN_TEST(test_scenario_faults_parsed);
    RUN_TEST(test_scenario_fault_errors_name_file_and_line);
    RUN_TEST(test_shipped_fault_scenarios_load);
    return UNITY_END();
}

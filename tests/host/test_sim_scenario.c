/* Host unit: YAML scenario parser — the shipped scenarios load; every
 * semantic error of the fixtures under tests/host/fixtures is reported as
 * file:line: reason, all of them in one run. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "scenario/scenario.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static scenario_t sc;
static char err[8192];

/* tests/host/ (this file's folder, an absolute path in CMake builds) */
static void here(char *out, size_t len, const char *rel)
{
    const char *f = __FILE__;
    const char *slash = strrchr(f, '/');
    const size_t n = (slash != NULL) ? (size_t)(slash - f) : 1u;
    (void)snprintf(out, len, "%.*s/%s", (int)n, (slash != NULL) ? f : ".", rel);
}

static int load(const char *rel)
{
    char path[1024];
    here(path, sizeof path, rel);
    return scenario_load(&sc, path, err, sizeof err);
}

static void expect(const char *needle)
{
    if (strstr(err, needle) == NULL) {
        TEST_MESSAGE(err);
        TEST_FAIL_MESSAGE(needle);
    }
}

static void test_shipped_scenarios_load(void)
{
    const char *names[7] = {"single_neuron", "crossing_clusters", "appearing_neuron", "intermittent_neuron",
                            "drift_away",    "empty_tissue",      "three_electrodes"};
    for (int i = 0; i < 7; ++i) {
        char rel[128];
        (void)snprintf(rel, sizeof rel, "../../scenarios/%s.yaml", names[i]);
        const int n = load(rel);
        if (n != 0) {
            TEST_MESSAGE(err);
        }
        TEST_ASSERT_EQUAL_INT(0, n);
        TEST_ASSERT_EQUAL_STRING(names[i], sc.name);
        sim_world_t *w = malloc(sizeof *w);
        TEST_ASSERT_NOT_NULL(w);
        TEST_ASSERT_EQUAL_INT(MD_OK, scenario_make_world(&sc, sc.seed, w));
        free(w);
    }
    TEST_ASSERT_EQUAL_INT(0, load("../../scenarios/three_electrodes.yaml"));
    TEST_ASSERT_EQUAL_UINT32(3u, sc.n_electrodes);
    TEST_ASSERT_EQUAL_UINT32(6u, sc.electrodes[1].random_neurons.count);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1.5, sc.electrodes[2].tissue.breathing_um);
    TEST_ASSERT_EQUAL_INT(0, load("../../scenarios/crossing_clusters.yaml"));
    TEST_ASSERT_EQUAL_INT(NEURON_TRIPHASIC, sc.electrodes[0].neurons[1].shape);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.7, sc.electrodes[0].neuron_model.shape_mix);
}

/* Defaults, neuron_defaults and per-electrode overrides, from a string. */
static void test_defaults_and_overrides(void)
{
    static const char y[] = "seed: 18446744073709551615\n"
                            "actuator: {step_nm: 50}\n"
                            "neuron_defaults: {rate_hz: 3, shape: triphasic}\n"
                            "electrodes:\n"
                            "  - neurons: [{depth_um: 10}, {depth_um: 20, rate_hz: 7}]\n"
                            "  - actuator: {step_nm: 30}\n"
                            "    start_um: 5\n";
    TEST_ASSERT_EQUAL_INT(0, scenario_parse(&sc, y, sizeof y - 1u, "s.yaml", err, sizeof err));
    TEST_ASSERT_EQUAL_UINT64(18446744073709551615ull, sc.seed);
    TEST_ASSERT_EQUAL_UINT32(2u, sc.n_electrodes);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 50.0, sc.electrodes[0].actuator.step_nm);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 30.0, sc.electrodes[1].actuator.step_nm);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.85, sc.electrodes[1].actuator.retract_ratio); /* default kept */
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1000.0, sc.electrodes[0].start_um);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 5.0, sc.electrodes[1].start_um);
    TEST_ASSERT_EQUAL_UINT32(2u, sc.electrodes[0].n_neurons);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 3.0, sc.electrodes[0].neurons[0].rate_hz);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 7.0, sc.electrodes[0].neurons[1].rate_hz);
    TEST_ASSERT_EQUAL_INT(NEURON_TRIPHASIC, sc.electrodes[0].neurons[1].shape);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 20.0, sc.electrodes[0].neurons[1].x_um); /* default */
    TEST_ASSERT_EQUAL_UINT32(20u, sc.export_cfg.intervals);
}

static void test_unknown_keys(void)
{
    TEST_ASSERT_EQUAL_INT(3, load("fixtures/scenario_unknown_key.yaml"));
    expect("scenario_unknown_key.yaml:5: unknown key 'stepsize_nm' in actuator\n");
    expect("scenario_unknown_key.yaml:6: unknown key 'colour'\n");
    expect("scenario_unknown_key.yaml:9: unknown key 'neuron' in electrode\n");
}

static void test_wrong_types(void)
{
    TEST_ASSERT_EQUAL_INT(6, load("fixtures/scenario_wrong_type.yaml"));
    expect("scenario_wrong_type.yaml:2: 'seed' must be a non-negative integer, got '-3'\n");
    expect("scenario_wrong_type.yaml:4: 'noise_uv' must be a number, got '6'\n");
    expect("scenario_wrong_type.yaml:9: 'rate_hz' must be a number, got 'fast'\n");
    expect("scenario_wrong_type.yaml:10: 'shape' must be biphasic or triphasic, got 'square'\n");
    expect("scenario_wrong_type.yaml:11: 'burst_spikes' must be a non-negative integer, got '2.5'\n");
    expect("scenario_wrong_type.yaml:12: 'start_um' in electrode must be a scalar\n");
}

static void test_values_out_of_range(void)
{
    TEST_ASSERT_EQUAL_INT(6, load("fixtures/scenario_out_of_range.yaml"));
    expect("scenario_out_of_range.yaml:3: 'sample_rate_hz' = 1000 out of range [20000, 50000]\n");
    expect("scenario_out_of_range.yaml:4: 'step_nm' = 0 out of range [1, 10000]\n");
    expect("scenario_out_of_range.yaml:4: actuator: miss_prob + slip_prob must be <= 1\n");
    expect("scenario_out_of_range.yaml:8: 'rate_hz' = 500 out of range [0.01, 200]\n");
    expect("scenario_out_of_range.yaml:9: neuron: rate_hz too high for refractory_ms and burst settings\n");
    expect("scenario_out_of_range.yaml:10: 'intervals' = 0 out of range [1, 100000]\n");
}

static void test_missing_required_fields(void)
{
    TEST_ASSERT_EQUAL_INT(2, load("fixtures/scenario_missing.yaml"));
    expect("scenario_missing.yaml:3: unknown key 'electrods'\n");
    expect("scenario_missing.yaml:1: missing required field 'electrodes'\n");
    TEST_ASSERT_EQUAL_INT(2, load("fixtures/scenario_missing_depth.yaml"));
    expect("scenario_missing_depth.yaml:5: missing required field 'depth_um' in neuron\n");
    expect("scenario_missing_depth.yaml:7: duplicate key 'depth_um' in neuron\n");
}

static void test_syntax_and_structure_errors(void)
{
    TEST_ASSERT_EQUAL_INT(1, load("fixtures/scenario_syntax.yaml"));
    expect("scenario_syntax.yaml:5: YAML syntax error: ");
    TEST_ASSERT_EQUAL_INT(2, load("fixtures/scenario_structure.yaml"));
    expect("scenario_structure.yaml:2: actuator must be a mapping\n");
    expect("scenario_structure.yaml:4: electrodes must be a sequence\n");
    TEST_ASSERT_EQUAL_INT(-1, load("fixtures/no_such_file.yaml"));
    expect("no_such_file.yaml:0: cannot open");
}

static void test_error_buffer_truncation_is_safe(void)
{
    char small[40];
    char path[1024];
    here(path, sizeof path, "fixtures/scenario_wrong_type.yaml");
    TEST_ASSERT_EQUAL_INT(6, scenario_load(&sc, path, small, sizeof small));
    TEST_ASSERT_TRUE(strlen(small) < sizeof small);
}

/* A value quoted in a message keeps its error on one line: a plain scalar
 * folded over blank lines holds '\n', a double-quoted one any escape. */
static void test_values_with_line_breaks_stay_on_one_line(void)
{
    static const char text[] = "name: x\nelectrodes:\n  - start_um: 1000\n    neurons:\n"
                               "      - {depth_um: 1200, shape: bi\n\n\n  phasic}\n"
                               "duration_s: \"1\\n2\\t\\x01\"\n";
    TEST_ASSERT_EQUAL_INT(2, scenario_parse(&sc, text, sizeof text - 1u, "s.yaml", err, sizeof err));
    expect("s.yaml:5: 'shape' must be biphasic or triphasic, got 'bi\\n\\nphasic'\n");
    expect("s.yaml:9: 'duration_s' must be a number, got '1\\n2\\t\\x01'\n");
    size_t lines = 0u;
    for (const char *p = err; *p != '\0'; ++p) {
        lines += (*p == '\n') ? 1u : 0u;
    }
    TEST_ASSERT_EQUAL_size_t(2u, lines);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_shipped_scenarios_load);
    RUN_TEST(test_defaults_and_overrides);
    RUN_TEST(test_unknown_keys);
    RUN_TEST(test_wrong_types);
    RUN_TEST(test_values_out_of_range);
    RUN_TEST(test_missing_required_fields);
    RUN_TEST(test_syntax_and_structure_errors);
    RUN_TEST(test_error_buffer_truncation_is_safe);
    RUN_TEST(test_values_with_line_breaks_stay_on_one_line);
    return UNITY_END();
}

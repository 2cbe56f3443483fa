/* Host unit: microdrive-sim's command line (host_sim/app/sim_cli.c). */
#include <string.h>

#include "sim_cli.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static sim_cli_t cli;
static char msg[256];

static int parse(int argc, const char *const *argv)
{
    msg[0] = '\0';
    return sim_cli_parse(&cli, argc, (char *const *)(uintptr_t)argv, msg, sizeof msg);
}

static void test_defaults(void)
{
    const char *argv[] = {"sim", "--scenario", "s.yaml"};
    TEST_ASSERT_EQUAL_INT(0, parse(3, argv));
    TEST_ASSERT_EQUAL_STRING("s.yaml", cli.scenario);
    TEST_ASSERT_EQUAL_STRING("auto", cli.bus);
    TEST_ASSERT_FALSE(cli.seed_given);
    TEST_ASSERT_FALSE(cli.realtime);
    TEST_ASSERT_TRUE(cli.autostart);
    TEST_ASSERT_NULL(cli.export_dir);
    TEST_ASSERT_NULL(cli.truth);
    TEST_ASSERT_EQUAL_UINT32(10000u, cli.calib_period_ms);
    TEST_ASSERT_EQUAL_UINT32(50000u, cli.pace_fps);
    TEST_ASSERT_TRUE(cli.duration_s < 0.0);
    TEST_ASSERT_FALSE(cli.help);
}

static void test_every_option(void)
{
    const char *argv[] = {"sim",
                          "--scenario",
                          "a.yaml",
                          "--seed",
                          "18446744073709551615",
                          "--bus",
                          "udp:5000",
                          "--realtime",
                          "--export-recording",
                          "out",
                          "--truth",
                          "t.jsonl",
                          "--hall-rate",
                          "250.5",
                          "--calib-period-ms",
                          "2000",
                          "--no-autostart",
                          "--duration-s",
                          "60",
                          "--pace",
                          "0"};
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, parse(21, argv), msg);
    TEST_ASSERT_TRUE(cli.seed_given);
    TEST_ASSERT_EQUAL_UINT64(UINT64_MAX, cli.seed);
    TEST_ASSERT_EQUAL_STRING("udp:5000", cli.bus);
    TEST_ASSERT_TRUE(cli.realtime);
    TEST_ASSERT_EQUAL_STRING("out", cli.export_dir);
    TEST_ASSERT_EQUAL_STRING("t.jsonl", cli.truth);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 250.5, cli.hall_rate_hz);
    TEST_ASSERT_EQUAL_UINT32(2000u, cli.calib_period_ms);
    TEST_ASSERT_FALSE(cli.autostart);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 60.0, cli.duration_s);
    TEST_ASSERT_EQUAL_UINT32(0u, cli.pace_fps);
}

static void test_help_needs_nothing_else(void)
{
    const char *argv[] = {"sim", "--help"};
    TEST_ASSERT_EQUAL_INT(0, parse(2, argv));
    TEST_ASSERT_TRUE(cli.help);
    /* the text documents every option */
    static const char *const opts[] = {"--scenario",         "--seed",       "--bus",       "--realtime",
                                       "--export-recording", "--truth",      "--hall-rate", "--calib-period-ms",
                                       "--no-autostart",     "--duration-s", "--pace",      "--help"};
    for (size_t i = 0; i < sizeof opts / sizeof opts[0]; i++) {
        TEST_ASSERT_NOT_NULL(strstr(sim_cli_usage(), opts[i]));
    }
}

static void test_errors_name_the_problem(void)
{
    const char *no_scenario[] = {"sim", "--seed", "1"};
    TEST_ASSERT_EQUAL_INT(-1, parse(3, no_scenario));
    TEST_ASSERT_NOT_NULL(strstr(msg, "--scenario"));
    const char *bad_seed[] = {"sim", "--scenario", "s", "--seed", "-3"};
    TEST_ASSERT_EQUAL_INT(-1, parse(5, bad_seed));
    TEST_ASSERT_NOT_NULL(strstr(msg, "--seed"));
    const char *overflow_seed[] = {"sim", "--scenario", "s", "--seed", "18446744073709551616"};
    TEST_ASSERT_EQUAL_INT(-1, parse(5, overflow_seed));
    const char *trailing[] = {"sim", "--scenario", "s", "--hall-rate", "10Hz"};
    TEST_ASSERT_EQUAL_INT(-1, parse(5, trailing));
    const char *zero_calib[] = {"sim", "--scenario", "s", "--calib-period-ms", "0"};
    TEST_ASSERT_EQUAL_INT(-1, parse(5, zero_calib));
    const char *missing[] = {"sim", "--scenario", "s", "--bus"};
    TEST_ASSERT_EQUAL_INT(-1, parse(4, missing));
    TEST_ASSERT_NOT_NULL(strstr(msg, "missing value after: --bus"));
    const char *unknown[] = {"sim", "--scenario", "s", "--fast"};
    TEST_ASSERT_EQUAL_INT(-1, parse(4, unknown));
    TEST_ASSERT_NOT_NULL(strstr(msg, "unknown option: --fast"));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_defaults);
    RUN_TEST(test_every_option);
    RUN_TEST(test_help_needs_nothing_else);
    RUN_TEST(test_errors_name_the_problem);
    return UNITY_END();
}

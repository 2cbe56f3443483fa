/* Host unit: piezo actuator model — step statistics, direction asymmetry,
 * missed steps/slips, rate limit, end stops (stall reported, never passed),
 * no backlash. */
#include <math.h>

#include "model/actuator.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static actuator_t act;

static void init_default(double start_um, uint64_t seed)
{
    actuator_params_t p;
    actuator_default_params(&p);
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_init(&act, &p, start_um, seed, 0u));
}

/* Mean and CV of single advance steps over many commands of one step. */
static void test_step_statistics_match_parameters(void)
{
    actuator_params_t p;
    actuator_default_params(&p);
    p.miss_prob = 0.0;
    p.slip_prob = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_init(&act, &p, 1000.0, 7u, 0u));
    const int n = 20000;
    double s = 0.0, s2 = 0.0;
    double t = 0.0;
    for (int i = 0; i < n; ++i) {
        TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&act, t, 1u, 1, 1000.0));
        t += 0.001;
        const double d_nm = actuator_advance_to(&act, t) * 1000.0;
        s += d_nm;
        s2 += d_nm * d_nm;
    }
    const double mean = s / n, sd = sqrt(s2 / n - mean * mean);
    TEST_ASSERT_DOUBLE_WITHIN(0.5, 40.0, mean); /* SE ~ 0.03 nm */
    TEST_ASSERT_DOUBLE_WITHIN(0.01, 0.10, sd / mean);
}

static void test_retract_steps_are_shorter(void)
{
    init_default(3000.0, 3u);
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&act, 0.0, 10000u, 1, 2000.0));
    const double adv = actuator_advance_to(&act, 10.0);
    TEST_ASSERT_EQUAL_INT(ACTUATOR_IDLE, actuator_status(&act).state);
    TEST_ASSERT_EQUAL_UINT32(10000u, actuator_status(&act).steps_done);
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&act, 10.0, 10000u, -1, 2000.0));
    const double ret = actuator_advance_to(&act, 20.0);
    /* 10000 steps: 400 um forward; back ~0.85 of it; misses/slips cost < 1 % */
    TEST_ASSERT_DOUBLE_WITHIN(6.0, 400.0, adv);
    TEST_ASSERT_DOUBLE_WITHIN(0.02, 0.85, -ret / adv);
    TEST_ASSERT_TRUE(act.missed_steps > 0u); /* 20000 steps at p = 0.002 */
    TEST_ASSERT_TRUE(act.slips > 0u);        /* 20000 steps at p = 0.0005 */
}

static void test_steps_follow_commanded_rate_and_max_rate(void)
{
    init_default(1000.0, 5u);
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&act, 0.0, 1000u, 1, 500.0));
    (void)actuator_advance_to(&act, 0.1999);
    TEST_ASSERT_EQUAL_UINT32(100u, actuator_status(&act).steps_done); /* steps at 0, 2 ms, ... 198 ms */
    TEST_ASSERT_EQUAL_INT(ACTUATOR_MOVING, actuator_status(&act).state);
    /* above the maximum: clamped to 2000 Hz and counted */
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&act, 0.2, 1000u, 1, 1.0e6));
    TEST_ASSERT_EQUAL_UINT32(1u, actuator_status(&act).rate_clamped_count);
    (void)actuator_advance_to(&act, 0.2 + 0.0999);
    TEST_ASSERT_EQUAL_UINT32(200u, actuator_status(&act).steps_done);
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, actuator_command(&act, 0.3, 10u, 0, 100.0));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, actuator_command(&act, 0.3, 10u, 1, 0.0));
}

static void test_lower_end_stop_stalls_and_is_never_passed(void)
{
    init_default(5590.0, 9u); /* 10 um above the lower stop */
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&act, 0.0, 5000u, 1, 2000.0));
    double worst = 0.0;
    for (int i = 1; i <= 400; ++i) {
        (void)actuator_advance_to(&act, 0.01 * i);
        worst = fmax(worst, act.position_um);
    }
    const actuator_status_t st = actuator_status(&act);
    TEST_ASSERT_EQUAL_INT(ACTUATOR_STALLED, st.state);
    TEST_ASSERT_TRUE(st.at_lower_stop);
    TEST_ASSERT_FALSE(st.at_upper_stop);
    TEST_ASSERT_EQUAL_UINT32(1u, st.stall_count);
    TEST_ASSERT_TRUE(st.steps_done < 400u); /* ~250 steps of 40 nm */
    TEST_ASSERT_TRUE(worst <= 5600.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 5600.0, act.position_um);
    /* pushing again stalls again, at once, and still does not pass */
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&act, 4.0, 10u, 1, 2000.0));
    (void)actuator_advance_to(&act, 5.0);
    TEST_ASSERT_EQUAL_INT(ACTUATOR_STALLED, actuator_status(&act).state);
    TEST_ASSERT_EQUAL_UINT32(2u, actuator_status(&act).stall_count);
    TEST_ASSERT_TRUE(act.position_um <= 5600.0);
    /* retracting leaves the stop */
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&act, 5.0, 100u, -1, 2000.0));
    (void)actuator_advance_to(&act, 6.0);
    TEST_ASSERT_EQUAL_INT(ACTUATOR_IDLE, actuator_status(&act).state);
    TEST_ASSERT_FALSE(actuator_status(&act).at_lower_stop);
    TEST_ASSERT_TRUE(act.position_um < 5600.0);
}

static void test_upper_end_stop(void)
{
    init_default(2.0, 11u);
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&act, 0.0, 1000u, -1, 2000.0));
    (void)actuator_advance_to(&act, 1.0);
    TEST_ASSERT_EQUAL_INT(ACTUATOR_STALLED, actuator_status(&act).state);
    TEST_ASSERT_TRUE(actuator_status(&act).at_upper_stop);
    TEST_ASSERT_TRUE(act.position_um >= 0.0);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.0, act.position_um);
}

/* No backlash: the first step after a reversal already moves the carrier. */
static void test_no_backlash_on_reversal(void)
{
    actuator_params_t p;
    actuator_default_params(&p);
    p.miss_prob = 0.0;
    p.slip_prob = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_init(&act, &p, 2000.0, 13u, 0u));
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&act, 0.0, 50u, 1, 1000.0));
    (void)actuator_advance_to(&act, 1.0);
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&act, 1.0, 1u, -1, 1000.0));
    const double back = actuator_advance_to(&act, 1.5);
    TEST_ASSERT_TRUE(back < -0.015); /* a full retract step (~34 nm), not zero */
}

static void test_stream_depends_on_seed_and_electrode(void)
{
    actuator_params_t p;
    actuator_default_params(&p);
    actuator_t a2;
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_init(&act, &p, 1000.0, 21u, 0u));
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_init(&a2, &p, 1000.0, 21u, 0u));
    (void)actuator_command(&act, 0.0, 500u, 1, 2000.0);
    (void)actuator_command(&a2, 0.0, 500u, 1, 2000.0);
    /* the same steps, however the time is sliced */
    (void)actuator_advance_to(&act, 1.0);
    for (int i = 1; i <= 100; ++i) {
        (void)actuator_advance_to(&a2, 0.01 * i);
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, act.position_um, a2.position_um);
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_init(&a2, &p, 1000.0, 21u, 1u));
    (void)actuator_command(&a2, 0.0, 500u, 1, 2000.0);
    (void)actuator_advance_to(&a2, 1.0);
    TEST_ASSERT_TRUE(fabs(act.position_um - a2.position_um) > 1e-9);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_step_statistics_match_parameters);
    RUN_TEST(test_retract_steps_are_shorter);
    RUN_TEST(test_steps_follow_commanded_rate_and_max_rate);
    RUN_TEST(test_lower_end_stop_stalls_and_is_never_passed);
    RUN_TEST(test_upper_end_stop);
    RUN_TEST(test_no_backlash_on_reversal);
    RUN_TEST(test_stream_depends_on_seed_and_electrode);
    return UNITY_END();
}

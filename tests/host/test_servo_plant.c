/* Host test: the depth servo (firmware/app/md_servo.h) against the
 * simulator's own piezo and Hall models (host_sim/model, library md_sim) in
 * one process: calibration handed over as float32 coefficients (the wire
 * format of HALL_CALIB), readings at 100 Hz of simulated time, the actuator
 * stepping at the commanded rate. Proves ±2 µm convergence of the TRUE depth,
 * Δmax and window never exceeded, end stops and stalls handled. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "md_protocol.h"
#include "md_servo.h"
#include "model/actuator.h"
#include "model/hall_sensor.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define READ_PERIOD_S 0.01

typedef struct {
    actuator_t act;
    hall_sensor_t hall;
    double t_s;
    double next_read_s;
    uint8_t seq;
    uint32_t commands;
    uint32_t stop_cmd;     /* the command that ended stalled at an end stop */
    double max_um, min_um; /* true extremes during the current move */
} rig_t;

static rig_t rig;
static md_servo_t servo;

static void rig_init(double start_um, uint64_t seed)
{
    memset(&rig, 0, sizeof rig);
    actuator_params_t ap;
    hall_params_t hp;
    actuator_default_params(&ap);
    hall_default_params(&hp);
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_init(&rig.act, &ap, start_um, seed, 0u));
    TEST_ASSERT_EQUAL_INT(MD_OK, hall_init(&rig.hall, &hp, ap.travel_um, seed, 0u));
    md_servo_config_t cfg;
    md_servo_config_default(&cfg);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_init(&servo, &cfg));
    const hall_calibration_t *cal = &rig.hall.cal;
    const uint8_t count = (uint8_t)(cal->degree + 1u);
    for (uint8_t k = 0u; k < count; ++k) { /* CoeffValue is float32 on the bus */
        TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&servo, k, count, (double)(float)cal->coef[k]));
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&servo, MD_SERVO_CAL_INDEX_MID, count, (double)(float)cal->code_mid));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&servo, MD_SERVO_CAL_INDEX_HALF, count, (double)(float)cal->code_half));
    TEST_ASSERT_TRUE(servo.calibrated);
}

/* Lets simulated time pass to t_end: actuator steps, a reading every 10 ms. */
static void rig_run_to(double t_end)
{
    for (uint32_t guard = 0u; guard < 1000000u && rig.next_read_s <= t_end; ++guard) {
        (void)actuator_advance_to(&rig.act, rig.next_read_s);
        rig.max_um = fmax(rig.max_um, rig.act.position_um);
        rig.min_um = fmin(rig.min_um, rig.act.position_um);
        const uint32_t code = hall_read(&rig.hall, rig.act.position_um, rig.next_read_s);
        md_servo_reading(&servo, (uint16_t)code);
        rig.next_read_s += READ_PERIOD_S;
    }
    (void)actuator_advance_to(&rig.act, t_end);
    rig.max_um = fmax(rig.max_um, rig.act.position_um);
    rig.min_um = fmin(rig.min_um, rig.act.position_um);
    rig.t_s = t_end;
}

/* One ACT_CMD step as the driver node executes it: runs to the motion's end. */
static void rig_step(const md_servo_action_t *a)
{
    rig.seq++;
    rig.commands++;
    md_servo_sent(&servo, rig.seq);
    const int dir = (a->direction == MD_ACT_DIR_ADVANCE) ? 1 : -1;
    TEST_ASSERT_EQUAL_INT(MD_OK, actuator_command(&rig.act, rig.t_s, a->steps, dir, (double)a->rate_hz));
    const double rate = fmin((double)a->rate_hz, rig.act.p.max_rate_hz);
    rig_run_to(rig.t_s + (double)a->steps / rate + 1e-6);
    const actuator_status_t st = actuator_status(&rig.act);
    TEST_ASSERT_TRUE(st.state != ACTUATOR_MOVING);
    const uint8_t stops = (uint8_t)((st.at_upper_stop ? 1u : 0u) | (st.at_lower_stop ? 2u : 0u));
    if (st.state == ACTUATOR_STALLED && stops != 0u) {
        rig.stop_cmd = rig.commands;
    }
    md_servo_act_status(&servo, rig.seq, (st.state == ACTUATOR_STALLED) ? MD_ACT_STALLED : MD_ACT_IDLE, stops,
                        (uint16_t)st.steps_done);
}

static md_servo_result_t move_to(double target, double win_min, double win_max, double step_max)
{
    rig.max_um = rig.min_um = rig.act.position_um;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&servo, target, win_min, win_max, step_max));
    for (uint32_t guard = 0u; guard < 100u; ++guard) {
        const md_servo_action_t a = md_servo_next(&servo);
        switch (a.kind) {
        case MD_SERVO_A_FINISHED: return servo.result;
        case MD_SERVO_A_STEP: rig_step(&a); break;
        case MD_SERVO_A_WAIT: rig_run_to(rig.t_s + (double)a.wait_us * 1e-6); break;
        case MD_SERVO_A_NONE:
        default: TEST_FAIL_MESSAGE("servo waits for nothing"); break;
        }
    }
    TEST_FAIL_MESSAGE("move did not end");
    return MD_SERVO_R_NONE;
}

/* 40 moves of up to ±30 µm: the TRUE depth ends within ±2 µm every time. */
static void test_converges_on_the_simulator_models(void)
{
    rig_init(2000.0, 11u);
    double target = 2000.0;
    double worst = 0.0;
    uint32_t iters_max = 0u;
    uint32_t rng = 99u;
    for (int i = 0; i < 40; ++i) {
        rng = rng * 1664525u + 1013904223u;
        const double step = ((double)(rng >> 8) / 16777216.0 - 0.5) * 60.0;
        target += step;
        const uint32_t before = rig.commands;
        TEST_ASSERT_EQUAL_INT(MD_SERVO_R_CONVERGED, move_to(target, 0.0, 5000.0, 30.0));
        const double err = fabs(rig.act.position_um - target);
        worst = fmax(worst, err);
        iters_max = (rig.commands - before > iters_max) ? rig.commands - before : iters_max;
        TEST_ASSERT_DOUBLE_WITHIN(2.0, target, rig.act.position_um);
    }
    /* learned step lengths near the model's 40 nm advance and 34 nm retract */
    TEST_ASSERT_DOUBLE_WITHIN(0.006, 0.040, servo.step_um[0]);
    TEST_ASSERT_DOUBLE_WITHIN(0.006, 0.034, servo.step_um[1]);
    /* 30 um is ~750-880 steps: chunks of 10, 30, 120, 480 and the rest
     * (md_servo.h: MD_SERVO_PROBE_STEPS, MD_SERVO_CHUNK_GROWTH), then at
     * most one correction */
    TEST_ASSERT_LESS_OR_EQUAL_UINT(6u, iters_max);
    char line[160];
    (void)snprintf(line, sizeof line,
                   "40 moves on md_sim models: worst true error %.3f um, at most %u commands per move", worst,
                   (unsigned)iters_max);
    TEST_MESSAGE(line);
    TEST_ASSERT_LESS_THAN_DOUBLE(2.0, worst);
}

/* Δmax and the window: the true depth never passes the region while moving. */
static void test_region_never_exceeded(void)
{
    rig_init(1000.0, 5u);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_CONVERGED, move_to(1200.0, 0.0, 5000.0, 30.0));
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(1030.0 + 2.0, rig.max_um);
    TEST_ASSERT_DOUBLE_WITHIN(2.0, 1030.0, rig.act.position_um);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_CONVERGED, move_to(1060.0, 0.0, 1045.0, 30.0));
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(1045.0 + 2.0, rig.max_um);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_CONVERGED, move_to(1000.0, 1030.0, 1045.0, 30.0));
    TEST_ASSERT_GREATER_OR_EQUAL_DOUBLE(1030.0 - 2.0, rig.min_um);
}

/* The lower end stop (travel 5600 µm): stalled there, no retry. */
static void test_lower_end_stop(void)
{
    rig_init(5585.0, 3u);
    const uint32_t before = rig.commands;
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_END_STOP, move_to(5610.0, 0.0, 6000.0, 30.0));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 5600.0, rig.act.position_um);
    TEST_ASSERT_GREATER_THAN_UINT(before, rig.stop_cmd);
    TEST_ASSERT_EQUAL_UINT32(rig.stop_cmd, rig.commands); /* no retry after the stop */
    TEST_ASSERT_TRUE(actuator_status(&rig.act).at_lower_stop);
}

/* The upper end stop (depth 0). */
static void test_upper_end_stop(void)
{
    rig_init(12.0, 4u);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_END_STOP, move_to(-10.0, -100.0, 5000.0, 30.0));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 0.0, rig.act.position_um);
}

/* A slider that no longer grips (step length ~0): the Hall code does not
 * follow, the servo declares a stall after MD_SERVO_STALL_REPEATS commands
 * whose expected travel is judged (the 10- and 30-step chunks, 0.4 and
 * 1.2 um, are below MD_SERVO_STALL_MIN_UM). */
static void test_stall_seen_by_hall(void)
{
    rig_init(2000.0, 8u);
    rig.act.p.step_nm = 0.5;
    const uint32_t before = rig.commands;
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_STALL, move_to(2025.0, 0.0, 5000.0, 30.0));
    TEST_ASSERT_EQUAL_UINT32(before + 2u + MD_SERVO_STALL_REPEATS, rig.commands);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_converges_on_the_simulator_models);
    RUN_TEST(test_region_never_exceeded);
    RUN_TEST(test_lower_end_stop);
    RUN_TEST(test_upper_end_stop);
    RUN_TEST(test_stall_seen_by_hall);
    return UNITY_END();
}

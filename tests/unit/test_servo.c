/* Unit tests of the depth servo (firmware/app/md_servo.h) against a scripted
 * fake plant: a linear Hall characteristic with noise, a piezo whose steps
 * differ per direction and vary, optional stall / end stop / fault. */
#include <math.h>
#include <string.h>

#include "md_protocol.h"
#include "md_servo.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define CODE_MID 32768.0
#define CODES_PER_UM 5.0 /* 1 code = 0.2 um */
#define HALF 30000.0

typedef struct {
    double pos_um;
    double adv_um, ret_um; /* true mean step lengths */
    double cv;             /* step variation */
    double noise_codes;    /* reading noise, uniform +- */
    double lower_stop_um;  /* steps beyond stall at the stop */
    int stuck;             /* steps do nothing, reported idle */
    int frozen;            /* the sensor repeats frozen_code whatever the position */
    uint16_t frozen_code;
    double slip_back_um; /* > 0: every step moves this far AGAINST the command (runaway) */
    int fault;           /* every command answered with fault */
    double hall_scale;   /* reported / true displacement (1: an honest sensor) */
    uint32_t stop_cmd;   /* the command that ran into the lower stop (0: none) */
    uint32_t rng;
    double max_pos, min_pos; /* extremes reached */
    uint8_t seq;
    uint32_t commands;
} plant_t;

static double urand(plant_t *p) /* [-1, 1) */
{
    p->rng = p->rng * 1664525u + 1013904223u;
    return ((double)(p->rng >> 8) / 8388608.0) - 1.0;
}

static void plant_init(plant_t *p, double pos)
{
    memset(p, 0, sizeof *p);
    p->pos_um = pos;
    p->adv_um = 0.047;
    p->ret_um = 0.036;
    p->cv = 0.1;
    p->noise_codes = 1.0;
    p->lower_stop_um = 5600.0;
    p->rng = 12345u;
    p->max_pos = p->min_pos = pos;
    p->hall_scale = 1.0;
}

static uint16_t plant_code(plant_t *p)
{
    if (p->frozen) {
        return p->frozen_code;
    }
    const double c = CODE_MID + CODES_PER_UM * p->hall_scale * (p->pos_um - 2800.0) + p->noise_codes * urand(p);
    return (uint16_t)floor(c + 0.5);
}

/* Linear calibration: depth = 2800 + x * HALF / CODES_PER_UM, sent as the sensor does. */
static void calibrate(md_servo_t *s)
{
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(s, 0u, 2u, 2800.0));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(s, 1u, 2u, HALF / CODES_PER_UM));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(s, MD_SERVO_CAL_INDEX_MID, 2u, CODE_MID));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(s, MD_SERVO_CAL_INDEX_HALF, 2u, HALF));
}

/* Executes one step command; returns the final state reported. */
static void plant_step(plant_t *p, md_servo_t *s, const md_servo_action_t *a)
{
    p->seq++;
    p->commands++;
    md_servo_sent(s, p->seq);
    md_servo_act_status(s, p->seq, MD_ACT_MOVING, 0u, 0u); /* the acknowledgement: ignored */
    if (p->fault) {
        md_servo_act_status(s, p->seq, MD_ACT_FAULT, 0u, 0u);
        return;
    }
    const int dir = (a->direction == MD_ACT_DIR_ADVANCE) ? 1 : -1;
    uint16_t done = 0u;
    for (uint16_t i = 0u; i < a->steps; ++i) {
        if (p->stuck) {
            done++;
            continue;
        }
        double len = ((dir > 0) ? p->adv_um : p->ret_um) * (1.0 + p->cv * urand(p));
        if (p->slip_back_um > 0.0) {
            len = -p->slip_back_um;
        }
        const double next = p->pos_um + (double)dir * len;
        if (next >= p->lower_stop_um) {
            p->pos_um = p->lower_stop_um;
            p->stop_cmd = p->commands;
            md_servo_act_status(s, p->seq, MD_ACT_STALLED, 2u, done);
            return;
        }
        p->pos_um = next;
        p->max_pos = fmax(p->max_pos, p->pos_um);
        p->min_pos = fmin(p->min_pos, p->pos_um);
        done++;
    }
    md_servo_act_status(s, p->seq, MD_ACT_IDLE, 0u, done);
}

/* Runs a move to its end; returns the number of actions taken. */
static uint32_t run_move(plant_t *p, md_servo_t *s, int readings_per_wait)
{
    for (uint32_t guard = 0u; guard < 200u; ++guard) {
        const md_servo_action_t a = md_servo_next(s);
        if (a.kind == MD_SERVO_A_FINISHED) {
            return guard;
        }
        if (a.kind == MD_SERVO_A_STEP) {
            TEST_ASSERT_GREATER_THAN_UINT(0u, a.steps);
            TEST_ASSERT_EQUAL_UINT16(s->cfg.rate_hz, a.rate_hz);
            plant_step(p, s, &a);
        } else if (a.kind == MD_SERVO_A_WAIT) {
            TEST_ASSERT_EQUAL_UINT32(s->cfg.wait_us, a.wait_us);
            for (int i = 0; i < readings_per_wait; ++i) {
                md_servo_reading(s, plant_code(p));
            }
        } else {
            TEST_FAIL_MESSAGE("servo idle in the middle of a move");
        }
    }
    TEST_FAIL_MESSAGE("move did not end");
    return 0u;
}

static void servo_new(md_servo_t *s)
{
    md_servo_config_t cfg;
    md_servo_config_default(&cfg);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_init(s, &cfg));
}

static void test_config_checks(void)
{
    md_servo_config_t cfg;
    md_servo_config_default(&cfg);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_config_check(&cfg));
    cfg.tol_um = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_servo_config_check(&cfg));
    md_servo_config_default(&cfg);
    cfg.avg_n = (uint8_t)(MD_SERVO_AVG_MAX + 1u);
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_servo_config_check(&cfg));
    md_servo_config_default(&cfg);
    cfg.step_nm = NAN;
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_servo_config_check(&cfg));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_servo_init(NULL, &cfg));
}

static void test_calibration_staging(void)
{
    md_servo_t s;
    servo_new(&s);
    double d = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, md_servo_code_to_depth_um(&s, 32768u, &d));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, 0u, 2u, 2800.0));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, 1u, 2u, HALF / CODES_PER_UM));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, MD_SERVO_CAL_INDEX_MID, 2u, CODE_MID));
    TEST_ASSERT_FALSE(s.calibrated); /* code_half missing */
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_servo_calib(&s, MD_SERVO_CAL_INDEX_HALF, 2u, 0.0));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_servo_calib(&s, 2u, 2u, 1.0));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_servo_calib(&s, 0u, 2u, INFINITY));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_servo_calib(&s, 0u, (uint8_t)(MD_SERVO_CAL_MAX + 1u), 1.0));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, MD_SERVO_CAL_INDEX_HALF, 2u, HALF));
    TEST_ASSERT_TRUE(s.calibrated);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_code_to_depth_um(&s, (uint16_t)(CODE_MID + 50.0), &d));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 2810.0, d);
    /* a set with another count starts over once the next frame confirms the count */
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, 0u, 3u, 1.0));
    TEST_ASSERT_TRUE(s.calibrated);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, 1u, 3u, 1.0));
    TEST_ASSERT_FALSE(s.calibrated);
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, md_servo_code_to_depth_um(&s, 1u, &d));
}

/* A calibrated servo, a code 500 above code_mid and its depth. */
static uint16_t calibrated_with_depth(md_servo_t *s, double *depth_um)
{
    servo_new(s);
    calibrate(s);
    const uint16_t code = (uint16_t)(CODE_MID + 500.0);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_code_to_depth_um(s, code, depth_um));
    return code;
}

/* bus_corrupt in the fault campaign: one HALL_CALIB frame whose count byte was
 * corrupted (10 -> 14) dropped the calibration in use, and the next set,
 * staged without confirmation, carried a corrupted coefficient (2196.9 ->
 * 2452.9): the depth was 186 um off for two cycles. Another count now needs
 * the very next frame to carry it too. */
static void test_changed_count_needs_the_next_frame(void)
{
    md_servo_t s;
    double d0 = 0.0, d = 0.0;
    const uint16_t code = calibrated_with_depth(&s, &d0);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, 1u, 6u, 1.0)); /* stray count */
    TEST_ASSERT_TRUE(s.calibrated);
    TEST_ASSERT_EQUAL_UINT32(1u, s.stats.cal_unconfirmed);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, 0u, 2u, 2800.0)); /* the set in use goes on */
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, 1u, 6u, 1.0));    /* not the next frame: stray again */
    TEST_ASSERT_TRUE(s.calibrated);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_code_to_depth_um(&s, code, &d));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, d0, d);
    TEST_ASSERT_EQUAL_UINT32(2u, s.stats.cal_unconfirmed);
}

/* bus_corrupt in the fault campaign: one HALL_CALIB payload corrupted within
 * range (code_half 21964 -> 30156) shifted the depth by 550 um for a whole
 * calibration period. A changed value is now applied only when the next
 * repetition confirms it. */
static void test_changed_calibration_needs_a_confirming_repetition(void)
{
    md_servo_t s;
    double d0 = 0.0, d = 0.0;
    const uint16_t code = calibrated_with_depth(&s, &d0);
    /* one corrupted value: held back, the depth does not move */
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, MD_SERVO_CAL_INDEX_HALF, 2u, HALF * 1.37));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_code_to_depth_um(&s, code, &d));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, d0, d);
    TEST_ASSERT_EQUAL_UINT32(1u, s.stats.cal_unconfirmed);
    /* the next repetition carries the value in use: the stray one is forgotten */
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, MD_SERVO_CAL_INDEX_HALF, 2u, HALF));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, MD_SERVO_CAL_INDEX_HALF, 2u, HALF * 1.37));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_code_to_depth_um(&s, code, &d));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, d0, d);
    TEST_ASSERT_EQUAL_UINT32(0u, s.stats.cal_changes);
    /* a real recalibration repeats its value: applied on the second copy */
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, MD_SERVO_CAL_INDEX_HALF, 2u, HALF * 1.37));
    TEST_ASSERT_EQUAL_UINT32(1u, s.stats.cal_changes);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_code_to_depth_um(&s, code, &d));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 2800.0 + (500.0 / (HALF * 1.37)) * (HALF / CODES_PER_UM), d);
    /* the same for a coefficient */
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, 0u, 2u, 9999.0));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_code_to_depth_um(&s, code, &d0));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, d, d0);
    TEST_ASSERT_TRUE(s.calibrated);
}

static void test_cubic_calibration_horner(void)
{
    md_servo_t s;
    servo_new(&s);
    const double c[4] = {100.0, 2000.0, -30.0, 4.0};
    for (uint8_t k = 0u; k < 4u; ++k) {
        TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, k, 4u, c[k]));
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, MD_SERVO_CAL_INDEX_MID, 4u, 30000.0));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_calib(&s, MD_SERVO_CAL_INDEX_HALF, 4u, 20000.0));
    double d = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_code_to_depth_um(&s, 40000u, &d));
    const double x = 0.5;
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, c[0] + c[1] * x + c[2] * x * x + c[3] * x * x * x, d);
}

static void test_averaging(void)
{
    md_servo_t s;
    servo_new(&s);
    calibrate(&s);
    double d = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, md_servo_depth_um(&s, &d));
    /* the median of every kept reading: 4 far ones of 11 do not move it */
    for (int i = 0; i < 11; ++i) {
        md_servo_reading(&s, (uint16_t)(i < 4 ? 30000 : 32768 + (i % 2 == 0 ? 1 : -1)));
    }
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_depth_um(&s, &d));
    TEST_ASSERT_DOUBLE_WITHIN(0.2 + 1e-9, 2800.0, d);
    /* even count: the mean of the two middle ones */
    md_servo_clear_readings(&s);
    md_servo_reading(&s, 32768u);
    md_servo_reading(&s, 32770u);
    md_servo_reading(&s, 60000u);
    md_servo_reading(&s, 1000u);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_depth_um(&s, &d));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 2800.2, d);
}

static void test_converges_both_directions_and_learns(void)
{
    md_servo_t s;
    plant_t p;
    servo_new(&s);
    calibrate(&s);
    plant_init(&p, 1000.0);
    const double targets[] = {1020.0, 1005.0, 1033.0, 1010.0, 1040.0, 1012.0};
    for (size_t i = 0u; i < sizeof targets / sizeof targets[0]; ++i) {
        TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, targets[i], 0.0, 5000.0, 30.0));
        (void)run_move(&p, &s, 6);
        TEST_ASSERT_EQUAL_INT(MD_SERVO_R_CONVERGED, s.result);
        TEST_ASSERT_DOUBLE_WITHIN(2.0 + 0.5, targets[i], p.pos_um); /* tolerance + Hall noise of the mean */
        TEST_ASSERT_LESS_OR_EQUAL_UINT(8u, s.iter);
    }
    /* learned step lengths approach the plant's (advance 47 nm, retract 36 nm) */
    TEST_ASSERT_DOUBLE_WITHIN(0.006, 0.047, s.step_um[0]);
    TEST_ASSERT_DOUBLE_WITHIN(0.006, 0.036, s.step_um[1]);
    TEST_ASSERT_EQUAL_UINT32(6u, s.stats.converged);
}

static void test_region_clamps_step_max_and_window(void)
{
    md_servo_t s;
    plant_t p;
    servo_new(&s);
    calibrate(&s);
    plant_init(&p, 1000.0);
    /* Δmax: a request 100 um away is clamped to 30 um */
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1100.0, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_CONVERGED, s.result);
    TEST_ASSERT_DOUBLE_WITHIN(2.5, 1030.0, p.pos_um);
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(1000.0 + 30.0 + 0.5, p.max_pos);
    TEST_ASSERT_EQUAL_UINT32(1u, s.stats.clamped);
    /* window: deep end at 1040, request 1060 */
    p.max_pos = p.pos_um;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1060.0, 0.0, 1040.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(1040.0 + 0.5, p.max_pos);
    TEST_ASSERT_DOUBLE_WITHIN(2.5, 1040.0, p.pos_um);
    /* the shallow end */
    p.min_pos = p.pos_um;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1000.0, 1025.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_GREATER_OR_EQUAL_DOUBLE(1025.0 - 0.5, p.min_pos);
}

static void test_first_move_with_wrong_step_estimate_stays_in_region(void)
{
    md_servo_t s;
    plant_t p;
    md_servo_config_t cfg;
    md_servo_config_default(&cfg);
    cfg.step_nm = 40.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_init(&s, &cfg));
    calibrate(&s);
    plant_init(&p, 1000.0);
    p.adv_um = 0.058; /* 45 % longer than the servo believes */
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1030.0, 0.0, 1030.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(1030.0 + 0.5, p.max_pos);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_CONVERGED, s.result);
}

static void test_end_stop(void)
{
    md_servo_t s;
    plant_t p;
    servo_new(&s);
    calibrate(&s);
    plant_init(&p, 5590.0);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 5615.0, 0.0, 6000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_END_STOP, s.result);
    TEST_ASSERT_GREATER_THAN_UINT(0u, p.stop_cmd);
    TEST_ASSERT_EQUAL_UINT32(p.stop_cmd, p.commands); /* no retry after an end stop */
    TEST_ASSERT_FALSE(md_servo_busy(&s));
}

static void test_stall_without_report(void)
{
    md_servo_t s;
    plant_t p;
    servo_new(&s);
    calibrate(&s);
    plant_init(&p, 1000.0);
    p.stuck = 1;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1020.0, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_STALL, s.result);
    /* chunks of 10 and 30 steps (0.4, 1.2 um expected) are below
     * MD_SERVO_STALL_MIN_UM and not judged; the next ones are */
    TEST_ASSERT_EQUAL_UINT32(2u + MD_SERVO_STALL_REPEATS, p.commands);
}

/* A sensor that under-reports motion (0.3 of the true travel) is not a
 * stall, so the servo keeps commanding: the per-move budget, counted in
 * commanded steps, ends it within Δmax of configured steps. */
static void test_travel_budget_bounds_an_under_reporting_sensor(void)
{
    md_servo_t s;
    plant_t p;
    servo_new(&s);
    calibrate(&s);
    plant_init(&p, 1000.0);
    p.hall_scale = 0.3;
    p.noise_codes = 0.0;
    p.frozen_code = plant_code(&p); /* the code at 1000 um as this sensor reports it */
    const double d0 = 2800.0 + (double)(p.frozen_code - (uint16_t)CODE_MID) / CODES_PER_UM;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, d0 + 30.0, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_GREATER_THAN_UINT(0u, s.stats.budget_limited);
    TEST_ASSERT_LESS_OR_EQUAL_UINT(1000u, s.stats.steps); /* 30 um at 0.75 x 40 nm */
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(1000.0 + 1000.0 * 0.047 * 1.1 + 1e-9, p.max_pos);
}

/* A carrier that slides 2 um back on every step (50 step lengths: a lost
 * clamp, not a stick-slip stroke) is caught by the first, probe-sized
 * command: the excursion stays inside Δmax and motion latches off. */
static void test_gross_slip_caught_by_the_probe(void)
{
    md_servo_t s;
    plant_t p;
    servo_new(&s);
    calibrate(&s);
    plant_init(&p, 1000.0);
    p.slip_back_um = 2.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1025.0, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_RUNAWAY, s.result);
    TEST_ASSERT_EQUAL_UINT32(1u, p.commands);
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(MD_SERVO_PROBE_STEPS * 2.0 + 1e-9, 1000.0 - p.min_pos);
    TEST_ASSERT_TRUE(1000.0 - p.min_pos < 30.0);
    TEST_ASSERT_TRUE(md_servo_latched(&s));
}

static void test_fault_and_send_failure(void)
{
    md_servo_t s;
    plant_t p;
    servo_new(&s);
    calibrate(&s);
    plant_init(&p, 1000.0);
    p.fault = 1;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1020.0, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_FAULT, s.result);
    p.fault = 0;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1020.0, 0.0, 5000.0, 30.0));
    for (int i = 0; i < 6; ++i) {
        md_servo_reading(&s, plant_code(&p));
    }
    const md_servo_action_t a = md_servo_next(&s);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_A_STEP, a.kind);
    md_servo_send_failed(&s);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_FAULT, s.result);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_A_FINISHED, md_servo_next(&s).kind);
}

static void test_no_sensor_no_motion(void)
{
    md_servo_t s;
    plant_t p;
    servo_new(&s);
    plant_init(&p, 1000.0);
    /* no calibration: waits, then gives up without a step */
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1020.0, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_NO_SENSOR, s.result);
    TEST_ASSERT_EQUAL_UINT32(0u, p.commands);
    /* calibrated but silent sensor */
    calibrate(&s);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1020.0, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 0);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_NO_SENSOR, s.result);
    TEST_ASSERT_EQUAL_UINT32(0u, p.commands);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 1000.0, p.pos_um);
}

static void test_bounded_iterations(void)
{
    md_servo_t s;
    plant_t p;
    md_servo_config_t cfg;
    md_servo_config_default(&cfg);
    cfg.max_iter = 3u;
    cfg.tol_um = 0.001; /* readings are multiples of 0.2 um from 2800: never within 1 nm of x.1 */
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_init(&s, &cfg));
    calibrate(&s);
    plant_init(&p, 1000.0);
    p.noise_codes = 0.0;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1020.1, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_NOT_CONVERGED, s.result);
    TEST_ASSERT_LESS_OR_EQUAL_UINT(3u, p.commands);
}

static void test_abort_and_begin_rules(void)
{
    md_servo_t s;
    servo_new(&s);
    calibrate(&s);
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_servo_begin(&s, NAN, 0.0, 5000.0, 30.0));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_servo_begin(&s, 10.0, 50.0, 40.0, 30.0));
    TEST_ASSERT_EQUAL_INT(MD_E_ARG, md_servo_begin(&s, 10.0, 0.0, 40.0, 0.0));
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 10.0, 0.0, 40.0, 30.0));
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, md_servo_begin(&s, 10.0, 0.0, 40.0, 30.0));
    TEST_ASSERT_TRUE(md_servo_busy(&s));
    md_servo_abort(&s);
    TEST_ASSERT_FALSE(md_servo_busy(&s));
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_ABORTED, s.result);
    TEST_ASSERT_EQUAL_STRING("aborted", md_servo_result_name(s.result));
    /* a stale status of another command changes nothing */
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 10.0, 0.0, 40.0, 30.0));
    md_servo_act_status(&s, 77u, MD_ACT_STALLED, 1u, 0u);
    TEST_ASSERT_TRUE(md_servo_busy(&s));
}

/* Hazard H10 (docs/safety.md): a sensor that freezes while the drive moves.
 * The travel commanded in one move stays within Δmax whatever the sensor
 * says, and no move starts while the sensor still repeats its frozen code. */
static void test_frozen_sensor_bounds_travel_and_blocks_next_move(void)
{
    md_servo_t s;
    plant_t p;
    servo_new(&s);
    calibrate(&s);
    plant_init(&p, 1000.0);
    p.frozen_code = plant_code(&p);
    p.frozen = 1;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1020.0, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_STALL, s.result);
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE(1000.0 + 30.0 * (0.047 * 1.1 / 0.040) + 1e-9, p.max_pos);
    TEST_ASSERT_LESS_OR_EQUAL_UINT(750u, s.stats.steps); /* 30 um at the configured 40 nm */
    TEST_ASSERT_TRUE(s.hall_suspect);
    /* still frozen: the next move ends before any step */
    const uint32_t cmds = p.commands;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1040.0, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_NO_SENSOR, s.result);
    TEST_ASSERT_EQUAL_UINT32(cmds, p.commands);
    TEST_ASSERT_EQUAL_UINT32(1u, s.stats.suspect_refusals);
    /* the sensor comes back: moves resume, from the true depth */
    p.frozen = 0;
    const double here = p.pos_um;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, here + 10.0, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_CONVERGED, s.result);
    TEST_ASSERT_DOUBLE_WITHIN(2.5, here + 10.0, p.pos_um);
    TEST_ASSERT_FALSE(s.hall_suspect);
}

/* A drive that runs against its command (slip): measured twice from
 * independent readings, then motion is latched off until cleared. */
static void test_runaway_latches_motion_off(void)
{
    md_servo_t s;
    plant_t p;
    servo_new(&s);
    calibrate(&s);
    plant_init(&p, 1000.0);
    p.slip_back_um = 0.1;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1020.0, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_RUNAWAY, s.result);
    TEST_ASSERT_EQUAL_STRING("runaway", md_servo_result_name(s.result));
    /* 0.1 um back per step: the 10-step probe (1 um) is within the noise
     * slack, the 30-step chunk (3 um) is not; nothing after it */
    TEST_ASSERT_EQUAL_UINT32(2u, p.commands);
    TEST_ASSERT_LESS_OR_EQUAL_DOUBLE((10.0 + 30.0) * 0.1 + 1e-9, 1000.0 - p.min_pos);
    TEST_ASSERT_EQUAL_UINT32(1u, s.stats.rechecks);
    TEST_ASSERT_TRUE(md_servo_latched(&s));
    TEST_ASSERT_EQUAL_INT(MD_E_STATE, md_servo_begin(&s, 1020.0, 0.0, 5000.0, 30.0));
    TEST_ASSERT_EQUAL_UINT32(1u, s.stats.latched_refusals);
    TEST_ASSERT_FALSE(md_servo_busy(&s));
    /* the operator clears it; a healthy drive moves again */
    p.slip_back_um = 0.0;
    md_servo_clear_fault(&s);
    TEST_ASSERT_FALSE(md_servo_latched(&s));
    const double here = p.pos_um;
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, here + 10.0, 0.0, 5000.0, 30.0));
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_CONVERGED, s.result);
}

/* Hall glitches: one implausible measurement is measured again, not
 * believed, and does not latch anything. */
static void test_single_glitch_is_measured_again(void)
{
    md_servo_t s;
    plant_t p;
    servo_new(&s);
    calibrate(&s);
    plant_init(&p, 1000.0);
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1020.0, 0.0, 5000.0, 30.0));
    int glitched = 0;
    for (uint32_t guard = 0u; guard < 200u; ++guard) {
        const md_servo_action_t a = md_servo_next(&s);
        if (a.kind == MD_SERVO_A_FINISHED) {
            break;
        }
        if (a.kind == MD_SERVO_A_STEP) {
            plant_step(&p, &s, &a);
        } else if (a.kind == MD_SERVO_A_WAIT) {
            const int glitch_now = (p.commands == 1u && !glitched);
            for (int i = 0; i < 6; ++i) { /* after the first command: 4 of 6 readings +2000 codes */
                const uint16_t c = plant_code(&p);
                md_servo_reading(&s, (uint16_t)(glitch_now && i < 4 ? c + 2000u : c));
            }
            glitched |= glitch_now;
        }
    }
    TEST_ASSERT_TRUE(glitched);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_CONVERGED, s.result);
    TEST_ASSERT_DOUBLE_WITHIN(2.5, 1020.0, p.pos_um);
    TEST_ASSERT_EQUAL_UINT32(1u, s.stats.rechecks);
    TEST_ASSERT_FALSE(md_servo_latched(&s));
    /* and a glitched start depth is measured again too (the carrier has not moved) */
    TEST_ASSERT_EQUAL_INT(MD_OK, md_servo_begin(&s, 1030.0, 0.0, 5000.0, 30.0));
    for (int i = 0; i < 6; ++i) {
        md_servo_reading(&s, (uint16_t)(plant_code(&p) + 2000u));
    }
    TEST_ASSERT_EQUAL_INT(MD_SERVO_A_WAIT, md_servo_next(&s).kind);
    TEST_ASSERT_EQUAL_UINT32(2u, s.stats.rechecks);
    (void)run_move(&p, &s, 6);
    TEST_ASSERT_EQUAL_INT(MD_SERVO_R_CONVERGED, s.result);
    TEST_ASSERT_DOUBLE_WITHIN(2.5, 1030.0, p.pos_um);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_config_checks);
    RUN_TEST(test_calibration_staging);
    RUN_TEST(test_cubic_calibration_horner);
    RUN_TEST(test_changed_calibration_needs_a_confirming_repetition);
    RUN_TEST(test_changed_count_needs_the_next_frame);
    RUN_TEST(test_averaging);
    RUN_TEST(test_converges_both_directions_and_learns);
    RUN_TEST(test_region_clamps_step_max_and_window);
    RUN_TEST(test_first_move_with_wrong_step_estimate_stays_in_region);
    RUN_TEST(test_end_stop);
    RUN_TEST(test_travel_budget_bounds_an_under_reporting_sensor);
    RUN_TEST(test_gross_slip_caught_by_the_probe);
    RUN_TEST(test_stall_without_report);
    RUN_TEST(test_fault_and_send_failure);
    RUN_TEST(test_no_sensor_no_motion);
    RUN_TEST(test_bounded_iterations);
    RUN_TEST(test_abort_and_begin_rules);
    RUN_TEST(test_frozen_sensor_bounds_travel_and_blocks_next_move);
    RUN_TEST(test_runaway_latches_motion_off);
    RUN_TEST(test_single_glitch_is_measured_again);
    return UNITY_END();
}

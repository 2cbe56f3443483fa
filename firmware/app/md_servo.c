/// @file md_servo.c
/// Depth servo: calibration, averaging, bounded iterative positioning with
/// learned step lengths. See md_servo.h.
#include "md_servo.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

#include "md_protocol.h"

#define CAL_BIT_MID 0x40000000u  /* bit 30 */
#define CAL_BIT_HALF 0x80000000u /* bit 31 */
#define US_PER_MS 1000u
#define STEP_LEARN_GAIN 0.5   /* weight of a new observation of the step length */
#define STEP_LEARN_MIN_UM 4.0 /* a move shorter than this says little about the step (Hall noise) */
#define STEP_EST_RANGE 4.0    /* the estimate stays within [nominal / 4, nominal * 4] */
#define NM_PER_UM 1000.0

void md_servo_config_default(md_servo_config_t *cfg)
{
    cfg->tol_um = 2.0;
    cfg->max_iter = 8u;
    cfg->avg_n = 5u;
    cfg->step_nm = 40.0;
    cfg->rate_hz = 1000u;
    cfg->wait_us = 60u * US_PER_MS;
    cfg->max_waits = 4u;
}

md_status_t md_servo_config_check(const md_servo_config_t *cfg)
{
    if (cfg == NULL || !(cfg->tol_um > 0.0) || !isfinite(cfg->tol_um) || cfg->max_iter < 1u ||
        cfg->max_iter > MD_SERVO_ITER_MAX || cfg->avg_n < 1u || cfg->avg_n > MD_SERVO_AVG_MAX ||
        !(cfg->step_nm > 0.0) || !isfinite(cfg->step_nm) || cfg->rate_hz < 1u || cfg->wait_us == 0u ||
        cfg->max_waits < 1u) {
        return MD_E_ARG;
    }
    return MD_OK;
}

md_status_t md_servo_init(md_servo_t *s, const md_servo_config_t *cfg)
{
    if (s == NULL || md_servo_config_check(cfg) != MD_OK) {
        return MD_E_ARG;
    }
    memset(s, 0, sizeof *s);
    s->cfg = *cfg;
    s->step_um[0] = cfg->step_nm / NM_PER_UM;
    s->step_um[1] = cfg->step_nm / NM_PER_UM;
    return MD_OK;
}

md_status_t md_servo_configure(md_servo_t *s, const md_servo_config_t *cfg)
{
    if (s == NULL || md_servo_config_check(cfg) != MD_OK) {
        return MD_E_ARG;
    }
    s->cfg = *cfg;
    return MD_OK;
}

/* ------------------------------------------------------------------ */
/* Calibration and readings                                            */
/* ------------------------------------------------------------------ */

/* The value in use at slot k (coefficient k, or MD_SERVO_CAL_MAX for code_mid,
 * MD_SERVO_CAL_MAX + 1 for code_half). */
static double *calib_slot(md_servo_t *s, size_t k)
{
    if (k == MD_SERVO_CAL_MAX) {
        return &s->cal_mid;
    }
    return (k == MD_SERVO_CAL_MAX + 1u) ? &s->cal_half : &s->cal_coef[k];
}

/* The bit of slot k in cal_have and cal_pend_have (layout of calib_slot). */
static uint32_t calib_bit(size_t k)
{
    uint32_t bit = CAL_BIT_HALF;
    if (k == MD_SERVO_CAL_MAX) {
        bit = CAL_BIT_MID;
    } else if (k < MD_SERVO_CAL_MAX) {
        const uint32_t shift = (uint32_t)k & 0x0Fu; /* k < 16: the mask changes nothing */
        bit = (uint32_t)1u << shift;
    } else {
        /* k == MD_SERVO_CAL_MAX + 1: code_half */
    }
    return bit;
}

/* A repetition of slot k while calibrated: equal to the value in use, it
 * clears a pending change; different, it becomes pending, and is applied
 * when the next repetition confirms it. */
static void calib_confirm(md_servo_t *s, size_t k, double value)
{
    const uint32_t bit = calib_bit(k);
    double *in_use = calib_slot(s, k);
    if (!(value < *in_use) && !(value > *in_use)) {
        s->cal_pend_have &= ~bit;
        return;
    }
    if (((s->cal_pend_have & bit) != 0u) && !(value < s->cal_pend[k]) && !(value > s->cal_pend[k])) {
        *in_use = value; /* seen twice in a row: a real change */
        s->cal_pend_have &= ~bit;
        s->stats.cal_changes++;
        return;
    }
    s->cal_pend[k] = value;
    s->cal_pend_have |= bit;
    s->stats.cal_unconfirmed++;
}

md_status_t md_servo_calib(md_servo_t *s, uint8_t index, uint8_t count, double value)
{
    if (s == NULL || !isfinite(value) || count == 0u || count > MD_SERVO_CAL_MAX) {
        return MD_E_ARG;
    }
    const bool mid = index == MD_SERVO_CAL_INDEX_MID;
    const bool half = index == MD_SERVO_CAL_INDEX_HALF;
    if ((!mid && !half && index >= count) || (half && !(value > 0.0))) {
        return MD_E_ARG;
    }
    if (s->calibrated && (count != s->cal_count) && (count != s->cal_pend_count)) {
        s->cal_pend_count = count; /* once: a corrupted count would reset to an unconfirmed set */
        s->stats.cal_unconfirmed++;
        return MD_OK;
    }
    if (count == s->cal_count) {
        s->cal_pend_count = 0u;
    } else {
        s->cal_count = count; /* a new set (confirmed while calibrated): start collecting again */
        s->cal_pend_count = 0u;
        s->cal_have = 0u;
        s->cal_pend_have = 0u;
        s->calibrated = false;
    }
    if (s->calibrated) {
        calib_confirm(s, mid ? MD_SERVO_CAL_MAX : (half ? MD_SERVO_CAL_MAX + 1u : (size_t)index), value);
        return MD_OK;
    }
    if (mid) {
        s->cal_mid = value;
        s->cal_have |= CAL_BIT_MID;
    } else if (half) {
        s->cal_half = value;
        s->cal_have |= CAL_BIT_HALF;
    } else {
        s->cal_coef[index] = value;
        s->cal_have |= 1u << index;
    }
    const uint32_t all = ((1u << count) - 1u) | CAL_BIT_MID | CAL_BIT_HALF;
    if ((s->cal_have & all) == all) {
        s->calibrated = true;
    }
    return MD_OK;
}

md_status_t md_servo_code_to_depth_um(const md_servo_t *s, uint16_t code, double *depth_um)
{
    if (s == NULL || depth_um == NULL) {
        return MD_E_ARG;
    }
    if (!s->calibrated) {
        return MD_E_STATE;
    }
    const double x = ((double)code - s->cal_mid) / s->cal_half; /* normalised code (HALL_CALIB comment) */
    double acc = 0.0;
    for (size_t k = s->cal_count; k-- > 0u;) {
        acc = acc * x + s->cal_coef[k]; /* Horner: depth = Σ c_k x^k */
    }
    if (!isfinite(acc)) {
        return MD_E_NUMERIC;
    }
    *depth_um = acc;
    return MD_OK;
}

void md_servo_reading(md_servo_t *s, uint16_t code)
{
    if (s == NULL) {
        return;
    }
    s->code[s->code_head] = code;
    s->code_head = (uint8_t)((s->code_head + 1u) % MD_SERVO_AVG_MAX);
    if (s->code_count < MD_SERVO_AVG_MAX) {
        s->code_count++;
    }
    if (s->fresh < UINT8_MAX) {
        s->fresh++;
    }
}

void md_servo_clear_readings(md_servo_t *s)
{
    if (s != NULL) {
        s->code_count = 0u;
        s->fresh = 0u;
    }
}

md_status_t md_servo_depth_um(const md_servo_t *s, double *depth_um)
{
    if (s == NULL || depth_um == NULL) {
        return MD_E_ARG;
    }
    if (!s->calibrated || s->code_count == 0u) {
        return MD_E_STATE;
    }
    double d[MD_SERVO_AVG_MAX] = {0.0};
    const size_t n = s->code_count;
    for (size_t i = 0u; i < n; ++i) {
        const size_t slot = (s->code_head + MD_SERVO_AVG_MAX - 1u - i) % MD_SERVO_AVG_MAX; /* newest first */
        const md_status_t st = md_servo_code_to_depth_um(s, s->code[slot], &d[i]);
        if (st != MD_OK) {
            return st;
        }
    }
    for (size_t i = 1u; i < n; ++i) { /* insertion sort: n <= MD_SERVO_AVG_MAX */
        const double v = d[i];
        size_t j = i;
        while (j > 0u && d[j - 1u] > v) {
            d[j] = d[j - 1u];
            --j;
        }
        d[j] = v;
    }
    *depth_um = ((n % 2u) != 0u) ? d[n / 2u] : 0.5 * (d[n / 2u - 1u] + d[n / 2u]);
    return MD_OK;
}

/* ------------------------------------------------------------------ */
/* Moves                                                               */
/* ------------------------------------------------------------------ */

md_status_t md_servo_begin(md_servo_t *s, double target_um, double win_min_um, double win_max_um, double move_max_um)
{
    if (s == NULL || !isfinite(target_um) || !isfinite(win_min_um) || !isfinite(win_max_um) ||
        !(win_min_um < win_max_um) || !(move_max_um > 0.0) || !isfinite(move_max_um)) {
        return MD_E_ARG;
    }
    if (s->phase != MD_SERVO_IDLE) {
        return MD_E_STATE;
    }
    if (s->motion_latched) {
        s->stats.latched_refusals++;
        return MD_E_STATE;
    }
    s->target_um = target_um;
    s->win_min_um = win_min_um;
    s->win_max_um = win_max_um;
    s->move_max_um = move_max_um;
    s->have_start = false;
    s->iter = 0u;
    s->waits = 0u;
    s->no_motion = 0u;
    s->cmd_travel_um[0] = 0.0;
    s->cmd_travel_um[1] = 0.0;
    s->move_steps = 0u;
    s->rechecking = false;
    s->result = MD_SERVO_R_NONE;
    s->phase = MD_SERVO_MEASURE;
    s->stats.moves++;
    md_servo_clear_readings(s); /* the move starts from readings taken after this call */
    return MD_OK;
}

static void finish(md_servo_t *s, md_servo_result_t r)
{
    s->phase = MD_SERVO_IDLE;
    s->result = r;
    switch (r) {
    case MD_SERVO_R_CONVERGED: s->stats.converged++; break;
    case MD_SERVO_R_NOT_CONVERGED: s->stats.not_converged++; break;
    case MD_SERVO_R_STALL: s->stats.stalls++; break;
    case MD_SERVO_R_END_STOP: s->stats.end_stops++; break;
    case MD_SERVO_R_FAULT: s->stats.faults++; break;
    case MD_SERVO_R_NO_SENSOR: s->stats.no_sensor++; break;
    case MD_SERVO_R_OUT_OF_REGION: s->stats.out_of_region++; break;
    case MD_SERVO_R_ABORTED: s->stats.aborted++; break;
    case MD_SERVO_R_RUNAWAY:
        s->stats.runaways++;
        s->motion_latched = true;
        break;
    case MD_SERVO_R_NONE:
    default: break;
    }
}

void md_servo_sent(md_servo_t *s, uint8_t seq)
{
    if (s != NULL && s->phase == MD_SERVO_MOVING) {
        s->cmd_seq = seq;
    }
}

void md_servo_send_failed(md_servo_t *s)
{
    if (s != NULL && s->phase != MD_SERVO_IDLE) {
        finish(s, MD_SERVO_R_FAULT);
    }
}

void md_servo_abort(md_servo_t *s)
{
    if (s != NULL && s->phase != MD_SERVO_IDLE) {
        finish(s, MD_SERVO_R_ABORTED);
    }
}

void md_servo_clear_fault(md_servo_t *s)
{
    if (s != NULL) {
        s->motion_latched = false;
        s->hall_suspect = false;
    }
}

bool md_servo_latched(const md_servo_t *s)
{
    return s != NULL && s->motion_latched;
}

bool md_servo_busy(const md_servo_t *s)
{
    return s != NULL && s->phase != MD_SERVO_IDLE;
}

void md_servo_act_status(md_servo_t *s, uint8_t cmd_seq, uint8_t state, uint8_t end_stops, uint16_t steps_done)
{
    if (s == NULL || s->phase != MD_SERVO_MOVING || cmd_seq != s->cmd_seq || state == (uint8_t)MD_ACT_MOVING) {
        return; /* not the final status of our command */
    }
    if (state == (uint8_t)MD_ACT_FAULT) {
        finish(s, MD_SERVO_R_FAULT);
        return;
    }
    if (state == (uint8_t)MD_ACT_STALLED) {
        finish(s, (end_stops != 0u) ? MD_SERVO_R_END_STOP : MD_SERVO_R_STALL);
        return;
    }
    s->cmd_steps = steps_done; /* what was really executed, for the learning */
    s->phase = MD_SERVO_MEASURE;
    s->waits = 0u;
    md_servo_clear_readings(s); /* readings taken during the motion are history */
}

/* True if every kept reading has the same code (stored in *code). */
static bool all_codes_equal(const md_servo_t *s, uint16_t *code)
{
    if (s->code_count == 0u) {
        return false;
    }
    const uint16_t first = s->code[(s->code_head + MD_SERVO_AVG_MAX - 1u) % MD_SERVO_AVG_MAX];
    for (size_t i = 1u; i < s->code_count; ++i) {
        if (s->code[(s->code_head + MD_SERVO_AVG_MAX - 1u - i) % MD_SERVO_AVG_MAX] != first) {
            return false;
        }
    }
    *code = first;
    return true;
}

/* Learns the step length of the direction just used from the Hall
 * displacement; judges "no motion" (a stall the driver did not report). */
static bool learn_step(md_servo_t *s, double moved_um)
{
    const size_t k = (s->cmd_dir == MD_ACT_DIR_ADVANCE) ? 0u : 1u;
    const double sign = (k == 0u) ? 1.0 : -1.0;
    const double expected_um = (double)s->cmd_steps * s->step_um[k];
    const double along_um = sign * moved_um;
    if (expected_um >= MD_SERVO_STALL_MIN_UM && along_um < MD_SERVO_STALL_FRACTION * expected_um) {
        s->no_motion++;
        if (s->no_motion < MD_SERVO_STALL_REPEATS) {
            return false;
        }
        s->hall_suspect = all_codes_equal(s, &s->stuck_code); /* a frozen sensor, not a stuck drive */
        return true;
    }
    s->no_motion = 0u;
    if (s->cmd_steps > 0u && along_um >= STEP_LEARN_MIN_UM) {
        const double nominal = s->cfg.step_nm / NM_PER_UM;
        double est = s->step_um[k] + STEP_LEARN_GAIN * (along_um / (double)s->cmd_steps - s->step_um[k]);
        est = fmax(nominal / STEP_EST_RANGE, fmin(nominal * STEP_EST_RANGE, est));
        s->step_um[k] = est;
    }
    return false;
}

/* First measurement of a move: fixes d0 and the allowed region, clamps the goal. */
static void set_region(md_servo_t *s, double d0)
{
    s->have_start = true;
    s->start_um = d0;
    s->region_lo_um = fmax(s->win_min_um, d0 - s->move_max_um);
    s->region_hi_um = fmin(s->win_max_um, d0 + s->move_max_um);
    s->goal_um = fmax(s->region_lo_um, fmin(s->region_hi_um, s->target_um));
    if (s->goal_um < s->target_um || s->goal_um > s->target_um) {
        s->stats.clamped++;
    }
}

/* Travel of one step in direction k as the per-move budget counts it: the
 * learned length, but never less than MD_SERVO_STEP_FLOOR of the configured
 * one (the learning cannot talk the budget into many more steps). */
static double worst_step_um(const md_servo_t *s, size_t k)
{
    return fmax(s->step_um[k], MD_SERVO_STEP_FLOOR * s->cfg.step_nm / NM_PER_UM);
}

/* Steps toward the goal, planned so that even steps MD_SERVO_STEP_SAFETY
 * times longer than learned stay inside the region, so that the travel
 * commanded in this move (worst-case steps, whatever the sensor reports)
 * stays within the distance from d0 to the region's edge, and no more than
 * the next chunk (probe, then growth) of the move. 0 if none fits. */
static uint16_t plan_steps(md_servo_t *s, double depth, size_t k)
{
    const double err = fabs(s->goal_um - depth);
    const double edge = (k == 0u) ? (s->region_hi_um - depth) : (depth - s->region_lo_um);
    const double reach = (k == 0u) ? (s->region_hi_um - s->start_um) : (s->start_um - s->region_lo_um);
    const double n_goal = floor(err / s->step_um[k] + 0.5);
    const double n_edge = floor(fmax(0.0, edge) / (s->step_um[k] * MD_SERVO_STEP_SAFETY));
    const double n_budget = floor(fmax(0.0, reach - s->cmd_travel_um[k]) / worst_step_um(s, k));
    double n = fmin(n_goal, n_edge);
    if (n_budget < n) {
        n = n_budget;
        s->stats.budget_limited++;
    }
    const double chunk = fmax((double)MD_SERVO_PROBE_STEPS, (double)MD_SERVO_CHUNK_GROWTH * (double)s->move_steps);
    if (chunk < n) {
        n = chunk; /* measured before the next, larger chunk goes out */
        s->stats.chunk_limited++;
    }
    n = fmin(n, (double)UINT16_MAX);
    return (n >= 1.0) ? (uint16_t)n : 0u;
}

/* After a command: is the measured displacement plausible? Against the
 * command beyond noise, or beyond MD_SERVO_STEP_SAFETY x the commanded
 * travel, it is not (a glitch, or a slipping / running-away actuator). */
static bool displacement_plausible(const md_servo_t *s, double moved_um)
{
    const bool advance = s->cmd_dir == (uint8_t)MD_ACT_DIR_ADVANCE;
    const size_t k = advance ? (size_t)0 : (size_t)1;
    const double along_um = advance ? moved_um : -moved_um;
    const double slack_um = s->cfg.tol_um + MD_SERVO_NOISE_UM;
    const double most_um = (double)s->cmd_steps * worst_step_um(s, k) * MD_SERVO_STEP_SAFETY;
    return along_um >= -slack_um && along_um <= most_um + slack_um;
}

static md_servo_action_t wait_action(md_servo_t *s)
{
    md_servo_action_t a = {MD_SERVO_A_WAIT, 0u, 0u, 0u, 0u};
    s->waits++;
    a.wait_us = s->cfg.wait_us;
    return a;
}

static md_servo_action_t finished_action(md_servo_t *s, md_servo_result_t r)
{
    md_servo_action_t a = {MD_SERVO_A_FINISHED, 0u, 0u, 0u, 0u};
    finish(s, r);
    return a;
}

/* Checks a fresh measurement against what the sensor and the last command
 * allow. MD_SERVO_R_NONE: go on; otherwise the move ends with that result,
 * except that an implausible displacement is measured once more
 * (*remeasure). */
static md_servo_result_t check_measurement(md_servo_t *s, double depth, bool *remeasure)
{
    *remeasure = false;
    if (!s->have_start) {
        uint16_t code = 0u;
        if (s->hall_suspect && all_codes_equal(s, &code) && code == s->stuck_code) {
            s->stats.suspect_refusals++;
            return MD_SERVO_R_NO_SENSOR; /* still frozen: moving blind is not allowed */
        }
        s->hall_suspect = false;
        if (s->have_depth && fabs(depth - s->depth_um) > s->cfg.tol_um + MD_SERVO_NOISE_UM && !s->rechecking) {
            s->rechecking = true; /* the carrier has not moved since the last move: d0 once more */
            s->stats.rechecks++;
            *remeasure = true;
            return MD_SERVO_R_NONE;
        }
        s->rechecking = false;
        set_region(s, depth);
        return MD_SERVO_R_NONE;
    }
    if (!displacement_plausible(s, depth - s->before_um)) {
        if (!s->rechecking) {
            s->rechecking = true;
            s->stats.rechecks++;
            *remeasure = true;
            return MD_SERVO_R_NONE;
        }
        return MD_SERVO_R_RUNAWAY; /* confirmed by independent readings */
    }
    s->rechecking = false;
    return learn_step(s, depth - s->before_um) ? MD_SERVO_R_STALL : MD_SERVO_R_NONE;
}

static md_servo_action_t measure(md_servo_t *s)
{
    md_servo_action_t a = {MD_SERVO_A_NONE, 0u, 0u, 0u, 0u};
    double depth = 0.0;
    if (!s->calibrated || s->fresh < s->cfg.avg_n || md_servo_depth_um(s, &depth) != MD_OK) {
        return (s->waits >= s->cfg.max_waits) ? finished_action(s, MD_SERVO_R_NO_SENSOR) : wait_action(s);
    }
    s->waits = 0u;
    bool remeasure = false;
    md_servo_result_t r = check_measurement(s, depth, &remeasure);
    if (remeasure) {
        md_servo_clear_readings(s); /* independent readings, not the same ones again */
        return wait_action(s);
    }
    if (r != MD_SERVO_R_NONE) {
        return finished_action(s, r);
    }
    s->depth_um = depth;
    s->have_depth = true;
    const double tol = s->cfg.tol_um;
    if (depth < s->region_lo_um - tol || depth > s->region_hi_um + tol) {
        r = MD_SERVO_R_OUT_OF_REGION;
    } else if (fabs(s->goal_um - depth) <= tol) {
        r = MD_SERVO_R_CONVERGED;
    } else if (s->iter >= s->cfg.max_iter) {
        r = MD_SERVO_R_NOT_CONVERGED;
    }
    const size_t k = (s->goal_um > depth) ? 0u : 1u;
    const uint16_t n = (r == MD_SERVO_R_NONE) ? plan_steps(s, depth, k) : 0u;
    if (r == MD_SERVO_R_NONE && n == 0u) {
        r = MD_SERVO_R_NOT_CONVERGED; /* no step fits safely: as close as it gets */
    }
    if (r != MD_SERVO_R_NONE) {
        return finished_action(s, r);
    }
    s->iter++;
    s->before_um = depth;
    s->cmd_dir = (k == 0u) ? (uint8_t)MD_ACT_DIR_ADVANCE : (uint8_t)MD_ACT_DIR_RETRACT;
    s->cmd_steps = n;
    s->cmd_travel_um[k] += (double)n * worst_step_um(s, k);
    s->move_steps += n;
    s->phase = MD_SERVO_MOVING;
    s->stats.commands++;
    s->stats.steps += n;
    a.kind = MD_SERVO_A_STEP;
    a.direction = s->cmd_dir;
    a.steps = n;
    a.rate_hz = s->cfg.rate_hz;
    return a;
}

md_servo_action_t md_servo_next(md_servo_t *s)
{
    md_servo_action_t a = {MD_SERVO_A_NONE, 0u, 0u, 0u, 0u};
    if (s == NULL) {
        return a;
    }
    switch (s->phase) {
    case MD_SERVO_MEASURE: return measure(s);
    case MD_SERVO_MOVING: return a; /* waiting for the final ACT_STATUS */
    case MD_SERVO_IDLE:
    default: a.kind = (s->result != MD_SERVO_R_NONE) ? MD_SERVO_A_FINISHED : MD_SERVO_A_NONE; return a;
    }
}

const char *md_servo_result_name(md_servo_result_t r)
{
    static const char *const NAMES[] = {"none",  "converged", "not_converged", "stall",   "end_stop",
                                        "fault", "no_sensor", "out_of_region", "aborted", "runaway"};
    return ((size_t)r < sizeof NAMES / sizeof NAMES[0]) ? NAMES[r] : "?";
}

#include "model/actuator.h"

#include <math.h>
#include <string.h>

void actuator_default_params(actuator_params_t *p)
{
    p->step_nm = 40.0;
    p->step_cv = 0.10;
    p->retract_ratio = 0.85;
    p->miss_prob = 0.002;
    p->slip_prob = 0.0005;
    p->slip_nm = 120.0;
    p->max_rate_hz = 2000.0;
    p->travel_um = 5600.0;
}

md_status_t actuator_params_check(const actuator_params_t *p)
{
    const bool ok = p->step_nm > 0.0 && p->step_nm <= 10000.0 && p->step_cv >= 0.0 && p->step_cv <= 1.0 &&
                    p->retract_ratio > 0.0 && p->retract_ratio <= 2.0 && p->miss_prob >= 0.0 && p->slip_prob >= 0.0 &&
                    p->miss_prob + p->slip_prob <= 1.0 && p->slip_nm >= 0.0 && p->max_rate_hz > 0.0 &&
                    p->travel_um > 0.0;
    return ok ? MD_OK : MD_E_ARG;
}

md_status_t actuator_init(actuator_t *a, const actuator_params_t *p, double start_um, uint64_t seed, uint32_t electrode)
{
    if (a == NULL || p == NULL || actuator_params_check(p) != MD_OK || !isfinite(start_um)) {
        return MD_E_ARG;
    }
    memset(a, 0, sizeof *a);
    a->p = *p;
    sim_rng_init(&a->rng, seed, SIM_RNG_ACTUATOR, electrode, 0u);
    a->position_um = fmin(fmax(start_um, 0.0), p->travel_um);
    a->t_last_step_s = -1.0;
    a->st.state = ACTUATOR_IDLE;
    a->st.direction = 1;
    a->st.at_upper_stop = a->position_um <= 0.0;
    a->st.at_lower_stop = a->position_um >= p->travel_um;
    sim_model_faults_default(&a->faults);
    return MD_OK;
}

void actuator_set_faults(actuator_t *a, const sim_model_faults_t *f, uint64_t seed, uint32_t electrode)
{
    a->faults = *f;
    sim_rng_init(&a->fault_rng, seed, SIM_RNG_FAULT, electrode, 1u);
}

md_status_t actuator_command(actuator_t *a, double t_now_s, uint32_t count, int direction, double rate_hz)
{
    if (a == NULL || (direction != 1 && direction != -1) || !(rate_hz > 0.0) || !isfinite(t_now_s)) {
        return MD_E_ARG;
    }
    if (rate_hz > a->p.max_rate_hz) {
        rate_hz = a->p.max_rate_hz;
        a->st.rate_clamped_count++;
    }
    a->t_cmd_s = fmax(t_now_s, a->t_s);
    a->rate_hz = rate_hz;
    a->st.direction = direction;
    a->st.steps_requested = count;
    a->st.steps_done = 0u;
    a->st.state = (count > 0u) ? ACTUATOR_MOVING : ACTUATOR_IDLE;
    return MD_OK;
}

/* One stick-slip step: its signed length in um. */
static double actuator_step_length_um(actuator_t *a, int dir)
{
    const double u = sim_rng_uniform(&a->rng);
    const double g = sim_rng_normal(&a->rng); /* drawn every step: the stream stays aligned */
    if (u < a->p.miss_prob) {
        a->missed_steps++;
        return 0.0;
    }
    if (u < a->p.miss_prob + a->p.slip_prob) {
        a->slips++;
        return -(double)dir * a->p.slip_nm * 1e-3;
    }
    const double mean_nm = (dir > 0) ? a->p.step_nm : a->p.step_nm * a->p.retract_ratio;
    const double len_nm = fmax(0.0, mean_nm * (1.0 + a->p.step_cv * g));
    return (double)dir * len_nm * 1e-3;
}

/* Applies one step; false when it hit an end stop (the command ends). */
static bool actuator_apply_step(actuator_t *a, double t_step)
{
    const int dir = a->st.direction;
    const sim_step_fault_t fault = sim_fault_actuator_step(&a->faults, &a->fault_rng, t_step);
    if (fault == SIM_STEP_STALL) {
        a->t_last_step_s = t_step;
        a->st.state = ACTUATOR_STALLED;
        a->st.stall_count++;
        a->fault_stalls++;
        return false;
    }
    double len_um = actuator_step_length_um(a, dir); /* drawn anyway: healthy stream aligned */
    if (fault == SIM_STEP_SLIP) {
        a->fault_slips++;
        len_um = -(double)dir * a->faults.act_slip_um;
    }
    const double next = a->position_um + len_um;
    a->t_last_step_s = t_step;
    if (next >= a->p.travel_um || next <= 0.0) {
        const bool lower = next >= a->p.travel_um;
        a->position_um = lower ? a->p.travel_um : 0.0;
        a->st.at_lower_stop = lower;
        a->st.at_upper_stop = !lower;
        if ((lower && dir > 0) || (!lower && dir < 0)) {
            a->st.state = ACTUATOR_STALLED;
            a->st.stall_count++;
            return false;
        }
        /* a slip against the commanded direction onto the far stop: the
         * carrier rests there, the command goes on */
        a->st.steps_done++;
        return true;
    }
    a->position_um = next;
    a->st.at_lower_stop = false;
    a->st.at_upper_stop = false;
    a->st.steps_done++;
    return true;
}

double actuator_advance_to(actuator_t *a, double t_s)
{
    const double start = a->position_um;
    if (!(t_s > a->t_s)) {
        return 0.0;
    }
    while (a->st.state == ACTUATOR_MOVING) {
        /* bounded: at most steps_requested iterations per command */
        const double t_step = a->t_cmd_s + (double)a->st.steps_done / a->rate_hz;
        if (t_step > t_s) {
            break;
        }
        if (!actuator_apply_step(a, t_step)) {
            break;
        }
        if (a->st.steps_done >= a->st.steps_requested) {
            a->st.state = ACTUATOR_IDLE;
        }
    }
    a->t_s = t_s;
    return a->position_um - start;
}

actuator_status_t actuator_status(const actuator_t *a)
{
    return a->st;
}

uint32_t actuator_steps_for(const actuator_params_t *p, double distance_um)
{
    const double mean_nm = (distance_um >= 0.0) ? p->step_nm : p->step_nm * p->retract_ratio;
    const double n = floor(fabs(distance_um) * 1000.0 / mean_nm + 0.5);
    return (n > 4.0e9) ? 4000000000u : (uint32_t)n;
}

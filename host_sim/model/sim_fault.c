#include "model/sim_fault.h"

#include <math.h>
#include <string.h>

#include "model/signal.h"

_Static_assert(SIM_FAULT_STORM_TMPL_MAX >= SIM_SHORT_WAVE_MAX, "storm template holds the artifact template");

void sim_model_faults_default(sim_model_faults_t *f)
{
    memset(f, 0, sizeof *f); /* every window [0, 0): empty */
    f->hall_glitch_prob = 0.1;
    f->hall_glitch_codes = 2000.0;
    f->act_slip_prob = 0.2;
    f->act_slip_um = 2.0;
    f->storm_rate_hz = 20.0;
    f->storm_amp_uv = 3000.0;
}

static bool window_set(const sim_window_t *w)
{
    return w->to_s > w->from_s;
}

bool sim_model_faults_any(const sim_model_faults_t *f)
{
    return window_set(&f->hall_glitch) || window_set(&f->hall_stuck) || window_set(&f->act_stall) ||
           window_set(&f->act_slip) || window_set(&f->adc_saturation) || window_set(&f->artifact_storm);
}

void sim_hall_fault_init(sim_hall_fault_state_t *s, uint64_t seed, uint32_t electrode)
{
    memset(s, 0, sizeof *s);
    sim_rng_init(&s->rng, seed, SIM_RNG_FAULT, electrode, 0u);
}

uint32_t sim_fault_hall_apply(const sim_model_faults_t *f, sim_hall_fault_state_t *s, double t_s, uint32_t code,
                              uint32_t code_max)
{
    if (sim_window_active(&f->hall_stuck, t_s) && s->have_last) {
        s->stuck_reads++;
        return s->last_code; /* frozen: the sensor repeats its last good value */
    }
    s->last_code = code;
    s->have_last = true;
    if (!sim_window_active(&f->hall_glitch, t_s)) {
        return code;
    }
    const double u = sim_rng_uniform(&s->rng);
    const double sign = (sim_rng_uniform(&s->rng) < 0.5) ? -1.0 : 1.0;
    if (!(u < f->hall_glitch_prob)) {
        return code;
    }
    s->glitches++;
    const double g = fmin(fmax((double)code + sign * f->hall_glitch_codes, 0.0), (double)code_max);
    return (uint32_t)g;
}

sim_step_fault_t sim_fault_actuator_step(const sim_model_faults_t *f, sim_rng_t *rng, double t_s)
{
    if (sim_window_active(&f->act_stall, t_s)) {
        return SIM_STEP_STALL;
    }
    if (sim_window_active(&f->act_slip, t_s) && sim_rng_uniform(rng) < f->act_slip_prob) {
        return SIM_STEP_SLIP;
    }
    return SIM_STEP_NORMAL;
}

void sim_signal_fault_init(sim_signal_fault_state_t *s, uint64_t seed, uint32_t electrode, double fs)
{
    memset(s, 0, sizeof *s);
    sim_rng_init(&s->rng, seed, SIM_RNG_FAULT, electrode, 2u);
    double t[SIM_SHORT_WAVE_MAX];
    s->tmpl_len = sim_artifact_template(fs, t);
    memcpy(s->tmpl, t, (size_t)s->tmpl_len * sizeof t[0]);
    s->next_event_s = -1.0;
}

/* Starts the storm transients due up to sample `c` (Poisson at storm_rate_hz). */
static void storm_events(const sim_model_faults_t *f, sim_signal_fault_state_t *s, uint64_t c, double fs)
{
    const double t = (double)c / fs;
    if (s->next_event_s < 0.0 || s->next_event_s < f->artifact_storm.from_s) {
        s->next_event_s = f->artifact_storm.from_s + sim_rng_exponential(&s->rng, 1.0 / f->storm_rate_hz);
    }
    for (uint32_t guard = 0u; guard < 64u && s->next_event_s <= t; ++guard) {
        if (sim_window_active(&f->artifact_storm, s->next_event_s)) {
            if (s->n_active < SIM_FAULT_STORM_ACTIVE_MAX) {
                const double sign = (sim_rng_uniform(&s->rng) < 0.5) ? -1.0 : 1.0;
                s->start[s->n_active] = c;
                s->amp[s->n_active] = sign * f->storm_amp_uv * (0.6 + 0.8 * sim_rng_uniform(&s->rng));
                s->n_active++;
                s->storm_events++;
            } else {
                s->storm_dropped++;
            }
        }
        s->next_event_s += sim_rng_exponential(&s->rng, 1.0 / f->storm_rate_hz);
    }
}

static double storm_sample(sim_signal_fault_state_t *s, uint64_t c)
{
    double v = 0.0;
    uint32_t kept = 0u;
    for (uint32_t i = 0u; i < s->n_active; ++i) {
        const uint64_t k = c - s->start[i];
        if (k < s->tmpl_len) {
            v += s->amp[i] * s->tmpl[k];
            s->start[kept] = s->start[i];
            s->amp[kept] = s->amp[i];
            kept++;
        }
    }
    s->n_active = kept;
    return v;
}

void sim_fault_signal_apply(const sim_model_faults_t *f, sim_signal_fault_state_t *s, uint64_t first, double fs,
                            double gain_uv, int16_t *x, size_t n)
{
    const bool storm = window_set(&f->artifact_storm) && f->storm_rate_hz > 0.0;
    const bool sat = window_set(&f->adc_saturation);
    if ((!storm && !sat) || !(fs > 0.0) || !(gain_uv > 0.0)) {
        return;
    }
    for (size_t i = 0u; i < n; ++i) {
        const uint64_t c = first + i;
        const double t = (double)c / fs;
        if (storm && (s->n_active > 0u || sim_window_active(&f->artifact_storm, t) ||
                      (s->next_event_s >= 0.0 && s->next_event_s <= t))) {
            storm_events(f, s, c, fs);
            const double v = (double)x[i] + storm_sample(s, c) / gain_uv;
            x[i] = (int16_t)fmin(fmax(floor(v + 0.5), -32768.0), 32767.0);
        }
        if (sat && sim_window_active(&f->adc_saturation, t)) {
            x[i] = (x[i] >= 0) ? (int16_t)32767 : (int16_t)-32768;
            s->saturated_samples++;
        }
    }
}

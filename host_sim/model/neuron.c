#include "model/neuron.h"

#include <math.h>
#include <string.h>

void neuron_default_model_params(neuron_model_params_t *p)
{
    p->falloff_um = 30.0;
    p->falloff_exp = 2.0;
    p->range_um = 150.0;
    p->damage_um = 12.0;
    p->shape_mix = 0.6;
    p->window_pre_ms = 0.6;
    p->window_post_ms = 1.4;
}

void neuron_default_params(neuron_params_t *p)
{
    memset(p, 0, sizeof *p);
    p->x_um = 20.0;
    p->y_um = 0.0;
    p->depth_um = 0.0;
    p->amp_uv = 400.0;
    p->shape = NEURON_BIPHASIC;
    p->trough_ms = 0.10;
    p->repol_ms = 0.25;
    p->repol_ratio = 0.35;
    p->rate_hz = 8.0;
    p->refractory_ms = 2.0;
    p->burst_prob = 0.05;
    p->burst_spikes = 3u;
    p->burst_isi_ms = 4.0;
    p->burst_amp_decay = 0.85;
    p->amp_jitter = 0.05;
}

md_status_t neuron_model_params_check(const neuron_model_params_t *p, double sample_rate_hz)
{
    const double len = floor(p->window_pre_ms * sample_rate_hz / 1000.0 + 0.5) +
                       floor(p->window_post_ms * sample_rate_hz / 1000.0 + 0.5) + 1.0;
    const bool ok = p->falloff_um > 0.0 && p->falloff_exp >= 1.0 && p->falloff_exp <= 4.0 && p->range_um > 0.0 &&
                    p->damage_um >= 0.0 && p->shape_mix >= 0.0 && p->shape_mix <= 1.0 && p->window_pre_ms > 0.0 &&
                    p->window_post_ms > 0.0 && len <= (double)SIM_WAVE_MAX;
    return ok ? MD_OK : MD_E_ARG;
}

/* Mean of the exponential part of the event ISI that makes the long-run rate
 * rate_hz: per event 1 + p*E spikes over refractory + m + p*E*burst_isi. */
static double neuron_mean_gap_s(const neuron_params_t *p)
{
    const double extra = p->burst_prob * 0.5 * (1.0 + (double)p->burst_spikes);
    return (1.0 + extra) / p->rate_hz - p->refractory_ms * 1e-3 - extra * p->burst_isi_ms * 1e-3;
}

md_status_t neuron_params_check(const neuron_params_t *p, const char **why)
{
    const char *w = NULL;
    if (!(p->amp_uv >= 0.0 && p->amp_uv <= 5000.0))
        w = "amp_uv must be in [0, 5000]";
    else if (!(p->trough_ms >= 0.02 && p->trough_ms <= 1.0))
        w = "trough_ms must be in [0.02, 1]";
    else if (!(p->repol_ms >= 0.02 && p->repol_ms <= 2.0))
        w = "repol_ms must be in [0.02, 2]";
    else if (!(p->repol_ratio >= 0.0 && p->repol_ratio <= 2.0))
        w = "repol_ratio must be in [0, 2]";
    else if (!(p->rate_hz > 0.0 && p->rate_hz <= 200.0))
        w = "rate_hz must be in (0, 200]";
    else if (!(p->refractory_ms >= 0.5 && p->refractory_ms <= 20.0))
        w = "refractory_ms must be in [0.5, 20]";
    else if (!(p->burst_prob >= 0.0 && p->burst_prob <= 1.0))
        w = "burst_prob must be in [0, 1]";
    else if (p->burst_spikes < 1u || p->burst_spikes > 10u)
        w = "burst_spikes must be in [1, 10]";
    else if (!(p->burst_isi_ms * 0.8 >= p->refractory_ms))
        w = "burst_isi_ms * 0.8 must be >= refractory_ms";
    else if (!(p->burst_amp_decay > 0.0 && p->burst_amp_decay <= 1.0))
        w = "burst_amp_decay must be in (0, 1]";
    else if (!(p->amp_jitter >= 0.0 && p->amp_jitter <= 0.5))
        w = "amp_jitter must be in [0, 0.5]";
    else if (!(p->active_mean_s >= 0.0 && p->silent_mean_s >= 0.0))
        w = "active_mean_s/silent_mean_s must be >= 0";
    else if (!(p->appear_s >= 0.0 && p->disappear_s >= 0.0))
        w = "appear_s/disappear_s must be >= 0";
    else if (!isfinite(p->x_um) || !isfinite(p->y_um) || !isfinite(p->depth_um))
        w = "position must be finite";
    else if (!isfinite(p->drift_um_per_min) || !(p->drift_start_s >= 0.0))
        w = "bad drift";
    else if (!(neuron_mean_gap_s(p) > 0.0))
        w = "rate_hz too high for refractory_ms and burst settings";
    if (why != NULL) {
        *why = w;
    }
    return (w == NULL) ? MD_OK : MD_E_ARG;
}

static double gauss(double u, double mu, double sigma)
{
    const double z = (u - mu) / sigma;
    return exp(-0.5 * z * z);
}

static void normalise_ptp(double *w, uint32_t n)
{
    double lo = w[0], hi = w[0];
    for (uint32_t i = 1u; i < n; ++i) {
        lo = fmin(lo, w[i]);
        hi = fmax(hi, w[i]);
    }
    const double ptp = hi - lo;
    for (uint32_t i = 0u; i < n && ptp > 0.0; ++i) {
        w[i] /= ptp;
    }
}

static void neuron_build_bases(neuron_t *n, double fs)
{
    const neuron_params_t *p = &n->p;
    const double st = p->trough_ms, sr = p->repol_ms, rho = p->repol_ratio;
    const double delta = 1.5 * st + sr;
    for (uint32_t i = 0u; i < n->wave_len; ++i) {
        const double u = ((double)i - (double)n->wave_pre) * 1000.0 / fs;
        double near = -gauss(u, 0.0, st) + rho * gauss(u, delta, sr);
        if (p->shape == NEURON_TRIPHASIC) {
            near += 0.3 * gauss(u, -2.0 * st, 0.8 * st);
        }
        n->basis_near[i] = near;
        n->basis_far[i] = -gauss(u, 0.05, 1.8 * st) + 1.8 * rho * gauss(u, 1.2 * delta, 1.4 * sr);
    }
    normalise_ptp(n->basis_near, n->wave_len);
    normalise_ptp(n->basis_far, n->wave_len);
}

/* Draws the next spike after the one at t_last (see the header for the law). */
static void neuron_schedule(neuron_t *n, double t_last)
{
    const neuron_params_t *p = &n->p;
    double t, amp = 1.0;
    if (n->burst_left > 0u) {
        t = t_last + p->burst_isi_ms * 1e-3 * (0.8 + 0.4 * sim_rng_uniform(&n->rng));
        n->burst_left--;
        n->burst_index++;
        amp = pow(p->burst_amp_decay, (double)n->burst_index);
    } else {
        t = t_last + p->refractory_ms * 1e-3 + sim_rng_exponential(&n->rng, n->mean_gap_s);
        n->burst_index = 0u;
        if (sim_rng_uniform(&n->rng) < p->burst_prob) {
            n->burst_left = 1u + (uint32_t)floor(sim_rng_uniform(&n->rng) * (double)p->burst_spikes);
        }
    }
    const bool intermittent = p->active_mean_s > 0.0 && p->silent_mean_s > 0.0;
    for (uint32_t guard = 0u; intermittent && t > n->active_until_s && guard < 100000u; ++guard) {
        const double resume = n->active_until_s + sim_rng_exponential(&n->rng, p->silent_mean_s);
        n->active_until_s = resume + sim_rng_exponential(&n->rng, p->active_mean_s);
        t = resume + sim_rng_exponential(&n->rng, n->mean_gap_s);
        n->burst_left = 0u;
        n->burst_index = 0u;
        amp = 1.0;
    }
    if ((p->disappear_s > 0.0 && t >= p->disappear_s) || !n->alive) {
        t = INFINITY;
    }
    n->next_s = t;
    n->next_amp = fmax(0.1, amp * (1.0 + p->amp_jitter * sim_rng_normal(&n->rng)));
}

md_status_t neuron_init(neuron_t *n, const neuron_params_t *p, const neuron_model_params_t *m, uint32_t id,
                        double sample_rate_hz, uint64_t seed, uint32_t electrode)
{
    if (n == NULL || p == NULL || m == NULL || neuron_params_check(p, NULL) != MD_OK ||
        neuron_model_params_check(m, sample_rate_hz) != MD_OK) {
        return MD_E_ARG;
    }
    memset(n, 0, sizeof *n);
    n->p = *p;
    n->id = id;
    n->alive = true;
    n->died_s = -1.0;
    sim_rng_init(&n->rng, seed, SIM_RNG_NEURON, electrode, id);
    n->wave_pre = (uint32_t)floor(m->window_pre_ms * sample_rate_hz / 1000.0 + 0.5);
    n->wave_len = n->wave_pre + (uint32_t)floor(m->window_post_ms * sample_rate_hz / 1000.0 + 0.5) + 1u;
    neuron_build_bases(n, sample_rate_hz);
    n->mean_gap_s = neuron_mean_gap_s(p);
    n->active_until_s = INFINITY;
    if (p->active_mean_s > 0.0 && p->silent_mean_s > 0.0) {
        n->active_until_s = p->appear_s + sim_rng_exponential(&n->rng, p->active_mean_s);
    }
    neuron_schedule(n, p->appear_s - p->refractory_ms * 1e-3);
    return MD_OK;
}

double neuron_depth_um(const neuron_t *n, double t_s)
{
    const double dt = t_s - n->p.drift_start_s;
    return n->p.depth_um + ((dt > 0.0) ? n->p.drift_um_per_min * dt / 60.0 : 0.0);
}

double neuron_amplitude_uv(const neuron_model_params_t *m, const neuron_t *n, double d_um)
{
    return n->p.amp_uv / (1.0 + pow(fabs(d_um) / m->falloff_um, m->falloff_exp));
}

void neuron_template(const neuron_model_params_t *m, const neuron_t *n, double r_um, double dz_um, double *out)
{
    const double d = hypot(r_um, dz_um);
    const double w = m->shape_mix * 0.5 * (1.0 + sin(atan2(dz_um, r_um)));
    const double a = neuron_amplitude_uv(m, n, d);
    double lo = 0.0, hi = 0.0;
    for (uint32_t i = 0u; i < n->wave_len; ++i) {
        out[i] = (1.0 - w) * n->basis_near[i] + w * n->basis_far[i];
        lo = fmin(lo, out[i]);
        hi = fmax(hi, out[i]);
    }
    const double k = (hi - lo > 0.0) ? a / (hi - lo) : 0.0;
    for (uint32_t i = 0u; i < n->wave_len; ++i) {
        out[i] *= k;
    }
}

void neuron_pop_spike(neuron_t *n)
{
    if (isfinite(n->next_s)) {
        neuron_schedule(n, n->next_s);
    }
}

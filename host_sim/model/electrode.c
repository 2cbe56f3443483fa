#include "model/electrode.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define RANDOM_NEURON_ID0 100u /* random neurons are numbered from here */

void sim_random_neurons_default(sim_random_neurons_t *r)
{
    r->count = 0u;
    r->depth_min_um = 500.0;
    r->depth_max_um = 5000.0;
    r->radius_um = 120.0;
    r->amp_min_uv = 150.0;
    r->amp_max_uv = 500.0;
    r->rate_min_hz = 1.0;
    r->rate_max_hz = 30.0;
}

void sim_electrode_default_config(sim_electrode_config_t *c)
{
    memset(c, 0, sizeof *c);
    actuator_default_params(&c->actuator);
    hall_default_params(&c->hall);
    tissue_default_params(&c->tissue);
    signal_default_params(&c->signal);
    neuron_default_model_params(&c->neuron_model);
    c->start_um = 1000.0;
    sim_random_neurons_default(&c->random_neurons);
    sim_model_faults_default(&c->faults);
}

static md_status_t place_random_neurons(sim_electrode_t *el, uint64_t seed)
{
    const sim_random_neurons_t *r = &el->cfg.random_neurons;
    if (r->count > SIM_MAX_NEURONS - el->cfg.n_neurons) {
        return MD_E_CAPACITY;
    }
    sim_rng_t rng;
    sim_rng_init(&rng, seed, SIM_RNG_PLACEMENT, el->index, 0u);
    for (uint32_t i = 0u; i < r->count; ++i) {
        neuron_params_t p;
        neuron_default_params(&p);
        const double rad = r->radius_um * sqrt(sim_rng_uniform(&rng));
        const double ang = 6.283185307179586 * sim_rng_uniform(&rng);
        p.x_um = rad * cos(ang);
        p.y_um = rad * sin(ang);
        p.depth_um = r->depth_min_um + (r->depth_max_um - r->depth_min_um) * sim_rng_uniform(&rng);
        p.amp_uv = r->amp_min_uv + (r->amp_max_uv - r->amp_min_uv) * sim_rng_uniform(&rng);
        p.rate_hz = r->rate_min_hz * pow(r->rate_max_hz / r->rate_min_hz, sim_rng_uniform(&rng));
        p.shape = (sim_rng_uniform(&rng) < 0.5) ? NEURON_BIPHASIC : NEURON_TRIPHASIC;
        p.trough_ms = 0.07 + 0.08 * sim_rng_uniform(&rng);
        p.repol_ms = 0.18 + 0.22 * sim_rng_uniform(&rng);
        const md_status_t st = neuron_init(&el->neurons[el->n_neurons], &p, &el->cfg.neuron_model,
                                           RANDOM_NEURON_ID0 + i, el->fs, seed, el->index);
        if (st != MD_OK) {
            return st;
        }
        el->n_neurons++;
    }
    return MD_OK;
}

static void electrode_die(sim_electrode_t *el, uint32_t k, double t_s, double d_um)
{
    neuron_t *n = &el->neurons[k];
    n->alive = false;
    n->died_s = t_s;
    n->next_s = INFINITY;
    if (el->truth != NULL) {
        (void)fprintf(el->truth,
                      "{\"type\":\"death\",\"electrode\":%" PRIu32 ",\"neuron\":%" PRIu32
                      ",\"t_s\":%.6f,\"distance_um\":%.3f}\n",
                      el->index, n->id, t_s, d_um);
    }
}

/* Slow models to sample s: actuator, tissue, geometry, damage, templates. */
static void electrode_update_model(sim_electrode_t *el, uint64_t s, bool render)
{
    const double t = (double)s / el->fs;
    const double moved = actuator_advance_to(&el->act, t);
    if (el->act.t_last_step_s > el->motion_t0_s) {
        el->motion_t0_s = el->act.t_last_step_s;
    }
    tissue_advance_to(&el->tissue, t, moved);
    const double tip = el->act.position_um;
    const double disp = tissue_displacement_um(&el->tissue);
    const neuron_model_params_t *m = &el->cfg.neuron_model;
    for (uint32_t k = 0u; k < el->n_neurons; ++k) {
        neuron_t *n = &el->neurons[k];
        el->in_range[k] = false;
        if (!n->alive) {
            continue;
        }
        const double dz = tip - (neuron_depth_um(n, t) + disp);
        const double r = hypot(n->p.x_um, n->p.y_um);
        /* closest approach on the path since the last update (tip passes the soma level) */
        const double dz_min = (dz * el->prev_dz[k] <= 0.0) ? 0.0 : fmin(fabs(dz), fabs(el->prev_dz[k]));
        el->prev_dz[k] = dz;
        el->closest_um[k] = fmin(el->closest_um[k], hypot(r, dz_min));
        if (hypot(r, dz_min) < m->damage_um) {
            electrode_die(el, k, t, hypot(r, dz_min));
            continue;
        }
        el->in_range[k] = hypot(r, dz) <= m->range_um;
        if (el->in_range[k] && render) {
            neuron_template(m, n, r, dz, el->tmpl[k]);
            el->tmpl_ptp[k] = neuron_amplitude_uv(m, n, hypot(r, dz));
        }
    }
    el->model_sample = s;
}

md_status_t sim_electrode_init(sim_electrode_t *el, const sim_electrode_config_t *cfg, uint64_t seed, uint32_t index)
{
    if (el == NULL || cfg == NULL || cfg->n_neurons > SIM_MAX_NEURONS || signal_params_check(&cfg->signal) != MD_OK ||
        neuron_model_params_check(&cfg->neuron_model, cfg->signal.sample_rate_hz) != MD_OK) {
        return MD_E_ARG;
    }
    memset(el, 0, sizeof *el);
    el->index = index;
    el->cfg = *cfg;
    el->fs = cfg->signal.sample_rate_hz;
    md_status_t st = actuator_init(&el->act, &cfg->actuator, cfg->start_um, seed, index);
    if (st == MD_OK) st = hall_init(&el->hall, &cfg->hall, cfg->actuator.travel_um, seed, index);
    if (st == MD_OK) st = tissue_init(&el->tissue, &cfg->tissue);
    for (uint32_t k = 0u; st == MD_OK && k < cfg->n_neurons; ++k) {
        st = neuron_init(&el->neurons[k], &cfg->neurons[k], &cfg->neuron_model, k, el->fs, seed, index);
        el->n_neurons = k + 1u;
    }
    if (st == MD_OK) st = place_random_neurons(el, seed);
    if (st != MD_OK) {
        return st;
    }
    sim_rng_init(&el->noise_rng, seed, SIM_RNG_NOISE, index, 0u);
    sim_rng_init(&el->mua_rng, seed, SIM_RNG_MUA, index, 0u);
    sim_rng_init(&el->art_rng, seed, SIM_RNG_ARTIFACT, index, 0u);
    sim_noise_filter_init(&el->filt, &cfg->signal);
    el->bg_rms_uv = sim_background_rms_uv(&cfg->signal);
    double energy = 0.0;
    el->mua_len = sim_mua_template(el->fs, el->mua_tmpl, &energy);
    el->art_len = sim_artifact_template(el->fs, el->art_tmpl);
    const signal_params_t *sp = &cfg->signal;
    el->mua_next_s = (sp->mua_rate_hz > 0.0) ? sim_rng_exponential(&el->mua_rng, 1.0 / sp->mua_rate_hz)
                                             : (double)INFINITY;
    el->art_next_s = (sp->large_artifact_rate_hz > 0.0)
                         ? sim_rng_exponential(&el->art_rng, 1.0 / sp->large_artifact_rate_hz)
                         : (double)INFINITY;
    el->motion_t0_s = -1.0e9;
    actuator_set_faults(&el->act, &cfg->faults, seed, index);
    sim_hall_fault_init(&el->hall_fault, seed, index);
    sim_signal_fault_init(&el->sig_fault, seed, index, el->fs);
    const double disp = tissue_displacement_um(&el->tissue);
    for (uint32_t k = 0u; k < el->n_neurons; ++k) {
        el->prev_dz[k] = el->act.position_um - (neuron_depth_um(&el->neurons[k], 0.0) + disp);
        el->closest_um[k] = INFINITY;
    }
    electrode_update_model(el, 0u, false);
    return MD_OK;
}

double sim_electrode_time_s(const sim_electrode_t *el)
{
    return (double)el->cursor / el->fs;
}

double sim_electrode_tip_um(const sim_electrode_t *el)
{
    return el->act.position_um;
}

static void push_pending(sim_electrode_t *el, uint64_t sample, int32_t id, double amp)
{
    if (el->n_pending >= SIM_PENDING_MAX) {
        el->gt_dropped++;
        return;
    }
    el->pending[el->n_pending].sample = sample;
    el->pending[el->n_pending].neuron_id = id;
    el->pending[el->n_pending].amp_uv = amp;
    el->n_pending++;
}

static void add_wave(sim_electrode_t *el, uint64_t start, const double *w, uint32_t len, double gain)
{
    for (uint32_t i = 0u; i < len; ++i) {
        el->acc[(start + i) & (SIM_ACC_LEN - 1u)] += gain * w[i];
    }
}

/* Renders every event whose window starts in [a, b). Earlier ones (time
 * that was not recorded) are consumed without rendering. */
static void electrode_render(sim_electrode_t *el, uint64_t a, uint64_t b)
{
    for (uint32_t k = 0u; k < el->n_neurons; ++k) {
        neuron_t *n = &el->neurons[k];
        for (uint32_t guard = 0u; isfinite(n->next_s) && guard < 1000000u; ++guard) {
            const int64_t trough = (int64_t)floor(n->next_s * el->fs);
            const int64_t start = trough - (int64_t)n->wave_pre;
            if (start >= (int64_t)b) {
                break;
            }
            if (start >= (int64_t)a && el->in_range[k]) {
                add_wave(el, (uint64_t)start, el->tmpl[k], n->wave_len, n->next_amp);
                push_pending(el, (uint64_t)trough, (int32_t)n->id, el->tmpl_ptp[k] * n->next_amp);
            }
            neuron_pop_spike(n);
        }
    }
    const signal_params_t *sp = &el->cfg.signal;
    for (uint32_t guard = 0u; el->mua_next_s * el->fs < (double)b && guard < 10000000u; ++guard) {
        const double start = floor(el->mua_next_s * el->fs);
        const double amp = sp->mua_amp_uv * (0.5 + sim_rng_uniform(&el->mua_rng));
        if (start >= (double)a) {
            add_wave(el, (uint64_t)start, el->mua_tmpl, el->mua_len, amp);
        }
        el->mua_next_s += sim_rng_exponential(&el->mua_rng, 1.0 / sp->mua_rate_hz);
    }
    for (uint32_t guard = 0u; el->art_next_s * el->fs < (double)b && guard < 1000000u; ++guard) {
        const double start = floor(el->art_next_s * el->fs);
        const double amp = sp->large_artifact_uv * (0.6 + 0.8 * sim_rng_uniform(&el->art_rng));
        if (start >= (double)a) {
            add_wave(el, (uint64_t)start, el->art_tmpl, el->art_len, amp);
            push_pending(el, (uint64_t)start + el->art_len / 4u, -1, amp);
        }
        el->art_next_s += sim_rng_exponential(&el->art_rng, 1.0 / sp->large_artifact_rate_hz);
    }
}

/* Noise + rendered events + motion ringing -> ADC codes, samples [c, c+m). */
static void electrode_synth(sim_electrode_t *el, int16_t *out, uint64_t c, size_t m)
{
    const signal_params_t *sp = &el->cfg.signal;
    const double inv_gain = 1.0 / sp->adc_gain_uv;
    const double ring_len_s = 8.0 * sp->motion_artifact_tau_s;
    const double w = 6.283185307179586 * sp->motion_artifact_hz;
    const bool ringing = sp->motion_artifact_uv > 0.0 && ((double)(c + m) / el->fs - el->motion_t0_s) >= 0.0 &&
                         ((double)c / el->fs - el->motion_t0_s) < ring_len_s;
    for (size_t i = 0u; i < m; ++i) {
        const uint64_t s = c + i;
        double v = sim_noise_filter_step(&el->filt, sim_rng_normal(&el->noise_rng));
        double *slot = &el->acc[s & (SIM_ACC_LEN - 1u)];
        v += *slot;
        *slot = 0.0;
        if (ringing) {
            const double dt = (double)s / el->fs - el->motion_t0_s;
            if (dt >= 0.0 && dt < ring_len_s) {
                v += sp->motion_artifact_uv * exp(-dt / sp->motion_artifact_tau_s) * sin(w * dt);
            }
        }
        double q = floor(v * inv_gain + 0.5);
        if (q > 32767.0 || q < -32768.0) {
            q = (q > 0.0) ? 32767.0 : -32768.0;
            el->adc_clipped++;
        }
        out[i] = (int16_t)q;
    }
}

static int gt_cmp(const void *pa, const void *pb)
{
    const sim_gt_spike_t *a = pa, *b = pb;
    if (a->sample != b->sample) return (a->sample < b->sample) ? -1 : 1;
    if (a->neuron_id != b->neuron_id) return (a->neuron_id < b->neuron_id) ? -1 : 1;
    return (a->amp_uv < b->amp_uv) ? -1 : (a->amp_uv > b->amp_uv) ? 1 : 0;
}

/* Moves pending spikes with trough < end into gt[]; the rest stay pending. */
static size_t deliver(sim_electrode_t *el, uint64_t end, sim_gt_spike_t *gt, size_t gt_n, size_t gt_cap)
{
    size_t keep = 0u;
    for (size_t i = 0u; i < el->n_pending; ++i) {
        const sim_gt_spike_t e = el->pending[i];
        if (e.sample >= end) {
            el->pending[keep++] = e;
            continue;
        }
        if (e.sample < el->cursor) {
            continue; /* trough before the recording started: not in it */
        }
        if (gt_n < gt_cap) {
            gt[gt_n++] = e;
        } else {
            el->gt_dropped++;
        }
        if (el->truth != NULL) {
            (void)fprintf(el->truth,
                          "{\"type\":\"spike\",\"electrode\":%" PRIu32 ",\"sample\":%" PRIu64 ",\"neuron\":%" PRId32
                          ",\"amp_uv\":%.2f}\n",
                          el->index, e.sample, e.neuron_id, e.amp_uv);
        }
    }
    el->n_pending = keep;
    return gt_n;
}

size_t sim_electrode_generate(sim_electrode_t *el, int16_t *out, size_t n, sim_gt_spike_t *gt, size_t gt_cap)
{
    size_t produced = 0u, gt_n = 0u;
    while (produced < n) {
        if (el->cursor >= el->rendered_until) {
            const uint64_t a = el->cursor;
            const uint64_t b = (a / SIM_BLOCK + 1u) * SIM_BLOCK;
            electrode_update_model(el, a, true);
            electrode_render(el, a, b);
            el->rendered_until = b;
        }
        const uint64_t room = el->rendered_until - el->cursor;
        const size_t m = (n - produced < room) ? n - produced : (size_t)room;
        electrode_synth(el, out + produced, el->cursor, m);
        sim_fault_signal_apply(&el->cfg.faults, &el->sig_fault, el->cursor, el->fs, el->cfg.signal.adc_gain_uv,
                               out + produced, m);
        gt_n = deliver(el, el->cursor + m, gt, gt_n, gt_cap);
        el->cursor += m;
        produced += m;
    }
    if (gt != NULL && gt_n > 1u) {
        qsort(gt, gt_n, sizeof gt[0], gt_cmp);
    }
    return gt_n;
}

void sim_electrode_advance(sim_electrode_t *el, uint64_t n_samples)
{
    if (n_samples == 0u) {
        return;
    }
    const uint64_t end = el->cursor + n_samples;
    for (uint64_t g = (el->cursor / SIM_BLOCK + 1u) * SIM_BLOCK; g < end; g += SIM_BLOCK) {
        electrode_update_model(el, g, false);
    }
    electrode_update_model(el, end, false);
    el->cursor = end;
    el->rendered_until = end;
    el->n_pending = 0u;
    memset(el->acc, 0, sizeof el->acc);
}

md_status_t sim_electrode_command(sim_electrode_t *el, uint32_t count, int direction, double rate_hz)
{
    return actuator_command(&el->act, sim_electrode_time_s(el), count, direction, rate_hz);
}

uint32_t sim_electrode_hall_read(sim_electrode_t *el)
{
    const double t_s = sim_electrode_time_s(el);
    const uint32_t code = hall_read(&el->hall, el->act.position_um, t_s);
    const uint32_t code_max = (uint32_t)(ldexp(1.0, (int)el->hall.p.adc_bits) - 1.0);
    return sim_fault_hall_apply(&el->cfg.faults, &el->hall_fault, t_s, code, code_max);
}

double sim_electrode_snr_at(const sim_electrode_t *el, uint32_t k, double tip_um)
{
    const neuron_t *n = &el->neurons[k];
    if (!n->alive || !(el->bg_rms_uv > 0.0)) {
        return 0.0;
    }
    const double t = (double)el->model_sample / el->fs;
    const double dz = tip_um - (neuron_depth_um(n, t) + tissue_displacement_um(&el->tissue));
    return neuron_amplitude_uv(&el->cfg.neuron_model, n, hypot(hypot(n->p.x_um, n->p.y_um), dz)) / el->bg_rms_uv;
}

size_t sim_electrode_truth(const sim_electrode_t *el, sim_neuron_truth_t *out, size_t cap)
{
    const double t = (double)el->model_sample / el->fs;
    const double disp = tissue_displacement_um(&el->tissue);
    const double tip = el->act.position_um;
    size_t k = 0u;
    for (; k < el->n_neurons && k < cap; ++k) {
        const neuron_t *n = &el->neurons[k];
        sim_neuron_truth_t *o = &out[k];
        o->id = n->id;
        o->x_um = n->p.x_um;
        o->y_um = n->p.y_um;
        o->depth_um = neuron_depth_um(n, t) + disp;
        o->alive = n->alive;
        o->died_s = n->died_s;
        o->distance_um = hypot(hypot(n->p.x_um, n->p.y_um), tip - o->depth_um);
        o->closest_um = fmin(el->closest_um[k], o->distance_um);
        o->snr = sim_electrode_snr_at(el, (uint32_t)k, tip);
        /* A(d) decreases with d = hypot(r, dz): the single SNR maximum along the track is at dz = 0 */
        o->snr_peak_depth_um = o->depth_um;
        o->snr_peak = sim_electrode_snr_at(el, (uint32_t)k, o->depth_um);
    }
    return k;
}

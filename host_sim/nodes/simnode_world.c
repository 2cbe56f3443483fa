#include "simnode_world.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "md_protocol.h"
#include "simnode.h"

_Static_assert(SIMNODE_MAX_ELECTRODES >= SIM_MAX_ELECTRODES, "the nodes must serve every scenario electrode");
_Static_assert(SIMNODE_WORLD_CAL_MAX >= HALL_CAL_MAX_DEGREE + 1u, "calibration must fit");

/* Time: the world's clock is t_us; each electrode counts its own ADC samples
 * (model/electrode.h). An electrode that is not recording is kept at sample
 * floor(t_us * fs / 1e6); a recording one moves only by generating samples. */
struct simnode_world {
    sim_world_t sim; /* ~0.4 MB per electrode: hence the heap */
    uint64_t t_us;
    uint32_t fs_hz; /* integer sampling rate shared by every electrode */
    bool recording[SIM_MAX_ELECTRODES];
    FILE *truth;              /* ground-truth sink (not owned) or NULL */
    scenario_faults_t faults; /* launcher/node-level faults of the scenario */
};

static void world_err(char *err, size_t errlen, const char *msg)
{
    if (err != NULL && errlen > 0u) {
        (void)snprintf(err, errlen, "%s", msg);
    }
}

simnode_world_t *simnode_world_create_scenario(const scenario_t *sc, uint64_t seed, char *err, size_t errlen)
{
    if (sc == NULL || sc->n_electrodes == 0u || sc->n_electrodes > SIM_MAX_ELECTRODES) {
        world_err(err, errlen, "scenario has no electrodes");
        return NULL;
    }
    const double fs = sc->electrodes[0].signal.sample_rate_hz;
    for (uint32_t e = 0; e < sc->n_electrodes; e++) {
        const double fe = sc->electrodes[e].signal.sample_rate_hz;
        if (!(fe > 0.0) || fabs(fe - fs) > 0.0 || fabs(fe - floor(fe)) > 0.0 || fe > 1e6) {
            world_err(err, errlen, "every electrode needs the same whole-Hz sample_rate_hz");
            return NULL;
        }
    }
    simnode_world_t *w = calloc(1u, sizeof *w);
    if (w == NULL) {
        world_err(err, errlen, "out of memory");
        return NULL;
    }
    if (scenario_make_world(sc, seed, &w->sim) != MD_OK) {
        world_err(err, errlen, "the models refused the scenario");
        free(w);
        return NULL;
    }
    w->fs_hz = (uint32_t)fs;
    w->faults = sc->faults;
    return w;
}

const scenario_faults_t *simnode_world_faults(const simnode_world_t *w)
{
    return &w->faults;
}

simnode_world_t *simnode_world_create(const char *scenario_path, uint64_t seed, char *err, size_t errlen)
{
    scenario_t *sc = malloc(sizeof *sc); /* large: 8 electrode configurations */
    if (sc == NULL) {
        world_err(err, errlen, "out of memory");
        return NULL;
    }
    if (scenario_path == NULL) {
        scenario_default(sc);
        for (uint32_t e = 1; e < SIMNODE_WORLD_DEFAULT_ELECTRODES; e++) {
            sc->electrodes[e] = sc->electrodes[0];
        }
        sc->n_electrodes = SIMNODE_WORLD_DEFAULT_ELECTRODES;
    } else if (scenario_load(sc, scenario_path, err, errlen) != 0) {
        free(sc);
        return NULL;
    }
    simnode_world_t *w = simnode_world_create_scenario(sc, seed, err, errlen);
    free(sc);
    return w;
}

void simnode_world_destroy(simnode_world_t *w)
{
    free(w);
}

uint32_t simnode_world_electrodes(const simnode_world_t *w)
{
    return w->sim.n_electrodes;
}

uint64_t simnode_world_time_us(const simnode_world_t *w)
{
    return w->t_us;
}

/* Sample index of time t (floor), exact in integers. */
static uint64_t world_sample_at(const simnode_world_t *w, uint64_t t_us)
{
    return t_us * w->fs_hz / 1000000u; /* no overflow below ~10 years of simulated time */
}

void simnode_world_advance(simnode_world_t *w, uint64_t t_us)
{
    if (t_us <= w->t_us) {
        return;
    }
    w->t_us = t_us;
    const uint64_t s = world_sample_at(w, t_us);
    for (uint32_t e = 0; e < w->sim.n_electrodes; e++) {
        sim_electrode_t *el = &w->sim.el[e];
        if (!w->recording[e] && s > el->cursor) {
            sim_electrode_advance(el, s - el->cursor);
        }
    }
}

md_status_t simnode_world_act_command(simnode_world_t *w, uint32_t e, uint32_t count, int direction, double rate_hz)
{
    if (e >= w->sim.n_electrodes) {
        return MD_E_ARG;
    }
    return sim_electrode_command(&w->sim.el[e], count, direction, rate_hz);
}

simnode_act_report_t simnode_world_act_report(const simnode_world_t *w, uint32_t e)
{
    simnode_act_report_t r;
    memset(&r, 0, sizeof r);
    if (e >= w->sim.n_electrodes) {
        return r;
    }
    const actuator_status_t st = actuator_status(&w->sim.el[e].act);
    switch (st.state) {
    case ACTUATOR_MOVING: r.state = (uint8_t)MD_ACT_MOVING; break;
    case ACTUATOR_STALLED: r.state = (uint8_t)MD_ACT_STALLED; break;
    case ACTUATOR_IDLE:
    default: r.state = (uint8_t)MD_ACT_IDLE; break;
    }
    r.steps_requested = st.steps_requested;
    r.steps_done = st.steps_done;
    r.at_upper_stop = st.at_upper_stop;
    r.at_lower_stop = st.at_lower_stop;
    return r;
}

uint64_t simnode_world_act_next_step_us(const simnode_world_t *w, uint32_t e)
{
    if (e >= w->sim.n_electrodes) {
        return UINT64_MAX;
    }
    const sim_electrode_t *el = &w->sim.el[e];
    const actuator_t *a = &el->act;
    if (a->st.state != ACTUATOR_MOVING) {
        return UINT64_MAX;
    }
    /* The model executes step k at t_cmd + k / rate once its time reaches it;
     * its time is a sample index: find the first sample at or after the step
     * (as the model computes s / fs), then the first us that maps to it. */
    const double t_step = a->t_cmd_s + (double)a->st.steps_done / a->rate_hz;
    const double fs = (double)w->fs_hz;
    double sd = ceil(t_step * fs);
    if (sd / fs < t_step) {
        sd += 1.0;
    }
    uint64_t s = (sd < 1.8e19) ? (uint64_t)sd : UINT64_MAX / 2u;
    const uint64_t now_s = world_sample_at(w, w->t_us);
    s = (s > now_s) ? s : now_s + 1u;
    return (s * 1000000u + w->fs_hz - 1u) / w->fs_hz;
}

uint16_t simnode_world_hall_read(simnode_world_t *w, uint32_t e)
{
    if (e >= w->sim.n_electrodes) {
        return 0u;
    }
    sim_electrode_t *el = &w->sim.el[e];
    const uint32_t code = sim_electrode_hall_read(el);
    const uint32_t bits = el->hall.p.adc_bits;
    /* RawCode is 16 bits: a wider ADC reports its 16 most significant bits */
    return (uint16_t)((bits > 16u) ? (code >> (bits - 16u)) : code);
}

void simnode_world_hall_cal(const simnode_world_t *w, uint32_t e, simnode_hall_cal_t *cal)
{
    memset(cal, 0, sizeof *cal);
    if (e >= w->sim.n_electrodes) {
        return;
    }
    const hall_calibration_t *c = &w->sim.el[e].hall.cal;
    const uint32_t bits = w->sim.el[e].hall.p.adc_bits;
    const double scale = (bits > 16u) ? ldexp(1.0, (int)bits - 16) : 1.0; /* as in hall_read */
    cal->count = c->degree + 1u;
    for (uint32_t k = 0; k < cal->count && k < SIMNODE_WORLD_CAL_MAX; k++) {
        cal->coef[k] = c->coef[k];
    }
    cal->code_mid = c->code_mid / scale;
    cal->code_half = c->code_half / scale;
}

double simnode_world_hall_rate_hz(const simnode_world_t *w)
{
    return w->sim.el[0].hall.p.report_rate_hz;
}

uint32_t simnode_world_fe_rate_hz(const simnode_world_t *w)
{
    return w->fs_hz;
}

double simnode_world_fe_gain_uv(const simnode_world_t *w)
{
    return w->sim.el[0].cfg.signal.adc_gain_uv;
}

md_status_t simnode_world_record_start(simnode_world_t *w, uint32_t e, uint32_t interval_id, uint32_t n_samples)
{
    if (e >= w->sim.n_electrodes) {
        return MD_E_ARG;
    }
    if (w->recording[e]) {
        return MD_E_STATE;
    }
    w->recording[e] = true;
    char label[48];
    (void)snprintf(label, sizeof label, "rec e%u i%u", (unsigned)e, (unsigned)interval_id);
    sim_world_truth_snapshot(&w->sim, label);
    if (w->truth != NULL) {
        /* The electrode's own sample clock can lag floor(t * fs) by one
         * sample after back-to-back recordings, so the first sample's index
         * is written as it is, not derived from the time. */
        (void)fprintf(w->truth,
                      "{\"type\":\"interval\",\"electrode\":%u,\"interval\":%u,\"t_us\":%llu"
                      ",\"start_sample\":%llu,\"num_samples\":%u,\"sample_rate_hz\":%u}\n",
                      (unsigned)e, (unsigned)interval_id, (unsigned long long)w->t_us,
                      (unsigned long long)w->sim.el[e].cursor, (unsigned)n_samples, (unsigned)w->fs_hz);
    }
    return MD_OK;
}

md_status_t simnode_world_record_next(simnode_world_t *w, uint32_t e, uint32_t n, int16_t *out)
{
    sim_gt_spike_t gt[64]; /* a few samples' spikes; the truth sink gets them all */
    if (e >= w->sim.n_electrodes || !w->recording[e]) {
        return MD_E_STATE;
    }
    for (uint32_t done = 0; done < n;) { /* bounded: n / 32 chunks */
        const uint32_t m = (n - done < 32u) ? n - done : 32u;
        (void)sim_electrode_generate(&w->sim.el[e], out + done, m, gt, sizeof gt / sizeof gt[0]);
        done += m;
    }
    return MD_OK;
}

void simnode_world_record_stop(simnode_world_t *w, uint32_t e)
{
    if (e < w->sim.n_electrodes) {
        w->recording[e] = false;
    }
}

uint64_t simnode_world_adc_clipped(const simnode_world_t *w)
{
    uint64_t n = 0u;
    for (uint32_t e = 0; e < w->sim.n_electrodes; e++) {
        n += w->sim.el[e].adc_clipped;
    }
    return n;
}

simnode_world_fault_counts_t simnode_world_fault_counts(const simnode_world_t *w)
{
    simnode_world_fault_counts_t c;
    memset(&c, 0, sizeof c);
    for (uint32_t e = 0; e < w->sim.n_electrodes; e++) {
        const sim_electrode_t *el = &w->sim.el[e];
        c.hall_glitches += el->hall_fault.glitches;
        c.hall_stuck_reads += el->hall_fault.stuck_reads;
        c.act_stalls += el->act.fault_stalls;
        c.act_slips += el->act.fault_slips;
        c.storm_events += el->sig_fault.storm_events;
        c.saturated_samples += el->sig_fault.saturated_samples;
    }
    return c;
}

void simnode_world_set_truth(simnode_world_t *w, FILE *f)
{
    w->truth = f;
    sim_world_set_truth(&w->sim, f);
}

#include "model/sim_world.h"

#include <inttypes.h>
#include <math.h>
#include <string.h>

md_status_t sim_world_init(sim_world_t *w, const sim_electrode_config_t *cfgs, uint32_t n, uint64_t seed)
{
    if (w == NULL || cfgs == NULL || n == 0u || n > SIM_MAX_ELECTRODES) {
        return MD_E_ARG;
    }
    memset(w, 0, sizeof *w);
    w->seed = seed;
    for (uint32_t e = 0u; e < n; ++e) {
        const md_status_t st = sim_electrode_init(&w->el[e], &cfgs[e], seed, e);
        if (st != MD_OK) {
            return st;
        }
    }
    w->n_electrodes = n;
    return MD_OK;
}

void sim_world_advance_s(sim_world_t *w, double dt_s)
{
    for (uint32_t e = 0u; e < w->n_electrodes && dt_s > 0.0; ++e) {
        sim_electrode_advance(&w->el[e], (uint64_t)floor(dt_s * w->el[e].fs + 0.5));
    }
}

bool sim_world_idle(const sim_world_t *w)
{
    for (uint32_t e = 0u; e < w->n_electrodes; ++e) {
        if (w->el[e].act.st.state == ACTUATOR_MOVING) {
            return false;
        }
    }
    return true;
}

void sim_world_set_truth(sim_world_t *w, FILE *f)
{
    w->truth = f;
    for (uint32_t e = 0u; e < w->n_electrodes; ++e) {
        w->el[e].truth = f;
    }
    if (f == NULL || w->n_electrodes == 0u) {
        return;
    }
    (void)fprintf(f,
                  "{\"type\":\"session\",\"seed\":%" PRIu64 ",\"sample_rate_hz\":%.3f,\"electrodes\":%" PRIu32
                  ",\"bg_rms_uv\":[",
                  w->seed, w->el[0].fs, w->n_electrodes);
    for (uint32_t e = 0u; e < w->n_electrodes; ++e) {
        (void)fprintf(f, "%s%.4f", e ? "," : "", w->el[e].bg_rms_uv);
    }
    (void)fprintf(f, "]}\n");
    for (uint32_t e = 0u; e < w->n_electrodes; ++e) {
        const sim_electrode_t *el = &w->el[e];
        for (uint32_t k = 0u; k < el->n_neurons; ++k) {
            const neuron_t *n = &el->neurons[k];
            (void)fprintf(f,
                          "{\"type\":\"neuron\",\"electrode\":%" PRIu32 ",\"neuron\":%" PRIu32
                          ",\"x_um\":%.3f,\"y_um\":%.3f,\"depth_um\":%.3f,\"amp_uv\":%.3f,\"rate_hz\":%.4f"
                          ",\"shape\":\"%s\"}\n",
                          e, n->id, n->p.x_um, n->p.y_um, n->p.depth_um, n->p.amp_uv, n->p.rate_hz,
                          n->p.shape == NEURON_TRIPHASIC ? "triphasic" : "biphasic");
        }
    }
}

void sim_world_truth_snapshot(sim_world_t *w, const char *label)
{
    if (w->truth == NULL) {
        return;
    }
    static sim_neuron_truth_t tr[SIM_MAX_NEURONS];
    for (uint32_t e = 0u; e < w->n_electrodes; ++e) {
        const sim_electrode_t *el = &w->el[e];
        const size_t n = sim_electrode_truth(el, tr, SIM_MAX_NEURONS);
        (void)fprintf(w->truth,
                      "{\"type\":\"state\",\"t_s\":%.6f,\"label\":\"%s\",\"electrode\":%" PRIu32
                      ",\"tip_um\":%.4f,\"neurons\":[",
                      sim_electrode_time_s(el), label != NULL ? label : "", e, sim_electrode_tip_um(el));
        for (size_t k = 0u; k < n; ++k) {
            (void)fprintf(w->truth,
                          "%s{\"neuron\":%" PRIu32 ",\"depth_um\":%.4f,\"alive\":%s,\"distance_um\":%.4f"
                          ",\"closest_um\":%.4f,\"snr\":%.4f,\"snr_peak_depth_um\":%.4f,\"snr_peak\":%.4f}",
                          k ? "," : "", tr[k].id, tr[k].depth_um, tr[k].alive ? "true" : "false", tr[k].distance_um,
                          tr[k].closest_um, tr[k].snr, tr[k].snr_peak_depth_um, tr[k].snr_peak);
        }
        (void)fprintf(w->truth, "]}\n");
    }
}

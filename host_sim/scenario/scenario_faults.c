/// @file scenario_faults.c
/// Queries of a scenario's fault schedule (see scenario_faults.h).
#include "scenario/scenario_faults.h"

bool scenario_faults_node_silent(const scenario_faults_t *f, uint32_t node, double t_s)
{
    for (uint32_t i = 0u; i < f->n_silent && i < SCENARIO_SILENT_MAX; ++i) {
        const scenario_silence_t *q = &f->silent[i];
        if (q->node == node && t_s >= q->from_s && t_s < q->to_s) {
            return true;
        }
    }
    return false;
}

uint32_t scenario_faults_restarts_due(const scenario_faults_t *f, double t_prev_s, double t_now_s)
{
    uint32_t n = 0u;
    for (uint32_t i = 0u; i < f->n_restarts && i < SCENARIO_RESTARTS_MAX; ++i) {
        n += (f->restart_at_s[i] > t_prev_s && f->restart_at_s[i] <= t_now_s) ? 1u : 0u;
    }
    return n;
}

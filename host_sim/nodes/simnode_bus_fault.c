/// @file simnode_bus_fault.c
/// Scenario bus faults -> md_bus_fault parameters. See simnode_bus_fault.h.
#include "simnode_bus_fault.h"

#include <inttypes.h>

#define ALL_ID_BITS 0x1FFFFFFFu
#define SEED_MIX 0x9E3779B97F4A7C15ull /* 2^64 / golden ratio: spreads consecutive seeds */
#define WINDOW_OPEN_S 9.2e12           /* to_s beyond this (INFINITY): the window never closes */

void simnode_bus_fault_params(const scenario_bus_fault_t *b, uint64_t session_seed, uint32_t index,
                              md_bus_fault_params_t *p)
{
    md_bus_fault_default_params(p);
    if (b->kind < (uint32_t)MD_BUS_FAULT_KINDS) {
        p->prob[b->kind] = b->prob;
    }
    p->directions = b->directions;
    p->delay_frames = (b->frames > 0u) ? b->frames : p->delay_frames;
    if (b->has_id != 0u) {
        p->id_mask = ALL_ID_BITS;
        p->id_match = b->can_id;
    }
    p->t_from_us = (int64_t)(b->from_s * 1e6);
    p->t_to_us = (b->to_s < WINDOW_OPEN_S) ? (int64_t)(b->to_s * 1e6) : INT64_MAX;
    p->seed = session_seed * SEED_MIX + index + 1u;
}

void simnode_bus_fault_print(FILE *out, const char *prog, uint32_t index, const md_bus_fault_t *f)
{
    const md_bus_fault_counters_t c = md_bus_fault_counters(f);
    fprintf(out, "%s: bus fault %u: frames seen %" PRIu64, prog, (unsigned)index, c.frames_seen);
    for (uint32_t k = 0; k < (uint32_t)MD_BUS_FAULT_KINDS; k++) {
        fprintf(out, ", %s %" PRIu64, md_bus_fault_kind_name((md_bus_fault_kind_t)k), c.injected[k]);
    }
    fprintf(out, ", hold full %" PRIu64 "\n", c.hold_full);
}

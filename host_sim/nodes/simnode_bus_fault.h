/// @file simnode_bus_fault.h
/// A scenario's bus faults (`faults:` entries bus_loss ... bus_reorder,
/// host_sim/scenario/scenario.h) as parameters of the md_bus_fault wrapper
/// (common/bus/md_bus_fault.h). One translation for both places that wrap
/// the plant's bus endpoint: microdrive-sim and the in-process launcher, so
/// a scenario injects the same faults whatever runs it.
#ifndef SIMNODE_BUS_FAULT_H
#define SIMNODE_BUS_FAULT_H

#include <stdint.h>
#include <stdio.h>

#include "md_bus_fault.h"
#include "scenario/scenario.h"

/// Fills p for the scenario's bus fault number `index`: its kind's
/// probability, directions, CAN id filter, window and delay, and a seed
/// derived from the session seed and the index (independent streams per
/// fault, the same for the same session seed). O(1).
void simnode_bus_fault_params(const scenario_bus_fault_t *b, uint64_t session_seed, uint32_t index,
                              md_bus_fault_params_t *p);

/// One line on `out`: "<prog>: bus fault <index>: frames seen N, <kind> N...,
/// hold full N" — what the wrapper injected (the fault campaign parses it). O(kinds).
void simnode_bus_fault_print(FILE *out, const char *prog, uint32_t index, const md_bus_fault_t *f);

#endif

/// @file md_cycle.h
/// The autonomous positioning cycle of every electrode (thesis §2.2).
/// (Interface being written; see md_controller.h for the public entry points.)
#ifndef MD_CYCLE_H
#define MD_CYCLE_H

#include <stdint.h>

/// Cycle state of every electrode and the shared workspace (to be filled in).
typedef struct {
    uint32_t cycles;  ///< completed cycles, all electrodes
} md_cycle_t;

#endif

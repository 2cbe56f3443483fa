/// @file simnode_hall.h
/// Position sensor node (node 3): HALL_READING of every electrode at a fixed
/// rate in simulated time (ticks at k * period from time 0, Seq per electrode
/// modulo 256, SampleTime_ms = simulated ms), and HALL_CALIB of every
/// electrode when it becomes operational and every calib_period_ms.
///
/// HALL_CALIB carries a polynomial in the normalised code
/// x = (code - code_mid) / code_half: CoeffIndex 0..CoeffCount-1 are the
/// coefficients of x^k, and two more frames with CoeffIndex
/// SIMNODE_HALL_CAL_INDEX_MID / _HALF carry code_mid and code_half (same
/// CoeffCount). In raw codes a degree-9 polynomial is hopeless in float32.
#ifndef SIMNODE_HALL_H
#define SIMNODE_HALL_H

#include <stdbool.h>
#include <stdint.h>

#include "simnode.h"
#include "simnode_world.h"

#define SIMNODE_HALL_CAL_INDEX_MID 0xF0u   ///< CoeffIndex carrying code_mid
#define SIMNODE_HALL_CAL_INDEX_HALF 0xF1u  ///< CoeffIndex carrying code_half

typedef struct {
    simnode_t node;
    simnode_world_t *world;
    uint64_t period_us;        ///< reading period (> 0)
    uint64_t calib_period_us;  ///< calibration repeat period (> 0)
    uint64_t next_reading_us;
    uint64_t next_calib_us;
    uint8_t seq[SIMNODE_MAX_ELECTRODES];
} simnode_hall_t;

/// Initialises the node; rate_hz > 0 (period rounded to whole us, >= 1 us),
/// calib_period_ms > 0.
void simnode_hall_init(simnode_hall_t *h, simnode_world_t *world, bool autostart, bool lockstep, double rate_hz,
                       uint32_t calib_period_ms, simnode_sink_t sink);

/// Sends the calibration and one reading of every electrode now; the next
/// reading is on the next tick of the fixed grid.
void simnode_hall_announce(simnode_hall_t *h, uint64_t t_us);

/// Reacts to an NMT command's effect on this node.
void simnode_hall_on_nmt(simnode_hall_t *h, simnode_nmt_effect_t effect, uint64_t t_us);

/// Earliest next event (reading tick or calibration); UINT64_MAX when silent.
uint64_t simnode_hall_next_event_us(const simnode_hall_t *h);

/// Runs the events due at t_us (world already at t_us).
void simnode_hall_run(simnode_hall_t *h, uint64_t t_us);

#endif

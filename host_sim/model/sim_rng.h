/// @file sim_rng.h
/// Deterministic pseudo-random streams for the simulator.
///
/// One stream per model component, each seeded from the session seed and a
/// component key (kind, electrode, index) through SplitMix64, so adding a
/// neuron never perturbs the actuator's or another neuron's numbers. The
/// generator is xoshiro256** (Blackman & Vigna), fast and with 2^256 period.
/// Everything here is pure integer/double arithmetic: the same seed gives the
/// same numbers on every IEEE-754 host.
#ifndef SIM_RNG_H
#define SIM_RNG_H

#include <stdint.h>

/// Component kinds used to derive independent streams.
typedef enum {
    SIM_RNG_ACTUATOR = 1,
    SIM_RNG_HALL = 2,
    SIM_RNG_TISSUE = 3,
    SIM_RNG_NOISE = 4,
    SIM_RNG_MUA = 5,
    SIM_RNG_ARTIFACT = 6,
    SIM_RNG_PLACEMENT = 7,
    SIM_RNG_NEURON = 8,
    SIM_RNG_FAULT = 9  ///< model faults (index: 0 Hall, 1 actuator, 2 signal)
} sim_rng_kind_t;

/// One stream's state. Plain data: copy it to fork a stream.
typedef struct {
    uint64_t s[4];
    double spare_normal;  ///< second value of the last Box-Muller pair
    int has_spare;
} sim_rng_t;

/// Seeds `rng` from the session seed and a component key. O(1).
void sim_rng_init(sim_rng_t *rng, uint64_t seed, sim_rng_kind_t kind, uint32_t electrode, uint32_t index);
/// Next raw 64-bit value. O(1).
uint64_t sim_rng_u64(sim_rng_t *rng);
/// Uniform double in [0, 1) with 53 random bits. O(1).
double sim_rng_uniform(sim_rng_t *rng);
/// Uniform double in (0, 1]: safe to take the log of. O(1).
double sim_rng_uniform_pos(sim_rng_t *rng);
/// Standard normal (Box-Muller, pairs cached). O(1).
double sim_rng_normal(sim_rng_t *rng);
/// Exponential with the given mean (> 0). O(1).
double sim_rng_exponential(sim_rng_t *rng, double mean);

#endif

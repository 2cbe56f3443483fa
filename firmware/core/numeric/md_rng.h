/// @file md_rng.h
/// Small deterministic pseudo-random generator (SplitMix64).
///
/// Used wherever the firmware needs reproducible randomness (noise-snippet
/// positions) and by self-tests that synthesise signals. The state is one
/// caller-owned 64-bit word; the same seed always gives the same sequence on
/// every platform. Not for cryptography.
#ifndef MD_RNG_H
#define MD_RNG_H

#include <stdint.h>

/// Generator state; initialise with md_rng_seed().
typedef struct {
    uint64_t state;
} md_rng_t;

/// Sets the state from a seed. Any seed, including 0, is valid.
void md_rng_seed(md_rng_t *rng, uint64_t seed);

/// Next 64 uniformly distributed bits. O(1).
uint64_t md_rng_next_u64(md_rng_t *rng);

/// Uniform double in [0, 1) with 53 random bits. O(1).
double md_rng_uniform(md_rng_t *rng);

/// Uniform integer in [0, bound) without modulo bias; 0 if bound is 0.
/// Rejection sampling bounded to a fixed number of draws (the probability of
/// reaching the bound is below 2^-64); O(1).
uint32_t md_rng_below(md_rng_t *rng, uint32_t bound);

/// Standard normal variate (Box–Muller, one of the pair). O(1).
double md_rng_gauss(md_rng_t *rng);

#endif

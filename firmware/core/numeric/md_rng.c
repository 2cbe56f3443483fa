/// @file md_rng.c
/// SplitMix64 (Steele, Lea & Flood 2014): a Weyl sequence passed through a
/// 64-bit finaliser; passes BigCrush and needs one word of state.
#include "numeric/md_rng.h"

#include <math.h>
#include <stddef.h>

#define MD_RNG_BELOW_MAX_DRAWS 64u

void md_rng_seed(md_rng_t *rng, uint64_t seed)
{
    if (rng != NULL) {
        rng->state = seed;
    }
}

uint64_t md_rng_next_u64(md_rng_t *rng)
{
    if (rng == NULL) {
        return 0u;
    }
    rng->state += 0x9E3779B97F4A7C15ull;
    uint64_t z = rng->state;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

double md_rng_uniform(md_rng_t *rng)
{
    return (double)(md_rng_next_u64(rng) >> 11) * (1.0 / 9007199254740992.0);
}

uint32_t md_rng_below(md_rng_t *rng, uint32_t bound)
{
    if (bound == 0u) {
        return 0u;
    }
    /* Accept only draws below the largest multiple of bound in 2^32, so every
     * residue is equally likely. Each draw is rejected with probability < 1/2. */
    const uint32_t limit = (uint32_t)(0x100000000ull - (0x100000000ull % bound)) - 1u;
    uint32_t r = 0u;
    for (unsigned i = 0u; i < MD_RNG_BELOW_MAX_DRAWS; ++i) {
        r = (uint32_t)(md_rng_next_u64(rng) >> 32);
        if (r <= limit) {
            break;
        }
    }
    return r % bound;
}

double md_rng_gauss(md_rng_t *rng)
{
    /* 1 - u lies in (0, 1], so the logarithm is finite. */
    const double u1 = 1.0 - md_rng_uniform(rng);
    const double u2 = md_rng_uniform(rng);
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

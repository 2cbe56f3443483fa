#include "model/sim_rng.h"

#include <math.h>

static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static uint64_t rotl(uint64_t x, int k)
{
    return (x << k) | (x >> (64 - k));
}

void sim_rng_init(sim_rng_t *rng, uint64_t seed, sim_rng_kind_t kind, uint32_t electrode, uint32_t index)
{
    /* The key is mixed through SplitMix64 twice so that nearby keys (index
     * 3 and 4) give unrelated streams. */
    uint64_t x = seed;
    uint64_t key = ((uint64_t)(uint32_t)kind << 56) ^ ((uint64_t)electrode << 40) ^ (uint64_t)index;
    x ^= splitmix64(&key);
    (void)splitmix64(&x);
    for (int i = 0; i < 4; ++i) {
        rng->s[i] = splitmix64(&x);
    }
    rng->spare_normal = 0.0;
    rng->has_spare = 0;
}

uint64_t sim_rng_u64(sim_rng_t *rng)
{
    uint64_t *s = rng->s;
    const uint64_t result = rotl(s[1] * 5u, 7) * 9u;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

double sim_rng_uniform(sim_rng_t *rng)
{
    return (double)(sim_rng_u64(rng) >> 11) * 0x1.0p-53;
}

double sim_rng_uniform_pos(sim_rng_t *rng)
{
    return ((double)(sim_rng_u64(rng) >> 11) + 1.0) * 0x1.0p-53;
}

double sim_rng_normal(sim_rng_t *rng)
{
    if (rng->has_spare) {
        rng->has_spare = 0;
        return rng->spare_normal;
    }
    const double r = sqrt(-2.0 * log(sim_rng_uniform_pos(rng)));
    const double a = 6.283185307179586 * sim_rng_uniform(rng);
    rng->spare_normal = r * sin(a);
    rng->has_spare = 1;
    return r * cos(a);
}

double sim_rng_exponential(sim_rng_t *rng, double mean)
{
    return -mean * log(sim_rng_uniform_pos(rng));
}

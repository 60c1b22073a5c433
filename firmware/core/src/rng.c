#include "coslam/rng.h"

#include <math.h>

#include "coslam/status.h"

static uint64_t rotl64(uint64_t x, unsigned k)
{
    return (x << k) | (x >> (64U - k));
}

/* splitmix64 step: a bijective mixer used only to expand the seed. */
static uint64_t splitmix64(uint64_t *state)
{
    uint64_t z = (*state += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

void rng_seed(rng_t *rng, uint64_t seed)
{
    COSLAM_ASSERT(rng != 0);
    uint64_t sm = seed;
    for (int i = 0; i < 4; ++i) {
        rng->s[i] = splitmix64(&sm);
    }
    /* splitmix64 is a bijection on distinct counters, so the state can
     * never be all zero; assert the invariant anyway. */
    COSLAM_ASSERT((rng->s[0] | rng->s[1] | rng->s[2] | rng->s[3]) != 0U);
    rng->spare = 0.0;
    rng->has_spare = 0;
}

uint64_t rng_next_u64(rng_t *rng)
{
    uint64_t *s = rng->s;
    const uint64_t result = rotl64(s[1] * 5U, 7) * 9U;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl64(s[3], 45);
    return result;
}

double rng_uniform(rng_t *rng)
{
    return (double)(rng_next_u64(rng) >> 11) * 0x1.0p-53;
}

uint32_t rng_below(rng_t *rng, uint32_t n)
{
    COSLAM_ASSERT(n > 0U);
    /* Lemire-style rejection on the high 32 bits */
    const uint32_t threshold = (uint32_t)(-n) % n;
    for (;;) {
        const uint64_t m = (rng_next_u64(rng) >> 32) * (uint64_t)n;
        if ((uint32_t)m >= threshold) {
            return (uint32_t)(m >> 32);
        }
    }
}

double rng_gauss(rng_t *rng)
{
    if (rng->has_spare) {
        rng->has_spare = 0;
        return rng->spare;
    }
    double u;
    double v;
    double s;
    do {
        u = 2.0 * rng_uniform(rng) - 1.0;
        v = 2.0 * rng_uniform(rng) - 1.0;
        s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    const double f = sqrt(-2.0 * log(s) / s);
    rng->spare = v * f;
    rng->has_spare = 1;
    return u * f;
}

double rng_normal(rng_t *rng, double mean, double sigma)
{
    return mean + sigma * rng_gauss(rng);
}

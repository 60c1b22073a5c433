/*
 * coslam/rng.h - the core's only source of randomness.
 *
 * Generator: xoshiro256** (Blackman and Vigna, 2018), 256-bit state, period
 * 2^256 - 1, seeded from one 64-bit seed through splitmix64 so that nearby
 * seeds give unrelated streams. Gaussian samples use the Marsaglia polar
 * method (one spare value cached in the state).
 *
 * Determinism: the same seed and the same sequence of calls give the same
 * numbers bit for bit on any IEEE-754 platform whose libm `log` and `sqrt`
 * are correctly rounded for the inputs used (sqrt always is; glibc's and
 * newlib's log agree in practice). There is no global state: each filter or
 * simulator object owns its rng_t.
 *
 * Memory: sizeof(rng_t) = 48 bytes. Every call is O(1).
 */
#ifndef COSLAM_RNG_H
#define COSLAM_RNG_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    uint64_t s[4];
    double spare;   /**< cached second polar-method sample */
    int has_spare;
} rng_t;

/** Seed the generator. Any 64-bit value is a valid seed (0 included). */
void rng_seed(rng_t *rng, uint64_t seed);

/** Next raw 64-bit output. */
uint64_t rng_next_u64(rng_t *rng);

/** Uniform double in [0, 1) with 53 random bits. */
double rng_uniform(rng_t *rng);

/** Uniform integer in [0, n) without modulo bias; n > 0. */
uint32_t rng_below(rng_t *rng, uint32_t n);

/** Standard normal N(0, 1). */
double rng_gauss(rng_t *rng);

/** Normal N(mean, sigma^2); sigma >= 0. */
double rng_normal(rng_t *rng, double mean, double sigma);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_RNG_H */

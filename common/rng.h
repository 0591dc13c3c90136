/* rng.h: PCG32 random streams. A stream is a pure function of up to three ids
 * (e.g. request id, epoch, dimension) and a seed, so a sample's randomness
 * does not depend on which rank or thread computes it (pbrt-v4 style). */
#ifndef CT_RNG_H
#define CT_RNG_H

#include <stdint.h>

typedef struct ct_rng {
    uint64_t state;
    uint64_t inc;
} ct_rng;

/* 64-bit mixing function (splitmix64 finalizer). */
static inline uint64_t ct_hash64(uint64_t x)
{
    x ^= x >> 30; x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27; x *= 0x94d049bb133111ebULL;
    x ^= x >> 31;
    return x;
}

/* The stream for (seed, a, b, c). */
ct_rng rng_make(uint64_t seed, uint64_t a, uint64_t b, uint64_t c);

/* Next 32 random bits. */
static inline uint32_t rng_u32(ct_rng *r)
{
    uint64_t old = r->state;
    r->state = old * 6364136223846793005ULL + r->inc;
    uint32_t xorshifted = (uint32_t)(((old >> 18u) ^ old) >> 27u);
    uint32_t rot = (uint32_t)(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((-rot) & 31));
}

/* Uniform float in [0, 1). */
static inline float rng_float(ct_rng *r)
{
    return (float)(rng_u32(r) >> 8) * 0x1p-24f;
}

/* Uniform double in [0, 1). */
static inline double rng_double(ct_rng *r)
{
    uint64_t hi = rng_u32(r), lo = rng_u32(r);
    return (double)(((hi << 32) | lo) >> 11) * 0x1p-53;
}

/* Uniform integer in [0, n) without modulo bias (n > 0). */
uint32_t rng_below(ct_rng *r, uint32_t n);

#endif

#include "common/rng.h"

/* 64 x 64 -> 128-bit product, its halves folded (wyhash's mixing step):
 * every bit of either factor reaches the upper half. */
__extension__ typedef unsigned __int128 u128;
static inline uint64_t mum(uint64_t a, uint64_t b)
{
    u128 p = (u128)a * b;
    return (uint64_t)p ^ (uint64_t)(p >> 64);
}

ct_rng rng_make(uint64_t seed, uint64_t a, uint64_t b, uint64_t c)
{
    /* Every id reaches both the start state and the stream selector, so
     * neighbouring ids give unrelated sequences. A tree of three products
     * (two of them independent) rather than a chain of five splitmix
     * rounds: this runs once or twice per traced sample, and in the
     * reuse-diffuse mode, with few rays per sample, the chain's latency was
     * 4-5 % of the render (docs/tracer.md, "Performance decisions"). */
    uint64_t h = mum(mum(seed ^ 0x9e3779b97f4a7c15ULL, a ^ 0xa0761d6478bd642fULL) ^ 0xe7037ed1a0b428dbULL,
                     mum(b ^ 0x8ebc6af09c88c6e3ULL, c ^ 0x589965cc75374cc3ULL) ^ 0x1d8e4e27c47d124fULL);
    ct_rng r;
    r.state = 0;
    r.inc = (mum(h ^ 0xda942042e4dd58b5ULL, 0x632be59bd9b4e019ULL) << 1u) | 1u;
    rng_u32(&r);
    r.state += h;
    rng_u32(&r);
    return r;
}

uint32_t rng_below(ct_rng *r, uint32_t n)
{
    uint32_t threshold = (uint32_t)(-n) % n;
    for (;;) {
        uint32_t x = rng_u32(r);
        if (x >= threshold) return x % n;
    }
}

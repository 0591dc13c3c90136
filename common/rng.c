#include "common/rng.h"

ct_rng rng_make(uint64_t seed, uint64_t a, uint64_t b, uint64_t c)
{
    /* Hash every id into both the start state and the stream selector, so
     * neighbouring ids give unrelated sequences. */
    uint64_t h = ct_hash64(seed ^ 0x9e3779b97f4a7c15ULL);
    h = ct_hash64(h ^ a);
    h = ct_hash64(h ^ (b + 0x632be59bd9b4e019ULL));
    h = ct_hash64(h ^ (c + 0x85157af5ULL));
    ct_rng r;
    r.state = 0;
    r.inc = (ct_hash64(h ^ 0xda942042e4dd58b5ULL) << 1u) | 1u;
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

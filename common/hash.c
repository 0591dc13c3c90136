#include "common/hash.h"
#include "common/rng.h"


uint64_t ct_hash_bytes(uint64_t h, const void *data, size_t len)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < len; i++) {
        h ^= p[i];
        h *= 0x100000001b3ULL;
    }
    return ct_hash64(h ^ len);
}

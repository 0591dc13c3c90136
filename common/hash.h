/* hash.h: 64-bit content hashes (FNV-1a, then mixed) for cache keys such as
 * the scene hash that tags a radiosity mesh. Not cryptographic. */
#ifndef CT_HASH_H
#define CT_HASH_H

#include <stddef.h>
#include <stdint.h>

#define CT_HASH_INIT 0xcbf29ce484222325ULL

/* Continues hash h over len bytes. */
uint64_t ct_hash_bytes(uint64_t h, const void *data, size_t len);

#endif

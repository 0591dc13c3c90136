/* idmap.h: a hash map from 32-bit ids to 32-bit indices (open addressing,
 * linear probing, deletion by backward shift: no tombstones). For tables
 * whose ids a peer chooses: the display's textures, looked up by every
 * message and every upload, held up to two per scene node, where a linear
 * search made a frame take seconds. The hash is keyed by a random seed per
 * map, so a peer cannot choose ids that all fall into one probe run. */
#ifndef CT_IDMAP_H
#define CT_IDMAP_H

#include <stdint.h>

#include "common/error.h"

#define IDMAP_NONE UINT32_MAX   /* idmap_get: no such id (never a stored index) */

typedef struct ct_idmap_slot {
    uint32_t key, val;   /* val IDMAP_NONE: empty */
} ct_idmap_slot;

typedef struct ct_idmap {
    ct_idmap_slot *s;
    uint32_t cap;    /* a power of two, or 0 */
    uint32_t n;
    uint32_t shift;  /* 64 - log2(cap) */
    uint64_t seed;   /* drawn at the first growth */
} ct_idmap;

/* A zeroed ct_idmap is an empty map; idmap_free returns it to that. */
void idmap_free(ct_idmap *m);

/* Forgets every id, keeping the memory. */
void idmap_clear(ct_idmap *m);

/* The index stored for key, or IDMAP_NONE. */
uint32_t idmap_get(const ct_idmap *m, uint32_t key);

/* Stores val for key, replacing what it had; IDMAP_NONE is refused. */
int idmap_put(ct_idmap *m, uint32_t key, uint32_t val, ct_error *err);

/* Forgets key (nothing when it is absent). */
void idmap_del(ct_idmap *m, uint32_t key);

#endif

#ifndef CORRTEX_DISP_CACHE_H
#define CORRTEX_DISP_CACHE_H
/* The display's scene cache: SCENE payloads of earlier connections, so that
 * SETTINGS can announce one and the master skips sending it again.
 *
 * In memory it holds one payload; with a directory also on disk:
 *   DIR/<hash>.ctscene   a payload, named by its BLAKE2b-256 content hash
 *   DIR/addr-<key>.last  the hash of the last scene received from one master
 *                        address (key: hash of the address text)
 *   DIR/last             the hash of the last scene received from any master
 * so a restarted display announces what that master sent it last (else the
 * last scene at all). The directory is bounded: after each new payload the
 * least recently used payloads beyond max_bytes are deleted (never the one in
 * use), with the index files that named them. Disk problems only warn: a
 * cache miss costs one transfer, never a failed connection. */

#include <stdbool.h>
#include <stdint.h>

#include "common/error.h"
#include "proto/wire.h"

/* The default bound on the payloads kept on disk: about 30 office scenes. */
#define DISP_CACHE_MAX_MB 1024u

typedef struct disp_scene_cache disp_scene_cache;

/* A cache; dir may be NULL (memory only). max_bytes bounds the payloads kept
 * in dir (0: no bound). Nothing is read until disp_scene_cache_select. */
int disp_scene_cache_new(const char *dir, uint64_t max_bytes, disp_scene_cache **out,
                         ct_error *err);

/* Frees it (NULL is fine). */
void disp_scene_cache_free(disp_scene_cache *c);

/* Before connecting to addr: loads the payload addr sent last (else DIR/last)
 * unless it is the one in memory already. A missing, unreadable or corrupt
 * file leaves the cache as it was (logged). */
void disp_scene_cache_select(disp_scene_cache *c, const char *addr);

/* The hash to announce; false when the cache is empty. */
bool disp_scene_cache_hash(const disp_scene_cache *c, uint8_t hash[WIRE_HASH_SIZE]);

/* The payload with this hash, or false. */
bool disp_scene_cache_get(const disp_scene_cache *c, const uint8_t hash[WIRE_HASH_SIZE],
                          const uint8_t **raw, uint64_t *size);

/* Keeps a payload received from addr (copied; hash is its content hash),
 * writes it to the directory and prunes. Without memory for the copy the
 * cache stays as it was. */
void disp_scene_cache_put(disp_scene_cache *c, const char *addr,
                          const uint8_t hash[WIRE_HASH_SIZE], const uint8_t *raw, uint64_t size);

#endif

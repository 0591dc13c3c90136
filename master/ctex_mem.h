/* ctex_mem.h: the texel memory of the corrective textures. Large texel
 * arrays that textures give back (a resolution change, a reprojection, a
 * texture freed) are kept, up to a bound, for the next ones instead of
 * going back to the system: a fresh array costs a page fault and a zeroed
 * page per 4 KiB (or 2 MiB), which on this project's virtual machines ran
 * at 0.4-10 GB/s depending on the host (docs/textures.md, "Texel memory"),
 * and a master that moves with the camera or doubles textures asks for
 * hundreds of MiB a second. Arrays under 2 MiB go to malloc. Thread-safe.
 * Owns the ctex_mem_ prefix. */
#ifndef CT_MASTER_CTEX_MEM_H
#define CT_MASTER_CTEX_MEM_H

#include <stddef.h>

typedef struct ctex_mem ctex_mem;

/* A pool that keeps at most keep_bytes of given-back arrays; NULL when out
 * of memory. */
ctex_mem *ctex_mem_new(size_t keep_bytes);

/* Frees the pool and every array it keeps (NULL is fine). */
void ctex_mem_free(ctex_mem *m);

/* An array of at least `bytes` (uninitialised), from the pool when one of
 * a fitting size is kept (at most a quarter or 2 MiB larger); arrays of
 * 2 MiB and more are aligned to 2 MiB and advised as huge pages. m NULL:
 * from the system. NULL when out of memory. */
void *ctex_mem_get(ctex_mem *m, size_t bytes);

/* Gives back p, which ctex_mem_get returned for `bytes` (NULL is fine):
 * kept while the pool holds less than its bound (the oldest kept arrays
 * make room), else freed. m NULL: freed. */
void ctex_mem_put(ctex_mem *m, void *p, size_t bytes);

/* Bytes kept now; large arrays handed out from the pool and fresh from the
 * system since the start. */
size_t ctex_mem_held(ctex_mem *m);
void ctex_mem_counts(ctex_mem *m, size_t *reused, size_t *fresh);

#endif

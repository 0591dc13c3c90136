/* hugemem.h: large arrays touched at random (texels, the request queue's
 * per-pixel records) as transparent huge pages where the kernel gives them:
 * with 4 KiB pages nearly every access to tens of MiB misses the TLB as
 * well as the caches. A hint only: without huge pages the memory is the
 * same, only slower. Owns the ct_huge_ prefix. */
#ifndef CT_COMMON_HUGEMEM_H
#define CT_COMMON_HUGEMEM_H

#include <stddef.h>

enum { CT_HUGE_PAGE = 2u << 20 };

/* bytes of memory, 2 MiB-aligned and advised as huge pages from CT_HUGE_PAGE
 * on (malloc below); not zeroed. free() gives it back. NULL when out of
 * memory. */
void *ct_huge_alloc(size_t bytes);

/* bytes of zeroed memory, advised as huge pages from CT_HUGE_PAGE on, its
 * pages zeroed by the kernel on first touch (nothing is written up front).
 * ct_huge_zfree with the same size gives it back. NULL when out of memory. */
void *ct_huge_zalloc(size_t bytes);
void ct_huge_zfree(void *p, size_t bytes);

#endif

/* hugemem.c: huge-page arrays (hugemem.h). */
#include "common/hugemem.h"

#include <stdlib.h>
#include <sys/mman.h>

static void advise(void *p, size_t bytes)
{
#ifdef MADV_HUGEPAGE
    if (bytes >= CT_HUGE_PAGE) (void)madvise(p, bytes, MADV_HUGEPAGE);   /* a hint: failure only costs speed */
#else
    (void)p;
    (void)bytes;
#endif
}

void *ct_huge_alloc(size_t bytes)
{
    if (bytes < CT_HUGE_PAGE) return malloc(bytes ? bytes : 1);
    void *p = NULL;
    if (posix_memalign(&p, CT_HUGE_PAGE, bytes)) return NULL;
    advise(p, bytes);
    return p;
}

void *ct_huge_zalloc(size_t bytes)
{
    void *p = mmap(NULL, bytes ? bytes : 1, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) return NULL;
    advise(p, bytes);
    return p;
}

void ct_huge_zfree(void *p, size_t bytes)
{
    if (p) munmap(p, bytes ? bytes : 1);
}

/* grow.h: the growing arrays of the per-frame and per-view scratch buffers
 * (capacity doubled past what is needed, at least 64 entries, so a steady
 * workload stops reallocating after a few frames). Header only. */
#ifndef CT_COMMON_GROW_H
#define CT_COMMON_GROW_H

#include <stdint.h>
#include <stdlib.h>

#include "common/error.h"

/* Makes *p (of *cap entries of elem bytes) hold at least need entries;
 * `what` names them in the out-of-memory error. *p is kept on failure. */
static inline int ct_grow(void **p, size_t *cap, size_t need, size_t elem, const char *what, ct_error *err)
{
    if (need <= *cap) return CT_OK;
    size_t n = need < 64 ? 64 : 2 * need;
    void *q = n <= SIZE_MAX / elem ? realloc(*p, n * elem) : NULL;
    if (!q) return ct_fail(err, CT_ENOMEM, "out of memory for %zu %s", n, what);
    *p = q;
    *cap = n;
    return CT_OK;
}

#endif

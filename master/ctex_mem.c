/* ctex_mem.c: the pool of large texel arrays (ctex_mem.h). A few dozen
 * arrays at most: a linear best-fit search is all it needs. Samples land
 * anywhere in 5-15 million texels (tens of MiB), so arrays come from
 * ct_huge_alloc (common/hugemem.h), huge pages from 2 MiB on; sizes are not
 * rounded up (the tail past the last whole 2 MiB stays in small pages), so
 * the memory cap's count (ctex_tex_bytes) stays true. */
#include "master/ctex_mem.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "common/hugemem.h"

typedef struct block {
    void *p;
    size_t bytes;
} block;

struct ctex_mem {
    pthread_mutex_t lock;
    block *b;            /* kept arrays, oldest first */
    size_t n, cap;
    size_t held, keep;
    size_t reused, fresh;
};

ctex_mem *ctex_mem_new(size_t keep_bytes)
{
    ctex_mem *m = calloc(1, sizeof *m);
    if (!m) return NULL;
    if (pthread_mutex_init(&m->lock, NULL)) {
        free(m);
        return NULL;
    }
    m->keep = keep_bytes;
    return m;
}

void ctex_mem_free(ctex_mem *m)
{
    if (!m) return;
    for (size_t i = 0; i < m->n; i++) free(m->b[i].p);
    free(m->b);
    pthread_mutex_destroy(&m->lock);
    free(m);
}

void *ctex_mem_get(ctex_mem *m, size_t bytes)
{
    if (!m || bytes < CT_HUGE_PAGE) return ct_huge_alloc(bytes);
    size_t slack = bytes / 4 > CT_HUGE_PAGE ? bytes / 4 : CT_HUGE_PAGE;
    pthread_mutex_lock(&m->lock);
    size_t best = m->n;
    for (size_t i = 0; i < m->n; i++)
        if (m->b[i].bytes >= bytes && m->b[i].bytes - bytes <= slack &&
            (best == m->n || m->b[i].bytes < m->b[best].bytes))
            best = i;
    void *p = NULL;
    if (best < m->n) {
        p = m->b[best].p;
        m->held -= m->b[best].bytes;
        memmove(m->b + best, m->b + best + 1, (m->n - best - 1) * sizeof *m->b);
        m->n--;
        m->reused++;
    } else {
        m->fresh++;
    }
    pthread_mutex_unlock(&m->lock);
    return p ? p : ct_huge_alloc(bytes);
}

void ctex_mem_put(ctex_mem *m, void *p, size_t bytes)
{
    if (!p) return;
    if (!m || bytes < CT_HUGE_PAGE || bytes > m->keep) {
        free(p);
        return;
    }
    /* A reused array may be larger than its texture asked for; it comes
     * back with the size asked for, which it holds at least. */
    pthread_mutex_lock(&m->lock);
    while (m->n && m->held + bytes > m->keep) {
        free(m->b[0].p);
        m->held -= m->b[0].bytes;
        memmove(m->b, m->b + 1, (m->n - 1) * sizeof *m->b);
        m->n--;
    }
    if (m->n == m->cap) {
        size_t cap = m->cap ? 2 * m->cap : 16;
        block *nb = realloc(m->b, cap * sizeof *nb);
        if (!nb) {
            pthread_mutex_unlock(&m->lock);
            free(p);
            return;
        }
        m->b = nb;
        m->cap = cap;
    }
    m->b[m->n++] = (block){p, bytes};
    m->held += bytes;
    pthread_mutex_unlock(&m->lock);
}

size_t ctex_mem_held(ctex_mem *m)
{
    if (!m) return 0;
    pthread_mutex_lock(&m->lock);
    size_t h = m->held;
    pthread_mutex_unlock(&m->lock);
    return h;
}

void ctex_mem_counts(ctex_mem *m, size_t *reused, size_t *fresh)
{
    *reused = *fresh = 0;
    if (!m) return;
    pthread_mutex_lock(&m->lock);
    *reused = m->reused;
    *fresh = m->fresh;
    pthread_mutex_unlock(&m->lock);
}

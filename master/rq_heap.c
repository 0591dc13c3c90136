/* rq_heap.c: 4-ary max-heap of rq_item (see rq_heap.h). A 4-ary heap halves
 * the depth of a binary one and its four children share one or two cache
 * lines, which is what matters at a million queued requests. */
#include "master/rq_heap.h"

#include <stdlib.h>

int rq_heap_init(rq_heap *h, size_t initial_cap, size_t max_items, ct_error *err)
{
    memset(h, 0, sizeof *h);
    if (initial_cap < 16) initial_cap = 16;
    if (max_items && initial_cap > max_items) initial_cap = max_items;
    h->a = malloc(initial_cap * sizeof *h->a);
    if (!h->a)
        return ct_fail(err, CT_ENOMEM, "request queue: cannot allocate %zu items", initial_cap);
    h->cap = initial_cap;
    h->max = max_items;
    h->grows = 1;
    return 0;
}

void rq_heap_free(rq_heap *h)
{
    free(h->a);
    memset(h, 0, sizeof *h);
}

static int grow(rq_heap *h)
{
    if (h->max && h->cap >= h->max) return CT_ENOMEM;
    size_t ncap = h->cap ? h->cap * 2 : 16;
    if (h->max && ncap > h->max) ncap = h->max;
    rq_item *na = realloc(h->a, ncap * sizeof *na);
    if (!na) return CT_ENOMEM;
    h->a = na;
    h->cap = ncap;
    h->grows++;
    return 0;
}

int rq_heap_push(rq_heap *h, const rq_item *it)
{
    if (h->n == h->cap) {
        int rc = grow(h);
        if (rc) return rc;
    }
    rq_item *a = h->a;
    size_t i = h->n++;
    uint64_t key = it->key;
    /* Sift up: move parents down until the new key fits. */
    while (i > 0) {
        size_t p = (i - 1) >> 2;
        if (a[p].key >= key) break;
        a[i] = a[p];
        i = p;
    }
    a[i] = *it;
    return 0;
}

bool rq_heap_pop(rq_heap *h, rq_item *out)
{
    if (h->n == 0) return false;
    rq_item *a = h->a;
    *out = a[0];
    size_t n = --h->n;
    if (n == 0) return true;
    rq_item last = a[n];
    uint64_t key = last.key;
    size_t i = 0;
    /* Sift down: promote the largest of up to four children. */
    for (;;) {
        size_t c = 4 * i + 1;
        if (c >= n) break;
        size_t best = c;
        uint64_t bk = a[c].key;
        size_t end = c + 4 < n ? c + 4 : n;
        for (size_t j = c + 1; j < end; j++)
            if (a[j].key > bk) { bk = a[j].key; best = j; }
        if (bk <= key) break;
        a[i] = a[best];
        i = best;
    }
    a[i] = last;
    return true;
}

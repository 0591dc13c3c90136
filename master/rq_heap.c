/* rq_heap.c: the request queue's buckets of 4-ary max-heaps (see
 * rq_heap.h). A 4-ary heap halves the depth of a binary one; with 16-byte
 * entries aligned so that a node's four children fill exactly one cache
 * line, each level of a sift-down costs one cache miss at most, and in a
 * bucket of a few thousand entries the levels stay in the caches. */
#include "master/rq_heap.h"

#include <stdlib.h>
#include <string.h>

static inline int bucket_of(uint64_t key)
{
    return (int)(key >> RQ_BUCKET_SHIFT);
}

/* The (empty) buckets. */
static int buckets_init(rq_heap *h)
{
    h->b = calloc(RQ_BUCKETS, sizeof *h->b);
    return h->b ? 0 : CT_ENOMEM;
}

/* The highest non-empty bucket at or below b, -1 when none. */
static int highest_used(const rq_heap *h, int b)
{
    for (int w = b >> 6; w >= 0; w--) {
        uint64_t m = h->used[w];
        if (w == b >> 6 && (b & 63) != 63) m &= ((uint64_t)2 << (b & 63)) - 1;
        if (m) return (w << 6) + 63 - __builtin_clzll(m);
    }
    return -1;
}

/* Room for one more entry in bucket k: its array doubles when full. */
static int bucket_room(rq_heap *h, rq_bucket *k)
{
    if (k->n < k->cap) return 0;
    uint32_t ncap = k->cap ? 2 * k->cap : 64;
    size_t bytes = ((size_t)ncap + 4) * sizeof(rq_hent);
    bytes = (bytes + 63) & ~(size_t)63;
    rq_hent *mem = aligned_alloc(64, bytes);
    if (!mem) return CT_ENOMEM;
    if (k->n) memcpy(mem + 3, k->a, k->n * sizeof *k->a);
    free(k->mem);
    k->mem = mem;
    k->a = mem + 3;
    k->cap = ncap;
    h->grows++;
    return 0;
}

/* Room for cap payload slots, keeping hw slots and nfree free ones. */
static int payload_room(rq_heap *h, size_t cap)
{
    rq_payload *pl = malloc(cap * sizeof *pl);
    uint32_t *freel = malloc(cap * sizeof *freel);
    if (!pl || !freel) {
        free(pl);
        free(freel);
        return CT_ENOMEM;
    }
    if (h->pl) {
        memcpy(pl, h->pl, h->hw * sizeof *pl);
        memcpy(freel, h->freel, h->nfree * sizeof *freel);
    }
    free(h->pl);
    free(h->freel);
    h->pl = pl;
    h->freel = freel;
    h->cap = cap;
    h->grows++;
    return 0;
}

int rq_heap_init(rq_heap *h, size_t initial_cap, size_t max_items, ct_error *err)
{
    memset(h, 0, sizeof *h);
    h->top = -1;
    if (max_items > UINT32_MAX) max_items = UINT32_MAX;
    if (initial_cap < 16) initial_cap = 16;
    if (max_items && initial_cap > max_items) initial_cap = max_items;
    h->max = max_items;
    if (buckets_init(h) != 0 || payload_room(h, initial_cap) != 0) {
        rq_heap_free(h);
        return ct_fail(err, CT_ENOMEM, "request queue: cannot allocate %zu items", initial_cap);
    }
    return 0;
}

void rq_heap_free(rq_heap *h)
{
    if (h->b)
        for (int i = 0; i < RQ_BUCKETS; i++) free(h->b[i].mem);
    free(h->b);
    free(h->pl);
    free(h->freel);
    memset(h, 0, sizeof *h);
    h->top = -1;
}

void rq_heap_clear(rq_heap *h)
{
    for (int w = 0; w < RQ_BUCKETS / 64; w++) {
        for (uint64_t m = h->used[w]; m; m &= m - 1) h->b[(w << 6) + __builtin_ctzll(m)].n = 0;
        h->used[w] = 0;
    }
    h->top = -1;
    h->n = h->hw = h->nfree = 0;
}

int rq_heap_init_keys(rq_heap *h, size_t max_items, ct_error *err)
{
    memset(h, 0, sizeof *h);
    h->top = -1;
    h->max = max_items > UINT32_MAX ? UINT32_MAX : max_items;
    if (buckets_init(h) != 0)
        return ct_fail(err, CT_ENOMEM, "request queue: cannot allocate its buckets");
    return 0;
}

/* Enters (key, slot, tag) into its bucket, which has room. */
static void insert(rq_heap *h, rq_bucket *k, int bi, uint64_t key, uint32_t slot, uint32_t tag)
{
    rq_hent *a = k->a;
    size_t i = k->n++;
    /* Sift up: move parents down until the new key fits. */
    while (i > 0) {
        size_t q = (i - 1) >> 2;
        if (a[q].key >= key) break;
        a[i] = a[q];
        i = q;
    }
    a[i].key = key;
    a[i].slot = slot;
    a[i].tag = tag;
    h->n++;
    h->used[bi >> 6] |= (uint64_t)1 << (bi & 63);
    if (bi > h->top) h->top = bi;
}

int rq_heap_push(rq_heap *h, const rq_item *it)
{
    if (h->n == h->cap) {
        if (h->max && h->cap >= h->max) return CT_ENOMEM;
        size_t ncap = h->cap * 2;
        if (h->max && ncap > h->max) ncap = h->max;
        if (payload_room(h, ncap) != 0) return CT_ENOMEM;
    }
    int bi = bucket_of(it->key);
    rq_bucket *k = &h->b[bi];
    if (bucket_room(h, k) != 0) return CT_ENOMEM;
    uint32_t slot = h->nfree ? h->freel[--h->nfree] : (uint32_t)h->hw++;
    rq_payload *p = &h->pl[slot];
    p->parent = it->parent;
    p->px = it->px;
    p->py = it->py;
    p->radius = it->radius;
    p->kind = it->kind;
    insert(h, k, bi, it->key, slot, it->tag);
    return 0;
}

int rq_heap_push_key(rq_heap *h, uint64_t key, uint32_t tag, uint32_t aux)
{
    if ((h->max && h->n >= h->max) || h->n >= UINT32_MAX) return CT_ENOMEM;
    int bi = bucket_of(key);
    rq_bucket *k = &h->b[bi];
    if (bucket_room(h, k) != 0) return CT_ENOMEM;
    insert(h, k, bi, key, aux, tag);
    return 0;
}

/* Frees the top's slot and restores the top bucket's heap without it. */
static void remove_top(rq_heap *h)
{
    rq_bucket *k = &h->b[h->top];
    rq_hent *a = k->a;
    if (h->pl) h->freel[h->nfree++] = a[0].slot;
    h->n--;
    size_t n = --k->n;
    if (n == 0) {
        int bi = h->top;
        h->used[bi >> 6] &= ~((uint64_t)1 << (bi & 63));
        h->top = bi > 0 ? highest_used(h, bi - 1) : -1;
        if (h->n == 0) h->hw = h->nfree = 0;
        return;
    }
    rq_hent last = a[n];
    uint64_t key = last.key;
    size_t i = 0;
    /* Sift down: promote the largest of up to four children. */
    for (;;) {
        size_t c = 4 * i + 1;
        if (c >= n) break;
        size_t best = c;
        uint64_t bk = a[c].key;
        if (c + 3 < n) {
            /* The next level's line is one of these four children's: ask
             * for all four before choosing, so their misses overlap. */
            size_t g = 4 * c + 1;
            if (g < n) {
                __builtin_prefetch(&a[g]);
                __builtin_prefetch(&a[g + 4]);
                __builtin_prefetch(&a[g + 8]);
                __builtin_prefetch(&a[g + 12]);
            }
            /* Full group: branch-light maximum of four. */
            uint64_t k1 = a[c + 1].key, k2 = a[c + 2].key, k3 = a[c + 3].key;
            size_t b01 = k1 > bk ? c + 1 : c;
            uint64_t m01 = k1 > bk ? k1 : bk;
            size_t b23 = k3 > k2 ? c + 3 : c + 2;
            uint64_t m23 = k3 > k2 ? k3 : k2;
            best = m23 > m01 ? b23 : b01;
            bk = m23 > m01 ? m23 : m01;
        } else {
            for (size_t j = c + 1; j < n; j++)
                if (a[j].key > bk) { bk = a[j].key; best = j; }
        }
        if (bk <= key) break;
        a[i] = a[best];
        i = best;
    }
    a[i] = last;
}

bool rq_heap_pop(rq_heap *h, rq_item *out)
{
    if (h->n == 0) return false;
    const rq_hent *top = &h->b[h->top].a[0];
    const rq_payload *p = &h->pl[top->slot];
    out->key = top->key;
    out->tag = top->tag;
    out->parent = p->parent;
    out->px = p->px;
    out->py = p->py;
    out->radius = p->radius;
    out->kind = p->kind;
    remove_top(h);
    return true;
}

void rq_heap_drop(rq_heap *h)
{
    if (h->n) remove_top(h);
}

bool rq_heap_pop_key(rq_heap *h, uint64_t *key, uint32_t *tag, uint32_t *aux)
{
    if (h->n == 0) return false;
    const rq_hent *top = &h->b[h->top].a[0];
    *key = top->key;
    *tag = top->tag;
    *aux = top->slot;
    remove_top(h);
    return true;
}

/* rq_heap.h: the request priority queue of the sampler (§3.7): max-heaps
 * of fixed-size items in buckets by priority. Pushing and popping never
 * allocate; an array only grows (doubling) when it is full, up to a cap.
 * Order is total and deterministic: higher priority first, and among equal
 * priorities the item pushed first (lower sequence number) first, both packed
 * into one 64-bit key so a comparison is a single integer compare. */
#ifndef CT_RQ_HEAP_H
#define CT_RQ_HEAP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "common/error.h"

/* Where a queued request came from (statistics and docs only). */
enum {
    RQ_KIND_SEED      = 0,  /* initial jittered grid */
    RQ_KIND_CHILD     = 1,  /* child of a returned sample */
    RQ_KIND_MISMATCH  = 2,  /* child of a sample whose node did not match */
    RQ_KIND_GLOBAL    = 3,  /* random global request (queue ran dry) */
    RQ_KIND_REPROJECT = 4,  /* reprojected significant sample */
    RQ_KIND_LIST      = 5,  /* remaining-pixel list */
    RQ_KIND_REFINE    = 6   /* refinement past full coverage (rq_refine.h) */
};

/* One queued request as pushed and popped. */
typedef struct rq_item {
    uint64_t key;     /* rq_key(priority, seq) */
    uint64_t parent;  /* id of the request whose sample spawned it, 0 = none */
    float px, py;     /* image position, pixels */
    float radius;     /* domain radius s, pixels */
    uint32_t kind;    /* RQ_KIND_* */
    uint32_t tag;     /* kept beside the key (the engine: the request's pixel), readable at the top without the rest */
} rq_item;

/* Storage: the 16-byte (key, slot, tag) entries sit in buckets by the
 * key's top 13 bits (the priority's exponent and its first 4 mantissa bits:
 * 16 buckets an octave), each bucket a 4-ary max-heap laid out so that the
 * four children of a node share one 64-byte cache line. Every key of a
 * bucket is above every key of a lower one, so the highest item is the top
 * of the highest non-empty bucket (a bitmap finds it), and the order is the
 * one heap's over all keys. Why: pops are most of the queue's time, and a
 * pop's sift-down in one heap of half a million entries missed the caches
 * at every level; the top bucket holds a few thousand (docs/sampling.md,
 * "Performance and memory"). The rest of an item waits in a slot of a
 * payload pool (free slots on a stack) and is touched once on push and
 * once on pop; an item dropped unread (rq_heap_drop: the engine's requests
 * for pixels handed out since they were queued, most of its pops) is never
 * touched again. */
typedef struct rq_hent {
    uint64_t key;
    uint32_t slot;      /* payload slot; a keys-only heap: the caller's aux value */
    uint32_t tag;
} rq_hent;

typedef struct rq_payload {
    uint64_t parent;
    float px, py, radius;
    uint32_t kind;
} rq_payload;

enum {
    RQ_BUCKET_SHIFT = 51,                       /* bucket = key >> 51 (bit 63 is the sign: 0) */
    RQ_BUCKETS = 1 << (63 - RQ_BUCKET_SHIFT)    /* 4096 */
};

typedef struct rq_bucket {
    rq_hent *mem;       /* allocation (64-byte aligned), NULL until first used */
    rq_hent *a;         /* mem + 3: a[4i+1..4i+4] start on a cache line */
    uint32_t n, cap;
} rq_bucket;

typedef struct rq_heap {
    rq_bucket *b;                       /* RQ_BUCKETS */
    uint64_t used[RQ_BUCKETS / 64];     /* non-empty buckets */
    int top;                            /* the highest non-empty bucket, -1 when empty */
    rq_payload *pl;     /* payload slots; NULL: a keys-only heap */
    uint32_t *freel;    /* stack of free slots below hw */
    size_t nfree;
    size_t hw;          /* slots ever used since the last clear */
    size_t n;           /* items queued */
    size_t cap;         /* payload slots allocated */
    size_t max;         /* cap on n (0 = none) */
    uint64_t grows;     /* allocations made so far (for the no-allocation check) */
} rq_heap;

/* The 64-bit key of an item: the priority's bits (non-negative floats order
 * like their bit patterns; negative and NaN count as 0) above the complement
 * of the sequence number, so that earlier pushes win ties. */
static inline uint64_t rq_key(float priority, uint32_t seq)
{
    uint32_t bits;
    if (!(priority > 0.0f)) priority = 0.0f;
    memcpy(&bits, &priority, sizeof bits);
    return ((uint64_t)bits << 32) | (uint64_t)(UINT32_MAX - seq);
}

/* The priority packed in a key. */
static inline float rq_key_priority(uint64_t key)
{
    uint32_t bits = (uint32_t)(key >> 32);
    float p;
    memcpy(&p, &bits, sizeof p);
    return p;
}

/* Allocates room for initial_cap items; max_items caps the size (0 = none). */
int rq_heap_init(rq_heap *h, size_t initial_cap, size_t max_items, ct_error *err);

/* Frees the array; h may be zeroed or initialised. */
void rq_heap_free(rq_heap *h);

/* Empties the queue, keeping its memory. */
void rq_heap_clear(rq_heap *h);

/* Queues a copy of *it. Returns 0, or CT_ENOMEM when the cap is reached or
 * growing failed (the item is then not queued and the heap is unchanged). */
int rq_heap_push(rq_heap *h, const rq_item *it);

/* Removes the highest item into *out; false when empty. */
bool rq_heap_pop(rq_heap *h, rq_item *out);

/* Removes the highest item without reading it (its payload's cache line
 * stays cold); nothing when empty. */
void rq_heap_drop(rq_heap *h);

/* A keys-only heap: entries of (key, tag, aux) and no payload pool, for a
 * queue whose items fit in the entry (the refinement's pixels,
 * rq_refine.h); the same buckets, order and cap. */
int rq_heap_init_keys(rq_heap *h, size_t max_items, ct_error *err);

/* Queues (key, tag, aux) on a keys-only heap: 0, or CT_ENOMEM at the cap
 * or when growing failed (the heap is then unchanged). */
int rq_heap_push_key(rq_heap *h, uint64_t key, uint32_t tag, uint32_t aux);

/* Removes the highest entry of a keys-only heap into *key, *tag, *aux;
 * false when empty. */
bool rq_heap_pop_key(rq_heap *h, uint64_t *key, uint32_t *tag, uint32_t *aux);

/* The highest item's tag; the heap must not be empty. */
static inline uint32_t rq_heap_top_tag(const rq_heap *h) { return h->b[h->top].a[0].tag; }

/* The highest key, or 0 when empty. */
static inline uint64_t rq_heap_top_key(const rq_heap *h) { return h->n ? h->b[h->top].a[0].key : 0; }

#endif

/* Unit tests of the request heap (master/rq_heap.c) and the sampled-pixel
 * mask with its remaining-pixel list (master/rq_mask.c). */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/rng.h"
#include "master/rq_heap.h"
#include "master/rq_mask.h"

typedef struct ref { float prio; uint32_t seq; } ref;

static int cmp_ref(const void *a, const void *b)
{
    const ref *x = a, *y = b;
    if (x->prio != y->prio) return x->prio > y->prio ? -1 : 1;
    return x->seq < y->seq ? -1 : (x->seq > y->seq ? 1 : 0);
}

Test(rq_heap, key_orders_priority_then_sequence)
{
    cr_assert(rq_key(2.0f, 0) > rq_key(1.0f, 0));
    cr_assert(rq_key(1.0f, 0) > rq_key(1.0f, 1), "equal priority: earlier push first");
    cr_assert(rq_key(1e-30f, 5) > rq_key(0.0f, 0));
    cr_assert(rq_key(INFINITY, 9) > rq_key(3e38f, 0));
    cr_assert_eq(rq_key(-1.0f, 3), rq_key(0.0f, 3), "negative priorities count as 0");
    cr_assert_eq(rq_key(NAN, 3), rq_key(0.0f, 3), "NaN counts as 0");
    cr_assert_eq(rq_key_priority(rq_key(0.375f, 77)), 0.375f);
}

Test(rq_heap, pops_in_priority_order_with_fifo_ties)
{
    rq_heap h;
    ct_error err;
    cr_assert_eq(rq_heap_init(&h, 16, 0, &err), 0);
    enum { N = 20000 };
    ref *r = malloc(N * sizeof *r);
    ct_rng g = rng_make(7, 0, 0, 0);
    for (uint32_t i = 0; i < N; i++) {
        /* Few distinct values, so ties are frequent. */
        r[i].prio = (float)rng_below(&g, 50) * 0.25f;
        r[i].seq = i;
        rq_item it = {rq_key(r[i].prio, i), i, (float)i, 0, 1, 0, 0};
        cr_assert_eq(rq_heap_push(&h, &it), 0);
    }
    qsort(r, N, sizeof *r, cmp_ref);
    for (uint32_t i = 0; i < N; i++) {
        rq_item it;
        cr_assert(rq_heap_pop(&h, &it));
        cr_assert_eq(rq_key_priority(it.key), r[i].prio, "pop %u: priority", i);
        cr_assert_eq(it.parent, r[i].seq, "pop %u: tie order", i);
    }
    rq_item it;
    cr_assert_not(rq_heap_pop(&h, &it));
    int used = 0;
    for (int b = 0; b < RQ_BUCKETS; b++) {
        if (!h.b[b].mem) continue;
        used++;
        cr_assert_eq((uintptr_t)(h.b[b].a + 1) % 64, 0u, "bucket %d: children groups start on a cache line", b);
    }
    cr_assert_gt(used, 10, "items of %d priorities in %d buckets", 50, used);
    cr_assert_lt(h.grows, 8 * (uint64_t)used, "doubling growth, not one allocation per push (%llu for %d buckets)",
                 (unsigned long long)h.grows, used);
    free(r);
    rq_heap_free(&h);
}

Test(rq_heap, interleaved_push_pop_matches_reference)
{
    rq_heap h;
    cr_assert_eq(rq_heap_init(&h, 4, 0, NULL), 0);
    ref pool[4096];
    int np = 0;
    uint32_t seq = 0;
    ct_rng g = rng_make(11, 0, 0, 0);
    for (int step = 0; step < 20000; step++) {
        if (np < 4096 && (np == 0 || rng_below(&g, 3) != 0)) {
            float p = rng_float(&g) * 100.0f;
            /* the tag travels beside the key: here a function of the item */
            rq_item it = {rq_key(p, seq), seq, (float)seq, 0, 0, 0, seq * 2654435761u};
            cr_assert_eq(rq_heap_push(&h, &it), 0);
            pool[np].prio = p;
            pool[np].seq = seq++;
            np++;
        } else {
            int best = 0;
            for (int i = 1; i < np; i++)
                if (cmp_ref(&pool[i], &pool[best]) < 0) best = i;
            cr_assert_eq(rq_heap_top_tag(&h), pool[best].seq * 2654435761u, "step %d: top tag", step);
            if (step % 3 == 0) {
                /* dropped unread: the next pop is the next in order */
                rq_heap_drop(&h);
            } else {
                rq_item it;
                cr_assert(rq_heap_pop(&h, &it));
                cr_assert_eq(it.parent, pool[best].seq, "step %d", step);
                cr_assert_eq(it.px, (float)pool[best].seq, "step %d: payload", step);
                cr_assert_eq(it.tag, pool[best].seq * 2654435761u, "step %d: tag", step);
            }
            pool[best] = pool[--np];
        }
        cr_assert_eq(h.n, (size_t)np);
    }
    rq_heap_free(&h);
}

Test(rq_heap, cap_refuses_and_keeps_heap_intact)
{
    rq_heap h;
    cr_assert_eq(rq_heap_init(&h, 2, 40, NULL), 0);
    for (uint32_t i = 0; i < 40; i++) {
        rq_item it = {rq_key((float)i, i), i, 0, 0, 0, 0, 0};
        cr_assert_eq(rq_heap_push(&h, &it), 0);
    }
    rq_item extra = {rq_key(1000.0f, 99), 99, 0, 0, 0, 0, 0};
    cr_assert_eq(rq_heap_push(&h, &extra), CT_ENOMEM);
    cr_assert_eq(h.n, 40u);
    rq_item it;
    cr_assert(rq_heap_pop(&h, &it));
    cr_assert_eq(it.parent, 39u, "the refused item did not enter");
    rq_heap_clear(&h);
    rq_heap_drop(&h);   /* empty: nothing */
    cr_assert_eq(h.n, 0u);
    /* cleared buckets take items again, in order across buckets */
    for (uint32_t i = 0; i < 6; i++) {
        rq_item again = {rq_key((float)(i % 3) * 0.001f + (float)(i / 3) * 1000.0f, i), i, 0, 0, 0, 0, i};
        cr_assert_eq(rq_heap_push(&h, &again), 0);
    }
    static const uint32_t order[] = {5, 4, 3, 2, 1, 0};
    for (int i = 0; i < 6; i++) {
        cr_assert(rq_heap_pop(&h, &it));
        cr_assert_eq(it.parent, order[i], "after clear, pop %d", i);
    }
    cr_assert_eq(rq_heap_top_key(&h), 0u);
    rq_heap_free(&h);
}

Test(rq_heap, buckets_split_octaves_and_keep_one_order)
{
    /* priorities straddling bucket boundaries (16 an octave), equal ones
     * (FIFO), zero and denormal-small ones: pops come in key order */
    static const float pr[] = {1.0f, 1.0624f, 1.0625f, 1.0626f, 2.0f, 0.0f, 1e-40f, 1.0f, 3e38f, 0.5f, 1.0625f};
    enum { N = sizeof pr / sizeof pr[0] };
    rq_heap h;
    cr_assert_eq(rq_heap_init(&h, 4, 0, NULL), 0);
    for (uint32_t i = 0; i < N; i++) {
        rq_item it = {rq_key(pr[i], i), i, 0, 0, 0, 0, 100 + i};
        cr_assert_eq(rq_heap_push(&h, &it), 0);
    }
    uint64_t last = UINT64_MAX;
    for (uint32_t i = 0; i < N; i++) {
        cr_assert_eq(rq_heap_top_key(&h), rq_key(pr[rq_heap_top_tag(&h) - 100], rq_heap_top_tag(&h) - 100));
        rq_item it;
        cr_assert(rq_heap_pop(&h, &it));
        cr_assert_lt(it.key, last, "pop %u out of order", i);
        last = it.key;
    }
    cr_assert_eq(h.n, 0u);
    cr_assert_eq(h.top, -1);
    rq_heap_free(&h);
}

Test(rq_heap, keys_only_heap_orders_and_carries_tag_and_aux)
{
    rq_heap h;
    ct_error err;
    cr_assert_eq(rq_heap_init_keys(&h, 0, &err), 0);
    cr_assert_null(h.pl, "no payload pool");
    enum { N = 30000 };
    ref *r = malloc(N * sizeof *r);
    ct_rng g = rng_make(5, 0, 0, 0);
    uint32_t seq = 0, popped = 0;
    /* pushes and pops interleaved, as refinement requeues a pixel after each
     * sample: a reference list sorted at every pop is the oracle */
    size_t nr = 0;
    for (int step = 0; step < 3 * N; step++) {
        if (nr < N && (nr == 0 || rng_below(&g, 3) != 0)) {
            float p = (float)rng_below(&g, 40) * 0.125f;
            r[nr++] = (ref){p, seq};
            cr_assert_eq(rq_heap_push_key(&h, rq_key(p, seq), seq ^ 0xabcdu, seq * 3u), 0);
            seq++;
        } else {
            qsort(r, nr, sizeof *r, cmp_ref);
            uint64_t key;
            uint32_t tag, aux;
            cr_assert(rq_heap_pop_key(&h, &key, &tag, &aux));
            cr_assert_eq(rq_key_priority(key), r[0].prio, "pop %u: priority", popped);
            cr_assert_eq(tag, r[0].seq ^ 0xabcdu, "pop %u: tag", popped);
            cr_assert_eq(aux, r[0].seq * 3u, "pop %u: aux", popped);
            memmove(r, r + 1, (nr - 1) * sizeof *r);
            nr--;
            popped++;
        }
    }
    cr_assert_eq(h.n, nr);
    rq_heap_clear(&h);
    uint64_t key;
    uint32_t tag, aux;
    cr_assert_not(rq_heap_pop_key(&h, &key, &tag, &aux), "empty after a clear");
    rq_heap_free(&h);

    /* a cap refuses and keeps what is queued */
    cr_assert_eq(rq_heap_init_keys(&h, 3, &err), 0);
    for (uint32_t i = 0; i < 3; i++) cr_assert_eq(rq_heap_push_key(&h, rq_key(1.0f + (float)i, i), i, i), 0);
    cr_assert_eq(rq_heap_push_key(&h, rq_key(9.0f, 3), 3, 3), CT_ENOMEM);
    cr_assert(rq_heap_pop_key(&h, &key, &tag, &aux));
    cr_assert_eq(tag, 2u, "the highest of the three");
    cr_assert_eq(rq_heap_push_key(&h, rq_key(9.0f, 3), 3, 3), 0, "room again after a pop");
    free(r);
    rq_heap_free(&h);
}

Test(rq_mask, test_set_counts_each_pixel_once)
{
    rq_mask m;
    cr_assert_eq(rq_mask_init(&m, 13, 7, NULL), 0);
    cr_assert_not(rq_mask_test_set(&m, 0));
    cr_assert(rq_mask_test_set(&m, 0));
    cr_assert_not(rq_mask_test_set(&m, 90));
    cr_assert(rq_mask_test(&m, 90));
    cr_assert_not(rq_mask_test(&m, 89));
    cr_assert_eq(m.count, 2u);
    rq_mask_clear(&m);
    cr_assert_eq(m.count, 0u);
    cr_assert_not(rq_mask_test(&m, 90));
    rq_mask_free(&m);
}

Test(rq_mask, bad_size_is_an_error)
{
    rq_mask m;
    ct_error err;
    cr_assert_eq(rq_mask_init(&m, 0, 5, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "0x5") != NULL, "%s", err.msg);
}

Test(rq_mask, remaining_list_holds_exactly_the_unset_pixels_shuffled)
{
    enum { W = 37, H = 11 };   /* not a multiple of 64: checks the tail word */
    rq_mask m;
    cr_assert_eq(rq_mask_init(&m, W, H, NULL), 0);
    ct_rng g = rng_make(3, 0, 0, 0);
    for (int i = 0; i < 300; i++) rq_mask_test_set(&m, rng_below(&g, W * H));
    uint64_t unset = W * H - m.count;
    cr_assert_eq(rq_mask_build_list(&m, 5, 2, NULL), 0);
    cr_assert_eq(m.list_n, unset);
    int seen[W * H] = {0};
    bool sorted = true;
    for (size_t i = 0; i < m.list_n; i++) {
        cr_assert_lt(m.list[i], (uint32_t)(W * H));
        cr_assert_not(rq_mask_test(&m, m.list[i]));
        seen[m.list[i]]++;
        if (i && m.list[i] < m.list[i - 1]) sorted = false;
    }
    for (int p = 0; p < W * H; p++) cr_assert_eq(seen[p], rq_mask_test(&m, (uint32_t)p) ? 0 : 1);
    cr_assert_not(sorted, "the list is shuffled");
    /* A pixel set after the list was built is skipped. */
    uint32_t skip = m.list[1];
    rq_mask_test_set(&m, skip);
    uint32_t p, n = 0;
    while (rq_mask_list_next(&m, &p)) {
        cr_assert_neq(p, skip);
        n++;
    }
    cr_assert_eq(n, unset - 1);
    cr_assert_eq(m.count, (uint64_t)(W * H));
    rq_mask_free(&m);
}

Test(rq_mask, shuffle_is_deterministic)
{
    rq_mask a, b;
    cr_assert_eq(rq_mask_init(&a, 16, 16, NULL), 0);
    cr_assert_eq(rq_mask_init(&b, 16, 16, NULL), 0);
    cr_assert_eq(rq_mask_build_list(&a, 9, 1, NULL), 0);
    cr_assert_eq(rq_mask_build_list(&b, 9, 1, NULL), 0);
    cr_assert_eq(memcmp(a.list, b.list, a.list_n * sizeof *a.list), 0);
    cr_assert_eq(rq_mask_build_list(&b, 9, 2, NULL), 0);
    cr_assert_neq(memcmp(a.list, b.list, a.list_n * sizeof *a.list), 0, "another epoch, another order");
    rq_mask_free(&a);
    rq_mask_free(&b);
}

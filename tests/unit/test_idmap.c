/* test_idmap.c: the id -> index hash map (common/idmap.h) against a plain
 * reference under a long random run of puts, updates and deletes (ids
 * clustered so that probe runs collide and deletions shift entries back),
 * including the extreme ids 0 and 2^32 - 1; clearing keeps it usable; the
 * empty mark is refused as a value. */
#include <criterion/criterion.h>
#include <stdlib.h>

#include "common/idmap.h"

#define NKEYS 3000

/* Keys: consecutive runs, multiples of 2^16 (the same low bits) and the ends. */
static uint32_t key_of(int k)
{
    if (k == 0) return 0;
    if (k == 1) return UINT32_MAX;
    if (k == 2) return UINT32_MAX - 1;
    return k % 3 == 0 ? (uint32_t)k << 16 : (uint32_t)k + 1000000u;
}

static void check_all(const ct_idmap *m, const uint32_t *ref)
{
    uint32_t n = 0;
    for (int k = 0; k < NKEYS; k++) {
        cr_assert_eq(idmap_get(m, key_of(k)), ref[k], "key %u: %u, want %u", key_of(k), idmap_get(m, key_of(k)),
                     ref[k]);
        n += ref[k] != IDMAP_NONE;
    }
    cr_assert_eq(m->n, n);
}

Test(idmap, random_operations_match_a_reference)
{
    ct_idmap m = {0};
    uint32_t *ref = malloc(NKEYS * sizeof *ref);
    for (int k = 0; k < NKEYS; k++) ref[k] = IDMAP_NONE;
    cr_assert_eq(idmap_get(&m, 5), IDMAP_NONE);
    idmap_del(&m, 5);   /* empty: nothing */
    uint64_t s = 12345;
    ct_error err;
    for (int step = 0; step < 200000; step++) {
        s = s * 6364136223846793005ull + 1442695040888963407ull;
        int k = (int)((s >> 33) % NKEYS);
        if ((s >> 20) % 3 == 0) {
            idmap_del(&m, key_of(k));
            ref[k] = IDMAP_NONE;
        } else {
            uint32_t v = (uint32_t)(s >> 40);
            cr_assert_eq(idmap_put(&m, key_of(k), v, &err), 0, "%s", err.msg);
            ref[k] = v;
        }
        if (step % 20000 == 0) check_all(&m, ref);
    }
    check_all(&m, ref);
    idmap_clear(&m);
    for (int k = 0; k < NKEYS; k++) ref[k] = IDMAP_NONE;
    check_all(&m, ref);
    cr_assert_eq(idmap_put(&m, 3, IDMAP_NONE, &err), CT_EINVAL);   /* the empty mark */
    cr_assert_eq(idmap_get(&m, 3), IDMAP_NONE);
    cr_assert_eq(idmap_put(&m, UINT32_MAX, 7, &err), 0);
    cr_assert_eq(idmap_get(&m, UINT32_MAX), 7u);
    idmap_free(&m);
    cr_assert_eq(m.cap, 0u);
    cr_assert_eq(idmap_get(&m, UINT32_MAX), IDMAP_NONE);
    free(ref);
}

/* The pool of texel arrays (master/ctex_mem.h): a given-back array serves
 * the next request of a fitting size, small arrays and arrays past the
 * bound are not kept, the oldest make room, and the arrays are usable
 * memory (written whole, under AddressSanitizer in make test-asan). */
#include <criterion/criterion.h>
#include <stdint.h>
#include <string.h>

#include "master/ctex_mem.h"

#define MIB ((size_t)1 << 20)

Test(ctex_mem, a_given_back_array_serves_the_next_request)
{
    ctex_mem *m = ctex_mem_new(64 * MIB);
    cr_assert_not_null(m);
    void *a = ctex_mem_get(m, 8 * MIB);
    cr_assert_not_null(a);
    cr_assert_eq((uintptr_t)a % (2 * MIB), 0, "a large array is not 2 MiB-aligned");
    memset(a, 1, 8 * MIB);
    ctex_mem_put(m, a, 8 * MIB);
    cr_assert_eq(ctex_mem_held(m), 8 * MIB);
    /* a request up to a quarter smaller: the same array */
    void *b = ctex_mem_get(m, 7 * MIB);
    cr_assert_eq(b, a);
    cr_assert_eq(ctex_mem_held(m), 0);
    memset(b, 2, 7 * MIB);
    ctex_mem_put(m, b, 7 * MIB);
    /* much smaller, or larger: a fresh one */
    void *c = ctex_mem_get(m, 3 * MIB), *d = ctex_mem_get(m, 9 * MIB);
    cr_assert(c != b && d != b);
    memset(c, 3, 3 * MIB);
    memset(d, 4, 9 * MIB);
    size_t reused, fresh;
    ctex_mem_counts(m, &reused, &fresh);
    cr_assert_eq(reused, 1);
    cr_assert_eq(fresh, 3);
    ctex_mem_put(m, c, 3 * MIB);
    ctex_mem_put(m, d, 9 * MIB);
    ctex_mem_free(m);   /* frees what it keeps (LeakSanitizer checks) */
}

Test(ctex_mem, the_bound_keeps_the_newest)
{
    ctex_mem *m = ctex_mem_new(20 * MIB);
    cr_assert_not_null(m);
    void *a = ctex_mem_get(m, 8 * MIB), *b = ctex_mem_get(m, 8 * MIB), *c = ctex_mem_get(m, 8 * MIB);
    void *big = ctex_mem_get(m, 24 * MIB), *small = ctex_mem_get(m, 1 * MIB);
    cr_assert(a && b && c && big && small);
    ctex_mem_put(m, a, 8 * MIB);
    ctex_mem_put(m, b, 8 * MIB);
    ctex_mem_put(m, c, 8 * MIB);   /* a makes room */
    cr_assert_eq(ctex_mem_held(m), 16 * MIB);
    ctex_mem_put(m, big, 24 * MIB);     /* past the bound: freed */
    ctex_mem_put(m, small, 1 * MIB);    /* small: freed */
    cr_assert_eq(ctex_mem_held(m), 16 * MIB);
    void *x = ctex_mem_get(m, 8 * MIB), *y = ctex_mem_get(m, 8 * MIB);
    cr_assert((x == b && y == c) || (x == c && y == b), "the kept ones are not the newest two");
    ctex_mem_put(m, x, 8 * MIB);
    ctex_mem_put(m, y, 8 * MIB);
    ctex_mem_free(m);
    /* without a pool: the system's */
    void *z = ctex_mem_get(NULL, 4 * MIB);
    cr_assert_not_null(z);
    ctex_mem_put(NULL, z, 4 * MIB);
}

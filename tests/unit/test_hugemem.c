/* Huge-page arrays (common/hugemem.h): zeroed on first touch, writable
 * end to end, aligned to 2 MiB from that size on, given back. */
#include <criterion/criterion.h>
#include <stdint.h>
#include <stdlib.h>

#include "common/hugemem.h"

Test(hugemem, zalloc_is_zero_and_writable)
{
    static const size_t sizes[] = {0, 1, 4096, CT_HUGE_PAGE - 8, 3 * (size_t)CT_HUGE_PAGE + 100};
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
        size_t n = sizes[k];
        unsigned char *p = ct_huge_zalloc(n);
        cr_assert_not_null(p, "%zu bytes", n);
        for (size_t i = 0; i < n; i += 4093) cr_assert_eq(p[i], 0, "%zu bytes: byte %zu not zero", n, i);
        if (n > 1) {
            p[0] = 1;
            p[n - 1] = 2;
            cr_assert_eq(p[0] + p[n - 1], 3);
        }
        ct_huge_zfree(p, n);
    }
    ct_huge_zfree(NULL, 0);
}

Test(hugemem, alloc_aligns_large_arrays)
{
    unsigned char *small = ct_huge_alloc(1000), *large = ct_huge_alloc(2 * (size_t)CT_HUGE_PAGE + 1);
    cr_assert(small && large);
    cr_assert_eq((uintptr_t)large % CT_HUGE_PAGE, 0u, "a large array starts on a huge page");
    large[2 * (size_t)CT_HUGE_PAGE] = 7;
    small[999] = 7;
    free(small);
    free(large);
}

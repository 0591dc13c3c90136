/* Screen order (tracer/screen_order.h): the curve's keys, a batch's
 * permutation and the sorted runs of pixels. */
#include <criterion/criterion.h>
#include <stdlib.h>
#include <string.h>

#include "common/rng.h"
#include "tracer/screen_order.h"

Test(screen_order, keys_follow_the_z_curve_and_clamp)
{
    cr_expect_eq(so_key(0, 0), 0u);
    cr_expect_eq(so_key(1, 0), 1u);
    cr_expect_eq(so_key(0, 1), 2u);
    cr_expect_eq(so_key(1, 1), 3u);
    cr_expect_eq(so_key(2, 0), 4u);
    cr_expect_eq(so_key(0xffff, 0xffff), 0xffffffffu);
    cr_expect_eq(so_key(70000, 3), so_key(0xffff, 3), "x beyond 16 bits clamps");
    /* a 2 x 2 block's four pixels are consecutive keys */
    cr_expect_eq(so_key(7, 5) - so_key(6, 4), 3u);
}

Test(screen_order, a_batch_permutation_visits_each_request_once_along_the_curve)
{
    enum { N = 3000 };
    static ct_request req[N];
    static uint32_t perm[N];
    ct_rng g = rng_make(5, 0, 0, 0);
    for (int i = 0; i < N; i++) {
        memset(&req[i], 0, sizeof req[i]);
        req[i].px = 1024.0f * rng_float(&g);
        req[i].py = 768.0f * rng_float(&g);
    }
    /* out of range positions clamp instead of wrapping */
    req[0].px = -3.0f;
    req[0].py = 0.5f;
    req[1].py = 1e9f;
    req[2].px = req[3].px = 10.5f;
    req[2].py = req[3].py = 20.5f;
    so_buf b = {0};
    cr_assert_eq(so_requests(&b, req, N, perm), CT_OK);
    static unsigned char seen[N];
    memset(seen, 0, sizeof seen);
    uint32_t last = 0;
    int pos2 = -1, pos3 = -1;
    for (int i = 0; i < N; i++) {
        cr_assert_lt(perm[i], (uint32_t)N);
        cr_assert_eq(seen[perm[i]], 0, "request %u twice", perm[i]);
        seen[perm[i]] = 1;
        const ct_request *r = &req[perm[i]];
        uint32_t x = r->px > 0.0f ? (uint32_t)r->px : 0u, y = r->py < 65535.0f ? (uint32_t)r->py : 65535u;
        uint32_t k = so_key(x, y);
        cr_assert_geq(k, last, "step %d goes back along the curve", i);
        last = k;
        if (perm[i] == 2) pos2 = i;
        if (perm[i] == 3) pos3 = i;
    }
    cr_expect_lt(pos2, pos3, "requests of one pixel keep their order");
    /* reused scratch, a smaller batch */
    cr_assert_eq(so_requests(&b, req, 4, perm), CT_OK);
    cr_expect(perm[0] == 0 && perm[1] == 2 && perm[2] == 3 && perm[3] == 1, "%u %u %u %u", perm[0], perm[1], perm[2],
              perm[3]);
    so_free(&b);
}

Test(screen_order, pixels_are_sorted_within_their_runs_only)
{
    enum { W = 50, H = 40, N = W * H, RUN = 300 };
    static uint32_t pix[N], orig[N];
    for (uint32_t i = 0; i < N; i++) pix[i] = i;
    ct_rng g = rng_make(8, 0, 0, 0);
    for (uint32_t i = N; i > 1; i--) {
        uint32_t k = rng_below(&g, i), t = pix[i - 1];
        pix[i - 1] = pix[k];
        pix[k] = t;
    }
    memcpy(orig, pix, sizeof pix);
    so_buf b = {0};
    cr_assert_eq(so_pixels(&b, pix, N, W, RUN), CT_OK);
    for (size_t a = 0; a < N; a += RUN) {
        size_t m = N - a < RUN ? N - a : RUN;
        static unsigned char in_run[N];
        memset(in_run, 0, sizeof in_run);
        for (size_t i = 0; i < m; i++) in_run[orig[a + i]] = 1;
        for (size_t i = 0; i < m; i++) {
            cr_assert(in_run[pix[a + i]], "pixel %u left its run at %zu", pix[a + i], a);
            in_run[pix[a + i]] = 0;
            if (i) cr_assert_lt(so_key(pix[a + i - 1] % W, pix[a + i - 1] / W), so_key(pix[a + i] % W, pix[a + i] / W));
        }
    }
    /* run 0: the whole set, which is then the curve through the image */
    cr_assert_eq(so_pixels(&b, pix, N, W, 0), CT_OK);
    cr_expect_eq(pix[0], 0u);
    cr_expect_eq(pix[1], 1u);
    cr_expect_eq(pix[2], (uint32_t)W);
    cr_expect_eq(so_pixels(&b, pix, N, 0, 0), CT_EINVAL);
    so_free(&b);
}

Test(screen_order, a_batch_goes_out_along_the_curve_and_its_samples_come_back_in_request_order)
{
    so_batch b = {0};
    ct_rng g = rng_make(11, 0, 0, 0);
    const size_t sizes[] = {5, 700, 64};   /* grows, then reuses its room */
    for (size_t t = 0; t < sizeof sizes / sizeof sizes[0]; t++) {
        size_t n = sizes[t];
        ct_request *req = calloc(n, sizeof *req);
        ct_sample *out = calloc(n, sizeof *out);
        cr_assert(req && out);
        for (size_t i = 0; i < n; i++) {
            req[i].id = 100 + i;
            req[i].px = 512.0f * rng_float(&g);
            req[i].py = 512.0f * rng_float(&g);
        }
        cr_assert_eq(so_batch_order(&b, req, n), CT_OK);
        for (size_t i = 0; i < n; i++) {
            if (i)
                cr_assert_leq(so_key((uint32_t)b.req[i - 1].px, (uint32_t)b.req[i - 1].py),
                              so_key((uint32_t)b.req[i].px, (uint32_t)b.req[i].py), "step %zu goes back", i);
            /* a stand-in tracer: each sample names its request */
            b.out[i].request_id = b.req[i].id;
        }
        so_batch_scatter(&b, n, out);
        for (size_t i = 0; i < n; i++) cr_assert_eq(out[i].request_id, req[i].id, "sample %zu is not its request's", i);
        free(req);
        free(out);
    }
    so_batch_free(&b);
    cr_expect(b.req == NULL && b.cap == 0);
}

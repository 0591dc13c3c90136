/* The parallel insertion (ctex_insert_par): the same as one sample at a time
 * when a call holds one sample or no resolution changes, and independent of
 * the number of threads that split the textures. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/half.h"
#include "common/pool.h"
#include "common/radmesh.h"
#include "common/rng.h"
#include "common/scene.h"
#include "master/ctex.h"
#include "master/ctex_hier.h"
#include "master/ctex_tex.h"
#include "tests/support/ctex_scenes.h"

static ct_error err;

static void same_textures(ctex *a, ctex *b, const char *what)
{
    ctex_stats sa = ctex_get_stats(a), sb = ctex_get_stats(b);
    cr_assert_eq(sa.texels, sb.texels, "%s: texel counts differ", what);
    cr_assert_eq(sa.resizes, sb.resizes, "%s: resize counts differ", what);
    cr_assert_eq(sa.inserted, sb.inserted, "%s", what);
    cr_assert_eq(sa.dropped, sb.dropped, "%s", what);
    for (uint32_t tex = 0; tex < 64; tex++) {
        int wa, ha, wb, hb;
        int live = ctex_texture_info(a, tex, NULL, &wa, &ha, NULL, NULL, NULL);
        cr_assert_eq(ctex_texture_info(b, tex, NULL, &wb, &hb, NULL, NULL, NULL), live);
        if (live < 0) continue;
        cr_assert(wa == wb && ha == hb, "%s: texture %u is %dx%d and %dx%d", what, tex, wa, ha, wb, hb);
        float *pa = malloc((size_t)wa * (size_t)ha * 3 * sizeof *pa), *pb = malloc((size_t)wa * (size_t)ha * 3 * sizeof *pb);
        cr_assert_eq(ctex_read_patch(a, tex, 0, 0, wa, ha, pa, &err), 0);
        cr_assert_eq(ctex_read_patch(b, tex, 0, 0, wb, hb, pb, &err), 0);
        cr_assert_eq(memcmp(pa, pb, (size_t)wa * (size_t)ha * 3 * sizeof *pa), 0, "%s: texture %u differs", what, tex);
        free(pa);
        free(pb);
    }
}

/* Samples on the floor and, every fifth, on a plate: several textures. */
static ct_sample *scattered_samples(const tcx_scene *t, int n)
{
    ct_sample *s = malloc((size_t)n * sizeof *s);
    ct_rng r = rng_make(77, 0, 0, 0);
    for (int i = 0; i < n; i++) {
        vec3 p = v3(-8.0f + 16.0f * rng_float(&r), 0.0f, -8.0f + 16.0f * rng_float(&r));
        uint32_t node = (uint32_t)t->floor;
        if (i % 5 == 0) {
            int g = (int)rng_below(&r, 3);
            p = v3(-4.0f + 4.0f * (float)g - 0.5f + rng_float(&r), 1.01f, -0.5f + rng_float(&r));
            node = (uint32_t)t->plate[g];
        }
        s[i] = tcx_sample(node, p, v3(rng_float(&r), rng_float(&r), rng_float(&r)), v3s(0.3f));
    }
    return s;
}

/* ctex_insert_par one sample a call inserts exactly like ctex_insert: the
 * same infos and texels, through enough samples to make textures grow. */
Test(ctex_parallel, parallel_insert_of_one_equals_single_inserts)
{
    tcx_scene t;
    tcx_build(&t);
    ctex_options o = ctex_options_default();
    o.splat_window = 16;
    ctex *a = tcx_engine(&t, o), *b = tcx_engine(&t, o);
    ct_camera cam = tcx_front_cam();
    cr_assert_eq(ctex_set_camera(a, &cam, 96, 96, &err), 0);
    cr_assert_eq(ctex_set_camera(b, &cam, 96, 96, &err), 0);
    enum { N = 4096 };
    ct_sample *s = scattered_samples(&t, N);
    ctex_insert_info *ia = malloc(N * sizeof *ia), *ib = malloc(N * sizeof *ib);
    for (int i = 0; i < N; i++) ctex_insert_par(a, NULL, s + i, 1, ia + i);
    for (int i = 0; i < N; i++) ctex_insert(b, &s[i], &ib[i]);
    for (int i = 0; i < N; i++)
        cr_assert_eq(memcmp(&ia[i], &ib[i], sizeof ia[i]), 0, "sample %d: infos differ", i);
    cr_assert_gt(ctex_get_stats(a).resizes, 0, "the textures should have grown");
    same_textures(a, b, "one sample a call");
    free(s); free(ia); free(ib);
    ctex_free(a);
    ctex_free(b);
    tcx_release(&t);
}

/* Batches inserted on 1, 2 and 3 threads (textures partitioned over them)
 * give the same infos, texels, resizes and events. */
Test(ctex_parallel, parallel_insert_independent_of_threads)
{
    tcx_scene t;
    tcx_build(&t);
    ctex_options o = ctex_options_default();
    o.splat_window = 16;
    enum { N = 12000, B = 1200 };   /* B over PAR_MIN_SAMPLES (ctex_insert.c): the threads take part */
    ct_sample *s = scattered_samples(&t, N);
    ctex *ref = NULL;
    ctex_insert_info *iref = malloc(N * sizeof *iref), *ii = malloc(N * sizeof *ii);
    ct_camera cam = tcx_front_cam();
    for (int threads = 1; threads <= 3; threads++) {
        ct_pool *pool = NULL;
        cr_assert_eq(pool_new(threads, &pool, &err), 0, "%s", err.msg);
        ctex *c = tcx_engine(&t, o);
        cr_assert_eq(ctex_set_camera(c, &cam, 96, 96, &err), 0);
        size_t nev_total = 0;
        for (int i = 0; i < N; i += B) {
            ctex_stats before = ctex_get_stats(c);
            ctex_insert_par(c, pool, s + i, B, (threads == 1 ? iref : ii) + i);
            ctex_stats after = ctex_get_stats(c);
            cr_assert_leq(after.resizes - before.resizes, before.textures,
                          "a texture changed its resolution twice in one call");
            size_t nev;
            ctex_events(c, &nev);
            nev_total += nev;
            ctex_events_clear(c);
        }
        pool_free(pool);
        cr_assert_gt(ctex_get_stats(c).resizes, 0, "the textures should have grown");
        cr_assert_gt(nev_total, 0);
        if (threads == 1) {
            ref = c;
            continue;
        }
        for (int i = 0; i < N; i++) cr_assert_eq(memcmp(&ii[i], &iref[i], sizeof ii[i]), 0, "%d threads: sample %d", threads, i);
        same_textures(ref, c, "1 thread against more");
        ctex_free(c);
    }
    /* Without resolution changes a batch is exactly the samples one by one,
     * in order, whatever the split over threads. */
    o.splat_window = 1000000;
    ctex *one = tcx_engine(&t, o), *par = tcx_engine(&t, o);
    cr_assert_eq(ctex_set_camera(one, &cam, 96, 96, &err), 0);
    cr_assert_eq(ctex_set_camera(par, &cam, 96, 96, &err), 0);
    ct_pool *pool = NULL;
    cr_assert_eq(pool_new(2, &pool, &err), 0, "%s", err.msg);
    for (int i = 0; i < N; i += B) ctex_insert_par(par, pool, s + i, B, ii + i);
    for (int i = 0; i < N; i++) ctex_insert(one, &s[i], &iref[i]);
    for (int i = 0; i < N; i++) cr_assert_eq(memcmp(&ii[i], &iref[i], sizeof ii[i]), 0, "in order: sample %d", i);
    same_textures(one, par, "one by one against 2 threads");
    pool_free(pool);
    ctex_free(one);
    ctex_free(par);
    free(s); free(iref); free(ii);
    ctex_free(ref);
    tcx_release(&t);
}


/* Determinism of the per-sample API (any batch order, any thread) and of the
 * reference renderer (any thread count): bit-identical records and images.
 * reuse-diffuse: corrections L_hq - L_base are never negative, except on
 * glass, whose L_base is the view through it. */
#include <criterion/criterion.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/radmesh.h"
#include "common/rng.h"
#include "tests/support/testscenes.h"
#include "tracer/render.h"
#include "tracer/tracer.h"

#define NREQ 384

static ct_scene *room;
static ct_radmesh rad;

static void setup(void)
{
    ct_error err;
    room = ts_room(&err);
    cr_assert(room, "room: %s", err.msg);
    cr_assert_eq(rmesh_from_scene(room, v3s(0.2f), &rad, &err), 0, "%s", err.msg);
}

static void teardown(void)
{
    rmesh_free(&rad);
    scene_free(room);
}

static trc_tracer *tracer_for(trc_mode mode, bool with_rad)
{
    trc_options o;
    trc_options_default(&o, mode);
    o.seed = 42;
    o.depth = mode == TRC_MODE_PATH ? 12 : 4;
    o.branch = 2;
    o.shadow_rays = 2;
    trc_tracer *t;
    ct_error err;
    cr_assert_eq(trc_new(room, with_rad ? &rad : NULL, &o, &t, &err), 0, "%s", err.msg);
    return t;
}

static trc_view room_view(void)
{
    trc_view v;
    v.cam = room->cams[0].cam;
    v.width = 64;
    v.height = 48;
    return v;
}

/* Renders the room's first camera under o into img (results in *r), which
 * must succeed. */
static void render_ok(const trc_tracer *t, const render_options *o, float *img, render_result *r)
{
    ct_error err;
    cr_assert_eq(render_image(t, &room->cams[0].cam, o, img, r, &err), 0, "%s", err.msg);
}

static void make_requests(ct_request *req, int n)
{
    ct_rng g = rng_make(3, 0, 0, 0);
    for (int i = 0; i < n; i++) {
        memset(&req[i], 0, sizeof req[i]);
        req[i].id = 1000 + (uint64_t)i * 7;
        req[i].epoch = (uint32_t)(i % 3);
        req[i].px = 64.0f * rng_float(&g);
        req[i].py = 48.0f * rng_float(&g);
    }
}

typedef struct half_job {
    const trc_tracer *t;
    const trc_view *v;
    const ct_request *req;
    ct_sample *out;
    int first, step, n;
} half_job;

static void *trace_strided(void *arg)
{
    half_job *h = arg;
    trc_stats st = {0};
    for (int i = h->first; i < h->n; i += h->step) trc_trace(h->t, h->v, &h->req[i], 1, &h->out[i], &st);
    return NULL;
}

static void check_batches(trc_mode mode, bool with_rad)
{
    trc_tracer *t = tracer_for(mode, with_rad);
    trc_view v = room_view();
    static ct_request req[NREQ], shuffled[NREQ];
    static ct_sample a[NREQ], b[NREQ], c[NREQ];
    make_requests(req, NREQ);
    trc_stats st = {0};
    trc_trace(t, &v, req, NREQ, a, &st);
    cr_assert(st.samples == NREQ && trc_stats_rays(&st) >= NREQ);

    /* Reversed order in batches of varying size. */
    int perm[NREQ];
    for (int i = 0; i < NREQ; i++) perm[i] = NREQ - 1 - i;
    ct_rng g = rng_make(9, 9, 9, 9);
    for (int i = NREQ - 1; i > 0; i--) {
        int k = (int)rng_below(&g, (uint32_t)i + 1), x = perm[i];
        perm[i] = perm[k];
        perm[k] = x;
    }
    for (int i = 0; i < NREQ; i++) shuffled[i] = req[perm[i]];
    for (int at = 0, size = 1; at < NREQ; at += size, size = size % 37 + 5) {
        int n = at + size <= NREQ ? size : NREQ - at;
        trc_trace(t, &v, shuffled + at, (size_t)n, b + at, &st);
    }
    for (int i = 0; i < NREQ; i++)
        cr_assert(memcmp(&a[perm[i]], &b[i], sizeof a[0]) == 0, "%s: request %llu differs in a shuffled batch",
                  trc_mode_name(mode), (unsigned long long)req[perm[i]].id);

    /* Two threads, interleaved. */
    pthread_t th[2];
    half_job h[2];
    for (int k = 0; k < 2; k++) {
        h[k] = (half_job){t, &v, req, c, k, 2, NREQ};
        cr_assert_eq(pthread_create(&th[k], NULL, trace_strided, &h[k]), 0);
    }
    for (int k = 0; k < 2; k++) pthread_join(th[k], NULL);
    cr_assert(memcmp(a, c, sizeof a) == 0, "%s: records differ when traced on two threads",
              trc_mode_name(mode));
    trc_free(t);
}

Test(determinism, path_any_batch_order_and_thread, .init = setup, .fini = teardown)
{
    check_batches(TRC_MODE_PATH, false);
}

Test(determinism, drt_any_batch_order_and_thread, .init = setup, .fini = teardown)
{
    check_batches(TRC_MODE_DRT, true);
}

Test(determinism, reuse_any_batch_order_and_thread, .init = setup, .fini = teardown)
{
    check_batches(TRC_MODE_REUSE, true);
}

Test(determinism, seed_changes_the_samples, .init = setup, .fini = teardown)
{
    trc_tracer *t1 = tracer_for(TRC_MODE_PATH, false);
    trc_options o = *trc_get_options(t1);
    o.seed = 43;
    trc_tracer *t2;
    ct_error err;
    cr_assert_eq(trc_new(room, NULL, &o, &t2, &err), 0);
    trc_view v = room_view();
    static ct_request req[64];
    static ct_sample a[64], b[64];
    make_requests(req, 64);
    trc_stats st = {0};
    trc_trace(t1, &v, req, 64, a, &st);
    trc_trace(t2, &v, req, 64, b, &st);
    int differ = 0;
    for (int i = 0; i < 64; i++) differ += memcmp(&a[i].l_hq, &b[i].l_hq, sizeof a[i].l_hq) != 0;
    cr_expect(differ > 32, "only %d of 64 samples changed with the seed", differ);
    trc_free(t1);
    trc_free(t2);
}

Test(determinism, reference_image_independent_of_threads, .init = setup, .fini = teardown)
{
    trc_tracer *t = tracer_for(TRC_MODE_DRT, false);
    render_options o;
    render_options_default(&o, 40, 30);
    o.spp = 2;
    o.tile = 8;
    float *img1 = calloc(40 * 30 * 3, sizeof(float)), *img2 = calloc(40 * 30 * 3, sizeof(float));
    cr_assert(img1 && img2);
    render_result r1, r2;
    render_ok(t, &o, img1, &r1);
    o.threads = 3;
    o.tile = 16;
    render_ok(t, &o, img2, &r2);
    cr_expect(memcmp(img1, img2, 40 * 30 * 3 * sizeof(float)) == 0, "image differs with 3 threads");
    cr_expect(r1.stats.samples == 40 * 30 * 2 && r2.stats.samples == r1.stats.samples);
    cr_expect(trc_stats_rays(&r1.stats) == trc_stats_rays(&r2.stats), "ray counts differ");
    double sum = 0;
    for (int i = 0; i < 40 * 30 * 3; i++) sum += img1[i];
    cr_expect(sum > 0.0, "black image");
    free(img1);
    free(img2);
    trc_free(t);
}

Test(determinism, reference_image_independent_of_pixel_order, .init = setup, .fini = teardown)
{
    /* 37 x 29 with tiles of 5: the last task of the shuffled order is short,
     * and 3 spp make calls of 21 pixels */
    trc_tracer *t = tracer_for(TRC_MODE_DRT, false);
    enum { W = 37, H = 29 };
    render_options o;
    render_options_default(&o, W, H);
    o.spp = 3;
    o.tile = 5;
    static float tiles[W * H * 3], other[W * H * 3];
    render_result r1, r2;
    render_ok(t, &o, tiles, &r1);
    const size_t runs[] = {0, 1, 7, 100000};
    for (size_t i = 0; i < sizeof runs / sizeof runs[0]; i++) {
        memset(other, 0, sizeof other);
        o.order = RENDER_ORDER_SHUFFLED;
        o.sort_runs = runs[i];
        o.threads = 2;
        render_ok(t, &o, other, &r2);
        cr_expect(memcmp(tiles, other, sizeof tiles) == 0, "shuffled order, runs of %zu: image differs", runs[i]);
        cr_expect(r2.stats.samples == (uint64_t)W * H * 3, "shuffled order traced %llu samples",
                  (unsigned long long)r2.stats.samples);
        cr_expect(trc_stats_rays(&r1.stats) == trc_stats_rays(&r2.stats), "ray counts differ");
    }
    ct_error err;
    o.order = 7;
    cr_expect_eq(render_image(t, &room->cams[0].cam, &o, other, &r2, &err), CT_EINVAL);
    trc_free(t);
}

Test(determinism, raw_replay_counts_the_logged_rays, .init = setup, .fini = teardown)
{
    trc_tracer *t = tracer_for(TRC_MODE_PATH, false);
    render_options o;
    render_options_default(&o, 32, 24);
    o.threads = 2;
    o.raylog_cap = 100000;
    float *img = calloc(32 * 24 * 3, sizeof(float));
    render_result r;
    render_ok(t, &o, img, &r);
    /* Every ray fits in the log: the replay covers all of them. */
    cr_expect(r.logged == trc_stats_rays(&r.stats), "logged %llu of %llu rays", (unsigned long long)r.logged,
              (unsigned long long)trc_stats_rays(&r.stats));
    cr_expect(r.replay_isect_s > 0.0 && r.replay_traced_s > 0.0);
    /* The rays are logged in a second, untimed pass: the image and the ray
     * counts are those of a render without the log. */
    float *plain = calloc(32 * 24 * 3, sizeof(float));
    render_result r0;
    o.raylog_cap = 0;
    render_ok(t, &o, plain, &r0);
    cr_expect(memcmp(img, plain, 32 * 24 * 3 * sizeof(float)) == 0, "the logging pass changed the image");
    cr_expect_eq(trc_stats_rays(&r0.stats), trc_stats_rays(&r.stats));
    cr_expect_eq(r0.logged, 0);
    free(plain);
    free(img);
    trc_free(t);
}

Test(reuse, corrections_never_negative, .init = setup, .fini = teardown)
{
    trc_tracer *t = tracer_for(TRC_MODE_REUSE, true);
    trc_view v = room_view();
    enum { N = 4000 };
    static ct_request req[N];
    static ct_sample out[N];
    ct_rng g = rng_make(5, 0, 0, 0);
    for (int i = 0; i < N; i++) {
        memset(&req[i], 0, sizeof req[i]);
        req[i].id = (uint64_t)i + 1;
        req[i].px = 64.0f * rng_float(&g);
        req[i].py = 48.0f * rng_float(&g);
    }
    trc_stats st = {0};
    trc_trace(t, &v, req, N, out, &st);
    int positive = 0, hits = 0, glass = 0, through = 0;
    for (int i = 0; i < N; i++) {
        if (!(out[i].flags & CT_SAMPLE_HIT)) continue;
        hits++;
        cr_assert(out[i].flags & CT_SAMPLE_HAS_BASE);
        /* Glass shows the room behind it in the interactive solution; its
         * Fresnel loss and refraction make corrections of either sign. */
        if (room->mats[rad.tri_mat[out[i].tri]].dielectric) {
            glass++;
            cr_assert(v3_finite(out[i].l_base) && out[i].l_base.x >= 0.0f && out[i].l_base.y >= 0.0f && out[i].l_base.z >= 0.0f, "glass sample %d: L_base %g %g %g",
                      i, (double)out[i].l_base.x, (double)out[i].l_base.y, (double)out[i].l_base.z);
            through += v3_maxc(out[i].l_base) > 0.0f;
            continue;
        }
        vec3 base = rmesh_eval(&rad, out[i].tri, out[i].u, out[i].v);
        cr_assert(memcmp(&base, &out[i].l_base, sizeof base) == 0, "l_base is not Gouraud at the hit");
        vec3 d = v3_sub(out[i].l_hq, out[i].l_base);
        cr_assert(d.x >= 0.0f && d.y >= 0.0f && d.z >= 0.0f,
                  "negative correction (%g %g %g) at request %d", (double)d.x, (double)d.y, (double)d.z, i);
        positive += v3_maxc(d) > 1e-3f;
    }
    cr_expect(hits == N, "closed room: every primary ray hits (%d of %d)", hits, N);
    cr_expect(glass > 0 && through > glass / 2, "%d samples on the glass, %d see the room behind it", glass,
              through);
    /* The glossy, mirror and glass surfaces must add something. */
    cr_expect(positive > N / 20, "only %d samples carry a correction", positive);
    trc_free(t);
}

Test(tracer_api, rejects_bad_options, .init = setup, .fini = teardown)
{
    trc_options o;
    trc_tracer *t;
    ct_error err;
    trc_options_default(&o, TRC_MODE_REUSE);
    cr_expect_eq(trc_new(room, NULL, &o, &t, &err), CT_EINVAL);
    cr_expect(strstr(err.msg, "radiosity") != NULL, "%s", err.msg);
    trc_options_default(&o, TRC_MODE_DRT);
    o.shadow_rays = 0;
    cr_expect_eq(trc_new(room, NULL, &o, &t, &err), CT_EINVAL);
    /* A radiosity mesh of another scene. */
    trc_options_default(&o, TRC_MODE_DRT);
    ct_radmesh other;
    cr_assert_eq(rmesh_from_scene(room, v3s(0.0f), &other, &err), 0);
    snprintf(other.nodes[2].name, sizeof other.nodes[2].name, "%s", "elsewhere");
    cr_expect_eq(trc_new(room, &other, &o, &t, &err), CT_ESTALE);
    cr_expect(strstr(err.msg, "elsewhere") != NULL, "%s", err.msg);
    rmesh_free(&other);
}

Test(determinism, capped_ray_log_is_a_spread_subset_in_traced_order, .init = setup, .fini = teardown)
{
    trc_tracer *t = tracer_for(TRC_MODE_DRT, false);
    render_options o;
    render_options_default(&o, 32, 24);
    o.raylog_cap = 500;
    float *img = calloc(32 * 24 * 3, sizeof(float));
    render_result r;
    render_ok(t, &o, img, &r);
    uint64_t rays = trc_stats_rays(&r.stats);
    cr_assert(rays > 10 * 500, "too few rays (%llu) for the test", (unsigned long long)rays);
    cr_expect_eq(r.logged, 500);
    free(img);
    /* The reservoir directly: offer rays through a tracer and check order. */
    trc_raylog log = {calloc(200, sizeof(trc_ray)), 0, 200, 0, 7};
    trc_stats st = {0};
    st.log = &log;
    trc_view v = room_view();
    static ct_request req[NREQ];
    static ct_sample out[NREQ];
    make_requests(req, NREQ);
    trc_trace(t, &v, req, NREQ, out, &st);
    cr_assert_eq(log.seen, trc_stats_rays(&st));
    cr_assert_eq(log.n, 200);
    trc_raylog_sort(&log);
    uint64_t late = 0;
    for (size_t i = 1; i < log.n; i++) cr_assert(log.rays[i].seq > log.rays[i - 1].seq);
    for (size_t i = 0; i < log.n; i++) late += log.rays[i].seq >= log.seen / 2;
    /* A uniform subset: about half of the kept rays come from the second half. */
    cr_expect(late > 60 && late < 140, "%llu of 200 kept rays from the second half", (unsigned long long)late);
    free(log.rays);
    trc_free(t);
}

Test(tracer_api, primary_hits_match_full_records, .init = setup, .fini = teardown)
{
    trc_tracer *t = tracer_for(TRC_MODE_DRT, true);
    trc_view v = room_view();
    static ct_request req[NREQ];
    static ct_sample full[NREQ], prim[NREQ];
    make_requests(req, NREQ);
    trc_stats sf = {0}, sp = {0};
    trc_trace(t, &v, req, NREQ, full, &sf);
    trc_trace_primary(t, &v, req, NREQ, prim, &sp);
    cr_expect_eq(sp.primary, NREQ);
    /* Positions that are not numbers give misses, not crashes. */
    ct_request bad[2] = {req[0], req[1]};
    bad[0].px = NAN;
    bad[1].py = INFINITY;
    ct_sample bo[2];
    trc_trace(t, &v, bad, 2, bo, &sf);
    cr_expect(!(bo[0].flags & CT_SAMPLE_HIT) && !(bo[1].flags & CT_SAMPLE_HIT));
    cr_expect(v3_is_zero(bo[0].l_hq) && bo[0].request_id == req[0].id);
    /* Only the glass hits trace on, straight through it, for L_base. */
    int glass = 0;
    for (int i = 0; i < NREQ; i++) glass += (prim[i].flags & CT_SAMPLE_HIT) && room->mats[rad.tri_mat[prim[i].tri]].dielectric;
    cr_expect_eq(sp.shadow, 0);
    cr_expect(glass ? sp.secondary >= (uint64_t)glass && sp.secondary <= 16u * (uint64_t)glass : sp.secondary == 0,
              "%llu rays through %d glass hits", (unsigned long long)sp.secondary, glass);
    for (int i = 0; i < NREQ; i++) {
        cr_assert_eq(prim[i].request_id, req[i].id);
        cr_assert_eq(prim[i].epoch, req[i].epoch);
        cr_assert_eq(prim[i].flags, full[i].flags);
        cr_assert(prim[i].flags & CT_SAMPLE_HIT);
        cr_assert_eq(prim[i].node, full[i].node);
        cr_assert_eq(prim[i].tri, full[i].tri);
        cr_assert(memcmp(&prim[i].hit, &full[i].hit, sizeof prim[i].hit) == 0);
        cr_assert(memcmp(&prim[i].l_base, &full[i].l_base, sizeof prim[i].l_base) == 0);
        cr_assert(v3_is_zero(prim[i].l_hq));
        /* The hit projects back onto the request's image position. */
        float px, py, depth;
        cr_assert(cam_project(&v.cam, v.width, v.height, prim[i].hit, &px, &py, &depth));
        cr_expect(fabsf(px - req[i].px) < 1e-2f && fabsf(py - req[i].py) < 1e-2f,
                  "hit projects to (%g, %g), request at (%g, %g)", (double)px, (double)py, (double)req[i].px,
                  (double)req[i].py);
    }
    trc_free(t);
}

Test(render, rejects_bad_sizes, .init = setup, .fini = teardown)
{
    trc_tracer *t = tracer_for(TRC_MODE_PATH, false);
    render_options o;
    float px[3];
    render_result r;
    ct_error err;
    render_options_default(&o, 0, 1);
    cr_expect_eq(render_image(t, &room->cams[0].cam, &o, px, &r, &err), CT_EINVAL);
    render_options_default(&o, 1, 1);
    o.spp = 0;
    cr_expect_eq(render_image(t, &room->cams[0].cam, &o, px, &r, &err), CT_EINVAL);
    o.spp = 1;
    o.threads = 0;
    cr_expect_eq(render_image(t, &room->cams[0].cam, &o, px, &r, &err), CT_EINVAL);
    /* more tasks than an int counts: refused before anything is traced */
    render_options_default(&o, 65536, 65536);
    o.tile = 1;
    cr_expect_eq(render_image(t, &room->cams[0].cam, &o, px, &r, &err), CT_EINVAL);
    o.order = RENDER_ORDER_SHUFFLED;
    cr_expect_eq(render_image(t, &room->cams[0].cam, &o, px, &r, &err), CT_EINVAL);
    render_options_default(&o, 65536, 32768);
    o.tile = 1;
    o.order = RENDER_ORDER_SHUFFLED;
    cr_expect_eq(render_image(t, &room->cams[0].cam, &o, px, &r, &err), CT_EINVAL);
    render_options_default(&o, 1, 1);
    cr_expect_eq(render_image(t, &room->cams[0].cam, &o, px, &r, &err), 0, "%s", err.msg);
    cr_expect(px[0] >= 0.0f && r.stats.samples == 1);
    trc_free(t);
}

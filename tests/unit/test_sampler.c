/* (Over 600 lines: one module's tests over one synthetic tracer.)
 * Unit tests of the adaptive sample acquisition (master/sampler.h, §3.7):
 * priorities, children formulas, discarding, coverage of a still camera,
 * concentration on large errors, reprojection, epochs and determinism. The
 * "tracer" here is a plane z = -10 seen by a pinhole camera and a synthetic
 * error field over the image; no component is replaced by a mock. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/image.h"
#include "common/rng.h"
#include "master/rq_refine.h"
#include "master/sampler.h"

#define PLANE_Z (-10.0f)

static ct_camera cam_a(void)
{
    return cam_look_at(v3(0, 0, 0), v3(0, 0, -1), v3(0, 1, 0), 60.0f);
}

/* The sample a tracer would return for request r: the hit on the plane. */
static ct_sample trace(const ct_camera *c, int w, int h, const ct_request *r)
{
    ct_sample s;
    memset(&s, 0, sizeof s);
    s.request_id = r->id;
    s.epoch = r->epoch;
    s.flags = CT_SAMPLE_HIT;
    s.px = r->px;
    s.py = r->py;
    s.node = 1;
    vec3 d = cam_ray_dir(c, w, h, r->px, r->py);
    float t = (PLANE_Z - c->eye.z) / d.z;
    s.hit = v3_madd(c->eye, d, t);
    return s;
}

/* Synthetic error: a bright disc (|E| = 1) on a dim background (0.02). */
static const float DISC_X = 40.0f, DISC_Y = 24.0f, DISC_R = 10.0f;
static bool in_disc(float px, float py)
{
    float dx = px - DISC_X, dy = py - DISC_Y;
    return dx * dx + dy * dy < DISC_R * DISC_R;
}
static vec3 disc_error(float px, float py)
{
    return in_disc(px, py) ? v3(1.0f, 0.5f, -0.25f) : v3(0.02f, -0.01f, 0.0f);
}

/* A smooth field with distinct values, for significance order. */
static vec3 smooth_error(float px, float py)
{
    return v3s(0.01f + 0.5f * (1.0f + sinf(px * 0.3f) * cosf(py * 0.2f)) + px * 1e-4f + py * 1e-6f);
}

/* The §3.7 tests stop at full coverage: no refinement unless o asks. */
static rq_engine *make(int w, int h, const rq_options *o, uint64_t seed)
{
    rq_engine *e = NULL;
    ct_error err;
    ct_camera c = cam_a();
    rq_options d;
    if (!o) {
        rq_options_default(&d);
        d.refine_error = 0.0f;
        o = &d;
    }
    int rc = rq_new(&e, w, h, &c, o, seed, &err);
    cr_assert_eq(rc, 0, "rq_new: %s", err.msg);
    return e;
}

/* The default options with the initial grid spaced `spacing` pixels. */
static rq_options spaced(float spacing)
{
    rq_options o;
    rq_options_default(&o);
    o.seed_spacing = spacing;
    o.refine_error = 0.0f;
    return o;
}

static int batch(rq_engine *e, ct_request *out, int n)
{
    ct_error err;
    int k = rq_next_batch(e, out, n, &err);
    cr_assert_geq(k, 0, "rq_next_batch: %s", err.msg);
    return k;
}

static int report(rq_engine *e, const ct_sample *s, vec3 E, uint32_t shown)
{
    ct_error err;
    int rc = rq_report(e, s, E, shown, &err);
    cr_assert_geq(rc, 0, "rq_report: %s", err.msg);
    return rc;
}

/* Traces request r under camera c (image w x h) and reports its sample with
 * error E, the interactive image showing node `shown`; returns what
 * rq_report returned. */
static int answer(rq_engine *e, const ct_camera *c, int w, int h, const ct_request *r, vec3 E, uint32_t shown)
{
    ct_sample s = trace(c, w, h, r);
    return report(e, &s, E, shown);
}

/* answer() for each of r[0..n), all with error E on node 1. */
static void answer_all(rq_engine *e, const ct_camera *c, int w, int h, const ct_request *r, int n, vec3 E)
{
    for (int i = 0; i < n; i++) answer(e, c, w, h, &r[i], E, 1);
}

Test(sampler, error_norms)
{
    vec3 E = v3(0.1f, -0.5f, 0.2f);
    cr_assert_float_eq(rq_error_norm(E, RQ_NORM_MAX), 0.5f, 1e-7f);
    cr_assert_float_eq(rq_error_norm(E, RQ_NORM_AVG), 0.8f / 3.0f, 1e-6f);
    cr_assert_float_eq(rq_error_norm(E, RQ_NORM_LUM), 0.2126f * 0.1f + 0.7152f * 0.5f + 0.0722f * 0.2f,
                       1e-6f);
    /* Signed channels do not cancel. */
    cr_assert_float_eq(rq_error_norm(v3(-1, 1, 0), RQ_NORM_AVG), 2.0f / 3.0f, 1e-6f);
}

Test(sampler, initial_grid_is_uniform_high_priority_and_spread)
{
    rq_options o = spaced(16);
    rq_engine *e = make(128, 64, &o, 1);
    ct_request r[64];
    int k = batch(e, r, 32);
    cr_assert_eq(k, 32);
    int cells[8][4] = {{0}};
    int left = 0;
    for (int i = 0; i < k; i++) {
        cr_assert_eq(r[i].priority, o.prio_seed);
        cr_assert_eq(r[i].radius, 16.0f, "radius = spacing");
        cr_assert_eq(r[i].parent, 0u);
        cr_assert_eq(r[i].id, (uint64_t)i + 1, "ids count from 1 in hand-out order");
        cells[(int)(r[i].px / 16)][(int)(r[i].py / 16)]++;
        if (r[i].px < 64) left++;
    }
    for (int x = 0; x < 8; x++)
        for (int y = 0; y < 4; y++) cr_assert_leq(cells[x][y], 1, "one request per grid cell");
    /* The first 32 of 32 cells' requests are shuffled over the whole image. */
    cr_assert(left >= 8 && left <= 24, "first batch spread left/right: %d of 32 left", left);
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert_eq(st.seeds, 32u);
    rq_free(e);
}

Test(sampler, children_radius_priority_and_domain)
{
    const int ns[] = {4, 9, 2};
    for (int t = 0; t < 3; t++) {
        rq_options o = spaced(64);
        o.children = ns[t];
        rq_engine *e = make(128, 128, &o, 5);
        ct_camera c = cam_a();
        ct_request r[16];
        cr_assert_eq(batch(e, r, 1), 1);
        ct_request p = r[0];
        cr_assert_eq(p.radius, 64.0f);
        vec3 E = v3(0.1f, -0.5f, 0.2f);   /* |E| = 0.5 under the max norm */
        cr_assert_eq(answer(e, &c, 128, 128, &p, E, 1), 0);
        int k = batch(e, r, 16);
        float sc = 64.0f / sqrtf((float)ns[t]);
        int nchild = 0;
        bool seen_global = false;
        for (int i = 0; i < k; i++) {
            if (i < 3) {
                cr_assert_eq(r[i].parent, 0u, "the other seeds come first");
                cr_assert_eq(r[i].priority, o.prio_seed);
                continue;
            }
            if (r[i].parent != p.id) {
                /* Then the queue is dry: global requests. */
                cr_assert_eq(r[i].parent, 0u);
                cr_assert_eq(r[i].priority, o.prio_seed);
                seen_global = true;
                continue;
            }
            cr_assert_not(seen_global, "children before global requests");
            nchild++;
            cr_assert_float_eq(r[i].radius, sc, 1e-5f, "s_c = s / sqrt(N)");
            cr_assert_float_eq(r[i].priority, 0.5f * sc, 1e-5f, "priority = |E| * s_c");
            cr_assert(fabsf(r[i].px - p.px) <= 32.0f && fabsf(r[i].py - p.py) <= 32.0f,
                      "child inside the parent's domain");
        }
        rq_stats st;
        rq_stats_get(e, &st);
        cr_assert_eq((uint64_t)nchild, st.children);
        cr_assert_eq(st.children + st.discarded_outside + st.discarded_mask, (uint64_t)ns[t],
                     "N=%d: every child queued or counted as discarded", ns[t]);
        cr_assert_gt(nchild, 0);
        rq_free(e);
    }
}

Test(sampler, children_cover_distinct_subcells)
{
    rq_options o = spaced(64);
    rq_engine *e = make(256, 256, &o, 2);
    ct_camera c = cam_a();
    ct_request r[32];
    /* Take all 16 seeds and report one near the middle, away from borders. */
    int k = batch(e, r, 16);
    cr_assert_eq(k, 16);
    int pick = -1;
    for (int i = 0; i < k; i++)
        if (r[i].px > 64 && r[i].px < 192 && r[i].py > 64 && r[i].py < 192) pick = i;
    cr_assert_geq(pick, 0);
    ct_request p = r[pick];
    answer(e, &c, 256, 256, &p, v3s(1.0f), 1);
    k = batch(e, r, 32);
    cr_assert_eq(k, 32);
    int quad[4] = {0};
    for (int i = 0; i < 4; i++) {
        cr_assert_eq(r[i].parent, p.id);
        int q = (r[i].px >= p.px) + 2 * (r[i].py >= p.py);
        quad[q]++;
    }
    for (int q = 0; q < 4; q++) cr_assert_eq(quad[q], 1, "one child per quadrant");
    rq_free(e);
}

Test(sampler, children_under_threshold_are_discarded)
{
    rq_options o = spaced(64);
    o.min_priority = 0.01f;
    rq_engine *e = make(128, 128, &o, 3);
    ct_camera c = cam_a();
    ct_request r[8];
    cr_assert_eq(batch(e, r, 2), 2);
    /* s_c = 32: |E| * 32 = 0.0096 < 0.01 is discarded; 0.0128 is kept. */
    answer(e, &c, 128, 128, &r[0], v3(0.0003f, 0, 0), 1);
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert_eq(st.discarded_threshold, 4u);
    cr_assert_eq(st.children, 0u);
    answer(e, &c, 128, 128, &r[1], v3(0, 0, -0.0004f), 1);
    rq_stats_get(e, &st);
    cr_assert_eq(st.discarded_threshold, 4u);
    cr_assert_eq(st.children + st.discarded_outside, 4u);
    rq_free(e);
}

Test(sampler, no_children_below_min_radius)
{
    rq_options o = spaced(2);   /* children radius 1: made; their children 0.5: not */
    rq_engine *e = make(8, 8, &o, 4);
    ct_camera c = cam_a();
    ct_request r[64];
    int k = batch(e, r, 16);
    cr_assert_eq(k, 16);
    answer(e, &c, 8, 8, &r[0], v3s(1), 1);
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert_eq(st.children + st.discarded_mask + st.discarded_outside, 4u);
    cr_assert_eq(st.leaves, 0u);
    k = batch(e, r, 64);
    for (int i = 0; i < k; i++) {
        if (r[i].radius != 1.0f) continue;
        answer(e, &c, 8, 8, &r[i], v3s(1), 1);
        rq_stats_get(e, &st);
        cr_assert_geq(st.leaves, 1u);
        break;
    }
    rq_free(e);
}

Test(sampler, mask_discards_children_on_sampled_pixels)
{
    rq_options o = spaced(1);
    o.min_radius = 0.25f;
    rq_engine *e = make(2, 2, &o, 6);
    ct_camera c = cam_a();
    ct_request r[8];
    cr_assert_eq(batch(e, r, 8), 4, "one request per pixel, then nothing");
    answer_all(e, &c, 2, 2, r, 4, v3s(1));
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert_eq(st.children, 0u);
    cr_assert_gt(st.discarded_mask, 0u);
    cr_assert_eq(st.discarded_mask + st.discarded_outside, 16u);
    cr_assert_eq(batch(e, r, 8), 0, "every pixel handed out");
    rq_stats_get(e, &st);
    cr_assert_eq(st.coverage, 1.0);
    rq_free(e);
}

Test(sampler, mismatch_is_counted_and_refined_at_high_priority)
{
    rq_options o = spaced(64);
    rq_engine *e = make(128, 128, &o, 7);
    ct_camera c = cam_a();
    ct_request r[16];
    cr_assert_eq(batch(e, r, 4), 4);
    /* Zero error would be discarded, but the interactive image shows node 7. */
    cr_assert_eq(answer(e, &c, 128, 128, &r[0], v3s(0), 7), RQ_REPORT_MISMATCH);
    cr_assert_eq(answer(e, &c, 128, 128, &r[1], v3s(0), RQ_NODE_UNKNOWN), 0, "unknown: no check");
    ct_sample s2 = trace(&c, 128, 128, &r[2]);
    s2.flags = 0;   /* missed everything, and the interactive image shows background */
    cr_assert_eq(report(e, &s2, v3s(0), RQ_NODE_NONE), 0);
    ct_sample s3 = trace(&c, 128, 128, &r[3]);
    s3.flags = 0;   /* missed, but the interactive image shows node 1 */
    cr_assert_eq(report(e, &s3, v3s(0), 1), RQ_REPORT_MISMATCH);
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert_eq(st.mismatches, 2u);
    uint64_t id0 = r[0].id, id3 = r[3].id;
    int k = batch(e, r, 16);
    int nm = 0;
    for (int i = 0; i < k; i++) {
        if (r[i].parent == 0) {
            cr_assert_eq(r[i].priority, o.prio_seed, "then global requests");
            continue;
        }
        cr_assert_eq(i, nm, "mismatch children first");
        cr_assert(r[i].parent == id0 || r[i].parent == id3, "only mismatches have children");
        cr_assert_eq(r[i].priority, o.prio_mismatch);
        cr_assert_float_eq(r[i].radius, 32.0f, 1e-6f);
        nm++;
    }
    cr_assert_gt(nm, 0);
    rq_free(e);
}

/* Drives a still camera until every pixel is handed out; returns the hand-out
 * order as pixel indices. */
static int *converge(rq_engine *e, int w, int h, vec3 (*field)(float, float), int bs, int *count)
{
    ct_camera c = cam_a();
    int *order = malloc((size_t)w * (size_t)h * 2 * sizeof *order);
    int n = 0;
    ct_request r[64];
    for (;;) {
        int k = batch(e, r, bs);
        if (k == 0) break;
        for (int i = 0; i < k; i++) {
            int p = (int)r[i].py * w + (int)r[i].px;
            cr_assert_lt(n, w * h * 2);
            order[n++] = p;
            answer(e, &c, w, h, &r[i], field(r[i].px, r[i].py), 1);
        }
    }
    *count = n;
    return order;
}

/* `covered` (the master's "view covered" line) means every pixel sampled,
 * not "nothing in flight": between lockstep frames nothing is in flight
 * long before the view is covered. */
Test(sampler, covered_only_when_every_pixel_is_sampled)
{
    enum { W = 32, H = 32 };
    rq_engine *e = make(W, H, NULL, 3);
    ct_camera c = cam_a();
    ct_request r[16];
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert_not(st.covered, "a fresh view is not covered");
    int k = batch(e, r, 16);
    cr_assert_eq(k, 16);
    answer_all(e, &c, W, H, r, k, disc_error(r[0].px, r[0].py));
    rq_stats_get(e, &st);
    cr_assert_eq(st.in_flight, 0u);
    cr_assert_lt(st.coverage, 1.0);
    cr_assert_not(st.covered, "16 of %d pixels sampled, nothing in flight: not covered", W * H);
    int n;
    free(converge(e, W, H, disc_error, 16, &n));
    rq_stats_get(e, &st);
    cr_assert_eq(st.coverage, 1.0);
    cr_assert(st.covered);
    rq_free(e);
}

Test(sampler, still_camera_covers_every_pixel_once_and_concentrates_on_error)
{
    /* Eight seeds, each run to full coverage; concentration is measured on
     * the first K samples of each: their share inside the disc against the
     * disc's share of the image area. */
    enum { W = 64, H = 64, K = 256, RUNS = 8 };
    int disc_px = 0;
    for (int p = 0; p < W * H; p++) disc_px += in_disc((float)(p % W) + 0.5f, (float)(p / W) + 0.5f);
    double area_share = (double)disc_px / (W * H);
    double sum_share = 0, min_share = 1;
    for (uint64_t seed = 1; seed <= RUNS; seed++) {
        rq_engine *e = make(W, H, NULL, seed);
        int n;
        int *order = converge(e, W, H, disc_error, 16, &n);
        cr_assert_eq(n, W * H, "seed %d: handed out %d requests for %d pixels", (int)seed, n, W * H);
        static int hits[W * H];
        memset(hits, 0, sizeof hits);
        for (int i = 0; i < n; i++) hits[order[i]]++;
        for (int p = 0; p < W * H; p++) cr_assert_eq(hits[p], 1, "pixel %d sampled %d times", p, hits[p]);
        rq_stats st;
        rq_stats_get(e, &st);
        cr_assert_eq(st.coverage, 1.0);
        cr_assert_eq(st.popped, (uint64_t)(W * H));
        cr_assert_eq(st.list_mode, 1);
        cr_assert_gt(st.from_list, 0u);
        cr_assert_gt(st.global, 0u);
        /* the queue's buckets (rq_heap.h) each double from 64 entries */
        cr_assert_lt(st.allocations, (uint64_t)(W * H) / 32, "buffers grow by doubling, not per request (%llu)",
                     (unsigned long long)st.allocations);
        int first_in = 0;
        for (int i = 0; i < K; i++)
            first_in += in_disc((float)(order[i] % W) + 0.5f, (float)(order[i] / W) + 0.5f);
        double share = (double)first_in / K;
        sum_share += share;
        if (share < min_share) min_share = share;
        free(order);
        rq_free(e);
    }
    double mean_share = sum_share / RUNS;
    cr_log_info("disc: %.1f%% of the area; %.1f%% of the first %d samples on average (%.1fx), "
                "%.1f%% at least (%.1fx)",
                100 * area_share, 100 * mean_share, K, mean_share / area_share, 100 * min_share,
                min_share / area_share);
    cr_assert_gt(mean_share, 4.0 * area_share, "samples concentrate where the error is large: %.3f vs %.3f",
                 mean_share, area_share);
    cr_assert_gt(min_share, 2.0 * area_share, "in every run: %.3f vs %.3f", min_share, area_share);
}

static vec3 zero_error(float px, float py)
{
    (void)px;
    (void)py;
    return v3s(0);
}

Test(sampler, zero_error_is_covered_by_global_requests_and_the_list)
{
    enum { W = 32, H = 32 };
    rq_options o = spaced(16);
    rq_engine *e = make(W, H, &o, 8);
    ct_camera c = cam_a();
    ct_request r[8];
    cr_assert_eq(batch(e, r, 4), 4);
    answer_all(e, &c, W, H, r, 4, v3s(0));
    /* The queue is dry: the next requests are global ones. */
    cr_assert_eq(batch(e, r, 8), 8);
    for (int i = 0; i < 8; i++) {
        cr_assert_eq(r[i].parent, 0u);
        cr_assert_eq(r[i].priority, o.prio_seed);
    }
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert_eq(st.global, (uint64_t)o.global_batch);
    cr_assert_float_eq(r[0].radius, sqrtf((float)(W * H - 4) / (float)o.global_batch), 1e-5f);
    answer_all(e, &c, W, H, r, 8, v3s(0));
    int n;
    int *order = converge(e, W, H, zero_error, 8, &n);
    cr_assert_eq(n + 12, W * H);
    rq_stats_get(e, &st);
    cr_assert_eq(st.coverage, 1.0);
    cr_assert_eq(st.children, 0u);
    cr_assert_gt(st.from_list, 0u);
    free(order);
    rq_free(e);
}

typedef struct logged { uint64_t id; float err; float radius; vec3 hit; } logged;

static int cmp_logged(const void *a, const void *b)
{
    const logged *x = a, *y = b;
    if (x->err != y->err) return x->err > y->err ? -1 : 1;
    return x->id < y->id ? -1 : 1;
}

Test(sampler, significant_samples_reproject_to_their_world_points)
{
    enum { W = 64, H = 48, NSIG = 20, NREP = 300 };
    rq_options o;
    rq_options_default(&o);
    o.n_sig = NSIG;
    rq_engine *e = make(W, H, &o, 9);
    ct_camera a = cam_a();
    static logged log[NREP];
    ct_request r[NREP];
    int k = batch(e, r, NREP);
    cr_assert_eq(k, NREP);
    for (int i = 0; i < k; i++) {
        ct_sample s = trace(&a, W, H, &r[i]);
        vec3 E = smooth_error(r[i].px, r[i].py);
        report(e, &s, E, 1);
        log[i] = (logged){r[i].id, rq_error_norm(E, o.norm), r[i].radius, s.hit};
    }
    qsort(log, NREP, sizeof *log, cmp_logged);

    ct_camera b = cam_look_at(v3(0.6f, 0.3f, 0.5f), v3(0.4f, 0.1f, -10.0f), v3(0, 1, 0), 55.0f);
    ct_error err;
    cr_assert_eq(rq_set_camera(e, &b, 1, &err), 0, "%s", err.msg);
    k = batch(e, r, NSIG);
    int j = 0, seen_px[W * H] = {0};
    int expected = 0;
    for (int i = 0; i < NSIG; i++) {
        float px, py;
        if (!cam_project(&b, W, H, log[i].hit, &px, &py, NULL) || px < 0 || py < 0 || px >= W || py >= H)
            continue;
        int p = (int)py * W + (int)px;
        if (seen_px[p]++) continue;   /* a second one on the same pixel is masked */
        expected++;
        cr_assert_lt(j, k);
        cr_assert_eq(r[j].px, px, "request %d: x %g, its world point projects to %g", j, (double)r[j].px, (double)px);
        cr_assert_eq(r[j].py, py);
        cr_assert_eq((int)r[j].px + W * (int)r[j].py, p, "same pixel");
        cr_assert_eq(r[j].parent, log[i].id, "parent = the significant sample's request");
        cr_assert_eq(r[j].radius, log[i].radius);
        cr_assert_eq(r[j].priority, o.prio_reproject);
        cr_assert_eq(r[j].epoch, 1u);
        j++;
    }
    cr_assert_geq(expected, NSIG / 2, "most reproject into the new view");
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert_eq(st.reprojected + st.reproject_dropped, (uint64_t)NSIG);
    /* After them, the new grid (reseed is on by default). */
    for (int i = j; i < k; i++) cr_assert_eq(r[i].priority, o.prio_seed);
    rq_free(e);
}

Test(sampler, epochs_drop_old_requests_and_samples)
{
    enum { W = 32, H = 32 };
    rq_options o = spaced(8);
    o.n_sig = 0;
    o.reseed = 0;   /* nothing new queued: what is left is old */
    rq_engine *e = make(W, H, &o, 10);
    ct_camera a = cam_a();
    ct_request r[16];
    cr_assert_eq(batch(e, r, 8), 8);
    answer(e, &a, W, H, &r[0], v3s(1), 1);
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert_gt(st.queued, 8u);
    cr_assert_eq(st.in_flight, 7u);

    ct_error err;
    cr_assert_eq(rq_set_camera(e, &a, 0, &err), CT_EINVAL, "epoch must grow");
    ct_camera bad = a;
    bad.fov_y = NAN;
    cr_assert_eq(rq_set_camera(e, &bad, 5, &err), CT_EINVAL);
    cr_assert_eq(rq_set_camera(e, &a, 3, &err), 0);
    rq_stats_get(e, &st);
    cr_assert_eq(st.epoch, 3u);
    cr_assert_eq(st.queued, 0u, "old requests dropped");
    cr_assert_eq(st.in_flight, 0u);
    cr_assert_eq(st.coverage, 0.0, "the mask belongs to the old view");

    /* An in-flight sample of epoch 0 comes back: ignored, no children. */
    ct_sample s1 = trace(&a, W, H, &r[1]);
    cr_assert_eq(rq_report(e, &s1, v3s(1), 1, &err), RQ_REPORT_STALE);
    rq_stats_get(e, &st);
    cr_assert_eq(st.stale, 1u);
    cr_assert_eq(st.queued, 0u);

    int k = batch(e, r, 16);
    cr_assert_eq(k, 16);
    for (int i = 0; i < k; i++) {
        cr_assert_eq(r[i].epoch, 3u);
        cr_assert_gt(r[i].id, 8u, "ids keep growing across epochs");
    }
    /* Protocol errors: future epoch, unknown id, duplicate, non-finite E. */
    ct_sample f = trace(&a, W, H, &r[0]);
    f.epoch = 4;
    cr_assert_eq(rq_report(e, &f, v3s(1), 1, &err), CT_EPROTO);
    cr_assert(strstr(err.msg, "epoch 4") != NULL, "%s", err.msg);
    f.epoch = 3;
    f.request_id = 999;
    cr_assert_eq(rq_report(e, &f, v3s(1), 1, &err), CT_EPROTO);
    ct_sample g = trace(&a, W, H, &r[0]);
    cr_assert_eq(rq_report(e, &g, v3(NAN, 0, 0), 1, &err), CT_EINVAL);
    cr_assert_eq(rq_report(e, &g, v3s(1), 1, &err), 0);
    cr_assert_eq(rq_report(e, &g, v3s(1), 1, &err), CT_EPROTO, "reported twice");
    cr_assert(strstr(err.msg, "not outstanding") != NULL, "%s", err.msg);
    rq_free(e);
}

Test(sampler, camera_change_queues_a_new_grid_unless_reseed_is_off)
{
    rq_options o = spaced(16);
    cr_assert_eq(o.reseed, 1, "on by default");
    o.n_sig = 0;
    rq_engine *e = make(64, 64, &o, 12);
    ct_camera a = cam_a();
    cr_assert_eq(rq_set_camera(e, &a, 1, NULL), 0);
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert_eq(st.seeds, 32u);
    cr_assert_eq(st.queued, 16u);
    rq_free(e);

    o.reseed = 0;   /* Fig. 4: only the reprojected samples (none here) */
    e = make(64, 64, &o, 12);
    cr_assert_eq(rq_set_camera(e, &a, 1, NULL), 0);
    rq_stats_get(e, &st);
    cr_assert_eq(st.seeds, 16u);
    cr_assert_eq(st.queued, 0u);
    rq_free(e);
}

/* Runs a fixed scenario with out-of-order reports and a camera change and
 * writes every request handed out into out; returns their number. */
static int scenario(uint64_t seed, ct_request *out, int cap)
{
    enum { W = 48, H = 40 };
    rq_engine *e = make(W, H, NULL, seed);
    ct_camera a = cam_a();
    ct_camera b = cam_look_at(v3(0.3f, 0, 0), v3(0.2f, 0.1f, -10), v3(0, 1, 0), 60.0f);
    int n = 0;
    ct_request r[3][37];
    bool handed[W * H] = {false};
    for (int round = 0; round < 40 && n + 3 * 37 <= cap; round++) {
        if (round == 20) {
            cr_assert_eq(rq_set_camera(e, &b, 1, NULL), 0);
            memset(handed, 0, sizeof handed);
        }
        const ct_camera *c = round < 20 ? &a : &b;
        int k[3];
        for (int t = 0; t < 3; t++) {
            k[t] = batch(e, r[t], 37);
            /* Three batches in flight: still never the same pixel twice. */
            for (int i = 0; i < k[t]; i++) {
                int p = (int)r[t][i].py * W + (int)r[t][i].px;
                cr_assert_not(handed[p], "pixel %d handed out twice in one epoch", p);
                handed[p] = true;
            }
            memcpy(out + n, r[t], (size_t)k[t] * sizeof *out);
            n += k[t];
        }
        /* Tracers finish out of order: batch 2, then 0, then 1 backwards. */
        const int tord[3] = {2, 0, 1};
        for (int ti = 0; ti < 3; ti++) {
            int t = tord[ti];
            for (int i = 0; i < k[t]; i++) {
                int ii = t == 1 ? k[t] - 1 - i : i;
                answer(e, c, W, H, &r[t][ii], disc_error(r[t][ii].px, r[t][ii].py), 1);
            }
        }
    }
    rq_free(e);
    return n;
}

static bool same_requests(const ct_request *a, const ct_request *b, int n)
{
    for (int i = 0; i < n; i++)
        if (a[i].id != b[i].id || a[i].parent != b[i].parent || a[i].epoch != b[i].epoch ||
            a[i].px != b[i].px || a[i].py != b[i].py || a[i].radius != b[i].radius ||
            a[i].priority != b[i].priority)
            return false;
    return true;
}

Test(sampler, same_seed_and_values_give_identical_requests)
{
    enum { CAP = 5000 };
    ct_request *a = malloc(CAP * sizeof *a), *b = malloc(CAP * sizeof *b), *c = malloc(CAP * sizeof *c);
    int na = scenario(77, a, CAP), nb = scenario(77, b, CAP), nc = scenario(78, c, CAP);
    cr_assert_gt(na, 2000);
    cr_assert_eq(na, nb);
    cr_assert(same_requests(a, b, na), "same seed, same sequence");
    cr_assert_not(nc == na && same_requests(a, c, na), "another seed, another sequence");
    free(a);
    free(b);
    free(c);
}

Test(sampler, options_parse_check_and_usage)
{
    rq_options o;
    rq_options_default(&o);
    ct_error err;
    cr_assert_eq(rq_options_set(&o, "children", "9", &err), 0);
    cr_assert_eq(o.children, 9);
    cr_assert_eq(rq_options_set(&o, "coverage-switch", "0.75", &err), 0);
    cr_assert_float_eq(o.coverage_switch, 0.75f, 1e-7f);
    cr_assert_eq(rq_options_set(&o, "error-norm", "lum", &err), 0);
    cr_assert_eq(o.norm, RQ_NORM_LUM);
    cr_assert_eq(rq_options_set(&o, "max-queue", "1000", &err), 0);
    cr_assert_eq(o.max_queue, 1000);
    cr_assert_eq(rq_options_set(&o, "children", "4x", &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "--children") != NULL, "%s", err.msg);
    cr_assert_eq(rq_options_set(&o, "error-norm", "l2", &err), CT_EINVAL);
    cr_assert_eq(rq_options_set(&o, "min-priority", "nan", &err), CT_EINVAL);
    cr_assert_eq(rq_options_set(&o, "bogus", "1", &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "unknown") != NULL, "%s", err.msg);
    cr_assert_eq(rq_options_check(&o, &err), 0, "%s", err.msg);
    o.children = 0;
    cr_assert_eq(rq_options_check(&o, &err), CT_EINVAL);
    rq_options_default(&o);
    o.coverage_switch = 1.5f;
    cr_assert_eq(rq_options_check(&o, &err), CT_EINVAL);

    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    rq_options_usage(f);
    fclose(f);
    cr_assert(strstr(buf, "--children N") != NULL && strstr(buf, "(default 4)") != NULL, "%s", buf);
    cr_assert(strstr(buf, "--coverage-switch F") != NULL && strstr(buf, "(default 0.9)") != NULL, "%s", buf);
    free(buf);

    rq_engine *e = NULL;
    ct_camera c = cam_a();
    cr_assert_eq(rq_new(&e, 0, 10, &c, NULL, 1, &err), CT_EINVAL);
    cr_assert_null(e);
    o.children = 65;
    cr_assert_eq(rq_new(&e, 10, 10, &c, &o, 1, &err), CT_EINVAL);
}

Test(sampler, queue_cap_drops_and_counts)
{
    rq_options o = spaced(4);
    o.max_queue = 20;
    rq_engine *e = make(32, 32, &o, 13);
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert_eq(st.queued, 20u);
    cr_assert_eq(st.discarded_full, 64u - 20u);
    rq_free(e);
}

Test(sampler, reprojection_drops_points_behind_or_far_outside_the_view)
{
    enum { W = 32, H = 32 };
    rq_options o = spaced(8);
    o.n_sig = 50;
    o.reseed = 0;   /* only reprojected requests in the queue */
    rq_engine *e = make(W, H, &o, 14);
    ct_camera a = cam_a();
    ct_request r[16];
    int k = batch(e, r, 16);
    for (int i = 0; i < k; i++) {
        ct_sample s = trace(&a, W, H, &r[i]);
        if (i == 0) s.hit = v3(1e-3f, 0, -1e-30f);     /* projects to ~1e27 px */
        if (i == 1) s.hit = v3(NAN, 0, -10);           /* not a point: never significant */
        report(e, &s, v3s(1.0f + (float)i), 1);
    }
    /* The same view again: the far-off point is dropped, the others return. */
    cr_assert_eq(rq_set_camera(e, &a, 1, NULL), 0);
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert_eq(st.reprojected, (uint64_t)(k - 2));
    cr_assert_eq(st.reproject_dropped, 1u);
    k = batch(e, r, 16);
    answer_all(e, &a, W, H, r, k, v3s(1.0f));
    /* Turn around: every significant point is behind the eye. */
    ct_camera back = cam_look_at(v3(0, 0, 0), v3(0, 0, 1), v3(0, 1, 0), 60.0f);
    cr_assert_eq(rq_set_camera(e, &back, 2, NULL), 0);
    rq_stats_get(e, &st);
    cr_assert_eq(st.reprojected, (uint64_t)(k - 2));
    cr_assert_eq(st.reproject_dropped, 1u + (uint64_t)k);
    cr_assert_eq(st.queued, 0u);
    rq_free(e);
}

/* --- refinement past full coverage (docs/sampling.md, "Refinement") ------------------ */

/* A noisy correction: inside the disc each sample is uniform in 0.3 +- 0.5
 * (by a hash of its request id), outside a constant 0.1. */
static vec3 noisy_dl(const ct_request *r)
{
    if (!in_disc(r->px, r->py)) return v3s(0.1f);
    return v3s(0.3f + (float)(ct_hash64(r->id) >> 40) * 0x1p-24f - 0.5f);
}

/* A two-level correction in the disc, like a dark drt pixel whose samples
 * are 0 (every lamp sample shadowed) half of the time: dL -0.2 or +0.6 by a
 * hash of the request id; outside a constant 0.1. */
static vec3 two_level_dl(const ct_request *r)
{
    if (!in_disc(r->px, r->py)) return v3s(0.1f);
    return v3s((ct_hash64(r->id) >> 63) ? 0.6f : -0.2f);
}

typedef struct refine_run {
    int samples[64 * 48];     /* per pixel */
    double sum[64 * 48];      /* of the dL that entered its mean */
    uint64_t ids[4096];       /* the first refinement requests */
    int nids;
    int batches;
} refine_run;

/* Runs a 64x48 still view until the engine goes idle; every sample's dL is
 * dl_of's (noisy_dl when NULL), and hits node 2 instead of 1 where
 * other_node says, nothing where misses says (both past a pixel's first). */
static rq_engine *refine_until_idle_or_miss(refine_run *rr, uint64_t seed, bool (*other_node)(const ct_request *),
                                            vec3 (*dl_of)(const ct_request *), bool (*misses)(const ct_request *))
{
    if (!dl_of) dl_of = noisy_dl;
    const int W = 64, H = 48;
    rq_options o;
    rq_options_default(&o);
    o.seed_spacing = 8;
    o.refine_max = 64;
    rq_engine *e = make(W, H, &o, seed);
    ct_camera c = cam_a();
    memset(rr, 0, sizeof *rr);
    static ct_request r[256];
    for (int it = 0; it < 100000; it++) {
        int k = batch(e, r, 256);
        if (k == 0) break;
        rr->batches++;
        for (int i = 0; i < k; i++) {
            int p = (int)r[i].py * W + (int)r[i].px;
            bool refine = rq_refines(e, r[i].id);
            rq_stats st;
            rq_stats_get(e, &st);
            if (refine) {
                cr_assert(st.coverage == 1.0, "refinement only after full coverage");
                cr_assert_eq(r[i].radius, 0.5f);
                cr_assert_eq(r[i].parent, 0u);
                if (rr->nids < 4096) rr->ids[rr->nids++] = r[i].id;
            }
            ct_sample smp = trace(&c, W, H, &r[i]);
            vec3 dl = dl_of(&r[i]);
            smp.l_hq = v3_add(v3s(1.0f), dl);
            smp.l_base = v3s(1.0f);
            bool other = other_node && other_node(&r[i]) && rr->samples[p] > 0;
            if (other) smp.node = 2;
            if (misses && misses(&r[i]) && rr->samples[p] > 0) {
                smp.flags = 0;
                smp.node = RQ_NODE_NONE;
                other = true;
            }
            int f = report(e, &smp, dl, 1);
            cr_assert_eq((f & RQ_REPORT_REFINE) != 0, refine && !other, "write the mean of same-node samples only");
            rr->samples[p]++;
            if (!other) rr->sum[p] += (double)dl.x;
        }
    }
    return e;
}

static rq_engine *refine_until_idle(refine_run *rr, uint64_t seed, bool (*other_node)(const ct_request *),
                                    vec3 (*dl_of)(const ct_request *))
{
    return refine_until_idle_or_miss(rr, seed, other_node, dl_of, NULL);
}

/* Pixel (x, y) lies wholly outside the disc (its four corners do). */
static bool outside_disc(int x, int y)
{
    return !in_disc((float)x, (float)y) && !in_disc((float)x + 1, (float)y + 1) && !in_disc((float)x + 1, (float)y) &&
           !in_disc((float)x, (float)y + 1);
}

Test(sampler, refinement_samples_uncertain_pixels_until_they_are_certain_then_idles)
{
    refine_run rr;
    rq_engine *e = refine_until_idle(&rr, 1, NULL, NULL);
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert(st.refining);
    cr_assert_eq(st.coverage, 1.0);
    int disc = 0, flat = 0, beside_disc = 0, beside_more = 0;
    for (int y = 0; y < 48; y++)
        for (int x = 0; x < 64; x++) {
            int p = y * 64 + x, n = rr.samples[p];
            cr_assert_geq(n, 1, "pixel %d,%d never sampled", x, y);
            if (in_disc((float)x + 0.5f, (float)y + 0.5f) && in_disc((float)x, (float)y) &&
                in_disc((float)x + 1, (float)y + 1) && in_disc((float)x + 1, (float)y) && in_disc((float)x, (float)y + 1)) {
                /* noise of 0.5: its standard error stays over the threshold
                 * until the cap of 64 samples */
                cr_assert_eq(n, 64, "disc pixel %d,%d: %d samples", x, y, n);
                disc++;
                vec3 m = rq_pixel_mean(e, (float)x + 0.5f, (float)y + 0.5f);
                cr_assert_float_eq(m.x, (float)(rr.sum[p] / n), 1e-5, "pixel mean %g vs %g", (double)m.x,
                                   rr.sum[p] / n);
            } else if (outside_disc(x, y)) {
                bool beside = !outside_disc(x - 1, y) || !outside_disc(x + 1, y) || !outside_disc(x, y - 1) ||
                              !outside_disc(x, y + 1);
                if (beside) {
                    /* a constant beside noisy pixels: its agreeing values
                     * are trusted after 16 at the latest (rq_refine.c
                     * SHRINK_UNTIL), sooner where its neighbours had too
                     * few samples to show their noise when it had 4 */
                    cr_assert(n >= 4 && n <= 16, "flat pixel %d,%d beside the disc: %d samples", x, y, n);
                    beside_disc++;
                    beside_more += n > 4;
                } else {
                    /* a constant 0.1 among constants: no variance once the
                     * first error (0.1) is no longer trusted alone, at 4 */
                    cr_assert_eq(n, 4, "flat pixel %d,%d: %d samples", x, y, n);
                    flat++;
                }
            }
        }
    cr_assert_gt(disc, 200);
    cr_assert_gt(flat, 2000);
    cr_assert_gt(beside_more, 20);
    printf("refinement: %d disc pixels at 64 samples, %d flat pixels at 4, %d beside the disc at 4-16 (%d over 4), "
           "%llu refinement samples, idle\n", disc, flat, beside_disc, beside_more,
           (unsigned long long)st.refine_samples);
    /* Idle: nothing is handed out any more. */
    ct_request r[8];
    cr_assert_eq(batch(e, r, 8), 0);
    rq_free(e);
}

Test(sampler, refinement_is_deterministic_and_a_camera_change_starts_over)
{
    static refine_run a, b;
    rq_engine *ea = refine_until_idle(&a, 7, NULL, NULL), *eb = refine_until_idle(&b, 7, NULL, NULL);
    cr_assert_eq(a.nids, b.nids);
    cr_assert_gt(a.nids, 100);
    cr_assert_eq(memcmp(a.ids, b.ids, (size_t)a.nids * sizeof a.ids[0]), 0);
    cr_assert_eq(memcmp(a.samples, b.samples, sizeof a.samples), 0);
    /* A new view forgets the means and stops refining until it is covered. */
    ct_error err;
    ct_camera c2 = cam_look_at(v3(0.5f, 0, 0), v3(0.5f, 0, -1), v3(0, 1, 0), 60.0f);
    cr_assert_eq(rq_set_camera(ea, &c2, 1, &err), 0);
    rq_stats st;
    rq_stats_get(ea, &st);
    cr_assert_not(st.refining);
    cr_assert_eq(st.refine_samples, 0u);
    vec3 m = rq_pixel_mean(ea, 40.5f, 24.5f);
    cr_assert_eq(m.x, 0.0f);
    rq_free(ea);
    rq_free(eb);
}

static bool odd_ids_hit_another_node(const ct_request *r) { return r->id & 1; }

Test(sampler, refinement_means_take_only_samples_of_the_pixels_first_node)
{
    static refine_run rr;
    rq_engine *e = refine_until_idle(&rr, 3, odd_ids_hit_another_node, NULL);
    int checked = 0;
    for (int p = 0; p < 64 * 48; p++) {
        if (rr.samples[p] < 3) continue;
        /* the sum counted only same-node samples; their number is unknown
         * here, but the mean must lie in the values' range and differ from
         * a mean over all samples where the other-node ones were dropped */
        vec3 m = rq_pixel_mean(e, (float)(p % 64) + 0.5f, (float)(p / 64) + 0.5f);
        cr_assert(m.x >= -0.2f - 1e-5f && m.x <= 0.8f + 1e-5f, "mean %g", (double)m.x);
        checked++;
    }
    cr_assert_gt(checked, 100);
    rq_free(e);
}

/* A silhouette against the background: a refinement sample that hits
 * nothing counts as a sample on another node does. A pixel used to leave
 * the queue at its first miss for good: with one refinement sample in three
 * missing, the noisy disc pixels stopped after a handful of samples instead
 * of reaching the cap, and the stats then showed the last pixel's error as
 * the largest left while the master idled. */
static bool every_third_misses(const ct_request *r) { return r->id % 3 == 0; }

Test(sampler, refinement_goes_on_past_samples_that_miss)
{
    static refine_run rr;
    rq_engine *e = refine_until_idle_or_miss(&rr, 1, NULL, NULL, every_third_misses);
    int disc = 0;
    for (int y = 0; y < 48; y++)
        for (int x = 0; x < 64; x++) {
            if (!(in_disc((float)x, (float)y) && in_disc((float)x + 1, (float)y + 1) &&
                  in_disc((float)x + 1, (float)y) && in_disc((float)x, (float)y + 1)))
                continue;
            cr_assert_eq(rr.samples[y * 64 + x], 64, "disc pixel %d,%d: %d samples", x, y, rr.samples[y * 64 + x]);
            disc++;
        }
    cr_assert_gt(disc, 200);
    rq_stats st;
    rq_stats_get(e, &st);
    cr_assert(st.refining);
    cr_assert_eq(st.refine_error, 0.0f, "idle: no error left over the threshold, got %g", (double)st.refine_error);
    ct_request r[8];
    cr_assert_eq(batch(e, r, 8), 0);
    rq_free(e);
}

/* Two-level samples agree by chance (four in a row one time in eight):
 * such a pixel must not stop while its neighbours' samples vary. Without
 * the neighbours' variance some stopped at 4 samples with a mean of -0.2
 * or 0.6 (off by 0.4; the truth is 0.2). */
Test(sampler, refinement_does_not_trust_chance_agreement_among_noisy_neighbours)
{
    static refine_run rr;
    rq_engine *e = refine_until_idle(&rr, 5, NULL, two_level_dl);
    int disc = 0, worst_n = 64;
    double worst = 0.0;
    for (int y = 1; y < 47; y++)
        for (int x = 1; x < 63; x++) {
            if (!in_disc((float)x - 1, (float)y - 1) || !in_disc((float)x + 2, (float)y + 2) ||
                !in_disc((float)x + 2, (float)y - 1) || !in_disc((float)x - 1, (float)y + 2))
                continue;   /* the disc's interior: every neighbour noisy too */
            int p = y * 64 + x, n = rr.samples[p];
            double m = rr.sum[p] / n;
            if (fabs(m - 0.2) > worst) worst = fabs(m - 0.2);
            if (n < worst_n) worst_n = n;
            disc++;
        }
    printf("two-level refinement: %d interior disc pixels, fewest samples %d, worst mean off by %.3f\n", disc,
           worst_n, worst);
    cr_assert_gt(disc, 150);
    cr_assert_eq(worst_n, 64, "a noisy pixel stopped at %d samples", worst_n);
    cr_assert_lt(worst, 0.25, "a pixel's mean is off by %.3f", worst);
    rq_free(e);
}

Test(sampler, refinement_options)
{
    rq_options o;
    rq_options_default(&o);
    ct_error err;
    cr_assert_gt(o.refine_error, 0.0f, "refinement is on by default");
    cr_assert_eq(rq_options_set(&o, "refine-error", "0", &err), 0);
    cr_assert_eq(o.refine_error, 0.0f);
    cr_assert_eq(rq_options_set(&o, "refine-max", "100", &err), 0);
    cr_assert_eq(rq_options_check(&o, &err), 0);
    o.refine_max = 0;
    cr_assert_eq(rq_options_check(&o, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "refine-max"), "%s", err.msg);
    o.refine_max = 70000;
    cr_assert_eq(rq_options_check(&o, &err), CT_EINVAL);
    o.refine_max = 8;
    o.refine_error = -1.0f;
    cr_assert_eq(rq_options_check(&o, &err), CT_EINVAL);
    cr_assert_eq(rq_options_set(&o, "refine-error", "inf", &err), CT_EINVAL);
}

/* Refinement weighs a pixel's uncertainty as it is displayed: the same
 * noise on a dark pixel (what a viewer sees there moves 12.92 times the
 * linear value at the darkest, 0.44 times at white) gets the higher
 * priority, so a dark surface does not keep one sample's noise. */
Test(sampler, refinement_priority_is_the_uncertainty_as_displayed)
{
    rq_refine r;
    ct_error err;
    cr_assert_eq(rq_refine_init(&r, 2, 1, 0.002f, 256, &err), 0, "%s", err.msg);
    const float noise[] = {0.010f, -0.008f, 0.012f, -0.011f, 0.004f, -0.007f};
    for (int i = 0; i < 6; i++) {
        vec3 dl = v3s(noise[i]);
        cr_assert_eq(rq_refine_add(&r, 0, 1, dl, 0.5f, 0.01f, &err), 1);   /* bright: displayed ~0.5 */
        cr_assert_eq(rq_refine_add(&r, 1, 1, dl, 0.02f, 0.01f, &err), 1);  /* dark: displayed ~0.02 */
    }
    float bright = rq_refine_priority(&r, 0), dark = rq_refine_priority(&r, 1);
    float want = img_tonemap_slope(0.02f) / img_tonemap_slope(0.5f);
    printf("metric: refinement priority, same noise: bright %.5f, dark %.5f (ratio %.2f, display slopes %.2f)\n",
           (double)bright, (double)dark, (double)(dark / bright), (double)want);
    cr_assert_gt(bright, 0.0f);
    cr_expect_float_eq(dark / bright, want, 0.05f * want, "dark/bright %g, want %g", (double)(dark / bright),
                       (double)want);
    /* the bright pixel is certain enough as displayed, the dark one is not */
    cr_expect_lt(bright, 0.002f * 3.0f);
    cr_expect_gt(dark, 0.002f);
    rq_refine_free(&r);
}

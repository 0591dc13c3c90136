/* (Over 600 lines: the solver's tests over shared test scenes.)
 * Hierarchical radiosity: form factors against the analytic value, energy
 * balance and region means in a closed box at four thresholds, the
 * conforming mesh (edges, T-vertices, values, node and material per
 * triangle), determinism across thread counts, and the memory cap. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "common/image.h"
#include "common/metrics.h"
#include "common/rng.h"
#include "tests/support/rad_fixtures.h"
#include "tests/support/testscenes.h"
#include "radiosity/radiosity.h"

/* Two parallel unit squares at distance 1: F = 0.19982 (Howell's catalogue,
 * configuration C-11). */
#define FF_SQUARES 0.199825

static rad_params test_params(void)
{
    rad_params p;
    rad_params_default(&p);
    p.threads = 2;
    p.memory_cap_mb = 512;
    return p;
}

/* Solves s under p into *m (and *st when not NULL), which must succeed. */
static void solve_ok(const ct_scene *s, const rad_params *p, ct_radmesh *m, rad_stats *st)
{
    ct_error err;
    cr_assert_eq(rad_solve(s, p, NULL, NULL, m, st, &err), 0, "%s", err.msg);
}

Test(radiosity, point_polygon_hemisphere)
{
    /* A huge square just above the point covers almost the whole hemisphere. */
    vec3 big[4] = {v3(-1e4f, -1e4f, 1), v3(-1e4f, 1e4f, 1), v3(1e4f, 1e4f, 1), v3(1e4f, -1e4f, 1)};
    double f = rad_ff_point_polygon(v3(0, 0, 0), v3(0, 0, 1), big, 4);
    cr_assert_float_eq(f, 1.0, 1e-3, "F to a covering plane = %f", f);
    /* Seen from behind, nothing. */
    vec3 rev[4] = {big[0], big[3], big[2], big[1]};
    cr_assert_eq(rad_ff_point_polygon(v3(0, 0, 0), v3(0, 0, 1), rev, 4), 0.0);
}

/* Point to a parallel rectangle [0, a] x [0, b] at height c, the point
 * under its corner (Howell's catalogue, B-3): the closed form the point
 * factor's edge angles must reproduce. */
static double ff_corner_rect(double a, double b, double c)
{
    double A = a / c, B = b / c, sa = sqrt(1.0 + A * A), sb = sqrt(1.0 + B * B);
    return (A / sa * atan(B / sa) + B / sb * atan(A / sb)) / (2.0 * M_PI);
}

Test(radiosity, point_polygon_matches_closed_form)
{
    /* From a thousandth of the height to a hundred times it: tiny angles,
     * and with the point under an edge's midpoint, edge angles near pi (the
     * rational atan's range reductions, rad_ff.c). */
    const double sizes[] = {1e-3, 0.1, 1.0, 7.0, 100.0};
    for (int i = 0; i < 5; i++) {
        float a = (float)sizes[i];
        vec3 corner[4] = {v3(0, 0, 1), v3(0, a, 1), v3(a, a, 1), v3(a, 0, 1)};
        double f = rad_ff_point_polygon(v3(0, 0, 0), v3(0, 0, 1), corner, 4), want = ff_corner_rect(a, a, 1.0);
        cr_assert(fabs(f - want) <= 1e-5 * want, "corner, side %g: F = %.9g, closed form %.9g", sizes[i], f, want);
        vec3 edge[4] = {v3(-a, 0, 1), v3(-a, a, 1), v3(a, a, 1), v3(a, 0, 1)};
        f = rad_ff_point_polygon(v3(0, 0, 0), v3(0, 0, 1), edge, 4);
        want = 2.0 * ff_corner_rect(a, a, 1.0);
        cr_assert(fabs(f - want) <= 1e-5 * want, "edge midpoint, side %g: F = %.9g, closed form %.9g", sizes[i], f,
                  want);
    }
}

Test(radiosity, form_factor_parallel_squares_analytic)
{
    vec3 a[4] = {v3(0, 0, 0), v3(1, 0, 0), v3(1, 1, 0), v3(0, 1, 0)};
    vec3 b[4] = {v3(0, 0, 1), v3(0, 1, 1), v3(1, 1, 1), v3(1, 0, 1)};
    double f = rad_ff_polygons(a, 4, b, 4, 40);
    cr_assert(fabs(f - FF_SQUARES) < 0.002 * FF_SQUARES, "F = %f, analytic %f", f, FF_SQUARES);
}

Test(radiosity, form_factor_parallel_squares_solver)
{
    /* The whole solver: power absorbed by a black receiver over power
     * emitted by the facing square is exactly F. */
    ct_scene *s = rfx_parallel_squares(1.0f, 1.0f);
    cr_assert_not_null(s);
    rad_params p = test_params();
    p.error = 1e-4;
    p.min_area = 1e-4;
    ct_radmesh m;
    rad_stats st;
    solve_ok(s, &p, &m, &st);
    double f = st.absorbed / st.emitted;
    cr_log_info("solver F = %f (analytic %f), %llu leaves", f, FF_SQUARES, (unsigned long long)st.leaves);
    cr_assert(fabs(f - FF_SQUARES) < 0.01 * FF_SQUARES, "solver F = %f, analytic %f", f, FF_SQUARES);
    /* The receiver is black: its vertices carry no light; the emitter's
     * carry exactly its emission. */
    for (uint32_t v = 0; v < m.nverts; v++) {
        if (m.pos[v].z > 0.5f) cr_assert_float_eq(m.rad[v].x, 1.0f, 1e-5f);
        else cr_assert_float_eq(m.rad[v].x, 0.0f, 1e-7f);
    }
    rmesh_free(&m);
    scene_free(s);
}

/* Two unit squares at a right angle sharing an edge: F = 0.200044
 * (Hottel's formula for perpendicular rectangles with a common edge,
 * W = H = 1). The point factor has a logarithmic kink at the shared edge,
 * which 2 x 2 Gauss points over one pair of whole squares overestimate by
 * 0.18 %; the solver splits the receiver along the edge until each leaf's
 * points are far from it for their size: -0.013 % at 1e-4, -0.003 % at
 * 1e-5. (4 x 4 points for neighbouring elements changed these by less
 * than 1e-6, the closed box's power by -0.007 %, and cost table 14 % more
 * time: not kept.) */
#define FF_CORNER 0.2000438

Test(radiosity, form_factor_perpendicular_squares_solver)
{
    ct_scene *s = rfx_perpendicular_squares(1.0f);
    cr_assert_not_null(s);
    const double thresholds[2] = {1e-4, 1e-5};
    for (int k = 0; k < 2; k++) {
        rad_params p = test_params();
        p.error = thresholds[k];
        ct_radmesh m;
        rad_stats st;
        solve_ok(s, &p, &m, &st);
        double f = st.absorbed / st.emitted;
        cr_log_info("corner, --error %g: solver F = %.6f (analytic %.6f, %+.3f %%), %llu links", p.error, f, FF_CORNER,
                    100.0 * (f / FF_CORNER - 1.0), (unsigned long long)st.links);
        cr_expect(fabs(f - FF_CORNER) < 0.0005 * FF_CORNER, "--error %g: solver F = %.6f, analytic %.6f", p.error, f,
                  FF_CORNER);
        rmesh_free(&m);
    }
    scene_free(s);
}

/* The closed unit box of tests/data/radiosity/closedbox.json (walls of
 * reflectance 0.5, a lamp in the ceiling) at four thresholds: every photon
 * is absorbed somewhere, so absorbed / emitted must be 1 within 0.2 % at
 * each (iterated to a residual of 1e-6, so what remains is the links'), and
 * the region means of the Gouraud view (64 x 64, 4 x 4 pixel blocks on one
 * flat surface) against the committed path-traced reference
 * (closedbox-ref.exr: 32768 samples per pixel, its blocks' noise about
 * 0.07 % rms, scripts/make-radiosity-refs) must be within 5 % and their rms
 * must fall with every tighter threshold. The solver before these checks
 * lost 0.26 % of the power at 5e-5 and had regions off by 10 %, 7.5 %, 6.3 %.
 * Version 13: 1.0013, 1.0009, 1.0006, 1.0005, rms 0.80, 0.73, 0.68, 0.58 %;
 * version 14 (inherited links shared out by the leaves' centres,
 * rad_leaf_scales): 1.0020, 1.0018, 1.0015, 1.0014, rms 0.26, 0.16, 0.09,
 * 0.08 %: the light where it belongs shows the factors' own excess a
 * little more (with the sharing in the final gather only, the power is
 * version 13's to the digit); version 15 (Gauss points from a fortieth of
 * the distance, not a tenth): 1.0006, 1.0007, 1.0009, 1.0009, rms 0.32,
 * 0.20, 0.10, 0.08 %. */
Test(radiosity, energy_and_regions_converge_in_a_closed_box, .timeout = 240)
{
    const char *scene_path = "tests/data/radiosity/closedbox.json", *ref_path = "tests/data/radiosity/closedbox-ref.exr";
    ct_scene *s;
    ct_error err;
    cr_assert_eq(scene_load(scene_path, &s, &err), 0, "%s", err.msg);
    int cam = scene_find_camera(s, "in");
    cr_assert_geq(cam, 0);
    ct_image ref, img, planes;
    cr_assert_eq(img_read_exr(ref_path, &ref, &err), 0, "%s", err.msg);
    const double thresholds[4] = {1e-4, 5e-5, 2e-5, 1e-5};
    double last_rms = HUGE_VAL;
    for (int k = 0; k < 4; k++) {
        rad_params p = test_params();
        p.error = thresholds[k];
        p.tolerance = 1e-6;
        ct_radmesh m;
        rad_stats st;
        solve_ok(s, &p, &m, &st);
        double ratio = st.absorbed / st.emitted;
        cr_assert_eq(img_alloc(&img, ref.width, ref.height, &err), 0, "%s", err.msg);
        cr_assert_eq(img_alloc(&planes, ref.width, ref.height, &err), 0, "%s", err.msg);
        cr_assert_eq(rad_render_view(&m, &s->cams[cam].cam, 64, RAD_VIEW_TOTAL, p.threads, &img, &err), 0, "%s", err.msg);
        cr_assert_eq(rad_render_view(&m, &s->cams[cam].cam, 16, RAD_VIEW_PLANES, p.threads, &planes, &err), 0, "%s",
                     err.msg);
        img_regions r;
        cr_assert_eq(metrics_regions(&img, &ref, &planes, 1, NULL, 1.0, 4, &r, &err), 0, "%s", err.msg);
        cr_log_info("closed box, --error %g: absorbed / emitted %.5f, %llu links; %d regions: worst %.4f, rms %.4f",
                    p.error, ratio, (unsigned long long)st.links, r.counted, r.worst, r.rms);
        cr_assert(fabs(ratio - 1.0) <= 0.002, "--error %g: absorbed / emitted = %.5f, not within 0.2 %%", p.error, ratio);
        cr_assert_gt(r.counted, 100);
        cr_assert_leq(r.worst, 0.05, "--error %g: a region is off by %.4f", p.error, r.worst);
        cr_assert_lt(r.rms, last_rms, "--error %g: region rms %.4f did not fall below %.4f", p.error, r.rms, last_rms);
        last_rms = r.rms;
        metrics_regions_free(&r);
        img_free(&img);
        img_free(&planes);
        rmesh_free(&m);
    }
    img_free(&ref);
    scene_free(s);
}

/* The closed box with 60 boxes in it (tests/data/radiosity/clutterbox.json):
 * every photon is still absorbed somewhere, but here links are partly or
 * wholly blocked and clusters hold boxes of six sides. Over three seeds at
 * --error 1e-4 (the solver is deterministic for a seed) the solver before
 * absorbed 0.9799, 0.9822 and 0.9808 of the emitted power (mean 0.9810).
 * Two causes were fixed: a cluster link whose rays all came back blocked
 * was dropped, although a later pass would have split it into children
 * with fresh estimates (a selection on the discarded rays: mean 0.9838
 * once kept), and a cluster showed every receiver its patches' mean
 * radiosity, the dark undersides to the ceiling as much as the lit tops
 * (0.9900, 0.9912, 0.9934, mean 0.9915, with the side it turns to the
 * receiver, rad_cluster_B). An element link whose value rays were all
 * blocked was dropped too, the same selection (0.9925, 0.9934, 0.9956,
 * mean 0.9938, once kept: solver version 10); dim receivers refined
 * further (--dim-floor, version 11): 0.9942, 0.9960, 0.9980, mean 0.9961;
 * factors over Gauss points (version 13): 0.9939, 0.9956, 0.9977, mean 0.9957;
 * inherited links shared out by the leaves' centres (version 14): 0.9939,
 * 0.9958, 0.9978, mean 0.9958; version 24: 0.9923, 0.9966, 0.9991 (seeds
 * 1-6 mean 0.9974); sources passing on their exposed part's radiosity
 * (version 25): 0.9963, 1.0003, 1.0028 at the default tolerance (seeds
 * 1-6 mean 1.0010, spread 0.9963-1.0061: each seed's visibility rays move
 * it by about 0.3 %, so a seed's bound allows 0.5 % and the mean's 0.3 %). docs/radiosity.md,
 * "Energy with occlusion" and "Covered parts". */
/* Absorbed over emitted power of scene file, solved at error (and
 * tolerance, when positive) for seeds 1..n, each at most max_each (a
 * closed scene: more is power created); returns their mean. */
static double absorbed_mean(const char *file, double error, double tolerance, int n, double max_each)
{
    ct_scene *s;
    ct_error err;
    cr_assert_eq(scene_load(file, &s, &err), 0, "%s", err.msg);
    double sum = 0.0;
    for (int seed = 1; seed <= n; seed++) {
        rad_params p = test_params();
        p.error = error;
        if (tolerance > 0.0) p.tolerance = tolerance;
        p.seed = (uint64_t)seed;
        ct_radmesh m;
        rad_stats st;
        solve_ok(s, &p, &m, &st);
        double ratio = st.absorbed / st.emitted;
        cr_log_info("%s at %g, seed %d: absorbed / emitted %.5f, %llu links", file, error, seed, ratio,
                    (unsigned long long)st.links);
        cr_assert_leq(ratio, max_each, "%s, seed %d: absorbed / emitted = %.5f: power created", file, seed, ratio);
        sum += ratio;
        rmesh_free(&m);
    }
    scene_free(s);
    return sum / n;
}

Test(radiosity, box_with_boxes_keeps_its_power, .timeout = 240)
{
    double mean = absorbed_mean("tests/data/radiosity/clutterbox.json", 1e-4, 1e-6, 3, 1.005);
    cr_assert_geq(mean, 0.995, "mean absorbed / emitted %.5f: power lost", mean);
    cr_assert_leq(mean, 1.003, "mean absorbed / emitted %.5f: power created", mean);
}

/* The L room (tests/data/radiosity/lroom.json, closed) with its box
 * standing on the floor: at a coarse --error the floor's large elements
 * reach under the box. Such an element's mean radiosity counts the dark
 * part under the box, and the visibility rays of its links from there are
 * blocked too, so the mean passed on for its open part lost the covered
 * part's share twice: 0.9909 of the emitted power absorbed at 1e-3 (seed
 * 1), 0.9937 at 1e-4. Passing on the exposed part's radiosity (rad_src_B,
 * version 25): 0.9972, 0.9951, 1.0011 (seeds 1-3) at 1e-3, 0.9969 at 1e-4. */
Test(radiosity, covered_parts_pass_on_their_light, .timeout = 240)
{
    double mean = absorbed_mean("tests/data/radiosity/lroom.json", 1e-3, 0.0, 2, 1.005);
    cr_assert_geq(mean, 0.9945, "mean absorbed / emitted %.5f: the covered parts' light lost", mean);
}

/* The final gather at the leaves (--gather-passes) moves light between
 * leaves and keeps the links' total: two steps created 0.6-0.8 % of the
 * box with boxes' power before their sum was scaled back to the links'. */
Test(radiosity, leaf_gather_keeps_the_power, .timeout = 240)
{
    ct_scene *s;
    ct_error err;
    cr_assert_eq(scene_load("tests/data/radiosity/clutterbox.json", &s, &err), 0, "%s", err.msg);
    for (int seed = 1; seed <= 2; seed++) {
        double ratio[2];
        for (int k = 0; k < 2; k++) {
            rad_params p = test_params();
            p.error = 1e-4;
            p.tolerance = 1e-6;
            p.seed = (uint64_t)seed;
            p.gather_passes = 2 * k;
            ct_radmesh m;
            rad_stats st;
            solve_ok(s, &p, &m, &st);
            ratio[k] = st.absorbed / st.emitted;
            rmesh_free(&m);
        }
        cr_log_info("box with boxes, seed %d: absorbed / emitted %.5f, %.5f after two steps at the leaves", seed,
                    ratio[0], ratio[1]);
        cr_assert_leq(fabs(ratio[1] - ratio[0]), 0.0015,
                      "seed %d: the leaves' steps took absorbed / emitted from %.5f to %.5f", seed, ratio[0], ratio[1]);
    }
    scene_free(s);
}

/* Position key for edge checks: exact bits (the mesh welds exactly). */
typedef struct pkey { float x, y, z; } pkey;

/* An edge by position (a < b) with the normal of a triangle it bounds; a
 * vertex with the normal of a triangle it belongs to. */
typedef struct nedge { pkey a, b; vec3 n; } nedge;
typedef struct nvert { pkey p; vec3 n; } nvert;

static int cmp_pkey(const void *a, const void *b)
{
    const pkey *p = a, *q = b;
    if (p->x != q->x) return p->x < q->x ? -1 : 1;
    if (p->y != q->y) return p->y < q->y ? -1 : 1;
    if (p->z != q->z) return p->z < q->z ? -1 : 1;
    return 0;
}

static int cmp_edge(const void *a, const void *b)
{
    const nedge *p = a, *q = b;
    int c = cmp_pkey(&p->a, &q->a);
    return c ? c : cmp_pkey(&p->b, &q->b);
}

static pkey key_of(vec3 v)
{
    pkey k;
    memset(&k, 0, sizeof k);
    k.x = v.x + 0.0f;
    k.y = v.y + 0.0f;
    k.z = v.z + 0.0f;
    return k;
}

static vec3 tri_normal(const ct_radmesh *m, uint32_t t)
{
    const uint32_t *i = m->tris + 3 * (size_t)t;
    return v3_norm(v3_cross(v3_sub(m->pos[i[1]], m->pos[i[0]]), v3_sub(m->pos[i[2]], m->pos[i[0]])));
}

/* Every undirected edge (by position) has at most two triangles, and no
 * mesh vertex lies strictly inside an edge of a triangle in its own plane
 * (a T-vertex: a crack in that surface). A vertex of another surface that
 * happens to lie on an edge (a block's corner on a floor edge) is no crack. */
static void check_conforming(const ct_radmesh *m)
{
    nedge *edges = malloc((size_t)m->ntris * 3 * sizeof *edges);
    nvert *vs = malloc((size_t)m->nverts * sizeof *vs);
    cr_assert(edges && vs);
    for (uint32_t v = 0; v < m->nverts; v++) vs[v].p = key_of(m->pos[v]), vs[v].n = v3s(0.0f);
    for (uint32_t t = 0; t < m->ntris; t++) {
        vec3 n = tri_normal(m, t);
        for (int k = 0; k < 3; k++) {
            uint32_t ia = m->tris[3 * t + k], ib = m->tris[3 * t + (k + 1) % 3];
            pkey a = key_of(m->pos[ia]), b = key_of(m->pos[ib]);
            if (cmp_pkey(&a, &b) > 0) { pkey x = a; a = b; b = x; }
            cr_assert_neq(cmp_pkey(&a, &b), 0, "triangle %u has a zero-length edge", t);
            edges[3 * t + k] = (nedge){a, b, n};
            vs[ia].n = n;
        }
    }
    size_t ne = (size_t)m->ntris * 3;
    qsort(edges, ne, sizeof *edges, cmp_edge);
    for (size_t i = 0; i < ne;) {
        size_t j = i;
        while (j < ne && cmp_edge(&edges[i], &edges[j]) == 0) j++;
        cr_assert_leq(j - i, 2, "edge (%g %g %g)-(%g %g %g) has %zu triangles", edges[i].a.x, edges[i].a.y,
                      edges[i].a.z, edges[i].b.x, edges[i].b.y, edges[i].b.z, j - i);
        i = j;
    }
    /* T-vertices: vertices sorted by x; for each edge (both triangles of a
     * shared one) test the vertices within its x range. */
    qsort(vs, m->nverts, sizeof *vs, cmp_pkey);
    size_t bad = 0;
    for (size_t i = 0; i < ne; i++) {
        vec3 a = v3(edges[i].a.x, edges[i].a.y, edges[i].a.z);
        vec3 b = v3(edges[i].b.x, edges[i].b.y, edges[i].b.z);
        vec3 ab = v3_sub(b, a);
        float l2 = v3_len2(ab);
        /* Binary search the first vertex with x >= a.x (a.x <= b.x by sort). */
        size_t lo = 0, hi = m->nverts;
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (vs[mid].p.x < a.x - 1e-6f) lo = mid + 1; else hi = mid;
        }
        for (size_t k = lo; k < m->nverts && vs[k].p.x <= b.x + 1e-6f; k++) {
            vec3 p = v3(vs[k].p.x, vs[k].p.y, vs[k].p.z);
            float t = v3_dot(v3_sub(p, a), ab) / l2;
            if (t <= 1e-4f || t >= 1.0f - 1e-4f) continue;
            vec3 q = v3_add(a, v3_scale(ab, t));
            if (v3_len2(v3_sub(p, q)) < 1e-10f * l2 && fabsf(v3_dot(vs[k].n, edges[i].n)) > 0.999f) {
                if (bad < 5)
                    cr_log_info("T-vertex (%g %g %g) inside edge (%g %g %g)-(%g %g %g)", p.x, p.y, p.z, a.x, a.y,
                                a.z, b.x, b.y, b.z);
                bad++;
            }
        }
    }
    cr_assert_eq(bad, 0, "%zu vertices lie inside triangle edges (T-vertices)", bad);
    free(vs);
    free(edges);
}

Test(radiosity, mesh_is_conforming)
{
    ct_scene *s = rfx_room_with_block();
    cr_assert_not_null(s);
    rad_params p = test_params();
    p.error = 1e-5;
    p.min_area = 1e-5;
    ct_radmesh m;
    rad_stats st;
    solve_ok(s, &p, &m, &st);
    cr_log_info("room: %u patches, %llu leaves, %u triangles, %u vertices, %llu links", st.patches,
                (unsigned long long)st.leaves, st.triangles, st.vertices, (unsigned long long)st.links);
    cr_assert_gt(st.leaves, (uint64_t)st.patches * 4, "the lamp should force refinement");
    check_conforming(&m);
    /* Node and material per triangle agree with the scene's parts. */
    for (uint32_t t = 0; t < m.ntris; t++) {
        uint32_t n = m.tri_node[t];
        cr_assert_lt(n, s->nnodes);
        cr_assert_eq(s->nodes[n].kind, SCENE_NODE_PART);
        cr_assert_eq(m.tri_mat[t], s->nodes[n].material);
    }
    for (uint32_t v = 0; v < m.nverts; v++) {
        cr_assert(v3_finite(m.rad[v]) && v3_finite(m.rad_direct[v]));
        cr_assert(m.rad[v].x >= 0.0f && m.rad_direct[v].x >= 0.0f);
        /* Total includes the direct part (interreflection only adds). */
        cr_assert_geq(m.rad[v].x + 1e-5f, m.rad_direct[v].x);
    }
    /* The red wall bleeds: the floor near it is redder than the floor far away. */
    rmesh_free(&m);
    scene_free(s);
}

Test(radiosity, values_kept_apart_across_creases_and_materials)
{
    ct_scene *s = rfx_closed_box(3, 0.5f, 10.0f);
    rad_params p = test_params();
    p.error = 1e-3;
    ct_radmesh m;
    solve_ok(s, &p, &m, NULL);
    /* The box corner (0,0,0) belongs to floor, front and left: three
     * vertices with three normals, never one averaged vertex. */
    int found = 0;
    for (uint32_t v = 0; v < m.nverts; v++)
        if (m.pos[v].x == 0.0f && m.pos[v].y == 0.0f && m.pos[v].z == 0.0f) {
            found++;
            vec3 n = m.nrm[v];
            cr_assert(fabsf(v3_maxabs(n) - 1.0f) < 1e-5f,
                      "corner normal not axis aligned: %g %g %g", n.x, n.y, n.z);
        }
    cr_assert_eq(found, 3);
    /* Lamp vertices carry the lamp's radiance exactly (not averaged with the ceiling). */
    for (uint32_t t = 0; t < m.ntris; t++)
        if (strcmp(s->nodes[m.tri_node[t]].name, "lamp") == 0)
            for (int k = 0; k < 3; k++) cr_assert_float_eq(m.rad[m.tris[3 * t + k]].x, 10.0f, 1e-4f);
    rmesh_free(&m);
    scene_free(s);
}

/* drt shades the radiosity mesh with its vertex normals, so they are the
 * scene's shading normals, not the patches' face normals averaged within
 * the crease angle: a flat-shaded sphere (facets 22.5 degrees apart, under
 * the 30-degree crease) keeps a vertex per facet with that facet's normal,
 * and a smooth one carries its interpolated normals, which on a sphere are
 * radial at every point of a facet. Before, both had averaged normals (a
 * faceted sphere read smooth in drt and banded in path). */
Test(radiosity, mesh_carries_the_scenes_shading_normals)
{
    ct_error err;
    ct_scene *s = scene_new("spheres");
    int floor_m = ts_diffuse(s, "floor", v3s(0.5f), v3s(0.0f), &err);
    int ball_m = ts_diffuse(s, "ball", v3s(0.7f), v3s(0.0f), &err);
    int lamp_m = ts_diffuse(s, "lamp", v3s(0.0f), v3s(10.0f), &err);
    cr_assert(floor_m >= 0 && ball_m >= 0 && lamp_m >= 0);
    cr_assert_geq(ts_quad(s, "floor", (uint32_t)floor_m, v3(-4, 0, -4), v3(0, 0, 8), v3(8, 0, 0), &err), 0);
    cr_assert_geq(ts_quad(s, "lamp", (uint32_t)lamp_m, v3(-0.5f, 3, -0.5f), v3(1, 0, 0), v3(0, 0, 1), &err), 0);
    vec3 cf = v3(-1.2f, 0.6f, 0), cs = v3(1.2f, 0.6f, 0);
    cr_assert_geq(ts_sphere(s, "flat", (uint32_t)ball_m, cf, 0.5f, 16, 8, false, &err), 0);
    cr_assert_geq(ts_smooth_sphere(s, "smooth", (uint32_t)ball_m, cs, 0.5f, 16, 8, &err), 0, "%s", err.msg);
    cr_assert_eq(scene_finalize(s, &err), 0, "%s", err.msg);
    rad_params p = test_params();
    p.error = 1e-4;
    ct_radmesh m;
    solve_ok(s, &p, &m, NULL);
    double worst_flat = 0.0, worst_smooth = 0.0;
    uint32_t nflat = 0, nsmooth = 0;
    for (uint32_t t = 0; t < m.ntris; t++) {
        const char *name = s->nodes[m.tri_node[t]].name;
        vec3 fn = tri_normal(&m, t);
        for (int k = 0; k < 3; k++) {
            uint32_t v = m.tris[3 * t + (uint32_t)k];
            if (strcmp(name, "flat") == 0) {
                worst_flat = fmax(worst_flat, 1.0 - (double)v3_dot(m.nrm[v], fn));
                nflat++;
            } else if (strcmp(name, "smooth") == 0) {
                worst_smooth = fmax(worst_smooth, 1.0 - (double)v3_dot(m.nrm[v], v3_norm(v3_sub(m.pos[v], cs))));
                nsmooth++;
            }
        }
    }
    printf("metric: shading normals, flat sphere: 1 - cos %.3g worst over %u corners; smooth: %.3g over %u\n",
           worst_flat, nflat, worst_smooth, nsmooth);
    cr_assert(nflat > 0 && nsmooth > 0);
    cr_expect_lt(worst_flat, 1e-4, "a flat facet's mesh normal is %.1f degrees off its face",
                 acos(1.0 - worst_flat) * 180.0 / CT_PI);
    cr_expect_lt(worst_smooth, 1e-4, "a smooth sphere's mesh normal is %.1f degrees off radial",
                 acos(1.0 - worst_smooth) * 180.0 / CT_PI);
    rmesh_free(&m);
    scene_free(s);
}

/* A vertex gathers with the normal it is shaded with, as the tracers
 * shade it: a smooth sphere's vertex is lit as its radial normal sees the
 * lamp, not as one of its facets' planes does (the Cornell box's spheres
 * were 20-46 % dark along their terminators in 8 x 8-pixel blocks). The
 * sphere is inscribed in its smooth surface, so nothing of it rises above a
 * vertex's tangent plane: the exact point factor to the lamp with the
 * radial normal is what the vertex's direct light must be. Gathered with
 * one of its facets' planes, the worst vertex was off by 0.113 of the
 * brightest (mean 0.030); with its own normal by 0.001. */
Test(radiosity, vertices_gather_with_their_shading_normals)
{
    ct_error err;
    ct_scene *s = scene_new("ball");
    int ball_m = ts_diffuse(s, "ball", v3s(0.7f), v3s(0.0f), &err);
    int lamp_m = ts_diffuse(s, "lamp", v3s(0.0f), v3s(10.0f), &err);
    cr_assert(ball_m >= 0 && lamp_m >= 0);
    vec3 lamp[4] = {v3(-0.5f, 1.5f, -0.5f), v3(0.5f, 1.5f, -0.5f), v3(0.5f, 1.5f, 0.5f), v3(-0.5f, 1.5f, 0.5f)};
    cr_assert_geq(ts_quad(s, "lamp", (uint32_t)lamp_m, lamp[0], v3(1, 0, 0), v3(0, 0, 1), &err), 0);
    vec3 cs = v3(0.0f, 0.0f, 0.0f);
    cr_assert_geq(ts_smooth_sphere(s, "smooth", (uint32_t)ball_m, cs, 0.5f, 16, 8, &err), 0, "%s", err.msg);
    cr_assert_eq(scene_finalize(s, &err), 0, "%s", err.msg);
    rad_params p = test_params();
    p.error = 1e-4;
    ct_radmesh m;
    solve_ok(s, &p, &m, NULL);
    double top = 0.0, worst = 0.0, sum = 0.0;
    uint32_t n = 0;
    for (uint32_t pass = 0; pass < 2; pass++) {
        for (uint32_t t = 0; t < m.ntris; t++) {
            if (strcmp(s->nodes[m.tri_node[t]].name, "smooth") != 0) continue;
            for (int k = 0; k < 3; k++) {
                uint32_t v = m.tris[3 * t + (uint32_t)k];
                vec3 nr = v3_norm(v3_sub(m.pos[v], cs));
                double want = 0.7 * 10.0 * rad_ff_point_polygon(m.pos[v], nr, lamp, 4);
                double got = m.rad_direct[v].x;
                if (pass == 0) {
                    top = fmax(top, want);
                    continue;
                }
                worst = fmax(worst, fabs(got - want) / top);
                sum += fabs(got - want) / top;
                n++;
            }
        }
    }
    printf("metric: smooth sphere's direct light at its vertices: worst %.4f, mean %.4f of the brightest over %u corners\n",
           worst, sum / n, n);
    cr_assert(n > 0);
    cr_expect_lt(worst, 0.03, "a vertex's direct light is off by %.3f of the brightest", worst);
    rmesh_free(&m);
    scene_free(s);
}

static uint64_t mesh_digest(const ct_radmesh *m)
{
    uint64_t h = 0;
    const float *f = (const float *)m->rad;
    for (size_t i = 0; i < (size_t)m->nverts * 3; i++) {
        uint32_t b;
        memcpy(&b, &f[i], 4);
        h = ct_hash64(h ^ b);
    }
    for (size_t i = 0; i < (size_t)m->ntris * 3; i++) h = ct_hash64(h ^ m->tris[i]);
    return h;
}

Test(radiosity, same_result_for_any_thread_count)
{
    ct_scene *s = rfx_room_with_block();
    rad_params p = test_params();
    p.error = 3e-5;
    ct_radmesh a, b;
    p.threads = 1;
    solve_ok(s, &p, &a, NULL);
    p.threads = 3;
    solve_ok(s, &p, &b, NULL);
    cr_assert_eq(a.ntris, b.ntris);
    cr_assert_eq(mesh_digest(&a), mesh_digest(&b));
    cr_assert_eq(a.scene_hash, b.scene_hash, "threads must not change the cache key");
    rmesh_free(&a);
    rmesh_free(&b);
    scene_free(s);
}

Test(radiosity, memory_cap_fails_clearly)
{
    ct_scene *s = rfx_room_with_block();
    rad_params p = test_params();
    p.error = 1e-9;
    p.min_area = 1e-9;
    p.memory_cap_mb = 16;
    ct_radmesh m;
    ct_error err;
    int rc = rad_solve(s, &p, NULL, NULL, &m, NULL, &err);
    cr_assert_eq(rc, CT_ENOMEM);
    cr_assert(strstr(err.msg, "memory cap") != NULL, "message: %s", err.msg);
    cr_assert_eq(m.ntris, 0);
    scene_free(s);
}

Test(radiosity, no_light_is_an_error)
{
    ct_scene *s = rfx_parallel_squares(1.0f, 0.0f);
    rad_params p = test_params();
    ct_radmesh m;
    ct_error err;
    cr_assert_eq(rad_solve(s, &p, NULL, NULL, &m, NULL, &err), CT_EEMPTY);
    cr_assert(strstr(err.msg, "emitting") != NULL, "message: %s", err.msg);
    scene_free(s);
}

Test(radiosity, bad_parameters_are_rejected)
{
    rad_params p = test_params();
    ct_error err;
    p.error = 0.0;
    cr_assert_eq(rad_params_check(&p, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "--error") != NULL);
    p = test_params();
    p.threads = 0;
    cr_assert_eq(rad_params_check(&p, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "--threads") != NULL);
    for (int bad = 0; bad < 2; bad++) {
        p = test_params();
        p.mirror_samples = bad ? 4097 : -1;
        cr_assert_eq(rad_params_check(&p, &err), CT_EINVAL);
        cr_assert(strstr(err.msg, "--mirror-samples") != NULL, "%s", err.msg);
    }
}

Test(radiosity, hash_follows_scene_and_parameters)
{
    ct_scene *s = rfx_closed_box(3, 0.5f, 10.0f);
    ct_scene *t = rfx_closed_box(3, 0.6f, 10.0f);
    rad_params p = test_params();
    uint64_t h = rad_solution_hash(s, &p);
    cr_assert_neq(h, rad_solution_hash(t, &p), "reflectance must change the hash");
    rad_params q = p;
    q.error *= 2;
    cr_assert_neq(h, rad_solution_hash(s, &q));
    q = p;
    q.threads = 7;
    q.memory_cap_mb = 99;
    cr_assert_eq(h, rad_solution_hash(s, &q));
    scene_free(s);
    scene_free(t);
}

Test(radiosity, cache_is_used_when_fresh_and_recomputed_when_stale)
{
    ct_scene *s = rfx_closed_box(3, 0.5f, 10.0f);
    rad_params p = test_params();
    p.error = 1e-3;
    char path[128];
    snprintf(path, sizeof path, "/tmp/ct_rad_cache_%ld.ctmesh", (long)getpid());
    unlink(path);
    ct_radmesh a, b, c;
    ct_error why, err;
    int from_cache = -1;
    cr_assert_eq(rad_cached_solve(s, &p, path, NULL, NULL, &a, NULL, &from_cache, &why, &err), 0, "%s", err.msg);
    cr_assert_eq(from_cache, 0);
    cr_assert(strstr(why.msg, "no cached solution at") != NULL, "why: %s", why.msg);
    cr_assert_eq(rad_cached_solve(s, &p, path, NULL, NULL, &b, NULL, &from_cache, &why, &err), 0, "%s", err.msg);
    cr_assert_eq(from_cache, 1, "the fresh cache was not used: %s", why.msg);
    cr_assert_eq(a.ntris, b.ntris);
    cr_assert_eq(mesh_digest(&a), mesh_digest(&b));
    /* Other parameters: the cache is stale and the solution recomputed. */
    p.error = 5e-4;
    cr_assert_eq(rad_cached_solve(s, &p, path, NULL, NULL, &c, NULL, &from_cache, &why, &err), 0, "%s", err.msg);
    cr_assert_eq(from_cache, 0);
    cr_assert(strstr(why.msg, "stale") != NULL, "why: %s", why.msg);
    cr_assert_gt(c.ntris, a.ntris);
    rmesh_free(&a);
    rmesh_free(&b);
    rmesh_free(&c);
    unlink(path);
    scene_free(s);
}

Test(radiosity, direct_part_is_one_bounce_of_emitted_light)
{
    /* Receiver grey, emitter black: light reflected by the receiver only
     * reaches the black emitter, so the receiver's total is its direct part.
     * A grey emitter reflects some back: then the total exceeds the direct. */
    for (int grey_emitter = 0; grey_emitter < 2; grey_emitter++) {
        ct_scene *s = rfx_parallel_squares(1.0f, 1.0f);
        s->mats[0].diffuse = v3s(0.5f);
        if (grey_emitter) s->mats[1].diffuse = v3s(0.5f);
        rad_params p = test_params();
        p.error = 1e-3;
        ct_radmesh m;
        solve_ok(s, &p, &m, NULL);
        double tot = 0, dir = 0;
        for (uint32_t v = 0; v < m.nverts; v++)
            if (m.pos[v].z < 0.5f) {
                tot += m.rad[v].x;
                dir += m.rad_direct[v].x;
            }
        cr_assert_gt(dir, 0.0);
        if (grey_emitter) cr_assert_gt(tot, dir * 1.01, "total %f, direct %f", tot, dir);
        else cr_assert_float_eq(tot, dir, 1e-6 * dir, "total %f, direct %f", tot, dir);
        rmesh_free(&m);
        scene_free(s);
    }
}

/* Parameters under which the room wants far more than 5,000 triangles. */
static rad_params budget_params(void)
{
    rad_params p = test_params();
    p.error = 1e-7;
    p.min_area = 1e-7;
    p.max_triangles = 5000;
    return p;
}

Test(radiosity, max_triangles_bounds_the_mesh)
{
    ct_scene *s = rfx_room_with_block();
    rad_params p = budget_params();
    ct_radmesh m;
    rad_stats st;
    solve_ok(s, &p, &m, &st);
    cr_log_info("max-triangles 5000: %u triangles", m.ntris);
    cr_assert_leq(m.ntris, 5000u, "%u triangles", m.ntris);
    cr_assert_gt(m.ntris, 2500u, "%u triangles: the budget should be nearly used", m.ntris);
    check_conforming(&m);
    rmesh_free(&m);
    scene_free(s);
}

/* With the budget binding, which elements get the last triangles must not
 * depend on thread timing (a shared running count did): the same mesh for
 * 1, 2 and 3 threads, twice over. */
Test(radiosity, max_triangles_mesh_is_the_same_for_any_thread_count)
{
    ct_scene *s = rfx_room_with_block();
    rad_params p = budget_params();
    uint64_t first = 0;
    uint32_t ntris = 0;
    for (int run = 0; run < 6; run++) {
        p.threads = 1 + run % 3;
        ct_radmesh m;
        solve_ok(s, &p, &m, NULL);
        uint64_t d = mesh_digest(&m);
        if (run == 0) {
            first = d;
            ntris = m.ntris;
            cr_log_info("max-triangles 5000: %u triangles", m.ntris);
        }
        cr_assert_eq(d, first, "run %d (%d threads): %u triangles, a different mesh than run 0's %u", run, p.threads,
                     m.ntris, ntris);
        rmesh_free(&m);
    }
    scene_free(s);
}

/* The view render runs its rows on a pool: each row has its own random
 * stream, so the image is the same for any thread count. */
Test(radiosity, view_render_is_the_same_for_any_thread_count)
{
    ct_scene *s = rfx_room_with_block();
    rad_params p = budget_params();
    ct_radmesh m;
    solve_ok(s, &p, &m, NULL);
    ct_camera cam = cam_look_at(v3(3.5f, 1.5f, 0.3f), v3(1.7f, 0.4f, 2.1f), v3(0, 1, 0), 60.0f);
    ct_image img[2];
    ct_error err;
    const int threads[2] = {1, 3};
    for (int k = 0; k < 2; k++) {
        cr_assert_eq(img_alloc(&img[k], 37, 29, &err), 0, "%s", err.msg);
        cr_assert_eq(rad_render_view(&m, &cam, 4, RAD_VIEW_TOTAL, threads[k], &img[k], &err), 0, "%s",
                     err.msg);
    }
    double sum = 0.0;
    for (int y = 0; y < 29; y++)
        for (int x = 0; x < 37; x++) {
            vec3 a = img_get(&img[0], x, y), b = img_get(&img[1], x, y);
            cr_assert(a.x == b.x && a.y == b.y && a.z == b.z, "pixel (%d, %d) differs between 1 and 3 threads", x, y);
            sum += a.x + a.y + a.z;
        }
    cr_assert_gt(sum, 0.0, "the view is black: nothing was rendered");
    img_free(&img[0]);
    img_free(&img[1]);
    rmesh_free(&m);
    scene_free(s);
}

/* The box's inside seen from a corner into *img (48 x 48). */
static void box_inside_view(const ct_radmesh *m, ct_image *img)
{
    ct_camera cam = cam_look_at(v3(0.9f, 0.6f, 0.1f), v3(0.1f, 0.4f, 0.9f), v3(0, 1, 0), 90.0f);
    ct_error err;
    cr_assert_eq(img_alloc(img, 48, 48, &err), 0, "%s", err.msg);
    cr_assert_eq(rad_render_view(m, &cam, 16, RAD_VIEW_TOTAL, 2, img, &err), 0, "%s", err.msg);
}

/* A closed room on a ground plane far larger than it: no light leaves the
 * room, so the ground must change nothing inside. Up to solver version 18
 * three of the solver's rules took the scene's size or total area for the
 * room's: the triangle budget was shared by area (the room's patches got
 * less than one split of it), the smallest element was a share of the
 * total area (0.8 m^2 with the 2 km ground) and rays were lifted off the
 * surfaces by a share of the scene's diagonal (6 cm). With the 2 km ground
 * that code absorbed 1.187 of the emitted power and a block inside was
 * 10.5 % off; with the 60 m one, 0.75 % (docs/radiosity.md, "Scale"). */
Test(radiosity, a_huge_ground_plane_changes_nothing_inside_a_closed_room, .timeout = 240)
{
    rad_params p = test_params();
    p.error = 1e-4;
    ct_image ref, img;
    ct_error err;
    double ref_ratio = 0.0;
    uint64_t ref_links = 0, ref_elems = 0;
    const float grounds[3] = {0.0f, 30.0f, 1000.0f};
    for (int k = 0; k < 3; k++) {
        ct_scene *s = rfx_closed_box_on_ground(5, 0.5f, 10.0f, grounds[k]);
        cr_assert_not_null(s);
        ct_radmesh m;
        rad_stats st;
        solve_ok(s, &p, &m, &st);
        double ratio = st.absorbed / st.emitted;
        box_inside_view(&m, k == 0 ? &ref : &img);
        if (k == 0) {
            ref_ratio = ratio;
            ref_links = st.links;
            ref_elems = st.elements;
        } else {
            img_regions r;
            cr_assert_eq(metrics_regions(&img, &ref, NULL, 0, NULL, 1.0, 8, &r, &err), 0, "%s", err.msg);
            cr_log_info("closed box on a ground %g m wide: %u triangles, absorbed / emitted %.5f (no ground %.5f); "
                        "inside, %d blocks against no ground: worst %.4f, rms %.4f",
                        2.0 * grounds[k], m.ntris, ratio, ref_ratio, r.counted, r.worst, r.rms);
            cr_assert(fabs(ratio - ref_ratio) <= 0.003, "ground %g m: absorbed / emitted %.5f against %.5f without",
                      2.0 * grounds[k], ratio, ref_ratio);
            cr_assert_eq(r.counted, 36, "ground %g m: %d blocks counted", 2.0 * grounds[k], r.counted);
            cr_assert_leq(r.worst, 0.03, "ground %g m: a block inside the box is off by %.4f", 2.0 * grounds[k],
                          r.worst);
            /* Nothing reaches the ground, so nothing is refined for it, and
             * next to nothing leaks onto it: ray ends (rad_vis_transmit),
             * links whose value rays missed (value in rad_link.c). The
             * bound leaves room for grazing links under the error
             * threshold that even 256 rays found no facing pair for. */
            float ground_max = 0.0f;
            double wall_sum = 0.0;
            uint32_t wall_n = 0;
            for (uint32_t t = 0; t < m.ntris; t++) {
                const char *part = m.nodes[m.tri_node[t]].name;
                for (int v = 0; v < 3; v++) {
                    float b = v3_maxc(m.rad[m.tris[3 * t + v]]);
                    if (strcmp(part, "ground") == 0) ground_max = fmaxf(ground_max, b);
                    else if (strcmp(part, "lamp") != 0) {
                        wall_sum += b;
                        wall_n++;
                    }
                }
            }
            double wall_mean = wall_n ? wall_sum / wall_n : 0.0;
            cr_log_info("  %llu elements, %llu links (no ground: %llu, %llu); brightest ground vertex %.3g of the "
                        "walls' mean",
                        (unsigned long long)st.elements, (unsigned long long)st.links,
                        (unsigned long long)ref_elems, (unsigned long long)ref_links, ground_max / wall_mean);
            cr_assert_leq(ground_max, 1e-3 * wall_mean, "ground %g m: light leaked onto it (%.3g of the walls' mean)",
                          2.0 * grounds[k], ground_max / wall_mean);
            cr_assert_leq(st.links, ref_links + ref_links / 8, "ground %g m: %llu links against %llu without",
                          2.0 * grounds[k], (unsigned long long)st.links, (unsigned long long)ref_links);
            cr_assert_leq(st.elements, ref_elems + ref_elems / 4, "ground %g m: %llu elements against %llu without",
                          2.0 * grounds[k], (unsigned long long)st.elements, (unsigned long long)ref_elems);
            metrics_regions_free(&r);
            img_free(&img);
        }
        rmesh_free(&m);
        scene_free(s);
    }
    img_free(&ref);
}

Test(radiosity, cornell_scene_mesh_is_conforming)
{
    /* The real pipeline: the generated Cornell box (make scenes), imported
     * by the loader, solved coarsely; its mesh must be conforming too. */
    ct_scene *s;
    ct_error err;
    if (access("scenes/cornell/cornell.obj", R_OK) != 0)
        cr_skip_test("scenes/cornell not generated (make scenes)");
    cr_assert_eq(scene_load("scenes/cornell/cornell.json", &s, &err), 0, "%s", err.msg);
    rad_params p = test_params();
    p.error = 1e-4;
    ct_radmesh m;
    rad_stats st;
    solve_ok(s, &p, &m, &st);
    cr_log_info("cornell: %u patches (%u input primitives), %u triangles", st.patches, s->nprims, m.ntris);
    /* Quads were rebuilt: fewer patches than triangles. */
    cr_assert_lt(st.patches, s->ntris);
    cr_assert_geq(st.patches, s->nprims);
    check_conforming(&m);
    cr_assert_eq(m.nnodes, s->nnodes);
    for (uint32_t n = 0; n < s->nnodes; n++) cr_assert_str_eq(m.nodes[n].name, s->nodes[n].name);
    rmesh_free(&m);
    scene_free(s);
}

/* The lamps seen in plane mirrors are a source term of the solution
 * (radiosity/rad_mirror.c): on ts_mirror_lamp's floor, lit only by the lamp's
 * image in the mirror ceiling, every vertex under the image's reach must
 * hold rho * R * L_e * F(image) (B / pi) as direct light (rad_direct);
 * with --mirror-samples 0 the floor has no direct light (the mirror then
 * passes the lamp's light on through its radiosity, as indirect light).
 * The diffuse wall beside the floor takes the floor's light on: the mirror
 * light is reflected further like any other light. */
Test(radiosity, lamps_seen_in_plane_mirrors)
{
    ct_error err;
    double wall_indirect[2] = {0.0, 0.0};
    for (int ms = 0; ms <= 256; ms += 256) {
        ct_scene *s = ts_mirror_lamp(false, false, false, &err);
        cr_assert(s, "%s", err.msg);
        rad_params p = test_params();
        p.mirror_samples = ms;
        ct_radmesh m;
        rad_stats st;
        solve_ok(s, &p, &m, &st);
        int checked = 0;
        double worst = 0.0, indirect = 0.0;
        for (uint32_t v = 0; v < m.nverts; v++) {
            vec3 x = m.pos[v];
            if (fabsf(x.x + 6.0f) < 1e-5f)   /* the side wall */
                indirect = fmax(indirect, v3_maxc(v3_sub(m.rad[v], m.rad_direct[v])));
            if (fabsf(x.y) > 1e-5f || !(m.nrm[v].y > 0.99f)) continue;   /* the floor's vertices */
            if (x.x < -1.5f || x.x > 0.5f || x.z < -1.0f || x.z > 1.0f) continue;
            vec3 want = ms ? ts_mirror_lamp_floor(x.x, x.z) : v3s(0.0f);
            for (int k = 0; k < 3; k++) {
                double got = v3_get(m.rad_direct[v], k), d = fabs(got - v3_get(want, k));
                worst = fmax(worst, d / (v3_get(want, k) + 1e-3));
                cr_expect(d < 0.05 * v3_get(want, k) + 1e-5, "mirror samples %d, vertex (%g, %g), channel %d: "
                          "direct %g, analytic %g", ms, (double)x.x, (double)x.z, k, got, (double)v3_get(want, k));
                cr_expect(v3_get(m.rad[v], k) >= got, "rad below its direct part");
            }
            checked++;
        }
        printf("metric: mirror samples %d: %d floor vertices, worst deviation %.4f, largest indirect on the wall "
               "%.3g\n", ms, checked, worst, indirect);
        cr_assert(checked >= 4, "only %d floor vertices checked", checked);
        wall_indirect[ms != 0] = indirect;
        rmesh_free(&m);
        scene_free(s);
    }
    /* Without images the mirror passes the lamp's light on through its
     * radiosity, spread as if diffuse (solver version 17): the side wall
     * gets light either way, of the same order. */
    cr_expect(wall_indirect[1] > 1e-4 && wall_indirect[1] > wall_indirect[0] / 3.0 &&
                  wall_indirect[1] < 3.0 * wall_indirect[0],
              "the mirror light is not reflected on: the wall's indirect light %g with images, %g without",
              wall_indirect[1], wall_indirect[0]);
}

/* Glossy and mirror layers pass their light on (solver version 17): a
 * closed unit box whose walls all emit B_e = 1 and reflect 1/2, one of them
 * not by a diffuse layer but by a mirror or by a diffuse 0.2 + glossy 0.3
 * layer in front of it. Passed on as if diffuse, every surface sends
 * B = 1 + H / 2 and the box is uniform: B = 2 on the diffuse walls; the
 * special wall shows only its diffuse part, 1 + 0.2 x 2. A mirror that
 * absorbed its light (the solver before) gave the walls about 1.86. Mirror
 * images off: the lamps are the walls themselves. */
static void special_wall_box(bool mirror, double *walls, double *special)
{
    ct_error err;
    ct_scene *s = scene_new("specialbox");
    int wall = ts_diffuse(s, "wall", v3s(0.5f), v3s(1.0f / (float)CT_PI), &err);
    scene_material m = scene_material_default("special");
    m.emission = v3s(1.0f / (float)CT_PI);
    if (mirror) {
        m.mirror = v3s(0.5f);
    } else {
        m.diffuse = v3s(0.2f);
        m.glossy = SCENE_GLOSSY_PHONG;
        m.specular = v3s(0.3f);
        m.phong_exp = 50.0f;
    }
    int sm = scene_add_material(s, &m, &err);
    cr_assert(wall >= 0 && sm >= 0, "%s", err.msg);
    cr_assert(ts_box(s, "box", (uint32_t)wall, v3s(0.0f), v3s(1.0f), true, &err) >= 0, "%s", err.msg);
    /* Just inside the floor, facing up ((0,0,1) x (1,0,0) = +y). */
    cr_assert(ts_quad(s, "special", (uint32_t)sm, v3(0, 0.001f, 0), v3(0, 0, 1), v3(1, 0, 0), &err) >= 0, "%s",
              err.msg);
    cr_assert(scene_finalize(s, &err) == CT_OK, "%s", err.msg);
    rad_params p = test_params();
    p.mirror_samples = 0;
    ct_radmesh r;
    solve_ok(s, &p, &r, NULL);
    double sw = 0, ss = 0;
    int nw = 0, ns = 0;
    for (uint32_t v = 0; v < r.nverts; v++) {
        vec3 x = r.pos[v];
        if (fabsf(x.y) < 1e-5f) continue;   /* the floor behind the special wall: nothing reaches it */
        /* Inside a face (two coordinates inside), away from its edges. */
        int inner = (x.x > 0.1f && x.x < 0.9f) + (x.y > 0.1f && x.y < 0.9f) + (x.z > 0.1f && x.z < 0.9f);
        if (inner != 2) continue;
        if (fabsf(x.y - 0.001f) < 1e-5f && r.nrm[v].y > 0.99f) ss += v3_avg(r.rad[v]), ns++;
        else sw += v3_avg(r.rad[v]), nw++;
    }
    cr_assert(nw > 8 && ns > 4, "only %d wall and %d special vertices", nw, ns);
    /* The mesh holds radiance, B / pi. */
    *walls = CT_PI * sw / nw;
    *special = CT_PI * ss / ns;
    rmesh_free(&r);
    scene_free(s);
}

Test(radiosity, glossy_and_mirror_layers_pass_their_light_on)
{
    for (int mirror = 1; mirror >= 0; mirror--) {
        double walls, special;
        special_wall_box(mirror, &walls, &special);
        double want_special = mirror ? 1.0 : 1.4;
        const char *kind = mirror ? "mirror" : "glossy";
        printf("metric: closed box with a %s wall: diffuse walls B %.4f (want 2), the %s wall shows %.4f (want %.1f)\n",
               kind, walls, kind, special, want_special);
        cr_expect(fabs(walls - 2.0) < 0.02 * 2.0, "%s wall: the diffuse walls' radiosity %g, want 2", kind, walls);
        cr_expect(fabs(special - want_special) < 0.02 * want_special, "%s wall shows %g, want %g", kind, special,
                  want_special);
    }
}

/* A plane mirror whose lamp images are sampled passes the lamps' light on
 * by them and the rest through its radiosity (rho_ml): neither twice nor
 * lost, so a closed box with a mirror wall absorbs what it emits. */
Test(radiosity, a_mirror_with_lamp_images_keeps_energy)
{
    ct_error err;
    ct_scene *s = scene_new("mirrorbox");
    int wall = ts_diffuse(s, "wall", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3s(10.0f), &err);
    scene_material m = scene_material_default("mirror");
    m.mirror = v3s(0.9f);
    int mm = scene_add_material(s, &m, &err);
    cr_assert(wall >= 0 && lamp >= 0 && mm >= 0, "%s", err.msg);
    cr_assert(ts_box(s, "box", (uint32_t)wall, v3s(0.0f), v3s(1.0f), true, &err) >= 0, "%s", err.msg);
    /* The mirror just inside the wall x = 0, facing +x; the lamp facing down
     * under the ceiling. */
    cr_assert(ts_quad(s, "mirror", (uint32_t)mm, v3(0.001f, 0, 0), v3(0, 1, 0), v3(0, 0, 1), &err) >= 0, "%s",
              err.msg);
    cr_assert(ts_quad(s, "lamp", (uint32_t)lamp, v3(0.4f, 0.99f, 0.4f), v3(0.2f, 0, 0), v3(0, 0, 0.2f), &err) >= 0,
              "%s", err.msg);
    cr_assert(scene_finalize(s, &err) == CT_OK, "%s", err.msg);
    rad_params p = test_params();
    ct_radmesh r;
    rad_stats st;
    solve_ok(s, &p, &r, &st);
    double ratio = st.absorbed / st.emitted;
    printf("metric: closed box with a plane mirror wall, mirror images on: absorbed / emitted %.4f\n", ratio);
    cr_expect(fabs(ratio - 1.0) < 0.01, "absorbed / emitted %g, want 1", ratio);
    rmesh_free(&r);
    scene_free(s);
}

/* Light passes glass (solver version 5): a floor under a lamp, with a glass
 * slab (index 1.5) between them, gets the lamp's direct light times the
 * two crossings' transmission T and (1 - F) each, F ~ 0.04 for the
 * near-normal directions from the lamp (within 1.5 % for all of them), so
 * T^2 0.96^2 of what it gets without the slab; for T = 0.98 and 0.5. */
static double floor_direct(float transmission)
{
    ct_error err;
    ct_scene *s = scene_new("glassfloor");
    int floor_m = ts_diffuse(s, "floor", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3s(10.0f), &err);
    cr_assert(floor_m >= 0 && lamp >= 0);
    cr_assert(ts_quad(s, "floor", (uint32_t)floor_m, v3(-1, 0, -1), v3(0, 0, 2), v3(2, 0, 0), &err) >= 0);
    cr_assert(ts_quad(s, "lamp", (uint32_t)lamp, v3(-0.5f, 1, -0.3f), v3(1, 0, 0), v3(0, 0, 0.6f), &err) >= 0);
    if (transmission > 0.0f) {
        scene_material g = scene_material_default("glass");
        g.diffuse = v3s(0.0f);
        g.dielectric = 1;
        g.ior = 1.5f;
        g.transmission = v3s(transmission);
        int gm = scene_add_material(s, &g, &err);
        cr_assert(gm >= 0, "%s", err.msg);
        cr_assert(ts_box(s, "slab", (uint32_t)gm, v3(-3, 0.5f, -3), v3(3, 0.51f, 3), false, &err) >= 0);
    }
    cr_assert_eq(scene_finalize(s, &err), 0, "%s", err.msg);
    rad_params p = test_params();
    ct_radmesh m;
    solve_ok(s, &p, &m, NULL);
    /* The floor's vertex nearest its centre. */
    double best = 1e9, val = 0.0;
    for (uint32_t v = 0; v < m.nverts; v++) {
        if (fabsf(m.pos[v].y) > 1e-5f) continue;
        double d = hypot(m.pos[v].x, m.pos[v].z);
        if (d < best) best = d, val = m.rad_direct[v].x;
    }
    cr_assert(best < 0.3, "no floor vertex near the centre (%g)", best);
    rmesh_free(&m);
    scene_free(s);
    return val;
}

/* A closed box (walls of reflectance 0.5, a lamp under the ceiling) with a
 * clear pane of glass (ior 1.5, transmission 1) across most of it: glass
 * absorbs nothing here, so every photon still ends in a wall. The pane
 * passes light through its links' visibility, (1 - F)^2 of it, and its
 * faces pass on what they reflect, 2 F / (1 + F) of what reaches them
 * (F of one face at each link's angle, rad_elem_links): absorbed / emitted 0.9962 (0.9992 without the pane),
 * bound 1.5 %. Before solver version 27 the reflection was lost (0.9292);
 * weighed by the hemisphere's mean reflectance it made light (1.0313). */
static double glass_box_absorbed(bool pane, int gather_passes)
{
    ct_error err;
    ct_scene *s = scene_new("glassbox");
    int wall = ts_diffuse(s, "wall", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3s(10.0f), &err);
    scene_material g = scene_material_default("glass");
    g.diffuse = v3s(0.0f);
    g.dielectric = 1;
    g.ior = 1.5f;
    g.transmission = v3s(1.0f);
    int gm = scene_add_material(s, &g, &err);
    cr_assert(wall >= 0 && lamp >= 0 && gm >= 0, "%s", err.msg);
    cr_assert(ts_box(s, "room", (uint32_t)wall, v3(0, 0, 0), v3(1, 1, 1), true, &err) >= 0);
    cr_assert(ts_quad(s, "lamp", (uint32_t)lamp, v3(0.4f, 0.999f, 0.4f), v3(0.2f, 0, 0), v3(0, 0, 0.2f), &err) >= 0);
    if (pane) cr_assert(ts_box(s, "pane", (uint32_t)gm, v3(0.1f, 0.45f, 0.1f), v3(0.9f, 0.46f, 0.9f), false, &err) >= 0);
    cr_assert_eq(scene_finalize(s, &err), 0, "%s", err.msg);
    rad_params p = test_params();
    p.error = 1e-4;
    p.tolerance = 1e-6;
    p.gather_passes = gather_passes;
    ct_radmesh m;
    rad_stats st;
    solve_ok(s, &p, &m, &st);
    rmesh_free(&m);
    scene_free(s);
    return st.absorbed / st.emitted;
}

Test(radiosity, glass_passes_on_what_it_reflects, .timeout = 240)
{
    double without = glass_box_absorbed(false, 0), with = glass_box_absorbed(true, 0);
    double steps = glass_box_absorbed(true, 2);
    printf("metric: closed box, absorbed / emitted: %.4f without the pane, %.4f with it, %.4f with it and two "
           "steps of the leaves' gather\n", without, with, steps);
    cr_expect(fabs(without - 1.0) < 0.005, "the box without the pane: %.4f", without);
    cr_expect(fabs(with - 1.0) < 0.015, "the box with a clear pane: absorbed / emitted %.4f", with);
    /* (the leaves' gather scales what the links bring, weighed already) */
    cr_expect(fabs(steps - 1.0) < 0.015, "the box with a clear pane, --gather-passes 2: %.4f", steps);
}

Test(radiosity, light_passes_glass)
{
    double open = floor_direct(0.0f);
    cr_assert(open > 0.0);
    const float T[2] = {0.98f, 0.5f};
    for (int i = 0; i < 2; i++) {
        double ratio = floor_direct(T[i]) / open, want = (double)T[i] * T[i] * 0.96 * 0.96;
        printf("metric: through glass of transmission %.2f: %.4f of the light (expected %.4f)\n", (double)T[i], ratio,
               want);
        cr_expect(fabs(ratio - want) < 0.03 * want, "transmission %g: ratio %g, expected %g", (double)T[i], ratio, want);
    }
}

/* The area-weighted mean radiosity of part `name` (each triangle its
 * vertices' mean: Gouraud shading's). */
static double part_mean(const ct_radmesh *m, const char *name)
{
    double sum = 0.0, area = 0.0;
    for (uint32_t t = 0; t < m->ntris; t++) {
        if (strcmp(m->nodes[m->tri_node[t]].name, name) != 0) continue;
        const uint32_t *i = m->tris + 3 * (size_t)t;
        double a = 0.5 * v3_len(v3_cross(v3_sub(m->pos[i[1]], m->pos[i[0]]), v3_sub(m->pos[i[2]], m->pos[i[0]])));
        sum += a * (v3_avg(m->rad[i[0]]) + v3_avg(m->rad[i[1]]) + v3_avg(m->rad[i[2]])) / 3.0;
        area += a;
    }
    return area > 0.0 ? sum / area : 0.0;
}

/* A cluster link reads its cluster's mean radiosity, weighted by area,
 * openness and facing, not by what its receiver sees: a receiver 5 m
 * above a lit floor that sees none of the dark covered floor beside it
 * got the mean of both from the cluster holding them, 0.39 of its light
 * (solver version 20). Now each cluster link scales the mean by what its
 * own rays found (bk, rad_ff.c): the receiver gets what the lit floor
 * shows it, 0.8 F B with F its factor to that 1 x 1 floor centred 5 m
 * below it (four corner rectangles of a = b = 0.1) and B the floor's mean.
 * 64 rays a link, so that the factor's own noise does not hide a bias. */
Test(radiosity, cluster_links_carry_the_light_their_rays_see, .timeout = 240)
{
    ct_scene *s = rfx_covered_floor(4, 20.0f);
    cr_assert_not_null(s);
    double a = 0.1, q = sqrt(1.0 + a * a);
    double F = 4.0 * (2.0 * a / q * atan(a / q)) / (2.0 * M_PI);
    for (int seed = 1; seed <= 2; seed++) {
        rad_params p = test_params();
        p.error = 1e-4;
        p.vis_rays = 64;
        p.seed = (uint64_t)seed;
        ct_radmesh m;
        solve_ok(s, &p, &m, NULL);
        double want = 0.8 * F * part_mean(&m, "open"), got = part_mean(&m, "receiver");
        cr_log_info("seed %d: receiver %.5f, 0.8 F B of the lit floor %.5f (ratio %.3f); covered floor %.2g",
                    seed, got, want, got / want, part_mean(&m, "covered"));
        cr_assert(fabs(got / want - 1.0) <= 0.05, "seed %d: the receiver has %.3f of the light the floor shows it",
                  seed, got / want);
        rmesh_free(&m);
    }
    scene_free(s);
}

/* The box room stretched four times along z (tests/data/radiosity/
 * longroom.json). Links from a non-emitting source share their points on
 * it, and version 21 put one of the ceiling's four 1 mm under the lamp for
 * seed 2 alone: every link to the ceiling looked part hidden and the room
 * came out with 1.7 times the triangles of seeds 1, 3 and 4 (16,692
 * against 9,768-9,784 at this threshold; 122,510 against 42,568-42,752 at
 * the default). Each receiver's deciding rays now turn the shared pattern
 * by an offset of their own; the mesh may depend on the seed by its noise
 * only (9,826-9,886 triangles). */
Test(radiosity, mesh_size_does_not_hang_on_the_seed, .timeout = 240)
{
    ct_scene *s = NULL;
    ct_error err;
    cr_assert_eq(scene_load("tests/data/radiosity/longroom.json", &s, &err), 0, "%s", err.msg);
    uint32_t lo = UINT32_MAX, hi = 0;
    for (int seed = 1; seed <= 4; seed++) {
        rad_params p = test_params();
        p.error = 1e-4;
        p.seed = (uint64_t)seed;
        ct_radmesh m;
        solve_ok(s, &p, &m, NULL);
        cr_log_info("seed %d: %u triangles", seed, (unsigned)m.ntris);
        if (m.ntris < lo) lo = m.ntris;
        if (m.ntris > hi) hi = m.ntris;
        rmesh_free(&m);
    }
    cr_assert(hi <= 1.3 * lo, "triangles over seeds 1-4 from %u to %u (more than 1.3 times)", (unsigned)lo,
              (unsigned)hi);
    scene_free(s);
}

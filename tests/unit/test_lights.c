/* The tracer's light selection (tracer/lights.h): in two rooms separated by a
 * wall, a point's shadow rays go to its own room's light, on either face of
 * the wall; the pdf that light_pdf_area reports is the density light_sample
 * draws from; emitters behind a point get only the defensive share;
 * emitters of negligible estimate are no candidates; unblocked candidates
 * are weighed by power * cos / d^2; racing threads make
 * the same estimates; the per-point choice is kept only where
 * it can gain; every triangle is picked as often as its pdf says, through
 * short and long CDFs alike. */
#include <criterion/criterion.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tests/support/testscenes.h"
#include "tracer/embree_scene.h"
#include "tracer/lights.h"

#define CHECK(x) do { int rc_ = (x); cr_assert_eq(rc_, 0, "%s: %s", #x, err.msg); } while (0)

typedef struct two_rooms {
    ct_scene *s;
    emb_scene *emb;
    light_set *l;
    int light_a, light_b, lamp_b;   /* part nodes */
} two_rooms;

/* Finalizes s and builds its Embree scene and light set. */
static void lights_of(ct_scene *s, emb_scene **e, light_set **l)
{
    ct_error err;
    CHECK(scene_finalize(s, &err));
    emb_mesh m = emb_mesh_of_scene(s);
    CHECK(emb_new(&m, NULL, e, &err));
    CHECK(light_build(*e, l, &err));
}

/* Room A is x in [0, 4], room B x in [4.1, 8.1] (a 0.1 wall between, closed
 * boxes), 3 high, 4 deep; a ceiling light in each, facing down, and a small
 * floor lamp (a closed box: not flat) in B. */
static void two_rooms_make(two_rooms *r)
{
    ct_error err;
    r->s = scene_new("two rooms");
    int wall = ts_diffuse(r->s, "wall", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(r->s, "lamp", v3s(0.0f), v3s(10.0f), &err);
    cr_assert(wall >= 0 && lamp >= 0);
    cr_assert(ts_box(r->s, "room_a", (uint32_t)wall, v3(0, 0, 0), v3(4, 3, 4), true, &err) >= 0);
    cr_assert(ts_box(r->s, "room_b", (uint32_t)wall, v3(4.1f, 0, 0), v3(8.1f, 3, 4), true, &err) >= 0);
    /* Front side e1 x e2 = (1,0,0) x (0,0,1) = (0,-1,0): down. */
    r->light_a = ts_quad(r->s, "light_a", (uint32_t)lamp, v3(1.5f, 2.99f, 1.5f), v3(1, 0, 0), v3(0, 0, 1), &err);
    r->light_b = ts_quad(r->s, "light_b", (uint32_t)lamp, v3(5.6f, 2.99f, 1.5f), v3(1, 0, 0), v3(0, 0, 1), &err);
    r->lamp_b = ts_box(r->s, "lamp_b", (uint32_t)lamp, v3(7.5f, 0.5f, 3.5f), v3(7.6f, 0.6f, 3.6f), false, &err);
    cr_assert(r->light_a >= 0 && r->light_b >= 0 && r->lamp_b >= 0);
    lights_of(r->s, &r->emb, &r->l);
}

static void two_rooms_free(two_rooms *r)
{
    light_free(r->l);
    emb_free(r->emb);
    scene_free(r->s);
}

/* Probability under sel that the picked point lies on part node. */
static double p_on(const light_set *l, const emb_scene *e, const light_sel *sel, int node)
{
    const emb_mesh *m = emb_get_mesh(e);
    double p = 0.0;
    for (uint32_t t = 0; t < m->ntris; t++)
        if (m->tri_node[t] == (uint32_t)node) p += (double)light_pdf_area(l, sel, t) * emb_tri_area(m, t);
    return p;
}

static double p_node(const two_rooms *r, const light_sel *sel, int node) { return p_on(r->l, r->emb, sel, node); }

Test(lights, own_room_light_gets_the_shadow_rays)
{
    two_rooms r;
    two_rooms_make(&r);
    cr_assert_eq(light_emitters(r.l), 3u);
    light_sel sel;
    light_select(r.l, v3(1.0f, 0.0f, 3.0f), v3(0, 1, 0), &sel);   /* on room A's floor */
    double pa = p_node(&r, &sel, r.light_a), pb = p_node(&r, &sel, r.light_b), pl = p_node(&r, &sel, r.lamp_b);
    cr_expect(fabs(pa + pb + pl - 1.0) < 1e-4, "probabilities sum to %g", pa + pb + pl);
    cr_expect(pa > 0.9, "room A's light gets %g of the shadow rays (B's light %g, B's lamp %g)", pa, pb, pl);
    /* Blocked lights keep a positive density (unbiased). */
    cr_expect(pb > 0.0 && pl > 0.0);
    /* Picking by power alone would send most rays elsewhere: the test scene
     * is one where the selection matters. */
    light_sel pow;
    light_select_power(&pow);
    cr_expect(p_node(&r, &pow, r.light_a) < 0.6);
    light_select(r.l, v3(7.0f, 0.0f, 1.0f), v3(0, 1, 0), &sel);   /* room B's floor */
    cr_expect(p_node(&r, &sel, r.light_a) < 0.1, "room A's light from room B: %g",
              p_node(&r, &sel, r.light_a));
    two_rooms_free(&r);
}

Test(lights, each_side_of_a_wall_gets_its_own_rooms_light)
{
    two_rooms r;
    two_rooms_make(&r);
    /* Both faces of the wall between the rooms (x = 4 faces room A, x = 4.1
     * room B) may share grid cells: the side decides. */
    light_sel sel;
    light_select(r.l, v3(4.0f, 1.2f, 2.2f), v3(-1, 0, 0), &sel);
    cr_expect(p_node(&r, &sel, r.light_a) > 0.9, "room A's face: A's light gets %g", p_node(&r, &sel, r.light_a));
    light_select(r.l, v3(4.1f, 1.2f, 2.2f), v3(1, 0, 0), &sel);
    cr_expect(p_node(&r, &sel, r.light_a) < 0.1, "room B's face: A's light gets %g", p_node(&r, &sel, r.light_a));
    two_rooms_free(&r);
}

Test(lights, sampled_points_follow_the_reported_pdf)
{
    two_rooms r;
    two_rooms_make(&r);
    const emb_mesh *m = emb_get_mesh(r.emb);
    vec3 xs[] = {v3(1.0f, 0.0f, 3.0f), v3(4.1f, 1.5f, 2.0f), v3(7.0f, 1.0f, 3.0f)};
    vec3 ns[] = {v3(0, 1, 0), v3(1, 0, 0), v3(0, 0, 1)};
    for (size_t k = 0; k < sizeof xs / sizeof xs[0]; k++) {
        light_sel sel;
        light_select(r.l, xs[k], ns[k], &sel);
        enum { N = 200000 };
        int hits[3] = {0, 0, 0};
        for (int i = 0; i < N; i++) {
            float u0 = ((float)i + 0.5f) / N, u1 = fmodf((float)i * 0.618034f, 1.0f),
                  u2 = fmodf((float)i * 0.754878f, 1.0f);
            light_point lp;
            cr_assert(light_sample(r.l, &sel, u0, u1, u2, &lp));
            cr_assert(fabsf(lp.pdf_area - light_pdf_area(r.l, &sel, lp.tri)) <= 1e-6f * lp.pdf_area);
            uint32_t node = m->tri_node[lp.tri];
            hits[node == (uint32_t)r.light_a ? 0 : node == (uint32_t)r.light_b ? 1 : 2]++;
        }
        int nodes[3] = {r.light_a, r.light_b, r.lamp_b};
        for (int j = 0; j < 3; j++) {
            double want = p_node(&r, &sel, nodes[j]), got = (double)hits[j] / N;
            cr_expect(fabs(got - want) < 2e-3, "point %zu emitter %d: picked %g, pdf says %g", k, j, got, want);
        }
    }
    two_rooms_free(&r);
}

Test(lights, emitters_behind_get_only_the_defensive_share)
{
    ct_error err;
    ct_scene *s = scene_new("three panels");
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3s(5.0f), &err);
    /* Two panels at y = 1 facing down, a point above them (behind both) and
     * a third panel at y = 3 facing down onto it. */
    int p1 = ts_quad(s, "p1", (uint32_t)lamp, v3(0, 1, 0), v3(1, 0, 0), v3(0, 0, 1), &err);
    int p2 = ts_quad(s, "p2", (uint32_t)lamp, v3(2, 1, 0), v3(1, 0, 0), v3(0, 0, 1), &err);
    int p3 = ts_quad(s, "p3", (uint32_t)lamp, v3(1, 3, 0), v3(1, 0, 0), v3(0, 0, 1), &err);
    cr_assert(p1 >= 0 && p2 >= 0 && p3 >= 0);
    emb_scene *e;
    light_set *l;
    lights_of(s, &e, &l);
    light_sel sel;
    light_select(l, v3(1.5f, 1.5f, 0.5f), v3(0, 1, 0), &sel);
    double p[3] = {p_on(l, e, &sel, p1), p_on(l, e, &sel, p2), p_on(l, e, &sel, p3)};
    cr_expect(fabs(p[0] + p[1] + p[2] - 1.0) < 1e-4);
    cr_expect(p[0] + p[1] <= LIGHT_DEFENSIVE + 1e-6, "panels behind the point get %g", p[0] + p[1]);
    cr_expect(p[0] > 0.0 && p[1] > 0.0, "but keep a positive density");
    light_free(l);
    emb_free(e);
    scene_free(s);
}

/* The weight of a flat emitter facing down onto a point x below it, as
 * lights.h states it with an unblocked view (V = 1): power * cos / max(d^2,
 * r^2)^(3/2) with d and cos taken to its centre c, r its bounding radius. */
static double flat_weight(double power, vec3 c, double r2, vec3 x)
{
    double dx = x.x - c.x, dy = x.y - c.y, dz = x.z - c.z;
    double m = fmax(dx * dx + dy * dy + dz * dz, r2);
    return power * (c.y - x.y) / (m * sqrt(m));
}

/* Node's share of the candidate picks under sel: its probability less the
 * defensive pick by power (pow). */
static double cand_share(const light_set *l, const emb_scene *e, const light_sel *sel, const light_sel *pow, int node)
{
    return (p_on(l, e, sel, node) - LIGHT_DEFENSIVE * p_on(l, e, pow, node)) / (1.0 - LIGHT_DEFENSIVE);
}

/* Four ceiling panels of different sizes and radiances over an open floor,
 * and a small lamp box (not flat), all seen unblocked from a point on the
 * floor under the largest panel (closer than its bounding radius): the
 * candidate picks of the panels follow power * cos / d^2 exactly, relative
 * to each other. Five candidates: the weighing's second group of four has
 * three idle lanes. */
Test(lights, candidate_weights_follow_power_cos_over_d2)
{
    ct_error err;
    ct_scene *s = scene_new("open floor");
    int floor_m = ts_diffuse(s, "floor", v3s(0.5f), v3s(0.0f), &err);
    float le[4] = {10.0f, 20.0f, 5.0f, 40.0f};
    vec3 corner[4] = {v3(-1, 3, -1), v3(3, 3, 2), v3(-6, 3, -6), v3(2, 3, -5)};
    float size[4][2] = {{2, 2}, {1, 3}, {6, 6}, {1, 1}};
    int panel[4];
    cr_assert(ts_quad(s, "floor", (uint32_t)floor_m, v3(-20, 0, -20), v3(0, 0, 40), v3(40, 0, 0), &err) >= 0);
    for (int i = 0; i < 4; i++) {
        char name[16];
        snprintf(name, sizeof name, "panel%d", i);
        int mat = ts_diffuse(s, name, v3s(0.0f), v3s(le[i]), &err);
        /* Front side (1,0,0) x (0,0,1) = (0,-1,0): down. */
        panel[i] = ts_quad(s, name, (uint32_t)mat, corner[i], v3(size[i][0], 0, 0), v3(0, 0, size[i][1]), &err);
        cr_assert(mat >= 0 && panel[i] >= 0);
    }
    int bulb = ts_diffuse(s, "bulb", v3s(0.0f), v3s(100.0f), &err);
    int lamp = ts_box(s, "lamp", (uint32_t)bulb, v3(-3, 0.5f, 3), v3(-2.8f, 0.7f, 3.2f), false, &err);
    cr_assert(bulb >= 0 && lamp >= 0);
    emb_scene *e;
    light_set *l;
    lights_of(s, &e, &l);
    cr_assert(light_is_spatial(l), "gain %g", light_spatial_gain(l));
    vec3 x = v3(-3.0f, 0.0f, -3.0f);
    light_sel sel, pow;
    light_select(l, x, v3(0, 1, 0), &sel);
    light_select_power(&pow);
    cr_assert_eq(sel.n, 5u, "candidates: %u", sel.n);
    double share[4], w[4];
    for (int i = 0; i < 4; i++) {
        share[i] = cand_share(l, e, &sel, &pow, panel[i]);
        vec3 c = v3(corner[i].x + 0.5f * size[i][0], 3.0f, corner[i].z + 0.5f * size[i][1]);
        double r2 = 0.25 * (size[i][0] * size[i][0] + size[i][1] * size[i][1]);
        w[i] = flat_weight(size[i][0] * size[i][1] * le[i], c, r2, x);
    }
    for (int i = 0; i < 4; i++) {
        double got = share[i] / share[2], want = w[i] / w[2];
        cr_expect(fabs(got - want) <= 1e-3 * want, "panel %d: share %g of the largest panel's, want %g", i, got, want);
    }
    /* The lamp (partly blocked by its own faces): a candidate, and far
     * weaker than the panel over the point. */
    double lamp_share = cand_share(l, e, &sel, &pow, lamp);
    cr_expect(lamp_share > 0.0 && lamp_share < share[2]);
    light_free(l);
    emb_free(e);
    scene_free(s);
}

/* Three rooms in a row, a ceiling panel in each: from the far end of room A,
 * room C's blocked panel is under LIGHT_CAND_MIN_SHARE of the summed
 * estimate (distance and the visibility floor), room B's just above it. C is
 * then no candidate and keeps only the defensive share, which stays
 * positive. */
Test(lights, negligible_emitters_are_no_candidates)
{
    ct_error err;
    ct_scene *s = scene_new("three rooms");
    int wall = ts_diffuse(s, "wall", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3s(10.0f), &err);
    cr_assert(wall >= 0 && lamp >= 0);
    int panel[3];
    for (int k = 0; k < 3; k++) {
        float x0 = 4.1f * (float)k;
        char name[16];
        snprintf(name, sizeof name, "room_%c", 'a' + k);
        cr_assert(ts_box(s, name, (uint32_t)wall, v3(x0, 0, 0), v3(x0 + 4, 3, 4), true, &err) >= 0);
        snprintf(name, sizeof name, "light_%c", 'a' + k);
        panel[k] = ts_quad(s, name, (uint32_t)lamp, v3(x0 + 1.5f, 2.99f, 1.5f), v3(1, 0, 0), v3(0, 0, 1), &err);
        cr_assert(panel[k] >= 0);
    }
    emb_scene *e;
    light_set *l;
    lights_of(s, &e, &l);
    cr_assert(light_is_spatial(l));
    light_sel sel;
    light_select(l, v3(0.3f, 0.0f, 2.0f), v3(0, 1, 0), &sel);
    /* Which panel each candidate is: all of a selection that has only that
     * candidate and no defensive share lands on it. */
    bool cand[3] = {false, false, false};
    for (uint32_t j = 0; j < sel.n; j++) {
        light_sel one = {.n = 1, .defensive = 0.0f, .idx = {sel.idx[j]}, .cdf = {0.0f, 1.0f}};
        for (int k = 0; k < 3; k++)
            if (p_on(l, e, &one, panel[k]) > 0.5) cand[k] = true;
    }
    cr_expect(cand[0] && cand[1], "rooms A and B's panels are candidates");
    cr_expect(!cand[2], "room C's panel is no candidate");
    double pc = p_on(l, e, &sel, panel[2]);
    cr_expect(pc > 0.0 && pc <= LIGHT_DEFENSIVE / 3.0 + 1e-6, "room C's panel keeps the defensive share: %g", pc);
    light_free(l);
    emb_free(e);
    scene_free(s);
}

typedef struct race {
    const light_set *l;
    vec3 x, n;
    light_sel sel;
} race;

static void *race_select(void *arg)
{
    race *r = arg;
    light_select(r->l, r->x, r->n, &r->sel);
    return NULL;
}

Test(lights, racing_threads_make_the_same_estimate)
{
    two_rooms a, b;
    two_rooms_make(&a);
    two_rooms_make(&b);
    vec3 x = v3(4.0f, 1.0f, 2.0f), n = v3(-1, 0, 0);   /* room A's side of the wall between the rooms */
    race rs[4];
    pthread_t th[4];
    for (int i = 0; i < 4; i++) {
        rs[i] = (race){a.l, x, n, {0}};
        cr_assert_eq(pthread_create(&th[i], NULL, race_select, &rs[i]), 0);
    }
    for (int i = 0; i < 4; i++) pthread_join(th[i], NULL);
    light_sel once, again;
    light_select(b.l, x, n, &once);    /* a fresh set: estimates the cell itself */
    light_select(a.l, x, n, &again);   /* the published estimate */
    for (int i = 0; i < 4; i++)
        cr_expect(memcmp(rs[i].sel.cdf, once.cdf, sizeof once.cdf[0] * (once.n + 1)) == 0, "thread %d differs", i);
    cr_expect(memcmp(again.cdf, once.cdf, sizeof once.cdf[0] * (once.n + 1)) == 0);
    two_rooms_free(&a);
    two_rooms_free(&b);
}

/* The per-point choice costs a lookup and a weighing at every shading point;
 * light_build keeps it only where it can gain (lights.h). Two like panels
 * side by side over one room light every point about alike: by power. Two
 * rooms apart: per point. */
Test(lights, per_point_choice_only_where_it_gains)
{
    ct_error err;
    ct_scene *s = scene_new("one room, two panels");
    int wall = ts_diffuse(s, "wall", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3s(10.0f), &err);
    cr_assert(wall >= 0 && lamp >= 0);
    cr_assert(ts_box(s, "room", (uint32_t)wall, v3(0, 0, 0), v3(5, 2.8f, 4.5f), true, &err) >= 0);
    cr_assert(ts_quad(s, "left", (uint32_t)lamp, v3(1.5f, 2.79f, 2.6f), v3(0.8f, 0, 0), v3(0, 0, 0.4f), &err) >= 0);
    cr_assert(ts_quad(s, "right", (uint32_t)lamp, v3(2.7f, 2.79f, 2.6f), v3(0.8f, 0, 0), v3(0, 0, 0.4f), &err) >= 0);
    emb_scene *e;
    light_set *l;
    lights_of(s, &e, &l);
    double g = light_spatial_gain(l);
    cr_expect(g >= 1.0 && g < 1.2, "gain %g", g);
    cr_expect(!light_is_spatial(l));
    light_sel sel;
    light_select(l, v3(1.0f, 0.0f, 1.0f), v3(0, 1, 0), &sel);
    cr_expect_eq(sel.n, 0u, "picked by power");
    light_free(l);
    emb_free(e);
    scene_free(s);

    two_rooms r;
    two_rooms_make(&r);
    cr_expect(light_is_spatial(r.l));
    cr_expect(light_spatial_gain(r.l) > 2.0, "gain %g", light_spatial_gain(r.l));
    two_rooms_free(&r);
}

/* Frequencies with which light_sample picks each emissive triangle under
 * sel, against what light_pdf_area says (pdf * area), stratified over u0. */
static void expect_triangle_frequencies(const light_set *l, const emb_scene *e, const light_sel *sel,
                                        const char *what)
{
    const emb_mesh *m = emb_get_mesh(e);
    enum { N = 400000 };
    int *hits = calloc(m->ntris, sizeof *hits);
    cr_assert(hits);
    for (int i = 0; i < N; i++) {
        float u0 = ((float)i + 0.5f) / N, u1 = fmodf((float)i * 0.618034f, 1.0f),
              u2 = fmodf((float)i * 0.754878f, 1.0f);
        light_point lp;
        cr_assert(light_sample(l, sel, u0, u1, u2, &lp));
        cr_assert(lp.tri < m->ntris);
        hits[lp.tri]++;
    }
    double worst = 0.0;
    for (uint32_t t = 0; t < m->ntris; t++) {
        double want = (double)light_pdf_area(l, sel, t) * emb_tri_area(m, t), got = (double)hits[t] / N;
        worst = fmax(worst, fabs(got - want));
        cr_expect(fabs(got - want) < 1e-4 + 1e-3 * want, "%s: triangle %u picked %g, pdf says %g", what, t, got,
                  want);
    }
    printf("%s: largest frequency error %.2g over %u triangles\n", what, worst, m->ntris);
    free(hits);
}

/* light_sample searches short CDFs by counting and long ones by bisection
 * (lights.c): both must pick every triangle as often as its pdf says. A
 * sphere lamp of 72 triangles of unequal area (a long emitter CDF) and 40 small
 * panels (41 emitters: a long power CDF) pick by power; a point's few
 * candidates give a short CDF. */
Test(lights, every_triangle_is_picked_as_often_as_its_pdf_says)
{
    ct_error err;
    ct_scene *s = scene_new("many lamps");
    int wall = ts_diffuse(s, "wall", v3s(0.5f), v3s(0.0f), &err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3s(4.0f), &err);
    int dim = ts_diffuse(s, "dim", v3s(0.0f), v3(1.0f, 0.5f, 0.25f), &err);
    cr_assert(wall >= 0 && lamp >= 0 && dim >= 0);
    cr_assert(ts_box(s, "hall", (uint32_t)wall, v3(0, 0, 0), v3(20, 3, 4), true, &err) >= 0);
    cr_assert(ts_sphere(s, "globe", (uint32_t)lamp, v3(2, 1.5f, 2), 0.3f, 12, 4, false, &err) >= 0);
    for (int i = 0; i < 40; i++) {
        char name[16];
        snprintf(name, sizeof name, "panel%d", i);
        float x = 0.25f + 0.49f * (float)i, w = 0.1f + 0.01f * (float)(i % 7);
        cr_assert(ts_quad(s, name, (uint32_t)(i % 3 ? lamp : dim), v3(x, 2.99f, 1.0f + 0.05f * (float)(i % 5)),
                          v3(w, 0, 0), v3(0, 0, 0.3f), &err) >= 0);
    }
    emb_scene *e;
    light_set *l;
    lights_of(s, &e, &l);
    cr_assert_eq(light_emitters(l), 41u);
    light_sel sel;
    light_select_power(&sel);
    expect_triangle_frequencies(l, e, &sel, "by power");
    light_select(l, v3(10.0f, 0.0f, 2.0f), v3(0, 1, 0), &sel);
    if (light_is_spatial(l)) cr_expect(sel.n > 0 && sel.n <= LIGHT_CANDS);
    expect_triangle_frequencies(l, e, &sel, "at a floor point");
    light_free(l);
    emb_free(e);
    scene_free(s);
}

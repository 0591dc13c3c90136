/* Light selection: the guide table in front of the CDF picks exactly the
 * triangle a search of the whole CDF picks (the first whose cumulative power
 * exceeds u), every light gets its power share of [0, 1), and the sampled
 * points carry the right pdf. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "common/rng.h"
#include "tests/support/testscenes.h"
#include "tracer/embree_scene.h"
#include "tracer/lights.h"

/* A floor and n emissive quads of different sizes and brightness. */
static ct_scene *lit_scene(int n)
{
    ct_error err;
    ct_scene *s = scene_new("lights");
    cr_assert(s);
    int floor = ts_diffuse(s, "floor", v3s(0.5f), v3s(0.0f), &err);
    cr_assert(floor >= 0);
    cr_assert(ts_quad(s, "floor", (uint32_t)floor, v3(0, 0, 0), v3(100, 0, 0), v3(0, 0, 100), &err) >= 0);
    for (int i = 0; i < n; i++) {
        char name[32];
        snprintf(name, sizeof name, "lamp%d", i);
        float le = 1.0f + (float)(i % 7) * 3.0f;
        int m = ts_diffuse(s, name, v3s(0.0f), v3(le, 0.5f * le, 0.25f * le), &err);
        cr_assert(m >= 0);
        float w = 0.1f + 0.37f * (float)(i % 5), h = 0.2f + 0.11f * (float)(i % 3);
        cr_assert(ts_quad(s, name, (uint32_t)m, v3((float)i, 5, 0), v3(w, 0, 0), v3(0, 0, h), &err) >= 0);
    }
    cr_assert_eq(scene_finalize(s, &err), 0, "%s", err.msg);
    return s;
}

/* The definition: the CDF over emissive triangles in mesh order, summed in
 * double as lights.c does, and the first index whose cdf[i + 1] > u. */
static uint32_t pick_by_definition(const float *cdf, uint32_t n, float u)
{
    for (uint32_t i = 0; i < n; i++)
        if (cdf[i + 1] > u) return i;
    return n - 1;
}

static void check_scene(int nquads)
{
    ct_scene *s = lit_scene(nquads);
    emb_mesh m = emb_mesh_of_scene(s);
    light_set *l;
    ct_error err;
    cr_assert_eq(light_build(&m, &l, &err), 0, "%s", err.msg);
    uint32_t n = light_count(l);
    cr_assert_eq(n, 2u * (uint32_t)nquads);
    float *cdf = calloc(n + 1, sizeof *cdf);
    double *power = calloc(n, sizeof *power), total = 0.0;
    uint32_t k = 0;
    for (uint32_t t = 0; t < m.ntris; t++) {
        vec3 le = m.mats[m.tri_mat[t]].emission;
        if (!(v3_luminance(le) > 0.0f)) continue;
        cr_assert_eq(light_pick_tri(l, k), t);
        power[k] = (double)emb_tri_area(&m, t) * v3_luminance(le);
        total += power[k++];
    }
    /* Exactly as lights.c: the running sum in double, then the ratio. */
    double acc = 0.0;
    for (uint32_t i = 0; i < n; i++) {
        acc += power[i];
        cdf[i + 1] = (float)(acc / total);
    }
    cdf[n] = 1.0f;
    /* Every float of a fine grid, the cell edges included, and random u. */
    enum { GRID = 1 << 20 };
    uint32_t *hits = calloc(n, sizeof *hits);
    uint32_t last = 0;
    for (uint32_t g = 0; g < GRID; g++) {
        float u = (float)g / (float)GRID;
        uint32_t p = light_pick(l, u);
        cr_assert_eq(p, pick_by_definition(cdf, n, u), "u = %.9g: guide picks %u", (double)u, p);
        cr_assert(p >= last, "not monotone at u = %g", (double)u);
        last = p;
        hits[p]++;
    }
    ct_rng r = rng_make(9, (uint64_t)nquads, 0, 0);
    for (int i = 0; i < 200000; i++) {
        float u = rng_float(&r);
        cr_assert_eq(light_pick(l, u), pick_by_definition(cdf, n, u));
    }
    for (uint32_t i = 0; i < n; i++)
        cr_expect(fabs((double)hits[i] / GRID - power[i] / total) < 2.0 / GRID + 1e-6,
                  "light %u: share %g, power share %g", i, (double)hits[i] / GRID, power[i] / total);
    /* A sampled point lies on its triangle's plane with the triangle's pdf. */
    for (int i = 0; i < 1000; i++) {
        light_point lp;
        cr_assert(light_sample(l, rng_float(&r), rng_float(&r), rng_float(&r), &lp));
        cr_expect_float_eq(lp.pdf_area, light_pdf_area(l, lp.tri), 0.0f);
        vec3 a = emb_tri_point(&m, lp.tri, 0.0f, 0.0f);
        cr_expect(fabsf(v3_dot(v3_sub(lp.p, a), lp.n)) < 1e-4f, "sample off its triangle's plane");
    }
    free(hits);
    free(power);
    free(cdf);
    light_free(l);
    scene_free(s);
}

Test(lights, guide_table_picks_as_the_whole_cdf_search) { check_scene(37); }

Test(lights, one_light_and_many) { check_scene(1); check_scene(300); }

Test(lights, no_light)
{
    ct_scene *s = lit_scene(0);
    emb_mesh m = emb_mesh_of_scene(s);
    light_set *l;
    ct_error err;
    cr_assert_eq(light_build(&m, &l, &err), 0, "%s", err.msg);
    cr_expect_eq(light_count(l), 0u);
    light_point lp;
    cr_expect(!light_sample(l, 0.5f, 0.5f, 0.5f, &lp));
    light_free(l);
    scene_free(s);
}

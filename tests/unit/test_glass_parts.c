/* Tests of which glass parts bend light (tracer/glass_parts.h): a pane (a
 * thin box), a pane whose top face is cut into slivers tilted by rounding,
 * and a single sheet pass light on in its own direction; a sphere (smooth
 * or faceted: its facets come in opposite pairs), a prism and a cube bend
 * it; parts without glass never count. */
#include <criterion/criterion.h>
#include <stdlib.h>

#include "tests/support/testscenes.h"
#include "tracer/embree_scene.h"
#include "tracer/glass_parts.h"

#define CHECK(x) do { int rc_ = (x); cr_assert_eq(rc_, 0, "%s: %s", #x, err.msg); } while (0)

/* A triangular prism (a wedge: two triangles and three rectangles) as one part. */
static int prism(ct_scene *s, uint32_t mat, ct_error *err)
{
    int node = scene_begin_node(s, "prism", SCENE_NODE_PART, mat, err);
    if (node < 0) return node;
    vec3 p[6] = {v3(5, 0, 0), v3(6, 0, 0), v3(5.5f, 1, 0), v3(5, 0, 1), v3(6, 0, 1), v3(5.5f, 1, 1)};
    uint32_t v[6];
    for (int i = 0; i < 6; i++) {
        int64_t k = scene_add_vertex(s, p[i], v3(0, 1, 0), err);
        if (k < 0) return (int)k;
        v[i] = (uint32_t)k;
    }
    const uint32_t faces[5][4] = {{0, 2, 1, 0}, {3, 4, 5, 0}, {0, 1, 4, 3}, {1, 2, 5, 4}, {2, 0, 3, 5}};
    for (int f = 0; f < 5; f++) {
        uint32_t idx[4] = {v[faces[f][0]], v[faces[f][1]], v[faces[f][2]], v[faces[f][3]]};
        int rc = scene_add_polygon(s, idx, f < 2 ? 3 : 4, err);
        if (rc) return rc;
    }
    int rc = scene_end_node(s, err);
    return rc ? rc : node;
}

/* A 3 x 1.5 pane 0.01 thick whose faces are quads and whose top edge holds
 * one sliver triangle tilted by 7 degrees (a subdivided mesh's rounded
 * corner), as one part. */
static int sliver_pane(ct_scene *s, uint32_t mat, ct_error *err)
{
    int node = scene_begin_node(s, "sliver pane", SCENE_NODE_PART, mat, err);
    if (node < 0) return node;
    const float x0 = 20, x1 = 23, y0 = 0, y1 = 1.5f, z0 = 0, z1 = 0.01f;
    vec3 q[6][4] = {{v3(x0, y0, z1), v3(x1, y0, z1), v3(x1, y1, z1), v3(x0, y1, z1)},
                    {v3(x1, y0, z0), v3(x0, y0, z0), v3(x0, y1, z0), v3(x1, y1, z0)},
                    {v3(x0, y1, z1), v3(x1, y1, z1), v3(x1, y1, z0), v3(x0, y1, z0)},
                    {v3(x0, y0, z0), v3(x1, y0, z0), v3(x1, y0, z1), v3(x0, y0, z1)},
                    {v3(x0, y0, z0), v3(x0, y0, z1), v3(x0, y1, z1), v3(x0, y1, z0)},
                    {v3(x1, y0, z1), v3(x1, y0, z0), v3(x1, y1, z0), v3(x1, y1, z1)}};
    for (int f = 0; f < 6; f++) {
        uint32_t idx[4];
        for (int k = 0; k < 4; k++) {
            int64_t v = scene_add_vertex(s, q[f][k], v3(0, 1, 0), err);
            if (v < 0) return (int)v;
            idx[k] = (uint32_t)v;
        }
        int rc = scene_add_polygon(s, idx, 4, err);
        if (rc) return rc;
    }
    vec3 t[3] = {v3(x0, y1, z1), v3(x0 + 0.01f, y1 + 0.00123f, z1), v3(x0 + 0.01f, y1, z1 - 0.0005f)};
    uint32_t idx[3];
    for (int k = 0; k < 3; k++) {
        int64_t v = scene_add_vertex(s, t[k], v3(0, 1, 0), err);
        if (v < 0) return (int)v;
        idx[k] = (uint32_t)v;
    }
    int rc = scene_add_polygon(s, idx, 3, err);
    if (rc) return rc;
    rc = scene_end_node(s, err);
    return rc ? rc : node;
}

Test(glass_parts, panes_and_sheets_are_flat_spheres_and_prisms_bend)
{
    ct_error err;
    ct_scene *s = scene_new("glass parts");
    int glass = ts_glass(s, "glass", 1.5f, v3s(1.0f), &err), wall = ts_diffuse(s, "wall", v3s(0.5f), v3s(0), &err);
    cr_assert(glass >= 0 && wall >= 0, "%s", err.msg);
    int pane = ts_box(s, "pane", (uint32_t)glass, v3(-3, 1, -3), v3(3, 1.02f, 3), false, &err);
    int ball = ts_smooth_sphere(s, "ball", (uint32_t)glass, v3(0, 3, 0), 0.5f, 48, 24, &err);
    int faceted = ts_sphere(s, "faceted", (uint32_t)glass, v3(2, 3, 0), 0.5f, 12, 6, false, &err);
    int wedge = prism(s, (uint32_t)glass, &err);
    int sheet = ts_quad(s, "sheet", (uint32_t)glass, v3(-5, 0, -5), v3(1, 0, 0), v3(0, 1, 0), &err);
    int block = ts_box(s, "block", (uint32_t)wall, v3(8, 0, 0), v3(9, 1, 1), false, &err);
    int cube = ts_box(s, "cube", (uint32_t)glass, v3(10, 0, 0), v3(11, 1, 1), false, &err);
    int faceted4 = ts_sphere(s, "faceted4", (uint32_t)glass, v3(12, 3, 0), 0.5f, 8, 4, false, &err);
    int sliver = sliver_pane(s, (uint32_t)glass, &err);
    cr_assert(pane >= 0 && ball >= 0 && faceted >= 0 && wedge >= 0 && sheet >= 0 && block >= 0 && cube >= 0 &&
                  faceted4 >= 0 && sliver >= 0,
              "%s", err.msg);
    CHECK(scene_finalize(s, &err));
    emb_mesh m = emb_mesh_of_scene(s);
    uint8_t *bends = NULL;
    CHECK(gparts_bending(&m, &bends, &err));
    cr_expect_eq(bends[pane], 0, "a pane is flat");
    cr_expect_eq(bends[ball], 1, "a smooth sphere bends light");
    cr_expect_eq(bends[faceted], 1, "a faceted sphere bends light");
    cr_expect_eq(bends[wedge], 1, "a prism bends light");
    cr_expect_eq(bends[sheet], 0, "a sheet is flat");
    cr_expect_eq(bends[block], 0, "no glass, nothing to bend");
    cr_expect_eq(bends[cube], 1, "a cube's sides take light in and out");
    cr_expect_eq(bends[faceted4], 1, "a sphere of 32 facets in opposite pairs bends light");
    cr_expect_eq(bends[sliver], 0, "a pane with a tilted sliver is flat");
    free(bends);
    scene_free(s);
}

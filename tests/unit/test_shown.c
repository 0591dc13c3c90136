/* The shown-node map (master/shown.h): which part the item buffer puts at a
 * pixel, near the eye in a scene far deeper than the view. */
#include <criterion/criterion.h>

#include "common/camera.h"
#include "common/pool.h"
#include "common/radmesh.h"
#include "master/shown.h"

/* Quad a, b, c, d (two triangles) of node `node` into m from vertex v, triangle t. */
static void put_quad(ct_radmesh *m, uint32_t v, uint32_t t, uint32_t node, vec3 a, vec3 b, vec3 c, vec3 d)
{
    m->pos[v] = a;
    m->pos[v + 1] = b;
    m->pos[v + 2] = c;
    m->pos[v + 3] = d;
    const uint32_t ix[6] = {v, v + 1, v + 2, v, v + 2, v + 3};
    for (int k = 0; k < 6; k++) m->tris[3 * t + (uint32_t)k] = ix[k];
    m->tri_node[t] = m->tri_node[t + 1] = node;
}

/* A panel 5 cm ahead of the eye in front of a wall, on a ground 20 km wide:
 * the map shows the panel. The near plane was 10^-4 of the mesh's diagonal
 * (2.8 m here), which clipped the panel away and showed the wall behind it,
 * where the display, whose near plane is 10^-7 of the scene's depth with
 * reversed depth (docs/display.md), draws the panel: every sample on it
 * would have counted as one that hit another object than shown (§3.7). */
Test(shown, a_panel_near_the_eye_shows_in_a_deep_scene)
{
    ct_radmesh m;
    ct_error err;
    cr_assert_eq(rmesh_alloc(&m, 12, 6, 3, &err), 0, "%s", err.msg);
    const float g = 1e4f;
    put_quad(&m, 0, 0, 0, v3(-g, -1, g), v3(g, -1, g), v3(g, -1, -g), v3(-g, -1, -g));
    put_quad(&m, 4, 2, 1, v3(-5, -1, -5), v3(5, -1, -5), v3(5, 5, -5), v3(-5, 5, -5));
    put_quad(&m, 8, 4, 2, v3(-0.01f, -0.01f, -0.05f), v3(0.01f, -0.01f, -0.05f), v3(0.01f, 0.01f, -0.05f),
             v3(-0.01f, 0.01f, -0.05f));
    ct_camera cam = cam_look_at(v3(0, 0, 0), v3(0, 0, -1), v3(0, 1, 0), 60.0f);
    ct_pool *pool;
    cr_assert_eq(pool_new(2, &pool, &err), 0, "%s", err.msg);
    shown_buf *b = NULL;
    enum { W = 33, H = 33 };
    uint32_t out[W * H];
    cr_assert_eq(shown_render(&m, &cam, W, H, pool, &b, 99, out, &err), 0, "%s", err.msg);
    cr_assert_eq(out[(H / 2) * W + W / 2], 2, "the centre pixel shows node %u, not the panel 5 cm ahead (2)",
                 out[(H / 2) * W + W / 2]);
    /* The panel covers about 0.02 / 0.05 of the view's 1.15 height: a few
     * pixels round the centre; the corners see the wall. */
    cr_assert_eq(out[0], 1, "the top left pixel shows node %u, not the wall (1)", out[0]);
    shown_buf_free(b);
    pool_free(pool);
    rmesh_free(&m);
}

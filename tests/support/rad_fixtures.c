#include "tests/support/rad_fixtures.h"

#include <stdio.h>

int rfx_add_grid(ct_scene *s, const char *name, uint32_t mat, vec3 corner, vec3 e1, vec3 e2, int n)
{
    ct_error err;
    if (scene_begin_node(s, name, SCENE_NODE_PART, mat, &err) < 0) return -1;
    vec3 nrm = v3_norm(v3_cross(e1, e2));
    uint32_t base = s->nverts;
    for (int j = 0; j <= n; j++)
        for (int i = 0; i <= n; i++) {
            vec3 p = v3_add(corner, v3_add(v3_scale(e1, (float)i / (float)n), v3_scale(e2, (float)j / (float)n)));
            if (scene_add_vertex(s, p, nrm, &err) < 0) return -1;
        }
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            uint32_t a = base + (uint32_t)(j * (n + 1) + i);
            uint32_t q[4] = {a, a + 1, a + 1 + (uint32_t)(n + 1), a + (uint32_t)(n + 1)};
            if (scene_add_polygon(s, q, 4, &err) != 0) return -1;
        }
    return scene_end_node(s, &err);
}

static int add_mat(ct_scene *s, const char *name, vec3 diffuse, vec3 emission)
{
    scene_material m = scene_material_default(name);
    m.diffuse = diffuse;
    m.emission = emission;
    return scene_add_material(s, &m, NULL);
}

ct_scene *rfx_closed_box(int n, float rho, float le) { return rfx_closed_box_on_ground(n, rho, le, 0.0f); }

ct_scene *rfx_closed_box_on_ground(int n, float rho, float le, float ground)
{
    ct_scene *s = scene_new("box");
    if (!s) return NULL;
    int wall = add_mat(s, "wall", v3s(rho), v3s(0.0f));
    int lamp = add_mat(s, "lamp", v3s(0.0f), v3s(le));
    int rc = 0;
    if (ground > 0.0f)
        rc |= rfx_add_grid(s, "ground", (uint32_t)wall, v3(0.5f - ground, -0.01f, 0.5f - ground), v3(0, 0, 2.0f * ground),
                           v3(2.0f * ground, 0, 0), 1);
    rc |= rfx_add_grid(s, "floor", (uint32_t)wall, v3(0, 0, 0), v3(0, 0, 1), v3(1, 0, 0), n);
    rc |= rfx_add_grid(s, "back", (uint32_t)wall, v3(0, 0, 1), v3(0, 1, 0), v3(1, 0, 0), n);
    rc |= rfx_add_grid(s, "front", (uint32_t)wall, v3(0, 0, 0), v3(1, 0, 0), v3(0, 1, 0), n);
    rc |= rfx_add_grid(s, "left", (uint32_t)wall, v3(0, 0, 0), v3(0, 1, 0), v3(0, 0, 1), n);
    rc |= rfx_add_grid(s, "right", (uint32_t)wall, v3(1, 0, 0), v3(0, 0, 1), v3(0, 1, 0), n);
    /* Ceiling: every quad but the centre one, then the centre as the lamp. */
    ct_error err;
    if (scene_begin_node(s, "ceiling", SCENE_NODE_PART, (uint32_t)wall, &err) < 0) rc = -1;
    int c = n / 2;
    for (int j = 0; j < n && !rc; j++)
        for (int i = 0; i < n && !rc; i++) {
            if (i == c && j == c) continue;
            float x0 = (float)i / (float)n, x1 = (float)(i + 1) / (float)n;
            float z0 = (float)j / (float)n, z1 = (float)(j + 1) / (float)n;
            vec3 q[4] = {v3(x0, 1, z0), v3(x1, 1, z0), v3(x1, 1, z1), v3(x0, 1, z1)};
            uint32_t idx[4];
            for (int k = 0; k < 4; k++) idx[k] = (uint32_t)scene_add_vertex(s, q[k], v3(0, -1, 0), &err);
            rc |= scene_add_polygon(s, idx, 4, &err);
        }
    rc |= scene_end_node(s, &err);
    if (scene_begin_node(s, "lamp", SCENE_NODE_PART, (uint32_t)lamp, &err) < 0) rc = -1;
    if (!rc) {
        float a0 = (float)c / (float)n, a1 = (float)(c + 1) / (float)n;
        vec3 q[4] = {v3(a0, 1, a0), v3(a1, 1, a0), v3(a1, 1, a1), v3(a0, 1, a1)};
        uint32_t idx[4];
        for (int k = 0; k < 4; k++) idx[k] = (uint32_t)scene_add_vertex(s, q[k], v3(0, -1, 0), &err);
        rc |= scene_add_polygon(s, idx, 4, &err);
        rc |= scene_end_node(s, &err);
    }
    if (rc || scene_finalize(s, &err) != 0) {
        scene_free(s);
        return NULL;
    }
    return s;
}

/* A black unit square receiver in z = 0 facing up and a unit square
 * emitter of radiance le spanning corner, corner + e1, corner + e1 + e2. */
static ct_scene *receiver_and_emitter(const char *name, vec3 corner, vec3 e1, vec3 e2, float le)
{
    ct_scene *s = scene_new(name);
    if (!s) return NULL;
    int black = add_mat(s, "black", v3s(0.0f), v3s(0.0f));
    int lamp = add_mat(s, "lamp", v3s(0.0f), v3s(le));
    int rc = 0;
    rc |= rfx_add_grid(s, "receiver", (uint32_t)black, v3(0, 0, 0), v3(1, 0, 0), v3(0, 1, 0), 1);
    rc |= rfx_add_grid(s, "emitter", (uint32_t)lamp, corner, e1, e2, 1);
    ct_error err;
    if (rc || scene_finalize(s, &err) != 0) {
        scene_free(s);
        return NULL;
    }
    return s;
}

ct_scene *rfx_parallel_squares(float d, float le)
{
    return receiver_and_emitter("squares", v3(0, 0, d), v3(0, 1, 0), v3(1, 0, 0), le);
}

ct_scene *rfx_perpendicular_squares(float le)
{
    return receiver_and_emitter("corner", v3(0, 0, 0), v3(0, 1, 0), v3(0, 0, 1), le);
}

ct_scene *rfx_covered_floor(int n, float le)
{
    ct_scene *s = scene_new("covered");
    if (!s) return NULL;
    int white = add_mat(s, "white", v3s(0.8f), v3s(0.0f));
    int black = add_mat(s, "black", v3s(0.0f), v3s(0.0f));
    int lamp = add_mat(s, "lamp", v3s(0.0f), v3s(le));
    int rc = 0;
    rc |= rfx_add_grid(s, "open", (uint32_t)white, v3(-1, 0, -0.5f), v3(0, 0, 1), v3(1, 0, 0), n);
    rc |= rfx_add_grid(s, "covered", (uint32_t)white, v3(0, 0, -0.5f), v3(0, 0, 1), v3(1, 0, 0), n);
    rc |= rfx_add_grid(s, "lid", (uint32_t)black, v3(0, 0.3f, -0.6f), v3(1.1f, 0, 0), v3(0, 0, 1.2f), 1);
    rc |= rfx_add_grid(s, "side", (uint32_t)black, v3(0, 0, -0.6f), v3(0, 0.3f, 0), v3(0, 0, 1.2f), 1);
    rc |= rfx_add_grid(s, "lamp", (uint32_t)lamp, v3(-2.5f, 1.5f, -0.5f), v3(1, 0, 0), v3(0, 0, 1), 1);
    rc |= rfx_add_grid(s, "receiver", (uint32_t)white, v3(-0.55f, 5, -0.05f), v3(0.1f, 0, 0), v3(0, 0, 0.1f), 1);
    ct_error err;
    if (rc || scene_finalize(s, &err) != 0) {
        scene_free(s);
        return NULL;
    }
    return s;
}

ct_scene *rfx_room_with_block(void)
{
    ct_scene *s = scene_new("room");
    if (!s) return NULL;
    int white = add_mat(s, "white", v3s(0.7f), v3s(0.0f));
    int red = add_mat(s, "red", v3(0.7f, 0.2f, 0.2f), v3s(0.0f));
    int lamp = add_mat(s, "lamp", v3s(0.0f), v3s(5.0f));
    int rc = 0;
    /* Room 4 x 3 x 4, opening nothing: floor, 4 walls, ceiling with a lamp
     * hanging just below it. */
    rc |= rfx_add_grid(s, "floor", (uint32_t)white, v3(0, 0, 0), v3(0, 0, 4), v3(4, 0, 0), 4);
    rc |= rfx_add_grid(s, "ceiling", (uint32_t)white, v3(0, 3, 0), v3(4, 0, 0), v3(0, 0, 4), 4);
    rc |= rfx_add_grid(s, "wall_back", (uint32_t)red, v3(0, 0, 4), v3(0, 3, 0), v3(4, 0, 0), 2);
    rc |= rfx_add_grid(s, "wall_front", (uint32_t)white, v3(0, 0, 0), v3(4, 0, 0), v3(0, 3, 0), 2);
    rc |= rfx_add_grid(s, "wall_left", (uint32_t)white, v3(0, 0, 0), v3(0, 3, 0), v3(0, 0, 4), 2);
    rc |= rfx_add_grid(s, "wall_right", (uint32_t)white, v3(4, 0, 0), v3(0, 0, 4), v3(0, 3, 0), 2);
    rc |= rfx_add_grid(s, "lamp", (uint32_t)lamp, v3(1.5f, 2.95f, 1.5f), v3(1, 0, 0), v3(0, 0, 1), 1);
    /* A block 1 x 0.8 x 1 on the floor (top and four sides). */
    vec3 o = v3(1.2f, 0.0f, 1.6f);
    float w = 1.0f, hh = 0.8f;
    rc |= rfx_add_grid(s, "block_top", (uint32_t)white, v3(o.x, hh, o.z), v3(0, 0, w), v3(w, 0, 0), 1);
    rc |= rfx_add_grid(s, "block_s1", (uint32_t)white, o, v3(0, hh, 0), v3(w, 0, 0), 1);
    rc |= rfx_add_grid(s, "block_s2", (uint32_t)white, v3(o.x, 0, o.z + w), v3(w, 0, 0), v3(0, hh, 0), 1);
    rc |= rfx_add_grid(s, "block_s3", (uint32_t)white, o, v3(0, 0, w), v3(0, hh, 0), 1);
    rc |= rfx_add_grid(s, "block_s4", (uint32_t)white, v3(o.x + w, 0, o.z), v3(0, hh, 0), v3(0, 0, w), 1);
    ct_error err;
    if (rc || scene_finalize(s, &err) != 0) {
        scene_free(s);
        return NULL;
    }
    return s;
}

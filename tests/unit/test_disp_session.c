/* The display session's bookkeeping: sample points of the last frames
 * (Fig. 7 view), counters from frames and statistics, and the errors of
 * texture events that do not fit the state (unknown ids, rectangles outside
 * the texture, nodes outside the mesh, sizes out of range). */
#include <criterion/criterion.h>
#include <string.h>

#include "tests/support/disp_fixture.h"

/* The points in order, through the two runs of the ring buffer. */
static uint32_t points_in_order(const disp_session *s, float *out, uint32_t cap)
{
    const float *a, *b;
    uint32_t na, nb;
    disp_session_points(s, &a, &na, &b, &nb);
    cr_assert_leq(na + nb, cap);
    if (na) memcpy(out, a, 3 * sizeof *out * na);
    if (nb) memcpy(out + 3 * na, b, 3 * sizeof *out * nb);
    return na + nb;
}

Test(disp_session, sample_points_of_the_last_frames)
{
    ct_error err;
    disp_session *s = NULL;
    cr_assert_eq(disp_session_new(&s, &err), 0);
    float xyz[3 * 10], got[3 * 10];
    for (int i = 0; i < 30; i++) xyz[i] = (float)(i / 3);   /* point i = (i, i, i) */
    cr_expect_eq(points_in_order(s, got, 10), 0u);
    /* At most 5 points: the oldest are overwritten (the ring wraps). */
    disp_session_set_sample_limits(s, 3, 5);
    disp_session_sample_points(s, xyz, 3, 0);           /* points 0 1 2, drawn in frame 0 */
    disp_session_frame_drawn(s);
    disp_session_sample_points(s, xyz + 9, 4, 7);       /* points 3 4 5 6, frame 1 */
    uint32_t n = points_in_order(s, got, 10);
    cr_assert_eq(n, 5u);
    for (uint32_t i = 0; i < n; i++) cr_expect_float_eq(got[3 * i], (float)(i + 2), 0, "point %u", i);
    const float *a, *b;
    uint32_t na, nb;
    disp_session_points(s, &a, &na, &b, &nb);
    cr_expect(na > 0 && nb > 0, "the ring wrapped: %u + %u", na, nb);
    /* A batch larger than the bound keeps its newest points. */
    disp_session_sample_points(s, xyz, 10, 7);
    n = points_in_order(s, got, 10);
    cr_assert_eq(n, 5u);
    cr_expect_float_eq(got[0], 5.0f, 0);
    cr_expect_float_eq(got[12], 9.0f, 0);
    /* Frames: with 3 kept, frame 1's points go after 3 more frames drawn. */
    disp_session_set_sample_limits(s, 3, 100);
    disp_session_sample_points(s, xyz, 2, 7);           /* 2 more of frame 1: 7 in all */
    disp_session_frame_drawn(s);                        /* frame 1 drawn */
    disp_session_sample_points(s, xyz + 27, 1, 7);      /* point 9, frame 2 */
    disp_session_frame_drawn(s);
    cr_expect_eq(points_in_order(s, got, 10), 8u);
    disp_session_frame_drawn(s);                        /* frame 3: frames 1 and earlier go */
    n = points_in_order(s, got, 10);
    cr_assert_eq(n, 1u);
    cr_expect_float_eq(got[0], 9.0f, 0);
    disp_session_frame_drawn(s);
    cr_expect_eq(points_in_order(s, got, 10), 0u);
    cr_expect_eq(disp_session_counters(s).sample_points, 20u);
    cr_expect_eq(disp_session_counters(s).points_dropped, 7u);
    /* FRAME events count frames and samples. */
    disp_session_frame_end(s, 0, 10, false);
    for (uint32_t f = 1; f < DISP_SAMPLE_FRAMES + 1; f++) disp_session_frame_end(s, f, f == 1 ? 3 : 0, false);
    disp_counters c = disp_session_counters(s);
    cr_expect_eq(c.samples, 13u);
    cr_expect_eq(c.frames, (uint32_t)DISP_SAMPLE_FRAMES + 1);
    cr_expect_eq(c.last_frame, (uint32_t)DISP_SAMPLE_FRAMES);
    /* STATS carry the authoritative total and the all-positive flag. */
    disp_session_stats(s, 5000, true);
    cr_expect(disp_session_all_positive(s));
    disp_session_frame_end(s, 9, 77, false);
    c = disp_session_counters(s);
    cr_expect_eq(c.samples, 5000u, "frames no longer add once stats arrive");
    /* ...but the frames' own counts stay exact (lockstep frames.csv). */
    cr_expect_eq(c.frame_samples, 13u + 77u);
    cr_expect_not(disp_session_all_positive(s), "the latest FRAME or STATS decides");
    disp_session_add_bytes(s, 12);
    cr_expect_eq(disp_session_counters(s).bytes, 12u);
    disp_session_free(s);
}

Test(disp_session, texture_events_that_do_not_fit)
{
    ct_error err;
    gl_backend *b = NULL;
    cr_assert_eq(gl_backend_open(GL_BACKEND_OSMESA, 8, 8, NULL, false, &b, &err), 0, "%s", err.msg);
    disp_session *s = NULL;
    cr_assert_eq(disp_session_new(&s, &err), 0);
    ct_radmesh m;
    fx_box_nodes nd;
    cr_assert_eq(fx_box_mesh(2, &m, &nd, &err), 0);
    cr_assert_eq(disp_session_scene(s, &m, &err), 0, "%s", err.msg);
    uint16_t half[4 * 4 * 3];
    memset(half, 0, sizeof half);
    mat4 id = m4_identity();
    cr_expect_eq(disp_session_tex_patch(s, 3, 0, 0, 1, 1, half, &err), CT_EPROTO);
    cr_expect_eq(disp_session_tex_projection(s, 3, &id, &err), CT_EPROTO);
    cr_expect_eq(disp_session_tex_free(s, 3, &err), CT_EPROTO);
    cr_expect_eq(disp_session_tex_alloc(s, 3, m.nnodes, 4, 4, DISP_PROJ_OBJECT_PARALLEL, &err), CT_ERANGE);
    cr_expect(strstr(err.msg, "node") != NULL, "%s", err.msg);
    cr_expect_eq(disp_session_tex_alloc(s, 3, nd.back, 0, 4, DISP_PROJ_OBJECT_PARALLEL, &err), CT_ERANGE);
    cr_expect_eq(disp_session_tex_alloc(s, 3, nd.back, 4, 100000, DISP_PROJ_OBJECT_PARALLEL, &err), CT_ERANGE);
    cr_expect_eq(disp_session_tex_alloc(s, 3, nd.back, 4, 4, (disp_proj_kind)7, &err), CT_EPROTO);
    cr_assert_eq(disp_session_tex_alloc(s, 3, nd.back, 4, 4, DISP_PROJ_OBJECT_PARALLEL, &err), 0, "%s", err.msg);
    cr_expect_eq(disp_session_tex_patch(s, 3, 2, 2, 3, 1, half, &err), CT_ERANGE);
    cr_expect(strstr(err.msg, "outside 4x4") != NULL, "%s", err.msg);
    cr_expect_eq(disp_session_tex_patch(s, 3, -1, 0, 1, 1, half, &err), CT_ERANGE);
    cr_expect_eq(disp_session_tex_patch(s, 3, 0, 0, 4, 4, half, &err), 0);
    mat4 bad = m4_identity();
    bad.m[1][2] = NAN;
    cr_expect_eq(disp_session_tex_projection(s, 3, &bad, &err), CT_ERANGE);
    const disp_texture *t = disp_textures_find(disp_session_textures(s), 3);
    cr_assert_not_null(t);
    cr_expect_not(t->has_proj, "a texture without a projection is not drawn");
    cr_expect_not(t->negative);
    cr_expect_not(t->nonzero, "zero texels (and -0) leave a texture all zero");
    half[7] = 0x8000;   /* -0 */
    cr_expect_eq(disp_session_tex_patch(s, 3, 0, 0, 4, 4, half, &err), 0);
    cr_expect_not(disp_textures_find(disp_session_textures(s), 3)->nonzero);
    cr_expect_not(disp_textures_find(disp_session_textures(s), 3)->negative);
    half[5] = fx_half(-0.25f);
    cr_expect_eq(disp_session_tex_patch(s, 3, 0, 0, 4, 4, half, &err), 0);
    cr_expect(disp_textures_find(disp_session_textures(s), 3)->negative);
    cr_expect(disp_textures_find(disp_session_textures(s), 3)->nonzero);
    /* The node's triangle range covers exactly the back wall's triangles. */
    uint32_t want = 0;
    for (uint32_t i = 0; i < m.ntris; i++) want += m.tri_node[i] == nd.back;
    cr_expect_eq(t->tri_end - t->tri_begin, want);
    /* A resize (TEX_ALLOC of a live id) keeps the projection; an
     * object-local one starts as its old texels scaled (so as non-zero and
     * negative as they were), any other re-allocation at zero; a freed and
     * reused id waits for a new projection. */
    cr_assert_eq(disp_session_tex_projection(s, 3, &id, &err), 0);
    cr_assert_eq(disp_session_tex_alloc(s, 3, nd.back, 8, 8, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    t = disp_textures_find(disp_session_textures(s), 3);
    cr_expect(t->has_proj);
    cr_expect_eq(t->width, 8);
    cr_expect(t->negative, "a resized object-local texture keeps its old texels, scaled");
    cr_expect(t->nonzero, "a resized object-local texture keeps its old texels, scaled");
    cr_assert_eq(disp_session_tex_alloc(s, 3, nd.back, 4, 4, DISP_PROJ_CAMERA_PERSPECTIVE, &err), 0);
    t = disp_textures_find(disp_session_textures(s), 3);
    cr_expect(t->has_proj);
    cr_expect_not(t->negative, "a re-allocated camera-local texture starts at zero");
    cr_expect_not(t->nonzero, "a re-allocated camera-local texture starts at zero");
    cr_expect_eq(disp_session_tex_free(s, 3, &err), 0);
    cr_expect_eq(disp_textures_count(disp_session_textures(s)), 0u);
    cr_assert_eq(disp_session_tex_alloc(s, 3, nd.back, 4, 4, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    cr_expect_not(disp_textures_find(disp_session_textures(s), 3)->has_proj);
    cr_expect_eq(disp_session_tex_free(s, 3, &err), 0);
    /* A new scene drops every texture. */
    cr_assert_eq(disp_session_tex_alloc(s, 4, nd.room, 4, 4, DISP_PROJ_CAMERA_PERSPECTIVE, &err), 0);
    t = disp_textures_find(disp_session_textures(s), 4);
    uint32_t room = 0;
    for (uint32_t i = 0; i < m.ntris; i++) room += m.tri_node[i] >= nd.room && m.tri_node[i] < m.nodes[nd.room].node_end;
    cr_expect_eq(t->tri_end - t->tri_begin, room, "an inner node covers its subtree");
    cr_assert_eq(disp_session_scene(s, &m, &err), 0);
    cr_expect_eq(disp_textures_count(disp_session_textures(s)), 0u);
    rmesh_free(&m);
    disp_session_free(s);
    gl_backend_close(b);
}

/* Node bounds (the compositor orders textured draws by them): each node's
 * box is exactly that of its subtree's triangles; a node without triangles
 * has an empty box. */
Test(disp_session, node_bounds_cover_the_subtree)
{
    ct_error err;
    gl_backend *b = NULL;
    cr_assert_eq(gl_backend_open(GL_BACKEND_OSMESA, 8, 8, NULL, false, &b, &err), 0, "%s", err.msg);
    ct_radmesh m;
    fx_box_nodes nd;
    cr_assert_eq(fx_box_mesh(2, &m, &nd, &err), 0);
    disp_scene *sc = NULL;
    cr_assert_eq(disp_scene_new(&m, &sc, &err), 0, "%s", err.msg);
    uint32_t with_tris = 0;
    for (uint32_t n = 0; n < m.nnodes; n++) {
        bounds3 want = b3_empty();
        for (uint32_t t = 0; t < m.ntris; t++)
            if (m.tri_node[t] >= n && m.tri_node[t] < m.nodes[n].node_end)
                for (int k = 0; k < 3; k++) want = b3_add(want, m.pos[m.tris[3 * t + (uint32_t)k]]);
        bounds3 got = disp_scene_node_bounds(sc, n);
        bool empty = want.lo.x > want.hi.x;
        with_tris += !empty;
        if (empty) {
            cr_expect(got.lo.x > got.hi.x, "node %u has no triangles but a box", n);
            continue;
        }
        cr_expect(memcmp(&got, &want, sizeof got) == 0, "node %u: box (%g %g %g)-(%g %g %g)", n, (double)got.lo.x,
                  (double)got.lo.y, (double)got.lo.z, (double)got.hi.x, (double)got.hi.y, (double)got.hi.z);
    }
    cr_expect_gt(with_tris, 2u);
    bounds3 all = disp_scene_bounds(sc), root = disp_scene_node_bounds(sc, 0);
    cr_expect(memcmp(&all, &root, sizeof all) == 0, "the root covers the whole mesh");
    bounds3 none = disp_scene_node_bounds(sc, m.nnodes);
    cr_expect(none.lo.x > none.hi.x, "a node out of range has an empty box");
    disp_scene_free(sc);
    rmesh_free(&m);
    gl_backend_close(b);
}

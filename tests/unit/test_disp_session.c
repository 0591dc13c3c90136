/* The display session's bookkeeping: sample positions of the last frames
 * (Fig. 7 view), counters from frames and statistics, and the errors of
 * texture events that do not fit the state (unknown ids, rectangles outside
 * the texture, nodes outside the mesh, sizes out of range). */
#include <criterion/criterion.h>
#include <string.h>

#include "tests/support/disp_fixture.h"

Test(disp_session, sample_positions_of_the_last_frames)
{
    ct_error err;
    disp_session *s = NULL;
    cr_assert_eq(disp_session_new(&s, &err), 0);
    float xy[2 * 10];
    for (int i = 0; i < 20; i++) xy[i] = (float)i;
    uint32_t n = 99;
    disp_session_sample_xy(s, &n);
    cr_expect_eq(n, 0u);
    disp_session_samples(s, xy, 10);          /* frame 0 */
    disp_session_frame_end(s, 0, 10, false);
    disp_session_samples(s, xy, 3);           /* frame 1 */
    disp_session_frame_end(s, 1, 3, false);
    const float *p = disp_session_sample_xy(s, &n);
    cr_expect_eq(n, 13u);
    cr_expect_float_eq(p[0], 0.0f, 0);
    for (uint32_t f = 2; f < DISP_SAMPLE_FRAMES + 1; f++) disp_session_frame_end(s, f, 0, false);
    p = disp_session_sample_xy(s, &n);
    /* After DISP_SAMPLE_FRAMES frame ends, frame 0's positions are gone. */
    cr_expect_eq(n, 3u, "%u positions left", n);
    cr_expect_float_eq(p[0], 0.0f, 0);
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
    half[5] = fx_half(-0.25f);
    cr_expect_eq(disp_session_tex_patch(s, 3, 0, 0, 4, 4, half, &err), 0);
    cr_expect(disp_textures_find(disp_session_textures(s), 3)->negative);
    /* The node's triangle range covers exactly the back wall's triangles. */
    uint32_t want = 0;
    for (uint32_t i = 0; i < m.ntris; i++) want += m.tri_node[i] == nd.back;
    cr_expect_eq(t->tri_end - t->tri_begin, want);
    /* A resize (TEX_ALLOC of a live id) keeps the projection; a freed and
     * reused id waits for a new one. */
    cr_assert_eq(disp_session_tex_projection(s, 3, &id, &err), 0);
    cr_assert_eq(disp_session_tex_alloc(s, 3, nd.back, 8, 8, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    t = disp_textures_find(disp_session_textures(s), 3);
    cr_expect(t->has_proj);
    cr_expect_eq(t->width, 8);
    cr_expect_not(t->negative, "a resized texture starts at zero");
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

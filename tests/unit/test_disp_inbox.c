/* test_disp_inbox.c: the hand-over from the display's connection thread to
 * its render thread (display/disp_inbox.h), with a real GL context
 * (OSMesa): many patches of one area between two frames are one upload of
 * the newest texels and render exactly like the same texels applied
 * directly; the upload buffer's storage is kept between frames, grown and
 * given back; a lockstep frame is ready only once its texels are on the
 * textures; a texture freed and allocated again between two frames starts
 * from zero at its new size; stamps reach the frame that shows them;
 * messages that do not fit are refused with their reason; the lag
 * histogram's quantiles; an exact resize (TEX_RESIZE) computed from the
 * inbox's copy and uploaded whole; resizes racing the frames that take them; every
 * kind of message (exact resizes included) in random order racing frames that draw them. Over 600
 * lines: the two threads' cases share one GL rig and its helpers. */
#include <criterion/criterion.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "display/disp_inbox.h"
#include "display/disp_lag.h"
#include "display/disp_rescale.h"
#include "tests/support/disp_fixture.h"

#define W 64
#define H 48

static gl_backend *gl_open(void)
{
    ct_error err;
    gl_backend *b = NULL;
    cr_assert_eq(gl_backend_open(GL_BACKEND_OSMESA, W, H, NULL, false, &b, &err), 0, "%s", err.msg);
    return b;
}

static void render(disp_session *s, uint8_t *out)
{
    ct_error err;
    cr_assert_eq(fx_render_session(s, W, H, out, &err), 0, "%s", err.msg);
}

/* What the hand-over tests share: a GL context, the box scene (handed to
 * the inbox by the test, which owns it until then), an inbox and the
 * render thread's session. */
typedef struct rig {
    gl_backend *b;
    ct_radmesh mesh;
    fx_box_nodes nd;
    disp_inbox *in;
    disp_session *s;
} rig;

static void rig_open(rig *r)
{
    ct_error err;
    r->b = gl_open();
    cr_assert_eq(fx_box_mesh(4, &r->mesh, &r->nd, &err), 0, "%s", err.msg);
    r->in = NULL;
    cr_assert_eq(disp_inbox_new(DISP_TEX_MAX_SIZE, &r->in, &err), 0, "%s", err.msg);
    r->s = NULL;
    cr_assert_eq(disp_session_new(&r->s, &err), 0, "%s", err.msg);
}

static void rig_close(rig *r)
{
    disp_session_free(r->s);
    disp_inbox_release_gl(r->in);
    disp_inbox_free(r->in);
    gl_backend_close(r->b);
}

/* The back wall's projection (x, y in [-1, 1] -> [0, 1]). */
static mat4 wall_proj(void)
{
    mat4 m;
    memset(&m, 0, sizeof m);
    m.m[0][0] = 0.5f;
    m.m[0][3] = 0.5f;
    m.m[1][1] = 0.5f;
    m.m[1][3] = 0.5f;
    m.m[3][3] = 1.0f;
    return m;
}

static void fill(uint16_t *h, int n, float base, float step)
{
    for (int i = 0; i < n; i++) h[i] = fx_half(base + step * (float)(i % 37) - 0.3f * (float)((i / 37) % 3));
}

/* rig_open, the box scene handed to the inbox and texture id (w x h, the
 * back wall's projection) allocated there: the connection thread's side of
 * most cases. */
static void rig_open_wall(rig *r, uint32_t id, int w, int h)
{
    ct_error err;
    rig_open(r);
    ct_radmesh copy;
    cr_assert_eq(fx_box_mesh(4, &copy, NULL, &err), 0);
    disp_inbox_scene(r->in, &copy);
    cr_assert_eq(disp_inbox_tex_alloc(r->in, id, r->nd.back, w, h, DISP_PROJ_OBJECT_PARALLEL, &err), 0, "%s", err.msg);
    mat4 p = wall_proj();
    cr_assert_eq(disp_inbox_tex_projection(r->in, id, &p, &err), 0);
}

/* Whether r's session renders as a fresh session with the same scene and
 * texture id, w x h texels applied directly. */
static bool renders_as_direct(rig *r, uint32_t id, int w, int h, const uint16_t *texels)
{
    ct_error err;
    mat4 p = wall_proj();
    disp_session *direct = NULL;
    cr_assert_eq(disp_session_new(&direct, &err), 0);
    cr_assert_eq(disp_session_scene(direct, &r->mesh, &err), 0);
    cr_assert_eq(disp_session_tex_alloc(direct, id, r->nd.back, w, h, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    cr_assert_eq(disp_session_tex_projection(direct, id, &p, &err), 0);
    cr_assert_eq(disp_session_tex_patch(direct, id, 0, 0, w, h, texels, &err), 0);
    static uint8_t got[W * H * 3], ref[W * H * 3];
    render(r->s, got);
    render(direct, ref);
    disp_session_free(direct);
    return memcmp(got, ref, sizeof got) == 0;
}

Test(disp_inbox, patches_of_one_area_are_one_upload_of_the_newest_texels)
{
    ct_error err;
    rig r;
    /* The connection thread's side: scene, texture, three patches. */
    rig_open_wall(&r, 5, 16, 12);
    disp_inbox *in = r.in;
    disp_session *s = r.s;
    static uint16_t a[16 * 12 * 3], c[6 * 4 * 3], d[16 * 2 * 3];
    fill(a, 16 * 12 * 3, 0.1f, 0.01f);
    fill(c, 6 * 4 * 3, -0.2f, 0.02f);
    fill(d, 16 * 2 * 3, 0.5f, -0.01f);
    cr_assert_eq(disp_inbox_tex_patch(in, 5, 0, 0, 16, 12, a, 1000, 7, &err), 0);
    cr_assert_eq(disp_inbox_tex_patch(in, 5, 3, 2, 6, 4, c, 2000, 3, &err), 0);
    cr_assert_eq(disp_inbox_tex_patch(in, 5, 0, 10, 16, 2, d, 3000, 0, &err), 0);
    /* The render thread's frame. */
    disp_inbox_took took;
    cr_assert_eq(disp_inbox_apply(in, s, &took, &err), 0, "%s", err.msg);
    disp_counters cnt = disp_session_counters(s);
    /* 16 x 12 texels are 2 x 2 tiles of 8: two runs of two tiles, one upload each */
    cr_expect_eq(cnt.patches, 2u, "%llu uploads", (unsigned long long)cnt.patches);
    cr_expect_eq(cnt.texels, 16u * 12u);
    cr_expect_eq(took.uploads, 2u, "the take counts its uploads");
    cr_expect_eq(took.texels, 16u * 12u);
    cr_expect_eq(took.patches, 3u, "patches received");
    cr_expect_eq(took.nstamps, 2u, "stamps of patches that carry samples");
    cr_expect_eq(took.stamps[0].stamp_us, 1000u);
    cr_expect_eq(took.stamps[1].samples, 3u);
    /* The same texels applied directly render the same image. */
    static uint16_t want[16 * 12 * 3];
    memcpy(want, a, sizeof want);
    for (int y = 0; y < 4; y++) memcpy(want + 3 * ((2 + y) * 16 + 3), c + 3 * y * 6, 6 * 6);
    memcpy(want + 3 * 10 * 16, d, sizeof d);
    cr_expect(renders_as_direct(&r, 5, 16, 12, want), "the inbox's image differs from direct patches");
    /* Nothing new: the next frame uploads nothing. */
    cr_assert_eq(disp_inbox_apply(in, s, &took, &err), 0);
    cr_expect_eq(disp_session_counters(s).patches, 2u);
    cr_expect_eq(took.nstamps, 0u);
    rmesh_free(&r.mesh);
    rig_close(&r);
}

/* The upload buffer keeps its storage between takes (re-specifying it each
 * frame made llvmpipe allocate and zero a fresh one every frame): a take that
 * fits reuses it, a larger one grows it, and a window of 64 takes that use
 * under a quarter of it gives the rest back. Texels staged in reused storage
 * render as the same texels applied directly. */
Test(disp_inbox, the_upload_buffer_is_kept_grown_and_given_back)
{
    ct_error err;
    rig r;
    rig_open_wall(&r, 5, 32, 32);
    static uint16_t whole[32 * 32 * 3], tile[8 * 8 * 3];
    fill(whole, 32 * 32 * 3, 0.1f, 0.01f);
    disp_inbox_took took;
    cr_assert_eq(disp_inbox_tex_patch(r.in, 5, 0, 0, 32, 32, whole, 1, 1, &err), 0);
    cr_assert_eq(disp_inbox_apply(r.in, r.s, &took, &err), 0, "%s", err.msg);
    size_t big = took.upload_buffer_bytes;
    cr_assert_geq(big, 32u * 32u * 6u, "the first take's storage holds its texels: %zu bytes", big);
    /* Takes 2..128 upload one 8 x 8 tile each. */
    for (int k = 2; k <= 128; k++) {
        fill(tile, 8 * 8 * 3, 0.02f * (float)k, -0.003f);
        cr_assert_eq(disp_inbox_tex_patch(r.in, 5, 0, 0, 8, 8, tile, (uint64_t)k, 1, &err), 0);
        cr_assert_eq(disp_inbox_apply(r.in, r.s, &took, &err), 0, "%s", err.msg);
        cr_assert_eq(took.uploads, 1u);
        if (k < 128)
            cr_assert_eq(took.upload_buffer_bytes, big, "take %d: kept (%zu bytes, first %zu)", k,
                         took.upload_buffer_bytes, big);
    }
    size_t small = took.upload_buffer_bytes;
    cr_expect_lt(small, big / 2, "a window of small takes gives storage back: %zu of %zu bytes", small, big);
    cr_expect_geq(small, 8u * 8u * 6u);
    /* What the reused storage staged renders as the texels applied directly. */
    static uint16_t want[32 * 32 * 3];
    memcpy(want, whole, sizeof want);
    for (int y = 0; y < 8; y++) memcpy(want + 3 * y * 32, tile + 3 * y * 8, 8 * 6);
    cr_expect(renders_as_direct(&r, 5, 32, 32, want), "texels staged in reused storage render differently");
    /* A larger take grows it again. */
    cr_assert_eq(disp_inbox_tex_patch(r.in, 5, 0, 0, 32, 32, whole, 200, 1, &err), 0);
    cr_assert_eq(disp_inbox_apply(r.in, r.s, &took, &err), 0, "%s", err.msg);
    cr_expect_geq(took.upload_buffer_bytes, big, "grown for the whole texture: %zu bytes", took.upload_buffer_bytes);
    rmesh_free(&r.mesh);
    rig_close(&r);
}

/* Runs of changed tiles at most UPLOAD_GAP_TILES (4) unchanged tiles apart
 * in a row of tiles go up as one upload, the unchanged tiles between them
 * with the texels they hold; five apart, as two. */
Test(disp_inbox, close_runs_of_a_tile_row_are_one_upload)
{
    ct_error err;
    rig r;
    enum { TW = 128, TH = 8 };   /* one row of 16 tiles of 8 x 8 */
    rig_open_wall(&r, 2, TW, TH);
    static uint16_t all[TW * TH * 3], t0[8 * 8 * 3], t5[8 * 8 * 3], t11[8 * 8 * 3];
    fill(all, TW * TH * 3, 0.05f, 0.002f);
    fill(t0, 8 * 8 * 3, 0.4f, 0.01f);
    fill(t5, 8 * 8 * 3, -0.3f, 0.01f);
    fill(t11, 8 * 8 * 3, 0.2f, -0.01f);
    cr_assert_eq(disp_inbox_tex_patch(r.in, 2, 0, 0, TW, TH, all, 100, 1, &err), 0);
    disp_inbox_took took;
    cr_assert_eq(disp_inbox_apply(r.in, r.s, &took, &err), 0, "%s", err.msg);
    cr_expect_eq(took.uploads, 1u, "the whole row of tiles: one run");
    /* tiles 0 and 5 (four unchanged between), 11 (five after 5) */
    cr_assert_eq(disp_inbox_tex_patch(r.in, 2, 0, 0, 8, 8, t0, 200, 1, &err), 0);
    cr_assert_eq(disp_inbox_tex_patch(r.in, 2, 40, 0, 8, 8, t5, 300, 1, &err), 0);
    cr_assert_eq(disp_inbox_tex_patch(r.in, 2, 88, 0, 8, 8, t11, 400, 1, &err), 0);
    cr_assert_eq(disp_inbox_apply(r.in, r.s, &took, &err), 0, "%s", err.msg);
    cr_expect_eq(took.uploads, 2u, "tiles 0-5 and tile 11: %llu uploads, %llu texels", (unsigned long long)took.uploads, (unsigned long long)took.texels);
    cr_expect_eq(took.texels, (uint64_t)(6 * 64 + 64), "tiles 1-4 went up with 0 and 5");
    /* the image is the one of the texels patched directly */
    static uint16_t want[TW * TH * 3];
    memcpy(want, all, sizeof want);
    for (int y = 0; y < 8; y++) {
        memcpy(want + 3 * (y * TW + 0), t0 + 3 * y * 8, 8 * 6);
        memcpy(want + 3 * (y * TW + 40), t5 + 3 * y * 8, 8 * 6);
        memcpy(want + 3 * (y * TW + 88), t11 + 3 * y * 8, 8 * 6);
    }
    cr_expect(renders_as_direct(&r, 2, TW, TH, want), "the merged uploads' image differs from direct patches");
    rmesh_free(&r.mesh);
    rig_close(&r);
}

Test(disp_inbox, a_frame_is_ready_once_its_texels_are_on_the_textures)
{
    ct_error err;
    rig r;
    rig_open(&r);
    disp_inbox *in = r.in;
    disp_session *s = r.s;
    fx_box_nodes nd = r.nd;
    disp_inbox_connection(in);
    disp_inbox_new_epoch(in, 1);
    disp_inbox_scene(in, &r.mesh);
    cr_assert_eq(disp_inbox_tex_alloc(in, 2, nd.floor, 8, 8, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    disp_inbox_took took;
    cr_assert_eq(disp_inbox_apply(in, s, &took, &err), 0);   /* the scene and the texture are drawn */
    static uint16_t t[8 * 8 * 3];
    fill(t, 8 * 8 * 3, 0.2f, 0.001f);
    cr_assert_eq(disp_inbox_tex_patch(in, 2, 0, 0, 8, 8, t, 5, 1, &err), 0);
    disp_inbox_frame_end(in, 0, 1, 100, false);
    cr_expect_not(disp_inbox_frame_ready(in, NULL), "texels still in the inbox");
    cr_assert_eq(disp_inbox_apply(in, s, &took, &err), 0);
    uint64_t f = 99;
    cr_expect(disp_inbox_frame_ready(in, &f));
    cr_expect_eq(f, 0u);
    disp_inbox_take_frame(in);
    cr_expect_not(disp_inbox_frame_ready(in, NULL), "taken once");
    /* A FRAME of an older epoch does not count. */
    disp_inbox_new_epoch(in, 2);
    disp_inbox_frame_end(in, 1, 1, 100, false);
    cr_assert_eq(disp_inbox_apply(in, s, &took, &err), 0);
    cr_expect_not(disp_inbox_frame_ready(in, NULL));
    disp_inbox_frame_end(in, 2, 2, 100, true);
    cr_expect(disp_inbox_frame_ready(in, NULL));
    cr_assert_eq(disp_inbox_apply(in, s, &took, &err), 0);
    cr_expect(disp_session_all_positive(s));
    cr_expect_eq(disp_session_counters(s).frames, 3u);
    rig_close(&r);
}

Test(disp_inbox, freed_and_allocated_again_between_frames_starts_from_zero)
{
    ct_error err;
    rig r;
    rig_open(&r);
    disp_inbox *in = r.in;
    disp_session *s = r.s;
    fx_box_nodes nd = r.nd;
    disp_inbox_scene(in, &r.mesh);
    cr_assert_eq(disp_inbox_tex_alloc(in, 9, nd.back, 8, 8, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    static uint16_t t[16 * 16 * 3];
    fill(t, 16 * 16 * 3, 0.7f, 0.0f);
    cr_assert_eq(disp_inbox_tex_patch(in, 9, 0, 0, 8, 8, t, 1, 1, &err), 0);
    disp_inbox_took took;
    cr_assert_eq(disp_inbox_apply(in, s, &took, &err), 0);
    const disp_texture *x = disp_textures_find(disp_session_textures(s), 9);
    cr_assert_not_null(x);
    cr_expect(x->nonzero);
    /* FREE, then ALLOC of the same id at another size, and one more id
     * allocated and freed unseen: the frame sees only the end state. */
    cr_assert_eq(disp_inbox_tex_free(in, 9, &err), 0);
    cr_assert_eq(disp_inbox_tex_alloc(in, 9, nd.floor, 16, 16, DISP_PROJ_CAMERA_PERSPECTIVE, &err), 0);
    cr_assert_eq(disp_inbox_tex_alloc(in, 11, nd.left, 4, 4, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    cr_assert_eq(disp_inbox_tex_free(in, 11, &err), 0);
    cr_assert_eq(disp_inbox_apply(in, s, &took, &err), 0, "%s", err.msg);
    x = disp_textures_find(disp_session_textures(s), 9);
    cr_assert_not_null(x);
    cr_expect_eq(x->width, 16);
    cr_expect_eq(x->node, nd.floor);
    cr_expect_not(x->nonzero, "a new allocation corrects nothing yet");
    cr_expect_null(disp_textures_find(disp_session_textures(s), 11));
    cr_expect_eq(disp_textures_count(disp_session_textures(s)), 1u);
    rig_close(&r);
}

/* TEX_RESIZE: the inbox computes the new texels from its copy
 * (disp_rescale.h) and the next frame uploads all of them: the image is the
 * one of the same texels patched into a texture of the new size. */
Test(disp_inbox, an_exact_resize_is_computed_here_and_uploaded_whole)
{
    ct_error err;
    rig r;
    rig_open_wall(&r, 5, 16, 12);
    disp_inbox *in = r.in;
    static uint16_t a[16 * 12 * 3], want[32 * 24 * 3];
    fill(a, 16 * 12 * 3, 0.1f, 0.01f);
    for (int i = 0; i < 16 * 12; i += 5) a[3 * i] = a[3 * i + 1] = a[3 * i + 2] = 0;   /* empty texels */
    cr_assert_eq(disp_inbox_tex_patch(in, 5, 0, 0, 16, 12, a, 1000, 7, &err), 0);
    disp_inbox_took took;
    cr_assert_eq(disp_inbox_apply(in, r.s, &took, &err), 0, "%s", err.msg);
    cr_assert_eq(disp_inbox_tex_resize(in, 5, 32, 24, &err), 0, "%s", err.msg);
    cr_assert_eq(disp_inbox_apply(in, r.s, &took, &err), 0, "%s", err.msg);
    cr_expect_eq(took.texels, 32u * 24u, "the whole resized texture goes up: %llu texels",
                 (unsigned long long)took.texels);
    bool neg, nz;
    cr_assert_eq(disp_rescale(a, 16, 12, want, 32, 24, &neg, &nz), 0);
    cr_expect(renders_as_direct(&r, 5, 32, 24, want), "the resized texture's image differs from its texels patched");
    /* a patch at the new size fits; what is no exact resize does not */
    cr_expect_eq(disp_inbox_tex_patch(in, 5, 28, 20, 4, 4, a, 0, 0, &err), 0, "%s", err.msg);
    cr_expect_eq(disp_inbox_tex_resize(in, 5, 48, 24, &err), CT_EPROTO);
    cr_expect(strstr(err.msg, "32x24 -> 48x24 is no exact resize"), "%s", err.msg);
    cr_expect_eq(disp_inbox_tex_resize(in, 6, 8, 8, &err), CT_EPROTO);
    cr_expect(strstr(err.msg, "unknown texture 6"), "%s", err.msg);
    cr_expect_eq(disp_inbox_tex_resize(in, 5, 64, 0, &err), CT_ERANGE);
    cr_assert_eq(disp_inbox_tex_free(in, 5, &err), 0);
    cr_expect_eq(disp_inbox_tex_resize(in, 5, 16, 12, &err), CT_EPROTO, "a freed texture");
    rmesh_free(&r.mesh);
    rig_close(&r);
}

/* Stamps of patches that wait for their upload merge in pairs past 65,536
 * (older stamp, summed samples): a backlog cannot grow the list without
 * bound, and no sample or its oldest time is lost. */
Test(disp_inbox, stamps_of_a_backlog_merge)
{
    ct_error err;
    rig r;
    rig_open(&r);
    disp_inbox *in = r.in;
    ct_radmesh copy;
    cr_assert_eq(fx_box_mesh(4, &copy, NULL, &err), 0);
    disp_inbox_scene(in, &copy);
    cr_assert_eq(disp_inbox_tex_alloc(in, 5, r.nd.back, 16, 12, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    static uint16_t a[3];
    const uint32_t n = 200000;
    uint64_t total = 0;
    for (uint32_t i = 0; i < n; i++) {
        cr_assert_eq(disp_inbox_tex_patch(in, 5, (int)(i % 16), (int)(i / 16 % 12), 1, 1, a, 1000 + i, 1 + i % 3,
                                          &err), 0);
        total += 1 + i % 3;
    }
    disp_inbox_took took;
    cr_assert_eq(disp_inbox_apply(in, r.s, &took, &err), 0, "%s", err.msg);
    cr_assert_leq(took.nstamps, 65536u + 1, "%u stamps kept", took.nstamps);
    uint64_t got = 0, oldest = UINT64_MAX;
    for (uint32_t i = 0; i < took.nstamps; i++) {
        got += took.stamps[i].samples;
        if (took.stamps[i].stamp_us < oldest) oldest = took.stamps[i].stamp_us;
    }
    cr_expect_eq(got, total, "samples %llu of %llu", (unsigned long long)got, (unsigned long long)total);
    cr_expect_eq(oldest, 1000u);
    rmesh_free(&r.mesh);
    rig_close(&r);
}

Test(disp_inbox, messages_that_do_not_fit_are_refused)
{
    ct_error err;
    disp_inbox *in = NULL;
    cr_assert_eq(disp_inbox_new(512, &in, &err), 0);
    static uint16_t t[4 * 3];
    cr_expect_eq(disp_inbox_tex_alloc(in, 1, 0, 4, 4, DISP_PROJ_OBJECT_PARALLEL, &err), CT_EPROTO);
    cr_expect(strstr(err.msg, "before any scene"), "%s", err.msg);
    ct_radmesh mesh;
    fx_box_nodes nd;
    cr_assert_eq(fx_box_mesh(4, &mesh, &nd, &err), 0);
    uint32_t nnodes = mesh.nnodes;
    disp_inbox_scene(in, &mesh);
    cr_expect_eq(disp_inbox_tex_alloc(in, 1, nnodes, 4, 4, DISP_PROJ_OBJECT_PARALLEL, &err), CT_EPROTO);
    cr_expect(strstr(err.msg, "out of range"), "%s", err.msg);
    cr_expect_eq(disp_inbox_tex_alloc(in, 1, 0, 513, 4, DISP_PROJ_OBJECT_PARALLEL, &err), CT_ERANGE);
    cr_expect(strstr(err.msg, "513x4"), "%s", err.msg);
    cr_assert_eq(disp_inbox_tex_alloc(in, 1, 0, 4, 4, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    cr_expect_eq(disp_inbox_tex_patch(in, 1, 3, 0, 2, 1, t, 0, 0, &err), CT_ERANGE);
    cr_expect(strstr(err.msg, "outside 4x4"), "%s", err.msg);
    cr_expect_eq(disp_inbox_tex_patch(in, 2, 0, 0, 1, 1, t, 0, 0, &err), CT_EPROTO);
    cr_expect(strstr(err.msg, "unknown texture 2"), "%s", err.msg);
    /* NaN, +inf, -inf: pixels of NaN otherwise; the largest halves are fine */
    const uint16_t nonfinite[3] = {0x7e00u, 0x7c00u, 0xfc00u};
    for (int k = 0; k < 3; k++) {
        uint16_t p[2 * 3] = {0x3c00u, 0, 0, 0, 0, 0};
        p[3 + k] = nonfinite[k];
        cr_expect_eq(disp_inbox_tex_patch(in, 1, 0, 0, 2, 1, p, 0, 0, &err), CT_ERANGE, "half %#x", nonfinite[k]);
        cr_expect(strstr(err.msg, "texture 1: patch holds non-finite texels"), "%s", err.msg);
    }
    const uint16_t big[3] = {0x7bffu, 0xfbffu, 0x8000u};   /* 65504, -65504, -0 */
    cr_expect_eq(disp_inbox_tex_patch(in, 1, 0, 0, 1, 1, big, 0, 0, &err), 0, "%s", err.msg);
    mat4 bad = m4_identity();
    bad.m[1][2] = NAN;
    cr_expect_eq(disp_inbox_tex_projection(in, 1, &bad, &err), CT_ERANGE);
    cr_expect_eq(disp_inbox_tex_free(in, 3, &err), CT_EPROTO);
    /* A texture per node at most, and the freed ones until a frame: past
     * twice the nodes and 1,024 more, a master only slows the display. */
    uint32_t id = 100, limit = 2 * nnodes + 1024, made = 1;
    for (; made < limit; made++, id++) cr_assert_eq(disp_inbox_tex_alloc(in, id, 0, 1, 1, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    cr_expect_eq(disp_inbox_tex_alloc(in, id, 0, 1, 1, DISP_PROJ_OBJECT_PARALLEL, &err), CT_ERANGE);
    cr_expect(strstr(err.msg, "textures for a scene of"), "%s", err.msg);
    disp_inbox_free(in);
}

Test(disp_lag, quantiles_are_weighted_by_samples)
{
    static disp_lag l;
    disp_lag_reset(&l);
    cr_expect_eq(disp_lag_quantile(&l, 0.5), 0.0);
    disp_lag_add(&l, 10.4, 90);    /* 90 samples at 10 ms */
    disp_lag_add(&l, 250.0, 9);    /* 9 at 250 ms */
    disp_lag_add(&l, 7000.0, 1);   /* 1 at 7 s */
    disp_lag_add(&l, -3.0, 0);     /* no weight: nothing */
    cr_expect_eq(l.n, 100u);
    cr_expect_eq(disp_lag_quantile(&l, 0.5), 11.0, "median in the 10 ms bin (upper edge)");
    cr_expect_eq(disp_lag_quantile(&l, 0.95), 251.0);
    cr_expect_eq(disp_lag_quantile(&l, 0.995), 7001.0);
    cr_expect_eq(l.max_ms, 7000.0);
    disp_lag_add(&l, -5.0, 100);   /* clock offset noise counts as 0 */
    cr_expect_eq(disp_lag_quantile(&l, 0.25), 1.0);
    disp_lag_add(&l, 1e9, 1);      /* beyond the histogram: the last bin */
    cr_expect_eq(disp_lag_quantile(&l, 1.0), (double)DISP_LAG_BINS);
}

/* The connection thread re-allocates a texture at a new size and patches
 * it all while frames are taken: every frame's uploads fit the GL texture
 * its operations made (the texture's operations and its texels are taken
 * together), and the projection of a texture is on the GL side before the
 * texels made for it. */
typedef struct resizer {
    disp_inbox *in;
    uint32_t node;
    int rounds;
    int rc;
    ct_error err;
    atomic_bool done;
} resizer;

static void *resize_loop(void *arg)
{
    resizer *r = arg;
    static uint16_t px[64 * 64 * 3];
    fill(px, 64 * 64 * 3, 0.2f, 0.01f);
    mat4 p = wall_proj();
    for (int i = 0; i < r->rounds && !r->rc; i++) {
        int s = 16 << (i % 3);
        r->rc = disp_inbox_tex_alloc(r->in, 7, r->node, s, s, DISP_PROJ_OBJECT_PARALLEL, &r->err);
        if (!r->rc) r->rc = disp_inbox_tex_projection(r->in, 7, &p, &r->err);
        for (int y = 0; y < s && !r->rc; y += 8)
            r->rc = disp_inbox_tex_patch(r->in, 7, 0, y, s, 8, px, 0, 0, &r->err);
    }
    atomic_store(&r->done, true);
    return NULL;
}

Test(disp_inbox, resizes_racing_frames_upload_into_the_texture_they_were_made_for)
{
    ct_error err;
    rig r;
    rig_open(&r);
    disp_inbox *in = r.in;
    disp_session *s = r.s;
    fx_box_nodes nd = r.nd;
    disp_inbox_scene(in, &r.mesh);
    resizer rz = {.in = in, .node = nd.back, .rounds = 20000};
    atomic_init(&rz.done, false);
    pthread_t th;
    cr_assert_eq(pthread_create(&th, NULL, resize_loop, &rz), 0);
    int frames = 0, rc = 0;
    uint64_t texels = 0;
    while (!rc && !atomic_load(&rz.done)) {
        disp_inbox_took took;
        rc = disp_inbox_apply(in, s, &took, &err);
        texels += took.texels;
        frames++;
    }
    pthread_join(th, NULL);
    cr_assert_eq(rz.rc, 0, "%s", rz.err.msg);
    printf("metric: %d frames taken while 20000 resizes raced them, %llu texels uploaded\n", frames,
           (unsigned long long)texels);
    cr_expect_eq(rc, 0, "frame %d: %s", frames, err.msg);
    rig_close(&r);
}

/* Every message the connection thread hands over, in random order and
 * sizes, racing the frames: textures of a few ids allocated at random
 * sizes, re-allocated, freed and allocated again, patched in random
 * rectangles with stamps, given projections, a new scene now and then,
 * sample points, frame ends and statistics; the render thread applies
 * what arrived, draws it, and reads the stamps a frame took, as the
 * display does. Nothing may be refused (the thread keeps to what it
 * allocated), and under the sanitizers nothing may touch memory it does
 * not own: a free-running walk crashed the display once with a corrupted
 * heap, the walk's traffic being of this kind. */
#define CHURN_IDS 12
typedef struct churner {
    disp_inbox *in;
    fx_box_nodes nd;
    int rounds, scenes;
    int rc;
    ct_error err;
    atomic_bool stop, done;
} churner;

static uint32_t churn_rand(uint64_t *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (uint32_t)(*s >> 33);
}

static void *churn_loop(void *arg)
{
    churner *c = arg;
    static uint16_t px[64 * 64 * 3];
    static float pts[3 * 300];
    fill(px, 64 * 64 * 3, 0.1f, 0.02f);
    for (int i = 0; i < 3 * 300; i++) pts[i] = (float)(i % 7) * 0.1f - 0.3f;
    const uint32_t nodes[] = {c->nd.back, c->nd.floor, c->nd.left, c->nd.right, c->nd.block, c->nd.room};
    int w[CHURN_IDS] = {0}, h[CHURN_IDS] = {0};   /* 0: not allocated */
    uint64_t seed = 12345;
    mat4 p = wall_proj();
    for (int i = 0; !c->rc && !atomic_load(&c->stop); i++) {
        uint32_t r = churn_rand(&seed), id = r % CHURN_IDS, op = (r >> 8) % 100;
        c->rounds = i + 1;
        if (i % 16 == 0) usleep(100);   /* a few hundred messages per frame, as a fast master sends */
        if (i && i % 20000 == 0) {
            ct_radmesh m;
            fx_box_nodes nd;
            c->rc = fx_box_mesh(2 + c->scenes % 3, &m, &nd, &c->err);
            if (!c->rc) {
                disp_inbox_scene(c->in, &m);
                rmesh_free(&m);
                c->scenes++;
                for (int k = 0; k < CHURN_IDS; k++) w[k] = h[k] = 0;
            }
        } else if (op < 15) {
            w[id] = 1 + (int)(churn_rand(&seed) % 64);
            h[id] = 1 + (int)(churn_rand(&seed) % 64);
            disp_proj_kind k = churn_rand(&seed) & 1 ? DISP_PROJ_CAMERA_PERSPECTIVE : DISP_PROJ_OBJECT_PARALLEL;
            c->rc = disp_inbox_tex_alloc(c->in, id, nodes[churn_rand(&seed) % 6], w[id], h[id], k, &c->err);
        } else if (op < 22 && w[id]) {
            c->rc = disp_inbox_tex_free(c->in, id, &c->err);
            w[id] = h[id] = 0;
        } else if (op < 30 && w[id]) {
            c->rc = disp_inbox_tex_projection(c->in, id, &p, &c->err);
        } else if (op < 90 && w[id]) {
            /* (at most 64 x 64: px's size; resizes make textures up to 128) */
            int pw = 1 + (int)(churn_rand(&seed) % (uint32_t)(w[id] < 64 ? w[id] : 64));
            int ph = 1 + (int)(churn_rand(&seed) % (uint32_t)(h[id] < 64 ? h[id] : 64));
            int x = (int)(churn_rand(&seed) % (uint32_t)(w[id] - pw + 1));
            int y = (int)(churn_rand(&seed) % (uint32_t)(h[id] - ph + 1));
            c->rc = disp_inbox_tex_patch(c->in, id, x, y, pw, ph, px, 1000u + (uint64_t)i, 1 + (uint32_t)(r % 5),
                                         &c->err);
        } else if (op < 94) {
            disp_inbox_points(c->in, pts, 1 + r % 300, r % 3);
        } else if (op < 97) {
            disp_inbox_frame_end(c->in, (uint64_t)i, 0, 7, false);
            disp_inbox_stats(c->in, (uint64_t)i, false);
        } else if (w[id]) {
            /* an exact resize, computed outside the lock while frames (and
             * their compaction of the table) go on */
            bool up = w[id] <= 64 && h[id] <= 64;
            int nw = up ? 2 * w[id] : (w[id] + 1) / 2, nh = up ? 2 * h[id] : (h[id] + 1) / 2;
            if (nw != w[id] || nh != h[id]) {
                c->rc = disp_inbox_tex_resize(c->in, id, nw, nh, &c->err);
                w[id] = nw;
                h[id] = nh;
            }
        }
    }
    atomic_store(&c->done, true);
    return NULL;
}

Test(disp_inbox, every_message_racing_frames_in_random_order)
{
    ct_error err;
    rig r;
    /* llvmpipe rasterises on this thread: its rasteriser threads race with
     * the scene reuse of Mesa 22.3 (a fence freed before its signalling
     * thread unlocks it), which this test's hundreds of flushes a second
     * hit about once in 100-200 runs on a busy host, as a crash in malloc
     * (docs/display.md, "Known problems"). The race under test is the
     * inbox's, between the connection thread and this one. */
    setenv("LP_NUM_THREADS", "0", 1);
    rig_open(&r);
    disp_inbox_scene(r.in, &r.mesh);
    churner ch = {.in = r.in, .nd = r.nd};
    atomic_init(&ch.stop, false);
    atomic_init(&ch.done, false);
    pthread_t th;
    cr_assert_eq(pthread_create(&th, NULL, churn_loop, &ch), 0);
    static uint8_t img[W * H * 3];
    int frames = 0, rc = 0;
    uint64_t texels = 0, stamped = 0;
    for (; !rc && frames < 300; frames++) {
        disp_inbox_took took;
        rc = disp_inbox_apply(r.in, r.s, &took, &err);
        if (rc) break;
        texels += took.texels;
        for (uint32_t i = 0; i < took.nstamps; i++) stamped += took.stamps[i].samples;
        if (disp_session_scene_of(r.s)) rc = fx_render_session(r.s, W, H, img, &err);
    }
    atomic_store(&ch.stop, true);
    pthread_join(th, NULL);
    cr_assert_eq(ch.rc, 0, "the connection thread was refused: %s", ch.err.msg);
    cr_expect_eq(rc, 0, "frame %d: %s", frames, err.msg);
    printf("metric: %d frames drew while %d random messages (%d scenes) raced them: %llu texels uploaded, "
           "%llu stamped samples shown\n",
           frames, ch.rounds, ch.scenes, (unsigned long long)texels, (unsigned long long)stamped);
    cr_expect_gt(texels, 0u);
    rig_close(&r);
}

/* The byte count is the session's: a new connection counts from 0, and the
 * render thread's difference (total - applied) wrapped to 3e16 bytes right
 * after a reconnection (the window's title showed kB/s of that size). */
Test(disp_inbox, bytes_received_add_up_over_connections)
{
    disp_inbox *b;
    ct_error err;
    cr_assert_eq(disp_inbox_new(4096, &b, &err), 0, "%s", err.msg);
    disp_inbox_connection(b);
    disp_inbox_bytes(b, 1000);
    cr_expect_eq(disp_inbox_get_state(b).bytes, 1000);
    disp_inbox_connection(b);
    disp_inbox_bytes(b, 10);
    cr_expect_eq(disp_inbox_get_state(b).bytes, 1010, "bytes %llu", (unsigned long long)disp_inbox_get_state(b).bytes);
    disp_inbox_bytes(b, 30);
    cr_expect_eq(disp_inbox_get_state(b).bytes, 1030);
    disp_inbox_free(b);
}

/* (Over 600 lines: the compositor's correction tests over one box fixture.)
 * Corrective textures on the box: a node with a known synthetic correction
 * (object-local parallel on a wall, camera-local perspective on an inner
 * node) gives the expected pixels; one-pass equals three-pass; the
 * subtractive pass is skipped when every correction is positive. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "display/gl_load.h"
#include "tests/support/disp_fixture.h"

#define W 96
#define H 72
/* Expected-pixel tolerance (linear): bilinear weights are computed in
 * reduced precision by some rasterisers; corrections here are <= 0.5. */
#define TOL_TEX 4e-3

typedef struct fx_tex {
    uint32_t id, node;
    int w, h;
    disp_proj_kind kind;
    mat4 proj;
    float *rgb;
    bool half;
} fx_tex;

typedef struct fx_setup {
    fx_tex tex[8];
    int ntex;
} fx_setup;

/* A synthetic correction with both signs, values k/256 (exact in half). */
static float *pattern(int w, int h, int seed, bool positive)
{
    float *p = malloc((size_t)w * (size_t)h * 3 * sizeof *p);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            for (int c = 0; c < 3; c++) {
                float v = 0.45f * sinf(0.9f * (float)x + 1.3f * (float)y + 2.1f * (float)c + (float)seed);
                if (positive) v = fabsf(v);
                p[3 * ((size_t)y * (size_t)w + (size_t)x) + (size_t)c] = roundf(v * 256.0f) / 256.0f;
            }
    return p;
}

/* Object-local parallel projection of the back wall (z = -1) onto the
 * rectangle [x0, x0+sx] x [y0, y0+sy]: s = (x - x0) / sx, t = (y - y0) / sy. */
static mat4 wall_proj(float x0, float y0, float sx, float sy)
{
    mat4 m;
    memset(&m, 0, sizeof m);
    m.m[0][0] = 1.0f / sx; m.m[0][3] = -x0 / sx;
    m.m[1][1] = 1.0f / sy; m.m[1][3] = -y0 / sy;
    m.m[3][3] = 1.0f;
    return m;
}

/* Camera-local perspective projection: the image-plane rectangle
 * [a, b] x [c, d] (NDC) of camera cam mapped to [0,1]^2. */
static mat4 camera_proj(const ct_camera *cam, float a, float b, float c, float d)
{
    mat4 s = m4_identity();
    s.m[0][0] = 1.0f / (b - a); s.m[0][3] = -a / (b - a);
    s.m[1][1] = 1.0f / (d - c); s.m[1][3] = -c / (d - c);
    mat4 pv = m4_mul(cam_proj(cam, W, H, 0.01f, 100.0f), cam_view(cam));
    /* x, y in NDC after the divide; s acts on (x, y, w) since ndc = clip / w. */
    mat4 r = m4_mul(s, pv);
    for (int k = 0; k < 4; k++) {
        r.m[0][k] = s.m[0][0] * pv.m[0][k] + s.m[0][3] * pv.m[3][k];
        r.m[1][k] = s.m[1][1] * pv.m[1][k] + s.m[1][3] * pv.m[3][k];
        r.m[2][k] = 0.0f;
        r.m[3][k] = pv.m[3][k];
    }
    return r;
}

static int setup(disp_session *s, void *ctx, ct_error *err)
{
    fx_setup *f = ctx;
    ct_radmesh m;
    int rc = fx_box_mesh(4, &m, NULL, err);
    if (!rc) rc = disp_session_scene(s, &m, err);
    rmesh_free(&m);
    for (int i = 0; i < f->ntex && !rc; i++) {
        fx_tex *t = &f->tex[i];
        rc = disp_session_tex_alloc(s, t->id, t->node, t->w, t->h, t->kind, err);
        if (!rc) rc = disp_session_tex_projection(s, t->id, &t->proj, err);
        if (rc) break;
        if (t->half) {
            size_t n = (size_t)t->w * (size_t)t->h * 3;
            uint16_t *hv = malloc(n * sizeof *hv);
            for (size_t k = 0; k < n; k++) hv[k] = fx_half(t->rgb[k]);
            /* Two patches: the top half of the rows, then the rest. */
            int h1 = t->h / 2;
            rc = disp_session_tex_patch(s, t->id, 0, 0, t->w, h1, hv, err);
            if (!rc) rc = disp_session_tex_patch(s, t->id, 0, h1, t->w, t->h - h1, hv + (size_t)h1 * (size_t)t->w * 3, err);
            free(hv);
        } else {
            rc = disp_session_tex_patch_float(s, t->id, 0, 0, t->w, t->h, t->rgb, err);
        }
    }
    return rc;
}

/* The node ids of the box (fx_box_mesh) the textures are put on. */
static fx_box_nodes box_nodes(void)
{
    fx_box_nodes nd;
    ct_radmesh m;
    ct_error err;
    cr_assert_eq(fx_box_mesh(4, &m, &nd, &err), 0, "%s", err.msg);
    rmesh_free(&m);
    return nd;
}

/* An in-process display: an OSMesa context, a session and a compositor,
 * all W x H. */
typedef struct rig {
    gl_backend *b;
    disp_session *s;
    disp_compositor *c;
} rig;

/* Opens a rig whose session setup() fills with the box and f's textures
 * (the box alone without f). */
static void rig_open(rig *r, fx_setup *f)
{
    ct_error err;
    fx_setup none = {.ntex = 0};
    memset(r, 0, sizeof *r);
    cr_assert_eq(gl_backend_open(GL_BACKEND_OSMESA, W, H, NULL, false, &r->b, &err), 0, "%s", err.msg);
    cr_assert_eq(disp_session_new(&r->s, &err), 0);
    cr_assert_eq(setup(r->s, f ? f : &none, &err), 0, "%s", err.msg);
    cr_assert_eq(disp_compositor_new(W, H, 0, 1, &r->c, &err), 0, "%s", err.msg);
}

static void rig_close(rig *r)
{
    disp_compositor_free(r->c);
    disp_session_free(r->s);
    gl_backend_close(r->b);
}

/* Renders the session's scene and textures under cam and o (stats into st
 * when not NULL); with disp, presents and reads the display pixels, with
 * lin, reads the linear image. */
static void rig_render(rig *r, const ct_camera *cam, const disp_render_opts *o, disp_render_stats *st, uint8_t *disp,
                       float *lin)
{
    ct_error err;
    cr_assert_eq(disp_compositor_render(r->c, disp_session_scene_of(r->s), disp_session_textures(r->s), cam, o, st, &err),
                 0, "%s", err.msg);
    if (disp) {
        cr_assert_eq(disp_compositor_present(r->c, o, false, W, H, &err), 0, "%s", err.msg);
        disp_compositor_read_display(r->c, disp);
    }
    if (lin) disp_compositor_read_linear(r->c, lin);
}

static bool in_subtree(uint32_t node, uint32_t root, const ct_radmesh *m)
{
    return node >= root && node < m->nodes[root].node_end;
}

/* Expected linear pixels: reference Gouraud plus each texture's bilinear
 * correction where the world point projects into [0,1]^2. Pixels too close
 * to a texture's border (or not smooth) are marked unusable. */
static void expected(const fx_ref *ref, const ct_radmesh *m, const fx_setup *f, float *out, bool *use)
{
    for (size_t p = 0; p < (size_t)W * H; p++) {
        use[p] = ref->smooth[p];
        vec3 c = v3(ref->rgb[3 * p], ref->rgb[3 * p + 1], ref->rgb[3 * p + 2]);
        if (ref->node[p] >= 0) {
            vec3 w = v3(ref->world[3 * p], ref->world[3 * p + 1], ref->world[3 * p + 2]);
            for (int i = 0; i < f->ntex; i++) {
                const fx_tex *t = &f->tex[i];
                if (!in_subtree((uint32_t)ref->node[p], t->node, m)) continue;
                vec4 q = m4_point4(&t->proj, w);
                if (q.w <= 0) continue;
                float s = q.x / q.w, tt = q.y / q.w;
                float margin = 0.03f;
                if (s > -margin && s < 1 + margin && tt > -margin && tt < 1 + margin &&
                    (s < margin || s > 1 - margin || tt < margin || tt > 1 - margin))
                    use[p] = false;
                if (s < 0 || s > 1 || tt < 0 || tt > 1) continue;
                c = v3_add(c, fx_bilinear(t->rgb, t->w, t->h, s, tt));
            }
        }
        out[3 * p] = c.x; out[3 * p + 1] = c.y; out[3 * p + 2] = c.z;
    }
}

static void check_expected(fx_setup *f, int passes, const char *what)
{
    ct_radmesh m;
    ct_camera cam;
    fx_ref ref;
    ct_error err;
    cr_assert_eq(fx_box_reference(W, H, &m, NULL, &cam, &ref, &err), 0, "%s", err.msg);
    float *exp = malloc((size_t)W * H * 3 * sizeof *exp);
    bool *use = malloc((size_t)W * H * sizeof *use);
    expected(&ref, &m, f, exp, use);
    disp_render_opts o = {passes, DISP_VIEW_FULL, 0.0f, false, false, DISP_KEPT_AUTO};
    const gl_backend_kind kinds[2] = {GL_BACKEND_OSMESA, GL_BACKEND_EGL};
    for (int k = 0; k < 2; k++) {
        fx_frame fr;
        char msg[256];
        cr_assert_eq(fx_render(kinds[k], W, H, &cam, &o, setup, f, &fr, msg, sizeof msg), 0, "%s", msg);
        size_t used = 0, corrected = 0;
        double mx = 0;
        for (size_t p = 0; p < (size_t)W * H; p++) {
            if (!use[p]) continue;
            used++;
            bool has = false;
            for (int c = 0; c < 3; c++) {
                double d = fabs((double)fr.linear[3 * p + (size_t)c] - exp[3 * p + (size_t)c]);
                if (d > mx) mx = d;
                if (fabsf(exp[3 * p + (size_t)c] - ref.rgb[3 * p + (size_t)c]) > 1e-3f) has = true;
            }
            corrected += has;
        }
        printf("metric: %s, %d-pass, %s: max |diff| %.2e vs expected over %zu pixels (%zu corrected), tolerance %.0e\n",
               what, passes, gl_backend_name(kinds[k]), mx, used, corrected, TOL_TEX);
        cr_expect_gt(corrected, (size_t)200, "%s: only %zu corrected pixels checked", what, corrected);
        cr_expect_leq(mx, TOL_TEX, "%s %s %d-pass: max error %.3e", what, gl_backend_name(kinds[k]), passes, mx);
        fx_frame_free(&fr);
    }
    free(exp);
    free(use);
    fx_ref_free(&ref);
    rmesh_free(&m);
}

Test(disp_corrections, object_local_parallel)
{
    fx_box_nodes nd = box_nodes();
    fx_setup f = {.ntex = 1};
    f.tex[0] = (fx_tex){7, nd.back, 8, 6, DISP_PROJ_OBJECT_PARALLEL, wall_proj(-0.8f, -0.5f, 1.4f, 1.4f),
                        pattern(8, 6, 1, false), true};
    check_expected(&f, 3, "object-local parallel");
    check_expected(&f, 1, "object-local parallel");
    free(f.tex[0].rgb);
}

Test(disp_corrections, camera_local_perspective_on_inner_node)
{
    fx_box_nodes nd = box_nodes();
    /* The texture was made from an earlier eye position (it floats with the
     * camera), covers part of the image and the whole "room" group. */
    ct_camera old = cam_look_at(v3(0.3f, 0.2f, 3.0f), v3(0, 0, 0), v3(0, 1, 0), 50.0f);
    fx_setup f = {.ntex = 1};
    f.tex[0] = (fx_tex){3, nd.room, 16, 12, DISP_PROJ_CAMERA_PERSPECTIVE,
                        camera_proj(&old, -0.7f, 0.5f, -0.6f, 0.8f), pattern(16, 12, 2, false), false};
    check_expected(&f, 3, "camera-local perspective");
    check_expected(&f, 1, "camera-local perspective");
    free(f.tex[0].rgb);
}

/* In-process rendering of the same setup with 1 and 3 passes. */
static void render_both(fx_setup *f, uint8_t *one, uint8_t *three, float *lin1, float *lin3,
                        disp_render_stats *st1, disp_render_stats *st3, bool all_positive)
{
    rig rg;
    rig_open(&rg, f);
    ct_camera cam = fx_box_camera();
    disp_render_opts o = {1, DISP_VIEW_FULL, 0.5f, all_positive, false, DISP_KEPT_AUTO};
    rig_render(&rg, &cam, &o, st1, one, lin1);
    o.passes = 3;
    o.full_redraw = true;   /* the same camera again: all three passes, not the kept base */
    rig_render(&rg, &cam, &o, st3, three, lin3);
    rig_close(&rg);
}

/* The third frame of one camera: the corrections over the kept base, in
 * screen space, over the mesh, or whichever the compositor picks. */
static void render_kept(fx_setup *f, bool all_positive, disp_kept_corr kept, float *lin, disp_render_stats *st)
{
    rig rg;
    rig_open(&rg, f);
    ct_camera cam = fx_box_camera();
    disp_render_opts o = {1, DISP_VIEW_FULL, 0.5f, all_positive, false, kept};
    for (int i = 0; i < 3; i++) rig_render(&rg, &cam, &o, st, NULL, i == 2 ? lin : NULL);
    rig_close(&rg);
}

/* The kept base's ways of adding corrections against the 1-pass frame
 * drawn at once (lin1): stacked textures (more than 4 on a node), mixed
 * signs and nested nodes all go through the screen pass's per-texture
 * tiles. The box has 174 triangles, far fewer than a 50th of the pixels
 * the screen pass would draw, so the automatic choice is the mesh. */
static void compare_kept(fx_setup *f, bool all_positive, const float *lin1, const char *what)
{
    size_t n = (size_t)W * H * 3;
    float *lk = malloc(n * sizeof *lk);
    static const disp_kept_corr modes[] = {DISP_KEPT_SCREEN, DISP_KEPT_MESH, DISP_KEPT_AUTO};
    static const char *const names[] = {"in screen space", "over the mesh", "chosen (auto)"};
    for (int m = 0; m < 3; m++) {
        disp_render_stats st;
        render_kept(f, all_positive, modes[m], lk, &st);
        double mx, mean;
        fx_diff(lk, lin1, n, &mx, &mean);
        printf("metric: %s: kept base, corrections %s, vs 1-pass drawn at once: linear max %.2e, mean %.2e; %u "
               "draws, %llu pixels in screen space\n", what, names[m], mx, mean, st.draws,
               (unsigned long long)st.screen_px);
        bool screen = modes[m] == DISP_KEPT_SCREEN;
        cr_expect(st.base_reused, "%s: the third frame reuses the base", what);
        cr_expect_eq(st.screen_pass, screen, "%s, %s: screen pass %s", what, names[m],
                     st.screen_pass ? "ran" : "did not run");
        if (screen)
            cr_expect(st.screen_px > 0 && st.screen_px <= (uint64_t)W * H * f->ntex,
                      "%s: the screen pass drew %llu pixels for %d textures", what,
                      (unsigned long long)st.screen_px, f->ntex);
        cr_expect_leq(mx, 1e-5, "%s: kept base (%s) differs by %.3e", what, names[m], mx);
    }
    free(lk);
}

static void compare_passes(fx_setup *f, bool all_positive, bool expect_pass3, const char *what)
{
    size_t n = (size_t)W * H * 3;
    uint8_t *one = malloc(n), *three = malloc(n);
    float *l1 = malloc(n * sizeof *l1), *l3 = malloc(n * sizeof *l3);
    disp_render_stats s1, s3;
    render_both(f, one, three, l1, l3, &s1, &s3, all_positive);
    int dmax = 0;
    size_t ndiff = 0;
    for (size_t i = 0; i < n; i++) {
        int d = abs((int)one[i] - (int)three[i]);
        if (d > dmax) dmax = d;
        ndiff += d != 0;
    }
    double mx, mean;
    fx_diff(l1, l3, n, &mx, &mean);
    printf("metric: %s: 1-pass vs 3-pass: max %d/255 (%zu of %zu values differ), linear max %.2e; draws %u vs %u, pass 3 %s\n",
           what, dmax, ndiff, n, mx, s1.draws, s3.draws, s3.pass3 ? "ran" : "skipped");
    cr_expect_leq(dmax, 1, "%s: 1-pass and 3-pass differ by %d/255", what, dmax);
    cr_expect_leq(mx, 1e-5, "%s: linear difference %.3e", what, mx);
    cr_expect_eq(s3.pass3, expect_pass3, "%s: pass 3 %s", what, s3.pass3 ? "ran" : "skipped");
    compare_kept(f, all_positive, l1, what);
    free(one); free(three); free(l1); free(l3);
}

Test(disp_corrections, one_pass_equals_three_pass)
{
    fx_box_nodes nd = box_nodes();
    ct_camera old = cam_look_at(v3(0.3f, 0.2f, 3.0f), v3(0, 0, 0), v3(0, 1, 0), 50.0f);
    fx_setup f = {.ntex = 8};
    /* Six textures stacked on the back wall (more than the one-pass shader
     * samples at once), one on the block, one camera-local on the room. */
    for (int i = 0; i < 6; i++)
        f.tex[i] = (fx_tex){(uint32_t)(10 + i), nd.back, 4 + i, 5, DISP_PROJ_OBJECT_PARALLEL,
                            wall_proj(-1.0f + 0.2f * (float)i, -0.9f + 0.1f * (float)i, 1.0f, 1.2f),
                            pattern(4 + i, 5, 3 + i, false), i % 2 == 0};
    f.tex[6] = (fx_tex){20, nd.block, 6, 6, DISP_PROJ_CAMERA_PERSPECTIVE, camera_proj(&old, -0.9f, 0.2f, -0.9f, 0.1f),
                        pattern(6, 6, 11, false), true};
    f.tex[7] = (fx_tex){21, nd.room, 9, 7, DISP_PROJ_CAMERA_PERSPECTIVE, camera_proj(&old, -0.2f, 0.9f, -0.3f, 0.9f),
                        pattern(9, 7, 12, false), false};
    compare_passes(&f, false, true, "mixed signs, 8 textures");
    for (int i = 0; i < 8; i++) free(f.tex[i].rgb);
}

Test(disp_corrections, pass3_skipped_when_all_positive)
{
    fx_box_nodes nd = box_nodes();
    fx_setup f = {.ntex = 2};
    f.tex[0] = (fx_tex){1, nd.back, 8, 8, DISP_PROJ_OBJECT_PARALLEL, wall_proj(-1, -1, 2, 2), pattern(8, 8, 5, true), true};
    f.tex[1] = (fx_tex){2, nd.floor, 8, 8, DISP_PROJ_OBJECT_PARALLEL, wall_proj(-1, -1, 2, 2), pattern(8, 8, 6, true), false};
    /* No texel is negative: pass 3 has nothing to do even without the master's flag. */
    compare_passes(&f, false, false, "positive textures");
    compare_passes(&f, true, false, "master says all positive");
    free(f.tex[0].rgb);
    free(f.tex[1].rgb);
}

/* The debug views: corrections only (signed grey), radiosity only, texture
 * assignment colours (Fig. 5), sample positions (Fig. 7). */
Test(disp_corrections, debug_views)
{
    fx_box_nodes nd;
    ct_radmesh m;
    ct_camera cam;
    fx_ref ref;
    ct_error err;
    cr_assert_eq(fx_box_reference(W, H, &m, &nd, &cam, &ref, &err), 0, "%s", err.msg);
    const float cval[3] = {0.25f, -0.125f, 0.5f};
    float rgb[4 * 4 * 3];
    for (int i = 0; i < 48; i++) rgb[i] = cval[i % 3];
    fx_setup f = {.ntex = 1};
    f.tex[0] = (fx_tex){9, nd.back, 4, 4, DISP_PROJ_OBJECT_PARALLEL, wall_proj(-1, -1, 2, 2), rgb, false};

    rig rg;
    rig_open(&rg, &f);
    size_t n = (size_t)W * H;
    float *lin = malloc(n * 3 * sizeof *lin);
    uint8_t *disp = malloc(n * 3);
    disp_render_opts o = {1, DISP_VIEW_CORRECTIONS, 0.0f, false, false, DISP_KEPT_AUTO};

    /* Corrections only: 0.5 + 0.5 * value, no sRGB; grey where none. */
    rig_render(&rg, &cam, &o, NULL, disp, NULL);
    size_t on_wall = 0, bad = 0;
    for (size_t p = 0; p < n; p++) {
        if (!ref.smooth[p]) continue;
        bool wall = ref.node[p] == (int32_t)nd.back;
        on_wall += wall;
        for (int k = 0; k < 3; k++) {
            int want = (int)lroundf(255.0f * (0.5f + 0.5f * (wall ? cval[k] : 0.0f)));
            if (abs(want - (int)disp[3 * p + (size_t)k]) > 1) bad++;
        }
    }
    cr_expect_gt(on_wall, (size_t)300);
    cr_expect_eq(bad, 0u, "corrections view: %zu wrong values", bad);

    /* Radiosity only: the Gouraud reference, no correction. */
    o.view = DISP_VIEW_RADIOSITY;
    rig_render(&rg, &cam, &o, NULL, NULL, lin);
    double mx = 0;
    for (size_t p = 0; p < n; p++)
        if (ref.smooth[p])
            for (int k = 0; k < 3; k++) mx = fmax(mx, fabs(lin[3 * p + (size_t)k] - ref.rgb[3 * p + (size_t)k]));
    cr_expect_leq(mx, 2e-3, "radiosity view differs from Gouraud by %g", mx);

    /* Assignment: the back wall is 0.6 * colour + 0.4 * radiosity with one
     * colour for the whole texture; other parts keep their radiosity. */
    o.view = DISP_VIEW_ASSIGNMENT;
    rig_render(&rg, &cam, &o, NULL, NULL, lin);
    float col[3] = {-1, -1, -1};
    double spread = 0, other = 0;
    for (size_t p = 0; p < n; p++) {
        if (!ref.smooth[p] || ref.node[p] < 0) continue;
        for (int k = 0; k < 3; k++) {
            float v = lin[3 * p + (size_t)k], r = ref.rgb[3 * p + (size_t)k];
            if (ref.node[p] == (int32_t)nd.back) {
                float cc = (v - 0.4f * r) / 0.6f;
                if (col[k] < 0) col[k] = cc;
                spread = fmax(spread, fabs(cc - col[k]));
            } else {
                other = fmax(other, fabs(v - r));
            }
        }
    }
    printf("metric: assignment colour of texture 9: (%.3f %.3f %.3f), spread %.1e; other parts off by %.1e\n",
           col[0], col[1], col[2], spread, other);
    cr_expect_leq(spread, 1e-3);
    cr_expect_leq(other, 2e-3);
    cr_expect(col[0] >= 0.25f && col[1] >= 0.25f && col[2] >= 0.25f);

    free(lin);
    free(disp);
    rig_close(&rg);
    fx_ref_free(&ref);
    rmesh_free(&m);
}

static bool sample_coloured(const uint8_t *px)
{
    return px[0] >= 250 && px[1] >= 190 && px[1] <= 235 && px[2] <= 40;
}

/* Sample points (SAMPLES): world points drawn as dots in the sample colour
 * over the image dimmed to DISP_SAMPLE_DIM, hidden behind nearer geometry,
 * at any exposure; a ring buffer keeps the points of the last frames only. */
Test(disp_corrections, sample_points_in_the_samples_view)
{
    ct_error err;
    rig rg;
    rig_open(&rg, NULL);
    disp_session *s = rg.s;
    disp_compositor *c = rg.c;
    disp_session_set_sample_limits(s, 2, 100);
    ct_camera cam = fx_box_camera();
    /* Two points on the back wall (z = -1), one behind it (hidden). */
    const float pts[9] = {-0.25f, 0.25f, -1.0f, 0.3f, -0.2f, -1.0f, 0.0f, 0.0f, -3.0f};
    disp_session_sample_points(s, pts, 3, 5);
    const float *pa, *pb;
    uint32_t na, nb;
    uint64_t v0 = disp_session_points(s, &pa, &na, &pb, &nb);
    cr_assert_eq(na + nb, 3u);
    cr_expect_eq(disp_session_counters(s).points_dropped, 5u);
    cr_assert_eq(disp_compositor_set_points(c, pa, na, pb, nb, &err), 0, "%s", err.msg);
    size_t n = (size_t)W * H;
    uint8_t *disp = malloc(n * 3);
    float *lin = malloc(n * 3 * sizeof *lin), *full = malloc(n * 3 * sizeof *full);
    disp_render_opts o = {1, DISP_VIEW_FULL, 0.0f, false, false, DISP_KEPT_AUTO};
    rig_render(&rg, &cam, &o, NULL, NULL, full);
    size_t at[3];
    for (int i = 0; i < 3; i++) {
        float px, py;
        cr_assert(cam_project(&cam, W, H, v3(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]), &px, &py, NULL));
        at[i] = (size_t)py * W + (size_t)px;
    }
    for (int e = 0; e < 2; e++) {
        o.view = DISP_VIEW_SAMPLES;
        o.exposure = e ? 2.0f : 0.0f;
        rig_render(&rg, &cam, &o, NULL, disp, lin);
        size_t dots = 0;
        for (size_t p = 0; p < n; p++) dots += sample_coloured(disp + 3 * p);
        for (int i = 0; i < 2; i++)
            cr_expect(sample_coloured(disp + 3 * at[i]), "exposure %g: point %d pixel (%u %u %u)", (double)o.exposure,
                      i, disp[3 * at[i]], disp[3 * at[i] + 1], disp[3 * at[i] + 2]);
        cr_expect_not(sample_coloured(disp + 3 * at[2]), "the point behind the wall shows");
        cr_expect_eq(dots, 2u, "exposure %g: %zu sample-coloured pixels, want 2", (double)o.exposure, dots);
        /* Elsewhere the linear image is the full one dimmed. */
        double worst = 0;
        for (size_t p = 0; p < n; p++) {
            if (p == at[0] || p == at[1]) continue;
            for (int k = 0; k < 3; k++)
                worst = fmax(worst, fabs(lin[3 * p + (size_t)k] - DISP_SAMPLE_DIM * full[3 * p + (size_t)k]));
        }
        cr_expect_leq(worst, 1e-5, "dimmed image off by %g", worst);
    }
    /* Frames: kept for 2 drawn frames, newer points after older ones. */
    disp_session_frame_drawn(s);
    const float one[3] = {0.1f, 0.1f, -1.0f};
    disp_session_sample_points(s, one, 1, 5);
    uint64_t v1 = disp_session_points(s, &pa, &na, &pb, &nb);
    cr_expect_neq(v1, v0);
    cr_expect_eq(na + nb, 4u);
    disp_session_frame_drawn(s);
    disp_session_points(s, &pa, &na, &pb, &nb);
    cr_assert_eq(na + nb, 1u, "after 2 frames only the newer point is left");
    cr_expect_float_eq((na ? pa : pb)[0], 0.1f, 0);
    disp_session_frame_drawn(s);
    disp_session_points(s, &pa, &na, &pb, &nb);
    cr_expect_eq(na + nb, 0u);
    cr_assert_eq(disp_compositor_set_points(c, pa, na, pb, nb, &err), 0);
    o.exposure = 0;
    rig_render(&rg, &cam, &o, NULL, disp, NULL);
    size_t dots = 0;
    for (size_t p = 0; p < n; p++) dots += sample_coloured(disp + 3 * p);
    cr_expect_eq(dots, 0u);
    free(disp);
    free(lin);
    free(full);
    rig_close(&rg);
}

/* A texture that got no patch corrects nothing (allocation zeroes it on the
 * GPU), also after a re-allocation at its size as another kind of a
 * texture that held values; an object-local one the master resized, or
 * re-allocated at its size (the master halving what it sends of a texture
 * that doubled, docs/protocol.md), starts as its old texels (scaled), so its
 * correction does not vanish while the new texels stream. */
/* Both ways of zeroing a texture (display/disp_textures.c): glClearTexImage
 * where the context has it, else a framebuffer clear (CORRTEX_GL_CLEAR_TEXTURE=0,
 * read when the context's entry points are loaded). */
static void zeroing_by(bool clear_texture)
{
    if (clear_texture) unsetenv("CORRTEX_GL_CLEAR_TEXTURE");
    else setenv("CORRTEX_GL_CLEAR_TEXTURE", "0", 1);
}

static void zeroing_check(bool clear_texture)
{
    if (!clear_texture) cr_assert_null(gl.ClearTexImage, "CORRTEX_GL_CLEAR_TEXTURE=0 left glClearTexImage on");
    else if (!gl.ClearTexImage) cr_log_warn("this context lacks glClearTexImage: the framebuffer clear was tested");
}

static void fresh_zero_resized_scaled(bool clear_texture)
{
    fx_box_nodes nd = box_nodes();
    ct_error err;
    rig rg;
    zeroing_by(clear_texture);
    rig_open(&rg, NULL);
    zeroing_check(clear_texture);
    disp_session *s = rg.s;
    mat4 p = wall_proj(-1, -1, 2, 2);
    cr_assert_eq(disp_session_tex_alloc(s, 1, nd.back, 64, 64, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    cr_assert_eq(disp_session_tex_projection(s, 1, &p, &err), 0);
    ct_camera cam = fx_box_camera();
    size_t n = (size_t)W * H * 3;
    float *full = malloc(n * sizeof *full), *rad = malloc(n * sizeof *rad);
    disp_render_opts o = {3, DISP_VIEW_RADIOSITY, 0.0f, false, false, DISP_KEPT_AUTO};
    rig_render(&rg, &cam, &o, NULL, NULL, rad);
    o.view = DISP_VIEW_FULL;
    /* Rounds: fresh 64x64; re-allocated at the same size as a camera-local
     * texture after holding values; as an object-local one at 32x16 after
     * holding values. */
    const int sizes[3][2] = {{64, 64}, {64, 64}, {32, 16}};
    const disp_proj_kind kinds[3] = {DISP_PROJ_OBJECT_PARALLEL, DISP_PROJ_CAMERA_PERSPECTIVE, DISP_PROJ_OBJECT_PARALLEL};
    for (int round = 0; round < 3; round++) {
        /* Never patched with a non-zero value: not drawn at all. */
        disp_render_stats st;
        rig_render(&rg, &cam, &o, &st, NULL, full);
        cr_expect_eq(st.textures_drawn, 0u, "round %d: an all-zero texture was drawn", round);
        cr_expect_eq(memcmp(full, rad, n * sizeof *full), 0, "round %d: pixels changed", round);
        /* A texel of 1e-30 marks it non-zero (so it is drawn) but is 0 as a
         * half float: every texel the GPU holds must still be zero. */
        const float tiny[3] = {1e-30f, 1e-30f, 1e-30f};
        cr_assert_eq(disp_session_tex_patch_float(s, 1, 0, 0, 1, 1, tiny, &err), 0, "%s", err.msg);
        cr_assert(disp_textures_find(disp_session_textures(s), 1)->nonzero);
        for (int passes = 1; passes <= 3; passes += 2) {
            o.passes = passes;
            rig_render(&rg, &cam, &o, &st, NULL, full);
            cr_expect_eq(st.textures_drawn, 1u);
            cr_expect_eq(memcmp(full, rad, n * sizeof *full), 0, "round %d, %d-pass: a zero texture changed pixels", round, passes);
        }
        /* Fill it, then resize: the new texels must be zero again. */
        const disp_texture *t = disp_textures_find(disp_session_textures(s), 1);
        int tw = t->width, th = t->height;
        float *v = malloc((size_t)tw * (size_t)th * 3 * sizeof *v);
        for (int i = 0; i < tw * th * 3; i++) v[i] = 0.5f;
        cr_assert_eq(disp_session_tex_patch_float(s, 1, 0, 0, tw, th, v, &err), 0, "%s", err.msg);
        free(v);
        if (round < 2) {
            cr_assert_eq(disp_session_tex_alloc(s, 1, nd.back, sizes[round + 1][0], sizes[round + 1][1],
                                                kinds[round + 1], &err), 0);
            cr_assert_eq(disp_session_tex_projection(s, 1, &p, &err), 0);
        }
    }
    /* Object-local again, filled with 0.5, then resized to 48x24: drawn as
     * if its 48x24 texels were all 0.5 (a constant scales to itself). */
    cr_assert_eq(disp_session_tex_alloc(s, 1, nd.back, 32, 16, DISP_PROJ_OBJECT_PARALLEL, &err), 0);
    cr_assert_eq(disp_session_tex_projection(s, 1, &p, &err), 0);
    float *half = malloc((size_t)48 * 24 * 3 * sizeof *half);
    for (int i = 0; i < 48 * 24 * 3; i++) half[i] = 0.5f;
    cr_assert_eq(disp_session_tex_patch_float(s, 1, 0, 0, 32, 16, half, &err), 0, "%s", err.msg);
    cr_assert_eq(disp_session_tex_alloc(s, 1, nd.back, 48, 24, DISP_PROJ_OBJECT_PARALLEL, &err), 0, "%s", err.msg);
    cr_assert(disp_textures_find(disp_session_textures(s), 1)->nonzero, "the scaled texels count as non-zero");
    float *scaled = malloc(n * sizeof *scaled);
    o.passes = 3;
    disp_render_stats st;
    rig_render(&rg, &cam, &o, &st, NULL, scaled);
    cr_expect_eq(st.textures_drawn, 1u, "the resized texture was not drawn");
    cr_assert_eq(disp_session_tex_patch_float(s, 1, 0, 0, 48, 24, half, &err), 0, "%s", err.msg);
    rig_render(&rg, &cam, &o, &st, NULL, full);
    double mx, mean;
    fx_diff(scaled, full, n, &mx, &mean);
    printf("metric: resized object-local texture before its patches vs after: linear max %.2e, mean %.2e\n", mx, mean);
    cr_expect_lt(mx, 1e-3, "the scaled old texels differ from the new ones by %g", mx);
    fx_diff(scaled, rad, n, &mx, &mean);
    cr_expect_gt(mx, 0.1, "the resized texture corrected nothing (max %g)", mx);
    /* Re-allocated at its own size and kind: it keeps its texels. */
    cr_assert_eq(disp_session_tex_alloc(s, 1, nd.back, 48, 24, DISP_PROJ_OBJECT_PARALLEL, &err), 0, "%s", err.msg);
    rig_render(&rg, &cam, &o, &st, NULL, scaled);
    fx_diff(scaled, full, n, &mx, &mean);
    printf("metric: object-local texture re-allocated at its size vs before: linear max %.2e\n", mx);
    cr_expect_eq(st.textures_drawn, 1u, "the re-allocated texture was not drawn");
    cr_expect_lt(mx, 1e-6, "a re-allocation at the same size changed the texels by %g", mx);
    free(half);
    free(scaled);
    free(full);
    free(rad);
    rig_close(&rg);
}

Test(disp_corrections, fresh_textures_are_zero_resized_ones_scaled) { fresh_zero_resized_scaled(true); }

Test(disp_corrections, fresh_textures_are_zero_resized_ones_scaled_framebuffer_clear)
{
    fresh_zero_resized_scaled(false);
}

/* A still camera's later frames start from the kept base (radiosity and
 * glass) and draw only the corrections: they equal a frame drawn anew,
 * also after texels changed in between; a moved camera draws anew. */
Test(disp_corrections, kept_base_follows_changed_texels)
{
    fx_box_nodes nd = box_nodes();
    fx_setup f = {.ntex = 2};
    f.tex[0] = (fx_tex){1, nd.back, 8, 8, DISP_PROJ_OBJECT_PARALLEL, wall_proj(-1, -1, 2, 2), pattern(8, 8, 5, false), true};
    f.tex[1] = (fx_tex){2, nd.block, 6, 6, DISP_PROJ_OBJECT_PARALLEL, wall_proj(-1, -1, 2, 2), pattern(6, 6, 7, false), false};
    size_t n = (size_t)W * H * 3;
    float *kept = malloc(n * sizeof *kept), *fresh = malloc(n * sizeof *fresh);
    float *other = pattern(8, 8, 9, false);
    ct_error err;
    for (int passes = 1; passes <= 3; passes += 2) {
        rig rg;
        rig_open(&rg, &f);
        ct_camera cam = fx_box_camera();
        disp_render_opts o = {passes, DISP_VIEW_FULL, 0.0f, false, false, DISP_KEPT_SCREEN};
        disp_render_stats st;
        rig_render(&rg, &cam, &o, &st, NULL, NULL);
        cr_expect_not(st.base_reused, "the first frame has no base");
        rig_render(&rg, &cam, &o, &st, NULL, NULL);
        cr_expect_not(st.base_reused, "the second frame draws the base");
        /* new texels on the back wall, as a stream brings them */
        cr_assert_eq(disp_session_tex_patch_float(rg.s, 1, 0, 0, 8, 8, other, &err), 0, "%s", err.msg);
        rig_render(&rg, &cam, &o, &st, NULL, kept);
        cr_expect(st.base_reused, "%d-pass: the third frame of the same camera reuses the base", passes);
        cr_expect_eq(st.screen_pass, passes == 1, "%d-pass: corrections in screen space only in 1-pass mode", passes);
        o.full_redraw = true;
        rig_render(&rg, &cam, &o, &st, NULL, fresh);
        cr_expect_not(st.base_reused, "--full-redraw draws everything");
        double mx, mean;
        fx_diff(kept, fresh, n, &mx, &mean);
        printf("metric: %d-pass, kept base vs drawn anew after a texel change: linear max %.2e, mean %.2e\n", passes,
               mx, mean);
        cr_expect_leq(mx, 1e-5, "%d-pass: kept base differs from a fresh frame by %.3e", passes, mx);
        /* the changed texels show: the frame differs from the old texels' */
        o.full_redraw = false;
        ct_camera moved = cam;
        moved.eye.x += 0.05f;
        rig_render(&rg, &moved, &o, &st, NULL, NULL);
        cr_expect_not(st.base_reused, "a moved camera draws anew");
        rig_render(&rg, &moved, &o, &st, NULL, NULL);
        rig_render(&rg, &moved, &o, &st, NULL, NULL);
        cr_expect(st.base_reused, "the moved camera's third frame reuses its own base");
        rig_close(&rg);
    }
    /* The new texels changed the image (so the comparison above is not of
     * two unchanged frames). */
    {
        rig rg;
        rig_open(&rg, &f);
        ct_camera cam = fx_box_camera();
        disp_render_opts o = {1, DISP_VIEW_FULL, 0.0f, false, true, DISP_KEPT_AUTO};
        rig_render(&rg, &cam, &o, NULL, NULL, fresh);
        rig_close(&rg);
        double mx, mean;
        fx_diff(kept, fresh, n, &mx, &mean);
        cr_expect_gt(mx, 0.05, "the changed texels do not show (max difference %.3e)", mx);
    }
    free(kept);
    free(fresh);
    free(other);
    free(f.tex[0].rgb);
    free(f.tex[1].rgb);
}

/* A camera-local texture the master resized keeps its projector too: it
 * starts as its old texels scaled; one re-created for a new view (another
 * PROJECTION follows, before any patch) starts as zeros, also when that
 * PROJECTION comes in a later update than its allocation. */
static void camera_local_zero(bool clear_texture)
{
    fx_box_nodes nd = box_nodes();
    ct_error err;
    rig rg;
    zeroing_by(clear_texture);
    rig_open(&rg, NULL);
    zeroing_check(clear_texture);
    disp_session *s = rg.s;
    mat4 p = wall_proj(-1, -1, 2, 2), q = wall_proj(-1, -1, 3, 3);
    ct_camera cam = fx_box_camera();
    size_t n = (size_t)W * H * 3;
    float *rad = malloc(n * sizeof *rad), *scaled = malloc(n * sizeof *scaled), *full = malloc(n * sizeof *full);
    float *half = malloc((size_t)64 * 32 * 3 * sizeof *half);
    for (int i = 0; i < 64 * 32 * 3; i++) half[i] = 0.5f;
    disp_render_opts o = {3, DISP_VIEW_RADIOSITY, 0.0f, false, false, DISP_KEPT_AUTO};
    disp_render_stats st;
    rig_render(&rg, &cam, &o, NULL, NULL, rad);
    o.view = DISP_VIEW_FULL;
    for (int late = 0; late < 2; late++) {
        cr_assert_eq(disp_session_tex_alloc(s, 1, nd.back, 32, 16, DISP_PROJ_CAMERA_PERSPECTIVE, &err), 0, "%s", err.msg);
        cr_assert_eq(disp_session_tex_projection(s, 1, &p, &err), 0, "%s", err.msg);
        cr_assert_eq(disp_session_tex_patch_float(s, 1, 0, 0, 32, 16, half, &err), 0, "%s", err.msg);
        /* resized (§3.6): the same projection follows */
        cr_assert_eq(disp_session_tex_alloc(s, 1, nd.back, 48, 24, DISP_PROJ_CAMERA_PERSPECTIVE, &err), 0, "%s", err.msg);
        cr_assert_eq(disp_session_tex_projection(s, 1, &p, &err), 0, "%s", err.msg);
        rig_render(&rg, &cam, &o, &st, NULL, scaled);
        cr_expect_eq(st.textures_drawn, 1u, "the resized camera-local texture was not drawn");
        cr_assert_eq(disp_session_tex_patch_float(s, 1, 0, 0, 48, 24, half, &err), 0, "%s", err.msg);
        rig_render(&rg, &cam, &o, &st, NULL, full);
        double mx, mean;
        fx_diff(scaled, full, n, &mx, &mean);
        cr_expect_lt(mx, 1e-3, "the scaled old texels differ from the new ones by %g", mx);
        fx_diff(scaled, rad, n, &mx, &mean);
        cr_expect_gt(mx, 0.1, "the resized texture corrected nothing (max %g)", mx);
        /* re-created for another view: another projection, at once or in a
         * later update (drawn in between with the old one) */
        cr_assert_eq(disp_session_tex_alloc(s, 1, nd.back, 64, 32, DISP_PROJ_CAMERA_PERSPECTIVE, &err), 0, "%s", err.msg);
        if (late) rig_render(&rg, &cam, &o, &st, NULL, full);
        cr_assert_eq(disp_session_tex_projection(s, 1, &q, &err), 0, "%s", err.msg);
        cr_assert_not(disp_textures_find(disp_session_textures(s), 1)->nonzero, "late %d: kept the old view's texels", late);
        rig_render(&rg, &cam, &o, &st, NULL, full);
        cr_expect_eq(st.textures_drawn, 0u);
        cr_expect_eq(memcmp(full, rad, n * sizeof *full), 0, "late %d: the reprojected texture changed pixels", late);
        /* patched under the new projection, a later projection change is
         * the master's (texels kept, as before) */
        cr_assert_eq(disp_session_tex_patch_float(s, 1, 0, 0, 64, 32, half, &err), 0, "%s", err.msg);
        cr_assert_eq(disp_session_tex_projection(s, 1, &p, &err), 0, "%s", err.msg);
        cr_assert(disp_textures_find(disp_session_textures(s), 1)->nonzero);
        cr_assert_eq(disp_session_tex_free(s, 1, &err), 0, "%s", err.msg);
    }
    free(half);
    free(full);
    free(scaled);
    free(rad);
    rig_close(&rg);
}

Test(disp_corrections, camera_local_resized_scaled_reprojected_zero) { camera_local_zero(true); }

Test(disp_corrections, camera_local_resized_scaled_reprojected_zero_framebuffer_clear) { camera_local_zero(false); }

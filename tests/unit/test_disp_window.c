/* The GLFW window under Xvfb (started by the test) shows the same image as
 * the headless backends: a screenshot of the window's default framebuffer
 * (glReadPixels of the back buffer) against OSMesa's 8-bit output; and the
 * tone mapping matches exposure + sRGB computed on the CPU. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "tests/support/disp_fixture.h"

#define W 80
#define H 60

static int setup_box(disp_session *s, void *ctx, ct_error *err)
{
    (void)ctx;
    ct_radmesh m;
    fx_box_nodes nd;
    int rc = fx_box_mesh(3, &m, &nd, err);
    if (!rc) rc = disp_session_scene(s, &m, err);
    rmesh_free(&m);
    /* One signed correction so the comparison covers the texture passes. */
    float rgb[4 * 4 * 3];
    for (int i = 0; i < 48; i++) rgb[i] = (float)((i * 37) % 64 - 32) / 128.0f;
    mat4 p;
    memset(&p, 0, sizeof p);
    p.m[0][0] = 0.5f; p.m[0][3] = 0.5f;
    p.m[1][1] = 0.5f; p.m[1][3] = 0.5f;
    p.m[3][3] = 1.0f;
    if (!rc) rc = disp_session_tex_alloc(s, 1, nd.back, 4, 4, DISP_PROJ_OBJECT_PARALLEL, err);
    if (!rc) rc = disp_session_tex_projection(s, 1, &p, err);
    if (!rc) rc = disp_session_tex_patch_float(s, 1, 0, 0, 4, 4, rgb, err);
    return rc;
}

static int max_byte_diff(const uint8_t *a, const uint8_t *b, size_t n, size_t *ndiff)
{
    int m = 0;
    *ndiff = 0;
    for (size_t i = 0; i < n; i++) {
        int d = abs((int)a[i] - (int)b[i]);
        if (d > m) m = d;
        *ndiff += d != 0;
    }
    return m;
}

Test(disp_window, glfw_under_xvfb_matches_headless)
{
    char msg[256];
    pid_t x = fx_xvfb_start(msg, sizeof msg);
    cr_assert_gt(x, 0, "%s", msg);
    ct_camera cam = fx_box_camera();
    disp_render_opts o = {3, DISP_VIEW_FULL, 0.3f, false, false, DISP_KEPT_AUTO};
    fx_frame win, osm;
    int rc = fx_render(GL_BACKEND_GLFW, W, H, &cam, &o, setup_box, NULL, &win, msg, sizeof msg);
    fx_xvfb_stop(x);
    cr_assert_eq(rc, 0, "glfw: %s", msg);
    cr_assert_eq(fx_render(GL_BACKEND_OSMESA, W, H, &cam, &o, setup_box, NULL, &osm, msg, sizeof msg), 0,
                 "osmesa: %s", msg);
    size_t n = (size_t)W * H * 3, ndiff;
    int d = max_byte_diff(win.display, osm.display, n, &ndiff);
    printf("metric: glfw window screenshot vs osmesa: max %d/255, %zu of %zu values differ\n", d, ndiff, n);
    cr_expect_leq(d, 1);
    /* The window shows something: not all black. */
    size_t lit = 0;
    for (size_t i = 0; i < n; i++) lit += win.display[i] > 16;
    cr_expect_gt(lit, n / 4);
    fx_frame_free(&win);
    fx_frame_free(&osm);
}

static double srgb(double x)
{
    x = x < 0 ? 0 : (x > 1 ? 1 : x);
    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

Test(disp_window, tone_mapping_matches_cpu)
{
    ct_camera cam = fx_box_camera();
    const float exposures[3] = {0.0f, 1.0f, -1.5f};
    for (int e = 0; e < 3; e++) {
        disp_render_opts o = {1, DISP_VIEW_FULL, exposures[e], false, false, DISP_KEPT_AUTO};
        fx_frame f;
        char msg[256];
        cr_assert_eq(fx_render(GL_BACKEND_EGL, W, H, &cam, &o, setup_box, NULL, &f, msg, sizeof msg), 0, "%s", msg);
        int dmax = 0;
        for (size_t i = 0; i < (size_t)W * H * 3; i++) {
            int want = (int)lround(255.0 * srgb(f.linear[i] * pow(2.0, exposures[e])));
            int dd = abs(want - (int)f.display[i]);
            if (dd > dmax) dmax = dd;
        }
        printf("metric: tone mapping at exposure %+.1f vs CPU sRGB: max %d/255\n", exposures[e], dmax);
        cr_expect_leq(dmax, 1);
        fx_frame_free(&f);
    }
}

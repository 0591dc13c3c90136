/* Golden images of the radiosity pass: the box mesh drawn by OSMesa and by
 * EGL agrees with a software Gouraud rasterisation at pixel centres, and the
 * two backends agree with each other. */
#include <criterion/criterion.h>
#include <stdio.h>
#include <stdlib.h>

#include "tests/support/disp_fixture.h"

#define W 96
#define H 72
/* Tolerance against the software rasteriser (linear radiance, values in
 * 0.05..0.95): float interpolation differences only. */
#define TOL_REF 2e-3
/* Between the two headless backends. */
#define TOL_BACKENDS 1e-4

static int setup_box(disp_session *s, void *ctx, ct_error *err)
{
    (void)ctx;
    ct_radmesh m;
    int rc = fx_box_mesh(4, &m, NULL, err);
    if (rc) return rc;
    rc = disp_session_scene(s, &m, err);
    rmesh_free(&m);
    return rc;
}

static void compare_ref(const fx_frame *f, const fx_ref *ref, const char *name)
{
    size_t used = 0, bg = 0;
    double mx = 0, sum = 0;
    for (size_t p = 0; p < (size_t)W * H; p++) {
        if (!ref->smooth[p]) continue;
        if (ref->node[p] < 0) {
            bg++;
            for (int k = 0; k < 3; k++) cr_expect_eq(f->linear[3 * p + (size_t)k], 0.0f, "%s background pixel %zu", name, p);
            continue;
        }
        used++;
        for (int k = 0; k < 3; k++) {
            double d = fabs((double)f->linear[3 * p + (size_t)k] - ref->rgb[3 * p + (size_t)k]);
            sum += d;
            if (d > mx) mx = d;
        }
    }
    printf("metric: %s vs software Gouraud: max |diff| %.2e, mean %.2e over %zu interior pixels "
           "(+%zu background), tolerance %.0e\n", name, mx, used ? sum / (3.0 * (double)used) : 0.0,
           used, bg, TOL_REF);
    cr_expect_gt(used, (size_t)W * H / 2, "%s: only %zu pixels comparable", name, used);
    cr_expect_leq(mx, TOL_REF, "%s: max error %.3e over tolerance", name, mx);
}

Test(disp_golden, backends_match_software_gouraud)
{
    ct_radmesh m;
    ct_error err;
    cr_assert_eq(fx_box_mesh(4, &m, NULL, &err), 0, "%s", err.msg);
    ct_camera cam = fx_box_camera();
    fx_ref ref;
    cr_assert_eq(fx_rasterise(&m, &cam, W, H, &ref), 0);
    disp_render_opts o = {3, DISP_VIEW_RADIOSITY, 0.0f, false};
    fx_frame osm, egl;
    char msg[256];
    cr_assert_eq(fx_render(GL_BACKEND_OSMESA, W, H, &cam, &o, setup_box, NULL, &osm, msg, sizeof msg), 0,
                 "osmesa: %s", msg);
    cr_assert_eq(fx_render(GL_BACKEND_EGL, W, H, &cam, &o, setup_box, NULL, &egl, msg, sizeof msg), 0,
                 "egl: %s", msg);
    compare_ref(&osm, &ref, "osmesa");
    compare_ref(&egl, &ref, "egl");
    double mx, mean;
    fx_diff(osm.linear, egl.linear, (size_t)W * H * 3, &mx, &mean);
    printf("metric: osmesa vs egl: max |diff| %.2e, mean %.2e over all pixels, tolerance %.0e\n", mx,
           mean, TOL_BACKENDS);
    cr_expect_leq(mx, TOL_BACKENDS);
    int dmax = 0;
    for (size_t i = 0; i < (size_t)W * H * 3; i++) {
        int d = abs((int)osm.display[i] - (int)egl.display[i]);
        if (d > dmax) dmax = d;
    }
    cr_expect_leq(dmax, 1, "tone-mapped images differ by %d/255", dmax);
    fx_frame_free(&osm);
    fx_frame_free(&egl);
    fx_ref_free(&ref);
    rmesh_free(&m);
}

Test(disp_golden, rejects_bad_mesh)
{
    /* A triangle naming a vertex that does not exist must fail cleanly. */
    ct_radmesh m;
    ct_error err;
    cr_assert_eq(fx_box_mesh(1, &m, NULL, &err), 0, "%s", err.msg);
    m.tris[5] = m.nverts + 7;
    gl_backend *b = NULL;
    cr_assert_eq(gl_backend_open(GL_BACKEND_OSMESA, 16, 16, NULL, false, &b, &err), 0, "%s", err.msg);
    disp_session *s = NULL;
    cr_assert_eq(disp_session_new(&s, &err), 0);
    cr_expect_eq(disp_session_scene(s, &m, &err), CT_ERANGE);
    cr_expect(strstr(err.msg, "vertex") != NULL, "message: %s", err.msg);
    m.tris[5] = 0;
    m.tri_node[0] = m.nnodes;
    cr_expect_eq(disp_session_scene(s, &m, &err), CT_ERANGE);
    cr_expect_eq(disp_session_tex_alloc(s, 1, 0, 4, 4, DISP_PROJ_OBJECT_PARALLEL, &err), CT_EPROTO);
    disp_session_free(s);
    gl_backend_close(b);
    rmesh_free(&m);
}

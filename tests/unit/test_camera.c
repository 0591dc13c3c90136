/* Unit tests of common/camera: rays and projections agree with each other
 * and with the GL matrices (pixel origin top-left, y down). */
#include <criterion/criterion.h>

#include <float.h>
#include <math.h>
#include <string.h>

#include "common/camera.h"
#include "common/rng.h"
#include "tests/support/fixtures.h"

typedef struct cam_case {
    ct_camera cam;
    int w, h;
} cam_case;

/* Random cameras: positions, directions, fields of view 20..110 degrees,
 * square, wide and tall images. */
static cam_case rand_case(ct_rng *r, int k)
{
    static const int sizes[][2] = {{64, 64}, {128, 72}, {33, 97}, {1024, 768}};
    cam_case c;
    vec3 eye = v3_scale(fx_rand_unit(r), 20.0f * rng_float(r));
    vec3 dir = fx_rand_unit(r);
    vec3 up = fabsf(dir.y) > 0.95f ? v3(1, 0, 0) : v3(0, 1, 0);
    c.cam = cam_look_at(eye, v3_add(eye, v3_scale(dir, 3.0f)), up, 20.0f + 90.0f * rng_float(r));
    c.w = sizes[k % 4][0];
    c.h = sizes[k % 4][1];
    return c;
}

Test(camera, look_at_axes)
{
    ct_camera c = cam_look_at(v3(0, 1, 5), v3(0, 1, 0), v3(0, 1, 0), 60.0f);
    vec3 r, u, f;
    cam_axes(&c, &r, &u, &f);
    cr_assert_float_eq(f.z, -1.0f, 1e-6, "forward towards the target");
    cr_assert_float_eq(u.y, 1.0f, 1e-6);
    cr_assert_float_eq(r.x, 1.0f, 1e-6, "right = forward x up");
    cr_assert_float_eq(c.fov_y, 60.0f * CT_PI / 180.0f, 1e-6);
    /* Looking straight along the up vector still yields an orthonormal frame. */
    ct_camera d = cam_look_at(v3(0, 0, 0), v3(0, 5, 0), v3(0, 1, 0), 45.0f);
    cam_axes(&d, &r, &u, &f);
    cr_assert(v3_finite(r) && v3_finite(u) && v3_finite(f));
    cr_assert_float_eq(f.y, 1.0f, 1e-6);
    cr_assert_float_eq(v3_dot(r, f), 0.0f, 1e-6);
    cr_assert_float_eq(v3_dot(u, f), 0.0f, 1e-6);
}

Test(camera, centre_and_edge_rays)
{
    ct_camera c = cam_look_at(v3(1, 2, 3), v3(4, 2, -1), v3(0, 1, 0), 50.0f);
    vec3 r, u, f;
    cam_axes(&c, &r, &u, &f);
    vec3 d = cam_ray_dir(&c, 200, 100, 100.0f, 50.0f);
    cr_assert_float_eq(v3_dot(d, f), 1.0f, 1e-6, "centre ray is the view direction");
    /* The top edge's centre is fov/2 above the axis, towards +up. */
    vec3 t = cam_ray_dir(&c, 200, 100, 100.0f, 0.0f);
    cr_assert_float_eq(acosf(v3_dot(t, f)), 25.0f * CT_PI / 180.0f, 1e-5);
    cr_assert_gt(v3_dot(t, u), 0.0f);
    /* Pixel columns grow to the right. */
    cr_assert_gt(v3_dot(cam_ray_dir(&c, 200, 100, 199.5f, 50.0f), r), 0.0f);
    cr_assert_float_eq(v3_len(cam_ray_dir(&c, 200, 100, 3.5f, 91.25f)), 1.0f, 1e-6);
}

Test(camera, project_inverts_ray_dir)
{
    ct_rng r = rng_make(21, 0, 0, 0);
    for (int k = 0; k < 400; k++) {
        cam_case cc = rand_case(&r, k);
        float px = (float)cc.w * rng_float(&r), py = (float)cc.h * rng_float(&r);
        float dist = 0.05f + 50.0f * rng_float(&r);
        vec3 p = v3_madd(cc.cam.eye, cam_ray_dir(&cc.cam, cc.w, cc.h, px, py), dist);
        float qx, qy, depth;
        cr_assert(cam_project(&cc.cam, cc.w, cc.h, p, &qx, &qy, &depth));
        cr_assert_float_eq(qx, px, 1e-3, "case %d: x %g -> %g", k, (double)px, (double)qx);
        cr_assert_float_eq(qy, py, 1e-3, "case %d: y %g -> %g", k, (double)py, (double)qy);
        cr_assert_gt(depth, 0.0f);
        cr_assert_leq(depth, dist * 1.0001f);
    }
}

Test(camera, project_rejects_points_behind)
{
    ct_camera c = cam_look_at(v3(0, 0, 0), v3(0, 0, -1), v3(0, 1, 0), 60.0f);
    float x, y, depth;
    cr_assert(!cam_project(&c, 64, 64, v3(0.2f, 0.1f, 1.0f), &x, &y, &depth));
    cr_assert_lt(depth, 0.0f);
    cr_assert(!cam_project(&c, 64, 64, v3(1.0f, 0.0f, 0.0f), &x, &y, &depth), "depth 0");
    cr_assert(cam_project(&c, 64, 64, v3(0, 0, -2), &x, &y, NULL));
    cr_assert_float_eq(x, 32.0f, 1e-5);
    cr_assert_float_eq(y, 32.0f, 1e-5);
}

Test(camera, gl_matrices_match_project)
{
    /* clip = P V p; ndc = clip / w; pixel x = (ndc.x + 1) / 2 W, pixel y =
     * (1 - ndc.y) / 2 H (GL's y is up, ours is down). */
    ct_rng r = rng_make(22, 0, 0, 0);
    const float znear = 0.01f, zfar = 100.0f;
    int tested = 0;
    for (int k = 0; k < 400; k++) {
        cam_case cc = rand_case(&r, k);
        mat4 pv = m4_mul(cam_proj(&cc.cam, cc.w, cc.h, znear, zfar), cam_view(&cc.cam));
        /* Points in and somewhat outside the frustum, in front of the eye. */
        float px = (float)cc.w * (1.4f * rng_float(&r) - 0.2f);
        float py = (float)cc.h * (1.4f * rng_float(&r) - 0.2f);
        float dist = 0.1f + 30.0f * rng_float(&r);
        vec3 p = v3_madd(cc.cam.eye, cam_ray_dir(&cc.cam, cc.w, cc.h, px, py), dist);
        float qx, qy, depth;
        if (!cam_project(&cc.cam, cc.w, cc.h, p, &qx, &qy, &depth)) continue;
        vec4 clip = m4_point4(&pv, p);
        cr_assert_gt(clip.w, 0.0f);
        float gx = 0.5f * (clip.x / clip.w + 1.0f) * (float)cc.w;
        float gy = 0.5f * (1.0f - clip.y / clip.w) * (float)cc.h;
        /* Float view matrices carry -dot(axis, eye) in their translation,
         * rounded to a few ulps of |eye|: an eye-space error of about
         * |eye| * FLT_EPSILON, which the projection scales by focal / depth
         * pixels (on the GPU too). Four such ulps, plus the rounding of the
         * pixel coordinate itself. */
        double focal = 0.5 * cc.h / tan(0.5 * (double)cc.cam.fov_y);
        double tol = 1e-3 + 4.0 * (double)v3_len(cc.cam.eye) * FLT_EPSILON * focal / (double)depth;
        cr_assert_float_eq(gx, qx, tol, "case %d: GL x %.9g vs project %.9g (depth %g, eye %g from the origin)", k,
                           (double)gx, (double)qx, (double)depth, (double)v3_len(cc.cam.eye));
        cr_assert_float_eq(gy, qy, tol, "case %d: GL y %.9g vs project %.9g (depth %g, eye %g from the origin)", k,
                           (double)gy, (double)qy, (double)depth, (double)v3_len(cc.cam.eye));
        /* Eye-space depth is GL's w. */
        cr_assert_float_eq(clip.w, depth, 1e-4 * (1 + depth), "case %d: GL w %.9g vs depth %.9g", k, (double)clip.w,
                           (double)depth);
        float nz = clip.z / clip.w;
        cr_assert(nz > -1.0f && nz < 1.0f, "ndc z %g inside the depth range", (double)nz);
        tested++;
    }
    cr_assert_gt(tested, 300);
}

Test(camera, lerp_endpoints)
{
    ct_camera a = cam_look_at(v3(0, 0, 0), v3(0, 0, -1), v3(0, 1, 0), 40.0f);
    ct_camera b = cam_look_at(v3(2, 4, 6), v3(3, 4, 6), v3(0, 1, 0), 80.0f);
    ct_camera m0 = cam_lerp(&a, &b, 0.0f), m1 = cam_lerp(&a, &b, 1.0f), mh = cam_lerp(&a, &b, 0.5f);
    cr_assert_eq(m0.eye.y, 0.0f);
    cr_assert_float_eq(m1.eye.z, 6.0f, 1e-6);
    cr_assert_float_eq(mh.fov_y, 60.0f * CT_PI / 180.0f, 1e-6);
    vec3 f0, f1, fh;
    cam_axes(&m0, NULL, NULL, &f0);
    cam_axes(&m1, NULL, NULL, &f1);
    cam_axes(&mh, NULL, NULL, &fh);
    cr_assert_float_eq(f0.z, -1.0f, 1e-6);
    cr_assert_float_eq(f1.x, 1.0f, 1e-6);
    /* Half way between -z and +x about the up axis. */
    cr_assert_float_eq(fh.x, sqrtf(0.5f), 1e-5);
    cr_assert_float_eq(fh.z, -sqrtf(0.5f), 1e-5);
}

/* The field of view's range: a CAMERA of 1e-33 radians was taken and made
 * the master's texture matrices infinite (every later display was dropped),
 * and a scene camera of 179.9999 degrees passed its loader but not the
 * wire. Every field of view a scene or path may give is one cam_valid takes. */
Test(camera, fov_range)
{
    ct_camera c = cam_look_at(v3(0, 0, 0), v3(0, 0, -1), v3(0, 1, 0), 40.0f);
    const float bad[] = {0.0f, 1e-33f, CT_FOV_MIN * 0.5f, CT_FOV_MAX, CT_PI, NAN};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        c.fov_y = bad[i];
        char why[96] = "";
        cr_expect_not(cam_valid(&c, why, sizeof why), "fov %g taken", (double)bad[i]);
        if (isfinite(bad[i])) cr_expect(strstr(why, "field of view") != NULL, "%s", why);
    }
    c.fov_y = CT_FOV_MIN;
    cr_expect(cam_valid(&c, NULL, 0));
    const float deg[] = {CT_FOV_DEG_MIN, 1.0f, 90.0f, CT_FOV_DEG_MAX};
    for (size_t i = 0; i < sizeof deg / sizeof deg[0]; i++) {
        cr_expect(cam_fov_deg_valid(deg[i]));
        ct_camera d = cam_look_at(v3(0, 0, 0), v3(0, 0, -1), v3(0, 1, 0), deg[i]);
        cr_expect(cam_valid(&d, NULL, 0), "a %g degree camera is refused on the wire", (double)deg[i]);
    }
    cr_expect_not(cam_fov_deg_valid(179.9999f));
    cr_expect_not(cam_fov_deg_valid(1e-30f));
    cr_expect_not(cam_fov_deg_valid(NAN));
}

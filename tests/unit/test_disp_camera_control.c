/* The fly camera: keys move along the view axes at the set speed (Shift 4x),
 * mouse motion turns about the start camera's up vector and pitches without
 * rolling, scrolling scales the speed; the overview camera sees the bounds. */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>

#include "display/disp_camera_control.h"

static gl_input none(void)
{
    gl_input in;
    memset(&in, 0, sizeof in);
    return in;
}

static void expect_vec(vec3 a, vec3 b, float tol, const char *what)
{
    cr_expect(fabsf(a.x - b.x) <= tol && fabsf(a.y - b.y) <= tol && fabsf(a.z - b.z) <= tol,
              "%s: (%g %g %g) vs (%g %g %g)", what, a.x, a.y, a.z, b.x, b.y, b.z);
}

Test(disp_camera_control, keys_move_along_the_view_axes)
{
    ct_camera c = cam_look_at(v3(0, 1, 5), v3(0, 1, 0), v3(0, 1, 0), 50);
    bounds3 b = {v3(-2, -2, -2), v3(2, 2, 2)};
    disp_fly f;
    disp_fly_init(&f, &c, b);
    cr_expect_float_eq(f.speed, 0.25f * v3_len(v3(4, 4, 4)), 1e-5f);
    f.speed = 2.0f;
    gl_input in = none();
    cr_expect_not(disp_fly_update(&f, &in, 0.5), "no input, no change");
    in.down['W'] = true;
    cr_expect(disp_fly_update(&f, &in, 0.5));
    expect_vec(f.cam.eye, v3(0, 1, 4), 1e-5f, "forward 1 unit");
    in.down['W'] = false;
    in.down[GL_KEY_RIGHT] = true;
    in.down[GL_KEY_SHIFT] = true;
    disp_fly_update(&f, &in, 0.25);
    expect_vec(f.cam.eye, v3(2, 1, 4), 1e-5f, "right 4x speed");
    in = none();
    in.down['E'] = true;
    disp_fly_update(&f, &in, 0.5);
    expect_vec(f.cam.eye, v3(2, 2, 4), 1e-5f, "up along the world up");
    in = none();
    in.scroll = 2;
    disp_fly_update(&f, &in, 0.1);
    cr_expect_float_eq(f.speed, 2.0f * 1.5625f, 1e-5f);
}

/* A hundred clicks of the wheel and a key held took the eye past the range a
 * CAMERA carries (the display's own encoder ended the connection); 1,200 the
 * other way left a speed of 0 that no scrolling brought back. */
Test(disp_camera_control, speed_and_eye_stay_within_bounds)
{
    ct_camera c = cam_look_at(v3(0, 1, 5), v3(0, 1, 0), v3(0, 1, 0), 50);
    bounds3 b = {v3(-2, -2, -2), v3(2, 2, 2)};
    float diag = v3_len(v3(4, 4, 4));
    disp_fly f;
    disp_fly_init(&f, &c, b);
    gl_input in = none();
    in.scroll = 1200;
    disp_fly_update(&f, &in, 0.01);
    cr_expect_float_eq(f.speed, 100.0f * diag, 1e-3f, "speed %g", (double)f.speed);
    in = none();
    in.down['W'] = true;
    for (int i = 0; i < 100000 && fabsf(f.cam.eye.z) < CT_COORD_MAX; i++) disp_fly_update(&f, &in, 1e4);
    cr_expect(v3_in_range(f.cam.eye), "eye (%g %g %g) out of range", (double)f.cam.eye.x, (double)f.cam.eye.y,
              (double)f.cam.eye.z);
    cr_expect_eq(f.cam.eye.z, -CT_COORD_MAX, "the eye stops at the range's edge (%g)", (double)f.cam.eye.z);
    in = none();
    in.scroll = -1e6;
    disp_fly_update(&f, &in, 0.01);
    cr_expect_float_eq(f.speed, 1e-6f * diag, 1e-9f, "speed %g", (double)f.speed);
    in.scroll = 2;
    disp_fly_update(&f, &in, 0.01);
    cr_expect_gt(f.speed, 1e-6f * diag, "scrolling up brings the speed back");
}

Test(disp_camera_control, mouse_turns_without_roll)
{
    ct_camera c = cam_look_at(v3(0, 0, 0), v3(0, 0, -1), v3(0, 1, 0), 50);
    bounds3 b = {v3(-1, -1, -1), v3(1, 1, 1)};
    disp_fly f;
    disp_fly_init(&f, &c, b);
    gl_input in = none();
    /* 90 degrees of yaw to the right: forward becomes +x. */
    in.mouse_dx = (CT_PI / 2) / f.look;
    cr_expect(disp_fly_update(&f, &in, 0.01));
    vec3 r, u, fw;
    cam_axes(&f.cam, &r, &u, &fw);
    expect_vec(fw, v3(1, 0, 0), 1e-4f, "yaw right");
    expect_vec(u, v3(0, 1, 0), 1e-4f, "no roll");
    /* Pitch up 30 degrees, then far past the zenith: clamped at 85 degrees. */
    in = none();
    in.mouse_dy = -(CT_PI / 6) / f.look;
    disp_fly_update(&f, &in, 0.01);
    cam_axes(&f.cam, &r, &u, &fw);
    cr_expect_float_eq(fw.y, sinf(CT_PI / 6), 1e-4f);
    cr_expect_float_eq(r.y, 0.0f, 1e-4f, "the right axis stays level");
    in.mouse_dy = -(CT_PI) / f.look;
    disp_fly_update(&f, &in, 0.01);
    cam_axes(&f.cam, &r, &u, &fw);
    cr_expect_float_eq(fw.y, sinf(85.0f * CT_PI / 180.0f), 1e-4f, "pitch stops at 85 degrees");
    cr_expect_gt(u.y, 0.0f, "not upside down");
}

Test(disp_camera_control, overview_sees_the_bounds)
{
    bounds3 b = {v3(-3, 0, -1), v3(5, 2, 4)};
    ct_camera c = disp_camera_overview(b, 50);
    for (int i = 0; i < 8; i++) {
        float px, py, depth;
        cr_expect(cam_project(&c, 100, 100, b3_corner(b, i), &px, &py, &depth));
        cr_expect(px >= 0 && px <= 100 && py >= 0 && py <= 100, "corner %d at (%g, %g)", i, px, py);
    }
}

/* A scene at the coordinate range's edge: the overview's eye stays within
 * it (it was placed 2.4 half-diagonals out, past 1e9, and the display's own
 * encoder refused its first CAMERA). */
Test(disp_camera_control, overview_of_a_huge_scene_stays_in_range)
{
    bounds3 b = {v3(-1e9f, -1e9f, -1e9f), v3(1e9f, 1e9f, 1e9f)};
    ct_camera c = disp_camera_overview(b, 50);
    cr_expect(v3_in_range(c.eye), "eye (%g, %g, %g)", c.eye.x, c.eye.y, c.eye.z);
    cr_expect(isfinite(c.fov_y) && c.fov_y > 0);
    float px, py, depth;
    cr_expect(cam_project(&c, 100, 100, v3(0, 0, 0), &px, &py, &depth), "the centre is not in view");
}

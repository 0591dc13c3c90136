#include "display/disp_camera_control.h"

#include <math.h>

void disp_fly_init(disp_fly *f, const ct_camera *cam, bounds3 scene)
{
    f->cam = *cam;
    cam_axes(cam, NULL, &f->world_up, NULL);
    float diag = b3_is_empty(scene) ? 1.0f : v3_len(b3_extent(scene));
    if (!(diag > 0 && isfinite(diag))) diag = 1.0f;
    f->speed = 0.25f * diag;
    /* Unbounded, a hundred clicks of the wheel sent the eye past the range
     * a CAMERA may carry in a second (the connection ended), and 1,200
     * the other way left a speed of exactly 0 that no scrolling restored. */
    f->speed_min = 1e-6f * diag;
    f->speed_max = 100.0f * diag;
    f->look = 0.004f;
}

bool disp_fly_update(disp_fly *f, const gl_input *in, double dt)
{
    bool changed = false;
    if (in->scroll != 0.0) {
        float sp = f->speed * powf(1.25f, (float)fmax(-200.0, fmin(200.0, in->scroll)));
        f->speed = fmaxf(f->speed_min, fminf(f->speed_max, sp));
    }
    vec3 r, u, fw;
    cam_axes(&f->cam, &r, &u, &fw);
    vec3 move = v3s(0);
    if (in->down['W'] || in->down[GL_KEY_UP]) move = v3_add(move, fw);
    if (in->down['S'] || in->down[GL_KEY_DOWN]) move = v3_sub(move, fw);
    if (in->down['D'] || in->down[GL_KEY_RIGHT]) move = v3_add(move, r);
    if (in->down['A'] || in->down[GL_KEY_LEFT]) move = v3_sub(move, r);
    if (in->down['E'] || in->down[GL_KEY_PAGE_UP]) move = v3_add(move, f->world_up);
    if (in->down['Q'] || in->down[GL_KEY_PAGE_DOWN]) move = v3_sub(move, f->world_up);
    if (!v3_is_zero(move)) {
        float step = f->speed * (float)dt * (in->down[GL_KEY_SHIFT] ? 4.0f : 1.0f);
        f->cam.eye = v3_clamp_range(v3_add(f->cam.eye, v3_scale(v3_norm(move), step)));
        changed = true;
    }
    if (in->mouse_dx != 0.0 || in->mouse_dy != 0.0) {
        /* Pitch is clamped to +-85 degrees about the horizon, so the camera
         * never flips over; yaw turns about the world up. */
        float pitch = asinf(fmaxf(-1.0f, fminf(1.0f, v3_dot(fw, f->world_up))));
        float lim = 85.0f * CT_PI / 180.0f;
        float want = fmaxf(-lim, fminf(lim, pitch - (float)in->mouse_dy * f->look));
        quat yaw = q_axis_angle(f->world_up, -(float)in->mouse_dx * f->look);
        quat tilt = q_axis_angle(v3(1, 0, 0), want - pitch);
        f->cam.orient = q_normalize(q_mul(yaw, q_mul(f->cam.orient, tilt)));
        changed = true;
    }
    return changed;
}

ct_camera disp_camera_overview(bounds3 b, float fov_deg)
{
    vec3 c = b3_center(b);
    float r = 0.5f * v3_len(b3_extent(b));
    if (!(r > 0)) r = 1.0f;
    float d = r / sinf(0.5f * fov_deg * CT_PI / 180.0f);
    /* Within the coordinate range: a scene spanning more than about 5e8
     * put the eye past it, and the display's first CAMERA was refused by
     * its own encoder (the connection ended). It then sees less than the
     * whole, but sees it. */
    vec3 eye = v3_clamp_range(v3_add(c, v3(0.0f, 0.15f * r, d)));
    return cam_look_at(eye, c, v3(0, 1, 0), fov_deg);
}

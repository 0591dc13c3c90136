#include "common/camera.h"

#include <stdio.h>

bool cam_fov_valid(float fov_y)
{
    return fov_y >= CT_FOV_MIN && fov_y < CT_FOV_MAX;
}

bool cam_fov_deg_valid(float fov_deg)
{
    return fov_deg >= CT_FOV_DEG_MIN && fov_deg <= CT_FOV_DEG_MAX;
}

ct_camera cam_look_at(vec3 eye, vec3 target, vec3 up, float fov_y_deg)
{
    vec3 f = v3_norm(v3_sub(target, eye));
    vec3 r = v3_cross(f, up);
    if (v3_len2(r) < 1e-12f) {
        /* Looking along up: any perpendicular right vector will do. */
        vec3 t, b;
        v3_basis(f, &t, &b);
        r = t;
    }
    r = v3_norm(r);
    vec3 u = v3_cross(r, f);
    ct_camera c;
    c.eye = eye;
    c.orient = q_from_basis(r, u, v3_neg(f));
    c.fov_y = fov_y_deg * CT_PI / 180.0f;
    return c;
}

bool cam_valid(const ct_camera *c, char *why, size_t cap)
{
    const quat q = c->orient;
    char buf[96];
    if (!why) {
        why = buf;
        cap = sizeof buf;
    }
    if (!v3_finite(c->eye) || !isfinite(q.w) || !isfinite(q.x) || !isfinite(q.y) || !isfinite(q.z) ||
        !isfinite(c->fov_y)) {
        snprintf(why, cap, "has a non-finite value");
        return false;
    }
    if (!cam_fov_valid(c->fov_y)) {
        snprintf(why, cap, "field of view %g out of range [%g, %g) radians", (double)c->fov_y, (double)CT_FOV_MIN,
                 (double)CT_FOV_MAX);
        return false;
    }
    if (!v3_in_range(c->eye)) {
        float e = fabsf(c->eye.x) > CT_COORD_MAX ? c->eye.x : fabsf(c->eye.y) > CT_COORD_MAX ? c->eye.y : c->eye.z;
        snprintf(why, cap, "eye coordinate %g outside +-%g", (double)e, (double)CT_COORD_MAX);
        return false;
    }
    if (!(fabsf(q_dot(q, q) - 1.0f) <= 1e-3f)) {
        snprintf(why, cap, "orientation is not a unit quaternion (norm^2 %g)", (double)q_dot(q, q));
        return false;
    }
    return true;
}

void cam_axes(const ct_camera *c, vec3 *right, vec3 *up, vec3 *forward)
{
    if (right) *right = q_rotate(c->orient, v3(1, 0, 0));
    if (up) *up = q_rotate(c->orient, v3(0, 1, 0));
    if (forward) *forward = q_rotate(c->orient, v3(0, 0, -1));
}

mat4 cam_view(const ct_camera *c)
{
    vec3 r, u, f;
    cam_axes(c, &r, &u, &f);
    mat4 m = m4_identity();
    m.m[0][0] = r.x;  m.m[0][1] = r.y;  m.m[0][2] = r.z;  m.m[0][3] = -v3_dot(r, c->eye);
    m.m[1][0] = u.x;  m.m[1][1] = u.y;  m.m[1][2] = u.z;  m.m[1][3] = -v3_dot(u, c->eye);
    m.m[2][0] = -f.x; m.m[2][1] = -f.y; m.m[2][2] = -f.z; m.m[2][3] = v3_dot(f, c->eye);
    return m;
}

mat4 cam_proj(const ct_camera *c, int width, int height, float znear, float zfar)
{
    return m4_perspective(c->fov_y, (float)width / (float)height, znear, zfar);
}

void cam_rays_init(cam_rays *p, const ct_camera *c, int width, int height)
{
    p->th = tanf(0.5f * c->fov_y);
    p->tw = p->th * (float)width / (float)height;
    p->w = (float)width;
    p->h = (float)height;
    cam_axes(c, &p->r, &p->u, &p->f);
}

vec3 cam_ray_dir(const ct_camera *c, int width, int height, float px, float py)
{
    cam_rays p;
    cam_rays_init(&p, c, width, height);
    return cam_rays_dir(&p, px, py);
}

bool cam_project(const ct_camera *c, int width, int height, vec3 p, float *px, float *py,
                 float *depth)
{
    vec3 r, u, f;
    cam_axes(c, &r, &u, &f);
    vec3 d = v3_sub(p, c->eye);
    float z = v3_dot(d, f);
    if (depth) *depth = z;
    if (z <= 0.0f) return false;
    float th = tanf(0.5f * c->fov_y);
    float tw = th * (float)width / (float)height;
    float sx = v3_dot(d, r) / (z * tw);
    float sy = v3_dot(d, u) / (z * th);
    if (px) *px = 0.5f * (sx + 1.0f) * (float)width;
    if (py) *py = 0.5f * (1.0f - sy) * (float)height;
    return true;
}

ct_camera cam_lerp(const ct_camera *a, const ct_camera *b, float t)
{
    ct_camera c;
    c.eye = v3_lerp(a->eye, b->eye, t);
    c.orient = q_slerp(a->orient, b->orient, t);
    c.fov_y = a->fov_y + (b->fov_y - a->fov_y) * t;
    return c;
}

bool cam_same(const ct_camera *a, const ct_camera *b)
{
    return a->eye.x == b->eye.x && a->eye.y == b->eye.y && a->eye.z == b->eye.z && a->orient.w == b->orient.w &&
           a->orient.x == b->orient.x && a->orient.y == b->orient.y && a->orient.z == b->orient.z &&
           a->fov_y == b->fov_y;
}

/* camera.h: the pinhole camera shared by tracer, master and display, and the
 * mapping between image positions and rays. Image positions are in pixels,
 * origin at the top-left corner, pixel (i, j) covering [i, i+1) x [j, j+1), so
 * its centre is (i + 0.5, j + 0.5). The GL projection built from the same
 * camera (cam_proj) maps every point to exactly that position. */
#ifndef CT_CAMERA_H
#define CT_CAMERA_H

#include <stdbool.h>
#include <stddef.h>

#include "common/vecmath.h"

typedef struct ct_camera {
    vec3 eye;
    quat orient;   /* camera frame -> world: +x right, +y up, -z forward */
    float fov_y;   /* vertical field of view, radians */
} ct_camera;

/* The vertical field of view a camera may have, radians: [CT_FOV_MIN,
 * CT_FOV_MAX). Below CT_FOV_MIN the master's texture projections, whose
 * focal length is 1 / tan(fov / 2) pixels times world coordinates, left
 * single precision (a CAMERA of 1e-33 radians gave texture matrices of
 * infinities, and every display after it was dropped); at CT_FOV_MIN they
 * stay some 10^13 below FLT_MAX for any image and eye the wire allows.
 * Above CT_FOV_MAX tan(fov / 2) is no longer finite in single precision. */
#define CT_FOV_MIN 1e-4f
#define CT_FOV_MAX 3.14159f

/* Scene cameras and camera path keys give the field of view in degrees:
 * [CT_FOV_DEG_MIN, CT_FOV_DEG_MAX], inside the radians above, so every camera
 * of a scene or path is one the wires carry (a scene camera of 179.9999
 * degrees made the master's first CAMERA unsendable: no display could
 * connect). */
#define CT_FOV_DEG_MIN 0.01f
/* The near plane as a share of the scene's depth, wherever a view is drawn
 * with depth compared in relative precision (reversed float depth in the
 * display, 1/z in the master's item buffer): the display and the master
 * must clip alike, or the master takes what the display shows near the eye
 * for another object (docs/display.md, docs/sampling.md). */
#define CT_NEAR_SHARE 1e-7f
#define CT_FOV_DEG_MAX 179.99f

/* Whether fov_y (radians) is in [CT_FOV_MIN, CT_FOV_MAX) (false for NaN). */
bool cam_fov_valid(float fov_y);

/* Whether fov_deg (degrees) is in [CT_FOV_DEG_MIN, CT_FOV_DEG_MAX]. */
bool cam_fov_deg_valid(float fov_deg);

/* A camera at eye looking at target with the given up vector and vertical
 * field of view in degrees. */
ct_camera cam_look_at(vec3 eye, vec3 target, vec3 up, float fov_y_deg);

/* Whether a and b are the same camera, value for value (NaNs never are).
 * A drawn or sampled view is reused only for the very same camera. */
bool cam_same(const ct_camera *a, const ct_camera *b);

/* Whether c can be traced: every value finite, a field of view in
 * [CT_FOV_MIN, CT_FOV_MAX),
 * the eye within +-CT_COORD_MAX and a unit orientation (within 1e-3; a zero
 * or huge quaternion makes the rays NaN or infinite). When not, why gets
 * the problem ("eye coordinate -1e+19 outside +-1e+09"; may be NULL). */
bool cam_valid(const ct_camera *c, char *why, size_t cap);

/* World-space unit axes of the camera. */
void cam_axes(const ct_camera *c, vec3 *right, vec3 *up, vec3 *forward);

/* World -> eye matrix (GL convention: camera looks down -z). */
mat4 cam_view(const ct_camera *c);

/* Eye -> clip matrix for a width:height image (GL convention). */
mat4 cam_proj(const ct_camera *c, int width, int height, float znear, float zfar);

/* Unit world direction of the primary ray through image position (px, py). */
vec3 cam_ray_dir(const ct_camera *c, int width, int height, float px, float py);

/* A camera's axes and tangents for a width x height image, computed once
 * (cam_rays_init) for many rays: cam_rays_dir does cam_ray_dir's arithmetic
 * (the same results, bit for bit) without its tangent and axes per ray,
 * which were most of a ray's cost where the master maps pixels to texels. */
typedef struct cam_rays {
    vec3 r, u, f;
    float th, tw;
    float w, h;
} cam_rays;

void cam_rays_init(cam_rays *p, const ct_camera *c, int width, int height);

static inline vec3 cam_rays_dir(const cam_rays *p, float px, float py)
{
    float sx = (2.0f * px / p->w - 1.0f) * p->tw;
    float sy = (1.0f - 2.0f * py / p->h) * p->th;
    return v3_norm(v3_add(p->f, v3_add(v3_scale(p->r, sx), v3_scale(p->u, sy))));
}

/* Projects world point p to image position (px, py) and its eye-space depth
 * along the view direction; false when p is behind the eye (depth <= 0). */
bool cam_project(const ct_camera *c, int width, int height, vec3 p, float *px, float *py,
                 float *depth);

/* Interpolates two cameras: position linearly, orientation by slerp, fov linearly. */
ct_camera cam_lerp(const ct_camera *a, const ct_camera *b, float t);

#endif

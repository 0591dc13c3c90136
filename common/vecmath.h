/* vecmath.h: small linear algebra for corrtex: vec3 (float), mat4 (row-major,
 * column vectors: p' = M p, as GL's uniform upload with transpose=GL_TRUE),
 * quaternions for camera orientation, axis-aligned bounds. Hot functions are
 * static inline; the rest lives in vecmath.c. */
#ifndef CT_VECMATH_H
#define CT_VECMATH_H

#include <math.h>
#include <stdbool.h>

#define CT_PI 3.14159265358979323846f

/* Largest magnitude of any coordinate that can reach a ray: scene vertices,
 * lights, cameras, camera paths, CAMERA messages (docs/scene-format.md).
 * Embree asserts (and the job dies) on ray origins beyond about 1.8e18;
 * 1e9 also keeps products of four coordinates, such as a triangle's squared
 * cross product, finite in float. */
#define CT_COORD_MAX 1e9f

typedef struct vec3 { float x, y, z; } vec3;
typedef struct vec4 { float x, y, z, w; } vec4;
typedef struct mat4 { float m[4][4]; } mat4;   /* m[row][col] */
typedef struct quat { float w, x, y, z; } quat;
typedef struct bounds3 { vec3 lo, hi; } bounds3;

static inline vec3 v3(float x, float y, float z) { vec3 r = {x, y, z}; return r; }
static inline vec3 v3s(float s) { return v3(s, s, s); }
static inline vec3 v3_add(vec3 a, vec3 b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline vec3 v3_sub(vec3 a, vec3 b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline vec3 v3_mul(vec3 a, vec3 b) { return v3(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline vec3 v3_scale(vec3 a, float s) { return v3(a.x * s, a.y * s, a.z * s); }
static inline vec3 v3_madd(vec3 a, vec3 b, float s) { return v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s); }
static inline vec3 v3_neg(vec3 a) { return v3(-a.x, -a.y, -a.z); }
static inline float v3_dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline vec3 v3_cross(vec3 a, vec3 b)
{
    return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline float v3_len2(vec3 a) { return v3_dot(a, a); }
static inline float v3_len(vec3 a) { return sqrtf(v3_dot(a, a)); }
static inline vec3 v3_norm(vec3 a)
{
    float l = v3_len(a);
    return l > 0.0f ? v3_scale(a, 1.0f / l) : a;
}
/* The angle (radians, [0, pi]) between a and b, neither of length 0: atan2
 * of |sin| and cos, exact for small angles, which acos of the normalized
 * dot product rounds to 0 or 3.5e-4 radians in floats. */
static inline float v3_angle(vec3 a, vec3 b) { return atan2f(v3_len(v3_cross(a, b)), v3_dot(a, b)); }
static inline vec3 v3_min(vec3 a, vec3 b) { return v3(fminf(a.x, b.x), fminf(a.y, b.y), fminf(a.z, b.z)); }
static inline vec3 v3_max(vec3 a, vec3 b) { return v3(fmaxf(a.x, b.x), fmaxf(a.y, b.y), fmaxf(a.z, b.z)); }
static inline vec3 v3_lerp(vec3 a, vec3 b, float t) { return v3_add(a, v3_scale(v3_sub(b, a), t)); }
static inline float v3_maxc(vec3 a) { return fmaxf(a.x, fmaxf(a.y, a.z)); }
/* The largest magnitude of a's coordinates. */
static inline float v3_maxabs(vec3 a) { return fmaxf(fabsf(a.x), fmaxf(fabsf(a.y), fabsf(a.z))); }
static inline float v3_avg(vec3 a) { return (a.x + a.y + a.z) * (1.0f / 3.0f); }
static inline float v3_luminance(vec3 a) { return 0.2126f * a.x + 0.7152f * a.y + 0.0722f * a.z; }
static inline bool v3_finite(vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }
/* Every coordinate within +-CT_COORD_MAX (false for NaN). */
static inline bool v3_in_range(vec3 a)
{
    return fabsf(a.x) <= CT_COORD_MAX && fabsf(a.y) <= CT_COORD_MAX && fabsf(a.z) <= CT_COORD_MAX;
}
/* a moved into +-CT_COORD_MAX: interpolation between points at the
 * range's edge rounds past it by a float step. */
static inline vec3 v3_clamp_range(vec3 a)
{
    return v3_min(v3_max(a, v3s(-CT_COORD_MAX)), v3s(CT_COORD_MAX));
}
static inline bool v3_is_zero(vec3 a) { return a.x == 0.0f && a.y == 0.0f && a.z == 0.0f; }
static inline float v3_get(vec3 a, int i) { return i == 0 ? a.x : (i == 1 ? a.y : a.z); }

/* An orthonormal basis (t, b) around unit n (Duff et al. 2017, branchless). */
void v3_basis(vec3 n, vec3 *t, vec3 *b);

/* --- mat4 --------------------------------------------------------------- */
mat4 m4_identity(void);
mat4 m4_mul(mat4 a, mat4 b);
mat4 m4_transpose(mat4 a);
/* General inverse; returns false (and identity) when singular. */
bool m4_invert(mat4 a, mat4 *out);
mat4 m4_translate(vec3 t);
mat4 m4_scale(vec3 s);
/* Rotation by angle (radians) about a unit axis, right-handed. */
mat4 m4_rotate(vec3 axis, float angle);
/* GL-style view matrix (camera looks down -z). */
mat4 m4_look_at(vec3 eye, vec3 target, vec3 up);
/* GL-style perspective (fov_y in radians), clip z in [-w, w]. */
mat4 m4_perspective(float fov_y, float aspect, float znear, float zfar);
/* GL-style off-axis frustum. */
mat4 m4_frustum(float l, float r, float b, float t, float n, float f);
/* GL-style orthographic. */
mat4 m4_ortho(float l, float r, float b, float t, float n, float f);

static inline vec3 m4_point(const mat4 *m, vec3 p)
{
    return v3(m->m[0][0] * p.x + m->m[0][1] * p.y + m->m[0][2] * p.z + m->m[0][3],
              m->m[1][0] * p.x + m->m[1][1] * p.y + m->m[1][2] * p.z + m->m[1][3],
              m->m[2][0] * p.x + m->m[2][1] * p.y + m->m[2][2] * p.z + m->m[2][3]);
}
static inline vec4 m4_point4(const mat4 *m, vec3 p)
{
    vec4 r;
    r.x = m->m[0][0] * p.x + m->m[0][1] * p.y + m->m[0][2] * p.z + m->m[0][3];
    r.y = m->m[1][0] * p.x + m->m[1][1] * p.y + m->m[1][2] * p.z + m->m[1][3];
    r.z = m->m[2][0] * p.x + m->m[2][1] * p.y + m->m[2][2] * p.z + m->m[2][3];
    r.w = m->m[3][0] * p.x + m->m[3][1] * p.y + m->m[3][2] * p.z + m->m[3][3];
    return r;
}
static inline vec3 m4_dir(const mat4 *m, vec3 d)
{
    return v3(m->m[0][0] * d.x + m->m[0][1] * d.y + m->m[0][2] * d.z,
              m->m[1][0] * d.x + m->m[1][1] * d.y + m->m[1][2] * d.z,
              m->m[2][0] * d.x + m->m[2][1] * d.y + m->m[2][2] * d.z);
}
/* Transforms a normal by the inverse transpose of m's upper 3x3 (inv given). */
static inline vec3 m4_normal(const mat4 *inv, vec3 n)
{
    return v3_norm(v3(inv->m[0][0] * n.x + inv->m[1][0] * n.y + inv->m[2][0] * n.z,
                      inv->m[0][1] * n.x + inv->m[1][1] * n.y + inv->m[2][1] * n.z,
                      inv->m[0][2] * n.x + inv->m[1][2] * n.y + inv->m[2][2] * n.z));
}

/* --- quaternions ---------------------------------------------------------- */
quat q_identity(void);
quat q_axis_angle(vec3 axis, float angle);
quat q_mul(quat a, quat b);
quat q_normalize(quat q);
quat q_conj(quat q);
float q_dot(quat a, quat b);
/* Shortest-arc spherical interpolation. */
quat q_slerp(quat a, quat b, float t);
vec3 q_rotate(quat q, vec3 v);
/* Rotation taking the camera frame (right=+x, up=+y, back=+z) to the given
 * orthonormal right/up/back axes. */
quat q_from_basis(vec3 right, vec3 up, vec3 back);

/* --- bounds --------------------------------------------------------------- */
bounds3 b3_empty(void);
static inline bool b3_is_empty(bounds3 b) { return b.lo.x > b.hi.x; }
static inline bounds3 b3_add(bounds3 b, vec3 p) { b.lo = v3_min(b.lo, p); b.hi = v3_max(b.hi, p); return b; }
static inline bounds3 b3_union(bounds3 a, bounds3 b) { a.lo = v3_min(a.lo, b.lo); a.hi = v3_max(a.hi, b.hi); return a; }
static inline vec3 b3_center(bounds3 b) { return v3_scale(v3_add(b.lo, b.hi), 0.5f); }
static inline vec3 b3_extent(bounds3 b) { return v3_sub(b.hi, b.lo); }
/* Corner i (bit 0: x, bit 1: y, bit 2: z; 1 = hi). */
static inline vec3 b3_corner(bounds3 b, int i)
{
    return v3(i & 1 ? b.hi.x : b.lo.x, i & 2 ? b.hi.y : b.lo.y, i & 4 ? b.hi.z : b.lo.z);
}
float b3_area(bounds3 b);
bounds3 b3_transform(bounds3 b, const mat4 *m);

#endif

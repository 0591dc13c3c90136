#include "common/vecmath.h"

#include <string.h>

void v3_basis(vec3 n, vec3 *t, vec3 *b)
{
    float sign = copysignf(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float bb = n.x * n.y * a;
    *t = v3(1.0f + sign * n.x * n.x * a, sign * bb, -sign * n.x);
    *b = v3(bb, sign + n.y * n.y * a, -n.y);
}

mat4 m4_identity(void)
{
    mat4 r;
    memset(&r, 0, sizeof r);
    r.m[0][0] = r.m[1][1] = r.m[2][2] = r.m[3][3] = 1.0f;
    return r;
}

mat4 m4_mul(mat4 a, mat4 b)
{
    mat4 r;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double s = 0.0;
            for (int k = 0; k < 4; k++) s += (double)a.m[i][k] * b.m[k][j];
            r.m[i][j] = (float)s;
        }
    return r;
}

mat4 m4_transpose(mat4 a)
{
    mat4 r;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) r.m[i][j] = a.m[j][i];
    return r;
}

bool m4_invert(mat4 a, mat4 *out)
{
    /* Gauss-Jordan with partial pivoting in double: the matrices here are
     * small and well-scaled, and precision matters more than speed. */
    double m[4][8];
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            m[i][j] = a.m[i][j];
            m[i][j + 4] = (i == j) ? 1.0 : 0.0;
        }
    for (int c = 0; c < 4; c++) {
        int p = c;
        for (int r = c + 1; r < 4; r++)
            if (fabs(m[r][c]) > fabs(m[p][c])) p = r;
        if (fabs(m[p][c]) < 1e-30) { *out = m4_identity(); return false; }
        if (p != c)
            for (int j = 0; j < 8; j++) { double t = m[c][j]; m[c][j] = m[p][j]; m[p][j] = t; }
        double inv = 1.0 / m[c][c];
        for (int j = 0; j < 8; j++) m[c][j] *= inv;
        for (int r = 0; r < 4; r++) {
            if (r == c) continue;
            double f = m[r][c];
            if (f == 0.0) continue;
            for (int j = 0; j < 8; j++) m[r][j] -= f * m[c][j];
        }
    }
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) out->m[i][j] = (float)m[i][j + 4];
    return true;
}

mat4 m4_translate(vec3 t)
{
    mat4 r = m4_identity();
    r.m[0][3] = t.x; r.m[1][3] = t.y; r.m[2][3] = t.z;
    return r;
}

mat4 m4_scale(vec3 s)
{
    mat4 r = m4_identity();
    r.m[0][0] = s.x; r.m[1][1] = s.y; r.m[2][2] = s.z;
    return r;
}

mat4 m4_rotate(vec3 axis, float angle)
{
    vec3 a = v3_norm(axis);
    float c = cosf(angle), s = sinf(angle), t = 1.0f - c;
    mat4 r = m4_identity();
    r.m[0][0] = t * a.x * a.x + c;       r.m[0][1] = t * a.x * a.y - s * a.z; r.m[0][2] = t * a.x * a.z + s * a.y;
    r.m[1][0] = t * a.x * a.y + s * a.z; r.m[1][1] = t * a.y * a.y + c;       r.m[1][2] = t * a.y * a.z - s * a.x;
    r.m[2][0] = t * a.x * a.z - s * a.y; r.m[2][1] = t * a.y * a.z + s * a.x; r.m[2][2] = t * a.z * a.z + c;
    return r;
}

mat4 m4_look_at(vec3 eye, vec3 target, vec3 up)
{
    vec3 f = v3_norm(v3_sub(target, eye));
    vec3 s = v3_norm(v3_cross(f, up));
    vec3 u = v3_cross(s, f);
    mat4 r = m4_identity();
    r.m[0][0] = s.x;  r.m[0][1] = s.y;  r.m[0][2] = s.z;  r.m[0][3] = -v3_dot(s, eye);
    r.m[1][0] = u.x;  r.m[1][1] = u.y;  r.m[1][2] = u.z;  r.m[1][3] = -v3_dot(u, eye);
    r.m[2][0] = -f.x; r.m[2][1] = -f.y; r.m[2][2] = -f.z; r.m[2][3] = v3_dot(f, eye);
    return r;
}

mat4 m4_frustum(float l, float r, float b, float t, float n, float f)
{
    mat4 m;
    memset(&m, 0, sizeof m);
    m.m[0][0] = 2.0f * n / (r - l);
    m.m[0][2] = (r + l) / (r - l);
    m.m[1][1] = 2.0f * n / (t - b);
    m.m[1][2] = (t + b) / (t - b);
    m.m[2][2] = -(f + n) / (f - n);
    m.m[2][3] = -2.0f * f * n / (f - n);
    m.m[3][2] = -1.0f;
    return m;
}

mat4 m4_perspective(float fov_y, float aspect, float znear, float zfar)
{
    float t = znear * tanf(0.5f * fov_y);
    float r = t * aspect;
    return m4_frustum(-r, r, -t, t, znear, zfar);
}

mat4 m4_ortho(float l, float r, float b, float t, float n, float f)
{
    mat4 m = m4_identity();
    m.m[0][0] = 2.0f / (r - l); m.m[0][3] = -(r + l) / (r - l);
    m.m[1][1] = 2.0f / (t - b); m.m[1][3] = -(t + b) / (t - b);
    m.m[2][2] = -2.0f / (f - n); m.m[2][3] = -(f + n) / (f - n);
    return m;
}

quat q_identity(void) { quat q = {1, 0, 0, 0}; return q; }

quat q_axis_angle(vec3 axis, float angle)
{
    vec3 a = v3_norm(axis);
    float s = sinf(0.5f * angle);
    quat q = {cosf(0.5f * angle), a.x * s, a.y * s, a.z * s};
    return q;
}

quat q_mul(quat a, quat b)
{
    quat r;
    r.w = a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z;
    r.x = a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y;
    r.y = a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x;
    r.z = a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w;
    return r;
}

float q_dot(quat a, quat b) { return a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z; }

quat q_normalize(quat q)
{
    float l = sqrtf(q_dot(q, q));
    if (l <= 0.0f) return q_identity();
    quat r = {q.w / l, q.x / l, q.y / l, q.z / l};
    return r;
}

quat q_conj(quat q) { quat r = {q.w, -q.x, -q.y, -q.z}; return r; }

quat q_slerp(quat a, quat b, float t)
{
    float d = q_dot(a, b);
    if (d < 0.0f) { b.w = -b.w; b.x = -b.x; b.y = -b.y; b.z = -b.z; d = -d; }
    if (d > 0.9995f) {
        quat r = {a.w + t * (b.w - a.w), a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), a.z + t * (b.z - a.z)};
        return q_normalize(r);
    }
    float th = acosf(d), s = sinf(th);
    float wa = sinf((1.0f - t) * th) / s, wb = sinf(t * th) / s;
    quat r = {wa * a.w + wb * b.w, wa * a.x + wb * b.x, wa * a.y + wb * b.y, wa * a.z + wb * b.z};
    return q_normalize(r);
}

vec3 q_rotate(quat q, vec3 v)
{
    vec3 u = v3(q.x, q.y, q.z);
    vec3 t = v3_scale(v3_cross(u, v), 2.0f);
    return v3_add(v3_add(v, v3_scale(t, q.w)), v3_cross(u, t));
}

quat q_from_basis(vec3 r, vec3 u, vec3 b)
{
    /* Columns of the rotation matrix are r, u, b (Shepperd's method). */
    float m00 = r.x, m01 = u.x, m02 = b.x;
    float m10 = r.y, m11 = u.y, m12 = b.y;
    float m20 = r.z, m21 = u.z, m22 = b.z;
    float tr = m00 + m11 + m22;
    quat q;
    if (tr > 0.0f) {
        float s = sqrtf(tr + 1.0f) * 2.0f;
        q.w = 0.25f * s; q.x = (m21 - m12) / s; q.y = (m02 - m20) / s; q.z = (m10 - m01) / s;
    } else if (m00 > m11 && m00 > m22) {
        float s = sqrtf(1.0f + m00 - m11 - m22) * 2.0f;
        q.w = (m21 - m12) / s; q.x = 0.25f * s; q.y = (m01 + m10) / s; q.z = (m02 + m20) / s;
    } else if (m11 > m22) {
        float s = sqrtf(1.0f + m11 - m00 - m22) * 2.0f;
        q.w = (m02 - m20) / s; q.x = (m01 + m10) / s; q.y = 0.25f * s; q.z = (m12 + m21) / s;
    } else {
        float s = sqrtf(1.0f + m22 - m00 - m11) * 2.0f;
        q.w = (m10 - m01) / s; q.x = (m02 + m20) / s; q.y = (m12 + m21) / s; q.z = 0.25f * s;
    }
    return q_normalize(q);
}

bounds3 b3_empty(void)
{
    bounds3 b = {v3s(INFINITY), v3s(-INFINITY)};
    return b;
}

float b3_area(bounds3 b)
{
    if (b3_is_empty(b)) return 0.0f;
    vec3 e = b3_extent(b);
    return 2.0f * (e.x * e.y + e.y * e.z + e.z * e.x);
}

bounds3 b3_transform(bounds3 b, const mat4 *m)
{
    bounds3 r = b3_empty();
    if (b3_is_empty(b)) return r;
    for (int i = 0; i < 8; i++) r = b3_add(r, m4_point(m, b3_corner(b, i)));
    return r;
}

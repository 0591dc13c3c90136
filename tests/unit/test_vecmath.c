/* Unit tests of common/vecmath: mat4 products and inverses, the GL-style
 * matrices, quaternions (slerp, rotation, basis round trip) and bounds. */
#include <criterion/criterion.h>

#include <float.h>
#include <math.h>

#include "common/camera.h"
#include "common/rng.h"
#include "common/vecmath.h"
#include "tests/support/fixtures.h"

static void assert_v3_near(vec3 a, vec3 b, float tol, const char *what)
{
    cr_assert(fabsf(a.x - b.x) <= tol && fabsf(a.y - b.y) <= tol && fabsf(a.z - b.z) <= tol,
              "%s: (%g %g %g) != (%g %g %g)", what, (double)a.x, (double)a.y, (double)a.z, (double)b.x,
              (double)b.y, (double)b.z);
}

static void assert_m4_near(mat4 a, mat4 b, float tol, const char *what)
{
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            cr_assert(fabsf(a.m[i][j] - b.m[i][j]) <= tol, "%s: [%d][%d] %g != %g", what, i, j,
                      (double)a.m[i][j], (double)b.m[i][j]);
}

/* a * b is the identity within the rounding of a float product: entry
 * (i, j) may be off by a few ulps of sum_k |a_ik| |b_kj| (the inverse is
 * exact to float rounding; a perspective matrix has entries of 10^3). */
static void assert_identity_product(mat4 a, mat4 b, const char *what)
{
    mat4 p = m4_mul(a, b);
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            float mag = 0.0f;
            for (int k = 0; k < 4; k++) mag += fabsf(a.m[i][k]) * fabsf(b.m[k][j]);
            float tol = 16.0f * FLT_EPSILON * mag + 1e-7f;
            cr_assert(fabsf(p.m[i][j] - (i == j ? 1.0f : 0.0f)) <= tol, "%s: [%d][%d] %g (tolerance %g)", what, i,
                      j, (double)p.m[i][j], (double)tol);
        }
}

/* Same rotation (q and -q are the same rotation). */
static void assert_same_rotation(quat a, quat b, float tol, const char *what)
{
    float d = fabsf(q_dot(q_normalize(a), q_normalize(b)));
    cr_assert(d >= 1.0f - tol, "%s: |dot| = %.9g", what, (double)d);
}

static quat rand_quat(ct_rng *r)
{
    vec3 axis = fx_rand_unit(r);
    return q_axis_angle(axis, (2.0f * rng_float(r) - 1.0f) * CT_PI);
}

Test(vecmath, m4_mul_hand_computed)
{
    mat4 a, b;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            a.m[i][j] = (float)(i * 4 + j);        /* 0..15 */
            b.m[i][j] = (float)(i == j ? 2 : (j == 3 ? 1 : 0));
        }
    /* (a b)[i][j] = 2 a[i][j] for j < 3; column 3: 2 a[i][3] + a[i][0] + a[i][1] + a[i][2]. */
    mat4 c = m4_mul(a, b);
    for (int i = 0; i < 4; i++) {
        for (int j = 0; j < 3; j++) cr_assert_eq(c.m[i][j], 2.0f * a.m[i][j]);
        cr_assert_eq(c.m[i][3], 2.0f * a.m[i][3] + a.m[i][0] + a.m[i][1] + a.m[i][2]);
    }
    assert_m4_near(m4_mul(m4_identity(), a), a, 0, "I a");
    assert_m4_near(m4_mul(m4_translate(v3(1, 2, 3)), m4_translate(v3(-4, 5, 0.5f))),
                   m4_translate(v3(-3, 7, 3.5f)), 0, "translations add");
    mat4 t = m4_transpose(a);
    cr_assert_eq(t.m[1][3], a.m[3][1]);
    assert_m4_near(m4_transpose(t), a, 0, "transpose twice");
}

Test(vecmath, m4_point_dir_rotate)
{
    mat4 rz = m4_rotate(v3(0, 0, 1), 0.5f * CT_PI);
    assert_v3_near(m4_point(&rz, v3(1, 0, 0)), v3(0, 1, 0), 1e-6f, "x -> y about z (right-handed)");
    mat4 rx = m4_rotate(v3(1, 0, 0), 0.5f * CT_PI);
    assert_v3_near(m4_point(&rx, v3(0, 1, 0)), v3(0, 0, 1), 1e-6f, "y -> z about x");
    mat4 m = m4_mul(m4_translate(v3(1, 2, 3)), m4_scale(v3(2, 3, 4)));
    assert_v3_near(m4_point(&m, v3(1, 1, 1)), v3(3, 5, 7), 0, "scale then translate");
    assert_v3_near(m4_dir(&m, v3(1, 1, 1)), v3(2, 3, 4), 0, "directions ignore translation");
    vec4 p = m4_point4(&m, v3(1, 1, 1));
    cr_assert_eq(p.w, 1.0f);
    /* Normals: a plane x + y = 0 scaled by (2, 1, 1) has normal ~ (1, 2, 0). */
    mat4 s = m4_scale(v3(2, 1, 1)), inv;
    cr_assert(m4_invert(s, &inv));
    assert_v3_near(m4_normal(&inv, v3_norm(v3(1, 1, 0))), v3_norm(v3(1, 2, 0)), 1e-6f, "normal");
}

Test(vecmath, m4_invert_random_and_singular)
{
    ct_rng r = rng_make(11, 0, 0, 0);
    for (int k = 0; k < 200; k++) {
        float t[3], s[3];
        for (int i = 0; i < 3; i++) t[i] = rng_float(&r);
        vec3 axis = fx_rand_unit(&r);
        float angle = 6.0f * rng_float(&r);
        for (int i = 0; i < 3; i++) s[i] = rng_float(&r);
        mat4 m = m4_mul(m4_translate(v3(10 * t[0] - 5, 3 * t[1], -7 * t[2])),
                        m4_mul(m4_rotate(axis, angle), m4_scale(v3(0.2f + s[0], 0.5f + 2 * s[1], 1.0f + s[2]))));
        if (k % 3 == 0) m = m4_mul(m4_perspective(0.3f + 2.0f * rng_float(&r), 1.5f, 0.1f, 100.0f), m);
        mat4 inv;
        cr_assert(m4_invert(m, &inv), "matrix %d reported singular", k);
        assert_identity_product(m, inv, "m inv");
        assert_identity_product(inv, m, "inv m");
    }
    /* A pivot in the wrong place (zero on the diagonal) still inverts. */
    mat4 perm;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) perm.m[i][j] = (j == (i + 1) % 4) ? 1.0f : 0.0f;
    mat4 pinv;
    cr_assert(m4_invert(perm, &pinv));
    assert_m4_near(pinv, m4_transpose(perm), 0, "permutation inverse is its transpose");

    mat4 sing = m4_identity(), out;
    sing.m[2][0] = 1; sing.m[2][1] = 1; sing.m[2][2] = 0;
    sing.m[1][0] = 1; sing.m[1][1] = 1; sing.m[1][2] = 0;  /* rows 1 and 2 equal */
    cr_assert(!m4_invert(sing, &out));
    assert_m4_near(out, m4_identity(), 0, "identity on failure");
    mat4 zero = {{{0}}};
    cr_assert(!m4_invert(zero, &out));
}

Test(vecmath, look_at_and_cam_view)
{
    vec3 eye = v3(1, 2, 3), target = v3(-2, 0.5f, -4), up = v3(0, 1, 0);
    mat4 v = m4_look_at(eye, target, up);
    assert_v3_near(m4_point(&v, eye), v3(0, 0, 0), 1e-6f, "eye to origin");
    float dist = v3_len(v3_sub(target, eye));
    assert_v3_near(m4_point(&v, target), v3(0, 0, -dist), 1e-5f, "target on -z");
    /* World up stays in the upper half (+y) of eye space. */
    cr_assert_gt(m4_dir(&v, up).y, 0.0f);
    cr_assert_float_eq(m4_dir(&v, up).x, 0.0f, 1e-6);
    ct_rng r = rng_make(3, 0, 0, 0);
    for (int k = 0; k < 100; k++) {
        vec3 e = v3_scale(fx_rand_unit(&r), 10 * rng_float(&r));
        vec3 t = v3_add(e, v3_scale(fx_rand_unit(&r), 0.5f + 5 * rng_float(&r)));
        vec3 u = fx_rand_unit(&r);
        if (fabsf(v3_dot(u, v3_norm(v3_sub(t, e)))) > 0.99f) continue;
        ct_camera c = cam_look_at(e, t, u, 50.0f);
        assert_m4_near(cam_view(&c), m4_look_at(e, t, u), 2e-5f * (1 + v3_len(e)), "cam_view == look_at");
    }
}

Test(vecmath, perspective_and_ortho_depth_range)
{
    mat4 p = m4_perspective(1.0f, 2.0f, 0.5f, 50.0f);
    vec4 n = m4_point4(&p, v3(0, 0, -0.5f)), f = m4_point4(&p, v3(0, 0, -50.0f));
    cr_assert_float_eq(n.z / n.w, -1.0f, 1e-5);
    cr_assert_float_eq(f.z / f.w, 1.0f, 1e-5);
    /* Top edge of the near plane maps to y = 1, right edge to x = 1. */
    float t = 0.5f * tanf(0.5f), rr = t * 2.0f;
    vec4 c = m4_point4(&p, v3(rr, t, -0.5f));
    cr_assert_float_eq(c.x / c.w, 1.0f, 1e-5);
    cr_assert_float_eq(c.y / c.w, 1.0f, 1e-5);
    mat4 o = m4_ortho(-1, 3, -2, 2, 1, 9);
    assert_v3_near(m4_point(&o, v3(3, 2, -9)), v3(1, 1, 1), 1e-6f, "ortho far corner");
    assert_v3_near(m4_point(&o, v3(-1, -2, -1)), v3(-1, -1, -1), 1e-6f, "ortho near corner");
}

Test(vecmath, quat_slerp_endpoints_and_unit_length)
{
    ct_rng r = rng_make(5, 0, 0, 0);
    for (int k = 0; k < 200; k++) {
        quat a = rand_quat(&r), b = rand_quat(&r);
        assert_same_rotation(q_slerp(a, b, 0.0f), a, 1e-6f, "slerp(0) = a");
        assert_same_rotation(q_slerp(a, b, 1.0f), b, 1e-6f, "slerp(1) = b");
        for (int i = 0; i <= 10; i++) {
            quat q = q_slerp(a, b, (float)i / 10.0f);
            cr_assert_float_eq(sqrtf(q_dot(q, q)), 1.0f, 1e-6, "unit length");
        }
    }
    /* Half way between 0 and 90 degrees about z is 45 degrees. */
    quat a = q_identity(), b = q_axis_angle(v3(0, 0, 1), 0.5f * CT_PI);
    assert_v3_near(q_rotate(q_slerp(a, b, 0.5f), v3(1, 0, 0)), v3_norm(v3(1, 1, 0)), 1e-6f, "45 deg");
    /* Constant angular speed: a quarter of the way is 22.5 degrees. */
    vec3 q1 = q_rotate(q_slerp(a, b, 0.25f), v3(1, 0, 0));
    cr_assert_float_eq(atan2f(q1.y, q1.x), 0.125f * CT_PI, 1e-6);
    /* Shortest arc: b and -b give the same path. */
    quat nb = {-b.w, -b.x, -b.y, -b.z};
    assert_v3_near(q_rotate(q_slerp(a, nb, 0.5f), v3(1, 0, 0)), v3_norm(v3(1, 1, 0)), 1e-6f, "-b");
    /* Nearly equal quaternions (the lerp branch) stay unit. */
    quat c = q_axis_angle(v3(0, 1, 0), 1e-4f);
    quat m = q_slerp(a, c, 0.5f);
    cr_assert_float_eq(q_dot(m, m), 1.0f, 1e-6);
}

Test(vecmath, quat_mul_and_rotate)
{
    ct_rng r = rng_make(6, 0, 0, 0);
    for (int k = 0; k < 100; k++) {
        quat a = rand_quat(&r), b = rand_quat(&r);
        vec3 v = v3_scale(fx_rand_unit(&r), 3.0f);
        assert_v3_near(q_rotate(q_mul(a, b), v), q_rotate(a, q_rotate(b, v)), 1e-5f, "composition");
        assert_v3_near(q_rotate(q_conj(a), q_rotate(a, v)), v, 1e-5f, "conjugate undoes");
        cr_assert_float_eq(v3_len(q_rotate(a, v)), 3.0f, 1e-5, "length preserved");
        /* Agrees with the matrix rotation. */
        vec3 axis = fx_rand_unit(&r);
        float ang = 3.0f * rng_float(&r);
        mat4 m = m4_rotate(axis, ang);
        assert_v3_near(q_rotate(q_axis_angle(axis, ang), v), m4_point(&m, v), 1e-5f, "quat vs matrix");
    }
}

Test(vecmath, quat_from_basis_round_trip)
{
    ct_rng r = rng_make(8, 0, 0, 0);
    quat qs[200 + 7];
    int n = 0;
    for (int k = 0; k < 200; k++) qs[n++] = rand_quat(&r);
    /* Rotations by pi make the trace -1 and exercise the other branches. */
    qs[n++] = q_axis_angle(v3(1, 0, 0), CT_PI);
    qs[n++] = q_axis_angle(v3(0, 1, 0), CT_PI);
    qs[n++] = q_axis_angle(v3(0, 0, 1), CT_PI);
    qs[n++] = q_axis_angle(v3_norm(v3(1, 1, 0)), CT_PI);
    qs[n++] = q_axis_angle(v3_norm(v3(0, 1, 1)), 0.99f * CT_PI);
    qs[n++] = q_identity();
    qs[n++] = q_axis_angle(v3_norm(v3(1, -1, 1)), 2.0f);
    for (int k = 0; k < n; k++) {
        quat q = qs[k];
        vec3 rr = q_rotate(q, v3(1, 0, 0)), u = q_rotate(q, v3(0, 1, 0)), b = q_rotate(q, v3(0, 0, 1));
        quat p = q_from_basis(rr, u, b);
        assert_same_rotation(p, q, 1e-6f, "q_from_basis(axes of q) = q");
        assert_v3_near(q_rotate(p, v3(1, 0, 0)), rr, 1e-5f, "right");
        assert_v3_near(q_rotate(p, v3(0, 1, 0)), u, 1e-5f, "up");
        assert_v3_near(q_rotate(p, v3(0, 0, 1)), b, 1e-5f, "back");
    }
}

Test(vecmath, basis_is_orthonormal)
{
    ct_rng r = rng_make(9, 0, 0, 0);
    vec3 ns[104] = {v3(0, 0, 1), v3(0, 0, -1), v3(1, 0, 0), v3(0, -1, 0)};
    for (int k = 4; k < 104; k++) ns[k] = fx_rand_unit(&r);
    for (int k = 0; k < 104; k++) {
        vec3 t, b, nn = ns[k];
        v3_basis(nn, &t, &b);
        cr_assert_float_eq(v3_len(t), 1.0f, 1e-5);
        cr_assert_float_eq(v3_len(b), 1.0f, 1e-5);
        cr_assert_float_eq(v3_dot(t, nn), 0.0f, 1e-5);
        cr_assert_float_eq(v3_dot(b, nn), 0.0f, 1e-5);
        cr_assert_float_eq(v3_dot(t, b), 0.0f, 1e-5);
        /* Right-handed: t x b = n. */
        assert_v3_near(v3_cross(t, b), nn, 1e-5f, "t x b = n");
    }
}

Test(vecmath, bounds)
{
    bounds3 e = b3_empty();
    cr_assert(b3_is_empty(e));
    cr_assert_eq(b3_area(e), 0.0f);
    cr_assert(b3_is_empty(b3_transform(e, &(mat4){{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}}})));
    bounds3 b = b3_add(e, v3(0, 0, 0));
    cr_assert(!b3_is_empty(b));
    cr_assert_eq(b3_area(b), 0.0f, "a point has no area");
    b = b3_add(b, v3(1, 2, 3));
    b = b3_add(b, v3(0.5f, -1, 1));
    assert_v3_near(b.lo, v3(0, -1, 0), 0, "lo");
    assert_v3_near(b.hi, v3(1, 2, 3), 0, "hi");
    assert_v3_near(b3_center(b), v3(0.5f, 0.5f, 1.5f), 0, "center");
    assert_v3_near(b3_extent(b), v3(1, 3, 3), 0, "extent");
    cr_assert_eq(b3_area(b), 2.0f * (3 + 9 + 3));
    assert_v3_near(b3_corner(b, 5), v3(1, -1, 3), 0, "corner 5 = hi x, lo y, hi z");
    bounds3 u = b3_union(b, (bounds3){v3(-2, 0, 0), v3(0, 0, 5)});
    assert_v3_near(u.lo, v3(-2, -1, 0), 0, "union lo");
    assert_v3_near(u.hi, v3(1, 2, 5), 0, "union hi");
    cr_assert_eq(b3_area((bounds3){v3(0, 0, 0), v3(1, 1, 1)}), 6.0f);
    /* The unit square rotated by 45 degrees about z spans sqrt(2). */
    mat4 rz = m4_rotate(v3(0, 0, 1), 0.25f * CT_PI);
    bounds3 rb = b3_transform((bounds3){v3(0, 0, 0), v3(1, 1, 1)}, &rz);
    cr_assert_float_eq(b3_extent(rb).x, sqrtf(2.0f), 1e-6);
    cr_assert_float_eq(b3_extent(rb).y, sqrtf(2.0f), 1e-6);
    cr_assert_float_eq(b3_extent(rb).z, 1.0f, 1e-6);
}

/* v3_angle holds small angles, which acos of the normalized dot product
 * rounds to 0 or 3.5e-4 radians (aging and late samples rest on it:
 * master/ctex_view.c, master/ctex_insert.c), and the large ones. */
Test(vecmath, angle_exact_for_small_turns)
{
    const float small[] = {1e-6f, 1e-5f, 1e-4f, 3e-4f};
    for (size_t i = 0; i < sizeof small / sizeof *small; i++) {
        vec3 a = v3(0.0f, 0.0f, 3.0f), b = v3(3.0f * sinf(small[i]), 0.0f, 3.0f * cosf(small[i]));
        float got = v3_angle(a, b);
        cr_assert_float_eq(got, small[i], small[i] * 1e-3f, "angle %g: %g", (double)small[i], (double)got);
    }
    cr_assert_float_eq(v3_angle(v3(1, 0, 0), v3(0, 2, 0)), (float)(M_PI / 2), 1e-6f);
    cr_assert_float_eq(v3_angle(v3(1, 0, 0), v3(-1, 0, 0)), (float)M_PI, 1e-6f);
    cr_assert_eq(v3_angle(v3(1, 2, 3), v3(2, 4, 6)), 0.0f);
}

Test(vecmath, maxabs_is_the_largest_magnitude)
{
    cr_expect_float_eq(v3_maxabs(v3(1.0f, -3.0f, 2.0f)), 3.0f, 0.0f);
    cr_expect_float_eq(v3_maxabs(v3(-0.5f, 0.25f, 0.0f)), 0.5f, 0.0f);
    cr_expect_float_eq(v3_maxabs(v3(0.0f, 0.0f, 0.0f)), 0.0f, 0.0f);
}

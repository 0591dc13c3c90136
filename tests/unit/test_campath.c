/* Unit tests of common/campath: keyframes are hit exactly, position and
 * velocity are continuous across keyframes (finite differences), frames
 * span the path, parse errors name the line, save/load round trip. */
#include <criterion/criterion.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "common/campath.h"

/* Unevenly spaced keys: the tangents must account for the time spacing. */
static const char *const PATH_TEXT =
    "# test path\n"
    "up 0 1 0\n"
    "0.0   0 1.5 8    0 1 0\n"
    "1.0   3 1.5 6    0 1 0   50\n"
    "3.5   5 2.5 0    0 1 -1  60\n"
    "\n"
    "4.0   2 1.0 -4   0 1 0   45   # short segment\n"
    "7.5  -4 1.5 -2   1 1 0\n";

static ct_campath load_text(const char *text)
{
    ct_campath p;
    ct_error err;
    cr_assert_eq(campath_parse(text, "test.path", &p, &err), 0, "%s", err.msg);
    return p;
}

static void assert_v3_eq(vec3 a, vec3 b, const char *what)
{
    cr_assert(a.x == b.x && a.y == b.y && a.z == b.z, "%s: (%.9g %.9g %.9g) != (%.9g %.9g %.9g)", what,
              (double)a.x, (double)a.y, (double)a.z, (double)b.x, (double)b.y, (double)b.z);
}

static vec3 pos(const ct_campath *p, double t)
{
    return campath_eval(p, (float)t).eye;
}

/* One-sided derivative estimates with Richardson extrapolation (second
 * order), so that a jump in acceleration does not look like one in velocity. */
static vec3 vel_left(const ct_campath *p, double t, double h)
{
    vec3 d1 = v3_scale(v3_sub(pos(p, t), pos(p, t - h)), (float)(1.0 / h));
    vec3 d2 = v3_scale(v3_sub(pos(p, t), pos(p, t - 2 * h)), (float)(1.0 / (2 * h)));
    return v3_sub(v3_scale(d1, 2.0f), d2);
}

static vec3 vel_right(const ct_campath *p, double t, double h)
{
    vec3 d1 = v3_scale(v3_sub(pos(p, t + h), pos(p, t)), (float)(1.0 / h));
    vec3 d2 = v3_scale(v3_sub(pos(p, t + 2 * h), pos(p, t)), (float)(1.0 / (2 * h)));
    return v3_sub(v3_scale(d1, 2.0f), d2);
}

Test(campath, parses_keys_and_defaults)
{
    ct_campath p = load_text(PATH_TEXT);
    cr_assert_eq(p.nkeys, 5);
    cr_assert_str_eq(p.name, "test");
    cr_assert_eq(p.keys[0].fov_deg, 45.0f, "default fov");
    cr_assert_eq(p.keys[1].fov_deg, 50.0f);
    cr_assert_eq(p.keys[3].t, 4.0f);
    cr_assert_float_eq(campath_duration(&p), 7.5f, 0);
    campath_free(&p);
    cr_assert_null(p.keys);
}

Test(campath, keyframes_hit_exactly)
{
    ct_campath p = load_text(PATH_TEXT);
    for (int i = 0; i < p.nkeys; i++) {
        ct_camera c = campath_eval(&p, p.keys[i].t);
        assert_v3_eq(c.eye, p.keys[i].eye, "eye at key time");
        cr_assert_eq(c.fov_y, p.cams[i].fov_y);
        vec3 f;
        cam_axes(&c, NULL, NULL, &f);
        vec3 want = v3_norm(v3_sub(p.keys[i].target, p.keys[i].eye));
        cr_assert(v3_len(v3_sub(f, want)) < 1e-6f, "key %d looks at its target", i);
    }
    campath_free(&p);
}

Test(campath, position_and_velocity_continuous)
{
    ct_campath p = load_text(PATH_TEXT);
    const double h = 2e-3;
    for (int i = 1; i < p.nkeys - 1; i++) {
        double t = p.keys[i].t;
        /* Position: the values just before and after the key are close to it. */
        vec3 at = pos(&p, t);
        cr_assert_lt(v3_len(v3_sub(pos(&p, t - 1e-4), at)), 5e-3f);
        cr_assert_lt(v3_len(v3_sub(pos(&p, t + 1e-4), at)), 5e-3f);
        /* Velocity: left and right derivatives agree, and equal the
         * non-uniform Catmull-Rom tangent (p[i+1] - p[i-1]) / (t[i+1] - t[i-1]). */
        vec3 vl = vel_left(&p, t, h), vr = vel_right(&p, t, h);
        vec3 tangent = v3_scale(v3_sub(p.keys[i + 1].eye, p.keys[i - 1].eye),
                                1.0f / (p.keys[i + 1].t - p.keys[i - 1].t));
        float scale = v3_len(tangent);
        cr_assert_gt(scale, 0.5f);
        cr_assert_lt(v3_len(v3_sub(vl, vr)), 0.01f * scale, "key %d: velocity jumps from (%g %g %g) to (%g %g %g)", i,
                     (double)vl.x, (double)vl.y, (double)vl.z, (double)vr.x, (double)vr.y, (double)vr.z);
        cr_assert_lt(v3_len(v3_sub(vl, tangent)), 0.01f * scale, "key %d: velocity (%g %g %g), tangent (%g %g %g)", i,
                     (double)vl.x, (double)vl.y, (double)vl.z, (double)tangent.x, (double)tangent.y,
                     (double)tangent.z);
    }
    /* Orientation is continuous too: the view direction does not jump. */
    for (int i = 1; i < p.nkeys - 1; i++) {
        vec3 f0, f1;
        ct_camera a = campath_eval(&p, p.keys[i].t - 1e-4f), b = campath_eval(&p, p.keys[i].t + 1e-4f);
        cam_axes(&a, NULL, NULL, &f0);
        cam_axes(&b, NULL, NULL, &f1);
        cr_assert_lt(v3_len(v3_sub(f0, f1)), 1e-3f);
    }
    /* The whole path is smooth at a fine sampling: no step exceeds the
     * largest speed times the step. */
    vec3 prev = pos(&p, 0.0);
    for (int k = 1; k <= 7500; k++) {
        vec3 cur = pos(&p, k * 1e-3);
        cr_assert_lt(v3_len(v3_sub(cur, prev)), 0.02f, "step at t = %g", k * 1e-3);
        prev = cur;
    }
    campath_free(&p);
}

Test(campath, frames_and_clamping)
{
    ct_campath p = load_text(PATH_TEXT);
    ct_camera first = campath_frame(&p, 0, 300), last = campath_frame(&p, 299, 300);
    assert_v3_eq(first.eye, p.keys[0].eye, "frame 0");
    assert_v3_eq(last.eye, p.keys[p.nkeys - 1].eye, "frame n-1");
    assert_v3_eq(campath_frame(&p, 0, 1).eye, p.keys[0].eye, "a single frame is the first key");
    /* Frame k of n is at time t0 + duration * k / (n - 1). */
    ct_camera mid = campath_frame(&p, 150, 301);
    assert_v3_eq(mid.eye, campath_eval(&p, 3.75f).eye, "frame 150 of 301");
    /* Outside the time range the path holds its end cameras. */
    assert_v3_eq(campath_eval(&p, -5.0f).eye, p.keys[0].eye, "before");
    assert_v3_eq(campath_eval(&p, 100.0f).eye, p.keys[4].eye, "after");
    campath_free(&p);

    ct_campath one = load_text("2.0  1 2 3  0 0 0  30\n");
    assert_v3_eq(campath_eval(&one, 0.0f).eye, v3(1, 2, 3), "single key");
    assert_v3_eq(campath_frame(&one, 5, 10).eye, v3(1, 2, 3), "single key frame");
    cr_assert_eq(campath_duration(&one), 0.0f);
    campath_free(&one);
}

/* Parses text and expects an error whose message contains every needle. */
static void expect_error(const char *text, int code, const char *n1, const char *n2)
{
    ct_campath p;
    ct_error err;
    memset(&err, 0, sizeof err);
    int rc = campath_parse(text, "bad.path", &p, &err);
    cr_assert_eq(rc, code, "'%s': rc %d (%s), expected %d", text, rc, err.msg, code);
    cr_assert(strstr(err.msg, n1) != NULL, "'%s': message '%s' lacks '%s'", text, err.msg, n1);
    if (n2) cr_assert(strstr(err.msg, n2) != NULL, "'%s': message '%s' lacks '%s'", text, err.msg, n2);
    cr_assert_eq(strchr(err.msg, '\n'), NULL);
    cr_assert_null(p.keys);
}

Test(campath, parse_errors_name_the_line)
{
    /* Wrong number counts. */
    expect_error("0 0 0 5 0 0 0\n1 1 0 5 0 0\n", CT_EPARSE, "bad.path:2:", "7 or 8 numbers");
    expect_error("# c\n\n0 0 0 5 0 0 0 45 9\n", CT_EPARSE, "bad.path:3:", NULL);
    expect_error("0 0 0 5 zero 0 0\n", CT_EPARSE, "bad.path:1:", NULL);
    expect_error("up 0 1\n", CT_EPARSE, "bad.path:1:", "up");
    /* A word that is not a number where the fov goes (sscanf stopped there
     * and the default fov was used), and words after it. */
    expect_error("0 0 0 5 0 0 0\n1 1 0 5 0 0 0 abc\n", CT_EPARSE, "bad.path:2:", "7 or 8 numbers");
    expect_error("0 0 0 5 0 0 0 39.3abc\n", CT_EPARSE, "bad.path:1:", "7 or 8 numbers");
    expect_error("0 0 0 5 0 0 0 abc def ghi\n", CT_EPARSE, "bad.path:1:", "7 or 8 numbers");
    expect_error("up 0 1 0 x\n0 0 0 5 0 0 0\n", CT_EPARSE, "bad.path:1:", "up");
    /* Times must increase strictly. */
    expect_error("0 0 0 5 0 0 0\n# gap\n2 1 0 5 0 0 0\n2 2 0 5 0 0 0\n", CT_EINVAL, "bad.path:4:", "time");
    expect_error("3 0 0 5 0 0 0\n1 1 0 5 0 0 0\n", CT_EINVAL, "bad.path:2:", "time");
    /* Non-finite values. */
    expect_error("0 0 0 5 0 0 0\n1 nan 0 5 0 0 0\n", CT_EINVAL, "bad.path:2:", "finite");
    expect_error("0 0 0 5 0 0 0 inf\n", CT_EINVAL, "bad.path:1:", "finite");
    /* Other invalid keys. */
    expect_error("0 0 0 5 0 0 0 180\n", CT_EINVAL, "bad.path:1:", "fov");
    /* Fields of view the wires refuse: a path must give cameras a display may send. */
    expect_error("0 0 0 5 0 0 0 179.9999\n", CT_EINVAL, "bad.path:1:", "fov 179.9999 outside");
    expect_error("0 0 0 5 0 0 0 1e-30\n", CT_EINVAL, "bad.path:1:", "fov 1e-30 outside");
    expect_error("\n\n0 1 1 1 1 1 1\n", CT_EINVAL, "bad.path:3:", "eye equals target");
    expect_error("# only a comment\n", CT_EEMPTY, "bad.path", "no keyframes");
    /* Coordinates a ray can take (an eye at -1e19 aborted a tracer). */
    expect_error("0 0 0 5 0 0 0\n1 0 0 -1e19 0 0 0\n", CT_ERANGE, "bad.path:2:", "outside the coordinate range");
    expect_error("0 0 0 5 0 2e9 0\n", CT_ERANGE, "bad.path:1:", "eye or target");
    expect_error("up 0 0 0\n0 0 0 5 0 0 0\n", CT_EINVAL, "bad.path", "up");
    /* Finite times whose span is not (the duration was inf, the cameras NaN). */
    expect_error("-3e38 0 0 5 0 0 0\n3e38 1 0 5 0 0 0\n", CT_ERANGE, "bad.path:2:", "span more than a float");
}

/* The widest span a float holds: every frame's camera is finite. */
Test(campath, frames_of_a_path_spanning_most_of_the_float_range)
{
    ct_campath p = load_text("-1e38 0 0 5 0 0 0\n1e38 1 0 5 0 0 0\n2e38 2 0 5 0 0 0\n");
    for (int k = 0; k < 7; k++) {
        ct_camera c = campath_frame(&p, k, 7);
        cr_assert(v3_finite(c.eye) && isfinite(c.fov_y), "frame %d: eye (%g %g %g) fov %g", k, (double)c.eye.x,
                  (double)c.eye.y, (double)c.eye.z, (double)c.fov_y);
    }
    /* Frame 3 of 7 is at 5e37, between the first two keys (duration x 3
     * overflowed a float: the frame jumped to the path's end). */
    float x = campath_frame(&p, 3, 7).eye.x;
    cr_expect(x > 0.0f && x < 1.0f, "frame 3: eye x %g, want between the first keys' 0 and 1", (double)x);
    campath_free(&p);
}

/* A NUL byte would end the text where it stands: what follows went unread. */
Test(campath, load_refuses_a_nul_byte)
{
    char path[] = "/tmp/ct-test-campath-nul-XXXXXX";
    int fd = mkstemp(path);
    cr_assert_geq(fd, 0);
    static const char text[] = "0 0 0 5 0 0 0\n\0garbage\n1 1 0 5 0 0 0\n";
    cr_assert_eq(write(fd, text, sizeof text - 1), (ssize_t)(sizeof text - 1));
    close(fd);
    ct_campath p;
    ct_error err;
    cr_assert_eq(campath_load(path, &p, &err), CT_EPARSE);
    cr_assert(strstr(err.msg, "contains a NUL byte") != NULL, "%s", err.msg);
    unlink(path);
}

Test(campath, load_missing_file)
{
    ct_campath p;
    ct_error err;
    cr_assert_eq(campath_load("/nonexistent-dir/x.path", &p, &err), CT_EIO);
    cr_assert(strstr(err.msg, "/nonexistent-dir/x.path") != NULL, "%s", err.msg);
}

Test(campath, save_load_round_trip)
{
    char dir[] = "/tmp/ct-test-campath-XXXXXX";
    cr_assert_not_null(mkdtemp(dir));
    char path[256];
    snprintf(path, sizeof path, "%s/walk.path", dir);
    ct_campath p = load_text(PATH_TEXT), q;
    /* Values that need all nine significant digits. */
    p.keys[2].eye.x = 0.1f;
    p.keys[2].target.z = -1.0f / 3.0f;
    p.keys[4].t = 7.123456789f;
    ct_error err;
    cr_assert_eq(campath_save(&p, path, &err), 0, "%s", err.msg);
    cr_assert_eq(campath_load(path, &q, &err), 0, "%s", err.msg);
    cr_assert_str_eq(q.name, "walk");
    cr_assert_eq(q.nkeys, p.nkeys);
    assert_v3_eq(q.up, p.up, "up");
    for (int i = 0; i < p.nkeys; i++) {
        cr_assert_eq(q.keys[i].t, p.keys[i].t);
        assert_v3_eq(q.keys[i].eye, p.keys[i].eye, "eye");
        assert_v3_eq(q.keys[i].target, p.keys[i].target, "target");
        cr_assert_eq(q.keys[i].fov_deg, p.keys[i].fov_deg);
    }
    campath_free(&p);
    campath_free(&q);
    /* A tilted up vector survives too. */
    campath_key keys[2] = {{0, v3(0, 0, 5), v3(0, 0, 0), 40}, {2, v3(1, 0, 5), v3(0, 0, 0), 40}};
    cr_assert_eq(campath_from_keys(keys, 2, v3(0.3f, 1, 0), "tilt", &p, &err), 0, "%s", err.msg);
    cr_assert_eq(campath_save(&p, path, &err), 0, "%s", err.msg);
    cr_assert_eq(campath_load(path, &q, &err), 0, "%s", err.msg);
    /* The path stores up normalized; normalizing again on load may move the
     * last bit, so the direction is compared to float precision. */
    cr_assert_lt(v3_len(v3_sub(q.up, p.up)), 1e-6f, "tilted up");
    campath_free(&p);
    campath_free(&q);
    unlink(path);
    cr_assert_eq(rmdir(dir), 0, "no temporary files left beside the path");
}

Test(campath, frames_stay_in_the_coordinate_range)
{
    /* Keys at the range's edges: the spline overshoots them between keys,
     * and a master refuses a CAMERA whose eye is out of range. */
    ct_campath p = load_text("0 0 0 0 0 0 1\n1 1e9 0 0 0 0 1\n2 1e9 0 0 0 0 1\n");
    float most = 0.0f;
    for (int k = 0; k < 300; k++) {
        ct_camera c = campath_frame(&p, k, 300);
        cr_assert(v3_in_range(c.eye), "frame %d: eye x %g", k, (double)c.eye.x);
        most = fmaxf(most, fabsf(c.eye.x));
    }
    cr_expect_eq(most, CT_COORD_MAX, "the spline did not reach past the keys (%g): nothing was clamped", (double)most);
    campath_free(&p);
}

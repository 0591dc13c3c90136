#include "common/campath.h"
#include "common/fsutil.h"

#include <ctype.h>
#include <stdlib.h>
#include <string.h>

#define CAMPATH_MAX_KEYS 100000
#define CAMPATH_MAX_BYTES (16u << 20)

/* Checks keyframes; errors name "origin:LINE:" when the source lines are
 * known (lines[i] for key i, up_line for the up vector; 0 = unknown), else
 * "origin: keyframe N:". */
static int validate(const campath_key *k, int n, vec3 up, const char *origin, const int *lines,
                    int up_line, ct_error *err)
{
    if (n < 1) return ct_fail(err, CT_EEMPTY, "%s: camera path has no keyframes", origin);
    if (!v3_finite(up) || v3_len2(up) <= 0.0f) {
        if (up_line > 0) return ct_fail(err, CT_EINVAL, "%s:%d: invalid up vector", origin, up_line);
        return ct_fail(err, CT_EINVAL, "%s: invalid up vector", origin);
    }
    for (int i = 0; i < n; i++) {
        char where[320];
        if (lines) snprintf(where, sizeof where, "%s:%d", origin, lines[i]);
        else snprintf(where, sizeof where, "%s: keyframe %d", origin, i + 1);
        if (!isfinite(k[i].t) || !v3_finite(k[i].eye) || !v3_finite(k[i].target) ||
            !isfinite(k[i].fov_deg))
            return ct_fail(err, CT_EINVAL, "%s: non-finite value", where);
        if (!v3_in_range(k[i].eye) || !v3_in_range(k[i].target))
            return ct_fail(err, CT_ERANGE, "%s: eye or target outside the coordinate range +-%g", where,
                           (double)CT_COORD_MAX);
        if (!cam_fov_deg_valid(k[i].fov_deg))
            return ct_fail(err, CT_EINVAL, "%s: fov %.7g outside [%g, %g] degrees", where, (double)k[i].fov_deg,
                           (double)CT_FOV_DEG_MIN, (double)CT_FOV_DEG_MAX);
        if (v3_len2(v3_sub(k[i].target, k[i].eye)) <= 0.0f)
            return ct_fail(err, CT_EINVAL, "%s: eye equals target", where);
        if (i > 0 && !(k[i].t > k[i - 1].t))
            return ct_fail(err, CT_EINVAL, "%s: time %g not after %g", where, (double)k[i].t,
                           (double)k[i - 1].t);
        /* Each time finite, their span not: the path's duration was inf and
         * every camera between the ends NaN (a tracer aborted on the rays). */
        if (i > 0 && !isfinite(k[i].t - k[0].t))
            return ct_fail(err, CT_ERANGE, "%s: times %g to %g span more than a float holds", where,
                           (double)k[0].t, (double)k[i].t);
    }
    return CT_OK;
}

int campath_from_keys(const campath_key *keys, int n, vec3 up, const char *origin,
                      ct_campath *out, ct_error *err)
{
    memset(out, 0, sizeof *out);
    int rc = validate(keys, n, up, origin, NULL, 0, err);
    if (rc) return rc;
    out->keys = malloc((size_t)n * sizeof *out->keys);
    out->cams = malloc((size_t)n * sizeof *out->cams);
    if (!out->keys || !out->cams) {
        campath_free(out);
        return ct_fail(err, CT_ENOMEM, "%s: out of memory", origin);
    }
    memcpy(out->keys, keys, (size_t)n * sizeof *keys);
    out->nkeys = n;
    out->up = v3_norm(up);
    for (int i = 0; i < n; i++) {
        out->cams[i] = cam_look_at(keys[i].eye, keys[i].target, out->up, keys[i].fov_deg);
        /* Keep consecutive quaternions in one hemisphere so slerp takes the
         * short way and the spline never flips. */
        if (i > 0 && q_dot(out->cams[i - 1].orient, out->cams[i].orient) < 0.0f) {
            quat *q = &out->cams[i].orient;
            q->w = -q->w; q->x = -q->x; q->y = -q->y; q->z = -q->z;
        }
    }
    const char *base = strrchr(origin, '/');
    snprintf(out->name, sizeof out->name, "%s", base ? base + 1 : origin);
    char *dot = strrchr(out->name, '.');
    if (dot && dot != out->name) *dot = '\0';
    return CT_OK;
}

/* The whitespace-separated numbers of s into v (at most max); -1 when a
 * word is not a number or there are more than max (with sscanf a fov of
 * 'abc' ended the scan and left the default fov in place). */
static int numbers(const char *s, float *v, int max)
{
    int n = 0;
    for (;;) {
        while (isspace((unsigned char)*s)) s++;
        if (!*s) return n;
        if (n == max) return -1;
        char *end;
        v[n] = strtof(s, &end);   /* (nan and inf parse: validate() names them) */
        if (end == s || (*end && !isspace((unsigned char)*end))) return -1;
        n++;
        s = end;
    }
}

int campath_parse(const char *text, const char *origin, ct_campath *out, ct_error *err)
{
    memset(out, 0, sizeof *out);
    campath_key *keys = NULL;
    int *lines = NULL;   /* source line of each key, for error messages */
    int n = 0, cap = 0, lineno = 0, up_line = 0;
    vec3 up = v3(0, 1, 0);
    const char *p = text;
    int rc = CT_OK;
    while (*p) {
        const char *eol = strchr(p, '\n');
        size_t len = eol ? (size_t)(eol - p) : strlen(p);
        lineno++;
        char line[512];
        if (len >= sizeof line) { rc = ct_fail(err, CT_EPARSE, "%s:%d: line too long", origin, lineno); break; }
        memcpy(line, p, len);
        line[len] = '\0';
        p = eol ? eol + 1 : p + len;
        char *hash = strchr(line, '#');
        if (hash) *hash = '\0';
        char *s = line;
        while (isspace((unsigned char)*s)) s++;
        if (!*s) continue;
        if (strncmp(s, "up", 2) == 0 && isspace((unsigned char)s[2])) {
            float u[3];
            if (numbers(s + 2, u, 3) != 3) {
                rc = ct_fail(err, CT_EPARSE, "%s:%d: expected 'up ux uy uz'", origin, lineno);
                break;
            }
            up = v3(u[0], u[1], u[2]);
            up_line = lineno;
            continue;
        }
        campath_key k;
        float f[8];
        int got = numbers(s, f, 8);
        if (got != 7 && got != 8) {
            rc = ct_fail(err, CT_EPARSE,
                         "%s:%d: expected 't ex ey ez tx ty tz [fov]' (7 or 8 numbers)", origin, lineno);
            break;
        }
        k.t = f[0];
        k.eye = v3(f[1], f[2], f[3]);
        k.target = v3(f[4], f[5], f[6]);
        k.fov_deg = got == 8 ? f[7] : 45.0f;
        if (n >= CAMPATH_MAX_KEYS) {
            rc = ct_fail(err, CT_ERANGE, "%s: more than %d keyframes", origin, CAMPATH_MAX_KEYS);
            break;
        }
        if (n == cap) {
            cap = cap ? cap * 2 : 16;
            campath_key *q = realloc(keys, (size_t)cap * sizeof *keys);
            if (q) keys = q;
            int *ql = q ? realloc(lines, (size_t)cap * sizeof *lines) : NULL;
            if (ql) lines = ql;
            if (!q || !ql) { rc = ct_fail(err, CT_ENOMEM, "%s: out of memory", origin); break; }
        }
        lines[n] = lineno;
        keys[n++] = k;
    }
    if (rc == CT_OK) rc = validate(keys, n, up, origin, lines, up_line, err);
    if (rc == CT_OK) rc = campath_from_keys(keys, n, up, origin, out, err);
    free(keys);
    free(lines);
    return rc;
}

int campath_load(const char *path, ct_campath *out, ct_error *err)
{
    char *text;
    size_t len;
    int rc = fs_read_all(path, CAMPATH_MAX_BYTES, &text, &len, err);
    if (rc) return rc;
    /* a NUL would end the text early: what follows it would go unread */
    if (memchr(text, '\0', len)) {
        free(text);
        return ct_fail(err, CT_EPARSE, "%s: contains a NUL byte (not a text file?)", path);
    }
    rc = campath_parse(text, path, out, err);
    free(text);
    return rc;
}

void campath_write(const ct_campath *p, FILE *f)
{
    /* A name from a scene file may hold a line break: it would end the
     * comment, and the rest of the name would be read as a keyframe. */
    char name[sizeof p->name];
    size_t n = 0;
    for (; p->name[n] && n + 1 < sizeof name; n++) {
        unsigned char c = (unsigned char)p->name[n];
        name[n] = c < 0x20 || c == 0x7f ? '?' : (char)c;
    }
    name[n] = '\0';
    fprintf(f, "# corrtex camera path '%s': t  eye(x y z)  target(x y z)  fov_deg\n", name);
    /* %.9g: every keyframe comes back bit for bit, so a path of a scene
     * written out plays the frames the scene's own path plays. */
    fprintf(f, "up %.9g %.9g %.9g\n", (double)p->up.x, (double)p->up.y, (double)p->up.z);
    for (int i = 0; i < p->nkeys; i++) {
        const campath_key *k = &p->keys[i];
        fprintf(f, "%.9g  %.9g %.9g %.9g  %.9g %.9g %.9g  %.9g\n", (double)k->t, (double)k->eye.x,
                (double)k->eye.y, (double)k->eye.z, (double)k->target.x, (double)k->target.y,
                (double)k->target.z, (double)k->fov_deg);
    }
}

int campath_save(const ct_campath *p, const char *path, ct_error *err)
{
    fs_atomic a;
    int rc = fs_atomic_open(&a, path, err);
    if (rc) return rc;
    campath_write(p, a.f);
    return fs_atomic_commit(&a, err);
}

float campath_duration(const ct_campath *p)
{
    return p->nkeys > 0 ? p->keys[p->nkeys - 1].t - p->keys[0].t : 0.0f;
}

/* Catmull-Rom on a non-uniform time grid: tangents are finite differences
 * over the neighbouring keys' times (cardinal spline, tension 0), so the
 * camera's velocity is continuous at every keyframe. */
static vec3 spline(const campath_key *k, int n, int i, float u)
{
    int i0 = i > 0 ? i - 1 : i, i2 = i + 1, i3 = i + 2 < n ? i + 2 : i + 1;
    vec3 p1 = k[i].eye, p2 = k[i2].eye;
    float dt = k[i2].t - k[i].t;
    vec3 m1 = i0 == i ? v3_sub(p2, p1)
                      : v3_scale(v3_sub(p2, k[i0].eye), dt / (k[i2].t - k[i0].t));
    vec3 m2 = i3 == i2 ? v3_sub(p2, p1)
                       : v3_scale(v3_sub(k[i3].eye, p1), dt / (k[i3].t - k[i].t));
    float u2 = u * u, u3 = u2 * u;
    float h00 = 2 * u3 - 3 * u2 + 1, h10 = u3 - 2 * u2 + u, h01 = -2 * u3 + 3 * u2, h11 = u3 - u2;
    return v3_add(v3_add(v3_scale(p1, h00), v3_scale(m1, h10)),
                  v3_add(v3_scale(p2, h01), v3_scale(m2, h11)));
}

ct_camera campath_eval(const ct_campath *p, float t)
{
    if (p->nkeys == 1 || t <= p->keys[0].t) return p->cams[0];
    if (t >= p->keys[p->nkeys - 1].t) return p->cams[p->nkeys - 1];
    int lo = 0, hi = p->nkeys - 1;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (p->keys[mid].t <= t) lo = mid; else hi = mid;
    }
    float u = (t - p->keys[lo].t) / (p->keys[lo + 1].t - p->keys[lo].t);
    ct_camera c = cam_lerp(&p->cams[lo], &p->cams[lo + 1], u);
    /* The spline overshoots its keys by up to about half their spread: keep
     * the eye in the range a master accepts in a CAMERA. */
    c.eye = v3_clamp_range(spline(p->keys, p->nkeys, lo, u));
    return c;
}

ct_camera campath_frame(const ct_campath *p, int k, int n)
{
    if (n <= 1) return p->cams[0];
    float t0 = p->keys[0].t;
    /* In double: duration * k alone may pass FLT_MAX. */
    return campath_eval(p, (float)((double)t0 + (double)campath_duration(p) * k / (n - 1)));
}

void campath_free(ct_campath *p)
{
    free(p->keys);
    free(p->cams);
    memset(p, 0, sizeof *p);
}

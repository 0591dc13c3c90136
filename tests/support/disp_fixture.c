#include "tests/support/disp_fixture.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/scene.h"

static int add_grid(ct_scene *s, vec3 o, vec3 u, vec3 v, int grid, ct_error *err)
{
    vec3 n = v3_norm(v3_cross(u, v));
    uint32_t base = s->nverts;
    for (int j = 0; j <= grid; j++)
        for (int i = 0; i <= grid; i++) {
            vec3 p = v3_add(o, v3_add(v3_scale(u, (float)i / (float)grid), v3_scale(v, (float)j / (float)grid)));
            if (scene_add_vertex(s, p, n, err) < 0) return CT_EINVAL;
        }
    for (int j = 0; j < grid; j++)
        for (int i = 0; i < grid; i++) {
            uint32_t a = base + (uint32_t)(j * (grid + 1) + i);
            uint32_t q[4] = {a, a + 1, a + 1 + (uint32_t)(grid + 1), a + (uint32_t)(grid + 1)};
            int rc = scene_add_polygon(s, q, 4, err);
            if (rc) return rc;
        }
    return CT_OK;
}

static int part(ct_scene *s, const char *name, uint32_t mat, uint32_t *id, ct_error *err)
{
    int n = scene_begin_node(s, name, SCENE_NODE_PART, mat, err);
    if (n < 0) return n;
    *id = (uint32_t)n;
    return CT_OK;
}

static float hash01(uint32_t h)
{
    h ^= h >> 16;
    h *= 0x7feb352du;
    h ^= h >> 15;
    h *= 0x846ca68bu;
    h ^= h >> 16;
    return (float)(h & 0xffffu) / 65535.0f;
}

static vec3 pos_colour(vec3 p)
{
    int32_t x = (int32_t)lroundf(p.x * 1000.0f), y = (int32_t)lroundf(p.y * 1000.0f),
            z = (int32_t)lroundf(p.z * 1000.0f);
    uint32_t h = (uint32_t)x * 73856093u ^ (uint32_t)y * 19349663u ^ (uint32_t)z * 83492791u;
    return v3(0.05f + 0.9f * hash01(h), 0.05f + 0.9f * hash01(h + 1), 0.05f + 0.9f * hash01(h + 2));
}

int fx_box_mesh(int grid, ct_radmesh *m, fx_box_nodes *nodes, ct_error *err)
{
    ct_scene *s = scene_new("box");
    if (!s) return ct_fail(err, CT_ENOMEM, "out of memory");
    scene_material white = scene_material_default("white"), red = scene_material_default("red"),
                   green = scene_material_default("green"), light = scene_material_default("light");
    white.diffuse = v3(0.7f, 0.7f, 0.7f);
    red.diffuse = v3(0.7f, 0.1f, 0.1f);
    green.diffuse = v3(0.1f, 0.7f, 0.1f);
    light.emission = v3(5, 5, 5);
    int mw = scene_add_material(s, &white, err), mr = scene_add_material(s, &red, err),
        mg = scene_add_material(s, &green, err), ml = scene_add_material(s, &light, err);
    int rc = (mw < 0 || mr < 0 || mg < 0 || ml < 0) ? CT_EINVAL : CT_OK;
    fx_box_nodes nd;
    nd.root = 0;
    int room = rc ? -1 : scene_begin_node(s, "room", SCENE_NODE_GROUP, UINT32_MAX, err);
    if (room < 0) rc = CT_EINVAL;
    nd.room = (uint32_t)room;
#define PART(name, mat, field, o, u, v, g)                                   \
    if (!rc) rc = part(s, name, (uint32_t)(mat), &nd.field, err);            \
    if (!rc) rc = add_grid(s, o, u, v, g, err);                              \
    if (!rc) rc = scene_end_node(s, err);
    PART("back", mw, back, v3(-1, -1, -1), v3(2, 0, 0), v3(0, 2, 0), grid)
    PART("floor", mw, floor, v3(-1, -1, 1), v3(2, 0, 0), v3(0, 0, -2), grid)
    PART("ceiling", mw, ceiling, v3(-1, 1, -1), v3(2, 0, 0), v3(0, 0, 2), grid)
    PART("left", mr, left, v3(-1, -1, 1), v3(0, 0, -2), v3(0, 2, 0), grid)
    PART("right", mg, right, v3(1, -1, -1), v3(0, 0, 2), v3(0, 2, 0), grid)
    if (!rc) rc = scene_end_node(s, err);   /* room */
    PART("light", ml, light, v3(-0.3f, 0.95f, -0.3f), v3(0.6f, 0, 0), v3(0, 0, 0.6f), 1)
    if (!rc) rc = part(s, "block", (uint32_t)mw, &nd.block, err);
    if (!rc) {
        vec3 lo = v3(-0.6f, -1.0f, -0.5f), hi = v3(0.0f, -0.2f, 0.1f), e = v3_sub(hi, lo);
        rc = add_grid(s, v3(lo.x, lo.y, hi.z), v3(e.x, 0, 0), v3(0, e.y, 0), 2, err);       /* front */
        if (!rc) rc = add_grid(s, v3(lo.x, hi.y, hi.z), v3(e.x, 0, 0), v3(0, 0, -e.z), 2, err); /* top */
        if (!rc) rc = add_grid(s, v3(hi.x, lo.y, hi.z), v3(0, 0, -e.z), v3(0, e.y, 0), 2, err); /* right */
        if (!rc) rc = add_grid(s, v3(lo.x, lo.y, lo.z), v3(0, 0, e.z), v3(0, e.y, 0), 2, err);  /* left */
        if (!rc) rc = add_grid(s, v3(hi.x, lo.y, lo.z), v3(-e.x, 0, 0), v3(0, e.y, 0), 2, err); /* back */
        if (!rc) rc = scene_end_node(s, err);
    }
#undef PART
    if (!rc) rc = scene_finalize(s, err);
    if (!rc) rc = rmesh_from_scene(s, v3s(0.5f), m, err);
    scene_free(s);
    if (rc) return rc;
    for (uint32_t v = 0; v < m->nverts; v++) m->rad[v] = pos_colour(m->pos[v]);
    if (nodes) *nodes = nd;
    return CT_OK;
}

ct_camera fx_box_camera(void)
{
    return cam_look_at(v3(0.15f, 0.1f, 3.2f), v3(0, -0.05f, 0), v3(0, 1, 0), 50.0f);
}

/* --- reference rasteriser ------------------------------------------------ */

int fx_rasterise(const ct_radmesh *m, const ct_camera *cam, int width, int height, fx_ref *out)
{
    memset(out, 0, sizeof *out);
    int gw = 2 * width + 1, gh = 2 * height + 1;
    size_t ng = (size_t)gw * (size_t)gh, np = (size_t)width * (size_t)height;
    float *zbuf = malloc(ng * sizeof *zbuf);
    int32_t *tri = malloc(ng * sizeof *tri);
    float *bary = malloc(ng * 3 * sizeof *bary);
    out->width = width;
    out->height = height;
    out->rgb = calloc(np * 3, sizeof *out->rgb);
    out->world = calloc(np * 3, sizeof *out->world);
    out->node = malloc(np * sizeof *out->node);
    out->smooth = calloc(np, sizeof *out->smooth);
    if (!zbuf || !tri || !bary || !out->rgb || !out->world || !out->node || !out->smooth) {
        free(zbuf); free(tri); free(bary);
        fx_ref_free(out);
        return CT_ENOMEM;
    }
    for (size_t i = 0; i < ng; i++) {
        zbuf[i] = INFINITY;
        tri[i] = -1;
    }
    for (uint32_t t = 0; t < m->ntris; t++) {
        float px[3], py[3], z[3];
        bool ok = true;
        for (int k = 0; k < 3; k++)
            ok = ok && cam_project(cam, width, height, m->pos[m->tris[3 * t + (uint32_t)k]], &px[k], &py[k], &z[k]);
        if (!ok) continue;
        double area = ((double)px[1] - px[0]) * ((double)py[2] - py[0]) - ((double)px[2] - px[0]) * ((double)py[1] - py[0]);
        if (fabs(area) < 1e-12) continue;
        int x0 = (int)floorf(2 * fminf(px[0], fminf(px[1], px[2]))) - 1;
        int x1 = (int)ceilf(2 * fmaxf(px[0], fmaxf(px[1], px[2]))) + 1;
        int y0 = (int)floorf(2 * fminf(py[0], fminf(py[1], py[2]))) - 1;
        int y1 = (int)ceilf(2 * fmaxf(py[0], fmaxf(py[1], py[2]))) + 1;
        if (x0 < 0) x0 = 0;
        if (y0 < 0) y0 = 0;
        if (x1 > gw - 1) x1 = gw - 1;
        if (y1 > gh - 1) y1 = gh - 1;
        for (int gy = y0; gy <= y1; gy++)
            for (int gx = x0; gx <= x1; gx++) {
                double qx = 0.5 * gx, qy = 0.5 * gy, l[3];
                for (int k = 0; k < 3; k++) {
                    int a = (k + 1) % 3, b = (k + 2) % 3;
                    l[k] = (((double)px[b] - px[a]) * (qy - py[a]) - ((double)py[b] - py[a]) * (qx - px[a])) / area;
                }
                if (l[0] < -1e-9 || l[1] < -1e-9 || l[2] < -1e-9) continue;
                /* Perspective-correct barycentrics, as GL interpolates. */
                double w[3], sw = 0;
                for (int k = 0; k < 3; k++) sw += (w[k] = l[k] / z[k]);
                double depth = 1.0 / sw;
                size_t g = (size_t)gy * (size_t)gw + (size_t)gx;
                if (depth < zbuf[g]) {
                    zbuf[g] = (float)depth;
                    tri[g] = (int32_t)t;
                    for (int k = 0; k < 3; k++) bary[3 * g + (size_t)k] = (float)(w[k] / sw);
                }
            }
    }
    for (int j = 0; j < height; j++)
        for (int i = 0; i < width; i++) {
            size_t p = (size_t)j * (size_t)width + (size_t)i;
            size_t g = (size_t)(2 * j + 1) * (size_t)gw + (size_t)(2 * i + 1);
            int32_t t = tri[g];
            out->node[p] = t < 0 ? -1 : (int32_t)m->tri_node[t];
            bool smooth = true;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int32_t tn = tri[g + (size_t)((ptrdiff_t)dy * gw + dx)];
                    int32_t nn = tn < 0 ? -1 : (int32_t)m->tri_node[tn];
                    if (nn != out->node[p]) smooth = false;
                }
            out->smooth[p] = smooth;
            if (t < 0) continue;
            vec3 c = v3s(0), w = v3s(0);
            for (int k = 0; k < 3; k++) {
                uint32_t v = m->tris[3 * (uint32_t)t + (uint32_t)k];
                float b = bary[3 * g + (size_t)k];
                c = v3_madd(c, m->rad[v], b);
                w = v3_madd(w, m->pos[v], b);
            }
            out->rgb[3 * p] = c.x; out->rgb[3 * p + 1] = c.y; out->rgb[3 * p + 2] = c.z;
            out->world[3 * p] = w.x; out->world[3 * p + 1] = w.y; out->world[3 * p + 2] = w.z;
        }
    free(zbuf);
    free(tri);
    free(bary);
    return CT_OK;
}

void fx_ref_free(fx_ref *r)
{
    free(r->rgb);
    free(r->world);
    free(r->node);
    free(r->smooth);
    memset(r, 0, sizeof *r);
}

int fx_box_reference(int width, int height, ct_radmesh *m, fx_box_nodes *nodes, ct_camera *cam, fx_ref *ref,
                     ct_error *err)
{
    int rc = fx_box_mesh(4, m, nodes, err);
    if (rc) return rc;
    *cam = fx_box_camera();
    if (fx_rasterise(m, cam, width, height, ref) != 0) {
        rmesh_free(m);
        return ct_fail(err, CT_ENOMEM, "out of memory rasterising the box at %dx%d", width, height);
    }
    return CT_OK;
}

/* --- rendering in a child ------------------------------------------------- */

typedef struct child_head {
    int rc;
    char msg[256];
} child_head;

static int write_all(int fd, const void *p, size_t n)
{
    const char *c = p;
    while (n) {
        ssize_t k = write(fd, c, n);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) return -1;
        c += k;
        n -= (size_t)k;
    }
    return 0;
}

static int read_all(int fd, void *p, size_t n)
{
    char *c = p;
    while (n) {
        ssize_t k = read(fd, c, n);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) return -1;
        c += k;
        n -= (size_t)k;
    }
    return 0;
}

static void child(int fd, gl_backend_kind kind, int width, int height, const ct_camera *cam,
                  const disp_render_opts *o, int samples, int frames, fx_setup_fn setup, void *ctx)
{
    child_head h;
    memset(&h, 0, sizeof h);
    ct_error err;
    ct_error_clear(&err);
    gl_backend *b = NULL;
    disp_session *s = NULL;
    disp_compositor *c = NULL;
    size_t np = (size_t)width * (size_t)height;
    float *lin = malloc(np * 3 * sizeof *lin);
    uint8_t *disp = malloc(np * 3);
    int rc = lin && disp ? CT_OK : CT_ENOMEM;
    if (!rc) rc = gl_backend_open(kind, width, height, "corrtex test", false, &b, &err);
    if (!rc) rc = disp_session_new(&s, &err);
    if (!rc && setup) rc = setup(s, ctx, &err);
    if (!rc) rc = disp_compositor_new(width, height, 0, samples, &c, &err);
    for (int k = 0; k < frames && !rc; k++)
        rc = disp_compositor_render(c, disp_session_scene_of(s), disp_session_textures(s), cam, o, NULL, &err);
    bool win = b && gl_backend_is_window(b);
    if (!rc) rc = disp_compositor_present(c, o, win, width, height, &err);
    if (!rc) {
        disp_compositor_read_linear(c, lin);
        if (win) disp_compositor_read_window(width, height, disp);
        else disp_compositor_read_display(c, disp);
    }
    h.rc = rc;
    snprintf(h.msg, sizeof h.msg, "%s", err.msg);
    write_all(fd, &h, sizeof h);
    if (!rc) {
        write_all(fd, lin, np * 3 * sizeof *lin);
        write_all(fd, disp, np * 3);
    }
    disp_compositor_free(c);
    disp_session_free(s);
    gl_backend_close(b);
    free(lin);
    free(disp);
    close(fd);
}

int fx_render(gl_backend_kind kind, int width, int height, const ct_camera *cam,
              const disp_render_opts *o, fx_setup_fn setup, void *ctx, fx_frame *out, char *msg,
              size_t msgcap)
{
    return fx_render_frames(kind, width, height, cam, o, 1, setup, ctx, out, msg, msgcap);
}

int fx_render_frames(gl_backend_kind kind, int width, int height, const ct_camera *cam,
                     const disp_render_opts *o, int frames, fx_setup_fn setup, void *ctx, fx_frame *out,
                     char *msg, size_t msgcap)
{
    return fx_render_ms(kind, width, height, cam, o, 1, frames, setup, ctx, out, msg, msgcap);
}

int fx_render_ms(gl_backend_kind kind, int width, int height, const ct_camera *cam, const disp_render_opts *o,
                 int samples, int frames, fx_setup_fn setup, void *ctx, fx_frame *out, char *msg, size_t msgcap)
{
    memset(out, 0, sizeof *out);
    int fds[2];
    if (pipe(fds)) {
        snprintf(msg, msgcap, "pipe: %s", strerror(errno));
        return -1;
    }
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) {
        snprintf(msg, msgcap, "fork: %s", strerror(errno));
        return -1;
    }
    if (pid == 0) {
        close(fds[0]);
        child(fds[1], kind, width, height, cam, o, samples, frames, setup, ctx);
        _exit(0);
    }
    close(fds[1]);
    child_head h;
    size_t np = (size_t)width * (size_t)height;
    int rc = -1;
    if (read_all(fds[0], &h, sizeof h)) {
        snprintf(msg, msgcap, "%s child died before reporting", gl_backend_name(kind));
    } else if (h.rc) {
        snprintf(msg, msgcap, "%s", h.msg);
    } else {
        out->width = width;
        out->height = height;
        out->linear = malloc(np * 3 * sizeof *out->linear);
        out->display = malloc(np * 3);
        if (out->linear && out->display && !read_all(fds[0], out->linear, np * 3 * sizeof *out->linear) &&
            !read_all(fds[0], out->display, np * 3))
            rc = 0;
        else
            snprintf(msg, msgcap, "%s child: short image", gl_backend_name(kind));
    }
    close(fds[0]);
    int st;
    waitpid(pid, &st, 0);
    if (rc) fx_frame_free(out);
    return rc;
}

void fx_frame_free(fx_frame *f)
{
    free(f->linear);
    free(f->display);
    memset(f, 0, sizeof *f);
}

pid_t fx_xvfb_start(char *msg, size_t msgcap)
{
    int fds[2];
    if (pipe(fds)) {
        snprintf(msg, msgcap, "pipe: %s", strerror(errno));
        return -1;
    }
    pid_t pid = fork();
    if (pid < 0) {
        snprintf(msg, msgcap, "fork: %s", strerror(errno));
        return -1;
    }
    if (pid == 0) {
        close(fds[0]);
        char fd[16];
        snprintf(fd, sizeof fd, "%d", fds[1]);
        int devnull = open("/dev/null", O_WRONLY);
        if (devnull >= 0) {
            dup2(devnull, 1);
            dup2(devnull, 2);
        }
        execlp("Xvfb", "Xvfb", "-displayfd", fd, "-screen", "0", "640x480x24", "-nolisten", "tcp",
               "+extension", "GLX", (char *)NULL);
        _exit(127);
    }
    close(fds[1]);
    char buf[32] = "";
    size_t got = 0;
    struct pollfd p = {fds[0], POLLIN, 0};
    while (got < sizeof buf - 1 && poll(&p, 1, 10000) > 0) {
        ssize_t k = read(fds[0], buf + got, sizeof buf - 1 - got);
        if (k <= 0) break;
        got += (size_t)k;
        if (memchr(buf, '\n', got)) break;
    }
    close(fds[0]);
    buf[got] = '\0';
    int num = -1;
    if (sscanf(buf, "%d", &num) != 1) {
        snprintf(msg, msgcap, "Xvfb did not report a display number (is xvfb installed?)");
        fx_xvfb_stop(pid);
        return -1;
    }
    char d[32];
    snprintf(d, sizeof d, ":%d", num);
    setenv("DISPLAY", d, 1);
    return pid;
}

void fx_xvfb_stop(pid_t pid)
{
    if (pid <= 0) return;
    kill(pid, SIGTERM);
    int st;
    waitpid(pid, &st, 0);
}

void fx_diff(const float *a, const float *b, size_t n, double *max, double *mean)
{
    double mx = 0, sum = 0;
    for (size_t i = 0; i < n; i++) {
        double d = fabs((double)a[i] - (double)b[i]);
        if (d > mx) mx = d;
        sum += d;
    }
    *max = mx;
    *mean = n ? sum / (double)n : 0;
}

uint16_t fx_half(float f)
{
    if (f == 0.0f) return 0;
    uint16_t sign = f < 0 ? 0x8000u : 0;
    float a = fabsf(f);
    int e;
    float m = frexpf(a, &e);   /* a = m * 2^e, m in [0.5, 1) */
    int he = e - 1 + 15;       /* a = (2m) * 2^(e-1) */
    if (he <= 0) {
        /* Below the smallest normal half: a multiple of 2^-24. */
        long sub = lroundf(a * 16777216.0f);
        return (uint16_t)(sign | (uint16_t)(sub > 1023 ? 1024 : sub));
    }
    if (he >= 31) return (uint16_t)(sign | 0x7c00u);   /* too large: infinity */
    uint32_t mant = (uint32_t)lroundf((2.0f * m - 1.0f) * 1024.0f);
    /* Rounding up may carry into the exponent: still the right bits. */
    return (uint16_t)(sign | (uint16_t)(((uint32_t)he << 10) + mant));
}

static vec3 texel(const float *rgb, int w, int h, int x, int y)
{
    x = x < 0 ? 0 : (x >= w ? w - 1 : x);
    y = y < 0 ? 0 : (y >= h ? h - 1 : y);
    const float *p = rgb + 3 * ((size_t)y * (size_t)w + (size_t)x);
    return v3(p[0], p[1], p[2]);
}

vec3 fx_bilinear(const float *rgb, int w, int h, float s, float t)
{
    float u = s * (float)w - 0.5f, v = t * (float)h - 0.5f;
    int x0 = (int)floorf(u), y0 = (int)floorf(v);
    float fu = u - (float)x0, fv = v - (float)y0;
    vec3 a = v3_lerp(texel(rgb, w, h, x0, y0), texel(rgb, w, h, x0 + 1, y0), fu);
    vec3 b = v3_lerp(texel(rgb, w, h, x0, y0 + 1), texel(rgb, w, h, x0 + 1, y0 + 1), fu);
    return v3_lerp(a, b, fv);
}


int fx_render_session(disp_session *s, int width, int height, uint8_t *out, ct_error *err)
{
    disp_compositor *c = NULL;
    int rc = disp_compositor_new(width, height, 0, 1, &c, err);
    if (rc) return rc;
    ct_camera cam = fx_box_camera();
    disp_render_opts o = {1, DISP_VIEW_FULL, 0.0f, false, false, DISP_KEPT_AUTO};
    rc = disp_compositor_render(c, disp_session_scene_of(s), disp_session_textures(s), &cam, &o, NULL, err);
    if (!rc) rc = disp_compositor_present(c, &o, false, width, height, err);
    if (!rc) disp_compositor_read_display(c, out);
    disp_compositor_free(c);
    return rc;
}

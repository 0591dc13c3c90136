#include "display/disp_session.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Points of the last frames, oldest first, each tagged with the number of
 * frame ends before it arrived. */
typedef struct pts {
    float *v;
    uint32_t *tag;
    uint32_t n, cap;
    int dim;
} pts;

static void pts_free(pts *p)
{
    free(p->v);
    free(p->tag);
    p->v = NULL;
    p->tag = NULL;
    p->n = p->cap = 0;
}

static void pts_drop(pts *p, uint32_t k)
{
    size_t d = (size_t)p->dim;
    memmove(p->v, p->v + d * k, d * (size_t)(p->n - k) * sizeof *p->v);
    memmove(p->tag, p->tag + k, (size_t)(p->n - k) * sizeof *p->tag);
    p->n -= k;
}

/* Appends n points (dim floats each) tagged `tag`, keeping at most
 * DISP_SAMPLE_MAX (the oldest go first). Out of memory: keeps what it has
 * (the views that show them are debugging aids). */
static void pts_push(pts *p, const float *v, uint32_t n, uint32_t tag)
{
    size_t d = (size_t)p->dim;
    if (n > DISP_SAMPLE_MAX) {
        v += d * (size_t)(n - DISP_SAMPLE_MAX);
        n = DISP_SAMPLE_MAX;
    }
    if (p->n + n > DISP_SAMPLE_MAX) pts_drop(p, p->n + n - DISP_SAMPLE_MAX);
    if (p->n + n > p->cap) {
        uint32_t cap = p->cap ? p->cap : 4096;
        while (cap < p->n + n) cap *= 2;
        float *a = realloc(p->v, d * (size_t)cap * sizeof *a);
        if (a) p->v = a;
        uint32_t *t = realloc(p->tag, (size_t)cap * sizeof *t);
        if (t) p->tag = t;
        if (!a || !t) return;
        p->cap = cap;
    }
    memcpy(p->v + d * (size_t)p->n, v, d * (size_t)n * sizeof *v);
    for (uint32_t i = 0; i < n; i++) p->tag[p->n + i] = tag;
    p->n += n;
}

/* Drops the points tagged before keep_from. */
static void pts_trim(pts *p, uint32_t keep_from)
{
    uint32_t k = 0;
    while (k < p->n && p->tag[k] < keep_from) k++;
    if (k) pts_drop(p, k);
}

struct disp_session;
static void patch_point(struct disp_session *s, uint32_t id, int x, int y, int w, int h);

struct disp_session {
    disp_scene *scene;
    disp_textures *tex;
    bool all_positive;
    bool samples_from_stats;   /* stats carry the sample total: do not count positions */
    disp_counters cnt;
    pts xy;                    /* sample image positions (2 floats) */
    pts wp;                    /* patch centres in world space (3 floats) */
};

int disp_session_new(disp_session **out, ct_error *err)
{
    disp_session *s = calloc(1, sizeof *s);
    if (!s) return ct_fail(err, CT_ENOMEM, "out of memory for a display session");
    s->xy.dim = 2;
    s->wp.dim = 3;
    int rc = disp_textures_new(&s->tex, err);
    if (rc) {
        free(s);
        return rc;
    }
    *out = s;
    return CT_OK;
}

void disp_session_free(disp_session *s)
{
    if (!s) return;
    disp_textures_free(s->tex);
    disp_scene_free(s->scene);
    pts_free(&s->xy);
    pts_free(&s->wp);
    free(s);
}

int disp_session_scene(disp_session *s, const ct_radmesh *m, ct_error *err)
{
    disp_scene *n = NULL;
    int rc = disp_scene_new(m, &n, err);
    if (rc) return rc;
    disp_textures_clear(s->tex);
    disp_scene_free(s->scene);
    s->scene = n;
    s->xy.n = 0;
    s->wp.n = 0;
    return CT_OK;
}

int disp_session_tex_alloc(disp_session *s, uint32_t id, uint32_t node, int width, int height,
                           disp_proj_kind kind, ct_error *err)
{
    if (!s->scene) return ct_fail(err, CT_EPROTO, "texture %u allocated before any scene", id);
    uint32_t b, e;
    int rc = disp_scene_node_range(s->scene, node, &b, &e, err);
    if (rc) {
        ct_error_prefix(err, "texture allocation");
        return rc;
    }
    if (kind != DISP_PROJ_OBJECT_PARALLEL && kind != DISP_PROJ_CAMERA_PERSPECTIVE)
        return ct_fail(err, CT_EPROTO, "texture %u: unknown projection kind %d", id, (int)kind);
    return disp_textures_alloc(s->tex, id, node, b, e, width, height, kind, err);
}

int disp_session_tex_projection(disp_session *s, uint32_t id, const mat4 *world_to_tex,
                                ct_error *err)
{
    return disp_textures_set_projection(s->tex, id, world_to_tex, err);
}

int disp_session_tex_patch(disp_session *s, uint32_t id, int x, int y, int w, int h,
                           const uint16_t *rgb, ct_error *err)
{
    int rc = disp_textures_patch_half(s->tex, id, x, y, w, h, rgb, err);
    if (!rc) {
        s->cnt.texels += (uint64_t)w * (uint64_t)h;
        s->cnt.patches++;
        patch_point(s, id, x, y, w, h);
    }
    return rc;
}

int disp_session_tex_patch_float(disp_session *s, uint32_t id, int x, int y, int w, int h,
                                 const float *rgb, ct_error *err)
{
    int rc = disp_textures_patch_float(s->tex, id, x, y, w, h, rgb, err);
    if (!rc) {
        s->cnt.texels += (uint64_t)w * (uint64_t)h;
        s->cnt.patches++;
        patch_point(s, id, x, y, w, h);
    }
    return rc;
}

int disp_session_tex_free(disp_session *s, uint32_t id, ct_error *err)
{
    return disp_textures_release(s->tex, id, err);
}

void disp_session_samples(disp_session *s, const float *xy, uint32_t n)
{
    pts_push(&s->xy, xy, n, s->cnt.frames);
}

void disp_session_frame_end(disp_session *s, uint32_t frame, uint32_t samples, bool all_positive)
{
    if (!s->samples_from_stats) s->cnt.samples += samples;
    s->cnt.frame_samples += samples;
    s->all_positive = all_positive;
    s->cnt.frames++;
    s->cnt.last_frame = frame;
    /* Points carry the number of frame ends before them: frame f's are
     * tagged f. Keep frames cnt.frames - DISP_SAMPLE_FRAMES .. and the one
     * in progress. */
    uint32_t keep_from = s->cnt.frames > DISP_SAMPLE_FRAMES ? s->cnt.frames - DISP_SAMPLE_FRAMES : 0;
    pts_trim(&s->xy, keep_from);
    pts_trim(&s->wp, keep_from);
}

void disp_session_stats(disp_session *s, uint64_t samples_total, bool all_positive)
{
    s->samples_from_stats = true;
    s->cnt.samples = samples_total;
    s->all_positive = all_positive;
}

void disp_session_add_bytes(disp_session *s, uint64_t n) { s->cnt.bytes += n; }

const disp_scene *disp_session_scene_of(const disp_session *s) { return s->scene; }
const disp_textures *disp_session_textures(const disp_session *s) { return s->tex; }
bool disp_session_all_positive(const disp_session *s) { return s->all_positive; }

const float *disp_session_sample_xy(const disp_session *s, uint32_t *n)
{
    *n = s->xy.n;
    return s->xy.v;
}

const float *disp_session_patch_points(const disp_session *s, uint32_t *n)
{
    *n = s->wp.n;
    return s->wp.v;
}

/* The world point whose texture position is (u, v): M^-1 (u, v, 0, 1). For
 * an object-local projection the third row is the distance from the node's
 * plane, so this is the point on the plane; for a camera-local one it is a
 * point on the ray through (u, v), which the same camera sees at the same
 * pixel. False when M is singular. */
static bool unproject(const mat4 *m, float u, float v, vec3 *out)
{
    mat4 inv;
    if (!m4_invert(*m, &inv)) return false;
    float x = inv.m[0][0] * u + inv.m[0][1] * v + inv.m[0][3];
    float y = inv.m[1][0] * u + inv.m[1][1] * v + inv.m[1][3];
    float z = inv.m[2][0] * u + inv.m[2][1] * v + inv.m[2][3];
    float w = inv.m[3][0] * u + inv.m[3][1] * v + inv.m[3][3];
    if (!(fabsf(w) > 1e-12f)) return false;
    *out = v3(x / w, y / w, z / w);
    return v3_finite(*out);
}

/* Records the centre of a patch as a world point (the samples view shows
 * where corrections changed when no sample positions are known). */
static void patch_point(disp_session *s, uint32_t id, int x, int y, int w, int h)
{
    const disp_texture *t = disp_textures_find(s->tex, id);
    vec3 p;
    if (!t || !t->has_proj) return;
    if (!unproject(&t->proj, ((float)x + 0.5f * (float)w) / (float)t->width,
                   ((float)y + 0.5f * (float)h) / (float)t->height, &p))
        return;
    float f[3] = {p.x, p.y, p.z};
    pts_push(&s->wp, f, 1, s->cnt.frames);
}

disp_counters disp_session_counters(const disp_session *s) { return s->cnt; }

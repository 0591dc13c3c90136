#include "display/disp_session.h"

#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

/* Sample points of the last frames: a ring buffer of world points (3 floats)
 * in arrival order, each tagged with the number of frames drawn before it
 * arrived. It grows on demand up to `max` points; beyond that the oldest
 * are overwritten. */
typedef struct ring {
    float *v;
    uint32_t *tag;
    uint32_t cap, head, n;
} ring;

static void ring_free(ring *r)
{
    free(r->v);
    free(r->tag);
    memset(r, 0, sizeof *r);
}

static void ring_drop(ring *r, uint32_t k)
{
    if (k > r->n) k = r->n;
    r->head = r->cap ? (r->head + k) % r->cap : 0;
    r->n -= k;
    if (!r->n) r->head = 0;
}

/* Makes room for want (<= max) points in order (unwrapping the ring),
 * doubling up to max; false without memory. */
static bool ring_reserve(ring *r, uint32_t want, uint32_t max)
{
    if (want <= r->cap) return true;
    uint32_t cap = r->cap ? r->cap : 4096;
    while (cap < want) cap = cap > UINT32_MAX / 2 ? want : 2 * cap;
    if (cap > max) cap = max > want ? max : want;
    float *v = malloc((size_t)cap * 3 * sizeof *v);
    uint32_t *t = malloc((size_t)cap * sizeof *t);
    if (!v || !t) {
        free(v);
        free(t);
        return false;
    }
    for (uint32_t i = 0; i < r->n; i++) {
        uint32_t k = (r->head + i) % r->cap;
        memcpy(v + 3 * (size_t)i, r->v + 3 * (size_t)k, 3 * sizeof *v);
        t[i] = r->tag[k];
    }
    free(r->v);
    free(r->tag);
    r->v = v;
    r->tag = t;
    r->cap = cap;
    r->head = 0;
    return true;
}

/* Appends n points tagged `tag`, keeping at most max (the oldest go first).
 * Out of memory: keeps what fits (the view that shows them is a debugging
 * aid). */
static void ring_push(ring *r, const float *v, uint32_t n, uint32_t tag, uint32_t max)
{
    if (n > max) {
        v += 3 * (size_t)(n - max);
        n = max;
    }
    if (!n) return;
    ring_reserve(r, r->n + n < max ? r->n + n : max, max);
    uint32_t limit = r->cap < max ? r->cap : max;
    if (n > limit) {
        v += 3 * (size_t)(n - limit);
        n = limit;
    }
    if (!n) return;
    if (r->n + n > limit) ring_drop(r, r->n + n - limit);
    for (uint32_t i = 0; i < n; i++) {
        uint32_t k = (r->head + r->n + i) % r->cap;
        memcpy(r->v + 3 * (size_t)k, v + 3 * (size_t)i, 3 * sizeof *v);
        r->tag[k] = tag;
    }
    r->n += n;
}

/* Drops the points tagged before keep_from; the number dropped. */
static uint32_t ring_trim(ring *r, uint32_t keep_from)
{
    uint32_t k = 0;
    while (k < r->n && r->tag[(r->head + k) % r->cap] < keep_from) k++;
    ring_drop(r, k);
    return k;
}

struct disp_session {
    disp_scene *scene;
    disp_textures *tex;
    bool all_positive;
    bool samples_from_stats;   /* stats carry the sample total: do not count positions */
    disp_counters cnt;
    ring pts;                  /* sample hit points of the last frames */
    uint32_t drawn;            /* frames drawn (tags of the points) */
    uint32_t keep_frames, max_points;
    uint64_t version;          /* changes whenever pts changes */
    uint64_t image_gen;        /* changes whenever what a frame shows may change */
};

int disp_session_new(disp_session **out, ct_error *err)
{
    disp_session *s = calloc(1, sizeof *s);
    if (!s) return ct_fail(err, CT_ENOMEM, "out of memory for a display session");
    s->keep_frames = DISP_SAMPLE_FRAMES;
    s->max_points = DISP_SAMPLE_MAX;
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
    ring_free(&s->pts);
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
    ring_drop(&s->pts, s->pts.n);
    s->version++;
    s->image_gen++;
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
    s->image_gen++;
    return disp_textures_alloc(s->tex, id, node, b, e, width, height, kind, err);
}

int disp_session_tex_projection(disp_session *s, uint32_t id, const mat4 *world_to_tex,
                                ct_error *err)
{
    s->image_gen++;
    return disp_textures_set_projection(s->tex, id, world_to_tex, err);
}

int disp_session_tex_patch(disp_session *s, uint32_t id, int x, int y, int w, int h,
                           const uint16_t *rgb, ct_error *err)
{
    int rc = disp_textures_patch_half(s->tex, id, x, y, w, h, rgb, err);
    if (!rc) {
        s->cnt.texels += (uint64_t)w * (uint64_t)h;
        s->cnt.patches++;
        s->image_gen++;
    }
    return rc;
}

int disp_session_tex_upload(disp_session *s, uint32_t id, int x, int y, int w, int h, size_t off, bool negative,
                            bool nonzero, ct_error *err)
{
    int rc = disp_textures_patch_pbo(s->tex, id, x, y, w, h, off, negative, nonzero, err);
    if (!rc) {
        s->cnt.texels += (uint64_t)w * (uint64_t)h;
        s->cnt.patches++;
        s->image_gen++;
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
        s->image_gen++;
    }
    return rc;
}

int disp_session_tex_free(disp_session *s, uint32_t id, ct_error *err)
{
    s->image_gen++;
    return disp_textures_release(s->tex, id, err);
}

void disp_session_set_sample_limits(disp_session *s, uint32_t frames, uint32_t max_points)
{
    s->keep_frames = frames ? frames : 1;
    s->max_points = max_points;
    if (s->pts.n > max_points) ring_drop(&s->pts, s->pts.n - max_points);
    s->version++;
    s->image_gen++;
}

void disp_session_sample_points(disp_session *s, const float *xyz, uint32_t n, uint64_t dropped)
{
    s->cnt.sample_points += n;
    s->cnt.points_dropped = dropped;
    if (!n) return;
    ring_push(&s->pts, xyz, n, s->drawn, s->max_points);
    s->version++;
    s->image_gen++;
}

void disp_session_frame_drawn(disp_session *s)
{
    s->drawn++;
    /* The next frame shows the points of the frames drawn last and its own. */
    uint32_t keep_from = s->drawn + 1 > s->keep_frames ? s->drawn + 1 - s->keep_frames : 0;
    if (ring_trim(&s->pts, keep_from)) {
        s->version++;
        s->image_gen++;   /* the samples view loses the oldest points */
    }
}

uint64_t disp_session_points(const disp_session *s, const float **a, uint32_t *na, const float **b,
                             uint32_t *nb)
{
    const ring *r = &s->pts;
    uint32_t first = r->cap - r->head < r->n ? r->cap - r->head : r->n;
    *a = r->n ? r->v + 3 * (size_t)r->head : NULL;
    *na = first;
    *b = r->n > first ? r->v : NULL;
    *nb = r->n - first;
    return s->version;
}

void disp_session_frame_end(disp_session *s, uint32_t frame, uint32_t samples, bool all_positive)
{
    if (!s->samples_from_stats) s->cnt.samples += samples;
    s->cnt.frame_samples += samples;
    if (s->all_positive != all_positive) s->image_gen++;
    s->all_positive = all_positive;
    s->cnt.frames++;
    s->cnt.last_frame = frame;
}

void disp_session_stats(disp_session *s, uint64_t samples_total, bool all_positive)
{
    s->samples_from_stats = true;
    s->cnt.samples = samples_total;
    if (s->all_positive != all_positive) s->image_gen++;
    s->all_positive = all_positive;
}

void disp_session_add_bytes(disp_session *s, uint64_t n) { s->cnt.bytes += n; }

const disp_scene *disp_session_scene_of(const disp_session *s) { return s->scene; }
const disp_textures *disp_session_textures(const disp_session *s) { return s->tex; }
bool disp_session_all_positive(const disp_session *s) { return s->all_positive; }

disp_counters disp_session_counters(const disp_session *s) { return s->cnt; }
uint64_t disp_session_image_gen(const disp_session *s) { return s->image_gen; }

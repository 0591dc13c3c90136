#include "display/disp_session.h"

#include <stdlib.h>
#include <string.h>

struct disp_session {
    disp_scene *scene;
    disp_textures *tex;
    bool all_positive;
    bool samples_from_stats;   /* stats carry the sample total: do not count positions */
    disp_counters cnt;
    float *xy;                 /* sample positions, oldest first */
    uint32_t *xy_frame;        /* frame-end count when each was received */
    uint32_t nxy, cap_xy;
};

int disp_session_new(disp_session **out, ct_error *err)
{
    disp_session *s = calloc(1, sizeof *s);
    if (!s) return ct_fail(err, CT_ENOMEM, "out of memory for a display session");
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
    free(s->xy);
    free(s->xy_frame);
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
    s->nxy = 0;
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
    }
    return rc;
}

int disp_session_tex_free(disp_session *s, uint32_t id, ct_error *err)
{
    return disp_textures_release(s->tex, id, err);
}

void disp_session_samples(disp_session *s, const float *xy, uint32_t n)
{
    if (n > DISP_SAMPLE_MAX) {
        xy += 2 * (size_t)(n - DISP_SAMPLE_MAX);
        n = DISP_SAMPLE_MAX;
    }
    if (s->nxy + n > DISP_SAMPLE_MAX) {
        /* Drop the oldest to stay under the cap. */
        uint32_t drop = s->nxy + n - DISP_SAMPLE_MAX;
        memmove(s->xy, s->xy + 2 * (size_t)drop, 2 * (size_t)(s->nxy - drop) * sizeof *s->xy);
        memmove(s->xy_frame, s->xy_frame + drop, (size_t)(s->nxy - drop) * sizeof *s->xy_frame);
        s->nxy -= drop;
    }
    if (s->nxy + n > s->cap_xy) {
        uint32_t cap = s->cap_xy ? s->cap_xy : 4096;
        while (cap < s->nxy + n) cap *= 2;
        float *a = realloc(s->xy, 2 * (size_t)cap * sizeof *a);
        if (a) s->xy = a;
        uint32_t *f = realloc(s->xy_frame, (size_t)cap * sizeof *f);
        if (f) s->xy_frame = f;
        if (!a || !f) return;   /* keep what we have: the view is a debugging aid */
        s->cap_xy = cap;
    }
    memcpy(s->xy + 2 * (size_t)s->nxy, xy, 2 * (size_t)n * sizeof *xy);
    for (uint32_t i = 0; i < n; i++) s->xy_frame[s->nxy + i] = s->cnt.frames;
    s->nxy += n;
}

void disp_session_frame_end(disp_session *s, uint32_t frame, uint32_t samples, bool all_positive)
{
    if (!s->samples_from_stats) s->cnt.samples += samples;
    s->all_positive = all_positive;
    s->cnt.frames++;
    s->cnt.last_frame = frame;
    /* Keep the positions of the last DISP_SAMPLE_FRAMES frames. */
    /* Positions carry the number of frame ends before them: frame f's are
     * tagged f. Keep frames cnt.frames - DISP_SAMPLE_FRAMES .. and the one
     * in progress. */
    uint32_t keep_from = s->cnt.frames > DISP_SAMPLE_FRAMES ? s->cnt.frames - DISP_SAMPLE_FRAMES : 0;
    uint32_t k = 0;
    while (k < s->nxy && s->xy_frame[k] < keep_from) k++;
    if (k) {
        memmove(s->xy, s->xy + 2 * (size_t)k, 2 * (size_t)(s->nxy - k) * sizeof *s->xy);
        memmove(s->xy_frame, s->xy_frame + k, (size_t)(s->nxy - k) * sizeof *s->xy_frame);
        s->nxy -= k;
    }
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
    *n = s->nxy;
    return s->xy;
}

disp_counters disp_session_counters(const disp_session *s) { return s->cnt; }

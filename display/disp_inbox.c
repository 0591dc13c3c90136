/* disp_inbox.c: the hand-over between the connection thread and the render
 * thread (disp_inbox.h). Over 600 lines on purpose: the two threads' halves
 * of one hand-over share one private struct and its lock, and are read
 * together when the locking is checked. */
#include "display/disp_inbox.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "common/bitrow.h"
#include "common/idmap.h"
#include "display/disp_rescale.h"
#include "display/gl_load.h"
#include "proto/wire.h"

/* Tiles of changed texels, as on the master (master/ctex_dirty.h): patches
 * arrive as runs of them, so uploads follow the same runs. */
#define TS_SHIFT 3
#define TS (1 << TS_SHIFT)
/* Runs of changed tiles in a row of tiles at most this many unchanged tiles
 * apart go up as one upload (the unchanged tiles' texels with them, the
 * inbox's copy holds them too): streaming table at 1024x1024, 2,200-2,600
 * uploads of 220-260 texels a frame became 1,180-1,420 of 450-510 (25 %
 * more bytes); llvmpipe drew as many frames or up to 8 % more (interleaved
 * pairs), and a GPU driver pays per call (docs/display.md, "Where a frame's
 * time goes"). Wider gaps (8, 16 tiles) carried up to 70 % more bytes and
 * the lag grew (median 90 -> 430-490 ms at 16, when the upload buffer was
 * still sized for the changed tiles alone). */
#define UPLOAD_GAP_TILES 4
/* Bytes per texel in the upload buffer: RGBA halves, the textures' own
 * format, so the driver copies instead of converting (llvmpipe converts RGB
 * to RGBA16F through floats, texel by texel). The inbox's copy stays RGB. */
#define UP_BPT 8
#define MAX_FRAMES 64

typedef struct ib_tex {
    uint32_t id, node;
    int w, h;
    disp_proj_kind kind;
    mat4 proj;
    bool proj_new;           /* a projection arrived since the last apply */
    bool live;               /* allocated (false: freed since the last apply) */
    bool fresh;              /* allocated anew since the last apply */
    bool in_gl;              /* the render thread has made its GL texture */
    bool negative, nonzero;  /* since its allocation (disp_textures.h) */
    bool dirty;              /* some tile is marked */
    uint16_t *tx;            /* w*h*3 halves, row by row */
    uint64_t *bits;          /* th rows of `words`: tiles changed since the last apply */
    int tw, th, words;
} ib_tex;

typedef struct frame_end {
    uint64_t frame;
    uint32_t samples;
    bool all_positive;
} frame_end;

/* An upload found under the lock, issued after it. */
typedef struct upload {
    uint32_t id;
    int x, y, w, h;
    size_t off;
    bool negative, nonzero;
} upload;

/* A texture operation found under the lock, issued after it. */
typedef struct texop {
    enum { OP_FREE, OP_ALLOC, OP_PROJ } kind;
    uint32_t id, node;
    int w, h;
    disp_proj_kind pk;
    mat4 m;
} texop;

struct disp_inbox {
    pthread_mutex_t mu;
    int max_tex;
    /* scene */
    ct_radmesh scene;
    bool scene_new, have_scene;
    uint32_t nnodes;
    /* textures */
    ib_tex *tex;
    uint32_t ntex, cap;
    ct_idmap ix;                   /* id -> index in tex: every message looks one up */
    uint64_t tex_bytes;            /* their CPU copies */
    size_t dirty_bytes;            /* marked for upload (an upper bound) */
    uint64_t texels_in, patches_in;
    disp_inbox_stamp *stamps;      /* patches received, not yet on a texture */
    uint32_t nstamps, cap_stamps;
    disp_inbox_stamp *taken;       /* handed to the last apply */
    uint32_t ntaken, cap_taken;
    /* points, frames, stats */
    float *pts;
    uint32_t npts, cap_pts;
    uint64_t pts_dropped;
    frame_end frames[MAX_FRAMES];
    uint32_t nframes;
    bool stats_new, stats_pos;
    uint64_t stats_total;
    /* lockstep and status */
    uint32_t epoch;
    disp_inbox_state st;
    bool frame_taken_any;
    uint64_t frame_taken;
    uint64_t bytes_applied;
    uint64_t bytes_base;   /* st.bytes when this connection began (it counts from 0) */
    /* render-thread scratch */
    texop *ops;
    uint32_t nops, cap_ops;
    upload *ups;
    uint32_t nups, cap_ups;
    unsigned pbo;
    size_t pbo_cap;        /* its storage's bytes (0: none yet) */
    size_t pbo_peak;       /* the most a take wanted in this window of takes */
    uint32_t pbo_takes;    /* takes in this window */
};

static bool grow(void **p, uint32_t *cap, uint32_t need, size_t elem)
{
    if (need <= *cap) return true;
    uint32_t n = *cap ? *cap : 64;
    while (n < need) n *= 2;
    void *q = realloc(*p, (size_t)n * elem);
    if (!q) return false;
    *p = q;
    *cap = n;
    return true;
}

int disp_inbox_new(int max_tex, disp_inbox **out, ct_error *err)
{
    disp_inbox *b = calloc(1, sizeof *b);
    if (!b) return ct_fail(err, CT_ENOMEM, "out of memory for the inbox");
    pthread_mutex_init(&b->mu, NULL);
    b->max_tex = max_tex;
    *out = b;
    return CT_OK;
}

static void tex_release(disp_inbox *b, ib_tex *t)
{
    if (t->tx) b->tex_bytes -= (uint64_t)t->w * (uint64_t)t->h * 6;
    free(t->tx);
    free(t->bits);
    t->tx = NULL;
    t->bits = NULL;
}

/* A CPU copy of w x h texels (zeroed when zero) and its tile marks, made
 * before they replace a texture's. */
typedef struct store {
    uint16_t *tx;
    uint64_t *bits;
    int w, h, tw, th, words;
} store;

static int store_new(int w, int h, bool zero, store *st, ct_error *err)
{
    st->w = w;
    st->h = h;
    st->tw = (w + TS - 1) >> TS_SHIFT;
    st->th = (h + TS - 1) >> TS_SHIFT;
    st->words = bitrow_words(st->tw);
    size_t n = (size_t)w * (size_t)h * 3;
    st->tx = zero ? calloc(n, sizeof *st->tx) : malloc(n * sizeof *st->tx);
    st->bits = calloc((size_t)st->th * (size_t)st->words, sizeof *st->bits);
    if (st->tx && st->bits) return CT_OK;
    free(st->tx);
    free(st->bits);
    return ct_fail(err, CT_ENOMEM, "out of memory for a %dx%d texture", w, h);
}

/* Puts st in place of what t held. */
static void store_attach(disp_inbox *b, ib_tex *t, const store *st)
{
    tex_release(b, t);
    t->w = st->w;
    t->h = st->h;
    t->tx = st->tx;
    t->bits = st->bits;
    t->tw = st->tw;
    t->th = st->th;
    t->words = st->words;
    b->tex_bytes += (uint64_t)st->w * (uint64_t)st->h * 6;
}

static void drop_textures(disp_inbox *b)
{
    for (uint32_t i = 0; i < b->ntex; i++) tex_release(b, &b->tex[i]);
    b->ntex = 0;
    idmap_clear(&b->ix);
    b->dirty_bytes = 0;
}

void disp_inbox_free(disp_inbox *b)
{
    if (!b) return;
    drop_textures(b);
    rmesh_free(&b->scene);
    free(b->tex);
    idmap_free(&b->ix);
    free(b->stamps);
    free(b->taken);
    free(b->pts);
    free(b->ops);
    free(b->ups);
    pthread_mutex_destroy(&b->mu);
    free(b);
}

void disp_inbox_connection(disp_inbox *b)
{
    pthread_mutex_lock(&b->mu);
    b->st.have_scene = false;
    b->st.frame_seen = false;
    b->st.have_view = false;
    b->frame_taken_any = false;
    b->epoch = 0;
    b->nframes = 0;
    /* st.bytes stays the session's total: the new connection's count
     * starts from 0, and st.bytes - bytes_applied wrapped to 3e16 bytes
     * right after a reconnection. */
    b->bytes_base = b->st.bytes;
    pthread_mutex_unlock(&b->mu);
}

/* --- the connection thread ------------------------------------------------ */

void disp_inbox_scene(disp_inbox *b, ct_radmesh *m)
{
    pthread_mutex_lock(&b->mu);
    rmesh_free(&b->scene);
    b->scene = *m;
    memset(m, 0, sizeof *m);
    b->scene_new = true;
    b->have_scene = true;
    b->st.have_scene = true;
    b->nnodes = b->scene.nnodes;
    drop_textures(b);   /* the session drops its textures with the old scene */
    b->nstamps = 0;
    pthread_mutex_unlock(&b->mu);
}

static ib_tex *find(disp_inbox *b, uint32_t id)
{
    uint32_t i = idmap_get(&b->ix, id);
    return i == IDMAP_NONE ? NULL : &b->tex[i];
}

int disp_inbox_tex_alloc(disp_inbox *b, uint32_t id, uint32_t node, int w, int h, disp_proj_kind kind,
                         ct_error *err)
{
    if (w < 1 || h < 1 || w > b->max_tex || h > b->max_tex)
        return ct_fail(err, CT_ERANGE, "texture %u: size %dx%d out of range 1..%d", id, w, h, b->max_tex);
    if (kind != DISP_PROJ_OBJECT_PARALLEL && kind != DISP_PROJ_CAMERA_PERSPECTIVE)
        return ct_fail(err, CT_EPROTO, "texture %u: unknown projection kind %d", id, (int)kind);
    int rc = CT_OK;
    pthread_mutex_lock(&b->mu);
    ib_tex *t = find(b, id);
    uint64_t bytes = (uint64_t)w * (uint64_t)h * 6;
    if (!b->have_scene) {
        rc = ct_fail(err, CT_EPROTO, "texture %u allocated before any scene", id);
    } else if (node >= b->nnodes) {
        rc = ct_fail(err, CT_EPROTO, "texture allocation: node %u out of range (%u nodes)", node, b->nnodes);
    } else if (b->tex_bytes - (t && t->tx ? (uint64_t)t->w * (uint64_t)t->h * 6 : 0) + bytes >
               DISP_INBOX_MAX_BYTES) {
        rc = ct_fail(err, CT_ENOMEM, "texture %u: %dx%d texels would pass the display's %llu MiB", id, w, h,
                     (unsigned long long)(DISP_INBOX_MAX_BYTES >> 20));
    } else if (!t && b->ntex >= 2 * b->nnodes + 1024) {
        /* The master keeps a texture per hierarchy node at most (docs/
         * textures.md); freed ones stay here until the next frame deletes
         * them. Beyond that a master only makes the display slow: every
         * message looks its texture up, every frame draws them. */
        rc = ct_fail(err, CT_ERANGE, "texture %u: more than %u textures for a scene of %u nodes", id, b->ntex,
                     b->nnodes);
    } else if (!t && !grow((void **)&b->tex, &b->cap, b->ntex + 1, sizeof *b->tex)) {
        rc = ct_fail(err, CT_ENOMEM, "out of memory for %u textures", b->ntex + 1);
    }
    store st;
    if (!rc && !(rc = store_new(w, h, true, &st, err)) && !t && (rc = idmap_put(&b->ix, id, b->ntex, err))) {
        free(st.tx);
        free(st.bits);
    }
    if (!rc) {
        if (!t) {
            t = &b->tex[b->ntex++];
            memset(t, 0, sizeof *t);
            t->id = id;
            t->proj = m4_identity();
        }
        /* A new texture's texels are zero, as its GL texture will be:
         * nothing to upload until a patch arrives. A re-allocated id keeps
         * its projection (a resize does not move it). */
        store_attach(b, t, &st);
        t->node = node;
        t->kind = kind;
        t->live = t->fresh = true;
        t->negative = t->nonzero = t->dirty = false;
    }
    pthread_mutex_unlock(&b->mu);
    return rc;
}

int disp_inbox_tex_resize(disp_inbox *b, uint32_t id, int w, int h, ct_error *err)
{
    if (w < 1 || h < 1 || w > b->max_tex || h > b->max_tex)
        return ct_fail(err, CT_ERANGE, "texture %u: size %dx%d out of range 1..%d", id, w, h, b->max_tex);
    int rc = CT_OK, ow = 0, oh = 0;
    const uint16_t *src = NULL;
    pthread_mutex_lock(&b->mu);
    ib_tex *t = find(b, id);
    uint64_t bytes = (uint64_t)w * (uint64_t)h * 6;
    if (!t || !t->live) {
        rc = ct_fail(err, CT_EPROTO, "resize of unknown texture %u", id);
    } else if (!wire_tex_resize_exact(t->w, t->h, w, h)) {
        rc = ct_fail(err, CT_EPROTO, "texture %u: %dx%d -> %dx%d is no exact resize", id, t->w, t->h, w, h);
    } else if (b->tex_bytes - (uint64_t)t->w * (uint64_t)t->h * 6 + bytes > DISP_INBOX_MAX_BYTES) {
        rc = ct_fail(err, CT_ENOMEM, "texture %u: %dx%d texels would pass the display's %llu MiB", id, w, h,
                     (unsigned long long)(DISP_INBOX_MAX_BYTES >> 20));
    } else {
        src = t->tx;
        ow = t->w;
        oh = t->h;
    }
    pthread_mutex_unlock(&b->mu);
    if (rc) return rc;
    /* Computed here, on the connection thread, and outside the lock: a
     * resize of a large texture takes most of a second, and the render
     * thread must go on drawing (and see --seconds or a signal) meanwhile.
     * src stays valid: only this thread replaces or frees a texture's copy. */
    store st;
    bool neg = false, nz = false;
    if ((rc = store_new(w, h, false, &st, err))) return rc;
    if (disp_rescale(src, ow, oh, st.tx, w, h, &neg, &nz)) {
        free(st.tx);
        free(st.bits);
        return ct_fail(err, CT_ENOMEM, "out of memory to resize texture %u", id);
    }
    pthread_mutex_lock(&b->mu);
    t = find(b, id);   /* (the render thread may have compacted the table) */
    if (!t) {
        /* cannot happen: compaction keeps live textures, and only this
         * thread frees one; refused rather than crashed on */
        pthread_mutex_unlock(&b->mu);
        free(st.tx);
        free(st.bits);
        return ct_fail(err, CT_ESYS, "texture %u vanished while it was resized", id);
    }
    store_attach(b, t, &st);
    /* The new GL texture (fresh) takes every tile (or the old texture's: the
     * GPU keeps its scaled texels until the upload replaces them,
     * disp_textures.h). */
    t->fresh = true;
    t->negative |= neg;
    t->nonzero |= nz;
    for (int ty = 0; ty < st.th; ty++) bitrow_set(st.bits + (size_t)ty * (size_t)st.words, 0, st.tw - 1);
    t->dirty = true;
    b->dirty_bytes += (size_t)st.tw * TS * UP_BPT * (size_t)st.th * TS;
    pthread_mutex_unlock(&b->mu);
    return CT_OK;
}

int disp_inbox_tex_projection(disp_inbox *b, uint32_t id, const mat4 *world_to_tex, ct_error *err)
{
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++)
            if (!isfinite(world_to_tex->m[r][c]))
                return ct_fail(err, CT_ERANGE, "texture %u: projection is not finite", id);
    int rc = CT_OK;
    pthread_mutex_lock(&b->mu);
    ib_tex *t = find(b, id);
    if (!t || !t->live) {
        rc = ct_fail(err, CT_EPROTO, "projection for unknown texture %u", id);
    } else {
        t->proj = *world_to_tex;
        t->proj_new = true;
    }
    pthread_mutex_unlock(&b->mu);
    return rc;
}

/* Stamps wait here until every marked tile has gone up; while uploads lag
 * (a backlog past DISP_INBOX_FRAME_BYTES a frame) they would pile up, one
 * a patch. Past MAX_STAMPS, neighbours merge: the older stamp and both
 * counts, so a lag is never understated (it is an upper bound already:
 * docs/display.md, "Lag"). */
#define MAX_STAMPS 65536u
static void merge_stamps(disp_inbox *b)
{
    uint32_t k = 0;
    for (uint32_t i = 0; i < b->nstamps; i += 2, k++) {
        disp_inbox_stamp m = b->stamps[i];
        if (i + 1 < b->nstamps) {
            const disp_inbox_stamp *o = &b->stamps[i + 1];
            if (o->stamp_us < m.stamp_us) m.stamp_us = o->stamp_us;
            m.samples = m.samples > UINT32_MAX - o->samples ? UINT32_MAX : m.samples + o->samples;
        }
        b->stamps[k] = m;
    }
    b->nstamps = k;
}

int disp_inbox_tex_patch(disp_inbox *b, uint32_t id, int x, int y, int w, int h, const uint16_t *rgb,
                         uint64_t stamp_us, uint32_t samples, ct_error *err)
{
    /* Non-zero: any bit but the sign; negative: the sign and not -0;
     * non-finite: an exponent of all ones (NaN, infinity), which the master
     * never sends (it clamps to the largest half) and which would spread
     * through the image as NaN pixels. Found here, off the render thread. */
    bool neg = false, nz = false, nf = false;
    size_t n = w > 0 && h > 0 ? (size_t)w * (size_t)h * 3 : 0;
    for (size_t i = 0; i < n; i++) {
        nz |= (rgb[i] & 0x7fffu) != 0;
        neg |= (rgb[i] & 0x8000u) && (rgb[i] & 0x7fffu);
        nf |= (rgb[i] & 0x7c00u) == 0x7c00u;
    }
    if (nf) return ct_fail(err, CT_ERANGE, "texture %u: patch holds non-finite texels (NaN or infinity)", id);
    int rc = CT_OK;
    pthread_mutex_lock(&b->mu);
    ib_tex *t = find(b, id);
    if (!t || !t->live) {
        rc = ct_fail(err, CT_EPROTO, "patch for unknown texture %u", id);
    } else if (x < 0 || y < 0 || w < 1 || h < 1 || x > t->w - w || y > t->h - h) {
        rc = ct_fail(err, CT_ERANGE, "texture %u: patch %dx%d at (%d,%d) outside %dx%d", id, w, h, x, y, t->w,
                     t->h);
    } else {
        for (int j = 0; j < h; j++)
            memcpy(t->tx + 3 * ((size_t)(y + j) * (size_t)t->w + (size_t)x), rgb + 3 * (size_t)j * (size_t)w,
                   (size_t)w * 6);
        int a = x >> TS_SHIFT, e = (x + w - 1) >> TS_SHIFT;
        for (int ty = y >> TS_SHIFT; ty <= (y + h - 1) >> TS_SHIFT; ty++)
            bitrow_set(t->bits + (size_t)ty * (size_t)t->words, a, e);
        t->dirty = true;
        t->negative |= neg;
        t->nonzero |= nz;
        b->dirty_bytes += (size_t)(e - a + 1) * TS * UP_BPT * (size_t)(((y + h - 1) >> TS_SHIFT) - (y >> TS_SHIFT) + 1) * TS;
        b->texels_in += (uint64_t)w * (uint64_t)h;
        b->patches_in++;
        if (samples && b->nstamps == MAX_STAMPS) merge_stamps(b);
        if (samples && grow((void **)&b->stamps, &b->cap_stamps, b->nstamps + 1, sizeof *b->stamps))
            b->stamps[b->nstamps++] = (disp_inbox_stamp){stamp_us, samples};
    }
    pthread_mutex_unlock(&b->mu);
    return rc;
}

int disp_inbox_tex_free(disp_inbox *b, uint32_t id, ct_error *err)
{
    int rc = CT_OK;
    pthread_mutex_lock(&b->mu);
    ib_tex *t = find(b, id);
    if (!t || !t->live) {
        rc = ct_fail(err, CT_EPROTO, "free of unknown texture %u", id);
    } else {
        /* Kept until the render thread has deleted its GL texture. */
        tex_release(b, t);
        t->live = false;
        t->fresh = false;
        t->dirty = false;
    }
    pthread_mutex_unlock(&b->mu);
    return rc;
}

void disp_inbox_points(disp_inbox *b, const float *xyz, uint32_t n, uint64_t dropped)
{
    pthread_mutex_lock(&b->mu);
    b->pts_dropped = dropped;
    /* The samples view keeps at most DISP_SAMPLE_MAX points anyway; more
     * pending ones than that are older than what it would show. */
    if (b->npts + n > DISP_SAMPLE_MAX) b->npts = 0;
    if (n && grow((void **)&b->pts, &b->cap_pts, 3 * (b->npts + n), sizeof *b->pts)) {
        memcpy(b->pts + 3 * (size_t)b->npts, xyz, 3 * (size_t)n * sizeof *xyz);
        b->npts += n;
    }
    pthread_mutex_unlock(&b->mu);
}

void disp_inbox_frame_end(disp_inbox *b, uint64_t frame, uint32_t epoch, uint32_t samples, bool all_positive)
{
    pthread_mutex_lock(&b->mu);
    if (b->nframes < MAX_FRAMES) b->frames[b->nframes++] = (frame_end){frame, samples, all_positive};
    if (epoch == b->epoch) {
        b->st.frame_seen = true;
        b->st.frame_last = frame;
    }
    pthread_mutex_unlock(&b->mu);
}

void disp_inbox_stats(disp_inbox *b, uint64_t samples_total, bool all_positive)
{
    pthread_mutex_lock(&b->mu);
    b->stats_new = true;
    b->stats_total = samples_total;
    b->stats_pos = all_positive;
    pthread_mutex_unlock(&b->mu);
}

void disp_inbox_view(disp_inbox *b, const ct_camera *cam)
{
    pthread_mutex_lock(&b->mu);
    b->st.have_view = true;
    b->st.view = *cam;
    pthread_mutex_unlock(&b->mu);
}

void disp_inbox_bytes(disp_inbox *b, uint64_t total)
{
    pthread_mutex_lock(&b->mu);
    b->st.bytes = b->bytes_base + total;
    pthread_mutex_unlock(&b->mu);
}

/* --- the render thread ------------------------------------------------------ */

void disp_inbox_new_epoch(disp_inbox *b, uint32_t epoch)
{
    pthread_mutex_lock(&b->mu);
    b->epoch = epoch;
    b->st.frame_seen = false;
    pthread_mutex_unlock(&b->mu);
}

disp_inbox_state disp_inbox_get_state(disp_inbox *b)
{
    pthread_mutex_lock(&b->mu);
    disp_inbox_state s = b->st;
    pthread_mutex_unlock(&b->mu);
    return s;
}

bool disp_inbox_frame_ready(disp_inbox *b, uint64_t *frame)
{
    pthread_mutex_lock(&b->mu);
    /* Every texel of the frame must be on the textures too. */
    bool ok = b->st.frame_seen && (!b->frame_taken_any || b->st.frame_last > b->frame_taken) &&
              b->dirty_bytes == 0 && !b->scene_new;
    if (ok && frame) *frame = b->st.frame_last;
    pthread_mutex_unlock(&b->mu);
    return ok;
}

void disp_inbox_take_frame(disp_inbox *b)
{
    pthread_mutex_lock(&b->mu);
    if (b->st.frame_seen) {
        b->frame_taken = b->st.frame_last;
        b->frame_taken_any = true;
    }
    pthread_mutex_unlock(&b->mu);
}

/* Under the lock: texture operations in the order the render thread must
 * issue them (frees, then allocations, then projections). */
static bool collect_ops(disp_inbox *b)
{
    b->nops = 0;
    for (uint32_t pass = 0; pass < 3; pass++)
        for (uint32_t i = 0; i < b->ntex; i++) {
            ib_tex *t = &b->tex[i];
            texop o = {.id = t->id};
            if (pass == 0 && t->in_gl && !t->live) {
                o.kind = OP_FREE;
                t->in_gl = false;
            } else if (pass == 1 && t->live && t->fresh) {
                o = (texop){.kind = OP_ALLOC, .id = t->id, .node = t->node, .w = t->w, .h = t->h, .pk = t->kind};
                t->fresh = false;
                t->in_gl = true;
                t->proj_new = true;   /* a new GL texture needs its projection */
            } else if (pass == 2 && t->live && t->proj_new && t->in_gl) {
                o = (texop){.kind = OP_PROJ, .id = t->id, .m = t->proj};
                t->proj_new = false;
            } else {
                continue;
            }
            if (!grow((void **)&b->ops, &b->cap_ops, b->nops + 1, sizeof *b->ops)) return false;
            b->ops[b->nops++] = o;
        }
    /* Entries freed and deleted from GL are forgotten; the others' indices
     * change (the map keeps its room: its puts here cannot fail). */
    uint32_t k = 0;
    for (uint32_t i = 0; i < b->ntex; i++)
        if (b->tex[i].live || b->tex[i].in_gl) b->tex[k++] = b->tex[i];
    if (k != b->ntex) {
        idmap_clear(&b->ix);
        for (uint32_t i = 0; i < k; i++) idmap_put(&b->ix, b->tex[i].id, i, NULL);
    }
    b->ntex = k;
    return true;
}

/* n RGB half texels to RGBA (alpha 0, as a cleared texture has) at dst,
 * which may be unaligned mapped memory: one 8-byte store per texel. */
static void rgb_to_rgba(uint8_t *dst, const uint16_t *src, int n)
{
    for (int i = 0; i < n; i++) {
        uint64_t v = (uint64_t)src[3 * i] | (uint64_t)src[3 * i + 1] << 16 | (uint64_t)src[3 * i + 2] << 32;
        memcpy(dst + (size_t)i * UP_BPT, &v, sizeof v);
    }
}

/* The run of marked tiles of a row at or after `from`, merged with the
 * runs after it that begin at most UPLOAD_GAP_TILES unmarked tiles later;
 * *len 0 when none. */
static int next_upload_run(const uint64_t *row, int n, int from, int *len)
{
    int a = bitrow_next_run(row, n, from, len);
    while (*len) {
        int l2, a2 = bitrow_next_run(row, n, a + *len, &l2);
        if (!l2 || a2 - (a + *len) > UPLOAD_GAP_TILES) break;
        *len = a2 + l2 - a;
    }
    return a;
}

/* The texels of tiles [a, a + len) of tile row ty of t (the last row and
 * column of tiles cut at the texture's edge); their bytes in the upload
 * buffer. */
static size_t run_rect(const ib_tex *t, int ty, int a, int len, int *x, int *y, int *w, int *h)
{
    *x = a << TS_SHIFT;
    *y = ty << TS_SHIFT;
    *w = *x + (len << TS_SHIFT) > t->w ? t->w - *x : len << TS_SHIFT;
    *h = *y + TS > t->h ? t->h - *y : TS;
    return (size_t)*w * (size_t)*h * UP_BPT;
}

/* Under the lock: the bytes the marked runs take in the upload buffer as
 * collect_uploads merges them, at most DISP_INBOX_FRAME_BYTES. */
static size_t upload_bytes(const disp_inbox *b)
{
    size_t sum = 0;
    for (uint32_t i = 0; i < b->ntex && sum < DISP_INBOX_FRAME_BYTES; i++) {
        const ib_tex *t = &b->tex[i];
        /* (a fresh texture gets its GL texture in the same take) */
        if (!t->live || !t->dirty) continue;
        for (int ty = 0; ty < t->th && sum < DISP_INBOX_FRAME_BYTES; ty++) {
            const uint64_t *row = t->bits + (size_t)ty * (size_t)t->words;
            int len, x, y, w, h, a = next_upload_run(row, t->tw, 0, &len);
            for (; len; a = next_upload_run(row, t->tw, a + len, &len)) sum += run_rect(t, ty, a, len, &x, &y, &w, &h);
        }
    }
    return sum < DISP_INBOX_FRAME_BYTES ? sum : DISP_INBOX_FRAME_BYTES;
}

/* Under the lock: copies marked runs into dst (cap bytes), making the
 * upload list; what does not fit stays marked. */
static void collect_uploads(disp_inbox *b, uint8_t *dst, size_t cap)
{
    size_t off = 0;
    b->nups = 0;
    for (uint32_t i = 0; i < b->ntex; i++) {
        ib_tex *t = &b->tex[i];
        if (!t->live || !t->dirty || !t->in_gl) continue;
        bool left = false;
        for (int ty = 0; ty < t->th; ty++) {
            uint64_t *row = t->bits + (size_t)ty * (size_t)t->words;
            int len, a = next_upload_run(row, t->tw, 0, &len);
            while (len) {
                int x, y, w, h;
                size_t bytes = run_rect(t, ty, a, len, &x, &y, &w, &h);
                if (off + bytes > cap) {
                    /* merged, it does not fit: its first run alone may */
                    a = bitrow_next_run(row, t->tw, a, &len);
                    bytes = run_rect(t, ty, a, len, &x, &y, &w, &h);
                }
                if (off + bytes > cap ||
                    !grow((void **)&b->ups, &b->cap_ups, b->nups + 1, sizeof *b->ups)) {
                    left = true;
                    break;
                }
                for (int j = 0; j < h; j++)
                    rgb_to_rgba(dst + off + (size_t)j * (size_t)w * UP_BPT,
                                t->tx + 3 * ((size_t)(y + j) * (size_t)t->w + (size_t)x), w);
                b->ups[b->nups++] = (upload){t->id, x, y, w, h, off, t->negative, t->nonzero};
                off += bytes;
                bitrow_clear(row, a, len);
                a = next_upload_run(row, t->tw, a + len, &len);
            }
            if (left) break;
        }
        if (left) break;
        t->dirty = false;
    }
    /* What is still marked, by whole tiles. */
    size_t rest = 0;
    for (uint32_t i = 0; i < b->ntex; i++) {
        const ib_tex *t = &b->tex[i];
        if (!t->live || !t->dirty) continue;
        for (size_t k = 0; k < (size_t)t->th * (size_t)t->words; k++)
            rest += (size_t)__builtin_popcountll(t->bits[k]) * TS * TS * UP_BPT;
    }
    b->dirty_bytes = rest;
}

bool disp_inbox_pending(disp_inbox *b)
{
    pthread_mutex_lock(&b->mu);
    bool p = b->dirty_bytes > 0 || b->nstamps > 0;
    pthread_mutex_unlock(&b->mu);
    return p;
}

/* The upload buffer's new storage size for a take of want bytes, or 0 to
 * keep the storage it has. Re-specifying it every frame (orphaning) made
 * llvmpipe allocate and zero a fresh buffer each frame: a quarter of the
 * render thread's time streaming table at 1024x1024 went to that memset and
 * its page faults. So the storage is kept, grown by doubling, and given
 * back when a window of takes used under a quarter of it (after a camera
 * change's burst of tens of MB). */
#define PBO_WINDOW 64
static size_t pbo_storage(disp_inbox *b, size_t want)
{
    if (want > b->pbo_peak) b->pbo_peak = want;
    size_t cap = 0;
    if (want > b->pbo_cap) {
        cap = 2 * b->pbo_cap > want ? 2 * b->pbo_cap : want;
        if (cap > DISP_INBOX_FRAME_BYTES) cap = DISP_INBOX_FRAME_BYTES;
    } else if (b->pbo_takes + 1 >= PBO_WINDOW && b->pbo_peak < b->pbo_cap / 4) {
        cap = 2 * b->pbo_peak;
    }
    if (++b->pbo_takes >= PBO_WINDOW) {
        b->pbo_takes = 0;
        b->pbo_peak = 0;
    }
    if (cap) b->pbo_cap = cap;
    return cap;
}

int disp_inbox_apply(disp_inbox *b, disp_session *s, disp_inbox_took *took, ct_error *err)
{
    memset(took, 0, sizeof *took);
    ct_radmesh scene = {0};
    bool have_scene = false;
    frame_end frames[MAX_FRAMES];
    uint32_t nframes;
    float *pts = NULL;
    uint32_t npts = 0;
    uint64_t dropped, bytes, stats_total = 0;
    bool stats_new, stats_pos, ops_ok;
    int rc = CT_OK;

    /* The upload buffer is sized from a first look (mapping it may not
     * happen under the lock); what arrives after it waits for the next
     * frame. */
    pthread_mutex_lock(&b->mu);
    size_t want = upload_bytes(b);
    pthread_mutex_unlock(&b->mu);
    uint8_t *dst = NULL;
    if (want) {
        if (!b->pbo) gl.GenBuffers(1, &b->pbo);
        gl.BindBuffer(GL_PIXEL_UNPACK_BUFFER, b->pbo);
        size_t cap = pbo_storage(b, want);
        if (cap) gl.BufferData(GL_PIXEL_UNPACK_BUFFER, (GLsizeiptr)cap, NULL, GL_STREAM_DRAW);
        /* Invalidated whole: a driver whose GPU still reads the last
         * frame's upload renames the storage instead of waiting. */
        dst = gl.MapBufferRange(GL_PIXEL_UNPACK_BUFFER, 0, (GLsizeiptr)want,
                                GL_MAP_WRITE_BIT | GL_MAP_INVALIDATE_BUFFER_BIT);
        if (!dst) {
            rc = gl_check("mapping the texel upload buffer", err);
            if (!rc) rc = ct_fail(err, CT_ESYS, "cannot map a %zu-byte texel upload buffer", want);
            gl.BindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
            return rc;
        }
    }

    /* One critical section: the texture operations and the texels taken
     * together, so every upload fits the GL texture the operations make
     * (a texture re-allocated at a new size between two looks had its
     * old ALLOC applied and its new texels uploaded). */
    pthread_mutex_lock(&b->mu);
    if (b->scene_new) {
        scene = b->scene;
        memset(&b->scene, 0, sizeof b->scene);
        b->scene_new = false;
        have_scene = true;
    }
    ops_ok = collect_ops(b);
    b->nups = 0;
    b->ntaken = 0;
    if (dst && ops_ok) {
        collect_uploads(b, dst, want);
        /* The stamps go with the texels they describe: once nothing is
         * left marked, every patch received so far is on a texture. */
        if (b->dirty_bytes == 0) {
            disp_inbox_stamp *t = b->taken;
            uint32_t ct = b->cap_taken;
            b->taken = b->stamps;
            b->cap_taken = b->cap_stamps;
            b->ntaken = b->nstamps;
            b->stamps = t;
            b->cap_stamps = ct;
            b->nstamps = 0;
        }
    }
    nframes = b->nframes;
    memcpy(frames, b->frames, nframes * sizeof *frames);
    b->nframes = 0;
    if (b->npts) {
        pts = b->pts;
        npts = b->npts;
        b->pts = NULL;
        b->npts = b->cap_pts = 0;
    }
    dropped = b->pts_dropped;
    stats_new = b->stats_new;
    stats_pos = b->stats_pos;
    stats_total = b->stats_total;
    b->stats_new = false;
    bytes = b->st.bytes - b->bytes_applied;
    b->bytes_applied = b->st.bytes;
    took->patches = b->patches_in;
    b->patches_in = 0;
    pthread_mutex_unlock(&b->mu);

    if (dst) {
        gl.UnmapBuffer(GL_PIXEL_UNPACK_BUFFER);
        /* Texture creation reads no pixels: no unpack buffer bound. */
        gl.BindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
    }
    if (!ops_ok) rc = ct_fail(err, CT_ENOMEM, "out of memory for texture operations");
    if (!rc && have_scene) rc = disp_session_scene(s, &scene, err);
    rmesh_free(&scene);
    for (uint32_t i = 0; i < b->nops && !rc; i++) {
        const texop *o = &b->ops[i];
        if (o->kind == OP_FREE) rc = disp_session_tex_free(s, o->id, err);
        else if (o->kind == OP_ALLOC) rc = disp_session_tex_alloc(s, o->id, o->node, o->w, o->h, o->pk, err);
        else rc = disp_session_tex_projection(s, o->id, &o->m, err);
    }
    if (b->nups) {
        gl.BindBuffer(GL_PIXEL_UNPACK_BUFFER, b->pbo);
        for (uint32_t i = 0; i < b->nups && !rc; i++) {
            const upload *u = &b->ups[i];
            rc = disp_session_tex_upload(s, u->id, u->x, u->y, u->w, u->h, u->off, u->negative, u->nonzero, err);
            took->texels += (uint64_t)u->w * (uint64_t)u->h;
            took->uploads++;
        }
        gl.BindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
    }
    took->stamps = b->taken;
    took->nstamps = b->ntaken;
    took->upload_buffer_bytes = b->pbo_cap;
    if (npts) disp_session_sample_points(s, pts, npts, dropped);
    free(pts);
    for (uint32_t i = 0; i < nframes; i++)
        disp_session_frame_end(s, (uint32_t)frames[i].frame, frames[i].samples, frames[i].all_positive);
    if (stats_new) disp_session_stats(s, stats_total, stats_pos);
    if (bytes) disp_session_add_bytes(s, bytes);
    return rc;
}

void disp_inbox_release_gl(disp_inbox *b)
{
    if (b->pbo) gl.DeleteBuffers(1, &b->pbo);
    b->pbo = 0;
    b->pbo_cap = b->pbo_peak = 0;
    b->pbo_takes = 0;
}

/* dsync.c: texture updates to the display, paced by its acknowledgements
 * (dsync.h). */
#include "master/dsync.h"

#include <stdlib.h>
#include <string.h>
#if defined(__SSSE3__)
#include <tmmintrin.h>
#endif

#include "common/grow.h"
#include "common/half.h"
#include "common/timer.h"
#include "master/ctex_tex.h"
#include "proto/wire.h"

#define WINDOW_MAX 16

/* A texture as the display has it, from its last TEX_ALLOC or TEX_RESIZE. */
typedef struct shown {
    int w, h;        /* the master's size then (0: the display has no such texture) */
    uint8_t shift;   /* 1: it goes as 2 x 2 means (fixed until the next ALLOC, so
                      * that its patches always fit the size the display has) */
} shown;

struct dsync {
    dsync_options o;
    uint32_t disp_epoch;            /* the display's epoch of the current camera */
    uint64_t seq, acked;            /* last SYNC sent, last acknowledged */
    double sent_at[WINDOW_MAX];     /* by seq % WINDOW_MAX: when it was sent */
    double in_socket_at[WINDOW_MAX]; /* and when its SYNC was seen written (< 0: not yet) */
    uint64_t w_mark;                /* bytes written to the display when last seen... */
    double w_time;                  /* ...and since when (< 0: not seen yet) */
    double checked;                 /* the last dsync_stalled_s */
    size_t sent_bytes[WINDOW_MAX];  /* and its texel bytes */
    double rate;                    /* texel bytes/s acknowledged, smoothed (0: unknown) */
    double next_due;                /* when the next free-running update may start (ct_now) */
    double io_mark;                 /* dsrv_io_seconds at the last update (< 0: none yet) */
    size_t budget;
    uint32_t cur_tex;               /* where the next update resumes its scan */
    int cur_row;
    wire_scratch scratch;
    uint64_t patches, texel_bytes;
    uint64_t resized, resized_texels, resized_whole;
    /* Per texture id, what this display has: */
    shown *shown;
    size_t shown_cap;
};

void dsync_options_default(dsync_options *o, bool tcp)
{
    /* LZ4 halves a patch's bytes but costs the master about a millisecond per
     * MiB and the display as much again: it pays on a network link, not on a
     * UNIX socket, where copying is cheaper than compressing
     * (docs/protocol.md, "Flow control", measured). */
    o->encoding = tcp ? WIRE_PATCH_LZ4 : WIRE_PATCH_RAW;
    /* Textures denser than the screen as 2 x 2 means: a quarter of their
     * bytes, the same image; over a 100 Mbit/s link the lag's median fell
     * from 1,022 to 361 ms. On a UNIX socket bytes cost little, and a display
     * sharing the host spent what it saved on more frames (docs/protocol.md,
     * "Texels at the display's rate"). */
    o->screen_rate = tcp;
    o->window = 2;
    o->send_timeout_ms = 10000;
    o->target_ms = 40.0;
    o->min_bytes = 64u << 10;
    o->max_bytes = 32u << 20;
    o->interval_s = 0.010;
    o->share = 0.25;
}

int dsync_new(const dsync_options *o, dsync **out, ct_error *err)
{
    *out = NULL;
    if (!(o->share > 0.0 && o->share <= 1.0) || !(o->interval_s >= 0.0))
        return ct_fail(err, CT_EINVAL, "display sync: update pacing out of range (interval %g s, share %g)",
                       o->interval_s, o->share);
    dsync *d = calloc(1, sizeof *d);
    if (!d) return ct_fail(err, CT_ENOMEM, "display sync: out of memory");
    d->o = *o;
    if (d->o.window < 1) d->o.window = 1;
    if (d->o.window > WINDOW_MAX) d->o.window = WINDOW_MAX;
    dsync_reset(d);
    *out = d;
    return 0;
}

void dsync_free(dsync *d)
{
    if (!d) return;
    wire_scratch_free(&d->scratch);
    free(d->shown);
    free(d);
}

void dsync_reset(dsync *d)
{
    d->seq = d->acked = 0;
    d->rate = 0.0;
    d->next_due = 0.0;   /* a new display's first update goes at once */
    d->io_mark = -1.0;
    /* A first update of 1 MiB: about 80 ms on a 100 Mbit/s link, a few
     * milliseconds on a UNIX socket; the rate measured from its ACK sizes
     * the next ones. */
    d->budget = 1u << 20;
    if (d->budget < d->o.min_bytes) d->budget = d->o.min_bytes;
    if (d->budget > d->o.max_bytes) d->budget = d->o.max_bytes;
    d->cur_tex = 0;
    d->cur_row = 0;
    d->w_mark = 0;
    d->w_time = -1.0;
    if (d->shown) memset(d->shown, 0, d->shown_cap * sizeof *d->shown);   /* a new display has none */
}

void dsync_set_epoch(dsync *d, uint32_t epoch)
{
    d->disp_epoch = epoch;
}

bool dsync_due(const dsync *d, double now)
{
    return now >= d->next_due && dsync_can_send(d);
}

bool dsync_can_send(const dsync *d)
{
    return d->seq - d->acked < (uint64_t)d->o.window;
}

double dsync_stalled_s(dsync *d, dsrv *ds, double now)
{
    uint64_t w = dsrv_written(ds);
    /* A master that did not look for a while (a long view change) cannot
     * tell whether the display was stuck meanwhile: the clocks start again. */
    bool gap = d->w_time >= 0.0 && now - d->checked > 1.0;
    d->checked = now;
    if (w != d->w_mark || d->w_time < 0.0 || gap) {
        d->w_mark = w;
        d->w_time = now;
    }
    for (int k = 0; gap && k < WINDOW_MAX; k++)
        if (d->in_socket_at[k] >= 0.0) d->in_socket_at[k] = now;
    if (dsrv_queued(ds) > 0) return now - d->w_time;
    if (d->seq == d->acked) return 0.0;
    /* everything written: the oldest unacknowledged SYNC is in the socket */
    size_t k = (size_t)((d->acked + 1) % WINDOW_MAX);
    if (d->in_socket_at[k] < 0.0) d->in_socket_at[k] = now;
    return now - d->in_socket_at[k];
}

/* --- events ----------------------------------------------------------------- */

static int send(const dsync *d, dsrv *ds, const wire_msg *m, ct_error *err)
{
    return dsrv_send(ds, m, d->o.send_timeout_ms, err);
}

static int send_proj(dsync *d, dsrv *ds, uint32_t tex, const mat4 *mat, ct_error *err)
{
    wire_msg m = {.type = WIRE_TEX_PROJECTION};
    m.u.tex_projection.tex = tex;
    m.u.tex_projection.epoch = d->disp_epoch;
    m.u.tex_projection.world_to_tex = *mat;
    return send(d, ds, &m, err);
}

/* Whether texture id goes to the display as 2 x 2 means: more than one
 * texel a screen pixel on both axes in the current view (§3.6 lets
 * the master keep up to tex-rate, 2, for its splats; at the display a
 * bilinear lookup at a pixel centre then reads about the mean of the 2 x 2
 * texels under it anyway), and sides that halve exactly. */
static int display_shift(const dsync *d, const ctex *tex, uint32_t id, int w, int h)
{
    float rx, ry;
    if (!d->o.screen_rate || ((w | h) & 1) || w < 2 || h < 2) return 0;
    if (!ctex_texel_rate(tex, id, &rx, &ry)) return 0;
    return rx > 1.0f && ry > 1.0f ? 1 : 0;
}

static shown *shown_at(dsync *d, uint32_t id, ct_error *err)
{
    size_t had = d->shown_cap;
    if (ct_grow((void **)&d->shown, &d->shown_cap, (size_t)id + 1, sizeof *d->shown, "display texture sizes", err))
        return NULL;
    if (d->shown_cap > had) memset(d->shown + had, 0, (d->shown_cap - had) * sizeof *d->shown);
    return &d->shown[id];
}

/* TEX_ALLOC names the texture's hierarchy node: the display's node table is
 * the texture hierarchy (the SCENE it got), so it draws the texture on
 * exactly the triangles of that node's subtree. A display creates the
 * texture anew on ALLOC, a resize included, and needs its projection again:
 * every ALLOC is followed by the texture's current projection (a later
 * PROJ event still comes after it and wins). The size is the display's:
 * halved when the texture goes as 2 x 2 means (display_shift, fixed until
 * the texture's next ALLOC). */
static int send_alloc(dsync *d, dsrv *ds, ctex *tex, uint32_t id, uint32_t hnode, int w, int h,
                      ctex_proj_kind kind, ct_error *err)
{
    shown *sh = shown_at(d, id, err);
    if (!sh) return CT_ENOMEM;
    int sf = display_shift(d, tex, id, w, h);
    *sh = (shown){w, h, (uint8_t)sf};
    wire_msg m = {.type = WIRE_TEX_ALLOC};
    m.u.tex_alloc = (wire_tex_alloc){id, hnode, (uint32_t)(w >> sf), (uint32_t)(h >> sf),
                                     kind == CTEX_PROJ_OBJECT ? WIRE_PROJ_OBJECT_PARALLEL
                                                              : WIRE_PROJ_CAMERA_PERSPECTIVE};
    int rc = send(d, ds, &m, err);
    mat4 pm;
    if (rc == 0 && ctex_texture_info(tex, id, NULL, NULL, NULL, NULL, &pm, NULL) >= 0)
        rc = send_proj(d, ds, id, &pm, err);
    return rc;
}

/* An exact resize: TEX_RESIZE when the display has the texture at the size
 * it was resized from, whole texels both then and now, so that it computes
 * the new texels the master has not marked (ctex_dirty_rescale) from its
 * own; otherwise an ALLOC with every tile marked. */
static int send_resize(dsync *d, dsrv *ds, ctex *tex, const ctex_event *e, ct_error *err)
{
    shown *sh = shown_at(d, e->tex, err);
    if (!sh) return CT_ENOMEM;
    if (sh->w == e->ow && sh->h == e->oh && !sh->shift && !display_shift(d, tex, e->tex, e->w, e->h)) {
        sh->w = e->w;
        sh->h = e->h;
        wire_msg m = {.type = WIRE_TEX_RESIZE};
        m.u.tex_resize = (wire_tex_resize){e->tex, (uint32_t)e->w, (uint32_t)e->h};
        d->resized++;
        d->resized_texels += (uint64_t)e->w * (uint64_t)e->h;
        return send(d, ds, &m, err);
    }
    ctex_tex *t = ctex_visible_texture(tex, e->tex);
    if (t) ctex_dirty_mark_all(&t->d);
    d->resized_whole++;
    return send_alloc(d, ds, tex, e->tex, e->node, e->w, e->h, e->proj, err);
}

static int send_events(dsync *d, dsrv *ds, ctex *tex, ct_error *err)
{
    size_t n = 0;
    const ctex_event *ev = ctex_events(tex, &n);
    int rc = 0;
    for (size_t i = 0; i < n && rc == 0 && dsrv_has_display(ds); i++) {
        const ctex_event *e = &ev[i];
        wire_msg m;
        switch (e->kind) {
        case CTEX_EV_ALLOC: rc = send_alloc(d, ds, tex, e->tex, e->node, e->w, e->h, e->proj, err); break;
        case CTEX_EV_RESIZE: rc = send_resize(d, ds, tex, e, err); break;
        case CTEX_EV_PROJ: rc = send_proj(d, ds, e->tex, &e->m, err); break;
        case CTEX_EV_FREE:
            if (e->tex < d->shown_cap) d->shown[e->tex] = (shown){0, 0, 0};
            memset(&m, 0, sizeof m);
            m.type = WIRE_TEX_FREE;
            m.u.tex_free.tex = e->tex;
            rc = send(d, ds, &m, err);
            break;
        }
    }
    ctex_events_clear(tex);
    return rc;
}

int dsync_send_state(dsync *d, dsrv *ds, ctex *tex, uint32_t *ntex, ct_error *err)
{
    /* Pending events describe changes the state below already contains. */
    ctex_events_clear(tex);
    dsync_reset(d);
    *ntex = 0;
    uint32_t ns = ctex_slot_count(tex);
    for (uint32_t id = 0; id < ns && dsrv_has_display(ds); id++) {
        uint32_t hnode;
        int w, h;
        ctex_proj_kind kind;
        if (!ctex_visible_texture(tex, id) || ctex_texture_info(tex, id, &hnode, &w, &h, &kind, NULL, NULL) <= 0)
            continue;
        int rc = send_alloc(d, ds, tex, id, hnode, w, h, kind, err);
        if (rc) return rc;
        (*ntex)++;
    }
    ctex_dirty_all(tex);
    return 0;
}

/* --- tiles ------------------------------------------------------------------ */

typedef struct gather {
    const ctex_tex *t;
    int x, y, w;
} gather;

/* A texel's halves as TEX_PATCH carries them: the display tells an empty
 * texel from a valid one by its bits (TEX_RESIZE, display/disp_rescale.h),
 * so an empty texel goes as +0 whatever it holds and a valid zero as -0. */
static inline void wire_halves(const ctex_texel *p, uint16_t c[3])
{
    c[0] = p->c[0], c[1] = p->c[1], c[2] = p->c[2];
    if (!ctex_texel_valid(p)) c[0] = c[1] = c[2] = 0;
    else if (!(c[0] | c[1] | c[2])) c[0] = 0x8000u;
}

/* One row of a patch: each 8-byte texel's three halves, little-endian. */
static void gather_row(void *ctx, uint32_t row, uint8_t *dst)
{
    const gather *g = ctx;
    const ctex_texel *p = ctex_tex_at(g->t, g->x, g->y + (int)row);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    /* The texel's halves are the wire's bytes already: 6 of its 8 (the
     * byte-wise loop below was a quarter of the master's time when the
     * display takes every update, bench_master); with SSSE3 two texels at
     * a time, a 16-byte store of which the next one overwrites the last 4.
     * The texels wire_halves changes (empty ones, valid zeros) are rare and
     * written again. */
    int i = 0;
#if defined(__SSSE3__)
    const __m128i pack = _mm_setr_epi8(0, 1, 2, 3, 4, 5, 8, 9, 10, 11, 12, 13, -1, -1, -1, -1);
    for (; i + 3 <= g->w; i += 2)
        _mm_storeu_si128((__m128i *)(void *)(dst + 6 * (size_t)i),
                         _mm_shuffle_epi8(_mm_loadu_si128((const __m128i *)(const void *)(p + i)), pack));
#endif
    for (; i < g->w; i++) memcpy(dst + 6 * (size_t)i, p[i].c, 6);
    for (i = 0; i < g->w; i++) {
        const uint16_t *c = p[i].c;
        if (ctex_texel_valid(p + i) == ((c[0] | c[1] | c[2]) != 0)) continue;
        uint16_t h[3];
        wire_halves(p + i, h);
        memcpy(dst + 6 * (size_t)i, h, 6);
    }
#else
    for (int i = 0; i < g->w; i++, dst += 6) {
        uint16_t c[3];
        wire_halves(p + i, c);
        for (int k = 0; k < 3; k++) {
            dst[2 * k] = (uint8_t)c[k];
            dst[2 * k + 1] = (uint8_t)(c[k] >> 8);
        }
    }
#endif
}

/* One row of a patch of 2 x 2 means: display texel i of row `row` is the
 * mean of master texels (2i, 2i + 1) x (2 row, 2 row + 1) from (x, y), each
 * channel in float, rounded to half once. */
static void gather_row_means(void *ctx, uint32_t row, uint8_t *dst)
{
    const gather *g = ctx;
    const ctex_texel *a = ctex_tex_at(g->t, g->x, g->y + 2 * (int)row);
    const ctex_texel *b = a + g->t->pitch;
    for (int i = 0; i < g->w; i++, a += 2, b += 2, dst += 6) {
        float f[4][4], m[4];
        half4_to_float(a[0].c, f[0]);
        half4_to_float(a[1].c, f[1]);
        half4_to_float(b[0].c, f[2]);
        half4_to_float(b[1].c, f[3]);
        for (int c = 0; c < 3; c++) m[c] = 0.25f * ((f[0][c] + f[1][c]) + (f[2][c] + f[3][c]));
        m[3] = 0.0f;
        uint16_t hv[4];
        float4_to_half(m, hv);
        for (int c = 0; c < 3; c++) {
            dst[2 * c] = (uint8_t)hv[c];
            dst[2 * c + 1] = (uint8_t)(hv[c] >> 8);
        }
    }
}

/* Encodes the tiles [a, a + n) of tile row ty of texture id into the
 * display's queue and clears them. Returns the texel bytes, or negative. */
static long send_run(dsync *d, dsrv *ds, uint32_t id, ctex_tex *t, int ty, int a, int n, uint32_t samples,
                     ct_error *err)
{
    wire_buf *out = dsrv_tail(ds);
    if (!out) return 0;   /* the display is gone */
    int x = a << CTEX_TILE_SHIFT, y = ty << CTEX_TILE_SHIFT;
    int w = (n << CTEX_TILE_SHIFT), h = CTEX_TILE;
    if (x + w > t->w) w = t->w - x;
    if (y + h > t->h) h = t->h - y;
    /* Tiles are 4 x 4 texels and a halved texture has even sides: a run
     * halves exactly. */
    int sh = id < d->shown_cap ? d->shown[id].shift : 0;
    wire_tex_patch p = {.tex = id, .x = (uint32_t)(x >> sh), .y = (uint32_t)(y >> sh), .w = (uint32_t)(w >> sh),
                        .h = (uint32_t)(h >> sh), .encoding = d->o.encoding, .samples = samples,
                        .stamp_us = t->d.row_t[ty]};
    gather g = {t, x, y, w >> sh};
    int rc = wire_encode_patch(&p, sh ? gather_row_means : gather_row, &g, out, &d->scratch, err);
    if (rc) return rc;
    dsrv_commit(ds, 1);
    ctex_dirty_clear_run(&t->d, ty, a, n);
    d->patches++;
    size_t bytes = (size_t)p.w * (size_t)p.h * 6;
    d->texel_bytes += bytes;
    return (long)bytes;
}

/* Sends unsent tiles, resuming the round-robin scan where the last update
 * stopped (so every tile waits at most one sweep however small the
 * budget), until `budget` texel bytes went out; *sent gets them. The
 * samples of a tile row go with its first patch. */
static int send_tiles(dsync *d, dsrv *ds, ctex *tex, size_t budget, size_t *sent, uint32_t *npatches,
                      ct_error *err)
{
    *sent = 0;
    uint32_t ns = ctex_slot_count(tex);
    if (!ns) return 0;
    if (d->cur_tex >= ns) d->cur_tex = 0, d->cur_row = 0;
    /* k = 0: the resumed texture from cur_row; k = ns: its rows before it. */
    for (uint32_t k = 0; k <= ns; k++) {
        uint32_t id = (d->cur_tex + k) % ns;
        ctex_tex *t = ctex_visible_texture(tex, id);
        if (k == ns && d->cur_row == 0) break;
        if (!t || !t->d.any) continue;
        int r0 = k == 0 ? d->cur_row : 0, r1 = k == ns ? d->cur_row : t->d.th;
        if (r1 > t->d.th) r1 = t->d.th;
        for (int ty = r0; ty < r1; ty++) {
            if (!t->d.row_t[ty]) continue;
            uint32_t samples = t->d.row_n[ty];
            t->d.row_n[ty] = 0;
            int len, a = ctex_dirty_next_run(&t->d, ty, 0, &len);
            while (len) {
                long b = send_run(d, ds, id, t, ty, a, len, samples, err);
                if (b < 0) return (int)b;
                if (!dsrv_has_display(ds)) return 0;
                samples = 0;
                *sent += (size_t)b;
                (*npatches)++;
                if (*sent >= budget) {
                    d->cur_tex = id;
                    d->cur_row = ty;
                    return 0;
                }
                a = ctex_dirty_next_run(&t->d, ty, a + len, &len);
            }
        }
        /* Every row of it scanned and sent (the resumed one after both parts). */
        if (k > 0 || r0 == 0) t->d.any = false;
    }
    d->cur_tex = 0;
    d->cur_row = 0;
    return 0;
}

/* --- updates ---------------------------------------------------------------- */

/* Why a share and not only an interval: a master that the tracers saturate
 * splats every few milliseconds into tiles it sent a moment ago, and an
 * update every 10 ms re-sent them again and again (the saturation replay in
 * rounds of 256: 530 MB to the display where rounds of 4,096 sent 124 MB;
 * docs/benchmarks.md, "Master: saturation"). Updates that cost little, as
 * on a master with time to spare, still go every interval. An update's
 * socket writes follow its encoding, so the writes counted with an update
 * are mostly the previous one's bytes. Costs are the thread's CPU time:
 * on a host shared with tracers and a display the wall time also counts
 * the waits for a core (live on 2 cores, table 1024^2: 6-7 ms an update
 * by the wall clock, three updates in four held 22 ms longer; 2 ms of CPU,
 * one in five held 4 ms longer). */
#define MAX_HOLD_S 1.0
static void pace(dsync *d, dsrv *ds, double t0, double cpu0)
{
    double io = dsrv_io_seconds(ds), cost = ct_thread_cpu() - cpu0;
    if (d->io_mark >= 0.0 && io > d->io_mark) cost += io - d->io_mark;
    d->io_mark = io;
    /* A costly update (a new display's whole state, a slow socket) holds
     * the next for a second at most: the display stays current. */
    double hold = cost / d->o.share;
    if (hold > MAX_HOLD_S) hold = MAX_HOLD_S;
    double by_share = t0 + hold, by_interval = t0 + d->o.interval_s;
    d->next_due = by_share > by_interval ? by_share : by_interval;
}

int dsync_update(dsync *d, dsrv *ds, ctex *tex, double now, uint64_t now_us, ct_error *err)
{
    if (!dsrv_has_display(ds) || !dsync_can_send(d)) return 0;
    double cpu0 = ct_thread_cpu();
    size_t nev = 0;
    ctex_events(tex, &nev);
    int rc = send_events(d, ds, tex, err);
    if (rc) return rc;
    size_t sent = 0;
    uint32_t np = 0;
    if ((rc = send_tiles(d, ds, tex, d->budget, &sent, &np, err))) return rc;
    if (!dsrv_has_display(ds) || (!nev && !np)) return 0;   /* nothing new: no update */
    wire_msg m = {.type = WIRE_SYNC};
    m.u.sync = (wire_sync){d->seq + 1, now_us};
    if ((rc = send(d, ds, &m, err))) return rc;
    d->seq++;
    d->sent_at[d->seq % WINDOW_MAX] = now;
    d->in_socket_at[d->seq % WINDOW_MAX] = -1.0;
    d->sent_bytes[d->seq % WINDOW_MAX] = sent;
    pace(d, ds, now, cpu0);
    return 1;
}

int dsync_flush_all(dsync *d, dsrv *ds, ctex *tex, uint32_t *patches, ct_error *err)
{
    *patches = 0;
    if (!dsrv_has_display(ds)) {
        ctex_events_clear(tex);
        return 0;
    }
    int rc = send_events(d, ds, tex, err);
    if (rc) return rc;
    size_t sent;
    return send_tiles(d, ds, tex, SIZE_MAX, &sent, patches, err);
}

int dsync_ack(dsync *d, uint64_t seq, double now, ct_error *err)
{
    if (seq > d->seq)
        return ct_fail(err, CT_EPROTO, "ACK of update %llu, but only %llu were sent", (unsigned long long)seq,
                       (unsigned long long)d->seq);
    if (seq <= d->acked) return 0;   /* an older ACK: nothing new */
    /* The rate of the newest update acknowledged: its bytes over the time
     * from its sending to its ACK (a slow display shows as a long time). */
    double dt = now - d->sent_at[seq % WINDOW_MAX];
    size_t bytes = d->sent_bytes[seq % WINDOW_MAX];
    d->acked = seq;
    if (bytes >= d->o.min_bytes / 2 && dt > 1e-4) {
        double r = (double)bytes / dt;
        d->rate = d->rate > 0 ? 0.7 * d->rate + 0.3 * r : r;
        double b = d->rate * d->o.target_ms / 1000.0;
        if (b < (double)d->o.min_bytes) b = (double)d->o.min_bytes;
        if (b > (double)d->o.max_bytes) b = (double)d->o.max_bytes;
        d->budget = (size_t)b;
    }
    return 0;
}

dsync_stats dsync_get_stats(const dsync *d)
{
    dsync_stats s = {d->seq,     d->acked,          d->patches,       d->texel_bytes,
                     d->resized, d->resized_texels, d->resized_whole, d->budget,
                     d->rate};
    return s;
}

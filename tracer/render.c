#include "tracer/render.h"

#include <limits.h>
#include <stdbool.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "common/pool.h"
#include "common/rng.h"
#include "common/timer.h"
#include "tracer/screen_order.h"

#define MAX_THREADS 256

void render_options_default(render_options *o, int width, int height)
{
    memset(o, 0, sizeof *o);
    o->width = width;
    o->height = height;
    o->spp = 1;
    o->threads = 1;
    o->tile = 16;
    o->bench_runs = 2;
}

typedef struct job {
    const trc_tracer *t;
    const render_options *o;
    trc_view view;
    float *rgb;
    int tiles_x, ntiles;
    uint32_t *order;        /* RENDER_ORDER_SHUFFLED: every pixel, tile x tile per task */
    atomic_int done;
    const char *progress;   /* progress line component of this pass, or NULL */
    double t0;
} job;

/* Cache-line aligned (and so padded): each thread bumps its own ray
 * counters on every ray, which must not share a line with a neighbour's. */
typedef struct worker {
    _Alignas(64) job *j;
    trc_stats st;
    trc_raylog log;
    ct_request *req;
    ct_sample *out;
    int replay_as_traced;
    bool use_log;         /* this pass records rays */
    uint64_t hits;        /* replay result, kept so the work is observable */
} worker;

/* Requests per trc_trace call: several pixels of a tile row when spp is
 * small, so the tracer can trace their primary rays back to back. */
#define CALL_REQUESTS 64

/* Traces the spp samples of each of the n pixels pix[] (n * spp <=
 * CALL_REQUESTS or n == 1) in one call and stores their means. */
static void trace_pixels(worker *w, const uint64_t *pix, size_t npix)
{
    job *j = w->j;
    const render_options *o = j->o;
    uint64_t seed = trc_get_options(j->t)->seed;
    size_t n = 0;
    for (size_t i = 0; i < npix; i++) {
        int x = (int)(pix[i] % (uint64_t)o->width), y = (int)(pix[i] / (uint64_t)o->width);
        for (int s = 0; s < o->spp; s++) {
            ct_request *r = &w->req[n++];
            r->id = pix[i] * (uint64_t)o->spp + (uint64_t)s + 1;
            r->parent = 0;
            r->epoch = o->epoch;
            ct_rng g = rng_make(seed, r->id, o->epoch, TRC_DIM_PIXEL);
            r->px = (float)x + rng_float(&g);
            r->py = (float)y + rng_float(&g);
            r->radius = 0.5f;
            r->priority = 0.0f;
        }
    }
    trc_trace(j->t, &j->view, w->req, n, w->out, &w->st);
    for (size_t i = 0; i < npix; i++) {
        const ct_sample *out = w->out + i * (size_t)o->spp;
        double sx = 0.0, sy = 0.0, sz = 0.0;
        for (int s = 0; s < o->spp; s++) {
            sx += out[s].l_hq.x;
            sy += out[s].l_hq.y;
            sz += out[s].l_hq.z;
        }
        float *p = j->rgb + 3 * pix[i];
        p[0] = (float)(sx / o->spp);
        p[1] = (float)(sy / o->spp);
        p[2] = (float)(sz / o->spp);
    }
}

static void render_tile(worker *w, int tile)
{
    job *j = w->j;
    const render_options *o = j->o;
    int group = o->spp < CALL_REQUESTS ? CALL_REQUESTS / o->spp : 1;
    uint64_t pix[CALL_REQUESTS];
    w->st.log = w->use_log && w->log.cap > 0 ? &w->log : NULL;
    if (j->order) {
        size_t per = (size_t)o->tile * (size_t)o->tile, total = (size_t)o->width * (size_t)o->height;
        size_t a = (size_t)tile * per, b = a + per < total ? a + per : total;
        for (size_t i = a; i < b; i += (size_t)group) {
            size_t m = b - i < (size_t)group ? b - i : (size_t)group;
            for (size_t k = 0; k < m; k++) pix[k] = j->order[i + k];
            trace_pixels(w, pix, m);
        }
        w->st.log = NULL;
        return;
    }
    int x0 = (tile % j->tiles_x) * o->tile, y0 = (tile / j->tiles_x) * o->tile;
    int x1 = x0 + o->tile < o->width ? x0 + o->tile : o->width;
    int y1 = y0 + o->tile < o->height ? y0 + o->tile : o->height;
    for (int y = y0; y < y1; y++)
        for (int xs = x0; xs < x1; xs += group) {
            int xe = xs + group < x1 ? xs + group : x1;
            for (int x = xs; x < xe; x++) pix[x - xs] = (uint64_t)y * (uint64_t)o->width + (uint64_t)x;
            trace_pixels(w, pix, (size_t)(xe - xs));
        }
    w->st.log = NULL;
}

/* Every pixel in a seeded shuffle (Fisher-Yates), sorted in runs of
 * o->sort_runs along the screen curve; NULL when out of memory. */
static uint32_t *shuffled_pixels(const render_options *o, uint64_t seed)
{
    size_t n = (size_t)o->width * (size_t)o->height;
    uint32_t *p = malloc(n * sizeof *p);
    if (!p) return NULL;
    for (size_t i = 0; i < n; i++) p[i] = (uint32_t)i;
    ct_rng g = rng_make(seed, 0x6f72646572ULL, o->epoch, 0);
    for (size_t i = n; i > 1; i--) {
        size_t k = rng_below(&g, (uint32_t)i);
        uint32_t t = p[i - 1];
        p[i - 1] = p[k];
        p[k] = t;
    }
    if (o->sort_runs > 1) {
        so_buf b = {0};
        int rc = so_pixels(&b, p, n, (uint32_t)o->width, o->sort_runs);
        so_free(&b);
        if (rc) {
            free(p);
            return NULL;
        }
    }
    return p;
}

/* A tile (pool task); the calling thread also prints the progress line
 * (ct_progress limits how often it writes). */
static void tile_task(void *ctx, int id, size_t tile)
{
    worker *ws = ctx, *w = &ws[id];
    job *j = w->j;
    render_tile(w, (int)tile);
    int done = atomic_fetch_add(&j->done, 1) + 1;
    if (id == 0 && j->progress && done < j->ntiles) {
        double el = ct_now() - j->t0, f = (double)done / j->ntiles;
        ct_progress(j->progress, f, 0, "%d/%d tiles, %.1f s, about %.0f s left", done, j->ntiles, el,
                    f > 0 ? el / f - el : 0.0);
    }
}

/* Replays worker `task`'s log (pool task). */
static void replay_task(void *ctx, int id, size_t task)
{
    (void)id;
    worker *w = &((worker *)ctx)[task];
    w->hits = trc_replay(w->j->t, &w->log, w->replay_as_traced);
}

static void free_workers(worker *ws, int n)
{
    for (int i = 0; i < n; i++) {
        free(ws[i].req);
        free(ws[i].out);
        free(ws[i].log.rays);
    }
    free(ws);
}

/* Wall time of replaying every worker's log, one log per task. */
static double replay(ct_pool *pool, worker *ws, int n, int as_traced)
{
    for (int i = 0; i < n; i++) ws[i].replay_as_traced = as_traced;
    double t0 = ct_now();
    pool_run(pool, (size_t)n, replay_task, ws);
    return ct_now() - t0;
}

/* One pass over every tile (logging rays when log is set), with the
 * progress line when progress is given. */
static void run_pass(ct_pool *pool, job *j, worker *ws, int n, bool log, const char *progress)
{
    atomic_store(&j->done, 0);
    for (int i = 0; i < n; i++) {
        memset(&ws[i].st, 0, sizeof ws[i].st);
        ws[i].use_log = log;
    }
    j->progress = progress;
    j->t0 = ct_now();
    pool_run(pool, (size_t)j->ntiles, tile_task, ws);
}

int render_image(const trc_tracer *t, const ct_camera *cam, const render_options *o, float *rgb,
                 render_result *res, ct_error *err)
{
    memset(res, 0, sizeof *res);
    if (o->width < 1 || o->height < 1 || o->width > 65536 || o->height > 65536)
        return ct_fail(err, CT_EINVAL, "image size %dx%d outside 1..65536", o->width, o->height);
    if (o->spp < 1 || o->spp > (1 << 20)) return ct_fail(err, CT_EINVAL, "spp %d outside 1..1048576", o->spp);
    if (o->threads < 1 || o->threads > MAX_THREADS)
        return ct_fail(err, CT_EINVAL, "threads %d outside 1..%d", o->threads, MAX_THREADS);
    if (o->tile < 1) return ct_fail(err, CT_EINVAL, "tile %d must be >= 1", o->tile);
    job j;
    j.t = t;
    j.o = o;
    j.view.cam = *cam;
    j.view.width = o->width;
    j.view.height = o->height;
    j.rgb = rgb;
    j.tiles_x = (o->width + o->tile - 1) / o->tile;
    uint64_t ntiles = (uint64_t)j.tiles_x * (uint64_t)((o->height + o->tile - 1) / o->tile);
    j.order = NULL;
    if (o->order == RENDER_ORDER_SHUFFLED) {
        uint64_t total = (uint64_t)o->width * (uint64_t)o->height, per = (uint64_t)o->tile * (uint64_t)o->tile;
        if (total > UINT32_MAX)
            return ct_fail(err, CT_EINVAL, "shuffled order: %dx%d has more pixels than 2^32 - 1", o->width, o->height);
        ntiles = (total + per - 1) / per;
    } else if (o->order != RENDER_ORDER_TILES) {
        return ct_fail(err, CT_EINVAL, "unknown pixel order %d", o->order);
    }
    /* (tasks are counted in an int, and a task per pixel of a huge image
     * would only schedule) */
    if (ntiles > INT_MAX)
        return ct_fail(err, CT_EINVAL, "%llu tiles of %d pixels: choose a larger --tile", (unsigned long long)ntiles,
                       o->tile);
    j.ntiles = (int)ntiles;
    atomic_init(&j.done, 0);
    ct_pool *pool = NULL;
    int prc = pool_new(o->threads, &pool, err);
    if (prc) return prc;
    worker *ws = aligned_alloc(_Alignof(worker), (size_t)o->threads * sizeof *ws);
    if (!ws) {
        pool_free(pool);
        return ct_fail(err, CT_ENOMEM, "out of memory");
    }
    memset(ws, 0, (size_t)o->threads * sizeof *ws);
    for (int i = 0; i < o->threads; i++) {
        ws[i].j = &j;
        size_t per_call = o->spp < CALL_REQUESTS ? CALL_REQUESTS : (size_t)o->spp;
        ws[i].req = malloc(per_call * sizeof *ws[i].req);
        ws[i].out = malloc(per_call * sizeof *ws[i].out);
        if (o->raylog_cap) {
            ws[i].log.rays = malloc(o->raylog_cap * sizeof *ws[i].log.rays);
            ws[i].log.cap = ws[i].log.rays ? o->raylog_cap : 0;
            ws[i].log.state = (uint64_t)i + 1;
        }
        if (o->raylog_cap && !ws[i].log.rays) {
            free_workers(ws, o->threads);
            pool_free(pool);
            return ct_fail(err, CT_ENOMEM, "out of memory for a ray log of %zu rays per thread", o->raylog_cap);
        }
        if (!ws[i].req || !ws[i].out) {
            free_workers(ws, o->threads);
            pool_free(pool);
            return ct_fail(err, CT_ENOMEM, "out of memory for %d samples per pixel", o->spp);
        }
    }
    if (o->order == RENDER_ORDER_SHUFFLED && !(j.order = shuffled_pixels(o, trc_get_options(t)->seed))) {
        free_workers(ws, o->threads);
        pool_free(pool);
        return ct_fail(err, CT_ENOMEM, "out of memory for the order of %dx%d pixels", o->width, o->height);
    }
    /* The timed pass traces without the ray log: recording every ray costs
     * the tracer some 15 % and is no part of its work. The log, when asked
     * for (a benchmark), comes from a first, untimed pass over the same
     * requests, which traces the very same rays (a sample is a pure function
     * of its request). Then bench_runs rounds of a timed pass and the two
     * raw replays, the fastest of each counting: interleaved, so that a
     * burst of load from other processes on a shared machine falls on both
     * sides of the comparison rather than on one. */
    if (o->raylog_cap) {
        run_pass(pool, &j, ws, o->threads, true, NULL);
        for (int i = 0; i < o->threads; i++) {
            res->logged += ws[i].log.n;
            trc_raylog_sort(&ws[i].log);
        }
    }
    int runs = o->raylog_cap && o->bench_runs > 1 ? o->bench_runs : 1;
    for (int run = 0; run < runs; run++) {
        double t0 = ct_now();
        run_pass(pool, &j, ws, o->threads, false, run == 0 ? o->progress : NULL);
        double dt = ct_now() - t0;
        if (run == 0 || dt < res->seconds) res->seconds = dt;
        if (!res->logged) continue;
        double ri = replay(pool, ws, o->threads, 0);
        double rt = replay(pool, ws, o->threads, 1);
        if (run == 0 || ri < res->replay_isect_s) res->replay_isect_s = ri;
        if (run == 0 || rt < res->replay_traced_s) res->replay_traced_s = rt;
    }
    if (o->progress) ct_progress(o->progress, 1.0, 1, "%d tiles, %.2f s", j.ntiles, res->seconds);
    for (int i = 0; i < o->threads; i++) {
        res->stats.primary += ws[i].st.primary;
        res->stats.secondary += ws[i].st.secondary;
        res->stats.shadow += ws[i].st.shadow;
        res->stats.samples += ws[i].st.samples;
    }
    free_workers(ws, o->threads);
    free(j.order);
    pool_free(pool);
    return CT_OK;
}

/* render.h: the offline reference renderer: every pixel of a view traced
 * with spp jittered requests through the per-sample API (tracer.h), on T
 * threads of the pool (common/pool.h) pulling square tiles, with a progress line.
 * Request ids are ((y * W + x) * spp + s + 1), the jitter comes from
 * rng_make(seed, id, epoch, TRC_DIM_PIXEL), so an image is bit-identical
 * for any thread count and either pixel order. Optionally logs (a random subset of) the rays it
 * traced, in a second untimed pass, and replays them with raw Embree queries
 * in the order they were traced: the benchmark's physical limit for the same
 * rays. */
#ifndef CT_TRACER_RENDER_H
#define CT_TRACER_RENDER_H

#include <stddef.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "tracer/tracer.h"

typedef struct render_options {
    int width, height;
    int spp;              /* samples per pixel */
    int threads;          /* worker threads (>= 1) */
    int tile;             /* tile edge in pixels */
    int order;            /* RENDER_ORDER_*: which pixels a pool task traces */
    size_t sort_runs;     /* RENDER_ORDER_SHUFFLED: the shuffled pixels sorted along
                             a Morton curve in runs of this many (screen_order.h),
                             as a tracer rank sorts each batch; 0: not sorted */
    uint32_t epoch;       /* the requests' epoch (frame index for --frames) */
    size_t raylog_cap;    /* rays logged per thread for the raw replay (0: none);
                             a uniform random subset of the traced rays */
    int bench_runs;       /* with a ray log: rounds of a timed render and the raw
                             replays, interleaved; the fastest of each counts (>= 1) */
    const char *progress; /* progress line component, NULL: silent */
} render_options;

/* The order pixels are traced in. The image does not depend on it (a
 * request's id and jitter come from its pixel); the speed does: shuffled
 * pixels are spread over the image as the request queue's are, a
 * benchmark of how much the tracer owes to coherent rays. */
enum {
    RENDER_ORDER_TILES = 0,     /* square tiles, rows within a tile */
    RENDER_ORDER_SHUFFLED = 1   /* a seeded shuffle of every pixel, tile x tile per task */
};

/* Defaults: 1 sample, 1 thread, 16-pixel tiles in tile order, epoch 0, no ray log. */
void render_options_default(render_options *o, int width, int height);

typedef struct render_result {
    double seconds;        /* wall time of the render (without the ray-logging pass;
                              with a ray log, the faster of two renders) */
    trc_stats stats;       /* summed over threads (log unset) */
    uint64_t logged;       /* rays logged for the replay */
    double replay_isect_s; /* wall time replaying them all with rtcIntersect1 */
    double replay_traced_s;/* wall time replaying them as traced (shadow: rtcOccluded1) */
} render_result;

/* Renders the view into rgb (width * height * 3 floats, row 0 at the top:
 * the mean L_hq of each pixel). */
int render_image(const trc_tracer *t, const ct_camera *cam, const render_options *o, float *rgb,
                 render_result *res, ct_error *err);

#endif

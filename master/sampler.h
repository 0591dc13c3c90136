/* sampler.h: the master's adaptive sample acquisition (§3.7), independent of
 * MPI and sockets. An rq_engine owns the request priority queue, the mask of
 * sampled pixels, the remaining-pixel list, the in-flight requests and the
 * n_sig most significant samples of the current view. The loop that drives it
 * (the MPI scheduler, `corrtex converge`) does:
 *
 *   rq_new(&e, w, h, &cam, &opt, seed, &err);
 *   loop: k = rq_next_batch(e, reqs, n, &err);         hand reqs to tracers
 *         for each returned sample s:              (compute E with ctex_*)
 *             rq_report(e, &s, E, shown_node, &err);
 *         on a camera change: rq_set_camera(e, &cam, epoch, &err);
 *         rq_stats(e, &st): st.coverage == 1 means every pixel was handed out.
 *
 * Determinism: for a given seed and the same sequence of calls with the same
 * sample values, every batch is identical (ids, positions, radii, priorities)
 * whatever the number of tracers; lockstep mode reports each batch's samples
 * in request-id order. See docs/sampling.md for the algorithm. */
#ifndef CT_SAMPLER_H
#define CT_SAMPLER_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#include "common/camera.h"
#include "common/error.h"
#include "common/optab.h"
#include "common/vecmath.h"
#include "common/records.h"

typedef struct rq_engine rq_engine;

/* The norm that turns the RGB error E into the scalar |E|. */
typedef enum rq_norm {
    RQ_NORM_MAX = 0,  /* max(|E.r|, |E.g|, |E.b|): default */
    RQ_NORM_LUM = 1,  /* Rec. 709 luminance of (|E.r|, |E.g|, |E.b|) */
    RQ_NORM_AVG = 2   /* mean of |E.r|, |E.g|, |E.b| */
} rq_norm;

/* Node ids for rq_report's shown_node argument. */
#define RQ_NODE_UNKNOWN UINT32_MAX          /* the caller does not know: no check */
#define RQ_NODE_NONE    (UINT32_MAX - 1u)   /* the interactive image shows background */

/* Flags returned by rq_report (>= 0). */
enum {
    RQ_REPORT_STALE    = 1,  /* the sample belongs to an older epoch: ignored */
    RQ_REPORT_MISMATCH = 2,  /* hit node != shown node */
    RQ_REPORT_REFINE   = 4   /* a refinement sample in its pixel's mean: write it (ctex_refine) */
};

/* Every tunable parameter, with its default (rq_options_default). */
typedef struct rq_options {
    int children;           /* N children per sample; §3.7: N = 4 */
    float min_priority;     /* children with |E| * s_c below this are discarded */
    float min_radius;       /* no children when s_c < this (pixels) */
    int n_sig;              /* significant samples kept per view; §3.7 n_sig */
    float seed_spacing;     /* spacing of the initial jittered grid (pixels) */
    int global_batch;       /* global requests added each time the queue runs dry */
    int global_tries;       /* random positions tried per global request */
    float coverage_switch;  /* coverage at which the remaining-pixel list takes over */
    rq_norm norm;           /* RGB norm of E */
    float prio_reproject;   /* priority of reprojected significant samples */
    float prio_seed;        /* priority of initial, global and list requests */
    float prio_mismatch;    /* priority of children of node-mismatch samples */
    int reseed;             /* 1: a new epoch also gets a fresh initial grid */
    long max_queue;         /* cap on queued requests; 0 = width * height */
    float refine_error;     /* past full coverage: refine pixels whose mean's error is over this (0: off) */
    int refine_max;         /* samples per pixel at most when refining */
} rq_options;

/* Statistics since rq_new (counters) and of the current epoch (coverage). */
typedef struct rq_stats {
    uint64_t popped;              /* requests handed out by rq_next_batch */
    uint64_t reported;            /* samples accepted by rq_report */
    uint64_t stale;               /* samples of older epochs ignored */
    uint64_t discarded_mask;      /* requests for already-sampled pixels */
    uint64_t discarded_threshold; /* children under min_priority */
    uint64_t discarded_outside;   /* children outside the image */
    uint64_t discarded_full;      /* requests dropped because the queue was full */
    uint64_t leaves;              /* samples whose children would be below min_radius */
    uint64_t seeds;               /* initial-grid requests queued */
    uint64_t children;            /* children queued (mismatch children included) */
    uint64_t global;              /* global requests queued */
    uint64_t from_list;           /* requests taken from the remaining-pixel list */
    uint64_t mismatches;          /* samples whose hit node != shown node */
    uint64_t reprojected;         /* significant samples re-queued on camera changes */
    uint64_t reproject_dropped;   /* significant samples that left the new view */
    uint64_t allocations;         /* buffer (re)allocations since rq_new */
    uint64_t queued;              /* requests in the queue now */
    uint64_t in_flight;           /* handed out, not yet reported, this epoch */
    uint64_t peak_queued;         /* largest queue size seen */
    uint32_t epoch;               /* current camera epoch */
    int list_mode;                /* 1 once the remaining-pixel list is in use */
    uint64_t sampled_pixels;      /* pixels handed out this epoch */
    uint64_t total_pixels;        /* width * height */
    double coverage;              /* sampled_pixels / total_pixels */
    int covered;                  /* every pixel handed out and its first sample reported */
    int refining;                 /* 1 once every pixel was handed out and refinement goes on */
    uint64_t refine_samples;      /* refinement samples reported this epoch */
    float refine_error;           /* priority of the last pixel refined: the largest error left */
} rq_stats;

/* Fills *o with the defaults (docs/sampling.md lists them). */
void rq_options_default(rq_options *o);

/* Sets one option by its command-line name without "--" (e.g. "children",
 * "min-priority"); CT_EINVAL with a message naming it on a bad name or value. */
int rq_options_set(rq_options *o, const char *name, const char *value, ct_error *err);

/* The option table (common/optab.h): one row per option with its default. */
const optab *rq_options_table(size_t *n);

/* Prints one "--name VALUE  help (default X)" line per option to f. */
void rq_options_usage(FILE *f);

/* Checks ranges; CT_EINVAL naming the first bad option. */
int rq_options_check(const rq_options *o, ct_error *err);

/* About the most bytes an engine holds for a width x height image under o:
 * the request queue at its cap (one request a pixel, or --max-queue; its
 * priority buckets grow by doubling), the sample mask and, when refining,
 * the per-pixel records and their queue. What a view's size costs before
 * anything is allocated (the master refuses views over its budget). */
uint64_t rq_view_bytes(int width, int height, const rq_options *o);

/* Creates an engine for a width x height image seen by cam at epoch 0 and
 * queues the initial grid. opt NULL = defaults. */
int rq_new(rq_engine **out, int width, int height, const ct_camera *cam,
           const rq_options *opt, uint64_t seed, ct_error *err);

/* Frees the engine (NULL is fine). */
void rq_free(rq_engine *e);

/* Writes up to n requests of the current epoch into out and returns how many
 * (fewer than n only when every pixel of this epoch has been handed out), or
 * CT_ENOMEM when a buffer could not grow. Allocates only when one must grow. */
int rq_next_batch(rq_engine *e, ct_request *out, int n, ct_error *err);

/* Reports a finished sample with its error E = L_hq - (L_base + dL) and the
 * node the interactive image shows at its pixel (RQ_NODE_UNKNOWN: no check).
 * Returns RQ_REPORT_* flags (>= 0), or CT_EPROTO for a request that is not
 * outstanding or from a future epoch, CT_EINVAL for a non-finite E. */
int rq_report(rq_engine *e, const ct_sample *s, vec3 E, uint32_t shown_node, ct_error *err);

/* Asks the caches for what rq_report(s) will touch that lies anywhere in
 * megabytes (its request's record, its pixel's refinement state): a caller
 * reporting a run of samples calls it a few samples ahead. */
void rq_report_prefetch(const rq_engine *e, const ct_sample *s);

/* A new camera with a new epoch (> the current one): drops every queued and
 * in-flight request, clears the mask, reprojects the significant samples
 * into the new view at prio_reproject. CT_EINVAL on an old epoch or a bad camera. */
int rq_set_camera(rq_engine *e, const ct_camera *cam, uint32_t epoch, ct_error *err);

/* Whether outstanding request id is a refinement request (its sample is not
 * splatted: the caller writes it into its pixel's texels, ctex_refine with
 * rq_pixel_samples, after rq_report when that says RQ_REPORT_REFINE). */
bool rq_refines(const rq_engine *e, uint64_t id);

/* The mean correction dL of the samples of the pixel at image position
 * (px, py) in the current view (docs/sampling.md, "Refinement"): the
 * queue's own estimate, whose uncertainty sets the pixel's priority. The
 * texels are not set to it (ctex_refine starts from the first pass's
 * value); tests read it to check the queue. */
vec3 rq_pixel_mean(const rq_engine *e, float px, float py);

/* How many samples the pixel at (px, py) has had in the current view. */
uint16_t rq_pixel_samples(const rq_engine *e, float px, float py);

/* Fills *st. */
void rq_stats_get(const rq_engine *e, rq_stats *st);

/* The scalar error |E| under norm. */
float rq_error_norm(vec3 E, rq_norm norm);

#endif

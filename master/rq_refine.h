/* rq_refine.h: sampling past full coverage (docs/sampling.md, "Refinement").
 * §3.7 ends when every pixel of a still view has one sample; one drt sample
 * is a noisy estimate, so the view keeps its noise forever. Refinement keeps
 * per pixel of the current view the running mean of its samples'
 * corrections dL = L_hq - L_base and the variance of their luminance
 * (Welford), and hands out further samples at the pixel whose mean is least
 * certain: the standard error sqrt(var / n), or, with fewer than four
 * samples, at least the first one's prior over sqrt(n): the larger of its
 * error |E| against what was displayed and its luminance's difference from
 * the mean of its four neighbours' (one sample per pixel says little about
 * a pixel's noise, its neighbours' spread more); under 16 samples its
 * variance is shrunk towards its neighbours' where theirs is larger (a few
 * samples that agree by chance prove nothing beside noisy ones); pixels
 * under the threshold get no more.
 * The master moves the pixel's texels towards each further sample
 * (ctex_refine, with the pixel's count from rq_refine_samples). Pixel state
 * carries the epoch it belongs to, so a camera change costs nothing.
 * Owns the rq_refine_ prefix; internal to the request queue (rq_engine.c). */
#ifndef CT_MASTER_RQ_REFINE_H
#define CT_MASTER_RQ_REFINE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/error.h"
#include "common/vecmath.h"
#include "master/rq_heap.h"

/* One pixel's samples in the current epoch. */
typedef struct rq_pixel {
    float mean[3];      /* running mean of dL */
    float m2;           /* sum of squared deviations of dL's luminance */
    float first_err;    /* its prior: |E| of its first sample, or the neighbours' contrast */
    float base;         /* luminance of L_base at its first sample: displayed = base + lum(mean) */
    uint32_t node;      /* the node its first sample hit */
    uint16_t n;         /* samples, 0 .. the option's maximum */
    uint16_t tag;       /* the refine epoch it belongs to */
} rq_pixel;

typedef struct rq_refine {
    rq_pixel *px;           /* npx records, mapped (px_bytes) */
    size_t npx, px_bytes;
    int w, h;
    uint16_t tag;
    bool active;            /* every pixel was handed out: refining */
    float threshold;        /* no more samples for a pixel under this priority */
    uint16_t max_n;         /* nor for one with this many */
    /* Pixels waiting for a further sample: key = rq_key(priority, seq),
     * tag = the pixel, aux = its sample count when queued (stale when it
     * differs). Buckets of 4-ary heaps (rq_heap.h), not one binary heap:
     * a master fed a few hundred thousand refinement samples a second
     * spent a fifth of its time in this queue's sift-downs, a cache miss a
     * level over a million pixels (docs/sampling.md, "Refinement"). */
    rq_heap q;
    uint32_t seq;           /* pushes this epoch (ties: first queued first) */
    float top;              /* priority of the last pixel handed out (the largest left); 0 when none is */
    uint64_t samples;       /* refinement samples reported, this epoch */
} rq_refine;

/* Pixel state for a w x h image (zero pages until touched). */
int rq_refine_init(rq_refine *r, int w, int h, float threshold, uint16_t max_n, ct_error *err);
void rq_refine_free(rq_refine *r);

/* A new view: every pixel's samples are forgotten. */
void rq_refine_epoch(rq_refine *r);

/* A sample of pixel p that hit `node`: its correction dL, the luminance of
 * its L_base and its error norm |E|. A sample on another node than the
 * pixel's first one (a silhouette) counts towards n but not into the mean:
 * the mean is written into that node's texture. While refining, the pixel
 * is queued again with its new priority. Returns 1 when the sample entered
 * the mean, 0 when not, negative on failure. */
int rq_refine_add(rq_refine *r, uint32_t p, uint32_t node, vec3 dl, float base_lum, float err_norm,
                  ct_error *err);

/* A refinement sample of pixel p that hit nothing (a silhouette against
 * the background): counted towards n as a sample on another node is, and
 * the pixel queued again, so it goes on refining its node's part instead
 * of leaving the queue at its first miss. Pixels without a record (their
 * first sample missed) stay out. Returns 0, negative on failure. */
int rq_refine_miss(rq_refine *r, uint32_t p, ct_error *err);

/* Starts refining: every pixel with a sample is queued. */
int rq_refine_start(rq_refine *r, ct_error *err);

/* The pixel that needs a sample most, and its priority; false when none
 * is over the threshold (or all wait for their samples); top is then 0. */
bool rq_refine_next(rq_refine *r, uint32_t *p, float *prio);

/* The mean dL of pixel p (zero without samples). */
vec3 rq_refine_mean(const rq_refine *r, uint32_t p);

/* Pixel p's samples in this epoch (those on another node included). */
uint16_t rq_refine_samples(const rq_refine *r, uint32_t p);

/* The priority pixel p's next sample would have: the uncertainty of its
 * mean as a viewer sees it, in display units at exposure 0 (linear
 * luminance times img_tonemap_slope of the displayed luminance), so a dark
 * pixel's noise counts as much as it shows. */
float rq_refine_priority(const rq_refine *r, uint32_t p);

#endif

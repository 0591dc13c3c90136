/* rq_refine.c: refinement past full coverage (rq_refine.h). */
#include "master/rq_refine.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/hugemem.h"
#include "common/image.h"

int rq_refine_init(rq_refine *r, int w, int h, float threshold, uint16_t max_n, ct_error *err)
{
    size_t npx = (size_t)w * (size_t)h;
    memset(r, 0, sizeof *r);
    r->w = w;
    r->h = h;
    /* Every report updates its pixel's record, anywhere in 32 MiB at
     * 1024^2: as huge pages (bench_rq "zero": rq_refine_add was 64 % of the
     * queue's time with 4 KiB pages), zeroed by the kernel as touched. */
    r->px_bytes = npx * sizeof *r->px;
    r->px = ct_huge_zalloc(r->px_bytes);
    if (!r->px) return ct_fail(err, CT_ENOMEM, "sampler: out of memory for the refinement of %zu pixels", npx);
    if (rq_heap_init_keys(&r->q, 0, err)) {
        ct_huge_zfree(r->px, r->px_bytes);
        r->px = NULL;
        return CT_ENOMEM;
    }
    r->npx = npx;
    r->tag = 1;
    r->threshold = threshold;
    r->max_n = max_n;
    return 0;
}

void rq_refine_free(rq_refine *r)
{
    ct_huge_zfree(r->px, r->px_bytes);
    rq_heap_free(&r->q);
    memset(r, 0, sizeof *r);
}

void rq_refine_epoch(rq_refine *r)
{
    if (!r->px) return;
    if (++r->tag == 0) {
        /* 65,535 views later the tags come round: start clean. */
        memset(r->px, 0, r->npx * sizeof *r->px);
        r->tag = 1;
    }
    r->active = false;
    rq_heap_clear(&r->q);
    r->seq = 0;
    r->top = 0.0f;
    r->samples = 0;
}

/* A pixel whose first sample differed from what was displayed gets at
 * least this many samples before its sample variance is believed: a few
 * equal values of a noisy pixel (K shadow rays give K + 1 levels) must not
 * pass for certainty. */
#define MIN_TRUSTED 4

/* Below this many samples a pixel's variance is shrunk towards its
 * neighbours' (SHRINK_K samples' worth of it) when theirs is larger. Past
 * MIN_TRUSTED a pixel whose samples happened to agree still passed for
 * certain: on the diffuse Cornell box half of the drt samples of the short
 * box's dark front face are 0 (every gather ray's lamp sample shadowed), so
 * one pixel in 16 saw four zeros, stopped at a mean of -L_base and stayed a
 * third as bright as the truth for good, a block in 16 with one or two of
 * them (tests/e2e/render_regions.sh failed a 10 % bound on it). A pixel
 * truly flat beside noisy ones pays at most this many samples. */
#define SHRINK_UNTIL 16
#define SHRINK_K 4.0f

static float var_of(const rq_pixel *x)
{
    return x->n > 1 ? x->m2 / (float)(x->n - 1) : 0.0f;
}

static float lum_of(const rq_pixel *x)
{
    return v3_luminance(v3(x->mean[0], x->mean[1], x->mean[2]));
}

/* The mean of f over p's 4-neighbours on its node with at least min_n
 * samples; 0 when there is none (*count: how many). */
static float neighbours_mean(const rq_refine *r, uint32_t p, uint16_t min_n, float (*f)(const rq_pixel *), int *count)
{
    const rq_pixel *x = &r->px[p];
    int px = (int)(p % (uint32_t)r->w), py = (int)(p / (uint32_t)r->w);
    const int dx[4] = {-1, 1, 0, 0}, dy[4] = {0, 0, -1, 1};
    float sum = 0.0f;
    int n = 0;
    for (int k = 0; k < 4; k++) {
        int qx = px + dx[k], qy = py + dy[k];
        if (qx < 0 || qy < 0 || qx >= r->w || qy >= r->h) continue;
        const rq_pixel *q = &r->px[(size_t)qy * (size_t)r->w + (size_t)qx];
        if (q->tag != r->tag || q->n < min_n || q->node != x->node) continue;
        sum += f(q);
        n++;
    }
    *count = n;
    return n ? sum / (float)n : 0.0f;
}

float rq_refine_priority(const rq_refine *r, uint32_t p)
{
    const rq_pixel *x = &r->px[p];
    if (x->tag != r->tag || x->n == 0) return 0.0f;
    float var = var_of(x);
    if (x->n > 1 && x->n < SHRINK_UNTIL) {
        int nn;
        float vn = neighbours_mean(r, p, 2, var_of, &nn);
        if (vn > var) var = (x->m2 + SHRINK_K * vn) / ((float)(x->n - 1) + SHRINK_K);
    }
    float se = sqrtf(var / (float)x->n);
    if (x->n < MIN_TRUSTED && x->first_err / sqrtf((float)x->n) > se) se = x->first_err / sqrtf((float)x->n);
    /* A linear threshold let dark pixels keep one sample's noise: on the
     * diffuse Cornell box the short box's front face (linear 0.02-0.05)
     * ended 20 % off the path-traced truth in 4 x 4 blocks while the bright
     * walls converged to 1-2 %. */
    float shown = x->base + v3_luminance(v3(x->mean[0], x->mean[1], x->mean[2]));
    return se * img_tonemap_slope(shown);
}

/* A pixel's first sample against its neighbours' (those with a sample of
 * the same node): the difference of its luminance from their mean. */
static float contrast(const rq_refine *r, uint32_t p)
{
    int n;
    float m = neighbours_mean(r, p, 1, lum_of, &n);
    return n ? fabsf(lum_of(&r->px[p]) - m) : 0.0f;
}

/* Queues pixel p when it may take another sample. */
static int queue(rq_refine *r, uint32_t p, ct_error *err)
{
    const rq_pixel *x = &r->px[p];
    float prio = rq_refine_priority(r, p);
    if (x->n >= r->max_n || !(prio > r->threshold)) return 0;
    if (rq_heap_push_key(&r->q, rq_key(prio, r->seq), p, x->n))
        return ct_fail(err, CT_ENOMEM, "sampler: out of memory for %zu pixels to refine", r->q.n + 1);
    r->seq++;
    return 0;
}

/* --- samples -------------------------------------------------------------------- */

int rq_refine_add(rq_refine *r, uint32_t p, uint32_t node, vec3 dl, float base_lum, float err_norm,
                  ct_error *err)
{
    if (!r->px || p >= r->npx) return 0;
    rq_pixel *x = &r->px[p];
    if (x->tag != r->tag) {
        memset(x, 0, sizeof *x);
        x->tag = r->tag;
        x->node = node;
        x->base = base_lum;
    }
    if (x->n == UINT16_MAX) return 0;
    if (node != x->node) {
        x->n++;
        if (r->active) r->samples++;
        int rc = r->active ? queue(r, p, err) : 0;
        return rc < 0 ? rc : 0;
    }
    /* Welford: the mean of dL, the squared deviations of its luminance. */
    float y_old = x->n ? v3_luminance(v3(x->mean[0], x->mean[1], x->mean[2])) : 0.0f;
    x->n++;
    float inv = 1.0f / (float)x->n;
    x->mean[0] += (dl.x - x->mean[0]) * inv;
    x->mean[1] += (dl.y - x->mean[1]) * inv;
    x->mean[2] += (dl.z - x->mean[2]) * inv;
    float y = v3_luminance(dl);
    float y_new = v3_luminance(v3(x->mean[0], x->mean[1], x->mean[2]));
    if (x->n == 1) {
        x->first_err = err_norm;
        if (r->active) {
            float c = contrast(r, p);
            if (c > x->first_err) x->first_err = c;
        }
    } else {
        x->m2 += (y - y_old) * (y - y_new);
    }
    if (!r->active) return 1;
    r->samples++;
    int rc = queue(r, p, err);
    return rc < 0 ? rc : 1;
}

int rq_refine_miss(rq_refine *r, uint32_t p, ct_error *err)
{
    if (!r->px || p >= r->npx) return 0;
    if (r->active) r->samples++;
    rq_pixel *x = &r->px[p];
    if (x->tag != r->tag || x->n == 0 || x->n == UINT16_MAX) return 0;
    x->n++;
    int rc = r->active ? queue(r, p, err) : 0;
    return rc < 0 ? rc : 0;
}

int rq_refine_start(rq_refine *r, ct_error *err)
{
    if (!r->px || r->active) return 0;
    r->active = true;
    rq_heap_clear(&r->q);
    r->seq = 0;
    /* Every pixel has its first sample now (or it is in flight): the
     * neighbours' contrast is known. */
    for (size_t p = 0; p < r->npx; p++) {
        rq_pixel *x = &r->px[p];
        if (x->tag != r->tag || x->n != 1) continue;
        float c = contrast(r, (uint32_t)p);
        if (c > x->first_err) x->first_err = c;
    }
    for (size_t p = 0; p < r->npx; p++) {
        const rq_pixel *x = &r->px[p];
        if (x->tag != r->tag || x->n == 0) continue;
        int rc = queue(r, (uint32_t)p, err);
        if (rc) return rc;
    }
    return 0;
}

bool rq_refine_next(rq_refine *r, uint32_t *p, float *prio)
{
    uint64_t key;
    uint32_t pixel, n;
    while (rq_heap_pop_key(&r->q, &key, &pixel, &n)) {
        const rq_pixel *x = &r->px[pixel];
        if (x->tag != r->tag || x->n != n) continue;   /* queued again since */
        /* the next pixel's record, read by the next call (a batch pops
         * thousands in a row, each one a miss over the view's records) */
        if (r->q.n) __builtin_prefetch(&r->px[rq_heap_top_tag(&r->q)], 0, 1);
        *p = pixel;
        *prio = rq_key_priority(key);
        r->top = *prio;
        return true;
    }
    r->top = 0.0f;
    return false;
}

uint16_t rq_refine_samples(const rq_refine *r, uint32_t p)
{
    if (!r->px || p >= r->npx || r->px[p].tag != r->tag) return 0;
    return r->px[p].n;
}

vec3 rq_refine_mean(const rq_refine *r, uint32_t p)
{
    if (!r->px || p >= r->npx || r->px[p].tag != r->tag) return v3s(0.0f);
    const rq_pixel *x = &r->px[p];
    return v3(x->mean[0], x->mean[1], x->mean[2]);
}

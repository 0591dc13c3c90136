/* screen_order.h: requests and pixels in screen order (a Morton curve over
 * their pixels). The request queue hands out requests spread over the
 * whole image, highest error first; traced in that order, consecutive
 * samples share no BVH nodes, triangles or mesh vertices in the cache: the
 * tracer alone traced 25 % fewer samples a second on table and office at
 * 1024^2 with its pixels shuffled than in tiles, and runs of 4096 sorted
 * along the curve got back a third to two fifths of that
 * (docs/benchmarks.md, "Tracer: request order"). Each sample's randomness
 * is its own (tracer.h), so the order changes no result.
 * Owns the so_ prefix. */
#ifndef CT_TRACER_SCREEN_ORDER_H
#define CT_TRACER_SCREEN_ORDER_H

#include <stddef.h>
#include <stdint.h>

#include "common/error.h"
#include "common/records.h"

/* The Morton code of pixel (x, y), 16 bits per axis (larger values clamp). */
uint32_t so_key(uint32_t x, uint32_t y);

/* Scratch kept between calls (zero-initialised before the first). */
typedef struct so_buf {
    uint64_t *k;
    size_t cap;
} so_buf;

void so_free(so_buf *b);

/* perm[0..n): the indices of req[0..n) along the curve through their pixels
 * (positions clamped into 0..65535; ties keep their order). CT_ENOMEM
 * without room for the keys (perm is then the identity). */
int so_requests(so_buf *b, const ct_request *req, size_t n, uint32_t *perm);

/* A batch of requests in screen order and room for its samples, kept
 * between batches (zero-initialised before the first): what a tracer rank
 * and the in-process port trace a batch through. */
typedef struct so_batch {
    so_buf keys;
    uint32_t *perm;
    ct_request *req;   /* the batch along the curve (so_batch_order) */
    ct_sample *out;    /* room for their samples, traced in that order */
    size_t cap;
} so_batch;

void so_batch_free(so_batch *b);

/* b->req[0..n): req[0..n) along the curve. CT_ENOMEM without the memory:
 * trace the batch as it came. */
int so_batch_order(so_batch *b, const ct_request *req, size_t n);

/* out[0..n): b->out[0..n) back in the order of the requests that
 * so_batch_order was given. */
void so_batch_scatter(const so_batch *b, size_t n, ct_sample *out);

/* Sorts pix[0..n) (pixel indices y * width + x) along the curve in place,
 * in runs of `run` (0 or >= n: all at once). CT_ENOMEM as above (pix is
 * then unchanged). */
int so_pixels(so_buf *b, uint32_t *pix, size_t n, uint32_t width, size_t run);

#endif

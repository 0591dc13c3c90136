/* rq_mask.h: the sampler's mask of sampled pixels (one bit per pixel) and
 * the shuffled list of the pixels still unsampled (§3.7: "a mask of sampled
 * pixel positions ... a special queue containing the remaining pixels").
 * Testing and setting a pixel never allocates; the list is built once per
 * camera epoch into a buffer that is reused. */
#ifndef CT_RQ_MASK_H
#define CT_RQ_MASK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/error.h"

typedef struct rq_mask {
    uint64_t *bits;     /* w*h bits, row-major */
    int w, h;
    uint64_t count;     /* pixels set */
    uint32_t *list;     /* remaining pixels (shuffled), valid when list_n > 0 */
    size_t list_n, list_cap, list_pos;
    uint64_t grows;     /* allocations made so far */
} rq_mask;

/* Allocates a cleared mask for a w x h image. */
int rq_mask_init(rq_mask *m, int w, int h, ct_error *err);

/* Frees the mask; m may be zeroed or initialised. */
void rq_mask_free(rq_mask *m);

/* Clears every pixel and drops the remaining list. */
void rq_mask_clear(rq_mask *m);

/* Whether pixel index p (y * w + x) is set. */
static inline bool rq_mask_test(const rq_mask *m, uint32_t p)
{
    return (m->bits[p >> 6] >> (p & 63)) & 1u;
}

/* Sets pixel p; returns whether it was set already. */
static inline bool rq_mask_test_set(rq_mask *m, uint32_t p)
{
    uint64_t bit = (uint64_t)1 << (p & 63);
    uint64_t *w = &m->bits[p >> 6];
    if (*w & bit) return true;
    *w |= bit;
    m->count++;
    return false;
}

/* Builds the list of unset pixels, shuffled (Fisher-Yates) with the stream
 * (seed, epoch). Returns 0 or CT_ENOMEM. */
int rq_mask_build_list(rq_mask *m, uint64_t seed, uint32_t epoch, ct_error *err);

/* Next pixel of the list that is still unset (and sets it); false when the
 * list is exhausted. */
bool rq_mask_list_next(rq_mask *m, uint32_t *p);

#endif

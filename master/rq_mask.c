/* rq_mask.c: sampled-pixel bitmask and remaining-pixel list (rq_mask.h). */
#include "master/rq_mask.h"

#include <stdlib.h>
#include <string.h>

#include "common/rng.h"

/* Stream selector of the list shuffle (see rq_engine.c for the others). */
#define STREAM_LIST 0x4c495354u

int rq_mask_init(rq_mask *m, int w, int h, ct_error *err)
{
    memset(m, 0, sizeof *m);
    if (w <= 0 || h <= 0 || (uint64_t)w * (uint64_t)h > UINT32_MAX)
        return ct_fail(err, CT_EINVAL, "sample mask: bad image size %dx%d", w, h);
    size_t words = ((size_t)w * (size_t)h + 63) / 64;
    m->bits = calloc(words, sizeof *m->bits);
    if (!m->bits)
        return ct_fail(err, CT_ENOMEM, "sample mask: cannot allocate %dx%d bits", w, h);
    m->w = w;
    m->h = h;
    m->grows = 1;
    return 0;
}

void rq_mask_free(rq_mask *m)
{
    free(m->bits);
    free(m->list);
    memset(m, 0, sizeof *m);
}

void rq_mask_clear(rq_mask *m)
{
    memset(m->bits, 0, ((size_t)m->w * (size_t)m->h + 63) / 64 * sizeof *m->bits);
    m->count = 0;
    m->list_n = m->list_pos = 0;
}

int rq_mask_build_list(rq_mask *m, uint64_t seed, uint32_t epoch, ct_error *err)
{
    size_t total = (size_t)m->w * (size_t)m->h;
    size_t need = total - (size_t)m->count;
    if (need > m->list_cap) {
        uint32_t *nl = realloc(m->list, (need ? need : 1) * sizeof *nl);
        if (!nl)
            return ct_fail(err, CT_ENOMEM, "sample mask: cannot allocate a list of %zu pixels", need);
        m->list = nl;
        m->list_cap = need;
        m->grows++;
    }
    size_t n = 0;
    size_t words = (total + 63) / 64;
    for (size_t wi = 0; wi < words; wi++) {
        uint64_t free_bits = ~m->bits[wi];
        if (wi == words - 1 && (total & 63)) free_bits &= ((uint64_t)1 << (total & 63)) - 1;
        while (free_bits) {
            int b = __builtin_ctzll(free_bits);
            free_bits &= free_bits - 1;
            m->list[n++] = (uint32_t)(wi * 64 + (size_t)b);
        }
    }
    ct_rng r = rng_make(seed, epoch, STREAM_LIST, 0);
    for (size_t i = n; i > 1; i--) {
        size_t j = rng_below(&r, (uint32_t)i);
        uint32_t t = m->list[i - 1];
        m->list[i - 1] = m->list[j];
        m->list[j] = t;
    }
    m->list_n = n;
    m->list_pos = 0;
    return 0;
}

bool rq_mask_list_next(rq_mask *m, uint32_t *p)
{
    while (m->list_pos < m->list_n) {
        uint32_t q = m->list[m->list_pos++];
        if (!rq_mask_test_set(m, q)) {
            *p = q;
            return true;
        }
    }
    return false;
}

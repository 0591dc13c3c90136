/* screen_order.c: requests and pixels along a Morton curve (screen_order.h). */
#include "tracer/screen_order.h"

#include <stdlib.h>
#include <string.h>

/* Interleaves the low 16 bits of x with zeros (a Morton code's half). */
static uint32_t spread16(uint32_t x)
{
    x &= 0xffffu;
    x = (x | (x << 8)) & 0x00ff00ffu;
    x = (x | (x << 4)) & 0x0f0f0f0fu;
    x = (x | (x << 2)) & 0x33333333u;
    x = (x | (x << 1)) & 0x55555555u;
    return x;
}

uint32_t so_key(uint32_t x, uint32_t y)
{
    if (x > 0xffffu) x = 0xffffu;
    if (y > 0xffffu) y = 0xffffu;
    return spread16(x) | spread16(y) << 1;
}

void so_free(so_buf *b)
{
    free(b->k);
    b->k = NULL;
    b->cap = 0;
}

static int reserve(so_buf *b, size_t n)
{
    if (n <= b->cap) return CT_OK;
    uint64_t *k = realloc(b->k, n * sizeof *k);
    if (!k) return CT_ENOMEM;
    b->k = k;
    b->cap = n;
    return CT_OK;
}

/* The key in the high half, the position below it: ties keep their order. */
static int by_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* A pixel coordinate of a position: clamped into 0..65535. */
static uint32_t coord(float p)
{
    return p > 0.0f ? (p < 65535.0f ? (uint32_t)p : 65535u) : 0u;
}

int so_requests(so_buf *b, const ct_request *req, size_t n, uint32_t *perm)
{
    if (reserve(b, n) != CT_OK) {
        for (size_t i = 0; i < n; i++) perm[i] = (uint32_t)i;
        return CT_ENOMEM;
    }
    for (size_t i = 0; i < n; i++) b->k[i] = (uint64_t)so_key(coord(req[i].px), coord(req[i].py)) << 32 | i;
    qsort(b->k, n, sizeof *b->k, by_u64);
    for (size_t i = 0; i < n; i++) perm[i] = (uint32_t)b->k[i];
    return CT_OK;
}

void so_batch_free(so_batch *b)
{
    so_free(&b->keys);
    free(b->perm);
    free(b->req);
    free(b->out);
    memset(b, 0, sizeof *b);
}

int so_batch_order(so_batch *b, const ct_request *req, size_t n)
{
    if (n > b->cap) {
        uint32_t *p = realloc(b->perm, n * sizeof *p);
        if (p) b->perm = p;
        ct_request *r = p ? realloc(b->req, n * sizeof *r) : NULL;
        if (r) b->req = r;
        ct_sample *s = r ? realloc(b->out, n * sizeof *s) : NULL;
        if (!s) return CT_ENOMEM;
        b->out = s;
        b->cap = n;
    }
    if (so_requests(&b->keys, req, n, b->perm) != CT_OK) return CT_ENOMEM;
    for (size_t i = 0; i < n; i++) b->req[i] = req[b->perm[i]];
    return CT_OK;
}

void so_batch_scatter(const so_batch *b, size_t n, ct_sample *out)
{
    for (size_t i = 0; i < n; i++) out[b->perm[i]] = b->out[i];
}

int so_pixels(so_buf *b, uint32_t *pix, size_t n, uint32_t width, size_t run)
{
    if (width == 0) return CT_EINVAL;
    if (run == 0 || run > n) run = n;
    if (reserve(b, run) != CT_OK) return CT_ENOMEM;
    for (size_t a = 0; a < n; a += run) {
        size_t m = n - a < run ? n - a : run;
        for (size_t i = 0; i < m; i++) {
            uint32_t p = pix[a + i];
            b->k[i] = (uint64_t)so_key(p % width, p / width) << 32 | p;
        }
        qsort(b->k, m, sizeof *b->k, by_u64);
        for (size_t i = 0; i < m; i++) pix[a + i] = (uint32_t)b->k[i];
    }
    return CT_OK;
}

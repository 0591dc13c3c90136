/* ctex_dirty.c: the unsent-tile maps of a corrective texture (ctex_dirty.h). */
#include "master/ctex_dirty.h"

#include <stdlib.h>
#include <string.h>

int ctex_dirty_reset(ctex_dirty *d, int w, int h, ct_error *err)
{
    int tw = (w + CTEX_TILE - 1) >> CTEX_TILE_SHIFT, th = (h + CTEX_TILE - 1) >> CTEX_TILE_SHIFT;
    int words = (tw + 63) >> 6;
    uint32_t carried = 0;
    for (int i = 0; d->row_n && i < d->th; i++) carried += d->row_n[i];
    if (tw != d->tw || th != d->th || !d->bits) {
        uint64_t *bits = calloc((size_t)th * (size_t)words, sizeof *bits);
        uint64_t *rt = calloc((size_t)th, sizeof *rt);
        uint32_t *rn = calloc((size_t)th, sizeof *rn);
        if (!bits || !rt || !rn) {
            free(bits);
            free(rt);
            free(rn);
            return ct_fail(err, CT_ENOMEM, "out of memory for the tile map of a %dx%d texture", w, h);
        }
        ctex_dirty_free(d);
        d->bits = bits;
        d->row_t = rt;
        d->row_n = rn;
        d->tw = tw;
        d->th = th;
        d->words = words;
    } else {
        memset(d->row_n, 0, (size_t)th * sizeof *d->row_n);
    }
    d->row_n[0] = carried;
    ctex_dirty_mark_all(d);
    return CT_OK;
}

/* The new texels [*lo, *hi] computed from old texels [a, b] of an axis of
 * n texels resized to nn (kept, doubled or halved). */
static void axis_span(int n, int nn, int a, int b, int *lo, int *hi)
{
    if (nn == n) {
        *lo = a, *hi = b;
    } else if (nn > n) {
        /* new texel 2i + 1 reads i + 1, 2i + 2 reads i - 1... and i itself */
        *lo = 2 * a - 1 < 0 ? 0 : 2 * a - 1;
        *hi = 2 * b + 2 > nn - 1 ? nn - 1 : 2 * b + 2;
    } else {
        *lo = a / 2, *hi = b / 2;
    }
}

int ctex_dirty_rescale(ctex_dirty *d, int w, int h, int nw, int nh, ct_error *err)
{
    if (!d->bits) return ctex_dirty_reset(d, nw, nh, err);
    ctex_dirty o = *d;
    d->bits = NULL;
    d->row_t = NULL;
    d->row_n = NULL;
    d->tw = d->th = 0;
    int rc = ctex_dirty_reset(d, nw, nh, err);
    if (rc) {
        *d = o;
        return rc;
    }
    ctex_dirty_clear_all(d);
    for (int ty = 0; ty < o.th; ty++) {
        if (o.row_n[ty]) {
            /* the samples' centres lie in the old row, not in a neighbour's reach */
            int y = ty << CTEX_TILE_SHIFT, ny = nh == h ? y : (nh > h ? 2 * y : y / 2);
            d->row_n[ny >> CTEX_TILE_SHIFT] += o.row_n[ty];
        }
        if (!o.row_t[ty]) continue;
        int y0, y1, len;
        int yb = (ty << CTEX_TILE_SHIFT) + CTEX_TILE - 1;
        axis_span(h, nh, ty << CTEX_TILE_SHIFT, yb < h - 1 ? yb : h - 1, &y0, &y1);
        for (int a = ctex_dirty_next_run(&o, ty, 0, &len); len; a = ctex_dirty_next_run(&o, ty, a + len, &len)) {
            int xb = ((a + len) << CTEX_TILE_SHIFT) - 1, x0, x1;
            axis_span(w, nw, a << CTEX_TILE_SHIFT, xb < w - 1 ? xb : w - 1, &x0, &x1);
            for (int ny = y0 >> CTEX_TILE_SHIFT; ny <= y1 >> CTEX_TILE_SHIFT; ny++) {
                bitrow_set(d->bits + (size_t)ny * (size_t)d->words, x0 >> CTEX_TILE_SHIFT, x1 >> CTEX_TILE_SHIFT);
                if (!d->row_t[ny] || o.row_t[ty] < d->row_t[ny]) d->row_t[ny] = o.row_t[ty];
                d->any = true;
            }
        }
    }
    ctex_dirty_free(&o);
    return CT_OK;
}

void ctex_dirty_free(ctex_dirty *d)
{
    free(d->bits);
    free(d->row_t);
    free(d->row_n);
    d->bits = d->row_t = NULL;
    d->row_n = NULL;
    d->tw = d->th = d->words = 0;
    d->any = false;
}

void ctex_dirty_mark_all(ctex_dirty *d)
{
    if (!d->bits) return;
    const uint64_t now = ctex_dirty_now(d);
    for (int ty = 0; ty < d->th; ty++) {
        if (!d->row_t[ty]) d->row_t[ty] = now;
        bitrow_set(d->bits + (size_t)ty * (size_t)d->words, 0, d->tw - 1);
    }
    d->any = true;
}

void ctex_dirty_clear_all(ctex_dirty *d)
{
    if (!d->bits) return;
    memset(d->bits, 0, (size_t)d->th * (size_t)d->words * sizeof *d->bits);
    memset(d->row_t, 0, (size_t)d->th * sizeof *d->row_t);
    memset(d->row_n, 0, (size_t)d->th * sizeof *d->row_n);
    d->any = false;
}

int ctex_dirty_next_run(const ctex_dirty *d, int ty, int from, int *len)
{
    *len = 0;
    if (!d->bits) return 0;
    return bitrow_next_run(d->bits + (size_t)ty * (size_t)d->words, d->tw, from, len);
}

void ctex_dirty_clear_run(ctex_dirty *d, int ty, int a, int n)
{
    if (!d->bits || n <= 0) return;
    bitrow_clear(d->bits + (size_t)ty * (size_t)d->words, a, n);
    if (!ctex_dirty_row(d, ty)) {
        d->row_t[ty] = 0;
        d->row_n[ty] = 0;
    }
}

bool ctex_dirty_row(const ctex_dirty *d, int ty)
{
    return bitrow_any(d->bits + (size_t)ty * (size_t)d->words, d->words);
}

bool ctex_dirty_bounds(const ctex_dirty *d, int w, int h, int *x0, int *y0, int *x1, int *y1)
{
    int bx0 = d->tw, by0 = d->th, bx1 = -1, by1 = -1;
    for (int ty = 0; d->bits && ty < d->th; ty++) {
        int len, a = ctex_dirty_next_run(d, ty, 0, &len);
        if (!len) continue;
        if (ty < by0) by0 = ty;
        by1 = ty;
        if (a < bx0) bx0 = a;
        for (; len; a = ctex_dirty_next_run(d, ty, a + len, &len))
            if (a + len - 1 > bx1) bx1 = a + len - 1;
    }
    if (bx1 < 0) return false;
    *x0 = bx0 << CTEX_TILE_SHIFT;
    *y0 = by0 << CTEX_TILE_SHIFT;
    *x1 = (bx1 + 1) << CTEX_TILE_SHIFT;
    *y1 = (by1 + 1) << CTEX_TILE_SHIFT;
    if (*x1 > w) *x1 = w;
    if (*y1 > h) *y1 = h;
    return true;
}

/* disp_tiles.c: the kept base's per-tile triangle lists (disp_tiles.h). */
#include "display/disp_tiles.h"

#include "common/grow.h"

#include <stdlib.h>
#include <string.h>

struct disp_tiles {
    int w, h, tw, th;
    uint32_t *first;   /* tw * th + 1 offsets into ids */
    uint32_t *ids;     /* each tile's distinct triangle indices, ascending */
    size_t ids_cap;
    uint32_t scratch[DISP_TILE * DISP_TILE];
};

int disp_tiles_new(disp_tiles **out, ct_error *err)
{
    *out = calloc(1, sizeof **out);
    return *out ? CT_OK : ct_fail(err, CT_ENOMEM, "out of memory for the tile index");
}

void disp_tiles_free(disp_tiles *t)
{
    if (!t) return;
    free(t->first);
    free(t->ids);
    free(t);
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

int disp_tiles_set(disp_tiles *t, const float *tri, int width, int height, ct_error *err)
{
    int tw = (width + DISP_TILE - 1) / DISP_TILE, th = (height + DISP_TILE - 1) / DISP_TILE;
    size_t ntiles = (size_t)tw * (size_t)th;
    uint32_t *first = realloc(t->first, (ntiles + 1) * sizeof *first);
    if (!first) return ct_fail(err, CT_ENOMEM, "out of memory for %zu tiles", ntiles);
    t->first = first;
    t->w = t->h = t->tw = t->th = 0;
    size_t used = 0;
    for (int ty = 0; ty < th; ty++)
        for (int tx = 0; tx < tw; tx++) {
            size_t n = 0;
            uint32_t last = UINT32_MAX;
            int y1 = (ty + 1) * DISP_TILE < height ? (ty + 1) * DISP_TILE : height;
            int x1 = (tx + 1) * DISP_TILE < width ? (tx + 1) * DISP_TILE : width;
            for (int y = ty * DISP_TILE; y < y1; y++) {
                const float *row = tri + (size_t)y * (size_t)width;
                for (int x = tx * DISP_TILE; x < x1; x++) {
                    float v = row[x];
                    if (!(v >= 0.0f) || v >= 4294967040.0f) continue;   /* background, NaN, out of range */
                    uint32_t u = (uint32_t)v;
                    if (u == last) continue;   /* runs along a row: most pixels repeat their left neighbour */
                    t->scratch[n++] = last = u;
                }
            }
            qsort(t->scratch, n, sizeof *t->scratch, cmp_u32);
            size_t k = 0;
            for (size_t i = 0; i < n; i++)
                if (!k || t->scratch[i] != t->scratch[k - 1]) t->scratch[k++] = t->scratch[i];
            int rc = ct_grow((void **)&t->ids, &t->ids_cap, used + k, sizeof *t->ids, "tile index entries", err);
            if (rc) return rc;
            first[(size_t)ty * (size_t)tw + (size_t)tx] = (uint32_t)used;
            if (k) memcpy(t->ids + used, t->scratch, k * sizeof *t->ids);   /* (ids is NULL while every tile is empty) */
            used += k;
        }
    first[ntiles] = (uint32_t)used;
    t->w = width;
    t->h = height;
    t->tw = tw;
    t->th = th;
    return CT_OK;
}

/* Whether tile k shows a triangle in [b, e): the first index >= b, by
 * binary search, is below e. */
static int shows(const disp_tiles *t, size_t k, uint32_t b, uint32_t e)
{
    uint32_t lo = t->first[k], hi = t->first[k + 1];
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (t->ids[mid] < b) lo = mid + 1;
        else hi = mid;
    }
    return lo < t->first[k + 1] && t->ids[lo] < e;
}

static int clampi(int v, int lo, int hi) { return v < lo ? lo : v > hi ? hi : v; }

size_t disp_tiles_cover(const disp_tiles *t, uint32_t b, uint32_t e, disp_rect within, disp_rect *out)
{
    if (!t->tw || b >= e) return 0;
    int tx0 = clampi(within.x0, 0, t->w) / DISP_TILE, ty0 = clampi(within.y0, 0, t->h) / DISP_TILE;
    int tx1 = (clampi(within.x1, 0, t->w) + DISP_TILE - 1) / DISP_TILE;
    int ty1 = (clampi(within.y1, 0, t->h) + DISP_TILE - 1) / DISP_TILE;
    size_t n = 0;
    for (int ty = ty0; ty < ty1; ty++) {
        int run = -1;
        for (int tx = tx0; tx <= tx1; tx++) {
            int on = tx < tx1 && shows(t, (size_t)ty * (size_t)t->tw + (size_t)tx, b, e);
            if (on && run < 0) run = tx;
            if (!on && run >= 0) {
                int x1 = tx * DISP_TILE < t->w ? tx * DISP_TILE : t->w;
                int y1 = (ty + 1) * DISP_TILE < t->h ? (ty + 1) * DISP_TILE : t->h;
                out[n++] = (disp_rect){run * DISP_TILE, ty * DISP_TILE, x1, y1};
                run = -1;
            }
        }
    }
    return n;
}

size_t disp_tiles_max_rects(const disp_tiles *t) { return (size_t)t->tw * (size_t)t->th; }

/* The kept base's tile index (display/disp_tiles.h): which tiles a
 * triangle range covers, against a brute-force scan of the pixels, for
 * images whose size is not a multiple of the tile, ranges that meet a
 * tile's list at its ends, background and a query window. */
#include <criterion/criterion.h>

#include <math.h>
#include <stdlib.h>

#include "display/disp_tiles.h"

/* Whether any pixel of tile (tx, ty) holds an index in [b, e). */
static bool brute(const float *img, int w, int h, int tx, int ty, uint32_t b, uint32_t e)
{
    for (int y = ty * DISP_TILE; y < (ty + 1) * DISP_TILE && y < h; y++)
        for (int x = tx * DISP_TILE; x < (tx + 1) * DISP_TILE && x < w; x++) {
            float v = img[(size_t)y * (size_t)w + (size_t)x];
            if (v >= 0.0f && (uint32_t)v >= b && (uint32_t)v < e) return true;
        }
    return false;
}

/* Marks the tiles the rectangles cover; fails on overlaps and on
 * rectangles outside the image or off the tile grid. */
static void mark(const disp_rect *r, size_t n, int w, int h, bool *on)
{
    int tw = (w + DISP_TILE - 1) / DISP_TILE;
    for (size_t k = 0; k < n; k++) {
        cr_assert(r[k].x0 >= 0 && r[k].y0 >= 0 && r[k].x1 <= w && r[k].y1 <= h && r[k].x0 < r[k].x1 &&
                      r[k].y0 < r[k].y1,
                  "rectangle %zu (%d %d %d %d) outside the %dx%d image", k, r[k].x0, r[k].y0, r[k].x1, r[k].y1, w, h);
        cr_assert(r[k].x0 % DISP_TILE == 0 && r[k].y0 % DISP_TILE == 0, "rectangle %zu off the tile grid", k);
        cr_assert(r[k].y1 - r[k].y0 <= DISP_TILE, "rectangle %zu spans rows of tiles", k);
        for (int x = r[k].x0; x < r[k].x1; x += DISP_TILE) {
            bool *t = &on[(r[k].y0 / DISP_TILE) * tw + x / DISP_TILE];
            cr_assert_not(*t, "tile (%d, %d) covered twice", x / DISP_TILE, r[k].y0 / DISP_TILE);
            *t = true;
        }
    }
}

Test(disp_tiles, cover_matches_a_scan_of_the_pixels)
{
    const int w = 100, h = 70;   /* 4 x 3 tiles, the last column and row partial */
    float *img = malloc((size_t)w * h * sizeof *img);
    srand(7);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            /* bands of a few triangles, background patches, one far index */
            float v = (float)((x / 7 + 3 * (y / 11)) % 40);
            if ((x * 31 + y * 17) % 97 == 0) v = -1.0f;
            if (x == 99 && y == 69) v = 1000000.0f;
            if (x > 60 && y < 20) v = -1.0f;
            img[(size_t)y * w + x] = v;
        }
    img[5] = NAN;
    disp_tiles *t;
    ct_error err;
    cr_assert_eq(disp_tiles_new(&t, &err), 0);
    disp_rect out[64];
    cr_expect_eq(disp_tiles_cover(t, 0, 100, (disp_rect){0, 0, w, h}, out), 0, "an empty index covers nothing");
    cr_assert_eq(disp_tiles_set(t, img, w, h, &err), 0, "%s", err.msg);
    cr_assert_leq(disp_tiles_max_rects(t), 64);
    const uint32_t ranges[][2] = {{0, 1}, {0, 40}, {5, 6}, {39, 40}, {12, 20}, {40, 999999}, {999999, 1000001},
                                  {7, 7}, {1000000, 1000001}};
    const disp_rect windows[] = {{0, 0, w, h}, {40, 10, 70, 50}, {-20, -5, 300, 300}, {96, 64, 100, 70}};
    size_t checked = 0, covered = 0;
    for (size_t wi = 0; wi < sizeof windows / sizeof *windows; wi++)
        for (size_t i = 0; i < sizeof ranges / sizeof *ranges; i++) {
            size_t n = disp_tiles_cover(t, ranges[i][0], ranges[i][1], windows[wi], out);
            bool on[12] = {false};
            mark(out, n, w, h, on);
            disp_rect win = windows[wi];
            for (int ty = 0; ty < 3; ty++)
                for (int tx = 0; tx < 4; tx++) {
                    /* the window reaches the tile */
                    bool inside = tx * DISP_TILE < win.x1 && (tx + 1) * DISP_TILE > win.x0 &&
                                  ty * DISP_TILE < win.y1 && (ty + 1) * DISP_TILE > win.y0;
                    bool want = inside && brute(img, w, h, tx, ty, ranges[i][0], ranges[i][1]);
                    cr_expect_eq(on[ty * 4 + tx], want, "range [%u, %u) window %zu tile (%d, %d): %s",
                                 ranges[i][0], ranges[i][1], wi, tx, ty, want ? "missed" : "covered for nothing");
                    checked++;
                    covered += want;
                }
        }
    cr_expect_gt(covered, checked / 10, "the ranges cover %zu of %zu tiles: too few to test", covered, checked);
    cr_expect_lt(covered, checked, "every tile covered: nothing to tell apart");
    disp_tiles_free(t);
    free(img);
}

/* A view with no triangle (all background, as when the window went away):
 * the index is empty, and no copy is made from a null table (UBSan caught a
 * memcpy of 0 bytes into NULL). */
Test(disp_tiles, an_image_of_background_only)
{
    disp_tiles *t;
    ct_error err;
    cr_assert_eq(disp_tiles_new(&t, &err), 0, "%s", err.msg);
    float img[70 * 40];
    for (int i = 0; i < 70 * 40; i++) img[i] = -1.0f;
    cr_expect_eq(disp_tiles_set(t, img, 70, 40, &err), 0, "%s", err.msg);
    disp_tiles_free(t);
}

#ifndef CORRTEX_DISP_TILES_H
#define CORRTEX_DISP_TILES_H
/* Which triangles each screen tile of the kept base shows.
 *
 * The compositor draws a still view's corrections in screen space, one
 * draw per texture over the pixels whose kept surface is one of the
 * texture's triangles (a node's subtree is one range of the sorted
 * triangles). A texture's node bounds project to a rectangle that is
 * mostly other surfaces (nested nodes, a wall behind the table), and on a
 * CPU rasteriser every pixel drawn costs; so the base's triangle indices
 * are read back once per kept view and kept per tile of DISP_TILE pixels
 * as a sorted list of the distinct indices, and a texture is drawn only
 * over the tiles that show one of its triangles. Pure CPU: no GL here. */

#include <stddef.h>
#include <stdint.h>

#include "common/error.h"

/* Tile edge in pixels. */
#define DISP_TILE 32

/* A pixel rectangle [x0, x1) x [y0, y1), rows counted as the index image's
 * (GL's window coordinates when it comes from glReadPixels). */
typedef struct disp_rect {
    int x0, y0, x1, y1;
} disp_rect;

typedef struct disp_tiles disp_tiles;

/* An empty index (no view: every query answers nothing). */
int disp_tiles_new(disp_tiles **out, ct_error *err);
void disp_tiles_free(disp_tiles *t);

/* Indexes a width x height image of triangle indices, row-major; a
 * negative value (or NaN) is background. Values are the float triangle
 * indices of the position buffer (exact below 2^24). */
int disp_tiles_set(disp_tiles *t, const float *tri, int width, int height, ct_error *err);

/* Appends to out (room for at least disp_tiles_max_rects) the tiles inside
 * `within` (pixels; clipped to tile edges, then to the image) that show a
 * triangle in [b, e), as rectangles of horizontal runs of tiles clipped to
 * the image; returns how many. */
size_t disp_tiles_cover(const disp_tiles *t, uint32_t b, uint32_t e, disp_rect within, disp_rect *out);

/* The most rectangles one disp_tiles_cover call can return. */
size_t disp_tiles_max_rects(const disp_tiles *t);

#endif

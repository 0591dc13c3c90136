/* ctex_dirty.h: which texels of one corrective texture changed since a
 * display last received them, in tiles of CTEX_TILE x CTEX_TILE texels: one
 * bit a tile, and per row of tiles the master clock of its oldest unsent
 * change and the samples centred in it since (the display's lag statistics).
 * The splats mark what they touch (ctex_dirty_mark, once a splat); the
 * display server reads runs of marked tiles when it has room to send them
 * and clears them (docs/protocol.md, "Flow control"): the texture itself is
 * the buffer in which newer texels replace older unsent ones. Owns the
 * ctex_dirty_ prefix. */
#ifndef CT_MASTER_CTEX_DIRTY_H
#define CT_MASTER_CTEX_DIRTY_H

#include <stdbool.h>
#include <stdint.h>

#include "common/bitrow.h"
#include "common/error.h"

/* 4 x 4: a late sample changes a few texels, and its whole tile goes out
 * again; against 8 x 8 tiles the texel bytes to the display fell by 21 %
 * (bench_master) to 35 % (table 1024^2 streaming), and the master's
 * replay rate rose by 7 % (docs/protocol.md, "Flow control"). */
enum {
    CTEX_TILE_SHIFT = 2,
    CTEX_TILE = 1 << CTEX_TILE_SHIFT   /* texels a tile is wide and high */
};

typedef struct ctex_dirty {
    uint64_t *bits;          /* th rows of `words` words; bit i of a row: tile column i */
    uint64_t *row_t;         /* per tile row: clock of its oldest unsent change, 0 when clean */
    uint32_t *row_n;         /* per tile row: samples centred in it since it was last sent */
    int tw, th, words;       /* tiles across and down; words per row */
    bool any;                /* some bit may be set */
    const uint64_t *clock;   /* the engine's clock (us), NULL: changes are stamped 1 */
} ctex_dirty;

/* Sizes the maps for a w x h texture and marks all of it (a new texture, or
 * a resize: every texel is new); the sample counts carry over. */
int ctex_dirty_reset(ctex_dirty *d, int w, int h, ct_error *err);

/* The maps of a w x h texture for its exact resize to nw x nh (each axis
 * kept, doubled or halved, as ctex_tex_resize makes it): a new tile is
 * marked when a texel it is computed from was (a doubling reads the old
 * texel under a new one and its neighbour towards the new centre, a halving
 * the 2 x 2 block), with the oldest stamp of those rows; the sample counts
 * go to the row that holds their old row. The display computes every other
 * texel itself from what it has (TEX_RESIZE, docs/protocol.md). */
int ctex_dirty_rescale(ctex_dirty *d, int w, int h, int nw, int nh, ct_error *err);

/* Frees the maps (clock stays). */
void ctex_dirty_free(ctex_dirty *d);

/* Marks every tile. */
void ctex_dirty_mark_all(ctex_dirty *d);

/* Clears every tile without sending (the display will get the texture
 * anew on its next ALLOC). */
void ctex_dirty_clear_all(ctex_dirty *d);

/* The clock a change made now is stamped with. */
static inline uint64_t ctex_dirty_now(const ctex_dirty *d)
{
    uint64_t t = d->clock ? *d->clock : 1;
    return t ? t : 1;
}

/* Marks the texels [x0, x1) x [y0, y1) (inside the texture, not empty) as
 * changed by a sample centred in texel row cy. */
static inline void ctex_dirty_mark(ctex_dirty *d, int x0, int y0, int x1, int y1, int cy)
{
    if (!d->bits) return;
    const int a = x0 >> CTEX_TILE_SHIFT, b = (x1 - 1) >> CTEX_TILE_SHIFT;
    const int ty1 = (y1 - 1) >> CTEX_TILE_SHIFT;
    const uint64_t now = ctex_dirty_now(d);
    for (int ty = y0 >> CTEX_TILE_SHIFT; ty <= ty1; ty++) {
        if (!d->row_t[ty]) d->row_t[ty] = now;
        bitrow_set(d->bits + (size_t)ty * (size_t)d->words, a, b);
    }
    d->row_n[cy >> CTEX_TILE_SHIFT]++;
    d->any = true;
}

/* The first run of marked tiles in tile row ty at or after tile column
 * from: its first column and length (0 when none is left). */
int ctex_dirty_next_run(const ctex_dirty *d, int ty, int from, int *len);

/* Clears the tiles [a, a + n) of tile row ty (they were sent); a row left
 * without marks forgets its stamp and count. */
void ctex_dirty_clear_run(ctex_dirty *d, int ty, int a, int n);

/* Whether tile row ty has a mark. */
bool ctex_dirty_row(const ctex_dirty *d, int ty);

/* The bounding box of the marked tiles in texels, clipped to w x h; false
 * when nothing is marked. (Tests, logs.) */
bool ctex_dirty_bounds(const ctex_dirty *d, int w, int h, int *x0, int *y0, int *x1, int *y1);

#endif

/* shown.h: the shown-node map of a view: which scene part the interactive
 * image shows at each pixel centre, an item buffer of the radiosity mesh as
 * the display draws it (every triangle, both sides, the nearest one under a
 * perspective depth test), so that the master can make §3.7's check "the
 * sample hit another object than the interactive image shows there" without
 * asking the display or the tracers. Rasterized in software on the thread
 * pool: each task draws a share of the triangles into its own depth and id
 * buffer, and the buffers are merged by depth, the lower triangle winning a
 * tie, so the map does not depend on the number of threads. Owns the shown_
 * prefix. */
#ifndef CT_MASTER_SHOWN_H
#define CT_MASTER_SHOWN_H

#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "common/pool.h"
#include "common/radmesh.h"

/* The item buffer's scratch (reused from view to view). */
typedef struct shown_buf shown_buf;

void shown_buf_free(shown_buf *b);

/* The most bytes a shown_buf holds for a width x height view drawn on
 * `threads` threads (a depth and a triangle plane a thread, at most 4). */
uint64_t shown_bytes(int width, int height, int threads);

/* Writes into out[y * width + x] the tri_node of the triangle of m seen at
 * pixel (x, y)'s centre, or `none` where no triangle is (background). The
 * buffers in *b grow as needed (*b NULL at first). CT_ENOMEM. */
int shown_render(const ct_radmesh *m, const ct_camera *cam, int width, int height, ct_pool *pool, shown_buf **b,
                 uint32_t none, uint32_t *out, ct_error *err);

#endif

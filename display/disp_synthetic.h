/* disp_synthetic.h: synthetic corrective textures for runs without a
 * master (benchmarks, demos): up to n camera-local perspective textures
 * (§3.2), one per part node visible from a camera, each texture domain the
 * bounding rectangle of the node's projected bounds; with `tiles`, parts are
 * cut into k x k tiles until there are n textures (§3.3's optional size
 * split), so several textures stack on one part. Resolution follows the
 * projected size; contents are a smooth signed (or positive) pattern. */
#ifndef CT_DISP_SYNTHETIC_H
#define CT_DISP_SYNTHETIC_H

#include <stdbool.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/radmesh.h"
#include "display/disp_session.h"

/* Allocates up to n textures (ids 1..) in s for mesh m seen by cam in a
 * width x height image; *made gets the number created (fewer when fewer
 * parts are visible and tiles is false). */
int disp_synthetic_textures(disp_session *s, const ct_radmesh *m, const ct_camera *cam, int width,
                            int height, uint32_t n, bool tiles, bool positive, uint32_t *made,
                            ct_error *err);

#endif

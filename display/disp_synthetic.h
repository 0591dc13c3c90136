/* disp_synthetic.h: synthetic corrective textures for runs without a
 * master (benchmarks, demos): n camera-local perspective textures (§3.2)
 * over the part nodes visible from a camera, each texture domain the
 * bounding rectangle of the node's projected bounds (cut into tiles when
 * there are more textures than visible parts, as §3.3's size split does),
 * resolution following the projected size, filled with a smooth signed
 * pattern (or a positive one). */
#ifndef CT_DISP_SYNTHETIC_H
#define CT_DISP_SYNTHETIC_H

#include <stdbool.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/radmesh.h"
#include "display/disp_session.h"

/* Allocates n textures (ids 1..n) in s for mesh m seen by cam in a
 * width x height image; *made gets the number created (fewer when nothing
 * is visible). */
int disp_synthetic_textures(disp_session *s, const ct_radmesh *m, const ct_camera *cam, int width,
                            int height, uint32_t n, bool positive, uint32_t *made, ct_error *err);

#endif

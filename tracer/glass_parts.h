/* glass_parts.h: which glass parts bend the light that crosses them. A part
 * (a scene node) whose glass is nearly all in one plane (a sheet) or in two
 * opposite parallel planes (a pane: thin against its width) passes a
 * crossing ray on in its own direction, only shifted sideways, so a straight
 * shadow ray stands for it well (docs/tracer.md, "Light through glass,
 * refracted": 1.004 of the refracted light under a thin pane). Any other
 * glass part (a sphere, a lens, a drinking glass, a prism, a block whose
 * sides take light in and out) bends it: its focus and its dark shadow need
 * refracted paths. Owns the gparts_ prefix. */
#ifndef CT_TRACER_GLASS_PARTS_H
#define CT_TRACER_GLASS_PARTS_H

#include <stdint.h>

#include "common/error.h"
#include "tracer/embree_scene.h"

/* The share of a flat part's glass area in its one plane or two opposite
 * ones (a 6 x 6 pane 0.2 thick: 94 %; a cube: 33 %). */
#define GPARTS_FLAT_SHARE 0.9

/* *out: one byte per part node of m (at least one), 1 where the part has
 * glass that bends light, else 0; for the caller to free. */
int gparts_bending(const emb_mesh *m, uint8_t **out, ct_error *err);

#endif

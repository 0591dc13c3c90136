/* disp_scene.h: the interactive solution on the GPU: the radiosity mesh's
 * vertices (position, per-vertex radiance) and its triangles sorted by part
 * node. Nodes are in depth-first pre-order, so after the sort every node's
 * subtree (a part, or an inner node a texture may cover) is one contiguous
 * triangle range, drawn with a single glDrawElements. The runs of glass
 * triangles (see-through materials of the mesh, rmesh_material) are listed
 * for the compositor's glass passes. */
#ifndef CT_DISP_SCENE_H
#define CT_DISP_SCENE_H

#include <stdint.h>

#include "common/error.h"
#include "common/radmesh.h"

typedef struct disp_scene disp_scene;

/* A run of see-through triangles [begin, end) in drawing order, all of one
 * material. */
typedef struct disp_glass {
    uint32_t begin, end;
    vec3 transmission;
    float ior;
    bounds3 bounds;   /* world bounds of the run's triangles */
} disp_glass;

/* Validates m (indices, node table) and uploads it; needs a current context. */
int disp_scene_new(const ct_radmesh *m, disp_scene **out, ct_error *err);

/* Deletes the GL objects. NULL is fine. */
void disp_scene_free(disp_scene *s);

/* Counts. */
uint32_t disp_scene_ntris(const disp_scene *s);

/* A number no other scene of this process had: what was drawn of a scene
 * is known to be of this one even when a new scene reuses its address. */
uint64_t disp_scene_serial(const disp_scene *s);

/* The glass runs, in drawing order (*n of them; NULL when none). */
const disp_glass *disp_scene_glass(const disp_scene *s, uint32_t *n);

/* World bounds of all vertices. */
bounds3 disp_scene_bounds(const disp_scene *s);

/* World bounds of the triangles of node n's subtree (empty for a node
 * without triangles or out of range). */
bounds3 disp_scene_node_bounds(const disp_scene *s, uint32_t n);

/* Triangle range [*begin, *end) of node n's subtree in drawing order;
 * CT_ERANGE when n is not a node. */
int disp_scene_node_range(const disp_scene *s, uint32_t n, uint32_t *begin, uint32_t *end,
                          ct_error *err);

/* Binds the vertex array (call once before drawing ranges). */
void disp_scene_bind(const disp_scene *s);

/* Draws triangles [begin, end) of the sorted order (vertex array bound). */
void disp_scene_draw(const disp_scene *s, uint32_t begin, uint32_t end);

#endif

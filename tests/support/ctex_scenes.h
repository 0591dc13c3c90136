/* ctex_scenes.h: scenes built in code for the corrective-texture tests
 * (tests/unit/test_ctex_*.c): parts made of quads and boxes, the three
 * groups on a floor that most tests look at, an engine over a scene's
 * stand-in mesh and the camera in front of it. Prefix tcx_. */
#ifndef CT_TESTS_CTEX_SCENES_H
#define CT_TESTS_CTEX_SCENES_H

#include "common/camera.h"
#include "common/radmesh.h"
#include "common/records.h"
#include "common/scene.h"
#include "master/ctex.h"

/* Adds the quad p[0..3] with normal n to the open part. */
void tcx_add_quad(ct_scene *s, const vec3 p[4], vec3 n);

/* A one-quad part a b c d of material mat. */
void tcx_quad_part(ct_scene *s, const char *name, uint32_t mat, vec3 a, vec3 b, vec3 c, vec3 d);

/* A scene with one grey material whose one part `part` is left open for
 * tcx_add_quad; tcx_one_part_end closes and finalizes it. */
ct_scene *tcx_one_part_begin(const char *name, const char *part);
void tcx_one_part_end(ct_scene *s);

/* A closed box as one part (not flat). */
void tcx_box_part(ct_scene *s, const char *name, uint32_t mat, vec3 lo, vec3 hi);

/* Three groups of objects on a floor, spread along x:
 *   floor (flat, diffuse); group g<i> = box + flat top plate, i = 0..2;
 *   a glossy flat panel; a box far behind the default camera. */
typedef struct tcx_scene {
    ct_scene *s;
    ct_radmesh m;
    int floor, panel, behind, box[3], plate[3];
} tcx_scene;

void tcx_build(tcx_scene *t);
void tcx_release(tcx_scene *t);

/* An engine over t's stand-in mesh. */
ctex *tcx_engine(tcx_scene *t, ctex_options o);

/* The camera in front of the three groups. */
ct_camera tcx_front_cam(void);

/* t built, and an engine of options o for it under the front camera at
 * w x h pixels; tcx_leaf_engine: with leaf textures (eps = 0). */
ctex *tcx_front_engine(tcx_scene *t, ctex_options o, int w, int h);
ctex *tcx_leaf_engine(tcx_scene *t, int w, int h);

/* A 40 x 40 grid of samples of value val at height y on part node. */
void tcx_fill_floor(ctex *c, uint32_t node, float val, float y);

/* A sample that hit node at hit with the given values. */
ct_sample tcx_sample(uint32_t node, vec3 hit, vec3 hq, vec3 base);

#endif

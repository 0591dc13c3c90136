/* testscenes.h: small scenes built in code for unit tests (quads, boxes,
 * spheres), through the scene builder API, each shape one part node. */
#ifndef CT_TESTS_TESTSCENES_H
#define CT_TESTS_TESTSCENES_H

#include <stdbool.h>

#include "common/scene.h"

/* Adds a one-part quad with corners c, c+e1, c+e1+e2, c+e2; its front side
 * (normal) is e1 x e2. Returns the part node id or < 0. */
int ts_quad(ct_scene *s, const char *name, uint32_t mat, vec3 c, vec3 e1, vec3 e2, ct_error *err);

/* Adds an axis-aligned box lo..hi as one part with flat faces; inward: the
 * faces' front sides point into the box. Returns the part node id or < 0. */
int ts_box(ct_scene *s, const char *name, uint32_t mat, vec3 lo, vec3 hi, bool inward, ct_error *err);

/* Adds a closed sphere (nu x nv latitude-longitude facets, flat normals) as
 * one part; inward: front sides point to the centre. Returns the node or < 0. */
int ts_sphere(ct_scene *s, const char *name, uint32_t mat, vec3 centre, float radius, int nu, int nv,
              bool inward, ct_error *err);

/* The same sphere smooth: shared vertices with radial normals, quads
 * (triangles at the poles), front sides out. Returns the node or < 0. */
int ts_smooth_sphere(ct_scene *s, const char *name, uint32_t mat, vec3 centre, float radius, int nu, int nv,
                     ct_error *err);

/* Adds a material with the given diffuse albedo and emission; returns its index. */
int ts_diffuse(ct_scene *s, const char *name, vec3 rho, vec3 le, ct_error *err);

/* Adds a clear dielectric of index ior with a transmission colour per
 * crossing; returns its index. */
int ts_glass(ct_scene *s, const char *name, float ior, vec3 transmission, ct_error *err);

/* A closed 4x3x4 room (diffuse walls, a ceiling light) holding every
 * material kind: a Ward sphere, a Phong box, a mirror, a glass box. Camera
 * "main" looks into it. Finalized. NULL on failure (err filled). */
ct_scene *ts_room(ct_error *err);

/* Form factor from the point (px, 0, pz) facing up to the rectangle
 * [x0,x1]x[z0,z1] at height c facing down. */
double ts_ff_rect(double px, double pz, double x0, double x1, double z0, double z1, double c);

/* A floor (rho 0.5, y = 0) lit only by a lamp seen in a mirror: a lamp
 * 0.6 x 0.6 at height 1 over x in [1.5, 2.1], z in [-0.3, 0.3], L_e
 * (10, 5, 2), facing up, under a mirror ceiling (R = (0.8, 0.6, 0.4)) at
 * height 2 facing down. The floor sees the lamp's image at height 3 facing
 * down; a diffuse wall (rho 0.5) at x = -6 facing +x, 2 high, takes
 * the floor's light on. split: the ceiling is two mirrors meeting at x = 3 and a third
 * mirror hangs on a wall; cover: a black plate just over the lamp hides it
 * from the mirror; diffuse_ceiling: a diffuse ceiling (0.8) instead of the
 * mirror. Finalized; NULL on failure (err filled). */
ct_scene *ts_mirror_lamp(bool split, bool cover, bool diffuse_ceiling, ct_error *err);

/* The floor's radiance at (x, 0, z) in ts_mirror_lamp's plain scene
 * (where the reflection point lies on the first mirror): rho * R * L_e *
 * F(image). */
vec3 ts_mirror_lamp_floor(float x, float z);

#endif

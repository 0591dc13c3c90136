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

/* Adds a material with the given diffuse albedo and emission; returns its index. */
int ts_diffuse(ct_scene *s, const char *name, vec3 rho, vec3 le, ct_error *err);

/* A closed 4x3x4 room (diffuse walls, a ceiling light) holding every
 * material kind: a Ward sphere, a Phong box, a mirror, a glass box. Camera
 * "main" looks into it. Finalized. NULL on failure (err filled). */
ct_scene *ts_room(ct_error *err);

#endif

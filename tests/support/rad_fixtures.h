/* rad_fixtures.h: scenes built in code for the radiosity tests: a closed box
 * of gridded quads with an emitting patch in its ceiling, and two parallel
 * squares. Every builder returns a finalized scene or NULL. */
#ifndef CT_TESTS_RAD_FIXTURES_H
#define CT_TESTS_RAD_FIXTURES_H

#include "common/scene.h"

/* Adds a part node `name` with material mat holding an n x n grid of quads
 * spanning corner, corner + e1, corner + e1 + e2, corner + e2 (front side
 * towards e1 x e2). Returns 0 or < 0. */
int rfx_add_grid(ct_scene *s, const char *name, uint32_t mat, vec3 corner, vec3 e1, vec3 e2, int n);

/* The unit cube [0,1]^3 seen from inside: floor, four walls and a ceiling of
 * n x n quads each (n odd >= 3), the ceiling's centre quad an emitter of
 * radiance le (a separate part); walls reflect rho. */
ct_scene *rfx_closed_box(int n, float rho, float le);

/* The same box standing 1 cm above a square ground of one quad, 2 ground
 * wide, facing up (0: no ground). No light leaves the box, so the ground
 * changes nothing inside it. */
ct_scene *rfx_closed_box_on_ground(int n, float rho, float le, float ground);

/* Two unit squares facing each other at distance d: an emitter of radiance
 * le at z = d facing down and a black receiver at z = 0 facing up. */
ct_scene *rfx_parallel_squares(float d, float le);

/* Two unit squares at a right angle sharing the edge x = z = 0: a black
 * receiver in z = 0 facing up and an emitter of radiance le in x = 0
 * facing +x. */
ct_scene *rfx_perpendicular_squares(float le);

/* Two 1 x 1 floors side by side facing up, n x n white quads each: one
 * open, lit by a lamp of radiance le off to its side; one covered by a
 * black lid 30 cm above it and a black side towards the open one, dark.
 * A small white receiver faces down 5 m above the open floor and sees
 * none of the covered one. A cluster of both floors' patches has about
 * half the light of the open one's on average (the covered floor sees its
 * lid, so it counts as nearly as open as the other). */
ct_scene *rfx_covered_floor(int n, float le);

/* A box room (floor, walls, ceiling lamp) with a table-like block standing
 * on the floor: shadows that force uneven refinement. */
ct_scene *rfx_room_with_block(void);

#endif

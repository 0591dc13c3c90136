#ifndef CORRTEX_DISP_SCREEN_H
#define CORRTEX_DISP_SCREEN_H
/* The corrections over a kept base, drawn in screen space.
 *
 * Owns the kept base's position buffer (per pixel the sorted triangle
 * index and world position of the surface the base shows, a second colour
 * attachment of the base's framebuffer that pass 1 writes with
 * GL_PASS_GBUF), its tile index (disp_tiles.h, read back once per kept
 * view) and the program that adds the corrections from it: per texture
 * one draw over the tiles that show one of its node's triangles, each
 * fragment fetching its kept surface and adding the texture's value where
 * that surface is in the node. Over the mesh (the compositor's late
 * corrections) every textured triangle is sent again each frame, which on
 * a CPU rasteriser is most of a still frame's cost. One draw per tile for
 * all the textures showing it (one fetch and one blend a pixel) was
 * slower on llvmpipe: a fragment that fails one texture's test there
 * still pays the others' lookups, where a discard ends it. Each pixel gets
 * the corrections of the one surface the base shows there (the depth
 * test's winner), as the one-pass mode gives them. */

#include <stdint.h>

#include "common/error.h"
#include "display/disp_textures.h"
#include "display/disp_tiles.h"
#include "display/gl_load.h"

typedef struct disp_screen disp_screen;

/* For a width x height base: programs, buffers, the tile index. */
int disp_screen_new(int width, int height, disp_screen **out, ct_error *err);
void disp_screen_free(disp_screen *p);

/* Makes the position buffer colour attachment 1 of fbo (once). */
int disp_screen_attach(disp_screen *p, GLuint fbo, ct_error *err);

/* After the base was drawn into fbo: reads its triangle indices back and
 * indexes them per tile. */
int disp_screen_index(disp_screen *p, GLuint fbo, ct_error *err);

/* Plans the corrections of the n textures, texture i only inside
 * within[i] (its node's projected bounds, pixels, GL window coordinates):
 * the tiles that show its node. *px: the pixels the draw would cover (what
 * it costs on a CPU rasteriser; the compositor weighs it against the
 * triangles the mesh path would send). */
int disp_screen_plan(disp_screen *p, const disp_texture *const *tex, const disp_rect *within, uint32_t n,
                     uint64_t *px, ct_error *err);

/* Adds the corrections of the same n textures as the last plan to the
 * bound target (blending, no depth test), once: a plan is drawn at most
 * once. Counts the draws into *draws. */
int disp_screen_draw(disp_screen *p, const disp_texture *const *tex, uint32_t n, uint32_t *draws, ct_error *err);

#endif

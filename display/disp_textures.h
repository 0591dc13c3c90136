/* disp_textures.h: the display's copy of the master's corrective textures:
 * one GL texture (RGBA16F, filled from RGB halves; bilinear, clamped) per texture id, with the node
 * whose triangles it covers, its world -> texture projection (§3.2) and
 * whether any texel was ever negative (pass 3 is skipped for textures that
 * never held a negative correction) or non-zero (textures that never held a
 * correction are not drawn at all). Texel (x, y) is GL row y, column x; its
 * centre is at texture coordinates ((x + 0.5) / w, (y + 0.5) / h). */
#ifndef CT_DISP_TEXTURES_H
#define CT_DISP_TEXTURES_H

#include <stdbool.h>
#include <stdint.h>

#include "common/error.h"
#include "common/vecmath.h"

/* How a texture is projected (§3.2). */
typedef enum disp_proj_kind {
    DISP_PROJ_OBJECT_PARALLEL    = 0,   /* object-local parallel, along the node's normal */
    DISP_PROJ_CAMERA_PERSPECTIVE = 1    /* camera-local perspective, floats with the eye */
} disp_proj_kind;

/* Largest texture side accepted. */
#define DISP_TEX_MAX_SIZE 8192

typedef struct disp_texture {
    uint32_t id;
    uint32_t node;                 /* mesh node whose subtree it covers */
    uint32_t tri_begin, tri_end;   /* that subtree's triangle range */
    int width, height;
    unsigned gl_tex;
    mat4 proj;                     /* world -> texture, homogeneous (divide by w) */
    disp_proj_kind kind;
    bool has_proj;                 /* drawn only once a projection arrived */
    bool negative;                 /* some texel was negative since allocation */
    bool nonzero;                  /* some texel was non-zero since allocation (else
                                    * the texture corrects nothing and is not drawn) */
    bool scaled_only;              /* holds only a resize's scaled old texels, made for
                                    * scaled_proj: zeroed if another projection comes */
    mat4 scaled_proj;
} disp_texture;

typedef struct disp_textures disp_textures;

/* An empty table. */
int disp_textures_new(disp_textures **out, ct_error *err);

/* Deletes every texture and the table. NULL is fine. */
void disp_textures_free(disp_textures *t);

/* Creates (or re-creates) texture id of width x height covering the
 * triangle range of `node`, projected the given way; a re-created id keeps
 * its projection (a resize does not move it). A new texture is zeroed; a
 * re-created one of the same kind (of any size) starts as its old texels
 * scaled, zeroed after all if a different projection follows before any
 * patch (a camera-local texture re-created for a new view, not resized).
 * Needs a current context. */
int disp_textures_alloc(disp_textures *t, uint32_t id, uint32_t node, uint32_t tri_begin,
                        uint32_t tri_end, int width, int height, disp_proj_kind kind,
                        ct_error *err);

/* Sets texture id's projection. */
int disp_textures_set_projection(disp_textures *t, uint32_t id, const mat4 *world_to_tex,
                                 ct_error *err);

/* Replaces the rectangle (x, y, w, h) of texture id with half-float RGB
 * texels (row by row, 3 halves each). */
int disp_textures_patch_half(disp_textures *t, uint32_t id, int x, int y, int w, int h,
                             const uint16_t *rgb, ct_error *err);

/* The same from the pixel unpack buffer bound now, at byte offset `off`
 * (w*h RGBA texels of 4 halves: the textures' own format, so the driver
 * copies rather than converts; alpha unused); negative / nonzero: what the
 * caller knows of them. */
int disp_textures_patch_pbo(disp_textures *t, uint32_t id, int x, int y, int w, int h, size_t off,
                            bool negative, bool nonzero, ct_error *err);

/* The same with float RGB texels. */
int disp_textures_patch_float(disp_textures *t, uint32_t id, int x, int y, int w, int h,
                              const float *rgb, ct_error *err);

/* Deletes texture id. */
int disp_textures_release(disp_textures *t, uint32_t id, ct_error *err);

/* Deletes all textures. */
void disp_textures_clear(disp_textures *t);

/* Number of textures and the i-th (0 <= i < count; order changes on release). */
uint32_t disp_textures_count(const disp_textures *t);
const disp_texture *disp_textures_at(const disp_textures *t, uint32_t i);

/* The texture with that id or NULL. */
const disp_texture *disp_textures_find(const disp_textures *t, uint32_t id);

/* Sum of width * height over all textures. */
uint64_t disp_textures_texels(const disp_textures *t);

#endif

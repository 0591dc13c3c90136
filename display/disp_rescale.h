/* disp_rescale.h: a correction texture's texels after an exact resolution
 * change of the master's (TEX_RESIZE, docs/protocol.md): each side kept,
 * doubled or halved. The display computes them from its own copy exactly
 * as the master computes its texels (master/ctex_tex.c), so that the master
 * sends only the tiles that changed since it last sent them instead of the
 * whole texture again. A texel is valid when any of its bits is set: the
 * master sends a valid zero as -0 and an empty texel as +0. Owns the
 * disp_rescale_ prefix. */
#ifndef CT_DISP_RESCALE_H
#define CT_DISP_RESCALE_H

#include <stdbool.h>
#include <stdint.h>

/* dst (nw*nh*3 halves, rows of nw) from src (w*h*3 halves, rows of w) for
 * an exact change (wire_tex_resize_exact, proto/wire.h). *negative / *nonzero: whether a new
 * texel is below zero / not zero (as disp_textures wants them). CT_OK, or
 * CT_ENOMEM for its row buffers. */
int disp_rescale(const uint16_t *src, int w, int h, uint16_t *dst, int nw, int nh, bool *negative, bool *nonzero);

#endif

/* gl_target.h: off-screen render targets (a colour texture, or a
 * multisampled colour renderbuffer, optionally a depth and stencil buffer,
 * in one framebuffer object), resolving and pixel read-back. Pixels come
 * back in GL order: row 0 is the bottom row. */
#ifndef CT_GL_TARGET_H
#define CT_GL_TARGET_H

#include <stdbool.h>
#include <stdint.h>

#include "display/gl_load.h"

typedef struct gl_target {
    GLuint fbo, color, depth;
    GLenum format;      /* GL_RGBA32F, GL_RGBA16F or GL_RGBA8 */
    int width, height;
    int samples;        /* 1: color is a texture; more: a multisampled renderbuffer */
} gl_target;

/* Creates a width x height target with the given colour format and an
 * optional depth buffer (32-bit float with reversed depth, else 24-bit)
 * with an 8-bit stencil, `samples` samples a pixel; checks completeness. A
 * multisampled target (samples > 1) is drawn into and resolved
 * (gl_target_resolve), not read or sampled. */
int gl_target_init(gl_target *t, int width, int height, GLenum format, bool depth, int samples, ct_error *err);

/* The most samples a pixel the context's renderbuffers allow (at least 1). */
int gl_target_max_samples(void);

/* Averages src's samples into dst's colour (same size; dst single-sampled). */
void gl_target_resolve(const gl_target *src, const gl_target *dst);

/* Deletes the GL objects and zeroes t. */
void gl_target_free(gl_target *t);

/* Copies src's colour, and with depth its depth and stencil, into dst
 * (same size, formats and samples) and leaves dst bound for drawing. */
void gl_target_copy(const gl_target *src, const gl_target *dst, bool depth);

/* Binds t for drawing (or the default framebuffer when t is NULL) and sets
 * the viewport to its size (w, h for the default framebuffer). */
void gl_target_bind(const gl_target *t, int w, int h);

/* Reads t's colour as RGB floats (3 * width * height, GL's row order:
 * bottom row first). */
void gl_target_read_f32(const gl_target *t, float *rgb);

/* Reads the colour of t (or of the default framebuffer's back buffer when t
 * is NULL, size w x h) as RGB bytes, rows packed, bottom row first. */
void gl_target_read_u8(const gl_target *t, int w, int h, uint8_t *rgb);

#endif

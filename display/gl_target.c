#include "display/gl_target.h"

#include <string.h>

int gl_target_init(gl_target *t, int width, int height, GLenum format, bool depth, int samples, ct_error *err)
{
    memset(t, 0, sizeof *t);
    t->width = width;
    t->height = height;
    t->format = format;
    t->samples = samples > 1 ? samples : 1;
    gl.GenFramebuffers(1, &t->fbo);
    gl.BindFramebuffer(GL_FRAMEBUFFER, t->fbo);
    if (t->samples > 1) {
        gl.GenRenderbuffers(1, &t->color);
        gl.BindRenderbuffer(GL_RENDERBUFFER, t->color);
        gl.RenderbufferStorageMultisample(GL_RENDERBUFFER, t->samples, format, width, height);
        gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, t->color);
    } else {
        gl.GenTextures(1, &t->color);
        gl.BindTexture(GL_TEXTURE_2D, t->color);
        GLenum type = format == GL_RGBA8 ? GL_UNSIGNED_BYTE : GL_FLOAT;
        gl.TexImage2D(GL_TEXTURE_2D, 0, (GLint)format, width, height, 0, GL_RGBA, type, NULL);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
        gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, t->color, 0);
    }
    if (depth) {
        GLenum df = gl.reversed_z ? GL_DEPTH32F_STENCIL8 : GL_DEPTH24_STENCIL8;
        gl.GenRenderbuffers(1, &t->depth);
        gl.BindRenderbuffer(GL_RENDERBUFFER, t->depth);
        if (t->samples > 1) gl.RenderbufferStorageMultisample(GL_RENDERBUFFER, t->samples, df, width, height);
        else gl.RenderbufferStorage(GL_RENDERBUFFER, df, width, height);
        gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, t->depth);
    }
    GLenum st = gl.CheckFramebufferStatus(GL_FRAMEBUFFER);
    gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
    if (st != GL_FRAMEBUFFER_COMPLETE) {
        int n = t->samples;
        gl_target_free(t);
        return ct_fail(err, CT_ESYS, "framebuffer %dx%d (format 0x%04x, %d samples) incomplete: 0x%04x", width,
                       height, (unsigned)format, n, (unsigned)st);
    }
    return gl_check("render target creation", err);
}

int gl_target_max_samples(void)
{
    /* GL 3.3 guarantees any count up to MAX_SAMPLES for the float and
     * depth formats (MAX_INTEGER_SAMPLES is for integer formats only). */
    GLint n = 0;
    gl.GetIntegerv(GL_MAX_SAMPLES, &n);
    while (gl.GetError() != GL_NO_ERROR) {}
    return n > 1 ? (int)n : 1;
}

void gl_target_resolve(const gl_target *src, const gl_target *dst)
{
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, src->fbo);
    gl.BindFramebuffer(GL_DRAW_FRAMEBUFFER, dst->fbo);
    gl.BlitFramebuffer(0, 0, src->width, src->height, 0, 0, dst->width, dst->height, GL_COLOR_BUFFER_BIT,
                       GL_NEAREST);
    gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
}

void gl_target_free(gl_target *t)
{
    if (t->fbo) gl.DeleteFramebuffers(1, &t->fbo);
    if (t->color && t->samples > 1) gl.DeleteRenderbuffers(1, &t->color);
    else if (t->color) gl.DeleteTextures(1, &t->color);
    if (t->depth) gl.DeleteRenderbuffers(1, &t->depth);
    memset(t, 0, sizeof *t);
}

void gl_target_copy(const gl_target *src, const gl_target *dst, bool depth)
{
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, src->fbo);
    gl.BindFramebuffer(GL_DRAW_FRAMEBUFFER, dst->fbo);
    GLbitfield what = GL_COLOR_BUFFER_BIT;
    if (depth && src->depth && dst->depth) what |= GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT;
    gl.BlitFramebuffer(0, 0, src->width, src->height, 0, 0, dst->width, dst->height, what, GL_NEAREST);
    gl_target_bind(dst, 0, 0);
}

void gl_target_bind(const gl_target *t, int w, int h)
{
    gl.BindFramebuffer(GL_FRAMEBUFFER, t ? t->fbo : 0);
    if (t) {
        w = t->width;
        h = t->height;
    }
    gl.Viewport(0, 0, w, h);
}

void gl_target_read_f32(const gl_target *t, float *rgb)
{
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, t->fbo);
    gl.ReadBuffer(GL_COLOR_ATTACHMENT0);
    gl.PixelStorei(GL_PACK_ALIGNMENT, 4);
    gl.ReadPixels(0, 0, t->width, t->height, GL_RGB, GL_FLOAT, rgb);
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, 0);
}

void gl_target_read_u8(const gl_target *t, int w, int h, uint8_t *rgb)
{
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, t ? t->fbo : 0);
    gl.ReadBuffer(t ? GL_COLOR_ATTACHMENT0 : GL_BACK);
    if (t) {
        w = t->width;
        h = t->height;
    }
    gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
    gl.ReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, rgb);
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, 0);
}

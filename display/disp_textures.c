#include "display/disp_textures.h"

#include <stdlib.h>
#include <string.h>

#include "common/idmap.h"
#include "display/gl_load.h"

struct disp_textures {
    disp_texture *items;
    uint32_t count, cap;
    ct_idmap ix;          /* id -> index in items: every upload looks one up */
    unsigned clear_fbo;   /* zeroes new textures on the GPU (no CPU buffer) */
    unsigned read_fbo;    /* the old texture of a resize, scaled into the new one */
};

int disp_textures_new(disp_textures **out, ct_error *err)
{
    *out = calloc(1, sizeof **out);
    return *out ? CT_OK : ct_fail(err, CT_ENOMEM, "out of memory for the texture table");
}

void disp_textures_clear(disp_textures *t)
{
    for (uint32_t i = 0; i < t->count; i++) gl.DeleteTextures(1, &t->items[i].gl_tex);
    t->count = 0;
    idmap_clear(&t->ix);
}

void disp_textures_free(disp_textures *t)
{
    if (!t) return;
    disp_textures_clear(t);
    if (t->clear_fbo) gl.DeleteFramebuffers(1, &t->clear_fbo);
    if (t->read_fbo) gl.DeleteFramebuffers(1, &t->read_fbo);
    free(t->items);
    idmap_free(&t->ix);
    free(t);
}

static disp_texture *find(const disp_textures *t, uint32_t id)
{
    uint32_t i = idmap_get(&t->ix, id);
    return i == IDMAP_NONE ? NULL : &t->items[i];
}

const disp_texture *disp_textures_find(const disp_textures *t, uint32_t id) { return find(t, id); }

/* Texture tex as the colour target of the clearing framebuffer (bound as
 * GL_FRAMEBUFFER); its completeness. target_detach undoes it. */
static GLenum target_attach(disp_textures *t, unsigned tex)
{
    if (!t->clear_fbo) gl.GenFramebuffers(1, &t->clear_fbo);
    gl.BindFramebuffer(GL_FRAMEBUFFER, t->clear_fbo);
    gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, tex, 0);
    return gl.CheckFramebufferStatus(GL_FRAMEBUFFER);
}

static void target_zero(void)
{
    gl.ClearColor(0, 0, 0, 0);
    gl.Clear(GL_COLOR_BUFFER_BIT);
}

static void target_detach(void)
{
    gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, 0, 0);
    gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
}

/* Zeroes texture tex; its completeness as a colour target when that was
 * needed. glClearTexImage where the context has it: no framebuffer change,
 * which on llvmpipe flushes the drawing queued so far into a scene of its
 * own (a camera change allocates dozens of textures), and whose fences are
 * where Mesa 22.3's llvmpipe races (docs/display.md, "Known problems"). */
static GLenum zero_texture(disp_textures *t, unsigned tex)
{
    if (gl.ClearTexImage) {
        gl.ClearTexImage(tex, 0, GL_RGBA, GL_HALF_FLOAT, NULL);
        return GL_FRAMEBUFFER_COMPLETE;
    }
    GLenum st = target_attach(t, tex);
    if (st == GL_FRAMEBUFFER_COMPLETE) target_zero();
    target_detach();
    return st;
}

int disp_textures_alloc(disp_textures *t, uint32_t id, uint32_t node, uint32_t tri_begin,
                        uint32_t tri_end, int width, int height, disp_proj_kind kind,
                        ct_error *err)
{
    GLint max = 0;
    gl.GetIntegerv(GL_MAX_TEXTURE_SIZE, &max);
    if (max > DISP_TEX_MAX_SIZE) max = DISP_TEX_MAX_SIZE;
    if (width < 1 || height < 1 || width > max || height > max)
        return ct_fail(err, CT_ERANGE, "texture %u: size %dx%d out of range 1..%d", id, width,
                       height, (int)max);
    disp_texture *x = find(t, id);
    /* A texture the master resized (§3.6) keeps its projection, so its old
     * texels, scaled, are the best picture of the new ones until their
     * patches arrive: without them the node's correction vanished for the
     * updates that resend a large texture (a 2048² one is tens of MB), a
     * flash of the bare radiosity on a still view. A camera-local texture
     * is also re-allocated when it is reprojected for a new view: the
     * PROJECTION that follows then differs from the one its texels were
     * made for, and disp_textures_set_projection zeroes it. */
    unsigned old_tex = 0;
    int ow = 0, oh = 0;
    bool old_neg = false;
    /* The same size too: the master halves what it sends of a texture once
     * it is denser than the screen (its doubling then keeps the size the
     * display has, docs/protocol.md), and the old texels are the new ones'
     * best picture until they arrive. */
    if (x && x->kind == kind && x->nonzero && x->has_proj) {
        old_tex = x->gl_tex;
        ow = x->width;
        oh = x->height;
        old_neg = x->negative;
        gl.GenTextures(1, &x->gl_tex);
    }
    if (!x) {
        if (t->count == t->cap) {
            uint32_t cap = t->cap ? 2 * t->cap : 64;
            disp_texture *n = realloc(t->items, cap * sizeof *n);
            if (!n) return ct_fail(err, CT_ENOMEM, "out of memory for %u textures", cap);
            t->items = n;
            t->cap = cap;
        }
        int rc = idmap_put(&t->ix, id, t->count, err);
        if (rc) return rc;
        x = &t->items[t->count++];
        memset(x, 0, sizeof *x);
        x->id = id;
        x->proj = m4_identity();
        gl.GenTextures(1, &x->gl_tex);
    }
    x->node = node;
    x->tri_begin = tri_begin;
    x->tri_end = tri_end;
    x->width = width;
    x->height = height;
    x->kind = kind;
    /* A re-allocation of a live id (the master resized it) keeps its
     * projection until a new one arrives; a new id waits for one. */
    /* Stored as RGBA16F: llvmpipe samples it faster than RGB16F, GPUs pad
     * RGB16F to four channels anyway, and it is colour-renderable, so the
     * zeroing below needs no CPU buffer of the texture's size. */
    gl.BindTexture(GL_TEXTURE_2D, x->gl_tex);
    gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA16F, width, height, 0, GL_RGB, GL_HALF_FLOAT, NULL);
    /* Zeroed contents: a fresh texture corrects nothing; a resized one
     * starts as its old texels scaled (bilinear, texel centres). */
    GLenum st = GL_FRAMEBUFFER_COMPLETE;
    bool scaled = false;
    if (old_tex) {
        st = target_attach(t, x->gl_tex);
        if (st == GL_FRAMEBUFFER_COMPLETE) {
            if (!t->read_fbo) gl.GenFramebuffers(1, &t->read_fbo);
            gl.BindFramebuffer(GL_READ_FRAMEBUFFER, t->read_fbo);
            gl.FramebufferTexture2D(GL_READ_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, old_tex, 0);
            if (gl.CheckFramebufferStatus(GL_READ_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE) {
                gl.BindFramebuffer(GL_DRAW_FRAMEBUFFER, t->clear_fbo);
                gl.BlitFramebuffer(0, 0, ow, oh, 0, 0, width, height, GL_COLOR_BUFFER_BIT, GL_LINEAR);
                scaled = true;
            }
            gl.FramebufferTexture2D(GL_READ_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, 0, 0);
            gl.BindFramebuffer(GL_READ_FRAMEBUFFER, 0);
            gl.BindFramebuffer(GL_FRAMEBUFFER, t->clear_fbo);
            if (!scaled) target_zero();
        }
        target_detach();
    } else {
        st = zero_texture(t, x->gl_tex);
    }
    if (old_tex) gl.DeleteTextures(1, &old_tex);
    /* scaled texels are the old ones (which were non-zero) */
    x->negative = scaled && old_neg;
    x->nonzero = scaled;
    x->scaled_only = scaled;
    x->scaled_proj = x->proj;
    if (st != GL_FRAMEBUFFER_COMPLETE)
        return ct_fail(err, CT_ESYS, "texture %u: cannot clear a %dx%d RGBA16F texture (0x%04x)", id, width,
                       height, (unsigned)st);
    /* Bilinear filtering (§4.3: the hardware interpolates between texels). */
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    return gl_check("texture allocation", err);
}

int disp_textures_set_projection(disp_textures *t, uint32_t id, const mat4 *world_to_tex,
                                 ct_error *err)
{
    disp_texture *x = find(t, id);
    if (!x) return ct_fail(err, CT_EPROTO, "projection for unknown texture %u", id);
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++)
            if (!isfinite(world_to_tex->m[r][c]))
                return ct_fail(err, CT_ERANGE, "texture %u: projection is not finite", id);
    if (x->scaled_only && memcmp(&x->scaled_proj, world_to_tex, sizeof *world_to_tex) != 0) {
        /* re-created for another view: the scaled texels belong to the old one */
        x->scaled_only = false;
        x->nonzero = x->negative = false;
        zero_texture(t, x->gl_tex);
    }
    x->proj = *world_to_tex;
    x->has_proj = true;
    return gl_check("texture projection", err);
}

static int patch(disp_textures *t, uint32_t id, int x, int y, int w, int h, const void *rgb,
                 GLenum format, GLenum type, bool negative, bool nonzero, ct_error *err)
{
    disp_texture *d = find(t, id);
    if (!d) return ct_fail(err, CT_EPROTO, "patch for unknown texture %u", id);
    if (x < 0 || y < 0 || w < 1 || h < 1 || x > d->width - w || y > d->height - h)
        return ct_fail(err, CT_ERANGE, "texture %u: patch %dx%d at (%d,%d) outside %dx%d", id, w,
                       h, x, y, d->width, d->height);
    gl.BindTexture(GL_TEXTURE_2D, d->gl_tex);
    gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    gl.TexSubImage2D(GL_TEXTURE_2D, 0, x, y, w, h, format, type, rgb);
    d->scaled_only = false;   /* texels for its projection now */
    d->negative = d->negative || negative;
    d->nonzero = d->nonzero || nonzero;
    return gl_check("texture patch", err);
}

int disp_textures_patch_half(disp_textures *t, uint32_t id, int x, int y, int w, int h,
                             const uint16_t *rgb, ct_error *err)
{
    bool neg = false, nz = false;
    size_t n = (w > 0 && h > 0) ? (size_t)w * (size_t)h * 3 : 0;
    /* Non-zero: any bit but the sign; negative: sign bit set and not -0. */
    for (size_t i = 0; i < n && !neg; i++) {
        nz = nz || (rgb[i] & 0x7fffu);
        neg = (rgb[i] & 0x8000u) && (rgb[i] & 0x7fffu);
    }
    return patch(t, id, x, y, w, h, rgb, GL_RGB, GL_HALF_FLOAT, neg, nz, err);
}

int disp_textures_patch_pbo(disp_textures *t, uint32_t id, int x, int y, int w, int h, size_t off,
                            bool negative, bool nonzero, ct_error *err)
{
    return patch(t, id, x, y, w, h, (const void *)(uintptr_t)off, GL_RGBA, GL_HALF_FLOAT, negative, nonzero, err);
}

int disp_textures_patch_float(disp_textures *t, uint32_t id, int x, int y, int w, int h,
                              const float *rgb, ct_error *err)
{
    bool neg = false, nz = false;
    size_t n = (w > 0 && h > 0) ? (size_t)w * (size_t)h * 3 : 0;
    for (size_t i = 0; i < n && !neg; i++) {
        nz = nz || rgb[i] != 0.0f;   /* NaN counts as non-zero */
        neg = rgb[i] < 0.0f;
    }
    return patch(t, id, x, y, w, h, rgb, GL_RGB, GL_FLOAT, neg, nz, err);
}

int disp_textures_release(disp_textures *t, uint32_t id, ct_error *err)
{
    disp_texture *x = find(t, id);
    if (!x) return ct_fail(err, CT_EPROTO, "free of unknown texture %u", id);
    gl.DeleteTextures(1, &x->gl_tex);
    idmap_del(&t->ix, id);
    *x = t->items[--t->count];
    /* the last entry moved into the hole: an update, which cannot fail */
    if (x != &t->items[t->count]) idmap_put(&t->ix, x->id, (uint32_t)(x - t->items), NULL);
    return CT_OK;
}

uint32_t disp_textures_count(const disp_textures *t) { return t->count; }

const disp_texture *disp_textures_at(const disp_textures *t, uint32_t i)
{
    return i < t->count ? &t->items[i] : NULL;
}

uint64_t disp_textures_texels(const disp_textures *t)
{
    uint64_t n = 0;
    for (uint32_t i = 0; i < t->count; i++) n += (uint64_t)t->items[i].width * (uint64_t)t->items[i].height;
    return n;
}

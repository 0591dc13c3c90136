/* disp_screen.c: the corrections over a kept base in screen space
 * (disp_screen.h). */
#include "display/disp_screen.h"

#include <stdlib.h>
#include <string.h>

#include "common/grow.h"
#include "display/gl_shaders.h"

struct disp_screen {
    int w, h;
    GLuint gbuf, vao, vbo, prog;
    GLint u_texproj, u_tris;
    disp_tiles *tiles;
    float *tri_img;           /* the triangle indices read back, w x h */
    disp_rect *rects;         /* one texture's tiles (disp_tiles_cover) */
    float *verts;             /* all textures' rectangles, NDC x, y, two triangles each */
    size_t verts_cap;
    uint32_t *range;          /* per texture: first vertex, count */
    size_t range_cap;
    size_t nv;                /* vertices planned */
};

int disp_screen_new(int width, int height, disp_screen **out, ct_error *err)
{
    *out = NULL;
    disp_screen *p = calloc(1, sizeof *p);
    if (!p) return ct_fail(err, CT_ENOMEM, "out of memory for the screen pass");
    p->w = width;
    p->h = height;
    size_t ntiles = (size_t)((width + DISP_TILE - 1) / DISP_TILE) * (size_t)((height + DISP_TILE - 1) / DISP_TILE);
    int rc = disp_tiles_new(&p->tiles, err);
    if (!rc) {
        p->tri_img = malloc((size_t)width * (size_t)height * sizeof *p->tri_img);
        p->rects = malloc(ntiles * sizeof *p->rects);
        if (!p->tri_img || !p->rects)
            rc = ct_fail(err, CT_ENOMEM, "out of memory for the screen pass's tiles (%dx%d)", width, height);
    }
    if (!rc) rc = gl_program_build("screen-corrections", gl_src_quads_vs, gl_src_screen_corr_fs, NULL, &p->prog, err);
    if (!rc) {
        p->u_texproj = gl.GetUniformLocation(p->prog, "u_texproj0");
        p->u_tris = gl.GetUniformLocation(p->prog, "u_tris");
        gl.UseProgram(p->prog);
        gl.Uniform1i(gl.GetUniformLocation(p->prog, "u_gbuf"), 1);
        gl.Uniform1i(gl.GetUniformLocation(p->prog, "u_tex0"), 0);
        gl.UseProgram(0);
    }
    if (!rc) {
        gl.GenVertexArrays(1, &p->vao);
        gl.GenBuffers(1, &p->vbo);
        gl.BindVertexArray(p->vao);
        gl.BindBuffer(GL_ARRAY_BUFFER, p->vbo);
        gl.EnableVertexAttribArray(0);
        gl.VertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 2 * sizeof(float), (const void *)0);
        gl.BindVertexArray(0);
        gl.BindBuffer(GL_ARRAY_BUFFER, 0);
        rc = gl_check("screen pass set-up", err);
    }
    if (rc) {
        disp_screen_free(p);
        return rc;
    }
    *out = p;
    return CT_OK;
}

void disp_screen_free(disp_screen *p)
{
    if (!p) return;
    if (p->prog) gl.DeleteProgram(p->prog);
    if (p->gbuf) gl.DeleteTextures(1, &p->gbuf);
    if (p->vao) gl.DeleteVertexArrays(1, &p->vao);
    if (p->vbo) gl.DeleteBuffers(1, &p->vbo);
    disp_tiles_free(p->tiles);
    free(p->tri_img);
    free(p->rects);
    free(p->verts);
    free(p->range);
    free(p);
}

int disp_screen_attach(disp_screen *p, GLuint fbo, ct_error *err)
{
    if (p->gbuf) return CT_OK;
    /* RGBA32F whatever --fbo says: positions to the float's precision,
     * triangle indices exact below 2^24. */
    gl.GenTextures(1, &p->gbuf);
    gl.BindTexture(GL_TEXTURE_2D, p->gbuf);
    gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, p->w, p->h, 0, GL_RGBA, GL_FLOAT, NULL);
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    gl.BindTexture(GL_TEXTURE_2D, 0);
    gl.BindFramebuffer(GL_FRAMEBUFFER, fbo);
    gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, p->gbuf, 0);
    GLenum st = gl.CheckFramebufferStatus(GL_FRAMEBUFFER);
    gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
    if (st != GL_FRAMEBUFFER_COMPLETE)
        return ct_fail(err, CT_ESYS, "kept base with a position buffer %dx%d incomplete: 0x%04x", p->w, p->h,
                       (unsigned)st);
    return gl_check("position buffer creation", err);
}

int disp_screen_index(disp_screen *p, GLuint fbo, ct_error *err)
{
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, fbo);
    gl.ReadBuffer(GL_COLOR_ATTACHMENT1);
    gl.PixelStorei(GL_PACK_ALIGNMENT, 4);
    gl.ReadPixels(0, 0, p->w, p->h, GL_RED, GL_FLOAT, p->tri_img);
    gl.ReadBuffer(GL_COLOR_ATTACHMENT0);
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    int rc = gl_check("position buffer read-back", err);
    return rc ? rc : disp_tiles_set(p->tiles, p->tri_img, p->w, p->h, err);
}

int disp_screen_plan(disp_screen *p, const disp_texture *const *tex, const disp_rect *within, uint32_t n,
                     uint64_t *px, ct_error *err)
{
    *px = 0;
    p->nv = 0;
    if (!n || !p->gbuf) return CT_OK;
    int rc = ct_grow((void **)&p->range, &p->range_cap, 2 * (size_t)n, sizeof *p->range, "texture draws", err);
    if (rc) return rc;
    float w = (float)p->w, h = (float)p->h;
    size_t nv = 0;
    for (uint32_t i = 0; i < n; i++) {
        size_t nr = disp_tiles_cover(p->tiles, tex[i]->tri_begin, tex[i]->tri_end, within[i], p->rects);
        rc = ct_grow((void **)&p->verts, &p->verts_cap, 2 * nv + 12 * nr, sizeof *p->verts, "screen pass vertices", err);
        if (rc) return rc;
        p->range[2 * i] = (uint32_t)nv;
        for (size_t k = 0; k < nr; k++) {
            const disp_rect *r = &p->rects[k];
            *px += (uint64_t)(r->x1 - r->x0) * (uint64_t)(r->y1 - r->y0);
            float x0 = 2.0f * (float)r->x0 / w - 1.0f, x1 = 2.0f * (float)r->x1 / w - 1.0f;
            float y0 = 2.0f * (float)r->y0 / h - 1.0f, y1 = 2.0f * (float)r->y1 / h - 1.0f;
            const float v[12] = {x0, y0, x1, y0, x1, y1, x0, y0, x1, y1, x0, y1};
            memcpy(p->verts + 2 * nv, v, sizeof v);
            nv += 6;
        }
        p->range[2 * i + 1] = (uint32_t)nv - p->range[2 * i];
    }
    p->nv = nv;
    return CT_OK;
}

int disp_screen_draw(disp_screen *p, const disp_texture *const *tex, uint32_t n, uint32_t *draws, ct_error *err)
{
    size_t nv = p->nv;
    p->nv = 0;   /* a plan is drawn once */
    if (!n || !nv || n > p->range_cap / 2) return CT_OK;
    gl.BindBuffer(GL_ARRAY_BUFFER, p->vbo);
    gl.BufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(2 * nv * sizeof *p->verts), p->verts, GL_STREAM_DRAW);
    gl.BindBuffer(GL_ARRAY_BUFFER, 0);
    gl.Disable(GL_DEPTH_TEST);
    gl.Enable(GL_BLEND);
    gl.BlendEquation(GL_FUNC_ADD);
    gl.BlendFunc(GL_ONE, GL_ONE);
    gl.UseProgram(p->prog);
    gl.ActiveTexture(GL_TEXTURE1);
    gl.BindTexture(GL_TEXTURE_2D, p->gbuf);
    gl.ActiveTexture(GL_TEXTURE0);
    gl.BindVertexArray(p->vao);
    for (uint32_t i = 0; i < n; i++) {
        if (!p->range[2 * i + 1]) continue;
        const disp_texture *x = tex[i];
        gl.UniformMatrix4fv(p->u_texproj, 1, GL_TRUE, &x->proj.m[0][0]);   /* row-major mat4: transposed */
        /* indices travel as floats: exact below 2^24 (the caller's check) */
        gl.Uniform2f(p->u_tris, (float)x->tri_begin, (float)x->tri_end);
        gl.BindTexture(GL_TEXTURE_2D, x->gl_tex);
        gl.DrawArrays(GL_TRIANGLES, (GLint)p->range[2 * i], (GLsizei)p->range[2 * i + 1]);
        (*draws)++;
    }
    gl.ActiveTexture(GL_TEXTURE1);
    gl.BindTexture(GL_TEXTURE_2D, 0);
    gl.ActiveTexture(GL_TEXTURE0);
    gl.BindVertexArray(0);
    gl.Disable(GL_BLEND);
    gl.Enable(GL_DEPTH_TEST);
    return gl_check("screen-space corrections", err);
}

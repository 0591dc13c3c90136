/* gl_shaders.h: GLSL 3.30 sources of the display's programs and the helper
 * that compiles and links them. The mesh vertex shader is shared by every
 * mesh pass and declares gl_Position invariant, so passes 2 and 3 hit exactly
 * the depth values pass 1 wrote (GL_LEQUAL depth test, no writes). */
#ifndef CT_GL_SHADERS_H
#define CT_GL_SHADERS_H

#include "display/gl_load.h"

/* Fragment-shader variants of the mesh program (the value of PASS). */
typedef enum gl_mesh_pass {
    GL_PASS_RAD  = 0,   /* pass 1: Gouraud radiosity (times u_rad_scale) */
    GL_PASS_POS  = 1,   /* pass 2: positive part of texture 0's correction */
    GL_PASS_NEG  = 2,   /* pass 3: negative part (drawn with REVERSE_SUBTRACT) */
    GL_PASS_ONE  = 3,   /* one pass: radiosity + signed corrections of NTEX (1..4) textures */
    GL_PASS_FLAT = 4,   /* flat colour u_color (texture assignment view) */
    GL_PASS_GLASS = 5,  /* see-through glass: u_transmission * (1 - F), a multiplicative blend */
    GL_PASS_GBUF = 6,   /* pass 1 into the kept base: radiosity, and at location 1 the sorted
                           triangle index (u_tri_base + gl_PrimitiveID) and world position */
    GL_PASS_COUNT = 7
} gl_mesh_pass;

/* Textures the one-pass program samples at once. */
#define GL_ONE_PASS_MAX_TEX 4

/* Vertex shader of every mesh pass: a_pos (location 0), a_rad (location 1),
 * u_mvp, u_texproj[4] (world -> texture, projective); passes the world
 * position on for the glass pass's Fresnel term. */
extern const char *const gl_src_mesh_vs;
/* Fragment shader of the mesh passes, specialised by "#define PASS n" (and
 * "#define NTEX n" for GL_PASS_ONE). */
extern const char *const gl_src_mesh_fs;
/* Screen-space triangles: a_ndc (location 0), normalized device x, y. */
extern const char *const gl_src_quads_vs;
/* Adds texture u_tex0's correction (through u_texproj0) at the pixels whose
 * kept surface (u_gbuf, from GL_PASS_GBUF) is one of triangles
 * [u_tris.x, u_tris.y). */
extern const char *const gl_src_screen_corr_fs;
/* A full-screen triangle (no attributes) with v_uv in [0,1]^2. */
extern const char *const gl_src_screen_vs;
/* Exposure and sRGB encoding of the float image (u_mode 0), or the signed
 * view 0.5 + 0.5 * clamp(v * 2^exposure) for corrections (u_mode 1). */
extern const char *const gl_src_tonemap_fs;
/* Points at world positions through u_mvp, pulled towards u_eye by the
 * factor u_pull (sample hit points in the samples view). */
extern const char *const gl_src_points_world_vs;
/* A flat colour u_color (points, and the dimming of the samples view). */
extern const char *const gl_src_points_fs;

/* Compiles vs and fs (each prefixed with "#version 330 core" and `defines`,
 * which may be NULL) and links them; `name` appears in error messages. */
int gl_program_build(const char *name, const char *vs, const char *fs, const char *defines,
                     GLuint *out, ct_error *err);

#endif

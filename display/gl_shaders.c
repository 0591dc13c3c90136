#include "display/gl_shaders.h"

#include <stdio.h>
#include <string.h>

const char *const gl_src_mesh_vs =
    "layout(location = 0) in vec3 a_pos;\n"
    "layout(location = 1) in vec3 a_rad;\n"
    "uniform mat4 u_mvp;\n"
    "uniform mat4 u_texproj[4];\n"
    "centroid out vec3 v_rad;\n"
    "out vec3 v_pos;\n"
    "centroid out vec4 v_tex0;\n"
    "centroid out vec4 v_tex1;\n"
    "centroid out vec4 v_tex2;\n"
    "centroid out vec4 v_tex3;\n"
    "invariant gl_Position;\n"
    "void main() {\n"
    "    vec4 p = vec4(a_pos, 1.0);\n"
    "    gl_Position = u_mvp * p;\n"
    "    v_rad = a_rad;\n"
    "    v_pos = a_pos;\n"
    "    v_tex0 = u_texproj[0] * p;\n"
    "    v_tex1 = u_texproj[1] * p;\n"
    "    v_tex2 = u_texproj[2] * p;\n"
    "    v_tex3 = u_texproj[3] * p;\n"
    "}\n";

/* Texture coordinates are projective (divide by w, §3.2); only fragments
 * whose coordinates fall in [0,1]^2 in front of the projection centre get a
 * correction. Textures have no mipmaps, so textureLod(level 0) is the
 * same bilinear lookup as texture() and may sit behind the test (no
 * derivatives needed): fragments outside a texture skip its fetch. The
 * one-pass variant is compiled for NTEX = 1..4 textures.
 * The glass pass draws transmission * (1 - F) per crossing, F the exact
 * unpolarized Fresnel reflectance at the angle between the eye ray and the
 * face (from the derivatives of the world position), evaluated as the
 * tracer's bsdf_fresnel on the outside (air) side. */
const char *const gl_src_mesh_fs =
    "centroid in vec3 v_rad;\n"
    "centroid in vec4 v_tex0;\n"
    "centroid in vec4 v_tex1;\n"
    "centroid in vec4 v_tex2;\n"
    "centroid in vec4 v_tex3;\n"
    "in vec3 v_pos;\n"
    "uniform float u_rad_scale;\n"
    "uniform vec3 u_color;\n"
    "uniform vec3 u_eye;\n"
    "uniform vec3 u_transmission;\n"
    "uniform float u_ior;\n"
    "uniform sampler2D u_tex0;\n"
    "uniform sampler2D u_tex1;\n"
    "uniform sampler2D u_tex2;\n"
    "uniform sampler2D u_tex3;\n"
    "uniform int u_tri_base;\n"
    "out vec4 o_color;\n"
    "#if PASS == 6\n"
    "layout(location = 1) out vec4 o_gbuf;\n"
    "#endif\n"
    "vec3 corr(sampler2D s, vec4 t, out bool inside) {\n"
    "    vec2 tc = t.xy / t.w;\n"
    "    inside = t.w > 0.0 && all(greaterThanEqual(tc, vec2(0.0))) &&\n"
    "             all(lessThanEqual(tc, vec2(1.0)));\n"
    "    if (!inside) return vec3(0.0);\n"
    "    return textureLod(s, tc, 0.0).rgb;\n"
    "}\n"
    "float fresnel(float ci, float eta) {\n"
    "    float s2 = eta * eta * max(0.0, 1.0 - ci * ci);\n"
    "    if (s2 >= 1.0) return 1.0;\n"
    "    float ct = sqrt(1.0 - s2);\n"
    "    float rs = (eta * ci - ct) / (eta * ci + ct);\n"
    "    float rp = (ci - eta * ct) / (ci + eta * ct);\n"
    "    return 0.5 * (rs * rs + rp * rp);\n"
    "}\n"
    "void main() {\n"
    "    bool in0, in1, in2, in3;\n"
    "#if PASS == 0 || PASS == 6\n"
    "    o_color = vec4(u_rad_scale * v_rad, 1.0);\n"
    "#if PASS == 6\n"
    "    o_gbuf = vec4(float(u_tri_base + gl_PrimitiveID), v_pos);\n"
    "#endif\n"
    "#elif PASS == 1\n"
    "    vec3 c = corr(u_tex0, v_tex0, in0);\n"
    "    if (!in0) discard;\n"
    "    o_color = vec4(max(c, vec3(0.0)), 0.0);\n"
    "#elif PASS == 2\n"
    "    vec3 c = corr(u_tex0, v_tex0, in0);\n"
    "    if (!in0) discard;\n"
    "    o_color = vec4(max(-c, vec3(0.0)), 0.0);\n"
    "#elif PASS == 3\n"
    "    vec3 sum = u_rad_scale * v_rad;\n"
    "    sum += corr(u_tex0, v_tex0, in0);\n"
    "#if NTEX > 1\n"
    "    sum += corr(u_tex1, v_tex1, in1);\n"
    "#endif\n"
    "#if NTEX > 2\n"
    "    sum += corr(u_tex2, v_tex2, in2);\n"
    "#endif\n"
    "#if NTEX > 3\n"
    "    sum += corr(u_tex3, v_tex3, in3);\n"
    "#endif\n"
    "    o_color = vec4(sum, 1.0);\n"
    "#elif PASS == 5\n"
    "    vec3 n = cross(dFdx(v_pos), dFdy(v_pos));\n"
    "    float len = length(n);\n"
    "    float c = len > 0.0 ? abs(dot(normalize(v_pos - u_eye), n)) / len : 1.0;\n"
    "    o_color = vec4(u_transmission * (1.0 - fresnel(min(c, 1.0), 1.0 / u_ior)), 1.0);\n"
    "#else\n"
    "    o_color = vec4(u_color, 1.0);\n"
    "#endif\n"
    "}\n";

const char *const gl_src_quads_vs =
    "layout(location = 0) in vec2 a_ndc;\n"
    "void main() { gl_Position = vec4(a_ndc, 0.0, 1.0); }\n";

/* The kept surface's world position (g.yzw) gives the texture coordinate
 * the mesh passes interpolate (t = M p is linear in p), so a pixel gets
 * the same lookup as over the mesh, without sending the node's triangles
 * again. The triangle index (g.x) stands for the node: a subtree is one
 * contiguous range of the sorted triangles. Background pixels hold -1. */
const char *const gl_src_screen_corr_fs =
    "uniform sampler2D u_gbuf;\n"
    "uniform sampler2D u_tex0;\n"
    "uniform mat4 u_texproj0;\n"
    "uniform vec2 u_tris;\n"
    "out vec4 o_color;\n"
    "void main() {\n"
    "    vec4 g = texelFetch(u_gbuf, ivec2(gl_FragCoord.xy), 0);\n"
    "    if (g.x < u_tris.x || g.x >= u_tris.y) discard;\n"
    "    vec4 t = u_texproj0 * vec4(g.yzw, 1.0);\n"
    "    vec2 tc = t.xy / t.w;\n"
    "    if (!(t.w > 0.0 && all(greaterThanEqual(tc, vec2(0.0))) && all(lessThanEqual(tc, vec2(1.0)))))\n"
    "        discard;\n"
    "    o_color = vec4(textureLod(u_tex0, tc, 0.0).rgb, 0.0);\n"
    "}\n";

const char *const gl_src_screen_vs =
    "out vec2 v_uv;\n"
    "void main() {\n"
    "    vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);\n"
    "    v_uv = 0.5 * p + 0.5;\n"
    "    gl_Position = vec4(p, 0.0, 1.0);\n"
    "}\n";

/* The sRGB curve of IEC 61966-2-1, the same img_tonemap applies to PNGs. */
const char *const gl_src_tonemap_fs =
    "in vec2 v_uv;\n"
    "uniform sampler2D u_image;\n"
    "uniform float u_exposure;\n"
    "uniform int u_mode;\n"
    "out vec4 o_color;\n"
    "float srgb(float x) {\n"
    "    x = clamp(x, 0.0, 1.0);\n"
    "    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;\n"
    "}\n"
    "void main() {\n"
    "    vec3 v = texture(u_image, v_uv).rgb * exp2(u_exposure);\n"
    "    vec3 c;\n"
    "    if (u_mode == 1) c = 0.5 + 0.5 * clamp(v, -1.0, 1.0);\n"
    "    else c = vec3(srgb(v.r), srgb(v.g), srgb(v.b));\n"
    "    o_color = vec4(c, 1.0);\n"
    "}\n";

/* A sample's hit point lies on a surface the mesh passes drew: it is moved
 * a fraction (1 - u_pull) of its distance towards the eye, along its own
 * viewing ray (same pixel), so the depth test keeps it in front of its
 * surface but hides it behind nearer geometry. */
const char *const gl_src_points_world_vs =
    "layout(location = 0) in vec3 a_pos;\n"
    "uniform mat4 u_mvp;\n"
    "uniform vec3 u_eye;\n"
    "uniform float u_pull;\n"
    "uniform float u_point;\n"
    "void main() {\n"
    "    gl_Position = u_mvp * vec4(mix(u_eye, a_pos, u_pull), 1.0);\n"
    "    gl_PointSize = u_point;\n"
    "}\n";

const char *const gl_src_points_fs =
    "uniform vec3 u_color;\n"
    "out vec4 o_color;\n"
    "void main() { o_color = vec4(u_color, 1.0); }\n";

static int compile(const char *name, GLenum type, const char *src, const char *defines,
                   GLuint *out, ct_error *err)
{
    const char *parts[3] = {"#version 330 core\n", defines ? defines : "", src};
    GLuint sh = gl.CreateShader(type);
    gl.ShaderSource(sh, 3, parts, NULL);
    gl.CompileShader(sh);
    GLint ok = 0;
    gl.GetShaderiv(sh, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[512] = "";
        gl.GetShaderInfoLog(sh, sizeof log, NULL, log);
        for (char *p = log; *p; p++)
            if (*p == '\n') *p = ' ';
        gl.DeleteShader(sh);
        return ct_fail(err, CT_ESYS, "shader %s (%s) does not compile: %s", name,
                       type == GL_VERTEX_SHADER ? "vertex" : "fragment", log);
    }
    *out = sh;
    return CT_OK;
}

int gl_program_build(const char *name, const char *vs, const char *fs, const char *defines,
                     GLuint *out, ct_error *err)
{
    GLuint v = 0, f = 0;
    int rc = compile(name, GL_VERTEX_SHADER, vs, defines, &v, err);
    if (rc) return rc;
    rc = compile(name, GL_FRAGMENT_SHADER, fs, defines, &f, err);
    if (rc) {
        gl.DeleteShader(v);
        return rc;
    }
    GLuint p = gl.CreateProgram();
    gl.AttachShader(p, v);
    gl.AttachShader(p, f);
    gl.BindFragDataLocation(p, 0, "o_color");
    gl.LinkProgram(p);
    gl.DeleteShader(v);
    gl.DeleteShader(f);
    GLint ok = 0;
    gl.GetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[512] = "";
        gl.GetProgramInfoLog(p, sizeof log, NULL, log);
        for (char *q = log; *q; q++)
            if (*q == '\n') *q = ' ';
        gl.DeleteProgram(p);
        return ct_fail(err, CT_ESYS, "program %s does not link: %s", name, log);
    }
    *out = p;
    return CT_OK;
}

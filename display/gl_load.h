/* gl_load.h: the GL 3.3 core entry points corrtex uses, as one table of
 * function pointers filled from the current context's backend
 * (OSMesaGetProcAddress, eglGetProcAddress or glfwGetProcAddress).
 * Why a table and not GL_GLEXT_PROTOTYPES: the display links libOSMesa and
 * libGL/libEGL into one program, and both export gl* symbols; calling them by
 * name would reach whichever library the dynamic linker found first, not the
 * context that is current. Fetching every entry point from the backend that
 * made the context current is correct for all three backends. Code calls
 * gl.Clear(...), gl.DrawElements(...), and so on. */
#ifndef CT_GL_LOAD_H
#define CT_GL_LOAD_H

#include <GL/glcorearb.h>
#include <stdbool.h>

#include "common/error.h"

#define GL_LOAD_FUNCS(X)                                                          \
    X(PFNGLGETERRORPROC, GetError)                                                \
    X(PFNGLGETSTRINGPROC, GetString)                                              \
    X(PFNGLGETSTRINGIPROC, GetStringi)                                            \
    X(PFNGLGETINTEGERVPROC, GetIntegerv)                                          \
    X(PFNGLVIEWPORTPROC, Viewport)                                                \
    X(PFNGLCLEARPROC, Clear)                                                      \
    X(PFNGLCLEARCOLORPROC, ClearColor)                                            \
    X(PFNGLCLEARDEPTHPROC, ClearDepth)                                            \
    X(PFNGLENABLEPROC, Enable)                                                    \
    X(PFNGLDISABLEPROC, Disable)                                                  \
    X(PFNGLBLENDFUNCPROC, BlendFunc)                                              \
    X(PFNGLBLENDEQUATIONPROC, BlendEquation)                                      \
    X(PFNGLBLENDCOLORPROC, BlendColor)                                            \
    X(PFNGLDEPTHFUNCPROC, DepthFunc)                                              \
    X(PFNGLDEPTHMASKPROC, DepthMask)                                              \
    X(PFNGLCOLORMASKPROC, ColorMask)                                              \
    X(PFNGLCOLORMASKIPROC, ColorMaski)                                            \
    X(PFNGLDRAWBUFFERSPROC, DrawBuffers)                                          \
    X(PFNGLCLEARBUFFERFVPROC, ClearBufferfv)                                      \
    X(PFNGLSTENCILFUNCPROC, StencilFunc)                                          \
    X(PFNGLSTENCILOPPROC, StencilOp)                                              \
    X(PFNGLSCISSORPROC, Scissor)                                                  \
    X(PFNGLFINISHPROC, Finish)                                                    \
    X(PFNGLFLUSHPROC, Flush)                                                      \
    X(PFNGLPIXELSTOREIPROC, PixelStorei)                                          \
    X(PFNGLREADPIXELSPROC, ReadPixels)                                            \
    X(PFNGLREADBUFFERPROC, ReadBuffer)                                            \
    X(PFNGLDRAWBUFFERPROC, DrawBuffer)                                            \
    X(PFNGLGENBUFFERSPROC, GenBuffers)                                            \
    X(PFNGLBINDBUFFERPROC, BindBuffer)                                            \
    X(PFNGLBUFFERDATAPROC, BufferData)                                            \
    X(PFNGLBUFFERSUBDATAPROC, BufferSubData)                                      \
    X(PFNGLDELETEBUFFERSPROC, DeleteBuffers)                                      \
    X(PFNGLMAPBUFFERRANGEPROC, MapBufferRange)                                    \
    X(PFNGLUNMAPBUFFERPROC, UnmapBuffer)                                          \
    X(PFNGLGENVERTEXARRAYSPROC, GenVertexArrays)                                  \
    X(PFNGLBINDVERTEXARRAYPROC, BindVertexArray)                                  \
    X(PFNGLDELETEVERTEXARRAYSPROC, DeleteVertexArrays)                            \
    X(PFNGLENABLEVERTEXATTRIBARRAYPROC, EnableVertexAttribArray)                  \
    X(PFNGLVERTEXATTRIBPOINTERPROC, VertexAttribPointer)                          \
    X(PFNGLCREATESHADERPROC, CreateShader)                                        \
    X(PFNGLSHADERSOURCEPROC, ShaderSource)                                        \
    X(PFNGLCOMPILESHADERPROC, CompileShader)                                      \
    X(PFNGLGETSHADERIVPROC, GetShaderiv)                                          \
    X(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog)                                \
    X(PFNGLDELETESHADERPROC, DeleteShader)                                        \
    X(PFNGLCREATEPROGRAMPROC, CreateProgram)                                      \
    X(PFNGLATTACHSHADERPROC, AttachShader)                                        \
    X(PFNGLBINDATTRIBLOCATIONPROC, BindAttribLocation)                            \
    X(PFNGLBINDFRAGDATALOCATIONPROC, BindFragDataLocation)                        \
    X(PFNGLLINKPROGRAMPROC, LinkProgram)                                          \
    X(PFNGLGETPROGRAMIVPROC, GetProgramiv)                                        \
    X(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog)                              \
    X(PFNGLDELETEPROGRAMPROC, DeleteProgram)                                      \
    X(PFNGLUSEPROGRAMPROC, UseProgram)                                            \
    X(PFNGLGETUNIFORMLOCATIONPROC, GetUniformLocation)                            \
    X(PFNGLUNIFORM1IPROC, Uniform1i)                                              \
    X(PFNGLUNIFORM1FPROC, Uniform1f)                                              \
    X(PFNGLUNIFORM2FPROC, Uniform2f)                                              \
    X(PFNGLUNIFORM3FPROC, Uniform3f)                                              \
    X(PFNGLUNIFORM4FPROC, Uniform4f)                                              \
    X(PFNGLUNIFORMMATRIX4FVPROC, UniformMatrix4fv)                                \
    X(PFNGLGENTEXTURESPROC, GenTextures)                                          \
    X(PFNGLBINDTEXTUREPROC, BindTexture)                                          \
    X(PFNGLACTIVETEXTUREPROC, ActiveTexture)                                      \
    X(PFNGLTEXIMAGE2DPROC, TexImage2D)                                            \
    X(PFNGLTEXSUBIMAGE2DPROC, TexSubImage2D)                                      \
    X(PFNGLTEXPARAMETERIPROC, TexParameteri)                                      \
    X(PFNGLDELETETEXTURESPROC, DeleteTextures)                                    \
    X(PFNGLGENFRAMEBUFFERSPROC, GenFramebuffers)                                  \
    X(PFNGLBINDFRAMEBUFFERPROC, BindFramebuffer)                                  \
    X(PFNGLBLITFRAMEBUFFERPROC, BlitFramebuffer)                                  \
    X(PFNGLFRAMEBUFFERTEXTURE2DPROC, FramebufferTexture2D)                        \
    X(PFNGLFRAMEBUFFERRENDERBUFFERPROC, FramebufferRenderbuffer)                  \
    X(PFNGLCHECKFRAMEBUFFERSTATUSPROC, CheckFramebufferStatus)                    \
    X(PFNGLDELETEFRAMEBUFFERSPROC, DeleteFramebuffers)                            \
    X(PFNGLGENRENDERBUFFERSPROC, GenRenderbuffers)                                \
    X(PFNGLBINDRENDERBUFFERPROC, BindRenderbuffer)                                \
    X(PFNGLRENDERBUFFERSTORAGEPROC, RenderbufferStorage)                          \
    X(PFNGLRENDERBUFFERSTORAGEMULTISAMPLEPROC, RenderbufferStorageMultisample)    \
    X(PFNGLDELETERENDERBUFFERSPROC, DeleteRenderbuffers)                          \
    X(PFNGLDRAWARRAYSPROC, DrawArrays)                                            \
    X(PFNGLDRAWELEMENTSPROC, DrawElements)                                        \
    X(PFNGLGENQUERIESPROC, GenQueries)                                            \
    X(PFNGLDELETEQUERIESPROC, DeleteQueries)                                      \
    X(PFNGLBEGINQUERYPROC, BeginQuery)                                            \
    X(PFNGLENDQUERYPROC, EndQuery)                                                \
    X(PFNGLGETQUERYOBJECTIVPROC, GetQueryObjectiv)                                \
    X(PFNGLGETQUERYOBJECTUI64VPROC, GetQueryObjectui64v)

typedef struct gl_api {
#define GL_LOAD_MEMBER(type, name) type name;
    GL_LOAD_FUNCS(GL_LOAD_MEMBER)
#undef GL_LOAD_MEMBER
    /* Optional (GL 4.5 or ARB_clip_control), NULL when the context lacks it. */
    PFNGLCLIPCONTROLPROC ClipControl;
    /* Optional (GL 4.4 or ARB_clear_texture), NULL when the context lacks
     * it: zeroes a new texture without binding it to a framebuffer (a
     * software rasteriser flushes its queued drawing at every framebuffer
     * change; docs/display.md, "Known problems"). */
    PFNGLCLEARTEXIMAGEPROC ClearTexImage;
    /* Depth is "reversed": a [0, 1] clip range (glClipControl), a 32-bit
     * float depth buffer, 1 at the near plane, 0 at infinity, so depth
     * resolution is relative to the distance everywhere. Without clip
     * control: the classic 24-bit depth, 0 near, 1 far. */
    bool reversed_z;
} gl_api;

/* The entry points of the current context (one context per process). */
extern gl_api gl;

/* A backend's lookup: returns the entry point named e.g. "glClear" or NULL. */
typedef void (*gl_proc)(void);
typedef gl_proc (*gl_getproc_fn)(const char *name);

/* Fills `gl` through getproc and checks the context is GL >= 3.3 core;
 * `backend` names the backend in error messages. Turns on reversed depth
 * where the context has clip control, unless CORRTEX_GL_REVERSED_Z=0. */
int gl_load(gl_getproc_fn getproc, const char *backend, ct_error *err);

/* Fails with the pending GL error (if any) naming `what`; clears all errors. */
int gl_check(const char *what, ct_error *err);

#endif

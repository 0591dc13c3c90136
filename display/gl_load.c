#include "display/gl_load.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

gl_api gl;

/* Whether the environment turns a GL feature off (NAME=0: the tests cover
 * both paths). */
static bool env_off(const char *name)
{
    const char *v = getenv(name);
    return v && strcmp(v, "0") == 0;
}

int gl_load(gl_getproc_fn getproc, const char *backend, ct_error *err)
{
    memset(&gl, 0, sizeof gl);
#define GL_LOAD_ONE(type, name)                                                           \
    gl.name = (type)getproc("gl" #name);                                                  \
    if (!gl.name)                                                                         \
        return ct_fail(err, CT_ESYS, "%s: the GL context lacks gl%s", backend, #name);
    GL_LOAD_FUNCS(GL_LOAD_ONE)
#undef GL_LOAD_ONE
    GLint major = 0, minor = 0, mask = 0;
    gl.GetIntegerv(GL_MAJOR_VERSION, &major);
    gl.GetIntegerv(GL_MINOR_VERSION, &minor);
    gl.GetIntegerv(GL_CONTEXT_PROFILE_MASK, &mask);
    while (gl.GetError() != GL_NO_ERROR) {}
    if (major * 10 + minor < 33)
        return ct_fail(err, CT_ESYS, "%s: GL %d.%d context, need 3.3 core (renderer %s)", backend,
                       major, minor, (const char *)gl.GetString(GL_RENDERER));
    if (!(mask & GL_CONTEXT_CORE_PROFILE_BIT))
        return ct_fail(err, CT_ESYS, "%s: GL %d.%d context is not a core profile", backend, major,
                       minor);
    /* Backends hand out pointers for names a context does not support, so
     * the version or the extension list decides, not the pointer. */
    bool clip = major * 10 + minor >= 45, clear_tex = major * 10 + minor >= 44;
    GLint next = 0;
    gl.GetIntegerv(GL_NUM_EXTENSIONS, &next);
    for (GLint i = 0; i < next && !(clip && clear_tex); i++) {
        const char *e = (const char *)gl.GetStringi(GL_EXTENSIONS, (GLuint)i);
        clip = clip || (e && strcmp(e, "GL_ARB_clip_control") == 0);
        clear_tex = clear_tex || (e && strcmp(e, "GL_ARB_clear_texture") == 0);
    }
    if (clear_tex && !env_off("CORRTEX_GL_CLEAR_TEXTURE"))
        gl.ClearTexImage = (PFNGLCLEARTEXIMAGEPROC)getproc("glClearTexImage");
    if (clip && !env_off("CORRTEX_GL_REVERSED_Z")) gl.ClipControl = (PFNGLCLIPCONTROLPROC)getproc("glClipControl");
    if (gl.ClipControl) {
        gl.ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
        gl.reversed_z = true;
    }
    while (gl.GetError() != GL_NO_ERROR) {}
    return CT_OK;
}

int gl_check(const char *what, ct_error *err)
{
    GLenum e = gl.GetError(), first = e;
    while (e != GL_NO_ERROR) e = gl.GetError();
    if (first == GL_NO_ERROR) return CT_OK;
    return ct_fail(err, CT_ESYS, "GL error 0x%04x in %s", (unsigned)first, what);
}

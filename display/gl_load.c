#include "display/gl_load.h"

#include <stdio.h>
#include <string.h>

gl_api gl;

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
    return CT_OK;
}

int gl_check(const char *what, ct_error *err)
{
    GLenum e = gl.GetError(), first = e;
    while (e != GL_NO_ERROR) e = gl.GetError();
    if (first == GL_NO_ERROR) return CT_OK;
    return ct_fail(err, CT_ESYS, "GL error 0x%04x in %s", (unsigned)first, what);
}

/* EGL surfaceless backend: EGL_MESA_platform_surfaceless through
 * eglGetPlatformDisplay (EGL 1.5), a config-less GL 3.3 core context
 * (EGL_KHR_no_config_context) made current without a surface
 * (EGL_KHR_surfaceless_context). Works with llvmpipe and with GPU drivers
 * that expose render nodes; no X server needed. */
#include "display/gl_load.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <stdlib.h>
#include <string.h>

#include "display/gl_backend_impl.h"

typedef struct egl_state {
    EGLDisplay dpy;
    EGLContext ctx;
} egl_state;

static gl_proc getproc(const char *name)
{
    return (gl_proc)eglGetProcAddress(name);
}

static bool has_ext(const char *list, const char *ext)
{
    size_t n = strlen(ext);
    for (const char *p = list; p && (p = strstr(p, ext)); p += n)
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
    return false;
}

static void egl_close(gl_backend *b)
{
    egl_state *s = b->state;
    if (!s) return;
    if (s->dpy != EGL_NO_DISPLAY) {
        eglMakeCurrent(s->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        if (s->ctx != EGL_NO_CONTEXT) eglDestroyContext(s->dpy, s->ctx);
        eglTerminate(s->dpy);
    }
    free(s);
    b->state = NULL;
}

static const gl_backend_ops egl_ops = {NULL, NULL, NULL, egl_close};

static int fail(gl_backend *b, ct_error *err, const char *what)
{
    EGLint e = eglGetError();
    egl_close(b);
    return ct_fail(err, CT_ESYS, "egl: %s failed (EGL error 0x%04x)", what, (unsigned)e);
}

int gl_backend_open_egl(gl_backend *b, ct_error *err)
{
    egl_state *s = calloc(1, sizeof *s);
    if (!s) return ct_fail(err, CT_ENOMEM, "egl: out of memory");
    s->dpy = EGL_NO_DISPLAY;
    s->ctx = EGL_NO_CONTEXT;
    b->state = s;
    b->ops = &egl_ops;
    const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!has_ext(client, "EGL_MESA_platform_surfaceless")) {
        egl_close(b);
        return ct_fail(err, CT_ESYS, "egl: EGL_MESA_platform_surfaceless is not offered "
                       "(client extensions: %.120s)", client ? client : "none");
    }
    s->dpy = eglGetPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    if (s->dpy == EGL_NO_DISPLAY) return fail(b, err, "eglGetPlatformDisplay(surfaceless)");
    EGLint major, minor;
    if (!eglInitialize(s->dpy, &major, &minor)) {
        s->dpy = EGL_NO_DISPLAY;
        return fail(b, err, "eglInitialize");
    }
    const char *exts = eglQueryString(s->dpy, EGL_EXTENSIONS);
    if (!has_ext(exts, "EGL_KHR_surfaceless_context") || !has_ext(exts, "EGL_KHR_no_config_context")) {
        egl_close(b);
        return ct_fail(err, CT_ESYS, "egl: display lacks EGL_KHR_surfaceless_context or "
                       "EGL_KHR_no_config_context");
    }
    if (!eglBindAPI(EGL_OPENGL_API)) return fail(b, err, "eglBindAPI(EGL_OPENGL_API)");
    const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 3,
                              EGL_CONTEXT_MINOR_VERSION, 3,
                              EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                              EGL_NONE};
    s->ctx = eglCreateContext(s->dpy, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attribs);
    if (s->ctx == EGL_NO_CONTEXT) return fail(b, err, "eglCreateContext(GL 3.3 core)");
    if (!eglMakeCurrent(s->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, s->ctx))
        return fail(b, err, "eglMakeCurrent(surfaceless)");
    int rc = gl_load(getproc, "egl", err);
    if (rc) egl_close(b);
    return rc;
}

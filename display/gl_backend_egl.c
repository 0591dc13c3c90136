/* EGL headless backend: a GL 3.3 core context made current without a
 * surface (EGL_KHR_surfaceless_context); the compositor draws into its own
 * FBOs. Where the display comes from, in order:
 *   1. a hardware EGL device (EGL_EXT_platform_device), what a GPU server
 *      without X offers: on a machine with Mesa and a GPU vendor's driver
 *      both installed, the surfaceless platform can be Mesa's, and the
 *      display would quietly render with llvmpipe;
 *   2. the surfaceless platform (EGL_MESA_platform_surfaceless; Mesa's
 *      render nodes or llvmpipe, NVIDIA's driver too);
 *   3. a software EGL device (EGL_MESA_device_software).
 * CORRTEX_EGL_DEVICE=N takes device N of eglQueryDevicesEXT's list instead
 * (one of several GPUs, or the software device on purpose). The context is
 * config-less where EGL_KHR_no_config_context is offered, else made with a
 * pbuffer-capable RGB8 config (never drawn to). */
#include "display/gl_load.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "display/gl_backend_impl.h"

#define COMP "corrtex-display"

#define MAX_DEVICES 16

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

/* Initialises dpy and makes a GL 3.3 core context current on it; on failure
 * terminates what it initialised and says which step failed in why. */
static bool make_current(egl_state *s, EGLDisplay dpy, char *why, size_t why_size)
{
    EGLint major, minor;
    if (dpy == EGL_NO_DISPLAY) {
        snprintf(why, why_size, "no display (EGL error 0x%04x)", (unsigned)eglGetError());
        return false;
    }
    if (!eglInitialize(dpy, &major, &minor)) {
        snprintf(why, why_size, "eglInitialize failed (EGL error 0x%04x)", (unsigned)eglGetError());
        return false;
    }
    const char *exts = eglQueryString(dpy, EGL_EXTENSIONS);
    const char *step = NULL;
    EGLContext ctx = EGL_NO_CONTEXT;
    EGLConfig cfg = EGL_NO_CONFIG_KHR;
    if (!has_ext(exts, "EGL_KHR_surfaceless_context")) {
        snprintf(why, why_size, "no EGL_KHR_surfaceless_context");
        eglTerminate(dpy);
        return false;
    }
    if (!eglBindAPI(EGL_OPENGL_API)) step = "eglBindAPI(EGL_OPENGL_API)";
    if (!step && !has_ext(exts, "EGL_KHR_no_config_context")) {
        const EGLint want[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT,
                               EGL_RED_SIZE, 8, EGL_GREEN_SIZE, 8, EGL_BLUE_SIZE, 8, EGL_NONE};
        EGLint n = 0;
        if (!eglChooseConfig(dpy, want, &cfg, 1, &n) || n < 1) step = "eglChooseConfig(OpenGL, RGB8)";
    }
    const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 3,
                              EGL_CONTEXT_MINOR_VERSION, 3,
                              EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                              EGL_NONE};
    if (!step) {
        ctx = eglCreateContext(dpy, cfg, EGL_NO_CONTEXT, attribs);
        if (ctx == EGL_NO_CONTEXT) step = "eglCreateContext(GL 3.3 core)";
    }
    if (!step && !eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx)) step = "eglMakeCurrent(surfaceless)";
    if (step) {
        snprintf(why, why_size, "%s failed (EGL error 0x%04x)", step, (unsigned)eglGetError());
        if (ctx != EGL_NO_CONTEXT) eglDestroyContext(dpy, ctx);
        eglTerminate(dpy);
        return false;
    }
    s->dpy = dpy;
    s->ctx = ctx;
    return true;
}

typedef struct devices {
    EGLDeviceEXT dev[MAX_DEVICES];
    EGLint n;
    PFNEGLQUERYDEVICESTRINGEXTPROC query_string;
} devices;

static void list_devices(const char *client, devices *d)
{
    d->n = 0;
    d->query_string = NULL;
    if (!has_ext(client, "EGL_EXT_device_enumeration") || !has_ext(client, "EGL_EXT_platform_device")) return;
    PFNEGLQUERYDEVICESEXTPROC query = (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
    d->query_string = (PFNEGLQUERYDEVICESTRINGEXTPROC)eglGetProcAddress("eglQueryDeviceStringEXT");
    if (!query || !d->query_string || !query(MAX_DEVICES, d->dev, &d->n)) d->n = 0;
}

static bool is_software(const devices *d, int i)
{
    return has_ext(d->query_string(d->dev[i], EGL_EXTENSIONS), "EGL_MESA_device_software");
}

static bool try_device(egl_state *s, const devices *d, int i, char *why, size_t why_size)
{
    const char *kind = is_software(d, i) ? "software" : "hardware";
    if (!make_current(s, eglGetPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, d->dev[i], NULL), why, why_size)) {
        ct_info(COMP, "egl: device %d of %d (%s): %s", i, (int)d->n, kind, why);
        return false;
    }
    ct_info(COMP, "egl: device %d of %d (%s)", i, (int)d->n, kind);
    return true;
}

/* The listed devices that are (or are not) software, in order, until one
 * gives a context. */
static bool try_devices(egl_state *s, const devices *d, bool software, char *why, size_t why_size)
{
    for (int i = 0; i < d->n; i++)
        if (is_software(d, i) == software && try_device(s, d, i, why, why_size)) return true;
    return false;
}

/* CORRTEX_EGL_DEVICE: -1 when unset, else the index; false when malformed. */
static bool chosen_device(int *out)
{
    const char *v = getenv("CORRTEX_EGL_DEVICE");
    *out = -1;
    if (!v || !*v) return true;
    char *end;
    errno = 0;
    long i = strtol(v, &end, 10);
    if (errno || *end || i < 0 || i >= MAX_DEVICES) return false;
    *out = (int)i;
    return true;
}

int gl_backend_open_egl(gl_backend *b, ct_error *err)
{
    egl_state *s = calloc(1, sizeof *s);
    if (!s) return ct_fail(err, CT_ENOMEM, "egl: out of memory");
    s->dpy = EGL_NO_DISPLAY;
    s->ctx = EGL_NO_CONTEXT;
    b->state = s;
    b->ops = &egl_ops;
    int want;
    if (!chosen_device(&want)) {
        egl_close(b);
        return ct_fail(err, CT_EINVAL, "egl: CORRTEX_EGL_DEVICE='%s' is not a device index (0 to %d)",
                       getenv("CORRTEX_EGL_DEVICE"), MAX_DEVICES - 1);
    }
    const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    devices d;
    list_devices(client, &d);
    char why[160] = "";
    bool ok = false;
    if (want >= 0) {
        if (want >= d.n) {
            egl_close(b);
            return ct_fail(err, CT_ESYS, "egl: CORRTEX_EGL_DEVICE=%d, but EGL lists %d device%s", want, (int)d.n,
                           d.n == 1 ? "" : "s");
        }
        ok = try_device(s, &d, want, why, sizeof why);
        if (!ok) {
            egl_close(b);
            return ct_fail(err, CT_ESYS, "egl: device %d: %s", want, why);
        }
    }
    if (!ok) ok = try_devices(s, &d, false, why, sizeof why);
    if (!ok && has_ext(client, "EGL_MESA_platform_surfaceless")) {
        ok = make_current(s, eglGetPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL), why,
                          sizeof why);
        if (ok) ct_info(COMP, "egl: the surfaceless platform");
    }
    if (!ok) ok = try_devices(s, &d, true, why, sizeof why);
    if (!ok) {
        egl_close(b);
        if (!why[0])
            return ct_fail(err, CT_ESYS, "egl: neither an EGL device nor EGL_MESA_platform_surfaceless is offered "
                           "(client extensions: %.120s)", client ? client : "none");
        return ct_fail(err, CT_ESYS, "egl: no display gave a GL 3.3 core context (last: %s)", why);
    }
    int rc = gl_load(getproc, "egl", err);
    if (rc) egl_close(b);
    return rc;
}

#include "display/gl_backend.h"

#include <dlfcn.h>
#include <link.h>
#include <stdlib.h>
#include <string.h>

#include "display/gl_backend_impl.h"

static const char *const names[] = {"glfw", "egl", "osmesa"};

static void pin_driver_libraries(void);

const char *gl_backend_name(gl_backend_kind kind)
{
    return (unsigned)kind < 3 ? names[kind] : "?";
}

gl_backend_kind gl_backend_default(void)
{
    /* Not $WAYLAND_DISPLAY: Debian's GLFW 3.3 (libglfw3) speaks X11 only,
     * and a Wayland desktop runs X clients through XWayland, which sets
     * $DISPLAY. */
    const char *d = getenv("DISPLAY");
    return d && *d ? GL_BACKEND_GLFW : GL_BACKEND_EGL;
}

int gl_backend_open(gl_backend_kind kind, int width, int height, const char *title, bool vsync,
                    gl_backend **out, ct_error *err)
{
    *out = NULL;
    if (width < 1 || height < 1 || width > 16384 || height > 16384)
        return ct_fail(err, CT_EINVAL, "image size %dx%d out of range 1..16384", width, height);
    gl_backend *b = calloc(1, sizeof *b);
    if (!b) return ct_fail(err, CT_ENOMEM, "out of memory for a GL backend");
    b->kind = kind;
    b->width = width;
    b->height = height;
    int rc;
    switch (kind) {
    case GL_BACKEND_GLFW: rc = gl_backend_open_glfw(b, title ? title : "corrtex", vsync, err); break;
    case GL_BACKEND_EGL: rc = gl_backend_open_egl(b, err); break;
    case GL_BACKEND_OSMESA: rc = gl_backend_open_osmesa(b, err); break;
    default: rc = ct_fail(err, CT_EINVAL, "unknown backend %d", (int)kind); break;
    }
    if (rc) {
        free(b);
        return rc;
    }
    pin_driver_libraries();
    *out = b;
    return CT_OK;
}

gl_backend_kind gl_backend_kind_of(const gl_backend *b) { return b->kind; }

bool gl_backend_is_window(const gl_backend *b) { return b->kind == GL_BACKEND_GLFW; }

bool gl_press_push(gl_press_queue *q, int key)
{
    if (q->n == GL_PRESS_QUEUE_CAP) {
        q->dropped++;
        return false;
    }
    q->keys[(q->head + q->n++) % GL_PRESS_QUEUE_CAP] = key;
    return true;
}

void gl_press_take(gl_press_queue *q, gl_input *in)
{
    in->npresses = 0;
    while (q->n > 0 && in->npresses < GL_INPUT_MAX_PRESSES) {
        in->presses[in->npresses++] = q->keys[q->head];
        q->head = (q->head + 1) % GL_PRESS_QUEUE_CAP;
        q->n--;
    }
}

void gl_backend_poll(gl_backend *b, gl_input *in)
{
    in->npresses = 0;
    in->mouse_dx = in->mouse_dy = in->scroll = 0;
    in->fb_width = b->width;
    in->fb_height = b->height;
    in->hidden = false;
    if (b->ops->poll) b->ops->poll(b, in);
}

void gl_backend_present(gl_backend *b)
{
    if (b->ops->present) b->ops->present(b);
}

void gl_backend_set_title(gl_backend *b, const char *title)
{
    if (b->ops->set_title) b->ops->set_title(b, title);
}

void gl_backend_close(gl_backend *b)
{
    if (!b) return;
    if (b->ops && b->ops->close) b->ops->close(b);
    free(b);
}

/* LeakSanitizer (sanitizer builds only read this): the Mesa/GLVND/X11 stack
 * behind the backends keeps process-lifetime allocations (driver screens,
 * glapi tables) that it never frees; they are not ours. Only these
 * libraries are suppressed. */
const char *__lsan_default_suppressions(void);
const char *__lsan_default_suppressions(void)
{
    return "leak:libOSMesa.so\n"
           "leak:libEGL_mesa.so\n"
           "leak:libGLX_mesa.so\n"
           "leak:libgallium\n"
           "leak:swrast_dri.so\n"
           "leak:libglapi.so\n"
           "leak:libGLdispatch.so\n"
           "leak:libLLVM\n"
           "leak:libX11.so\n"
           "leak:libxcb.so\n"
           "leak:libglfw.so\n";
}

/* GLVND unloads the vendor libraries and the driver at exit, before
 * LeakSanitizer looks, so their allocations show up from "<unknown module>"
 * and cannot be suppressed by name; marking the loaded GL libraries
 * RTLD_NODELETE keeps their names. Only sanitizer builds do this (GCC
 * defines __SANITIZE_ADDRESS__, Clang 14 only answers __has_feature). */
#if defined(__SANITIZE_ADDRESS__)
#define CT_ASAN_BUILD 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define CT_ASAN_BUILD 1
#endif
#endif

#if defined(CT_ASAN_BUILD)
static int pin_one(struct dl_phdr_info *info, size_t size, void *data)
{
    (void)size;
    (void)data;
    const char *n = info->dlpi_name;
    if (n && *n && (strstr(n, "_dri.so") || strstr(n, "gallium") || strstr(n, "EGL_mesa") ||
                    strstr(n, "GLX_mesa") || strstr(n, "OSMesa")))
        dlopen(n, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
    return 0;
}
#endif

static void pin_driver_libraries(void)
{
#if defined(CT_ASAN_BUILD)
    dl_iterate_phdr(pin_one, NULL);
#endif
}

/* GLFW backend: the interactive window, GL 3.3 core forward-compatible.
 * Input arrives through GLFW callbacks into a pending gl_input that
 * gl_backend_poll hands over. */
#include "display/gl_load.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <X11/Xlib.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "display/gl_backend_impl.h"

typedef struct glfw_state {
    GLFWwindow *win;
    gl_input pending;    /* all but the presses, which queue in presses */
    gl_press_queue presses;
    double last_x, last_y;
    bool have_last;
} glfw_state;

static char glfw_msg[200];

/* GLFW's own X11 accessor (glfw3native.h declares it, but with
 * GLFW_EXPOSE_NATIVE_X11 that header also wants the XRandR headers). */
GLFWAPI Display *glfwGetX11Display(void);

/* The window gone under the program: another client destroyed it (an X
 * error, BadWindow) or the X server went away (an I/O error). Xlib's own
 * handlers printed five lines or one of their own and called exit(): no
 * BYE to the master, frames.csv not completed. Now the window counts as
 * closed, with one line saying why, and the run ends in order. 1: an X
 * error, 2: the connection broke (Xlib then does nothing more on it). */
static volatile int x_gone;
static bool x_told;
static char x_why[160];

static int on_x_error(Display *d, XErrorEvent *e)
{
    if (!x_gone) {
        char text[96];
        XGetErrorText(d, e->error_code, text, sizeof text);
        snprintf(x_why, sizeof x_why, "X error %s (request %u)", text, (unsigned)e->request_code);
        x_gone = 1;
    }
    return 0;
}

static int on_x_io_error(Display *d)
{
    (void)d;
    return 0;   /* Xlib then calls the exit handler below instead of exit() */
}

static void on_x_io_exit(Display *d, void *user)
{
    (void)d;
    (void)user;
    snprintf(x_why, sizeof x_why, "the connection to the X server broke");
    x_gone = 2;
}

/* Ours, also after GLFW set and reset its own around some of its calls. */
static void x_handlers(void)
{
    Display *d = glfwGetX11Display();
    if (!d) return;
    XSetErrorHandler(on_x_error);
    XSetIOErrorHandler(on_x_io_error);
    XSetIOErrorExitHandler(d, on_x_io_exit, NULL);
}

static void on_error(int code, const char *desc)
{
    snprintf(glfw_msg, sizeof glfw_msg, "%s (GLFW error 0x%x)", desc, (unsigned)code);
}

static gl_proc getproc(const char *name)
{
    return (gl_proc)glfwGetProcAddress(name);
}

static int map_key(int k)
{
    if (k >= GLFW_KEY_A && k <= GLFW_KEY_Z) return 'A' + (k - GLFW_KEY_A);
    if (k >= GLFW_KEY_0 && k <= GLFW_KEY_9) return '0' + (k - GLFW_KEY_0);
    switch (k) {
    case GLFW_KEY_SPACE: return GL_KEY_SPACE;
    case GLFW_KEY_ESCAPE: return GL_KEY_ESCAPE;
    case GLFW_KEY_UP: return GL_KEY_UP;
    case GLFW_KEY_DOWN: return GL_KEY_DOWN;
    case GLFW_KEY_LEFT: return GL_KEY_LEFT;
    case GLFW_KEY_RIGHT: return GL_KEY_RIGHT;
    case GLFW_KEY_PAGE_UP: return GL_KEY_PAGE_UP;
    case GLFW_KEY_PAGE_DOWN: return GL_KEY_PAGE_DOWN;
    case GLFW_KEY_LEFT_SHIFT: case GLFW_KEY_RIGHT_SHIFT: return GL_KEY_SHIFT;
    case GLFW_KEY_F1: return GL_KEY_F1;
    case GLFW_KEY_EQUAL: case GLFW_KEY_KP_ADD: return '+';
    case GLFW_KEY_MINUS: case GLFW_KEY_KP_SUBTRACT: return '-';
    case GLFW_KEY_SLASH: return '?';
    default: return GL_KEY_NONE;
    }
}

static void queue_press(glfw_state *s, int k)
{
    if (!gl_press_push(&s->presses, k) && s->presses.dropped == 1)
        ct_warn("display", "more than %d key presses waiting for one frame: the rest are dropped", GL_PRESS_QUEUE_CAP);
}

static void on_key(GLFWwindow *w, int key, int scancode, int action, int mods)
{
    (void)scancode;
    (void)mods;
    glfw_state *s = glfwGetWindowUserPointer(w);
    int k = map_key(key);
    if (k == GL_KEY_NONE) return;
    if (action == GLFW_PRESS) {
        s->pending.down[k] = true;
        queue_press(s, k);
    } else if (action == GLFW_REPEAT && (k == '+' || k == '-')) {
        /* Exposure steps repeat while held (one step for a 2 s hold before);
         * toggles (P, the views) do not. */
        queue_press(s, k);
    } else if (action == GLFW_RELEASE) {
        s->pending.down[k] = false;
    }
}

static void on_cursor(GLFWwindow *w, double x, double y)
{
    glfw_state *s = glfwGetWindowUserPointer(w);
    bool held = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS ||
                glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS ||
                glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS;
    if (held && s->have_last) {
        s->pending.mouse_dx += x - s->last_x;
        s->pending.mouse_dy += y - s->last_y;
    }
    s->last_x = x;
    s->last_y = y;
    s->have_last = true;
}

static void on_scroll(GLFWwindow *w, double dx, double dy)
{
    (void)dx;
    glfw_state *s = glfwGetWindowUserPointer(w);
    s->pending.scroll += dy;
}

/* With the window gone: says so once, and asks to close. */
static bool window_gone(gl_input *in)
{
    if (!x_gone) return false;
    if (!x_told) ct_warn("display", "the window is gone: %s; ending as if it were closed", x_why);
    x_told = true;
    in->close = true;
    return true;
}

static void glfw_poll(gl_backend *b, gl_input *in)
{
    glfw_state *s = b->state;
    if (window_gone(in)) return;
    x_handlers();
    glfwPollEvents();
    memcpy(in->down, s->pending.down, sizeof in->down);
    gl_press_take(&s->presses, in);
    in->mouse_dx = s->pending.mouse_dx;
    in->mouse_dy = s->pending.mouse_dy;
    in->scroll = s->pending.scroll;
    in->close = glfwWindowShouldClose(s->win);
    if (window_gone(in)) return;
    glfwGetFramebufferSize(s->win, &in->fb_width, &in->fb_height);
    in->hidden = glfwGetWindowAttrib(s->win, GLFW_ICONIFIED) || !glfwGetWindowAttrib(s->win, GLFW_VISIBLE);
    s->pending.mouse_dx = s->pending.mouse_dy = s->pending.scroll = 0;
}

static void glfw_present(gl_backend *b)
{
    glfw_state *s = b->state;
    if (x_gone) return;
    glfwSwapBuffers(s->win);
}

static void glfw_title(gl_backend *b, const char *title)
{
    glfw_state *s = b->state;
    if (x_gone) return;
    glfwSetWindowTitle(s->win, title);
}

static void glfw_close(gl_backend *b)
{
    glfw_state *s = b->state;
    if (!s) return;
    /* (with the server gone there is nothing to destroy, and GLFW's
     * teardown would wait on the dead connection) */
    if (x_gone != 2) {
        if (s->win) glfwDestroyWindow(s->win);
        glfwTerminate();
    }
    free(s);
    b->state = NULL;
}

static const gl_backend_ops glfw_ops = {glfw_poll, glfw_present, glfw_title, glfw_close};

int gl_backend_open_glfw(gl_backend *b, const char *title, bool vsync, ct_error *err)
{
    glfw_msg[0] = '\0';
    glfwSetErrorCallback(on_error);
    if (!glfwInit()) {
        const char *dpy = getenv("DISPLAY");
        return ct_fail(err, CT_ESYS, "glfw: cannot initialise: %s (%s%s%s; try --backend egl)",
                       glfw_msg[0] ? glfw_msg : "unknown error", dpy && *dpy ? "DISPLAY=" : "$DISPLAY is not set",
                       dpy && *dpy ? dpy : "", dpy && *dpy ? " cannot be opened" : "");
    }
    glfw_state *s = calloc(1, sizeof *s);
    if (!s) {
        glfwTerminate();
        return ct_fail(err, CT_ENOMEM, "glfw: out of memory");
    }
    b->state = s;
    b->ops = &glfw_ops;
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
    glfwWindowHint(GLFW_SRGB_CAPABLE, GLFW_FALSE);
    s->win = glfwCreateWindow(b->width, b->height, title, NULL, NULL);
    if (!s->win) {
        glfw_close(b);
        return ct_fail(err, CT_ESYS, "glfw: cannot create a %dx%d GL 3.3 core window: %s",
                       b->width, b->height, glfw_msg[0] ? glfw_msg : "unknown error");
    }
    glfwSetWindowUserPointer(s->win, s);
    glfwSetKeyCallback(s->win, on_key);
    glfwSetCursorPosCallback(s->win, on_cursor);
    glfwSetScrollCallback(s->win, on_scroll);
    glfwMakeContextCurrent(s->win);
    glfwSwapInterval(vsync ? 1 : 0);
    x_gone = 0;
    x_told = false;
    x_handlers();
    int rc = gl_load(getproc, "glfw", err);
    if (rc) glfw_close(b);
    return rc;
}

/* gl_backend.h: where the GL 3.3 core context comes from. Three backends
 * behind one interface: a GLFW window (interactive, needs an X or Wayland
 * display), EGL (headless: a GPU's EGL device, else the surfaceless
 * platform; gl_backend_egl.c) and OSMesa (headless, software). Opening a
 * backend makes its context current and fills the gl_load.h table from it. Headless backends have no default
 * framebuffer worth drawing to: the compositor renders into its own FBOs. */
#ifndef CT_GL_BACKEND_H
#define CT_GL_BACKEND_H

#include <stdbool.h>

#include "common/error.h"

typedef enum gl_backend_kind {
    GL_BACKEND_GLFW   = 0,
    GL_BACKEND_EGL    = 1,
    GL_BACKEND_OSMESA = 2
} gl_backend_kind;

/* Keys the display reacts to: printable keys are their upper-case ASCII
 * code, the others follow. */
enum {
    GL_KEY_NONE   = 0,
    GL_KEY_SPACE  = ' ',
    GL_KEY_ESCAPE = 256,
    GL_KEY_UP, GL_KEY_DOWN, GL_KEY_LEFT, GL_KEY_RIGHT,
    GL_KEY_PAGE_UP, GL_KEY_PAGE_DOWN,
    GL_KEY_SHIFT, GL_KEY_F1,
    GL_KEY_COUNT
};

#define GL_INPUT_MAX_PRESSES 32

/* Input gathered by one gl_backend_poll. */
typedef struct gl_input {
    bool down[GL_KEY_COUNT];              /* keys held now */
    int presses[GL_INPUT_MAX_PRESSES];    /* keys pressed since the last poll, in order */
    int npresses;
    double mouse_dx, mouse_dy;            /* cursor motion while a mouse button is held */
    double scroll;                        /* wheel steps since the last poll */
    bool close;                           /* the window was asked to close */
    int fb_width, fb_height;              /* framebuffer size in pixels */
    bool hidden;                          /* window iconified or unmapped: nothing to see */
} gl_input;

/* Key presses between two polls, in order. A poll takes at most
 * GL_INPUT_MAX_PRESSES and leaves the rest for the next: a frame of
 * software GL on a large scene can last seconds, more presses than one
 * gl_input holds (a held + or - repeats), and the surplus was dropped. A
 * press beyond the queue's capacity (seconds of typing in one frame) is
 * dropped and counted. */
#define GL_PRESS_QUEUE_CAP 1024
typedef struct gl_press_queue {
    int keys[GL_PRESS_QUEUE_CAP];
    int head, n;                          /* the oldest press, and how many */
    unsigned long dropped;                /* presses that found it full */
} gl_press_queue;

/* Appends a press; false (and counted) when the queue is full. */
bool gl_press_push(gl_press_queue *q, int key);

/* Moves the oldest presses into in (up to GL_INPUT_MAX_PRESSES). */
void gl_press_take(gl_press_queue *q, gl_input *in);

typedef struct gl_backend gl_backend;

/* Name of a backend kind. */
const char *gl_backend_name(gl_backend_kind kind);

/* glfw when $DISPLAY is set, egl otherwise. */
gl_backend_kind gl_backend_default(void);

/* Creates the context (and window, for glfw, of width x height with the
 * given title; vsync on or off), makes it current and loads GL. */
int gl_backend_open(gl_backend_kind kind, int width, int height, const char *title, bool vsync,
                    gl_backend **out, ct_error *err);

/* Kind of an open backend. */
gl_backend_kind gl_backend_kind_of(const gl_backend *b);

/* True for the window backend (it has a visible default framebuffer). */
bool gl_backend_is_window(const gl_backend *b);

/* Processes window events into *in (keys, mouse, close, size); headless
 * backends report no input and their fixed size. */
void gl_backend_poll(gl_backend *b, gl_input *in);

/* Shows the default framebuffer (window: swap buffers; headless: no-op). */
void gl_backend_present(gl_backend *b);

/* Sets the window title (no-op when headless). */
void gl_backend_set_title(gl_backend *b, const char *title);

/* Destroys the context (and window). NULL is fine. */
void gl_backend_close(gl_backend *b);

#endif

/* gl_backend_impl.h: the table each backend file fills (private to the
 * gl_backend*.c files). */
#ifndef CT_GL_BACKEND_IMPL_H
#define CT_GL_BACKEND_IMPL_H

#include "display/gl_backend.h"

typedef struct gl_backend_ops {
    void (*poll)(gl_backend *b, gl_input *in);
    void (*present)(gl_backend *b);
    void (*set_title)(gl_backend *b, const char *title);
    void (*close)(gl_backend *b);
} gl_backend_ops;

struct gl_backend {
    gl_backend_kind kind;
    const gl_backend_ops *ops;
    int width, height;
    void *state;   /* the backend's own */
};

/* Each backend: creates its context on b (kind, width, height set), fills
 * ops and state, makes the context current and loads GL. */
int gl_backend_open_glfw(gl_backend *b, const char *title, bool vsync, ct_error *err);
int gl_backend_open_egl(gl_backend *b, ct_error *err);
int gl_backend_open_osmesa(gl_backend *b, ct_error *err);

#endif

/* disp_fixture.h: test helpers for the display: a Cornell-like box built in
 * code with smoothly varying per-vertex colours, a software Gouraud
 * rasteriser at pixel centres (the reference for the GL images), and a
 * helper that renders a frame with one backend in a child process (so each
 * backend gets a fresh process, as in the real program). */
#ifndef CT_TESTS_DISP_FIXTURE_H
#define CT_TESTS_DISP_FIXTURE_H

#include <stdbool.h>
#include <stdint.h>
#include <sys/types.h>

#include "common/camera.h"
#include "common/radmesh.h"
#include "display/disp_compositor.h"
#include "display/disp_session.h"
#include "display/gl_backend.h"

/* Node ids of the box. */
typedef struct fx_box_nodes {
    uint32_t root, room, back, floor, ceiling, left, right, light, block;
} fx_box_nodes;

/* The box [-1,1]^3 open towards +z, walls cut into grid x grid quads, a
 * light quad under the ceiling and a block on the floor; per-vertex
 * radiance is a hash of the vertex position (continuous across shared
 * corners, not linear). */
int fx_box_mesh(int grid, ct_radmesh *m, fx_box_nodes *nodes, ct_error *err);

/* The camera looking into the box. */
ct_camera fx_box_camera(void);

/* A software rasterisation at pixel centres (camera.h image convention):
 * per pixel the Gouraud colour, world point and node of the nearest
 * triangle, and whether the pixel is "smooth" (the same node at the centre
 * and at the 8 half-pixel neighbours, so pixel coverage rules cannot change
 * its value). */
typedef struct fx_ref {
    int width, height;
    float *rgb;       /* 3 per pixel, row 0 at the top */
    float *world;     /* 3 per pixel */
    int32_t *node;    /* -1 = background */
    bool *smooth;
} fx_ref;

int fx_rasterise(const ct_radmesh *m, const ct_camera *cam, int width, int height, fx_ref *out);
void fx_ref_free(fx_ref *r);

/* The box of grid 4 (its nodes in *nodes unless NULL) under fx_box_camera
 * (*cam), rasterised at width x height into *ref; 0, or an error (err says
 * which) with nothing to free. */
int fx_box_reference(int width, int height, ct_radmesh *m, fx_box_nodes *nodes, ct_camera *cam, fx_ref *ref,
                     ct_error *err);

/* Called in the child after the backend is open: fills the session. */
typedef int (*fx_setup_fn)(disp_session *s, void *ctx, ct_error *err);

/* A rendered frame. */
typedef struct fx_frame {
    int width, height;
    float *linear;     /* 3 per pixel, top row first */
    uint8_t *display;  /* tone-mapped RGB bytes: the 8-bit target, or the window for glfw */
} fx_frame;

/* Renders one frame with backend kind in a child process. Returns 0, or -1
 * with the child's error in msg. */
int fx_render(gl_backend_kind kind, int width, int height, const ct_camera *cam,
              const disp_render_opts *o, fx_setup_fn setup, void *ctx, fx_frame *out, char *msg,
              size_t msgcap);

/* fx_render drawing `frames` frames of the same camera and returning the
 * last: from the second on, the compositor starts from its kept base. */
int fx_render_frames(gl_backend_kind kind, int width, int height, const ct_camera *cam,
                     const disp_render_opts *o, int frames, fx_setup_fn setup, void *ctx, fx_frame *out,
                     char *msg, size_t msgcap);
/* fx_render_frames with a multisampled float target of `samples` samples a
 * pixel (disp_compositor_new). */
int fx_render_ms(gl_backend_kind kind, int width, int height, const ct_camera *cam, const disp_render_opts *o,
                 int samples, int frames, fx_setup_fn setup, void *ctx, fx_frame *out, char *msg, size_t msgcap);
void fx_frame_free(fx_frame *f);

/* Starts Xvfb on a free display number and points $DISPLAY at it; returns
 * its pid or -1 (msg says why). */
pid_t fx_xvfb_start(char *msg, size_t msgcap);
void fx_xvfb_stop(pid_t pid);

/* Renders session s in this process's current GL context from
 * fx_box_camera(), one pass, full view, into out (width x height display
 * bytes, RGB): how the tests compare a session's state with another's. */
int fx_render_session(disp_session *s, int width, int height, uint8_t *out, ct_error *err);

/* Max and mean absolute difference over n floats. */
void fx_diff(const float *a, const float *b, size_t n, double *max, double *mean);

/* Half-float bits of f: round to nearest, subnormals below 2^-14, infinity above the range. */
uint16_t fx_half(float f);

/* GL's bilinear lookup (clamp to edge) of an RGB float texture at (s, t). */
vec3 fx_bilinear(const float *rgb, int w, int h, float s, float t);

#endif

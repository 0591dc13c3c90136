/* disp_compositor.h: draws one frame. Into a float framebuffer (RGBA32F by
 * default): pass 1 the radiosity mesh (Gouraud), glass see-through over it
 * (a multiplicative blend, then its depth), then per textured node pass
 * 2 adds the positive part of its correction and pass 3 subtracts the
 * negative part with GL_FUNC_REVERSE_SUBTRACT (§4.3; skipped when all
 * corrections are positive), or all of it in one shader pass (--passes 1).
 * A camera drawn again (streamed texels under a still view) starts from a
 * copy of its radiosity and glass kept from its first repeat (the base),
 * so only the corrections are drawn anew; in 1-pass mode in screen space
 * from the surfaces the base keeps per pixel (disp_screen.h; docs/display.md,
 * "Still views").
 * Then exposure and sRGB tone mapping to the window or to an 8-bit target,
 * plus the debug views (radiosity only, corrections only, texture
 * assignment as in the paper's Fig. 5, sample positions as in Fig. 7). */
#ifndef CT_DISP_COMPOSITOR_H
#define CT_DISP_COMPOSITOR_H

#include <stdbool.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "display/disp_scene.h"
#include "display/disp_textures.h"

typedef enum disp_view {
    DISP_VIEW_FULL        = 0,   /* radiosity + corrections */
    DISP_VIEW_RADIOSITY   = 1,   /* the interactive solution alone */
    DISP_VIEW_CORRECTIONS = 2,   /* corrections alone, signed: grey = 0 */
    DISP_VIEW_ASSIGNMENT  = 3,   /* one colour per texture (Fig. 5) */
    DISP_VIEW_SAMPLES     = 4,   /* positions of the last frames' samples (Fig. 7) */
    DISP_VIEW_COUNT       = 5
} disp_view;

/* How a still view's corrections are drawn over its kept base (1-pass
 * mode): in screen space from the surfaces the base keeps (disp_screen.h),
 * over the mesh's triangles, or whichever costs less on a CPU rasteriser
 * (screen space when the textured triangles are at least 1/50 of the
 * pixels the screen pass would draw; docs/display.md, "Still views"). */
typedef enum disp_kept_corr {
    DISP_KEPT_AUTO   = 0,
    DISP_KEPT_SCREEN = 1,
    DISP_KEPT_MESH   = 2
} disp_kept_corr;

/* Name of a view ("full", "radiosity", ...). */
const char *disp_view_name(disp_view v);

/* The samples view: the image is scaled by this (linear), and sample points
 * are drawn in this colour as displayed (linear RGB, before exposure). */
#define DISP_SAMPLE_DIM 0.12f
#define DISP_SAMPLE_COLOR_R 1.0f
#define DISP_SAMPLE_COLOR_G 0.7f
#define DISP_SAMPLE_COLOR_B 0.0f

typedef struct disp_render_opts {
    int passes;           /* 1 or 3 */
    disp_view view;
    float exposure;       /* stops: displayed = linear * 2^exposure */
    bool all_positive;    /* the master says no correction is negative: no pass 3 */
    bool full_redraw;     /* draw the radiosity anew even when the camera did not move */
    disp_kept_corr kept;  /* how the corrections go over a kept base */
} disp_render_opts;

/* What the last render drew. */
typedef struct disp_render_stats {
    uint32_t draws;           /* glDrawElements calls */
    uint32_t textures_drawn;  /* textures with a projection that were applied */
    bool pass3;               /* the subtractive pass ran */
    bool base_reused;         /* radiosity and glass came from the kept base */
    bool screen_pass;         /* the corrections over it were drawn in screen space */
    uint64_t screen_px;       /* pixels that pass drew, all textures together */
} disp_render_stats;

typedef struct disp_compositor disp_compositor;

/* Compiles the programs and creates width x height targets; float_format is
 * GL_RGBA32F or GL_RGBA16F (0: RGBA32F); samples a pixel of the float target
 * (multisampling: 1 for none, at most gl_target_max_samples()), averaged
 * into the image each render leaves. Needs a current context. */
int disp_compositor_new(int width, int height, unsigned float_format, int samples, disp_compositor **out,
                        ct_error *err);

/* Deletes programs and targets. NULL is fine. */
void disp_compositor_free(disp_compositor *c);

/* Uploads the sample hit points the samples view draws (world positions, 3
 * floats each, in two runs a[3 * na] and b[3 * nb]; either may be empty). */
int disp_compositor_set_points(disp_compositor *c, const float *a, uint32_t na, const float *b,
                               uint32_t nb, ct_error *err);

/* Renders the linear image of scene s with textures t (may be NULL) seen by
 * cam into the float target (in the samples view: dimmed, with the uploaded
 * sample points drawn over it). */
int disp_compositor_render(disp_compositor *c, const disp_scene *s, const disp_textures *t,
                           const ct_camera *cam, const disp_render_opts *o,
                           disp_render_stats *stats, ct_error *err);

/* Tone-maps the float target into the window's default framebuffer of size
 * win_w x win_h (to_window) or into the 8-bit target. */
int disp_compositor_present(disp_compositor *c, const disp_render_opts *o, bool to_window, int win_w,
                            int win_h, ct_error *err);

/* The float image as linear RGB, row 0 at the top (3 * width * height floats). */
void disp_compositor_read_linear(disp_compositor *c, float *rgb);

/* The 8-bit presented image as RGB, row 0 at the top (3 * width * height). */
void disp_compositor_read_display(disp_compositor *c, uint8_t *rgb);

/* The window's back buffer (win_w x win_h) as RGB, row 0 at the top. */
void disp_compositor_read_window(int win_w, int win_h, uint8_t *rgb);

/* Near and far planes that bound the scene seen from cam (also what the
 * render uses); the near plane follows the current context's depth
 * convention (gl_load.h: far nearer with reversed float depth). */
void disp_compositor_depth_range(const disp_scene *s, const ct_camera *cam, float *znear,
                                 float *zfar);

#endif

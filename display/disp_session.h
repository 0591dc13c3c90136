/* disp_session.h: the display's state as the master describes it, changed
 * only through events: a scene (the radiosity mesh), texture allocation,
 * projection, patch and free, sample positions, frame ends and statistics.
 * The socket client decodes protocol messages into these calls; the
 * standalone viewer (--mesh) and the tests call them directly. Keeps the
 * counters the window title and frames.csv report. Needs a current GL
 * context for every call that touches textures or the mesh. */
#ifndef CT_DISP_SESSION_H
#define CT_DISP_SESSION_H

#include <stdbool.h>
#include <stdint.h>

#include "common/error.h"
#include "common/radmesh.h"
#include "display/disp_scene.h"
#include "display/disp_textures.h"

/* Frames of sample positions (and patch centres) kept for the samples view
 * (Fig. 7). */
#define DISP_SAMPLE_FRAMES 4
/* At most this many sample positions are kept. */
#define DISP_SAMPLE_MAX 1000000u

/* Running totals since the session started. */
typedef struct disp_counters {
    uint64_t samples;       /* samples the master inserted (from stats / positions) */
    uint64_t frame_samples; /* sum of the FRAMEs' sample counts: exact per lockstep frame,
                               where the periodic STATS total lags behind the frames */
    uint64_t texels;        /* texels received in patches */
    uint64_t patches;
    uint64_t bytes;         /* bytes received from the master */
    uint32_t frames;        /* frame-end events */
    uint32_t last_frame;    /* number of the last frame-end event */
} disp_counters;

typedef struct disp_session disp_session;

/* An empty session (no scene yet). */
int disp_session_new(disp_session **out, ct_error *err);

/* Frees the GL objects and the session. NULL is fine. */
void disp_session_free(disp_session *s);

/* SCENE: replaces the mesh (uploading it) and drops all textures. */
int disp_session_scene(disp_session *s, const ct_radmesh *m, ct_error *err);

/* TEX_ALLOC: texture id of width x height for node's subtree (zeroed),
 * projected the given way. It is drawn once its projection arrives. */
int disp_session_tex_alloc(disp_session *s, uint32_t id, uint32_t node, int width, int height,
                           disp_proj_kind kind, ct_error *err);

/* TEX_PROJECTION: world -> texture matrix of texture id. */
int disp_session_tex_projection(disp_session *s, uint32_t id, const mat4 *world_to_tex,
                                ct_error *err);

/* TEX_PATCH: rectangle (x, y, w, h) of texture id, half-float RGB texels. */
int disp_session_tex_patch(disp_session *s, uint32_t id, int x, int y, int w, int h,
                           const uint16_t *rgb, ct_error *err);

/* The same with float texels (tests, synthetic contents). */
int disp_session_tex_patch_float(disp_session *s, uint32_t id, int x, int y, int w, int h,
                                 const float *rgb, ct_error *err);

/* TEX_FREE. */
int disp_session_tex_free(disp_session *s, uint32_t id, ct_error *err);

/* Image positions (pixels, y down; 2 floats each) of n samples of the
 * current frame, for the samples view (they do not change the counters). */
void disp_session_samples(disp_session *s, const float *xy, uint32_t n);

/* FRAME: the master finished frame `frame` (all its patches were sent),
 * with `samples` samples in it; all_positive: no correction is negative
 * (then pass 3 is skipped). */
void disp_session_frame_end(disp_session *s, uint32_t frame, uint32_t samples, bool all_positive);

/* STATS: the master's sample total and the all-positive flag. Once stats
 * arrive, their total is the sample counter. */
void disp_session_stats(disp_session *s, uint64_t samples_total, bool all_positive);

/* Adds n received bytes to the counters. */
void disp_session_add_bytes(disp_session *s, uint64_t n);

/* The mesh (NULL before the first scene) and the textures. */
const disp_scene *disp_session_scene_of(const disp_session *s);
const disp_textures *disp_session_textures(const disp_session *s);

/* Whether the master declared all corrections positive. */
bool disp_session_all_positive(const disp_session *s);

/* Sample positions of the last DISP_SAMPLE_FRAMES frames (2 floats each). */
const float *disp_session_sample_xy(const disp_session *s, uint32_t *n);

/* World points (3 floats each) at the centres of the texel patches of the
 * last DISP_SAMPLE_FRAMES frames: where corrections changed. The samples
 * view shows them when no sample positions arrive (protocol version 1
 * carries none). */
const float *disp_session_patch_points(const disp_session *s, uint32_t *n);

/* Running totals. */
disp_counters disp_session_counters(const disp_session *s);

#endif

/* disp_session.h: the display's state as the master describes it, changed
 * only through events: a scene (the radiosity mesh), texture allocation,
 * projection, patch and free, sample points (kept in a bounded ring buffer
 * for the last frames), frame ends and statistics.
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

/* Frames whose sample points the samples view (Fig. 7) shows, by default
 * (--sample-frames). */
#define DISP_SAMPLE_FRAMES 8
/* At most this many sample points are kept, by default (--sample-max). */
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
    uint64_t sample_points; /* sample hit points received (SAMPLES) */
    uint64_t points_dropped; /* points the master could not send (its latest count) */
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

/* The same from the bound pixel unpack buffer at byte offset off (the
 * inbox's uploads, disp_inbox.h). */
int disp_session_tex_upload(disp_session *s, uint32_t id, int x, int y, int w, int h, size_t off, bool negative,
                            bool nonzero, ct_error *err);

/* The same with float texels (tests, synthetic contents). */
int disp_session_tex_patch_float(disp_session *s, uint32_t id, int x, int y, int w, int h,
                                 const float *rgb, ct_error *err);

/* TEX_FREE. */
int disp_session_tex_free(disp_session *s, uint32_t id, ct_error *err);

/* Keeps the sample points of the last `frames` drawn frames (at least 1),
 * at most max_points of them (the oldest go first). */
void disp_session_set_sample_limits(disp_session *s, uint32_t frames, uint32_t max_points);

/* SAMPLES: n world hit points (3 floats each) of samples the master
 * inserted; dropped is the master's count of points it did not send. */
void disp_session_sample_points(disp_session *s, const float *xyz, uint32_t n, uint64_t dropped);

/* The display drew a frame: points that arrived before the last `frames`
 * frames are forgotten. */
void disp_session_frame_drawn(disp_session *s);

/* The kept points, oldest first, in at most two runs of a ring buffer:
 * a[3 * na] then b[3 * nb]. Returns a version that changes whenever they do
 * (so a caller uploads them only then). */
uint64_t disp_session_points(const disp_session *s, const float **a, uint32_t *na, const float **b,
                             uint32_t *nb);

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

/* Running totals. */
disp_counters disp_session_counters(const disp_session *s);

/* A number that changes whenever what a frame of this session shows may
 * change (scene, textures, their texels, sample points): the run loop
 * redraws a still camera only when it moved. */
uint64_t disp_session_image_gen(const disp_session *s);

#endif

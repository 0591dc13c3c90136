/* disp_app_internal.h: the display program's state, shared by disp_app.c
 * (options, the frame loop, drawing and capture) and disp_app_conn.c (the
 * master connection: connecting, reconnecting, taking what arrived,
 * lockstep, the lag of what was shown). Internal to those two files;
 * prefix app_. */
#ifndef CT_DISP_APP_INTERNAL_H
#define CT_DISP_APP_INTERNAL_H

#include "common/campath.h"
#include "common/radmesh.h"
#include "display/disp_app.h"
#include "display/disp_camera_control.h"
#include "display/disp_capture.h"
#include "display/disp_client.h"
#include "display/disp_inbox.h"
#include "display/disp_gpu_time.h"
#include "display/disp_lag.h"
#include "display/disp_session.h"

typedef struct app {
    const disp_app_opts *o;
    gl_backend *backend;
    disp_session *session;
    disp_compositor *comp;
    disp_capture *capture;
    ct_radmesh mesh;          /* kept for synthetic textures */
    bool have_mesh;
    ct_campath path;
    bool have_path;
    disp_fly fly;
    bool have_cam;            /* fly.cam was set from the options or the scene */
    bool frame_taken;         /* lockstep: a frame was drawn, the next one is not asked for yet */
    disp_render_opts ropts;
    /* the master connection */
    disp_client *client;
    disp_inbox *inbox;            /* what its thread received, applied before each frame */
    disp_inbox_took took;         /* what the frame being drawn took from it */
    disp_lag *lag;                /* insertion at the master -> presented frame */
    disp_gpu_time *gt;            /* GPU time of taking in texels, drawing, presenting */
    double t_take, t_wait, t_capture; /* seconds taking the inbox, waiting for lockstep frames, capturing */
    uint64_t uploads, uploaded;   /* texture upload calls and the texels they carried, all takes */
    double t_idle;                /* seconds with nothing new to draw (no frame drawn) */
    double t_held;                /* seconds new texels waited for --texel-fps / --texel-cpu */
    uint64_t kept_frames;         /* frames that reused a kept base */
    uint64_t screen_frames, screen_px;   /* frames with the corrections in screen space, the pixels they drew */
    bool hold_texels;             /* the inbox is not taken: texel redraws are held back */
    disp_scene_cache *cache;
    double retry_at, backoff;     /* next reconnection attempt, its delay */
    bool cam_sent;                /* last_cam went to this connection */
    bool ever_connected;
    ct_error last_cause;          /* why the last connection attempt failed or ended */
    ct_camera last_cam;
    /* title statistics */
    double stat_t0;
    uint32_t stat_frames;
    disp_counters stat_c0;
    /* The title's samples/s, measured between changes of the count (STATS
     * every --stats-s: over the title's 0.5 s it read 0 and 2x in turn). */
    double t_run0;            /* when run() began: the time of C's keyframe lines */
    uint64_t sps_samples;
    double sps_t, sps_shown;
    char status[160];
    uint64_t points_version;      /* of the sample points last uploaded */
    bool points_uploaded;
} app;

/* What the connection says about the frame about to be drawn. */
enum { STEP_DRAW = 0, STEP_END = 1, STEP_WAIT = 2, STEP_QUIT = 3, STEP_LOST = 4, STEP_ERROR = 5 };

/* disp_app_window.c: the window title (statistics and status), at most
 * twice a second unless forced; the keys (false: the user asked to quit). */
void app_set_title(app *a, double now, bool force);
bool app_handle_keys(app *a, const gl_input *in);

/* disp_app_conn.c: connects to a->o->connect (3 s at most). */
int app_try_connect(app *a, ct_error *err);

/* The connection failed or was lost: with --reconnect a retry is scheduled
 * and the last image stays; else DISP_EXIT_LOST with err filled. */
int app_connection_lost(app *a, ct_error *cause, double now, ct_error *err);

/* Before a frame's camera is known: checks the connection and takes what
 * arrived (STEP_DRAW, STEP_END, STEP_LOST or STEP_ERROR). */
int app_connection_begin(app *a, ct_error *err);

/* With the frame's camera (cam; NULL: none yet) and in lockstep the next
 * one's: sends it when it changed, waits for the scene (STEP_WAIT) and in
 * lockstep for the frame's texels. */
int app_connection_step(app *a, const ct_camera *cam, const ct_camera *next, gl_input *in, double t_start,
                        ct_error *err);

/* After a frame is presented: the lag of every sample its patches carried. */
void app_count_lag(app *a);
int app_take_inbox(app *a, ct_error *err);

#endif

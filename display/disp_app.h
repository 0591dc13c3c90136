/* disp_app.h: the display program's run loop behind bin/corrtex-display:
 * opens a backend, gets the interactive solution (from a .ctmesh file, a
 * scene file with a stand-in radiosity, or a master over a socket), moves
 * the camera (fly control in the window, or a scripted path), renders with
 * the compositor, shows statistics in the title, and captures frames. */
#ifndef CT_DISP_APP_H
#define CT_DISP_APP_H

#include <stdbool.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "display/disp_compositor.h"
#include "display/gl_backend.h"

/* Exit statuses of the program. */
enum {
    DISP_EXIT_OK    = 0,
    DISP_EXIT_ERROR = 1,   /* a runtime failure (GL, files) */
    DISP_EXIT_USAGE = 2,   /* bad options or input files */
    DISP_EXIT_LOST  = 3    /* the master connection was lost and --reconnect is off */
};

/* --gpu-times: auto = on hardware GL, not on a software rasteriser. */
enum { DISP_GPU_TIMES_AUTO, DISP_GPU_TIMES_ON, DISP_GPU_TIMES_OFF };

typedef struct disp_app_opts {
    gl_backend_kind backend;
    int width, height;
    float exposure;
    int passes;
    disp_view view;
    bool vsync;
    unsigned float_format;        /* GL_RGBA32F or GL_RGBA16F */
    int msaa;                     /* samples a pixel; 0: 4 on a GPU, 1 on a software rasteriser */
    const char *mesh;             /* --mesh FILE.ctmesh */
    const char *scene;            /* --scene FILE.json (stand-in radiosity) */
    float ambient;                /* stand-in radiosity's ambient term */
    const char *camera_name;      /* a named camera of the scene file */
    bool has_camera;
    ct_camera camera;             /* --camera */
    const char *path;             /* --path FILE */
    int frames;                   /* --frames N; 0: real time (path) or until closed */
    int samples_per_frame;        /* lockstep frames from the master */
    const char *out_dir;
    const char *ref_dir;          /* --reference: a folder of per-frame references or one image */
    double out_every;             /* capture a frame at most every this many seconds (0: every frame) */
    bool no_images;               /* frames.csv only */
    double hold_seconds;          /* real-time path: keep its last camera this long after it ends */
    uint32_t synthetic;           /* synthetic correction textures (no master) */
    bool synthetic_positive;
    bool synthetic_tiles;         /* cut parts into tiles to reach the count */
    const char *connect;          /* unix:PATH or tcp:HOST:PORT */
    const char *token_file;
    const char *cache_dir;        /* scene cache directory (NULL: memory only) */
    uint32_t cache_max_mb;        /* payloads kept there, at most (0: no bound) */
    bool reconnect;
    double max_seconds;           /* stop after this long (0: no limit) */
    bool continuous;              /* draw every frame, also when nothing changed (timings) */
    double texel_fps;             /* new texels alone redraw a view at most this often (0: no limit) */
    double texel_cpu;             /* and use at most this many cores doing so (0: no limit) */
    bool full_redraw;             /* no kept base: a still camera's radiosity drawn every frame */
    int kept_corrections;         /* disp_kept_corr: how the corrections go over a kept base */
    int gpu_times;                /* DISP_GPU_TIMES_*: time the stages with GL timer queries */
    uint32_t sample_frames;       /* the samples view shows the points of this many frames */
    uint32_t sample_max;          /* and keeps at most this many points */
    volatile int *stop;           /* set (by a signal handler) to end the run in order; NULL: none */
} disp_app_opts;

/* The defaults --help prints. */
void disp_app_defaults(disp_app_opts *o);

/* Runs the display; returns a DISP_EXIT_* status, err filled when not 0. */
int disp_app_run(const disp_app_opts *o, ct_error *err);

/* The key help text (also printed by --help). */
const char *disp_app_keys_help(void);

#endif

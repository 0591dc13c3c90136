/* bin/corrtex-display: the display client. Parses options and runs
 * display/disp_app.c; links common, proto, display and GL only. */
#include <errno.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "common/fsutil.h"
#include "common/log.h"
#include "common/optab.h"
#include "common/version.h"
#include "display/disp_app.h"
#include "display/disp_capture.h"
#include "display/gl_load.h"
#include "proto/wire.h"
#include "proto/xport.h"

#define COMP "corrtex-display"

static volatile int g_stop;

/* SIGINT and SIGTERM end the run in order: the frames written so far and
 * frames.csv are completed, the master gets BYE. */
static void on_signal(int sig)
{
    g_stop = sig;
}

/* The command line: the run's options, and the choices and switches that
 * map onto them once parsed. */
typedef struct cli {
    disp_app_opts o;
    int backend;                  /* -1 until given: disp_app_defaults' choice, which depends on $DISPLAY */
    int passes, view, fbo;
    const char *camera;           /* --camera EX,EY,EZ,TX,TY,TZ[,FOV] */
    bool no_cache, no_vsync, quiet, verbose, version;
} cli;

#define OF(f) offsetof(cli, f)
static const int BACKENDS[] = {GL_BACKEND_GLFW, GL_BACKEND_EGL, GL_BACKEND_OSMESA};
static const int PASSES[] = {1, 3};
static const int FBOS[] = {GL_RGBA32F, GL_RGBA16F};
static const int VIEWS[] = {DISP_VIEW_FULL, DISP_VIEW_RADIOSITY, DISP_VIEW_CORRECTIONS, DISP_VIEW_ASSIGNMENT,
                            DISP_VIEW_SAMPLES};

/* No row has a default of its own: disp_app_defaults' are the only ones
 * (--help shows them from the defaults struct). */
static const optab INPUT_OPTS[] = {
    {"connect", 0, OPTAB_STRING, OF(o.connect), 0, 0, NULL, "ADDR",
     "master's display socket: unix:PATH or tcp:HOST:PORT", NULL},
    {"token-file", 0, OPTAB_STRING, OF(o.token_file), 0, 0, NULL, "FILE",
     "shared token for the handshake (else $CORRTEX_TOKEN)", NULL},
    {"reconnect", 0, OPTAB_FLAG, OF(o.reconnect), 0, 0, NULL, NULL,
     "on a lost connection retry with back-off (else exit 3)", NULL},
    {"cache", 0, OPTAB_STRING, OF(o.cache_dir), 0, 0, NULL, "DIR",
     "keep received scenes in DIR by content hash ($XDG_CACHE_HOME/corrtex, else ~/.cache/corrtex)", NULL},
    {"cache-max-mb", 0, OPTAB_U32, OF(o.cache_max_mb), 0, 1 << 24, NULL, "N",
     "MiB of scenes kept there at most, least recently used removed first (0: no bound)", NULL},
    {"no-cache", 0, OPTAB_FLAG, OF(no_cache), 0, 0, NULL, NULL, "keep the scene in memory only", NULL},
    /* the protocol's bound: above it the display used to start GL, connect,
     * and only then fail to encode its SETTINGS (exit 3, not 2) */
    {"samples-per-frame", 0, OPTAB_INT, OF(o.samples_per_frame), 0, WIRE_SPF_MAX, NULL, "K",
     "lockstep: the master inserts K samples per frame (0: free running)", NULL},
    {"mesh", 0, OPTAB_STRING, OF(o.mesh), 0, 0, NULL, "FILE.ctmesh",
     "a radiosity mesh cache (corrtex radiosity), no master", NULL},
    {"scene", 0, OPTAB_STRING, OF(o.scene), 0, 0, NULL, "FILE.json",
     "a scene with a stand-in radiosity (constant per material), no master", NULL},
    {"ambient", 0, OPTAB_FLOAT, OF(o.ambient), 0, 100, NULL, "A",
     "stand-in radiosity: emission + diffuse * A; only with --scene", NULL},
    {"synthetic", 0, OPTAB_U32, OF(o.synthetic), 0, 100000, NULL, "N",
     "up to N synthetic correction textures, one per visible part (benchmarks without a master; not with "
     "--connect)", NULL},
    {"synthetic-tiles", 0, OPTAB_FLAG, OF(o.synthetic_tiles), 0, 0, NULL, NULL,
     "cut parts into tiles to make all N (textures stack on parts); only with --synthetic N", NULL},
    {"synthetic-positive", 0, OPTAB_FLAG, OF(o.synthetic_positive), 0, 0, NULL, NULL,
     "make them all positive; only with --synthetic N", NULL},
};

static const optab VIEW_OPTS[] = {
    {"backend", 0, OPTAB_CHOICE, OF(backend), 0, 0, NULL, "glfw|egl|osmesa",
     "a window, or headless (default: glfw when $DISPLAY is set, else egl: a GPU's EGL device, else the "
     "surfaceless platform; $CORRTEX_EGL_DEVICE=N takes device N)", BACKENDS},
    {"width", 0, OPTAB_INT, OF(o.width), 1, 16384, NULL, "W", "image width", NULL},
    {"height", 0, OPTAB_INT, OF(o.height), 1, 16384, NULL, "H", "image height", NULL},
    {"exposure", 0, OPTAB_FLOAT, OF(o.exposure), -30, 30, NULL, "STOPS", "displayed = linear * 2^STOPS", NULL},
    {"passes", 0, OPTAB_CHOICE, OF(passes), 0, 0, NULL, "1|3", "corrections in one shader pass or three passes",
     PASSES},
    {"view", 0, OPTAB_CHOICE, OF(view), 0, 0, NULL, "full|radiosity|corrections|assignment|samples",
     "what is drawn (docs/display.md, \"Debug views\")", VIEWS},
    {"sample-frames", 0, OPTAB_U32, OF(o.sample_frames), 1, 100000, NULL, "N",
     "samples view: show the sample points of the last N frames", NULL},
    {"sample-max", 0, OPTAB_U32, OF(o.sample_max), 1, 100000000, NULL, "N", "samples view: keep at most N points",
     NULL},
    {"msaa", 0, OPTAB_INT, OF(o.msaa), 0, 64, NULL, "N",
     "samples a pixel (antialiasing; 1: none; default 0: 4 on a GPU, 1 on a software rasteriser, whose CPU the "
     "tracers on the same host would use)", NULL},
    {"fbo", 0, OPTAB_CHOICE, OF(fbo), 0, 0, NULL, "32f|16f", "float framebuffer format", FBOS},
    {"no-vsync", 0, OPTAB_FLAG, OF(no_vsync), 0, 0, NULL, NULL, "window: do not wait for vertical sync", NULL},
    {"camera", 0, OPTAB_STRING, OF(camera), 0, 0, NULL, "EX,EY,EZ,TX,TY,TZ[,FOV]",
     "start camera: eye, target, vertical field of view in degrees (default 50)", NULL},
    {"camera-name", 0, OPTAB_STRING, OF(o.camera_name), 0, 0, NULL, "NAME",
     "a named camera of --scene (default: its first one); only with --scene", NULL},
};

static const optab RUN_OPTS[] = {
    {"path", 0, OPTAB_STRING, OF(o.path), 0, 0, NULL, "FILE|NAME",
     "camera path: a path file (docs/scene-format.md), or with --scene the name of one of its paths", NULL},
    {"frames", 0, OPTAB_INT, OF(o.frames), 0, 10000000, NULL, "N",
     "N frames spread over the path (0: real time); headless without a path, N frames of the still camera (0: one, "
     "or with --connect until the master ends or a signal)", NULL},
    {"seconds", 0, OPTAB_DOUBLE, OF(o.max_seconds), 0, 1e7, NULL, "S", "stop after S seconds (0: no limit)", NULL},
    {"out", 0, OPTAB_STRING, OF(o.out_dir), 0, 0, NULL, "DIR", "write frame_NNNNN.exr/.png and frames.csv", NULL},
    {"out-every", 0, OPTAB_DOUBLE, OF(o.out_every), 0, 1e6, NULL, "S",
     "capture a frame at most every S seconds (0: every frame)", NULL},
    {"no-images", 0, OPTAB_FLAG, OF(o.no_images), 0, 0, NULL, NULL, "with --out: frames.csv only", NULL},
    {"reference", 0, OPTAB_STRING, OF(o.ref_dir), 0, 0, NULL, "DIR|FILE",
     "add RMSE/PSNR against DIR/frame_NNNNN.exr (with --frames N: exactly N of them), or against FILE.exr for "
     "every frame (a still view), to frames.csv", NULL},
    {"hold", 0, OPTAB_DOUBLE, OF(o.hold_seconds), 0, 1e6, NULL, "S",
     "real-time path: stay at its last camera S seconds after it ends; only with --path, not with --frames N",
     NULL},
    {"continuous", 0, OPTAB_FLAG, OF(o.continuous), 0, 0, NULL, NULL,
     "draw every frame, also when nothing changed (frame-rate measurements; else a still, unchanged view is not "
     "redrawn)", NULL},
    {"full-redraw", 0, OPTAB_FLAG, OF(o.full_redraw), 0, 0, NULL, NULL,
     "draw a still camera's radiosity every frame (else it is kept from the second frame on and only the "
     "corrections are redrawn)", NULL},
    {"kept-corrections", 0, OPTAB_CHOICE, OF(o.kept_corrections), 0, 0, NULL, "auto|screen|mesh",
     "a still view's corrections over its kept base (1-pass, one sample a pixel): in screen space from the "
     "surfaces the base keeps, over the mesh's triangles, or whichever costs less (docs/display.md)", NULL},
    {"gpu-times", 0, OPTAB_CHOICE, OF(o.gpu_times), 0, 0, NULL, "auto|on|off",
     "time taking in texels, drawing and presenting on the GPU (GL timer queries) and print it per frame at the "
     "end; auto: on hardware GL, not on a software rasteriser, whose queries cost frames (docs/display.md)", NULL},
    {"texel-fps", 0, OPTAB_DOUBLE, OF(o.texel_fps), 0, 1000, NULL, "F",
     "redraw a view for new texels alone at most F times a second; a moving camera is drawn at once (0: whenever "
     "they arrive). On a host shared with tracer ranks, what the display does not draw the tracers trace "
     "(docs/display.md)", NULL},
    {"texel-cpu", 0, OPTAB_DOUBLE, OF(o.texel_cpu), 0, 1000, NULL, "C",
     "and spend at most C cores on such redraws, taking in texels, drawing and tone mapping included (0: no "
     "limit): software GL at 1024x1024 is held to a few redraws a second, a GPU is not", NULL},
};

static const optab LOG_OPTS[] = {
    {"quiet", 'q', OPTAB_FLAG, OF(quiet), 0, 0, NULL, NULL, "warnings and errors only", NULL},
    {"verbose", 0, OPTAB_FLAG, OF(verbose), 0, 0, NULL, NULL, "debug lines too", NULL},
    {"version", 0, OPTAB_FLAG, OF(version), 0, 0, NULL, NULL, "print the version and the git commit, and exit",
     NULL},
};
#undef OF

enum { NGROUPS = 5 };
static const char *const GROUP_TITLES[NGROUPS] = {"input", "view", "walkthroughs and output", "log", NULL};

static void groups(cli *c, optab_group *g)
{
    g[0] = (optab_group){INPUT_OPTS, OPTAB_COUNT(INPUT_OPTS), c};
    g[1] = (optab_group){VIEW_OPTS, OPTAB_COUNT(VIEW_OPTS), c};
    g[2] = (optab_group){RUN_OPTS, OPTAB_COUNT(RUN_OPTS), c};
    g[3] = (optab_group){LOG_OPTS, OPTAB_COUNT(LOG_OPTS), c};
    g[4] = (optab_group){NULL, 0, NULL};
}

/* Every option's default: disp_app_defaults', and the scene cache in the
 * user's cache folder (fs_user_cache_dir, in cache; made when a scene is
 * kept). */
static void defaults(cli *c, char *cache, size_t cache_size)
{
    memset(c, 0, sizeof *c);
    disp_app_defaults(&c->o);
    c->backend = -1;
    c->passes = c->o.passes;
    c->view = (int)c->o.view;
    c->fbo = (int)c->o.float_format;
    ct_error e;
    if (fs_user_cache_dir(cache, cache_size, 0, &e) == CT_OK) c->o.cache_dir = cache;
    else cache[0] = '\0';
}

static void usage(FILE *f)
{
    cli d;
    char cache[2048];
    defaults(&d, cache, sizeof cache);
    fprintf(f, "usage: corrtex-display [options]\n"
               "Shows the interactive solution corrected by corrective textures, from a master\n"
               "(--connect) or alone (--mesh / --scene), in a window or headless.\n");
    optab_group g[NGROUPS];
    groups(&d, g);
    for (int k = 0; g[k].rows; k++) {
        fprintf(f, "\n%s:\n", GROUP_TITLES[k]);
        optab_usage(g[k].rows, g[k].n, g[k].base, f);
    }
    fprintf(f, "  --help                       this text\n\n%s", disp_app_keys_help());
}

static int parse_camera(const char *s, ct_camera *cam)
{
    float v[7] = {0, 0, 0, 0, 0, 0, 50.0f};
    int n = 0;
    const char *p = s;
    while (n < 7) {
        char *end;
        v[n] = strtof(p, &end);
        if (end == p) break;
        n++;
        if (*end == '\0') {
            p = end;
            break;
        }
        if (*end != ',') break;
        p = end + 1;
    }
    if ((n != 6 && n != 7) || *p != '\0') {
        /* corrtex reference takes a camera's name here: say where names go */
        ct_log(CT_LOG_ERROR, COMP,
               "--camera: '%s' is not EX,EY,EZ,TX,TY,TZ[,FOV] (a scene camera by name: --camera-name with --scene; "
               "connected to a master the display starts at the scene's first camera)",
               s);
        return -1;
    }
    /* The range of scene cameras and paths (it was (1, 179) here alone). */
    if (!cam_fov_deg_valid(v[6])) {
        ct_log(CT_LOG_ERROR, COMP, "--camera: '%s': the field of view %g is outside [%g, %g] degrees", s,
               (double)v[6], (double)CT_FOV_DEG_MIN, (double)CT_FOV_DEG_MAX);
        return -1;
    }
    vec3 eye = v3(v[0], v[1], v[2]), target = v3(v[3], v[4], v[5]);
    if (!v3_in_range(eye) || !v3_in_range(target)) {
        ct_log(CT_LOG_ERROR, COMP, "--camera: '%s': eye and target must be finite and within +-%g", s,
               (double)CT_COORD_MAX);
        return -1;
    }
    if (v3_len(v3_sub(target, eye)) <= 0) {
        ct_log(CT_LOG_ERROR, COMP, "--camera: eye and target coincide");
        return -1;
    }
    *cam = cam_look_at(eye, target, v3(0, 1, 0), v[6]);
    return 0;
}

int main(int argc, char **argv)
{
    cli c;
    char cache[2048];
    defaults(&c, cache, sizeof cache);
    optab_group g[NGROUPS];
    groups(&c, g);
    const char *pos[1];
    int npos = 0;
    ct_error err;
    ct_error_clear(&err);
    int rc = optab_parse(g, NGROUPS - 1, argc, argv, pos, 0, &npos, &err);
    if (rc == 1) {
        usage(stdout);
        return 0;
    }
    if (rc) {
        ct_log(CT_LOG_ERROR, COMP, "%s", err.msg);
        return DISP_EXIT_USAGE;
    }
    if (c.version) {
        ct_version_print(COMP, stdout);
        return DISP_EXIT_OK;
    }
    if (c.quiet) ct_log_set_level(CT_LOG_WARN);
    if (c.verbose) ct_log_set_level(CT_LOG_DEBUG);
    /* (also at their default values: refused below with a source that does
     * not use them) */
    bool ambient_given = optab_given(g, NGROUPS - 1, argc, argv, "ambient"),
         hold_given = optab_given(g, NGROUPS - 1, argc, argv, "hold");
    disp_app_opts o = c.o;
    if (c.backend >= 0) o.backend = (gl_backend_kind)c.backend;
    o.passes = c.passes;
    o.view = (disp_view)c.view;
    o.float_format = (unsigned)c.fbo;
    o.vsync = !c.no_vsync;
    if (c.no_cache) o.cache_dir = NULL;
    if (c.camera) {
        if (parse_camera(c.camera, &o.camera)) return DISP_EXIT_USAGE;
        o.has_camera = true;
    }
    int sources = (o.mesh != NULL) + (o.scene != NULL) + (o.connect != NULL);
    if (sources != 1) {
        ct_log(CT_LOG_ERROR, COMP, "give exactly one of --connect, --mesh or --scene (see --help)");
        return DISP_EXIT_USAGE;
    }
    /* Only a scene file names cameras: a .ctmesh and the scene a master
     * sends carry none, and the option used to be dropped without a word. */
    if (o.camera_name && !o.scene) {
        ct_log(CT_LOG_ERROR, COMP, "--camera-name needs --scene: %s names no cameras (give --camera EX,EY,EZ,TX,TY,TZ)",
               o.mesh ? "a .ctmesh" : "the scene a master sends");
        return DISP_EXIT_USAGE;
    }
    /* The same for the options of a connection: dropped without a word,
     * a --token-file meant for a master looked taken. */
    if (!o.connect) {
        disp_app_opts d;
        disp_app_defaults(&d);
        const char *only = o.token_file ? "--token-file"
                           : o.reconnect ? "--reconnect"
                           : o.samples_per_frame ? "--samples-per-frame"
                           : c.no_cache ? "--no-cache"
                           : c.o.cache_dir != (cache[0] ? cache : d.cache_dir) ? "--cache"
                           : o.cache_max_mb != d.cache_max_mb ? "--cache-max-mb"
                           : NULL;
        if (only) {
            ct_log(CT_LOG_ERROR, COMP, "%s needs --connect: %s has no master", only, o.mesh ? "--mesh" : "--scene");
            return DISP_EXIT_USAGE;
        }
    }
    /* Options that shape what another option makes, given without it: each
     * was dropped without a word. */
    if (ambient_given && !o.scene) {
        ct_log(CT_LOG_ERROR, COMP, "--ambient is the stand-in radiosity of --scene: not with %s",
               o.mesh ? "--mesh (a .ctmesh has its radiosity)" : "--connect (the master sends its radiosity)");
        return DISP_EXIT_USAGE;
    }
    if ((o.synthetic_tiles || o.synthetic_positive) && !o.synthetic) {
        ct_log(CT_LOG_ERROR, COMP, "%s needs --synthetic N (N > 0): it shapes the synthetic textures",
               o.synthetic_tiles ? "--synthetic-tiles" : "--synthetic-positive");
        return DISP_EXIT_USAGE;
    }
    if (hold_given && !o.path) {
        ct_log(CT_LOG_ERROR, COMP, "--hold needs --path: it keeps a real-time path's last camera");
        return DISP_EXIT_USAGE;
    }
    /* --frames N steps the path and ends at its last frame: no real time
     * to stay in, and --hold was dropped without a word. */
    if (hold_given && o.frames > 0) {
        ct_log(CT_LOG_ERROR, COMP, "--hold needs --path in real time, not --frames %d: it keeps a real-time path's "
               "last camera", o.frames);
        return DISP_EXIT_USAGE;
    }
    /* A master sends its own corrective textures: the synthetic ones were
     * made only over a --mesh or --scene, and dropped without a word. */
    if (o.synthetic && o.connect) {
        ct_log(CT_LOG_ERROR, COMP,
               "--synthetic %u makes corrective textures without a master: not with --connect (the master sends "
               "its own)", (unsigned)o.synthetic);
        return DISP_EXIT_USAGE;
    }
    if ((o.ref_dir || o.no_images || o.out_every > 0) && !o.out_dir) {
        ct_log(CT_LOG_ERROR, COMP, "--reference, --no-images and --out-every need --out");
        return DISP_EXIT_USAGE;
    }
    /* Bad input found now is bad input (exit 2, before a GL context and
     * the first frame): a --connect address no transport takes used to be a
     * lost connection (3), a missing --reference or an --out that is a file
     * a failure (1) after the first frame. */
    xport_addr xa;
    if (o.connect && xport_parse(o.connect, false, &xa, &err) != CT_OK) {
        ct_log(CT_LOG_ERROR, COMP, "--connect %s", err.msg);
        return DISP_EXIT_USAGE;
    }
    struct stat st;
    if (o.ref_dir && stat(o.ref_dir, &st) != 0) {
        ct_log(CT_LOG_ERROR, COMP, "--reference %s: %s", o.ref_dir, strerror(errno));
        return DISP_EXIT_USAGE;
    }
    if (o.ref_dir && S_ISDIR(st.st_mode) && o.frames > 0 && disp_capture_check_refs(o.ref_dir, o.frames, &err)) {
        ct_log(CT_LOG_ERROR, COMP, "%s", err.msg);
        return DISP_EXIT_USAGE;
    }
    if (o.out_dir && fs_folder_check("--out", o.out_dir, &err)) {
        ct_log(CT_LOG_ERROR, COMP, "%s", err.msg);
        return DISP_EXIT_USAGE;
    }
    /* The --out folder itself is made by disp_app_run once the solution
     * (or the connection) is known good: made here, a bad scene, mesh or
     * master left it behind. */
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    o.stop = &g_stop;
    ct_error_clear(&err);
    int status = disp_app_run(&o, &err);
    if (status != DISP_EXIT_OK) ct_log(CT_LOG_ERROR, COMP, "%s", err.msg);
    return status;
}

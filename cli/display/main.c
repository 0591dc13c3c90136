/* bin/corrtex-display: the display client. Parses options and runs
 * display/disp_app.c; links common, proto, display and GL only. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "display/disp_app.h"
#include "display/gl_load.h"

#define COMP "corrtex-display"

static volatile int g_stop;

/* SIGINT and SIGTERM end the run in order: the frames written so far and
 * frames.csv are completed, the master gets BYE. */
static void on_signal(int sig)
{
    g_stop = sig;
}

static void usage(FILE *f, const disp_app_opts *d)
{
    fprintf(f,
            "usage: corrtex-display [options]\n"
            "Shows the interactive solution corrected by corrective textures, from a master\n"
            "(--connect) or alone (--mesh / --scene), in a window or headless.\n\n"
            "input:\n"
            "  --connect ADDR        master's display socket: unix:PATH or tcp:HOST:PORT\n"
            "  --token-file FILE     shared token for the handshake (else $CORRTEX_TOKEN)\n"
            "  --reconnect           on a lost connection retry with back-off (default: exit 3)\n"
            "  --cache DIR           keep received scenes in DIR by content hash (default %s)\n"
            "  --cache-max-mb N      scenes kept there, at most, least recently used removed first\n"
            "                        (default %u MiB; 0: no bound)\n"
            "  --no-cache            keep the scene in memory only\n"
            "  --samples-per-frame K lockstep: the master inserts K samples per frame (default 0: free-running)\n"
            "  --mesh FILE.ctmesh    a radiosity mesh cache (corrtex radiosity), no master\n"
            "  --scene FILE.json     a scene with a stand-in radiosity (constant per material), no master\n"
            "  --ambient A           stand-in radiosity: emission + diffuse * A (default %.2f)\n"
            "  --synthetic N         up to N synthetic correction textures, one per visible part\n"
            "                        (benchmarks without a master; default 0)\n"
            "  --synthetic-tiles     cut parts into tiles to make all N (textures stack on parts)\n"
            "  --synthetic-positive  make them all positive\n"
            "view:\n"
            "  --backend B           glfw, egl or osmesa (default %s: glfw when $DISPLAY is set)\n"
            "  --width W --height H  image size (default %dx%d)\n"
            "  --exposure STOPS      displayed = linear * 2^STOPS (default %.1f)\n"
            "  --passes 1|3          corrections in one shader pass or three passes (default %d)\n"
            "  --view V              full, radiosity, corrections, assignment, samples (default %s)\n"
            "  --sample-frames N     samples view: show the sample points of the last N frames (default %u)\n"
            "  --sample-max N        samples view: keep at most N points (default %u)\n"
            "  --fbo 32f|16f         float framebuffer format (default 32f)\n"
            "  --no-vsync            window: do not wait for vertical sync\n"
            "  --camera EX,EY,EZ,TX,TY,TZ[,FOV]   start camera (eye, target, vertical fov degrees, default 50)\n"
            "  --camera-name NAME    a named camera of --scene (default: its first one)\n"
            "walkthroughs and output:\n"
            "  --path FILE           camera path (common/campath.h format)\n"
            "  --frames N            N frames spread over the path (default 0: real time; headless\n"
            "                        without a path: N frames of the still camera, default: 1,\n"
            "                        or with --connect until the master ends or a signal)\n"
            "  --seconds S           stop after S seconds (default 0: no limit)\n"
            "  --out DIR             write frame_NNNNN.exr/.png and frames.csv\n"
            "  --out-every S         capture a frame at most every S seconds (default 0: every frame)\n"
            "  --no-images           with --out: frames.csv only\n"
            "  --reference DIR|FILE  add RMSE/PSNR against DIR/frame_NNNNN.exr, or against FILE.exr for\n"
            "                        every frame (a still view), to frames.csv\n"
            "  --hold S              real-time path: stay at its last camera S seconds after it ends (0)\n"
            "  --continuous          draw every frame, also when nothing changed (frame-rate\n"
            "                        measurements; by default a still, unchanged view is not redrawn)\n"
            "  --full-redraw         draw a still camera's radiosity every frame (by default it is\n"
            "                        kept from the second frame on and only corrections are redrawn)\n"
            "  --texel-fps F         redraw a view for new texels alone at most F times a second\n"
            "                        (a moving camera is drawn at once; default 0: whenever they\n"
            "                        arrive). On a host shared with tracer ranks, what the display\n"
            "                        does not draw the tracers trace (docs/display.md)\n"
            "  --texel-cpu C         and spend at most C cores on such redraws, drawing, tone mapping\n"
            "                        and texel uploads included (default %.2g; 0: no limit): software\n"
            "                        GL at 1024x1024 is held to a few redraws a second, a GPU is not\n"
            "  --quiet | --verbose\n\n%s",
            d->cache_dir ? d->cache_dir : "none", d->cache_max_mb, d->ambient, gl_backend_name(d->backend), d->width, d->height, d->exposure, d->passes,
            disp_view_name(d->view), d->sample_frames, d->sample_max, d->texel_cpu, disp_app_keys_help());
}

static int parse_int(const char *opt, const char *s, int lo, int hi, int *out)
{
    char *end;
    long v = strtol(s, &end, 10);
    if (*s == '\0' || *end != '\0' || v < lo || v > hi) {
        ct_log(CT_LOG_ERROR, COMP, "%s: '%s' is not an integer in %d..%d", opt, s, lo, hi);
        return -1;
    }
    *out = (int)v;
    return 0;
}

static int parse_float(const char *opt, const char *s, float lo, float hi, float *out)
{
    char *end;
    float v = strtof(s, &end);
    if (*s == '\0' || *end != '\0' || !(v >= lo && v <= hi)) {
        ct_log(CT_LOG_ERROR, COMP, "%s: '%s' is not a number in %g..%g", opt, s, lo, hi);
        return -1;
    }
    *out = v;
    return 0;
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
    if ((n != 6 && n != 7) || *p != '\0' || !(v[6] > 1 && v[6] < 179)) {
        ct_log(CT_LOG_ERROR, COMP, "--camera: '%s' is not EX,EY,EZ,TX,TY,TZ[,FOV]", s);
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
    disp_app_opts o, d;
    disp_app_defaults(&o);
    /* Default scene cache: $XDG_CACHE_HOME/corrtex or ~/.cache/corrtex. */
    char cache[2048] = "";
    const char *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    if (xdg && *xdg) snprintf(cache, sizeof cache, "%s/corrtex", xdg);
    else if (home && *home) snprintf(cache, sizeof cache, "%s/.cache/corrtex", home);
    if (cache[0]) o.cache_dir = cache;
    d = o;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        ct_error err;
        int bad = 0;
#define NEED()                                                                  \
    if (!v) {                                                                   \
        ct_log(CT_LOG_ERROR, COMP, "%s needs a value (see --help)", a);         \
        return DISP_EXIT_USAGE;                                                 \
    }                                                                           \
    i++;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            usage(stdout, &d);
            return 0;
        } else if (!strcmp(a, "--backend")) {
            NEED();
            if (gl_backend_parse(v, &o.backend, &err)) {
                ct_log(CT_LOG_ERROR, COMP, "%s", err.msg);
                return DISP_EXIT_USAGE;
            }
        } else if (!strcmp(a, "--width")) { NEED(); bad = parse_int(a, v, 1, 16384, &o.width); }
        else if (!strcmp(a, "--height")) { NEED(); bad = parse_int(a, v, 1, 16384, &o.height); }
        else if (!strcmp(a, "--exposure")) { NEED(); bad = parse_float(a, v, -30, 30, &o.exposure); }
        else if (!strcmp(a, "--passes")) {
            NEED();
            bad = parse_int(a, v, 1, 3, &o.passes);
            if (!bad && o.passes == 2) {
                ct_log(CT_LOG_ERROR, COMP, "--passes: 1 or 3");
                bad = 1;
            }
        } else if (!strcmp(a, "--view")) {
            NEED();
            int k;
            for (k = 0; k < DISP_VIEW_COUNT; k++)
                if (!strcmp(v, disp_view_name((disp_view)k))) break;
            if (k == DISP_VIEW_COUNT) {
                ct_log(CT_LOG_ERROR, COMP, "--view: unknown view '%s'", v);
                bad = 1;
            }
            o.view = (disp_view)k;
        } else if (!strcmp(a, "--sample-frames")) {
            NEED();
            int n;
            bad = parse_int(a, v, 1, 100000, &n);
            o.sample_frames = (uint32_t)n;
        } else if (!strcmp(a, "--sample-max")) {
            NEED();
            int n;
            bad = parse_int(a, v, 1, 100000000, &n);
            o.sample_max = (uint32_t)n;
        } else if (!strcmp(a, "--fbo")) {
            NEED();
            if (!strcmp(v, "32f")) o.float_format = GL_RGBA32F;
            else if (!strcmp(v, "16f")) o.float_format = GL_RGBA16F;
            else {
                ct_log(CT_LOG_ERROR, COMP, "--fbo: 32f or 16f, not '%s'", v);
                bad = 1;
            }
        } else if (!strcmp(a, "--no-vsync")) o.vsync = false;
        else if (!strcmp(a, "--camera")) { NEED(); bad = parse_camera(v, &o.camera); o.has_camera = true; }
        else if (!strcmp(a, "--camera-name")) { NEED(); o.camera_name = v; }
        else if (!strcmp(a, "--mesh")) { NEED(); o.mesh = v; }
        else if (!strcmp(a, "--scene")) { NEED(); o.scene = v; }
        else if (!strcmp(a, "--ambient")) { NEED(); bad = parse_float(a, v, 0, 100, &o.ambient); }
        else if (!strcmp(a, "--synthetic")) {
            NEED();
            int n;
            bad = parse_int(a, v, 0, 100000, &n);
            o.synthetic = (uint32_t)n;
        } else if (!strcmp(a, "--synthetic-positive")) o.synthetic_positive = true;
        else if (!strcmp(a, "--synthetic-tiles")) o.synthetic_tiles = true;
        else if (!strcmp(a, "--path")) { NEED(); o.path = v; }
        else if (!strcmp(a, "--frames")) { NEED(); bad = parse_int(a, v, 0, 10000000, &o.frames); }
        else if (!strcmp(a, "--seconds")) {
            NEED();
            float s;
            bad = parse_float(a, v, 0, 1e7f, &s);
            o.max_seconds = s;
        } else if (!strcmp(a, "--samples-per-frame")) { NEED(); bad = parse_int(a, v, 0, 100000000, &o.samples_per_frame); }
        else if (!strcmp(a, "--out")) { NEED(); o.out_dir = v; }
        else if (!strcmp(a, "--reference")) { NEED(); o.ref_dir = v; }
        else if (!strcmp(a, "--no-images")) o.no_images = true;
        else if (!strcmp(a, "--continuous")) o.continuous = true;
        else if (!strcmp(a, "--full-redraw")) o.full_redraw = true;
        else if (!strcmp(a, "--texel-fps")) {
            NEED();
            float f;
            bad = parse_float(a, v, 0, 1000, &f);
            o.texel_fps = f;
        }
        else if (!strcmp(a, "--texel-cpu")) {
            NEED();
            float f;
            bad = parse_float(a, v, 0, 1000, &f);
            o.texel_cpu = f;
        }
        else if (!strcmp(a, "--out-every") || !strcmp(a, "--hold")) {
            NEED();
            float x;
            bad = parse_float(a, v, 0, 1e6f, &x);
            if (!strcmp(a, "--hold")) o.hold_seconds = x;
            else o.out_every = x;
        }
        else if (!strcmp(a, "--connect")) { NEED(); o.connect = v; }
        else if (!strcmp(a, "--token-file")) { NEED(); o.token_file = v; }
        else if (!strcmp(a, "--reconnect")) o.reconnect = true;
        else if (!strcmp(a, "--cache")) { NEED(); o.cache_dir = v; }
        else if (!strcmp(a, "--no-cache")) o.cache_dir = NULL;
        else if (!strcmp(a, "--cache-max-mb")) {
            NEED();
            int n;
            bad = parse_int(a, v, 0, 1 << 24, &n);
            o.cache_max_mb = (uint32_t)n;
        }
        else if (!strcmp(a, "--quiet")) ct_log_set_level(CT_LOG_WARN);
        else if (!strcmp(a, "--verbose")) ct_log_set_level(CT_LOG_DEBUG);
        else {
            ct_log(CT_LOG_ERROR, COMP, "unknown option '%s' (see --help)", a);
            return DISP_EXIT_USAGE;
        }
#undef NEED
        if (bad) return DISP_EXIT_USAGE;
    }
    int sources = (o.mesh != NULL) + (o.scene != NULL) + (o.connect != NULL);
    if (sources != 1) {
        ct_log(CT_LOG_ERROR, COMP, "give exactly one of --connect, --mesh or --scene (see --help)");
        return DISP_EXIT_USAGE;
    }
    if ((o.ref_dir || o.no_images || o.out_every > 0) && !o.out_dir) {
        ct_log(CT_LOG_ERROR, COMP, "--reference, --no-images and --out-every need --out");
        return DISP_EXIT_USAGE;
    }
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    o.stop = &g_stop;
    ct_error err;
    ct_error_clear(&err);
    int status = disp_app_run(&o, &err);
    if (status != DISP_EXIT_OK) ct_log(CT_LOG_ERROR, COMP, "%s", err.msg);
    return status;
}

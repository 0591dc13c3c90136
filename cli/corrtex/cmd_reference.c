/* corrtex reference: the offline high-quality renderer (tracer/render.h):
 * one image of a scene camera or of a camera path frame, or every frame of
 * a path into a folder, written as EXR (and an optional PNG preview). */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli/corrtex/commands.h"
#include "common/campath.h"
#include "common/fsutil.h"
#include "common/image.h"
#include "common/log.h"
#include "common/optab.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/timer.h"
#include "tracer/render.h"
#include "tracer/tracer.h"
#include "tracer/trc_cli.h"

#define CMD "corrtex reference"

typedef struct ref_args {
    const char *scene, *camera, *path, *out;
    const char *radmesh;    /* .ctmesh interactive solution, or NULL */
    int frame, frames;      /* -1: not given */
    int width, height, spp, threads, tile;   /* width, height, spp 0: not given */
    int order;              /* RENDER_ORDER_* */
    long sort_runs;
    trc_cli trc;            /* the tracer's options; mode -1: not given */
    uint64_t seed;
    float exposure;
    bool png, half, raw_embree, quiet, verbose;
    int bench_runs;
    float stand_in;         /* < 0: no stand-in radiosity */
    long raw_cap;
} ref_args;

/* Rows without a default are set in parse_args (-1: not given). */
#define OF(f) offsetof(ref_args, f)
static const optab OPTS[] = {
    {"camera", 0, OPTAB_STRING, OF(camera), 0, 0, NULL, "NAME", "", NULL},
    {"path", 0, OPTAB_STRING, OF(path), 0, 0, NULL, "PATH", "", NULL},
    {"frames", 0, OPTAB_INT, OF(frames), 1, 1000000, NULL, "N", "", NULL},
    {"frame", 0, OPTAB_INT, OF(frame), 0, 1000000, NULL, "K", "", NULL},
    {"width", 0, OPTAB_INT, OF(width), 1, 65536, NULL, "W", "", NULL},
    {"height", 0, OPTAB_INT, OF(height), 1, 65536, NULL, "H", "", NULL},
    {"spp", 0, OPTAB_INT, OF(spp), 1, 1 << 20, NULL, "S", "", NULL},
    {"radmesh", 0, OPTAB_STRING, OF(radmesh), 0, 0, NULL, "FILE", "", NULL},
    {"stand-in-radiosity", 0, OPTAB_FLOAT, OF(stand_in), 0, 1e6, NULL, "A", "", NULL},
    {"threads", 0, OPTAB_INT, OF(threads), 1, 256, NULL, "T", "", NULL},
    {"seed", 0, OPTAB_U64, OF(seed), 0, 1.8446744073709552e19, "1", "N", "", NULL},
    {"tile", 0, OPTAB_INT, OF(tile), 1, 4096, "16", "N", "", NULL},
    {"order", 0, OPTAB_CHOICE, OF(order), 0, 0, "tiles", "tiles|shuffled", "", NULL},
    {"sort-runs", 0, OPTAB_LONG, OF(sort_runs), 0, 1L << 32, "0", "N", "", NULL},
    {"half", 0, OPTAB_FLAG, OF(half), 0, 0, NULL, NULL, "", NULL},
    {"png", 0, OPTAB_FLAG, OF(png), 0, 0, NULL, NULL, "", NULL},
    {"exposure", 0, OPTAB_FLOAT, OF(exposure), -30, 30, "0", "E", "", NULL},
    {"raw-embree", 0, OPTAB_FLAG, OF(raw_embree), 0, 0, NULL, NULL, "", NULL},
    {"raw-cap", 0, OPTAB_LONG, OF(raw_cap), 1, 100000000, "2000000", "N", "", NULL},
    {"bench-runs", 0, OPTAB_INT, OF(bench_runs), 1, 20, "2", "R", "", NULL},
    {"out", 'o', OPTAB_STRING, OF(out), 0, 0, NULL, "OUT", "", NULL},
    {"quiet", 'q', OPTAB_FLAG, OF(quiet), 0, 0, NULL, NULL, "", NULL},
    {"verbose", 0, OPTAB_FLAG, OF(verbose), 0, 0, NULL, NULL, "", NULL},
};
#undef OF

static void help(FILE *f)
{
    trc_options p, d;
    trc_options_default(&p, TRC_MODE_PATH);
    trc_options_default(&d, TRC_MODE_DRT);
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    fprintf(f,
        "usage: corrtex reference SCENE [--camera NAME | --path PATH [--frame K] --frames N]\n"
        "                         --width W --height H --spp S --mode MODE [options] -o OUT\n"
        "\n"
        "Renders the high-quality reference (docs/tracer.md) and prints the rays/s and\n"
        "samples/s it reached.\n"
        "\n"
        "  SCENE             scene file (docs/scene-format.md)\n"
        "  --camera NAME     a camera of the scene (default: its first camera)\n"
        "  --path PATH       a camera path: the name of one of the scene's paths, or a path file\n"
        "  --frames N        the path's frame count (frames spread evenly over it); without\n"
        "                    --frame, renders all N frames into the folder OUT as\n"
        "                    frame_00000.exr, frame_00001.exr, ...\n"
        "  --frame K         render only frame K (0-based) of the N frames\n"
        "  --width W, --height H   image size in pixels (1..65536, at most 2^28 in all; required)\n"
        "  --spp S           samples per pixel, jittered in the pixel (required)\n"
        "  --mode MODE       path | drt | reuse-diffuse (required)\n"
        "                      path: unbiased path tracing with next-event estimation and MIS\n"
        "                      drt: distributed ray tracing; indirect diffuse light from the\n"
        "                           radiosity mesh (--radmesh, --indirect); without one it is\n"
        "                           path-traced\n"
        "                      reuse-diffuse: the diffuse part from a radiosity mesh, only\n"
        "                           specular transport traced; needs --radmesh\n"
        "  --radmesh FILE    the interactive solution (a .ctmesh from corrtex radiosity): rays\n"
        "                    intersect its triangles and drt/reuse-diffuse take its radiosity\n"
        "  --stand-in-radiosity A   use a stand-in interactive solution (every surface\n"
        "                    L_e + rho_d * A, no shadows; rmesh_from_scene) for drt and\n"
        "                    reuse-diffuse: for tests and throughput only, the images are\n"
        "                    not references (default: none)\n"
        "  --threads T       render threads (default: %ld, the online CPUs)\n"
        "  --shadow-rays K   light samples per shading point (default: path %d, drt %d)\n"
        "  --branch B        drt: rays per glossy lobe at a hit (default %d)\n"
        "  --branch-depth L  drt: levels that split into B glossy rays; deeper levels\n"
        "                    trace one ray per lobe, so a sample costs about B * D rays,\n"
        "                    not B^D (default %d)\n"
        "  --fresnel-depth F drt: levels that trace both the reflection and the refraction\n"
        "                    at glass; below, the stronger and the weaker by chance\n"
        "                    (default %d)\n"
        "  --depth D         drt: recursion depth (default %d); path: maximum bounces\n"
        "                    (default %d, Russian roulette after 3); -1: the mode's\n"
        "  --indirect I      drt with a radiosity mesh: its indirect diffuse light,\n"
        "                      mesh: the mesh's indirect part read at the hit\n"
        "                      gather: a final gather, G cosine rays reading the mesh where\n"
        "                           they land, at the first diffuse hit (default %s)\n"
        "  --gather-rays G   rays of --indirect gather per shading point (default %d)\n"
        "  --gather-direct W --indirect gather: the lamps' light where a gather ray lands,\n"
        "                      trace: one traced lamp sample beside the mesh's indirect part\n"
        "                      mesh: read from the mesh (faster; its shadows blurred)\n"
        "                    (default %s)\n"
        "  --caustic-photons N   drt with a radiosity mesh: photons shot from the lamps\n"
        "                    for their reflective caustics, the light curved mirrors and\n"
        "                    glass faces throw onto diffuse surfaces (0: none; default %d)\n"
        "  --glass-light L   path, drt: the lamps' light through glass,\n"
        "                      straight: by shadow rays that pass glass attenuated (the\n"
        "                           paper's model; default)\n"
        "                      refracted: only by refracted paths (glass blocks shadow\n"
        "                           rays; drt with a mesh: refracted photons)\n"
        "                      auto: straight through flat glass (panes, sheets),\n"
        "                           refracted through glass that bends light\n"
        "  --seed N          random seed (default %llu)\n",
        ncpu > 0 ? ncpu : 1, p.shadow_rays, d.shadow_rays, d.branch, d.branch_depth, d.fresnel_depth, d.depth, p.depth,
        trc_indirect_name(d.indirect), d.gather_rays, trc_gather_direct_name(d.gather_direct), d.caustic_photons,
        (unsigned long long)p.seed);
    fprintf(f,
        "  --tile N          tile edge in pixels (default 16)\n"
        "  --order O         benchmark: the order pixels are traced in (the image is the\n"
        "                    same): tiles, or shuffled over the whole image as the request\n"
        "                    queue hands them out, tile x tile pixels a task (default tiles)\n"
        "  --sort-runs N     --order shuffled: sort runs of N pixels along a Morton curve,\n"
        "                    as a tracer rank sorts each batch (default 0: unsorted)\n"
        "  --half            write half-float EXR (default: 32-bit float)\n"
        "  --png             also write a PNG preview beside each EXR\n"
        "  --exposure E      PNG preview exposure in stops (default 0)\n"
        "  --raw-embree      benchmark: log the rays in a first, untimed render, then R\n"
        "                    rounds of a timed render and raw Embree replays of the log\n"
        "                    (the fastest of each counts)\n"
        "  --raw-cap N       rays logged per thread, a uniform random subset of all\n"
        "                    traced rays (default 2000000)\n"
        "  --bench-runs R    rounds of --raw-embree (default 2)\n"
        "  -o, --out OUT     output EXR file, in a folder that exists; with --frames and no\n"
        "                    --frame a folder of frames, made with its parents\n"
        "  --quiet, --verbose\n"
        "tracer version %d (changes when the images change: cached references carry it)\n",
        TRC_VERSION);
}

static int bad(const char *fmt, const char *a, const char *b)
{
    char msg[512];
    snprintf(msg, sizeof msg, fmt, a, b);
    ct_log(CT_LOG_ERROR, CMD, "%s", msg);
    return 2;
}

/* The table (OPTS) parses and range-checks every value; --help keeps its
 * hand-written text, which explains how the options work together. */
static int parse_args(int argc, char **argv, ref_args *a)
{
    memset(a, 0, sizeof *a);
    ct_error err;
    optab_defaults(OPTS, OPTAB_COUNT(OPTS), a, &err);
    a->frame = a->frames = -1;
    size_t ntrc;
    const optab *trc = trc_cli_table(&ntrc);
    optab_defaults(trc, ntrc, &a->trc, &err);
    a->trc.mode = -1;
    a->stand_in = -1.0f;
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    a->threads = ncpu > 0 ? (int)(ncpu < 256 ? ncpu : 256) : 1;
    optab_group g[2] = {{OPTS, OPTAB_COUNT(OPTS), a}, {trc, ntrc, &a->trc}};
    const char *pos[1];
    int npos = 0, rc = optab_parse(g, 2, argc, argv, pos, 1, &npos, &err);
    if (rc == 1) {
        help(stdout);
        return 1;
    }
    if (a->quiet) ct_log_set_level(CT_LOG_WARN);
    if (a->verbose) ct_log_set_level(CT_LOG_DEBUG);
    if (rc) return bad("%s%s", err.msg, ""), -1;
    a->scene = npos ? pos[0] : NULL;
    if (!a->scene) return bad("missing SCENE (try --help)%s%s", "", ""), -1;
    if (!a->width || !a->height) return bad("missing --width or --height%s%s", "", ""), -1;
    if (!a->spp) return bad("missing --spp%s%s", "", ""), -1;
    if (a->trc.mode < 0) return bad("missing --mode (path, drt, reuse-diffuse)%s%s", "", ""), -1;
    if (!a->out || !*a->out) return bad("missing -o OUT%s%s", "", ""), -1;
    if (a->camera && a->path) return bad("--camera and --path exclude each other%s%s", "", ""), -1;
    if (!a->path && (a->frame >= 0 || a->frames >= 0)) return bad("--frame/--frames need --path%s%s", "", ""), -1;
    if (a->path && a->frames < 0) return bad("--path needs --frames N (the path's frame count)%s%s", "", ""), -1;
    /* one image (no --frames, or --frame K): an EXR file; else a folder */
    if ((a->frames < 0 || a->frame >= 0) && img_file_kind_of(a->out) != IMG_FILE_EXR)
        return bad("-o %s: the image is written as OpenEXR: give a name ending in .exr (--png writes an 8-bit copy "
                   "beside it)%s", a->out, ""), -1;
    if (a->frame >= 0 && a->frame >= a->frames) {
        char f[32], n[32];
        snprintf(f, sizeof f, "%d", a->frame);
        snprintf(n, sizeof n, "%d", a->frames);
        return bad("--frame %s is not below --frames %s", f, n), -1;
    }
    if (a->radmesh && a->stand_in >= 0.0f)
        return bad("give --radmesh or --stand-in-radiosity, not both%s%s", "", ""), -1;
    if (a->trc.mode == TRC_MODE_REUSE && a->stand_in < 0.0f && !a->radmesh)
        return bad("mode reuse-diffuse needs a radiosity mesh: give --radmesh FILE.ctmesh%s%s", "", ""), -1;
    return 0;
}

/* Replaces the extension of path (or appends one) into out. */
static void with_ext(const char *path, const char *ext, char *out, size_t cap)
{
    snprintf(out, cap, "%s", path);
    char *dot = strrchr(out, '.'), *slash = strrchr(out, '/');
    if (dot && (!slash || dot > slash)) *dot = '\0';
    size_t l = strlen(out);
    snprintf(out + l, cap - l, "%s", ext);
}

/* Frame k's EXR: -o itself, or frame_NNNNN.exr in the folder -o names. */
static void output_name(const ref_args *a, bool folder, int k, char *name, size_t cap)
{
    if (folder) {
        char leaf[32];
        snprintf(leaf, sizeof leaf, "frame_%05d.exr", k);
        fs_join(a->out, leaf, name, cap);
    } else {
        snprintf(name, cap, "%s", a->out);
    }
}

static int write_outputs(const ref_args *a, const char *exr, const ct_image *img, ct_error *err)
{
    int rc = img_write_exr(exr, img, a->half ? IMG_HALF : IMG_FLOAT, err);
    if (rc) return rc;
    if (a->png) {
        char png[4096];
        with_ext(exr, ".png", png, sizeof png);
        rc = img_write_png(png, img, a->exposure, err);
    }
    return rc;
}

static void report(const ref_args *a, const render_result *r, double total_s, int nimages)
{
    uint64_t rays = trc_stats_rays(&r->stats);
    double s = r->seconds > 0 ? r->seconds : 1e-9;
    char glass[40] = "";
    if (a->trc.glass_light != TRC_GLASS_AUTO && a->trc.mode != TRC_MODE_REUSE)
        snprintf(glass, sizeof glass, " (glass light %s)", trc_glass_light_name((trc_glass_light)a->trc.glass_light));
    printf("reference: %dx%d, %d spp, mode %s%s, %d thread%s, %d image%s: %.3f s tracing (%.3f s total)\n",
           a->width, a->height, a->spp, trc_mode_name((trc_mode)a->trc.mode), glass, a->threads,
           a->threads == 1 ? "" : "s", nimages, nimages == 1 ? "" : "s", r->seconds, total_s);
    printf("reference: %llu samples, %.0f samples/s; %llu rays (%llu primary, %llu secondary, "
           "%llu shadow), %.0f rays/s\n",
           (unsigned long long)r->stats.samples, (double)r->stats.samples / s, (unsigned long long)rays,
           (unsigned long long)r->stats.primary, (unsigned long long)r->stats.secondary,
           (unsigned long long)r->stats.shadow, (double)rays / s);
    if (r->logged) {
        printf("reference: raw embree on %llu logged rays: rtcIntersect1 %.0f rays/s, as traced "
               "(shadow rays rtcOccluded1) %.0f rays/s; tracer at %.0f%% of raw rtcIntersect1\n",
               (unsigned long long)r->logged, (double)r->logged / r->replay_isect_s,
               (double)r->logged / r->replay_traced_s,
               100.0 * ((double)rays / s) / ((double)r->logged / r->replay_isect_s));
    }
    /* One machine-readable line for scripts (scripts/bench-tracer). */
    printf("stats: mode=%s threads=%d width=%d height=%d spp=%d seconds=%.6f samples=%llu rays=%llu "
           "samples_per_s=%.1f rays_per_s=%.1f logged=%llu raw_isect_rays_per_s=%.1f "
           "raw_traced_rays_per_s=%.1f\n",
           trc_mode_name((trc_mode)a->trc.mode), a->threads, a->width, a->height, a->spp, r->seconds,
           (unsigned long long)r->stats.samples, (unsigned long long)rays, (double)r->stats.samples / s,
           (double)rays / s, (unsigned long long)r->logged,
           r->logged ? (double)r->logged / r->replay_isect_s : 0.0,
           r->logged ? (double)r->logged / r->replay_traced_s : 0.0);
}

static void add_result(render_result *sum, const render_result *r)
{
    sum->seconds += r->seconds;
    sum->stats.primary += r->stats.primary;
    sum->stats.secondary += r->stats.secondary;
    sum->stats.shadow += r->stats.shadow;
    sum->stats.samples += r->stats.samples;
    sum->logged += r->logged;
    sum->replay_isect_s += r->replay_isect_s;
    sum->replay_traced_s += r->replay_traced_s;
}

int cmd_reference(int argc, char **argv)
{
    ref_args a;
    int prc = parse_args(argc, argv, &a);
    if (prc) return prc > 0 ? 0 : 2;
    double t0 = ct_now();
    ct_error err;
    ct_error_clear(&err);
    ct_scene *s = NULL;
    trc_tracer *t = NULL;
    ct_campath own_path;
    memset(&own_path, 0, sizeof own_path);
    const ct_campath *path = NULL;
    ct_camera cam;
    ct_image img = {0, 0, NULL};
    ct_radmesh rad;
    memset(&rad, 0, sizeof rad);
    bool have_rad = false;
    int status = 2, rc;

    /* an image no reader of ours would open again (16384 x 65536 traced
     * for hours, then written as 6 GB nothing loads) is refused at once */
    if ((rc = img_size_check(a.width, a.height, &err)) || (rc = trc_cli_check(&a.trc, &err))) goto fail;
    /* One image (no --path, or --frame K): -o is a file, and its folder must
     * exist, as for every program's output file (docs/architecture.md,
     * "Outputs"); a missing one used to be created, where corrtex radiosity
     * refused it. Checked before the scene is loaded. */
    bool folder = a.path && a.frame < 0;
    if (!folder) {
        char png[4096];
        with_ext(a.out, ".png", png, sizeof png);
        if ((rc = fs_output_check(a.out, &err)) || (a.png && (rc = fs_output_check(png, &err)))) goto fail;
    }
    if ((rc = scene_load(a.scene, &s, &err))) goto fail;
    if (a.path) {
        if (!(path = scene_path_or_file(s, a.scene, a.path, &own_path, &err))) {
            rc = CT_EINVAL;
            goto fail;
        }
    } else if (a.camera) {
        int ci = scene_find_camera(s, a.camera);
        if (ci < 0) {
            ct_fail(&err, CT_EINVAL, "camera '%s' is not in %s (%u cameras)", a.camera, a.scene, s->ncams);
            goto fail;
        }
        cam = s->cams[ci].cam;
    } else {
        if (s->ncams == 0) {
            ct_fail(&err, CT_EINVAL, "%s has no camera: give --path", a.scene);
            goto fail;
        }
        cam = s->cams[0].cam;
    }

    trc_options to;
    trc_cli_apply(&a.trc, &to);
    to.seed = a.seed;
    double tb = ct_now();
    if (a.radmesh) {
        /* Any solution hash: trc_new checks that the mesh's nodes and
         * materials are this scene's. */
        if ((rc = rmesh_load(a.radmesh, 0, &rad, &err))) goto fail;
        have_rad = true;
        ct_info(CMD, "%s: %u triangles of radiosity mesh", a.radmesh, rad.ntris);
    } else if (a.stand_in >= 0.0f) {
        if ((rc = rmesh_from_scene(s, v3s(a.stand_in), &rad, &err))) goto fail;
        have_rad = true;
        ct_warn(CMD, "stand-in radiosity (L_e + rho_d * %g): throughput and tests only, not a reference",
                (double)a.stand_in);
    }
    if ((rc = trc_new(s, have_rad ? &rad : NULL, &to, &t, &err))) {
        if (rc == CT_ESTALE && a.radmesh) ct_error_prefix(&err, a.radmesh);   /* another scene's mesh */
        goto fail;
    }
    ct_info(CMD, "%s: %u triangles, %u lights; Embree scene built in %.2f s", a.scene, s->ntris, s->nemitters,
            ct_now() - tb);
    uint32_t nem;
    bool spatial;
    double gain;
    trc_light_choice(t, &nem, &spatial, &gain);
    if (gain > 0.0)
        ct_info(CMD, "%u emitters, picked %s (estimated gain of a per-point choice %.2f)", nem,
                spatial ? "per shading point" : "by power", gain);
    uint64_t ph, landed;
    double cs;
    trc_caustic_stats(t, &ph, &landed, &cs);
    if (ph)
        ct_info(CMD, "caustics: %llu photons, %llu landed after a reflection%s, %.2f s", (unsigned long long)ph,
                (unsigned long long)landed, to.glass_light != TRC_GLASS_STRAIGHT ? " or through glass" : "", cs);
    if ((rc = img_alloc(&img, a.width, a.height, &err))) goto fail;
    render_options ro;
    render_options_default(&ro, a.width, a.height);
    ro.spp = a.spp;
    ro.threads = a.threads;
    ro.tile = a.tile;
    ro.order = a.order;
    ro.sort_runs = (size_t)a.sort_runs;
    ro.progress = ct_log_get_level() >= CT_LOG_INFO ? "reference" : NULL;
    if (a.raw_embree) ro.raylog_cap = (size_t)a.raw_cap;
    ro.bench_runs = a.bench_runs;
    render_result total;
    memset(&total, 0, sizeof total);
    int first = path ? (a.frame >= 0 ? a.frame : 0) : 0;
    int last = path ? (a.frame >= 0 ? a.frame : a.frames - 1) : 0;
    /* An output folder (--path without --frame) is made, with its parents. */
    if (folder && (rc = fs_mkdirs(a.out, &err))) goto fail;
    /* Fail on an output that cannot be written now, not after a render
     * that may take hours (a folder named x.exr was refused only once the
     * image was traced; a frame_00007.exr that is a folder, once the seven
     * frames before it were). */
    for (int k = first; k <= last; k++) {
        char name[4096], png[4096];
        output_name(&a, folder, k, name, sizeof name);
        with_ext(name, ".png", png, sizeof png);
        if ((rc = fs_output_check(name, &err)) || (a.png && (rc = fs_output_check(png, &err)))) goto fail;
    }
    for (int k = first; k <= last; k++) {
        if (path) cam = campath_frame(path, k, a.frames);
        ro.epoch = (uint32_t)k;
        render_result r;
        if ((rc = render_image(t, &cam, &ro, img.px, &r, &err))) goto fail;
        add_result(&total, &r);
        char name[4096];
        output_name(&a, folder, k, name, sizeof name);
        if ((rc = write_outputs(&a, name, &img, &err))) goto fail;
        ct_info(CMD, "wrote %s", name);
    }
    report(&a, &total, ct_now() - t0, last - first + 1);
    status = 0;
    goto done;
fail:
    ct_log(CT_LOG_ERROR, CMD, "%s", err.msg);
done:
    free(img.px);
    trc_free(t);
    if (have_rad) rmesh_free(&rad);
    if (own_path.keys) campath_free(&own_path);
    scene_free(s);
    return status;
}

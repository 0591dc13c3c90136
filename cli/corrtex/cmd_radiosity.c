/* corrtex radiosity SCENE -o FILE.ctmesh [options]: solves the scene's
 * interactive solution (hierarchical radiosity, tracer/radiosity.h) and writes
 * its conforming mesh as a .ctmesh cache (docs/radiosity.md). */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/corrtex/commands.h"
#include "common/fsutil.h"
#include "common/image.h"
#include "common/log.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "tracer/radiosity.h"

static void usage(FILE *f, const rad_params *d)
{
    fprintf(f,
            "usage: corrtex radiosity SCENE.json -o FILE.ctmesh [options]\n"
            "  Hierarchical radiosity (Hanrahan, Salzman, Aupperle 1991) meshed into a conforming\n"
            "  Gouraud mesh with per-vertex total and direct radiance (docs/radiosity.md).\n"
            "  -o, --output FILE      the .ctmesh cache to write (required)\n"
            "  --reuse                keep FILE when it already holds this scene's solution for\n"
            "                         these parameters (same hash), else solve and overwrite it\n"
            "  --error E              link error threshold: the largest B*F*A a link may carry,\n"
            "                         as a fraction of the total emitted power (default %g)\n"
            "  --min-area A           smallest element, as a fraction of the total surface area\n"
            "                         (default %g)\n"
            "  --max-triangles N      stop subdividing near N output triangles (default %u)\n"
            "  --threads T            worker threads (default %d: the online CPUs)\n"
            "  --memory-cap MB        fail instead of growing past MB megabytes (default %u)\n"
            "  --vis-rays N           visibility rays per link from a non-emitting source (default %d)\n"
            "  --shadow-rays N        visibility rays per link from an emitting source (default %d)\n"
            "  --tolerance R          stop iterating when the largest change of a radiosity, relative\n"
            "                         to the brightest reflected radiosity, is below R (default %g)\n"
            "  --max-iterations N     gather/push-pull iterations per pass at most (default %d)\n"
            "  --max-passes N         refinement passes at most (default %d)\n"
            "  --crease-angle DEG     average vertex values only below this normal angle (default %g)\n"
            "  --seed S               visibility ray seed (default %llu)\n"
            "  --image FILE           also render the solution as the display shows it (Gouraud)\n"
            "                         from a scene camera: FILE.exr (linear) or FILE.png (sRGB)\n"
            "  --camera NAME          the camera of --image (default: the scene's first)\n"
            "  --width W, --height H  size of --image (default 512 x 512)\n"
            "  --spp S                jittered samples per pixel of --image (default 4)\n"
            "  --image-direct         --image shows the direct part only\n"
            "  --image-planes FILE    also write FILE.exr: per pixel the plane its samples hit\n"
            "                         (0 at edges between surfaces; corrtex compare --planes)\n"
            "  --quiet, --verbose     log level\n",
            d->error, d->min_area, d->max_triangles, d->threads, d->memory_cap_mb, d->vis_rays,
            d->shadow_rays, d->tolerance, d->max_iterations, d->max_passes, d->crease_deg,
            (unsigned long long)d->seed);
}

static void on_progress(void *user, double fraction, const char *what)
{
    (void)user;
    ct_progress("radiosity", fraction, 0, "%s", what);
}

/* Parses a number option fully; returns 0 or prints the error. */
static int num(const char *opt, const char *s, double lo, double hi, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || end == s || *end || !(v >= lo && v <= hi)) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "--%s: '%s' is not a number in [%g, %g]", opt, s, lo, hi);
        return -1;
    }
    *out = v;
    return 0;
}

int cmd_radiosity(int argc, char **argv)
{
    rad_params p, defaults;
    rad_params_default(&p);
    defaults = p;
    const char *out_path = NULL;
    enum { O_ERROR = 256, O_MINAREA, O_MAXTRI, O_THREADS, O_MEMCAP, O_VIS, O_SHADOW, O_TOL, O_MAXIT,
           O_PASSES, O_CREASE, O_SEED, O_QUIET, O_VERBOSE, O_REUSE, O_IMAGE, O_CAMERA, O_WIDTH,
           O_HEIGHT, O_SPP, O_IMGDIRECT, O_IMGPLANES };
    static const struct option opts[] = {
        {"output", required_argument, 0, 'o'}, {"error", required_argument, 0, O_ERROR},
        {"min-area", required_argument, 0, O_MINAREA}, {"max-triangles", required_argument, 0, O_MAXTRI},
        {"threads", required_argument, 0, O_THREADS}, {"memory-cap", required_argument, 0, O_MEMCAP},
        {"vis-rays", required_argument, 0, O_VIS}, {"shadow-rays", required_argument, 0, O_SHADOW},
        {"tolerance", required_argument, 0, O_TOL}, {"max-iterations", required_argument, 0, O_MAXIT},
        {"max-passes", required_argument, 0, O_PASSES}, {"crease-angle", required_argument, 0, O_CREASE},
        {"seed", required_argument, 0, O_SEED}, {"quiet", no_argument, 0, O_QUIET},
        {"verbose", no_argument, 0, O_VERBOSE}, {"reuse", no_argument, 0, O_REUSE},
        {"image", required_argument, 0, O_IMAGE}, {"camera", required_argument, 0, O_CAMERA},
        {"width", required_argument, 0, O_WIDTH}, {"height", required_argument, 0, O_HEIGHT},
        {"spp", required_argument, 0, O_SPP}, {"image-direct", no_argument, 0, O_IMGDIRECT},
        {"image-planes", required_argument, 0, O_IMGPLANES},
        {"help", no_argument, 0, 'h'}, {0, 0, 0, 0}};
    int reuse = 0, width = 512, height = 512, spp = 4, img_direct = 0;
    const char *image = NULL, *camera = NULL, *planes = NULL;
    int c;
    double v = 0.0;
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
        const char *name = c >= 256 ? opts[c - 256 + 1].name : "";
        int bad = 0;
        switch (c) {
        case 'o': out_path = optarg; break;
        case O_ERROR: bad = num("error", optarg, 1e-15, 1.0, &p.error); break;
        case O_MINAREA: bad = num("min-area", optarg, 1e-15, 1.0, &p.min_area); break;
        case O_MAXTRI: bad = num(name, optarg, 1, 4e9, &v); p.max_triangles = (uint32_t)v; break;
        case O_THREADS: bad = num(name, optarg, 1, 256, &v); p.threads = (int)v; break;
        case O_MEMCAP: bad = num(name, optarg, 16, 1 << 24, &v); p.memory_cap_mb = (uint32_t)v; break;
        case O_VIS: bad = num(name, optarg, 1, 1024, &v); p.vis_rays = (int)v; break;
        case O_SHADOW: bad = num(name, optarg, 1, 1024, &v); p.shadow_rays = (int)v; break;
        case O_TOL: bad = num(name, optarg, 1e-15, 1.0, &p.tolerance); break;
        case O_MAXIT: bad = num(name, optarg, 1, 1e6, &v); p.max_iterations = (int)v; break;
        case O_PASSES: bad = num(name, optarg, 1, 1000, &v); p.max_passes = (int)v; break;
        case O_CREASE: bad = num(name, optarg, 0, 180, &p.crease_deg); break;
        case O_SEED: bad = num(name, optarg, 0, 1.8e19, &v); p.seed = (uint64_t)v; break;
        case O_QUIET: ct_log_set_level(CT_LOG_ERROR); break;
        case O_VERBOSE: ct_log_set_level(CT_LOG_DEBUG); break;
        case O_REUSE: reuse = 1; break;
        case O_IMAGE: image = optarg; break;
        case O_CAMERA: camera = optarg; break;
        case O_WIDTH: bad = num("width", optarg, 1, 16384, &v); width = (int)v; break;
        case O_HEIGHT: bad = num("height", optarg, 1, 16384, &v); height = (int)v; break;
        case O_SPP: bad = num("spp", optarg, 1, 4096, &v); spp = (int)v; break;
        case O_IMGDIRECT: img_direct = 1; break;
        case O_IMGPLANES: planes = optarg; break;
        case 'h': usage(stdout, &defaults); return 0;
        default:
            ct_log(CT_LOG_ERROR, "corrtex radiosity", "unknown or incomplete option '%s' (try --help)",
                   argv[optind - 1]);
            return 2;
        }
        if (bad) return 2;
    }
    if (optind != argc - 1) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "expected one scene file (got %d arguments; try --help)",
               argc - optind);
        return 2;
    }
    if (!out_path) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "missing -o FILE.ctmesh (try --help)");
        return 2;
    }
    ct_error err;
    if (rad_params_check(&p, &err) != CT_OK) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s", err.msg);
        return 2;
    }
    /* Fail on an unwritable output now, not after a long solve. */
    const char *outs[3] = {out_path, image, planes};
    for (int i = 0; i < 3; i++) {
        if (outs[i] && fs_output_check(outs[i], &err) != CT_OK) {
            ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s", err.msg);
            return 2;
        }
    }
    ct_scene *s;
    if (scene_load(argv[optind], &s, &err) != CT_OK) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s", err.msg);
        return 2;
    }
    int cam = 0;
    if (image || planes) {
        cam = camera ? scene_find_camera(s, camera) : (s->ncams ? 0 : -1);
        if (cam < 0) {
            if (camera) ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s: no camera named '%s'", argv[optind], camera);
            else ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s: --image needs a camera and the scene has none", argv[optind]);
            scene_free(s);
            return 2;
        }
    }
    ct_info("radiosity", "%s: %u primitives, %u triangles, %u emitters; error %g, min-area %g, %d threads",
            s->name, s->nprims, s->ntris, s->nemitters, p.error, p.min_area, p.threads);
    ct_radmesh m;
    rad_stats st;
    rad_progress_fn prog = ct_log_get_level() >= CT_LOG_INFO ? on_progress : NULL;
    int rc, from_cache = 0;
    if (reuse) {
        ct_error why;
        rc = rad_cached_solve(s, &p, out_path, prog, NULL, &m, &st, &from_cache, &why, &err);
        if (!from_cache) ct_info("radiosity", "solving: %s", why.msg);
    } else {
        rc = rad_solve(s, &p, prog, NULL, &m, &st, &err);
    }
    if (prog && !from_cache) ct_progress("radiosity", 1.0, 1, "%s", rc ? "failed" : "done");
    if (rc != CT_OK) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s: %s", argv[optind], err.msg);
        scene_free(s);
        /* A scene without light is bad input; running out of the cap is a resource failure. */
        return rc == CT_ENOMEM ? 1 : 2;
    }
    for (int k = 0; k < 2 && !rc; k++) {
        const char *path = k ? planes : image;
        if (!path) continue;
        ct_image img;
        rc = img_alloc(&img, width, height, &err);
        if (!rc)
            rc = rad_render_view(&m, &s->cams[cam].cam, spp,
                                 k ? RAD_VIEW_PLANES : img_direct ? RAD_VIEW_DIRECT : RAD_VIEW_TOTAL, p.threads,
                                 &img, &err);
        if (!rc) {
            size_t n = strlen(path);
            rc = !k && n > 4 && strcmp(path + n - 4, ".png") == 0 ? img_write_png(path, &img, 0.0f, &err)
                                                                  : img_write_exr(path, &img, IMG_FLOAT, &err);
        }
        img_free(&img);
        if (rc) {
            ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s", err.msg);
            rmesh_free(&m);
            scene_free(s);
            return 2;
        }
        ct_info("radiosity", "%s: %d x %d, camera '%s', %d samples per pixel", path, width, height,
                s->cams[cam].name, spp);
    }
    if (from_cache) {
        ct_info("radiosity", "%s: up to date (hash %016llx), %u triangles, %u vertices", out_path,
                (unsigned long long)m.scene_hash, m.ntris, m.nverts);
        printf("cached 1\ntriangles %u\nvertices %u\n", m.ntris, m.nverts);
        rmesh_free(&m);
        scene_free(s);
        return 0;
    }
    rc = reuse ? CT_OK : rmesh_save(&m, out_path, &err);
    if (rc != CT_OK) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s", err.msg);
        rmesh_free(&m);
        scene_free(s);
        return 2;
    }
    ct_info("radiosity",
            "%s: %u patches, %llu elements, %llu links, %d passes, %d iterations, residual %.2e, "
            "%u triangles, %u vertices, %llu rays, %.1f MB, %.2f s",
            out_path, st.patches, (unsigned long long)st.elements, (unsigned long long)st.links, st.passes,
            st.iterations, st.residual, st.triangles, st.vertices, (unsigned long long)st.rays,
            (double)st.peak_bytes / (1 << 20), st.seconds);
    printf("patches %u\nelements %llu\nlinks %llu\npasses %d\niterations %d\nresidual %.3e\n"
           "triangles %u\nvertices %u\nrays %llu\nsolver_mb %.1f\nseconds %.2f\nemitted %.6g\nabsorbed %.6g\n",
           st.patches, (unsigned long long)st.elements, (unsigned long long)st.links, st.passes, st.iterations,
           st.residual, st.triangles, st.vertices, (unsigned long long)st.rays,
           (double)st.peak_bytes / (1 << 20), st.seconds, st.emitted, st.absorbed);
    rmesh_free(&m);
    scene_free(s);
    return 0;
}

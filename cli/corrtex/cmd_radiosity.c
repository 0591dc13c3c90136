/* corrtex radiosity SCENE [-o FILE.ctmesh] [options]: solves the scene's
 * interactive solution (hierarchical radiosity, radiosity/radiosity.h) and writes
 * its conforming mesh as a .ctmesh cache (docs/radiosity.md); without -o
 * into the default cache that corrtex-render reads (rad_cache_default). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/corrtex/commands.h"
#include "common/fsutil.h"
#include "common/image.h"
#include "common/log.h"
#include "common/optab.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "radiosity/radiosity.h"

typedef struct radiosity_opts {
    rad_params p;
    const char *out, *image, *camera, *planes;
    int width, height, spp;
    bool reuse, cache_path, image_direct, quiet, verbose;
} radiosity_opts;

/* The solver's rows have no default of their own: rad_params_default's. */
#define OF(f) offsetof(radiosity_opts, f)
static const optab OPTS[] = {
    {"output", 'o', OPTAB_STRING, OF(out), 0, 0, NULL, "FILE",
     "the .ctmesh file to write (default: the cache corrtex-render reads, HASH.ctmesh in $XDG_CACHE_HOME/corrtex, "
     "else ~/.cache/corrtex, made when missing; kept when up to date, as with --reuse)", NULL},
    {"reuse", 0, OPTAB_FLAG, OF(reuse), 0, 0, NULL, NULL,
     "keep FILE when it already holds this scene's solution for these parameters (same hash), else solve and "
     "overwrite it", NULL},
    {"cache-path", 0, OPTAB_FLAG, OF(cache_path), 0, 0, NULL, NULL,
     "print the default cache file of this scene and these parameters (where -o is left out) and exit: nothing "
     "is solved or written", NULL},
    {"error", 0, OPTAB_DOUBLE, OF(p.error), 1e-15, 1.0, NULL, "E",
     "link error threshold: the largest B*F*A a link may carry, as a fraction of the total emitted power", NULL},
    {"min-area", 0, OPTAB_DOUBLE, OF(p.min_area), 1e-15, 1.0, NULL, "A",
     "smallest element, as a fraction of the lit surface area (of all of it in the first pass)", NULL},
    {"max-triangles", 0, OPTAB_U32, OF(p.max_triangles), 1, 4e9, NULL, "N", "stop subdividing near N output triangles",
     NULL},
    {"threads", 0, OPTAB_INT, OF(p.threads), 1, 256, NULL, "T", "worker threads (the online CPUs)", NULL},
    {"memory-cap", 0, OPTAB_U32, OF(p.memory_cap_mb), 16, 1 << 24, NULL, "MB",
     "fail instead of growing past MB megabytes", NULL},
    {"vis-rays", 0, OPTAB_INT, OF(p.vis_rays), 1, 1024, NULL, "N", "visibility rays per link from a non-emitting source",
     NULL},
    {"shadow-rays", 0, OPTAB_INT, OF(p.shadow_rays), 1, 1024, NULL, "N",
     "visibility rays per link from an emitting source", NULL},
    {"dim-floor", 0, OPTAB_DOUBLE, OF(p.dim_floor), 0, 1, NULL, "F",
     "a receiver dimmer than the scene's mean reflected radiosity is refined for errors down to its share of "
     "the threshold, at least F times it (0: one threshold everywhere)", NULL},
    {"vertex-rays", 0, OPTAB_INT, OF(p.vertex_rays), 0, 1024, NULL, "N",
     "final gather: visibility rays from a mesh vertex to a partly hidden source whose light it may change by "
     "more than 1 % (0: every vertex takes its element's visibility)", NULL},
    {"gather-passes", 0, OPTAB_INT, OF(p.gather_passes), 0, 16, NULL, "N",
     "after the solve, steps of the final gather at every leaf's centre, so that what the vertices gather from "
     "has each leaf's own visibility, the scene's total light kept (0: the links' values; 2 takes the Cornell box's "
     "contact shadows from 1.7 to 1.3 times the truth and costs about 1.4-2 times the solve)", NULL},
    {"tolerance", 0, OPTAB_DOUBLE, OF(p.tolerance), 1e-15, 1.0, NULL, "R",
     "stop iterating when the largest change of a radiosity, relative to the brightest reflected radiosity, is "
     "below R", NULL},
    {"max-iterations", 0, OPTAB_INT, OF(p.max_iterations), 1, 1e6, NULL, "N", "gather/push-pull iterations per pass at most",
     NULL},
    {"max-passes", 0, OPTAB_INT, OF(p.max_passes), 1, 1000, NULL, "N", "refinement passes at most", NULL},
    {"crease-angle", 0, OPTAB_DOUBLE, OF(p.crease_deg), 0, 180, NULL, "DEG",
     "average vertex values only below this normal angle", NULL},
    {"seed", 0, OPTAB_U64, OF(p.seed), 0, 1.8446744073709552e19, NULL, "S", "visibility ray seed", NULL},
    {"mirror-samples", 0, OPTAB_INT, OF(p.mirror_samples), 0, 4096, NULL, "N",
     "lamp samples by way of plane mirrors per element and vertex: the light a mirror reflects from the lamps "
     "onto diffuse surfaces (0: none; a mirror then passes the lamps' light on as if diffuse, docs/radiosity.md)", NULL},
    {"image", 0, OPTAB_STRING, OF(image), 0, 0, NULL, "FILE",
     "also render the solution as the display shows it (Gouraud) from a scene camera: FILE.exr (linear) or "
     "FILE.png (sRGB)", NULL},
    {"camera", 0, OPTAB_STRING, OF(camera), 0, 0, NULL, "NAME", "the camera of --image (default: the scene's first)",
     NULL},
    {"width", 0, OPTAB_INT, OF(width), 1, 16384, "512", "W", "width of --image", NULL},
    {"height", 0, OPTAB_INT, OF(height), 1, 16384, "512", "H", "height of --image", NULL},
    {"spp", 0, OPTAB_INT, OF(spp), 1, 4096, "4", "S", "jittered samples per pixel of --image", NULL},
    {"image-direct", 0, OPTAB_FLAG, OF(image_direct), 0, 0, NULL, NULL, "--image shows the direct part only", NULL},
    {"image-planes", 0, OPTAB_STRING, OF(planes), 0, 0, NULL, "FILE",
     "also write FILE.exr: per pixel the plane its samples hit (0 at edges between surfaces; corrtex compare "
     "--planes)", NULL},
    {"quiet", 'q', OPTAB_FLAG, OF(quiet), 0, 0, NULL, NULL, "errors only", NULL},
    {"verbose", 0, OPTAB_FLAG, OF(verbose), 0, 0, NULL, NULL, "debug lines too", NULL},
};
#undef OF

static void usage(FILE *f, const radiosity_opts *d)
{
    fprintf(f, "usage: corrtex radiosity SCENE.json [-o FILE.ctmesh] [options]\n"
               "  Hierarchical radiosity (Hanrahan, Salzman, Aupperle 1991) meshed into a conforming\n"
               "  Gouraud mesh with per-vertex total and direct radiance (docs/radiosity.md).\n");
    optab_usage(OPTS, OPTAB_COUNT(OPTS), d, f);
}

static void on_progress(void *user, double fraction, const char *what)
{
    (void)user;
    ct_progress("radiosity", fraction, 0, "%s", what);
}

int cmd_radiosity(int argc, char **argv)
{
    radiosity_opts o;
    ct_error err;
    optab_defaults(OPTS, OPTAB_COUNT(OPTS), &o, &err);
    rad_params_default(&o.p);
    radiosity_opts defaults = o;
    optab_group g = {OPTS, OPTAB_COUNT(OPTS), &o};
    const char *pos[1];
    int npos = 0, prc = optab_parse(&g, 1, argc, argv, pos, 1, &npos, &err);
    if (prc == 1) {
        usage(stdout, &defaults);
        return 0;
    }
    if (o.quiet) ct_log_set_level(CT_LOG_ERROR);
    if (o.verbose) ct_log_set_level(CT_LOG_DEBUG);
    if (prc) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s", err.msg);
        return 2;
    }
    if (npos != 1) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "expected one scene file (got %d arguments; try --help)", npos);
        return 2;
    }
    const char *scene_path = pos[0], *out_path = o.out, *image = o.image, *camera = o.camera, *planes = o.planes;
    rad_params p = o.p;
    if (o.cache_path && out_path) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "--cache-path prints the file -o leaves out: not with -o");
        return 2;
    }
    if (rad_params_check(&p, &err) != CT_OK) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s", err.msg);
        return 2;
    }
    if (image && img_file_kind_of(image) == IMG_FILE_OTHER) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "--image %s: give a name ending in .exr (linear) or .png (sRGB)",
               image);
        return 2;
    }
    if (planes && img_file_kind_of(planes) != IMG_FILE_EXR) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "--image-planes %s: give a name ending in .exr", planes);
        return 2;
    }
    /* Fail on an unwritable output now, not after a long solve (the
     * default cache's name needs the scene: checked after it loads). */
    const char *outs[3] = {out_path, image, planes};
    for (int i = 0; i < 3; i++) {
        if (outs[i] && (i == 0 ? rmesh_output_check(outs[i], &err) : fs_output_check(outs[i], &err)) != CT_OK) {
            ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s", err.msg);
            return 2;
        }
    }
    ct_scene *s;
    if (scene_load(scene_path, &s, &err) != CT_OK) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s", err.msg);
        return 2;
    }
    char cache[4096];
    if (!out_path) {
        if (rad_cache_default(s, &p, !o.cache_path, cache, sizeof cache, &err) != CT_OK ||
            (!o.cache_path && rmesh_output_check(cache, &err) != CT_OK)) {
            ct_log(CT_LOG_ERROR, "corrtex radiosity", "the default cache: %s", err.msg);
            scene_free(s);
            return 2;
        }
        if (o.cache_path) {
            printf("%s\n", cache);
            scene_free(s);
            return 0;
        }
        out_path = cache;
        o.reuse = true;
    }
    int cam = 0;
    if (image || planes) {
        cam = camera ? scene_find_camera(s, camera) : (s->ncams ? 0 : -1);
        if (cam < 0) {
            if (camera) ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s: no camera named '%s'", scene_path, camera);
            else ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s: --image needs a camera and the scene has none", scene_path);
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
    if (o.reuse) {
        ct_error why;
        rc = rad_cached_solve(s, &p, out_path, prog, NULL, &m, &st, &from_cache, &why, &err);
        if (!from_cache) ct_info("radiosity", "solving: %s", why.msg);
    } else {
        rc = rad_solve(s, &p, prog, NULL, &m, &st, &err);
    }
    if (prog && !from_cache) ct_progress("radiosity", 1.0, 1, "%s", rc ? "failed" : "done");
    if (rc != CT_OK) {
        ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s: %s", scene_path, err.msg);
        scene_free(s);
        /* A scene without light is bad input; running out of the cap is a resource failure. */
        return rc == CT_ENOMEM ? 1 : 2;
    }
    for (int k = 0; k < 2 && !rc; k++) {
        const char *path = k ? planes : image;
        if (!path) continue;
        ct_image img;
        rc = img_alloc(&img, o.width, o.height, &err);
        if (!rc)
            rc = rad_render_view(&m, &s->cams[cam].cam, o.spp,
                                 k ? RAD_VIEW_PLANES : o.image_direct ? RAD_VIEW_DIRECT : RAD_VIEW_TOTAL, p.threads,
                                 &img, &err);
        if (!rc) {
            rc = img_file_kind_of(path) == IMG_FILE_PNG ? img_write_png(path, &img, 0.0f, &err)
                                                        : img_write_exr(path, &img, IMG_FLOAT, &err);
        }
        img_free(&img);
        if (rc) {
            ct_log(CT_LOG_ERROR, "corrtex radiosity", "%s", err.msg);
            rmesh_free(&m);
            scene_free(s);
            return 2;
        }
        ct_info("radiosity", "%s: %d x %d, camera '%s', %d samples per pixel", path, o.width, o.height,
                s->cams[cam].name, o.spp);
    }
    if (from_cache) {
        ct_info("radiosity", "%s: up to date (hash %016llx), %u triangles, %u vertices", out_path,
                (unsigned long long)m.scene_hash, m.ntris, m.nverts);
        printf("file %s\ncached 1\ntriangles %u\nvertices %u\n", out_path, m.ntris, m.nverts);
        rmesh_free(&m);
        scene_free(s);
        return 0;
    }
    rc = o.reuse ? CT_OK : rmesh_save(&m, out_path, &err);
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
    printf("file %s\npatches %u\nelements %llu\nlinks %llu\npasses %d\niterations %d\nresidual %.3e\n"
           "triangles %u\nvertices %u\ncontact_vertices %u\nrays %llu\nsolver_mb %.1f\nseconds %.2f\nemitted %.6g\n"
           "absorbed %.6g\n",
           out_path, st.patches, (unsigned long long)st.elements, (unsigned long long)st.links, st.passes,
           st.iterations, st.residual, st.triangles, st.vertices, st.contact_vertices, (unsigned long long)st.rays,
           (double)st.peak_bytes / (1 << 20), st.seconds, st.emitted, st.absorbed);
    rmesh_free(&m);
    scene_free(s);
    return 0;
}

/* bin/corrtex-render: the MPI job. `mpirun -np 1+T corrtex-render SCENE
 * [options]`: rank 0 runs the master (master/sched.h), ranks 1..T the tracer
 * loop (tracer/rank.h). Thin main: options, MPI start-up, the interactive
 * solution (radiosity cache or solve) and its broadcast, then the loops.
 * docs/distributed.md is the user guide. */
#include <errno.h>
#include <inttypes.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "common/log.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "master/ctex.h"
#include "master/dsrv.h"
#include "master/sampler.h"
#include "master/sched.h"
#include "proto/auth.h"
#include "proto/mpi_link.h"
#include "proto/wire.h"
#include "proto/xport.h"
#include "tracer/radiosity.h"
#include "tracer/rank.h"
#include "tracer/tracer.h"

#define PROG "corrtex-render"

/* The signal that asks the loops to end (0: none). */
static volatile int g_stop_int;

static void on_signal(int sig)
{
    g_stop_int = sig;
}

typedef struct opts {
    const char *scene;
    const char *listen;
    const char *token_file;
    const char *mesh;           /* use this .ctmesh as it is */
    const char *rad_cache;      /* cache file; default in the cache directory */
    trc_mode mode;
    int shadow_rays, branch, depth;   /* -1: the mode's default */
    int indirect, gather_rays;        /* -1: the default */
    uint64_t seed;
    int threads;
    unsigned idle_sleep_us;
    rad_params rad;
    rq_options rq;
    ctex_options ctex;
    sched_options sched;
} opts;

static void usage(FILE *f)
{
    rad_params rd;
    rad_params_default(&rd);
    fprintf(f,
            "usage: mpirun -np 1+T " PROG " SCENE.json [options]\n"
            "  Rank 0 is the master (request queue, corrective textures, display server),\n"
            "  ranks 1..T trace samples. A display connects with corrtex-display --connect ADDR.\n"
            "\n"
            "display socket:\n"
            "  --listen ADDR            unix:PATH or tcp:HOST:PORT (default unix:$XDG_RUNTIME_DIR/corrtex-PID.sock,\n"
            "                           or under /tmp; TCP needs a token)\n"
            "  --token-file FILE        shared token (else $%s); required on TCP, checked on UNIX when given\n"
            "  --exit-when-display-leaves  end the job when the display disconnects (batch runs)\n"
            "\n"
            "interactive solution:\n"
            "  --mesh FILE.ctmesh       use this radiosity mesh as it is (no cache check)\n"
            "  --rad-cache FILE         radiosity cache file (default $XDG_CACHE_HOME/corrtex/HASH.ctmesh,\n"
            "                           else ~/.cache/corrtex; recomputed when the scene or parameters change)\n"
            "  --rad-error E            link error threshold (default %g)\n"
            "  --rad-min-area A         smallest element, fraction of the surface (default %g)\n"
            "  --rad-max-triangles N    output mesh size target (default %u)\n"
            "  --rad-threads N          solver threads (default %d)\n"
            "\n"
            "tracers:\n"
            "  --mode M                 drt | reuse-diffuse | path (default drt)\n"
            "  --shadow-rays K          light samples per shading point (default: the mode's, drt 4)\n"
            "  --branch B               rays per glossy lobe (default: the mode's, drt 4)\n"
            "  --depth D                bounces (default: the mode's, drt 5)\n"
            "  --indirect I             drt's indirect light: mesh (read at the hit) | gather (final\n"
            "                           gather of the mesh, docs/tracer.md) (default gather)\n"
            "  --gather-rays G          rays of --indirect gather per shading point (default 4)\n"
            "  --seed S                 seed of every random stream (default 1)\n"
            "  --threads N              threads per tracer rank (default 1)\n"
            "  --idle-sleep-us U        longest sleep of an idle tracer between probes (default 1000; 0 spins)\n"
            "\n"
            "scheduling loop:\n",
            AUTH_TOKEN_ENV, rd.error, rd.min_area, rd.max_triangles, rd.threads);
    sched_options_usage(f);
    fprintf(f, "\nrequest queue (docs/sampling.md):\n");
    rq_options_usage(f);
    fprintf(f, "\ncorrective textures (docs/textures.md):\n");
    ctex_options_help(f);
    fprintf(f, "\n  --quiet, --verbose       log level\n  --help                   this text\n");
}

static int num(const char *name, const char *v, double lo, double hi, double *out, ct_error *err)
{
    char *end;
    errno = 0;
    double x = strtod(v, &end);
    if (errno || end == v || *end || !(x >= lo && x <= hi))
        return ct_fail(err, CT_EINVAL, "--%s: '%s' is not a number in [%g, %g]", name, v, lo, hi);
    *out = x;
    return 0;
}

/* Sets option a ("--name") to v: 0, 1 when there is no such option, or
 * negative for a bad value (err filled). */
static int set_option(opts *o, const char *a, const char *v, ct_error *err)
{
    const char *name = a + 2;
    double x;
    int rc = 0;
    if (!strcmp(name, "listen")) o->listen = v;
    else if (!strcmp(name, "token-file")) o->token_file = v;
    else if (!strcmp(name, "mesh")) o->mesh = v;
    else if (!strcmp(name, "rad-cache")) o->rad_cache = v;
    else if (!strcmp(name, "mode")) rc = trc_mode_parse(v, &o->mode, err);
    else if (!strcmp(name, "shadow-rays")) { if (!(rc = num(name, v, 1, 4096, &x, err))) o->shadow_rays = (int)x; }
    else if (!strcmp(name, "branch")) { if (!(rc = num(name, v, 1, 4096, &x, err))) o->branch = (int)x; }
    else if (!strcmp(name, "depth")) { if (!(rc = num(name, v, 1, 1024, &x, err))) o->depth = (int)x; }
    else if (!strcmp(name, "indirect")) {
        trc_indirect ind = TRC_INDIRECT_GATHER;
        if (!(rc = trc_indirect_parse(v, &ind, err))) o->indirect = (int)ind;
    }
    else if (!strcmp(name, "gather-rays")) { if (!(rc = num(name, v, 1, 4096, &x, err))) o->gather_rays = (int)x; }
    else if (!strcmp(name, "seed")) { if (!(rc = num(name, v, 0, 1.8e19, &x, err))) o->seed = (uint64_t)x; }
    else if (!strcmp(name, "threads")) { if (!(rc = num(name, v, 1, 64, &x, err))) o->threads = (int)x; }
    else if (!strcmp(name, "idle-sleep-us")) { if (!(rc = num(name, v, 0, 1e6, &x, err))) o->idle_sleep_us = (unsigned)x; }
    else if (!strcmp(name, "rad-error")) rc = num(name, v, 1e-15, 1.0, &o->rad.error, err);
    else if (!strcmp(name, "rad-min-area")) rc = num(name, v, 1e-15, 1.0, &o->rad.min_area, err);
    else if (!strcmp(name, "rad-max-triangles")) { if (!(rc = num(name, v, 1, 4e9, &x, err))) o->rad.max_triangles = (uint32_t)x; }
    else if (!strcmp(name, "rad-threads")) { if (!(rc = num(name, v, 1, 256, &x, err))) o->rad.threads = (int)x; }
    else {
        /* The engines' own options: the loop's, the textures', the queue's. */
        rc = sched_options_set(&o->sched, name, v, err);
        if (rc == 0) rc = ctex_options_parse(&o->ctex, a, v, err);
        if (rc == 0) return rq_options_has(name) ? rq_options_set(&o->rq, name, v, err) : 1;
        if (rc > 0) rc = 0;
    }
    return rc;
}

/* Parses argv into o; 1 for --help, 0 ok, negative with err filled. */
static int parse(int argc, char **argv, opts *o, ct_error *err)
{
    memset(o, 0, sizeof *o);
    o->mode = TRC_MODE_DRT;
    o->shadow_rays = o->branch = o->depth = -1;
    o->indirect = o->gather_rays = -1;
    o->seed = 1;
    o->threads = 1;
    o->idle_sleep_us = 1000;
    rad_params_default(&o->rad);
    rq_options_default(&o->rq);
    o->ctex = ctex_options_default();
    sched_options_default(&o->sched);
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) return 1;
        if (strcmp(a, "--quiet") == 0) { ct_log_set_level(CT_LOG_ERROR); continue; }
        if (strcmp(a, "--verbose") == 0) { ct_log_set_level(CT_LOG_DEBUG); continue; }
        if (strcmp(a, "--exit-when-display-leaves") == 0) { o->sched.exit_when_display_leaves = true; continue; }
        if (strncmp(a, "--", 2) != 0) {
            if (o->scene) return ct_fail(err, CT_EINVAL, "more than one scene file ('%s' and '%s')", o->scene, a);
            o->scene = a;
            continue;
        }
        if (i + 1 >= argc) {
            /* Given last: a dry run on a copy tells a missing value from an
             * option that does not exist. */
            opts scratch = *o;
            ct_error e;
            return ct_fail(err, CT_EINVAL, set_option(&scratch, a, "", &e) == 1 ? "unknown option '%s' (try --help)"
                                                                                 : "%s needs a value (try --help)", a);
        }
        int rc = set_option(o, a, argv[++i], err);
        if (rc == 1) return ct_fail(err, CT_EINVAL, "unknown option '%s' (try --help)", a);
        if (rc < 0) return rc;
    }
    if (!o->scene) return ct_fail(err, CT_EINVAL, "no scene file given (try --help)");
    int rc = rq_options_check(&o->rq, err);
    if (rc == 0) rc = rad_params_check(&o->rad, err);
    if (rc == 0 && o->sched.batch_min > o->sched.batch_max)
        rc = ct_fail(err, CT_EINVAL, "--batch-min %d is larger than --batch-max %d", o->sched.batch_min,
                     o->sched.batch_max);
    return rc;
}

static void cache_path(const opts *o, const ct_scene *s, char *out, size_t cap)
{
    if (o->rad_cache) {
        snprintf(out, cap, "%s", o->rad_cache);
        return;
    }
    char dir[900];
    const char *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    if (xdg && *xdg) snprintf(dir, sizeof dir, "%s/corrtex", xdg);
    else if (home && *home) snprintf(dir, sizeof dir, "%s/.cache/corrtex", home);
    else snprintf(dir, sizeof dir, "/tmp/corrtex-cache");
    char parent[900];
    snprintf(parent, sizeof parent, "%s", dir);
    char *slash = strrchr(parent, '/');
    if (slash && slash != parent) {
        *slash = 0;
        mkdir(parent, 0755);
    }
    mkdir(dir, 0755);
    snprintf(out, cap, "%s/%016" PRIx64 ".ctmesh", dir, rad_solution_hash(s, &o->rad));
}

static void on_progress(void *user, double fraction, const char *what)
{
    (void)user;
    ct_progress("radiosity", fraction, 0, "%s", what);
}

/* Rank 0: the interactive solution from --mesh, the cache, or a solve. */
static int get_mesh(const opts *o, const ct_scene *s, ct_radmesh *m, ct_error *err)
{
    if (o->mesh) return rmesh_load(o->mesh, 0, m, err);
    char path[1024];
    cache_path(o, s, path, sizeof path);
    uint64_t h = rad_solution_hash(s, &o->rad);
    ct_error e;
    int rc = rmesh_load(path, h, m, &e);
    if (rc == 0) {
        ct_info(PROG, "radiosity mesh from the cache %s (%u triangles)", path, m->ntris);
        return 0;
    }
    if (rc == CT_ESTALE) ct_info(PROG, "radiosity cache %s is stale: solving again", path);
    else ct_info(PROG, "no radiosity cache at %s: solving", path);
    rad_stats st;
    rc = rad_solve(s, &o->rad, ct_log_get_level() >= CT_LOG_INFO ? on_progress : NULL, NULL, m, &st, err);
    if (ct_log_get_level() >= CT_LOG_INFO) ct_progress("radiosity", 1.0, 1, "%s", rc ? "failed" : "done");
    if (rc) return rc;
    if (rmesh_save(m, path, &e) != 0) ct_warn(PROG, "cannot write the radiosity cache: %s", e.msg);
    else ct_info(PROG, "radiosity mesh (%u triangles, %.1f s) cached in %s", m->ntris, st.seconds, path);
    return 0;
}

/* Set when the loop failed in MPI or lost a tracer: the ranks cannot end in
 * order (MPI_Finalize would wait for the silent one). */
static int g_need_abort;

static int run_master(const opts *o, int ntracers, ct_error *err)
{
    ct_scene *scene = NULL;
    ct_radmesh mesh;
    memset(&mesh, 0, sizeof mesh);
    wire_scene_tx tx;
    memset(&tx, 0, sizeof tx);
    auth_token token;
    bool have_token = false;
    char listen[XPORT_ADDR_LEN];
    if (o->listen) snprintf(listen, sizeof listen, "%s", o->listen);
    else dsrv_default_listen(listen, sizeof listen);
    /* The display socket's configuration first: TCP without a token used to
     * be refused only after the radiosity solve and the broadcast. */
    int rc = auth_token_get(o->token_file, &token, &have_token, err);
    if (rc == 0) {
        dsrv_config dc = {.listen = listen, .token = have_token ? &token : NULL};
        rc = dsrv_check_config(&dc, err);
    }
    if (rc == 0) rc = scene_load(o->scene, &scene, err);
    if (rc == 0) rc = get_mesh(o, scene, &mesh, err);
    if (rc == 0) rc = wire_scene_tx_init(&tx, &mesh, err);
    /* Everyone learns whether the master could start, so nobody waits for a
     * broadcast that never comes. */
    int status = rc ? 1 : 0;
    ct_error e;
    if (mpil_allreduce_max(&status, &e) != 0) {
        *err = e;
        rc = CT_EIO;
    }
    if (rc == 0 && status == 0) {
        uint64_t h = scene->source_hash;
        wire_buf payload = {tx.raw, (size_t)tx.raw_size, (size_t)tx.raw_size};
        rc = mpil_bcast_u64(0, &h, err);
        if (rc == 0) rc = mpil_bcast(0, &payload, err);
        ct_info(PROG, "sent the radiosity mesh (%u triangles, %.1f MiB) to %d tracer rank%s", mesh.ntris,
                tx.raw_size / 1048576.0, ntracers, ntracers == 1 ? "" : "s");
    }
    if (rc == 0 && status == 0) {
        /* Did every tracer build its scene? */
        int tstatus = 0;
        rc = mpil_allreduce_max(&tstatus, err);
        if (rc == 0 && tstatus) rc = ct_fail(err, CT_EINVAL, "a tracer rank could not start (see its log line)");
    }
    if (rc == 0 && status == 0) {
        sched_config c = {.scene = scene,
                          .mesh = &mesh,
                          .ntracers = ntracers,
                          .rq = &o->rq,
                          .ctex = &o->ctex,
                          .seed = o->seed,
                          .opt = o->sched,
                          .listen = listen,
                          .token = have_token ? &token : NULL,
                          .stop = &g_stop_int};
        rc = sched_run(&c, err);
        if (rc == CT_EIO) g_need_abort = 1;
    }
    if (have_token) auth_token_wipe(&token);
    wire_scene_tx_free(&tx);
    rmesh_free(&mesh);
    scene_free(scene);
    return rc;
}

static int run_tracer(const opts *o, int rank, ct_error *err)
{
    int status = 0;
    if (mpil_allreduce_max(&status, err)) return CT_EIO;
    if (status) return 0;   /* the master could not start: it says why, and its status is the job's */
    ct_scene *scene = NULL;
    ct_radmesh mesh;
    memset(&mesh, 0, sizeof mesh);
    trc_tracer *t = NULL;
    uint64_t h = 0;
    wire_buf payload = {0};
    int rc = mpil_bcast_u64(0, &h, err);
    if (rc == 0) rc = mpil_bcast(0, &payload, err);
    if (rc) return rc;   /* MPI itself failed: nothing collective is possible */
    char host[256];
    mpil_host(host, sizeof host);
    rc = scene_load(o->scene, &scene, err);
    if (rc == 0 && scene->source_hash != h)
        rc = ct_fail(err, CT_ESTALE, "rank %d on %s: %s differs from the master's copy (hash %016" PRIx64
                     " vs %016" PRIx64 ")", rank, host, o->scene, scene->source_hash, h);
    char peer[64];
    snprintf(peer, sizeof peer, "master broadcast (rank %d)", rank);
    if (rc == 0) rc = wire_scene_parse(payload.data, payload.len, peer, &mesh, err);
    wire_buf_free(&payload);
    trc_options to;
    trc_options_default(&to, o->mode);
    to.seed = o->seed;
    if (o->shadow_rays > 0) to.shadow_rays = o->shadow_rays;
    if (o->branch > 0) to.branch = o->branch;
    if (o->depth > 0) to.depth = o->depth;
    if (o->indirect >= 0) to.indirect = (trc_indirect)o->indirect;
    if (o->gather_rays > 0) to.gather_rays = o->gather_rays;
    if (rc == 0) rc = trc_new(scene, &mesh, &to, &t, err);
    if (rc) ct_log(CT_LOG_ERROR, PROG, "tracer rank %d on %s: %s", rank, host, err->msg);
    int bad = rc ? 1 : 0;
    ct_error e;
    if (mpil_allreduce_max(&bad, &e) == 0 && bad == 0) {
        ct_debug(PROG, "tracer rank %d on %s ready (%s)", rank, host, trc_mode_name(o->mode));
        trank_config tc = {.tracer = t, .rank = rank, .threads = o->threads, .idle_sleep_us = o->idle_sleep_us,
                           .stop = &g_stop_int};
        trank_stats st;
        rc = trank_run(&tc, &st, err);
        if (rc) {
            ct_log(CT_LOG_ERROR, PROG, "tracer rank %d on %s: %s", rank, host, err->msg);
            /* The master waits for this rank: end the whole job. */
            mpil_abort(1);
        }
    }
    trc_free(t);
    rmesh_free(&mesh);
    scene_free(scene);
    return rc ? 1 : 0;
}

int main(int argc, char **argv)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);

    ct_error err;
    ct_error_clear(&err);
    int rank = 0, size = 0;
    if (mpil_init(&argc, &argv, &rank, &size, &err) != 0) {
        ct_log(CT_LOG_ERROR, PROG, "%s", err.msg);
        return 1;
    }
    opts o;
    int prc = parse(argc, argv, &o, &err);
    if (prc != 0 || size < 2) {
        if (rank == 0) {
            if (prc == 1) usage(stdout);
            else if (prc < 0) ct_log(CT_LOG_ERROR, PROG, "%s", err.msg);
            else ct_log(CT_LOG_ERROR, PROG, "needs at least one tracer rank: mpirun -np 2 (or more) %s SCENE", PROG);
        }
        mpil_finalize(&err);
        return prc == 1 ? 0 : 2;
    }
    if (rank != 0) {
        int rc = run_tracer(&o, rank, &err);
        ct_error e;
        mpil_finalize(&e);
        return rc;
    }
    int rc = run_master(&o, size - 1, &err);
    if (rc) ct_log(CT_LOG_ERROR, PROG, "%s", err.msg);
    if (g_need_abort) {
        mpil_abort(1);
        return 1;
    }
    ct_error e;
    if (mpil_finalize(&e) != 0) ct_warn(PROG, "%s", e.msg);
    if (rc == 0) return 0;
    /* Bad input (options, scene, token, an unreadable scene file): 2. */
    return rc == CT_EINVAL || rc == CT_EPARSE || rc == CT_EEMPTY || rc == CT_EAUTH || rc == CT_ESTALE ||
                   (rc == CT_EIO && !g_need_abort)
               ? 2
               : 1;
}

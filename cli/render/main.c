/* bin/corrtex-render: the MPI job. `mpirun -np 1+T corrtex-render SCENE
 * [options]`: rank 0 runs the master (master/sched.h), ranks 1..T the tracer
 * loop (tracer/rank.h). Thin main: options, MPI start-up, the interactive
 * solution (radiosity cache or solve) and its broadcast, then the loops.
 * docs/distributed.md is the user guide. */
#include <inttypes.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "common/fsutil.h"
#include "common/log.h"
#include "common/optab.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/version.h"
#include "master/ctex.h"
#include "master/dsrv.h"
#include "master/sampler.h"
#include "master/sched.h"
#include "proto/auth.h"
#include "proto/mpi_link.h"
#include "proto/tport.h"
#include "proto/wire.h"
#include "proto/xport.h"
#include "radiosity/radiosity.h"
#include "tracer/rank.h"
#include "tracer/tracer.h"
#include "tracer/trc_cli.h"

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
    trc_cli trc;                /* the tracer's mode and options */
    uint64_t seed;
    int threads;
    int idle_sleep_us;
    bool quiet, verbose, version;
    rad_params rad;
    rq_options rq;
    ctex_options ctex;
    sched_options sched;
    drv_options drive;
    sess_options session;
} opts;

#define OF(f) offsetof(opts, f)
static const optab SOCKET_OPTS[] = {
    {"listen", 0, OPTAB_STRING, OF(listen), 0, 0, NULL, "ADDR",
     "unix:PATH or tcp:HOST:PORT (default unix:$XDG_RUNTIME_DIR/corrtex-PID.sock, or under /tmp; TCP needs a token)",
     NULL},
    {"token-file", 0, OPTAB_STRING, OF(token_file), 0, 0, NULL, "FILE",
     "shared token (else $" AUTH_TOKEN_ENV "); required on TCP, checked on UNIX when given", NULL},
};
static const optab MESH_OPTS[] = {
    {"mesh", 0, OPTAB_STRING, OF(mesh), 0, 0, NULL, "FILE.ctmesh", "use this radiosity mesh as it is (no cache check)",
     NULL},
    {"rad-cache", 0, OPTAB_STRING, OF(rad_cache), 0, 0, NULL, "FILE",
     "radiosity cache file, in a folder that exists (default $XDG_CACHE_HOME/corrtex/HASH.ctmesh, else "
     "~/.cache/corrtex, made when missing; recomputed when the scene or parameters change); not with --mesh",
     NULL},
    {"rad-error", 0, OPTAB_DOUBLE, OF(rad.error), 1e-15, 1.0, NULL, "E",
     "link error threshold; this and the --rad-* below: not with --mesh", NULL},
    {"rad-min-area", 0, OPTAB_DOUBLE, OF(rad.min_area), 1e-15, 1.0, NULL, "A",
     "smallest element, fraction of the lit surface (corrtex radiosity --min-area)", NULL},
    {"rad-dim-floor", 0, OPTAB_DOUBLE, OF(rad.dim_floor), 0, 1.0, NULL, "F",
     "dim receivers refined down to F times the threshold (0: one threshold; corrtex radiosity --dim-floor)", NULL},
    {"rad-max-triangles", 0, OPTAB_U32, OF(rad.max_triangles), 1, 4e9, NULL, "N", "output mesh size target", NULL},
    {"rad-threads", 0, OPTAB_INT, OF(rad.threads), 1, 256, NULL, "N", "solver threads", NULL},
};
static const optab TRACER_OPTS[] = {
    {"seed", 0, OPTAB_U64, OF(seed), 0, 1.8446744073709552e19, "1", "S", "seed of every random stream", NULL},
    {"threads", 0, OPTAB_INT, OF(threads), 1, 64, "1", "N", "threads per tracer rank", NULL},
    {"idle-sleep-us", 0, OPTAB_INT, OF(idle_sleep_us), 0, 1000000, "1000", "U",
     "longest sleep of an idle tracer between probes (0 spins)", NULL},
};
static const optab LOG_OPTS[] = {
    {"quiet", 'q', OPTAB_FLAG, OF(quiet), 0, 0, NULL, NULL, "errors only", NULL},
    {"verbose", 0, OPTAB_FLAG, OF(verbose), 0, 0, NULL, NULL, "debug lines too", NULL},
    {"version", 0, OPTAB_FLAG, OF(version), 0, 0, NULL, NULL, "print the version and the git commit, and exit",
     NULL},
};
#undef OF

/* The option groups, in --help order. */
enum { NGROUPS = 11 };
static void groups(opts *o, optab_group *g)
{
    size_t n;
    const optab *t;
    int k = 0;
    g[k++] = (optab_group){SOCKET_OPTS, OPTAB_COUNT(SOCKET_OPTS), o};
    t = sched_options_table(&n);
    g[k++] = (optab_group){t, n, &o->sched};
    g[k++] = (optab_group){MESH_OPTS, OPTAB_COUNT(MESH_OPTS), o};
    t = trc_cli_table(&n);
    g[k++] = (optab_group){t, n, &o->trc};
    g[k++] = (optab_group){TRACER_OPTS, OPTAB_COUNT(TRACER_OPTS), o};
    t = drv_options_table(&n);
    g[k++] = (optab_group){t, n, &o->drive};
    t = sess_options_table(&n);
    g[k++] = (optab_group){t, n, &o->session};
    t = rq_options_table(&n);
    g[k++] = (optab_group){t, n, &o->rq};
    t = ctex_options_table(&n);
    g[k++] = (optab_group){t, n, &o->ctex};
    g[k++] = (optab_group){LOG_OPTS, OPTAB_COUNT(LOG_OPTS), o};
    g[k++] = (optab_group){NULL, 0, NULL};
}

static const char *const GROUP_TITLES[NGROUPS] = {
    "display socket", NULL, "interactive solution", "tracers", NULL, "scheduling loop", NULL,
    "request queue (docs/sampling.md)", "corrective textures (docs/textures.md)", "log", NULL};

/* Every option's default. */
static void defaults(opts *o)
{
    memset(o, 0, sizeof *o);
    optab_group g[NGROUPS];
    groups(o, g);
    ct_error e;
    for (int k = 0; g[k].rows; k++) optab_defaults(g[k].rows, g[k].n, g[k].base, &e);
    rad_params_default(&o->rad);   /* the solver's own defaults (rows without one) */
}

static void usage(FILE *f)
{
    opts d;
    defaults(&d);
    fprintf(f, "usage: mpirun -np 1+T " PROG " SCENE.json [options]\n"
               "  Rank 0 is the master (request queue, corrective textures, display server),\n"
               "  ranks 1..T trace samples. A display connects with corrtex-display --connect ADDR.\n");
    optab_group g[NGROUPS];
    groups(&d, g);
    for (int k = 0; g[k].rows; k++) {
        if (GROUP_TITLES[k]) fprintf(f, "\n%s:\n", GROUP_TITLES[k]);
        optab_usage(g[k].rows, g[k].n, g[k].base, f);
    }
    fprintf(f, "  --help                       this text\n");
}

/* Parses argv into o; 1 for --help, 2 for --version, 0 ok, negative with
 * err filled. */
static int parse(int argc, char **argv, opts *o, ct_error *err)
{
    defaults(o);
    optab_group g[NGROUPS];
    groups(o, g);
    const char *pos[1];
    int npos = 0;
    int rc = optab_parse(g, NGROUPS - 1, argc, argv, pos, 1, &npos, err);
    if (rc) return rc;
    if (o->version) return 2;
    if (o->quiet) ct_log_set_level(CT_LOG_ERROR);
    if (o->verbose) ct_log_set_level(CT_LOG_DEBUG);
    if (!npos) return ct_fail(err, CT_EINVAL, "no scene file given (try --help)");
    o->scene = pos[0];
    /* A given mesh is used as it is: nothing is solved, so the cache was
     * neither read nor written, without a word. */
    if (o->mesh && o->rad_cache)
        return ct_fail(err, CT_EINVAL,
                       "--rad-cache is the cache of the radiosity solve: not with --mesh (a given mesh is used as it "
                       "is, nothing is solved)");
    /* The same for the solver's parameters: they were dropped without a word. */
    static const char *const SOLVE_OPTS[] = {"rad-error", "rad-min-area", "rad-dim-floor", "rad-max-triangles",
                                             "rad-threads"};
    for (size_t i = 0; o->mesh && i < OPTAB_COUNT(SOLVE_OPTS); i++)
        if (optab_given(g, NGROUPS - 1, argc, argv, SOLVE_OPTS[i]))
            return ct_fail(err, CT_EINVAL,
                           "--%s is a parameter of the radiosity solve: not with --mesh (a given mesh is used as it "
                           "is, nothing is solved)", SOLVE_OPTS[i]);
    rc = rq_options_check(&o->rq, err);
    if (rc == 0) rc = rad_params_check(&o->rad, err);
    if (rc == 0) rc = trc_cli_check(&o->trc, err);
    if (rc == 0 && o->drive.batch_min > o->drive.batch_max)
        rc = ct_fail(err, CT_EINVAL, "--batch-min %d is larger than --batch-max %d", o->drive.batch_min,
                     o->drive.batch_max);
    return rc;
}

/* --rad-cache, else the default cache that corrtex radiosity also fills
 * (rad_cache_default); 0 when there is none to use (a warning says why). */
static int cache_path(const opts *o, const ct_scene *s, char *out, size_t cap)
{
    if (o->rad_cache) {
        snprintf(out, cap, "%s", o->rad_cache);
        return 1;
    }
    ct_error e;
    if (rad_cache_default(s, &o->rad, 1, out, cap, &e) == CT_OK) return 1;
    ct_warn(PROG, "no radiosity cache: %s", e.msg);
    return 0;
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
    char path[4096];
    int cached = cache_path(o, s, path, sizeof path);
    uint64_t h = rad_solution_hash(s, &o->rad);
    ct_error e;
    int rc = cached ? rmesh_load(path, h, m, &e) : CT_EIO;
    if (rc == 0) {
        ct_info(PROG, "radiosity mesh from the cache %s (%u triangles)", path, m->ntris);
        return 0;
    }
    if (!cached) ct_info(PROG, "solving the radiosity");
    else if (rc == CT_ESTALE) ct_info(PROG, "radiosity cache %s is stale: solving again", path);
    else ct_info(PROG, "no radiosity cache at %s: solving", path);
    rad_stats st;
    rc = rad_solve(s, &o->rad, ct_log_get_level() >= CT_LOG_INFO ? on_progress : NULL, NULL, m, &st, err);
    if (ct_log_get_level() >= CT_LOG_INFO) ct_progress("radiosity", 1.0, 1, "%s", rc ? "failed" : "done");
    if (rc) return rc;
    if (!cached) ct_info(PROG, "radiosity mesh (%u triangles, %.1f s)", m->ntris, st.seconds);
    else if (rmesh_save(m, path, &e) != 0) ct_warn(PROG, "cannot write the radiosity cache: %s", e.msg);
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
    /* A cache file named on the command line is an output file: its folder
     * must exist (docs/architecture.md, "Outputs"). It used to be found
     * missing only after the solve, as a warning that nothing was cached. */
    if (rc == 0 && o->rad_cache) rc = fs_output_folder_check(o->rad_cache, err);
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
    tport *port = NULL;
    if (rc == 0 && status == 0) rc = tport_mpi_new(ntracers, &port, err);
    if (rc == 0 && status == 0) {
        sched_config c = {.scene = scene,
                          .mesh = &mesh,
                          .port = port,
                          .rq = &o->rq,
                          .ctex = &o->ctex,
                          .seed = o->seed,
                          .opt = o->sched,
                          .drive = o->drive,
                          .session = o->session,
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
    trc_cli_apply(&o->trc, &to);
    to.seed = o->seed;
    if (rc == 0) rc = trc_new(scene, &mesh, &to, &t, err);
    if (rc == CT_ESTALE && o->mesh) ct_error_prefix(err, o->mesh);   /* (it does not belong to the scene) */
    if (rc) ct_log(CT_LOG_ERROR, PROG, "tracer rank %d on %s: %s", rank, host, err->msg);
    int bad = rc ? 1 : 0;
    ct_error e;
    if (mpil_allreduce_max(&bad, &e) == 0 && bad == 0) {
        ct_debug(PROG, "tracer rank %d on %s ready (%s)", rank, host, trc_mode_name((trc_mode)o->trc.mode));
        trank_config tc = {.tracer = t, .rank = rank, .threads = o->threads, .idle_sleep_us = (unsigned)o->idle_sleep_us,
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
            else if (prc == 2) ct_version_print(PROG, stdout);
            else if (prc < 0) ct_log(CT_LOG_ERROR, PROG, "%s", err.msg);
            else ct_log(CT_LOG_ERROR, PROG, "needs at least one tracer rank: mpirun -np 2 (or more) %s SCENE", PROG);
        }
        mpil_finalize(&err);
        return prc > 0 ? 0 : 2;
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

/* sched.h: the master of corrtex-render (rank 0): the adapter between the
 * display socket (dsrv.h, dsink.h) and the tracer ranks (the MPI port,
 * proto/tport.h) around the master's loop (drive.h) and session
 * (session.h). Display events become views and lockstep frame requests;
 * the loop runs until a signal, the display leaving (with
 * exit_when_display_leaves) or a failure, printing stats and watching for
 * silent tracers. Owns the sched_ prefix; docs/distributed.md describes it. */
#ifndef CT_MASTER_SCHED_H
#define CT_MASTER_SCHED_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/error.h"
#include "common/optab.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "master/ctex.h"
#include "master/drive.h"
#include "master/sampler.h"
#include "master/session.h"
#include "proto/auth.h"
#include "proto/tport.h"

/* Tunables of the display side and the loop's pace (sched_options_table). */
typedef struct sched_options {
    double patch_ms;            /* free-running: interval between texture updates to the display */
    double patch_share;         /* free-running: the most of the master's time the updates may take */
    double stats_s;             /* interval of the stats line and STATS message */
    int handshake_ms;           /* a display must finish its handshake within this */
    int send_timeout_ms;        /* a display whose full queue does not drain for this long is dropped */
    double tracer_timeout_s;    /* a tracer silent this long with work outstanding ends the job */
    int idle_ms;                /* poll timeout while there is nothing to do */
    size_t queue_mb;            /* display send queue bound, MiB */
    int patch_encoding;         /* TEX_PATCH texels: wire_patch_enc, or -1: by transport (dsync.h) */
    int display_texels;         /* 1: at most one texel a screen pixel to the display, 0: all, -1: by transport (dsync.h) */
    double view_ms;             /* free running: shortest interval between two camera changes */
    double view_share;          /* free running: the most of the master's time camera changes may take */
    bool exit_when_display_leaves;
} sched_options;

/* The option table. */
const optab *sched_options_table(size_t *n);

typedef struct sched_config {
    const ct_scene *scene;
    const ct_radmesh *mesh;
    tport *port;                /* the tracers (kept by the caller; closed by sched_run) */
    const rq_options *rq;
    const ctex_options *ctex;
    uint64_t seed;
    sched_options opt;
    drv_options drive;
    sess_options session;
    const char *listen;         /* unix:PATH | tcp:HOST:PORT */
    const auth_token *token;    /* NULL: none */
    volatile int *stop;         /* signal number that asks to stop, 0 = go on */
} sched_config;

/* Runs until a signal, the display leaving (with exit_when_display_leaves),
 * or a failure; tells the display, closes the port (the tracers get
 * SHUTDOWN), then returns (0 or a negative code with err filled). The caller
 * ends MPI. */
int sched_run(const sched_config *c, ct_error *err);

#endif

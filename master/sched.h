/* sched.h: the master's scheduling loop (rank 0 of corrtex-render): serves
 * the display socket (dsrv.h) and the tracer ranks (proto/mpi_link.h) at
 * once, drives the request queue (sampler.h) and the corrective textures
 * (ctex.h), and streams texture events to the display. Free-running mode
 * keeps a window of adaptively sized batches in flight per tracer; lockstep
 * mode (the display's SETTINGS ask for K samples per frame) answers every
 * CAMERA with exactly K samples in fixed-size rounds inserted in request-id
 * order, then FRAME, so its images do not depend on the number of tracers.
 * Owns the sched_ prefix; docs/distributed.md describes the loop. */
#ifndef CT_MASTER_SCHED_H
#define CT_MASTER_SCHED_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "common/error.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "master/ctex.h"
#include "master/sampler.h"
#include "proto/auth.h"

/* Tunables of the loop (sched_options_default; every one is an option). */
typedef struct sched_options {
    int window;                 /* request batches in flight per tracer */
    int batch_min, batch_max;   /* free-running batch size bounds (requests) */
    double batch_ms;            /* free-running: target tracing time of one batch */
    int round;                  /* lockstep: requests per round (independent of the tracer count) */
    double patch_ms;            /* free-running: interval between texture updates to the display */
    double stats_s;             /* interval of the stats line and STATS message */
    int handshake_ms;           /* a display must finish its handshake within this */
    int send_timeout_ms;        /* a display whose full queue does not drain for this long is dropped */
    double tracer_timeout_s;    /* a tracer silent this long with work outstanding ends the job */
    int idle_ms;                /* poll timeout while there is nothing to do */
    size_t queue_mb;            /* display send queue bound, MiB */
    int patch_encoding;         /* TEX_PATCH texels: wire_patch_enc, or -1: by transport (dsync.h) */
    bool exit_when_display_leaves;
} sched_options;

typedef struct sched_config {
    const ct_scene *scene;
    const ct_radmesh *mesh;
    int ntracers;               /* ranks 1..ntracers */
    const rq_options *rq;
    const ctex_options *ctex;
    uint64_t seed;
    sched_options opt;
    const char *listen;         /* unix:PATH | tcp:HOST:PORT */
    const auth_token *token;    /* NULL: none */
    volatile int *stop;         /* signal number that asks to stop, 0 = go on */
} sched_config;

/* The defaults. */
void sched_options_default(sched_options *o);

/* Sets one option by its name without "--"; 1 when it is one of ours, 0 when
 * not, negative for a bad value. */
int sched_options_set(sched_options *o, const char *name, const char *value, ct_error *err);

/* One "--name VALUE  help (default X)" line per option. */
void sched_options_usage(FILE *f);

/* Runs until a signal, the display leaving (with exit_when_display_leaves),
 * or a failure; tells the display and the tracers, then returns (0 or a
 * negative code with err filled). The caller ends MPI. */
int sched_run(const sched_config *c, ct_error *err);

#endif

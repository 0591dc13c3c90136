/* rank.h: the main loop of a tracer rank (ranks 1..T of corrtex-render):
 * receives request batches from the master over MPI (proto/mpi_link.h),
 * traces them with the per-sample API (tracer.h), optionally on several
 * threads, and sends the sample batches back. Camera changes raise the
 * rank's epoch. Once a batch of the newer view has come, queued batches of
 * older epochs are answered empty without tracing and the batch being
 * traced stops at its next slice, answering with the samples traced so far:
 * a new view's requests reach the tracing within one slice, no traced
 * sample is thrown away, and the rank never waits idle while it holds
 * requests of an older view. Owns the trank_ prefix. docs/distributed.md
 * describes the loop. */
#ifndef CT_TRACER_RANK_H
#define CT_TRACER_RANK_H

#include <stdint.h>

#include "common/error.h"
#include "tracer/tracer.h"

typedef struct trank_config {
    const trc_tracer *tracer;   /* built from the broadcast mesh */
    int rank;                   /* this rank (>= 1) */
    int threads;                /* threads tracing one batch (>= 1) */
    unsigned idle_sleep_us;     /* sleep between probes while idle (0: spin) */
    volatile int *stop;         /* set by a signal handler: leave the loop */
} trank_config;

typedef struct trank_stats {
    uint64_t batches;           /* request batches answered */
    uint64_t gave_way;     /* gave way to a newer view: answered empty, or with what was traced when stopped */
    uint64_t requests;          /* requests received (those of batches that gave way partly untraced) */
    uint64_t samples;           /* samples traced */
    uint64_t rays;              /* rays traced (primary, secondary and shadow) */
    double busy_s;              /* seconds spent tracing */
} trank_stats;

/* Runs until the master sends SHUTDOWN (0), *stop is set (0), or an MPI or
 * protocol error (negative, err filled). */
int trank_run(const trank_config *c, trank_stats *st, ct_error *err);

#endif

/* pool.h: the one pool of worker threads behind every fan-out (a tracer
 * rank's batch, the reference renderer's tiles, corrtex converge and naive,
 * the master's insertion and its item buffer, the radiosity solver's
 * refinement passes, iterations and final gather, its view renders): a
 * parallel loop over tasks
 * [0, n) in which the calling thread takes part, tasks handed out one at a
 * time by an atomic counter so that uneven tasks balance, workers asleep on
 * a condition variable between loops. One loop at a time, started from one
 * thread; a task must not start another. Beside the loops, one *side job*
 * at a time: a function one worker runs while the caller goes on (its own
 * loops then run on the other threads; the worker joins them when the job
 * is done), so that two independent stages of work overlap. Owns the pool_
 * prefix. */
#ifndef CT_COMMON_POOL_H
#define CT_COMMON_POOL_H

#include <stddef.h>

#include "common/error.h"

/* Largest pool (threads, the caller included). */
#define POOL_MAX_THREADS 256

typedef struct ct_pool ct_pool;

/* A task: `worker` is 0 for the calling thread and 1 .. threads-1 for the
 * pool's own, so it can index per-thread scratch; `task` is in [0, n). */
typedef void (*pool_fn)(void *ctx, int worker, size_t task);

/* A pool of `threads` threads in all (the caller and threads - 1 workers,
 * 1 .. POOL_MAX_THREADS). CT_ESYS when a worker cannot be started. */
int pool_new(int threads, ct_pool **out, ct_error *err);

/* Stops and joins the workers (NULL is fine). */
void pool_free(ct_pool *p);

/* Threads of p, the caller included (1 for NULL). */
int pool_threads(const ct_pool *p);

/* Runs fn(ctx, worker, i) for every i in [0, n) and returns when all are
 * done. With p NULL (or one thread) the caller runs them in order. */
void pool_run(ct_pool *p, size_t n, pool_fn fn, void *ctx);

/* A side job. */
typedef void (*pool_side_fn)(void *ctx);

/* Hands fn(ctx) to one worker and returns at once; with p NULL or one
 * thread the caller runs it before returning. Until pool_side_wait the
 * caller must not touch what the side job touches, and the side job must
 * not start loops. One at a time: a second pool_side waits for the first. */
void pool_side(ct_pool *p, pool_side_fn fn, void *ctx);

/* Returns once the side job (if any) is done; its writes are then visible. */
void pool_side_wait(ct_pool *p);

/* The cores this process may run on (its CPU affinity), at least 1. */
int pool_cpus(void);

#endif

/* pool.c: the thread pool (pool.h). A loop is a generation: pool_run
 * publishes the task function and count, bumps the generation and wakes the
 * workers; everyone takes task numbers from one atomic word that holds the
 * generation beside the next task number, so a worker that wakes late (its
 * core busy with another process) can never take a task of a later loop
 * with the function of an earlier one; the caller returns as soon as every
 * task is done, without waiting for workers that found nothing left to do.
 * (Waiting for every worker to check in cost the master's insertion more
 * than the second thread gave on a 2-core machine shared with a display:
 * docs/benchmarks.md, "Master: saturation".) */
#include "common/pool.h"

#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>

typedef struct worker {
    ct_pool *p;
    int id;
    pthread_t th;
} worker;

/* One loop as a worker copies it. */
typedef struct job {
    pool_fn fn;
    void *ctx;
    size_t ntasks;
    uint32_t gen;
} job;

struct ct_pool {
    int n;                      /* threads, the caller included */
    worker *w;                  /* n - 1 workers */
    pthread_mutex_t mu;
    pthread_cond_t go, done;
    job cur;                    /* the current loop (mu) */
    int stop;                   /* (mu) */
    atomic_uint_fast64_t next;  /* generation << 32 | next task number */
    atomic_size_t finished;     /* tasks of the current loop done */
    pool_side_fn side_fn;       /* the side job (mu) */
    void *side_ctx;
    int side_state;             /* (mu) SIDE_* */
    pthread_cond_t side_done;
};

enum { SIDE_NONE, SIDE_PENDING, SIDE_RUNNING };

/* Takes and runs tasks of loop j until none is left or a later loop began. */
static void take_tasks(ct_pool *p, const job *j, int id)
{
    uint_fast64_t v = atomic_load_explicit(&p->next, memory_order_acquire);
    for (;;) {
        if ((uint32_t)(v >> 32) != j->gen || (v & 0xffffffffu) >= j->ntasks) return;
        if (!atomic_compare_exchange_weak_explicit(&p->next, &v, v + 1, memory_order_acq_rel, memory_order_acquire))
            continue;
        j->fn(j->ctx, id, (size_t)(v & 0xffffffffu));
        if (atomic_fetch_add_explicit(&p->finished, 1, memory_order_acq_rel) + 1 == j->ntasks) {
            pthread_mutex_lock(&p->mu);
            pthread_cond_signal(&p->done);
            pthread_mutex_unlock(&p->mu);
        }
        v = atomic_load_explicit(&p->next, memory_order_acquire);
    }
}

static void *worker_main(void *arg)
{
    worker *w = arg;
    ct_pool *p = w->p;
    uint32_t seen = 0;
    pthread_mutex_lock(&p->mu);
    for (;;) {
        while (p->cur.gen == seen && p->side_state != SIDE_PENDING && !p->stop) pthread_cond_wait(&p->go, &p->mu);
        if (p->stop) break;
        if (p->side_state == SIDE_PENDING) {
            /* The side job first: the caller is waiting for it last. Loops
             * published meanwhile are joined after, if any task is left. */
            p->side_state = SIDE_RUNNING;
            pool_side_fn fn = p->side_fn;
            void *ctx = p->side_ctx;
            pthread_mutex_unlock(&p->mu);
            fn(ctx);
            pthread_mutex_lock(&p->mu);
            p->side_state = SIDE_NONE;
            pthread_cond_broadcast(&p->side_done);
            continue;
        }
        job j = p->cur;
        seen = j.gen;
        pthread_mutex_unlock(&p->mu);
        take_tasks(p, &j, w->id);
        pthread_mutex_lock(&p->mu);
    }
    pthread_mutex_unlock(&p->mu);
    return NULL;
}

int pool_new(int threads, ct_pool **out, ct_error *err)
{
    *out = NULL;
    if (threads < 1 || threads > POOL_MAX_THREADS)
        return ct_fail(err, CT_EINVAL, "thread pool of %d threads outside 1..%d", threads, POOL_MAX_THREADS);
    ct_pool *p = calloc(1, sizeof *p);
    if (!p) return ct_fail(err, CT_ENOMEM, "out of memory for a thread pool");
    p->n = 1;
    pthread_mutex_init(&p->mu, NULL);
    pthread_cond_init(&p->go, NULL);
    pthread_cond_init(&p->done, NULL);
    pthread_cond_init(&p->side_done, NULL);
    atomic_init(&p->next, 0);
    atomic_init(&p->finished, 0);
    if (threads > 1) {
        p->w = calloc((size_t)threads - 1, sizeof *p->w);
        if (!p->w) {
            pool_free(p);
            return ct_fail(err, CT_ENOMEM, "out of memory for a thread pool");
        }
    }
    for (int i = 1; i < threads; i++) {
        worker *w = &p->w[i - 1];
        w->p = p;
        w->id = i;
        if (pthread_create(&w->th, NULL, worker_main, w) != 0) {
            pool_free(p);
            return ct_fail(err, CT_ESYS, "cannot start worker thread %d of %d", i + 1, threads);
        }
        p->n = i + 1;
    }
    *out = p;
    return CT_OK;
}

void pool_free(ct_pool *p)
{
    if (!p) return;
    pool_side_wait(p);
    pthread_mutex_lock(&p->mu);
    p->stop = 1;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->mu);
    for (int i = 1; i < p->n; i++) pthread_join(p->w[i - 1].th, NULL);
    pthread_cond_destroy(&p->go);
    pthread_cond_destroy(&p->done);
    pthread_cond_destroy(&p->side_done);
    pthread_mutex_destroy(&p->mu);
    free(p->w);
    free(p);
}

int pool_threads(const ct_pool *p)
{
    return p ? p->n : 1;
}

void pool_run(ct_pool *p, size_t n, pool_fn fn, void *ctx)
{
    if (n == 0) return;
    if (!p || p->n == 1 || n == 1 || n > UINT32_MAX) {
        for (size_t i = 0; i < n; i++) fn(ctx, 0, i);
        return;
    }
    pthread_mutex_lock(&p->mu);
    job j = {fn, ctx, n, p->cur.gen + 1};
    if (j.gen == 0) j.gen = 1;   /* 0 is what a new worker has seen */
    p->cur = j;
    atomic_store_explicit(&p->finished, 0, memory_order_relaxed);
    atomic_store_explicit(&p->next, (uint_fast64_t)j.gen << 32, memory_order_release);
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->mu);
    take_tasks(p, &j, 0);
    pthread_mutex_lock(&p->mu);
    while (atomic_load_explicit(&p->finished, memory_order_acquire) < n) pthread_cond_wait(&p->done, &p->mu);
    pthread_mutex_unlock(&p->mu);
}

/* Waits, holding p->mu, until no side job is pending or running. */
static void side_idle(ct_pool *p)
{
    while (p->side_state != SIDE_NONE) pthread_cond_wait(&p->side_done, &p->mu);
}

void pool_side(ct_pool *p, pool_side_fn fn, void *ctx)
{
    if (!p || p->n == 1) {
        fn(ctx);
        return;
    }
    pthread_mutex_lock(&p->mu);
    side_idle(p);
    p->side_fn = fn;
    p->side_ctx = ctx;
    p->side_state = SIDE_PENDING;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->mu);
}

void pool_side_wait(ct_pool *p)
{
    if (!p || p->n == 1) return;
    pthread_mutex_lock(&p->mu);
    side_idle(p);
    pthread_mutex_unlock(&p->mu);
}

int pool_cpus(void)
{
    cpu_set_t set;
    if (sched_getaffinity(0, sizeof set, &set) == 0) {
        int n = CPU_COUNT(&set);
        if (n > 0) return n;
    }
    return 1;
}

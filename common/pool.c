/* pool.c: the thread pool (pool.h). A loop is a generation: pool_run
 * publishes the task function and count, bumps the generation and wakes the
 * workers; everyone takes task numbers from one atomic counter; the last
 * worker to finish wakes the caller. */
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

struct ct_pool {
    int n;                      /* threads, the caller included */
    worker *w;                  /* n - 1 workers */
    pthread_mutex_t mu;
    pthread_cond_t go, done;
    uint64_t gen;               /* loops started (guarded by mu) */
    int busy;                   /* workers not finished with the current loop (mu) */
    int stop;                   /* (mu) */
    pool_fn fn;
    void *ctx;
    size_t ntasks;
    atomic_size_t next;
};

static void take_tasks(ct_pool *p, int id)
{
    for (;;) {
        size_t i = atomic_fetch_add_explicit(&p->next, 1, memory_order_relaxed);
        if (i >= p->ntasks) return;
        p->fn(p->ctx, id, i);
    }
}

static void *worker_main(void *arg)
{
    worker *w = arg;
    ct_pool *p = w->p;
    uint64_t seen = 0;
    pthread_mutex_lock(&p->mu);
    for (;;) {
        while (p->gen == seen && !p->stop) pthread_cond_wait(&p->go, &p->mu);
        if (p->stop) break;
        seen = p->gen;
        pthread_mutex_unlock(&p->mu);
        take_tasks(p, w->id);
        pthread_mutex_lock(&p->mu);
        if (--p->busy == 0) pthread_cond_signal(&p->done);
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
    atomic_init(&p->next, 0);
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
    pthread_mutex_lock(&p->mu);
    p->stop = 1;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->mu);
    for (int i = 1; i < p->n; i++) pthread_join(p->w[i - 1].th, NULL);
    pthread_cond_destroy(&p->go);
    pthread_cond_destroy(&p->done);
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
    if (!p || p->n == 1 || n == 1) {
        for (size_t i = 0; i < n; i++) fn(ctx, 0, i);
        return;
    }
    pthread_mutex_lock(&p->mu);
    p->fn = fn;
    p->ctx = ctx;
    p->ntasks = n;
    atomic_store_explicit(&p->next, 0, memory_order_relaxed);
    p->busy = p->n - 1;
    p->gen++;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->mu);
    take_tasks(p, 0);
    pthread_mutex_lock(&p->mu);
    while (p->busy > 0) pthread_cond_wait(&p->done, &p->mu);
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

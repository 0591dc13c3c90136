/* The thread pool (common/pool.h): every task runs exactly once per loop,
 * on a worker id in range that no other thread holds at the same time; the
 * pool survives many short loops and loops with fewer tasks than threads;
 * bad sizes are refused. */
#include <criterion/criterion.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <time.h>

#include "common/pool.h"

#define NTASKS 10007

typedef struct counts {
    atomic_int runs[NTASKS];
    atomic_int in_use[8];      /* per worker id: 1 while a task of it runs */
    atomic_int overlap;        /* a worker id seen running twice at once */
    atomic_int bad_id;
    int threads;
} counts;

static void count_task(void *ctx, int worker, size_t task)
{
    counts *c = ctx;
    if (worker < 0 || worker >= c->threads) {
        atomic_fetch_add(&c->bad_id, 1);
        return;
    }
    if (atomic_exchange(&c->in_use[worker], 1)) atomic_fetch_add(&c->overlap, 1);
    atomic_fetch_add(&c->runs[task], 1);
    atomic_store(&c->in_use[worker], 0);
}

static void check_loop(ct_pool *p, int threads, size_t n)
{
    counts *c = calloc(1, sizeof *c);
    cr_assert(c);
    c->threads = threads;
    pool_run(p, n, count_task, c);
    for (size_t i = 0; i < n; i++) cr_assert_eq(atomic_load(&c->runs[i]), 1, "task %zu ran %d times", i, c->runs[i]);
    for (size_t i = n; i < NTASKS; i++) cr_assert_eq(atomic_load(&c->runs[i]), 0);
    cr_assert_eq(atomic_load(&c->bad_id), 0, "worker id out of range");
    cr_assert_eq(atomic_load(&c->overlap), 0, "two threads ran with one worker id");
    free(c);
}

Test(pool, every_task_once_for_any_size)
{
    for (int threads = 1; threads <= 4; threads++) {
        ct_pool *p = NULL;
        ct_error err;
        cr_assert_eq(pool_new(threads, &p, &err), 0, "%s", err.msg);
        cr_assert_eq(pool_threads(p), threads);
        check_loop(p, threads, NTASKS);
        check_loop(p, threads, 1);
        check_loop(p, threads, 2);
        check_loop(p, threads, 0);
        check_loop(p, threads, 3);
        pool_free(p);
    }
    check_loop(NULL, 1, 100);   /* no pool: the caller alone */
    cr_assert_eq(pool_threads(NULL), 1);
}

static void sum_task(void *ctx, int worker, size_t task)
{
    (void)worker;
    atomic_fetch_add((atomic_long *)ctx, (long)task + 1);
}

Test(pool, many_short_loops)
{
    ct_pool *p = NULL;
    ct_error err;
    cr_assert_eq(pool_new(3, &p, &err), 0, "%s", err.msg);
    for (int k = 0; k < 20000; k++) {
        atomic_long sum;
        atomic_init(&sum, 0);
        size_t n = (size_t)(k % 7);
        pool_run(p, n, sum_task, &sum);
        cr_assert_eq(atomic_load(&sum), (long)(n * (n + 1) / 2), "loop %d", k);
    }
    pool_free(p);
}

/* A task that finishes late: the loop must still wait for it. */
static void slow_task(void *ctx, int worker, size_t task)
{
    (void)worker;
    struct timespec ts = {0, 3 * 1000 * 1000};
    nanosleep(&ts, NULL);
    atomic_store(&((atomic_int *)ctx)[task], 1);
}

Test(pool, returns_when_every_task_is_done)
{
    ct_pool *p = NULL;
    ct_error err;
    cr_assert_eq(pool_new(4, &p, &err), 0, "%s", err.msg);
    for (int k = 0; k < 20; k++) {
        atomic_int done[6];
        for (int i = 0; i < 6; i++) atomic_init(&done[i], 0);
        pool_run(p, 6, slow_task, done);
        for (int i = 0; i < 6; i++) cr_assert_eq(atomic_load(&done[i]), 1, "loop %d: task %d not done on return", k, i);
    }
    pool_free(p);
}

Test(pool, bad_sizes_refused)
{
    ct_pool *p = (ct_pool *)1;
    ct_error err;
    cr_assert_eq(pool_new(0, &p, &err), CT_EINVAL);
    cr_assert_null(p);
    cr_assert_eq(pool_new(POOL_MAX_THREADS + 1, &p, &err), CT_EINVAL);
    cr_assert(pool_cpus() >= 1);
    pool_free(NULL);
}

/* Side jobs: each runs exactly once, beside loops that still do every task
 * (the worker running it joins them late or not at all), and its writes are
 * visible after pool_side_wait; without workers it runs at once. */
typedef struct side_ctx {
    atomic_int runs;
    long value;          /* written by the job, read after the wait */
    int sleep_ms;
} side_ctx;

static void side_job(void *ctx)
{
    side_ctx *c = ctx;
    if (c->sleep_ms) {
        struct timespec ts = {0, (long)c->sleep_ms * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    c->value = 12345;
    atomic_fetch_add(&c->runs, 1);
}

Test(pool, side_job_beside_loops)
{
    for (int threads = 1; threads <= 3; threads++) {
        ct_pool *p = NULL;
        ct_error err;
        cr_assert_eq(pool_new(threads, &p, &err), 0, "%s", err.msg);
        for (int k = 0; k < 50; k++) {
            side_ctx c = {.sleep_ms = k % 5 == 0 ? 2 : 0};
            atomic_init(&c.runs, 0);
            pool_side(p, side_job, &c);
            if (threads == 1) cr_assert_eq(atomic_load(&c.runs), 1, "one thread: the job runs before pool_side returns");
            /* loops while it runs: every task once */
            for (int l = 0; l < 3; l++) check_loop(p, threads, (size_t)(1 + (k * 7 + l * 13) % 40));
            pool_side_wait(p);
            cr_assert_eq(atomic_load(&c.runs), 1, "threads %d, round %d: side job ran %d times", threads, k,
                         atomic_load(&c.runs));
            cr_assert_eq(c.value, 12345);
        }
        /* a second side job waits for the first; freeing waits for the last */
        side_ctx a = {.sleep_ms = 3}, b = {0};
        atomic_init(&a.runs, 0);
        atomic_init(&b.runs, 0);
        pool_side(p, side_job, &a);
        pool_side(p, side_job, &b);
        pool_free(p);
        cr_assert_eq(atomic_load(&a.runs), 1);
        cr_assert_eq(atomic_load(&b.runs), 1);
    }
    pool_side_wait(NULL);
}

/* GPU timer queries of the display's stages (display/disp_gpu_time.h), on
 * a software GL context (OSMesa): the first pair is not counted (Mesa
 * answers it with the host's uptime), timed pairs add to their stage, a
 * pair begun inside another is ignored, pairs beyond the queries in flight
 * go untimed and are counted, and polling frees the queries the GPU is done
 * with so that timing goes on. */
#include <criterion/criterion.h>

#include "display/disp_gpu_time.h"
#include "display/gl_backend.h"
#include "display/gl_load.h"

static gl_backend *b;
static ct_error err;

static void setup(void)
{
    cr_assert_eq(gl_backend_open(GL_BACKEND_OSMESA, 64, 64, NULL, false, &b, &err), 0, "%s", err.msg);
}

static void teardown(void)
{
    gl_backend_close(b);
}

TestSuite(disp_gpu_time, .init = setup, .fini = teardown);

/* Some GL work the timer sees: clears of the default framebuffer. */
static void work(int n)
{
    for (int i = 0; i < n; i++) {
        gl.ClearColor(0.1f * (float)(i % 10), 0.5f, 0.25f, 1.0f);
        gl.Clear(GL_COLOR_BUFFER_BIT);
    }
}

/* The pair that is never counted. */
static void first_pair(disp_gpu_time *t)
{
    disp_gpu_time_begin(t, DISP_GT_PRESENT);
    work(3);
    disp_gpu_time_end(t);
}

Test(disp_gpu_time, stages_add_up_and_nested_pairs_are_ignored)
{
    disp_gpu_time *t;
    cr_assert_eq(disp_gpu_time_new(&t, &err), 0, "%s", err.msg);
    first_pair(t);
    for (int f = 0; f < 10; f++) {
        disp_gpu_time_begin(t, DISP_GT_TAKE);
        work(2);
        disp_gpu_time_end(t);
        disp_gpu_time_begin(t, DISP_GT_DRAW);
        work(20);
        disp_gpu_time_begin(t, DISP_GT_PRESENT);   /* inside DRAW: ignored */
        work(1);
        disp_gpu_time_end(t);
        disp_gpu_time_end(t);                      /* nothing open: ignored */
        gl.Finish();
        disp_gpu_time_poll(t);
    }
    double ms[DISP_GT_STAGES];
    uint64_t n[DISP_GT_STAGES], untimed;
    disp_gpu_time_totals(t, ms, n, &untimed);
    cr_assert_eq(n[DISP_GT_TAKE], 10u, "take %llu draw %llu present %llu untimed %llu", (unsigned long long)n[0], (unsigned long long)n[1], (unsigned long long)n[2], (unsigned long long)untimed);
    cr_assert_eq(n[DISP_GT_DRAW], 10u);
    cr_assert_eq(n[DISP_GT_PRESENT], 0u, "the first or the nested pair was counted");
    cr_assert_eq(untimed, 0u);
    cr_assert(ms[DISP_GT_TAKE] >= 0.0 && ms[DISP_GT_DRAW] > 0.0 && ms[DISP_GT_DRAW] < 60000.0,
              "take %.3f ms, draw %.3f ms", ms[DISP_GT_TAKE], ms[DISP_GT_DRAW]);
    cr_assert_eq(gl_check("timer queries", &err), 0, "%s", err.msg);
    disp_gpu_time_free(t);
}

Test(disp_gpu_time, pairs_beyond_the_queries_in_flight_go_untimed_until_polled)
{
    disp_gpu_time *t;
    cr_assert_eq(disp_gpu_time_new(&t, &err), 0, "%s", err.msg);
    first_pair(t);
    enum { PAIRS = 200 };
    for (int i = 0; i < PAIRS; i++) {
        disp_gpu_time_begin(t, DISP_GT_DRAW);
        work(1);
        disp_gpu_time_end(t);
    }
    double ms[DISP_GT_STAGES];
    uint64_t n[DISP_GT_STAGES], untimed;
    disp_gpu_time_totals(t, ms, n, &untimed);
    cr_assert_gt(untimed, 0u, "never polled: the queries ran out");
    cr_assert_eq(n[DISP_GT_DRAW] + untimed, (uint64_t)PAIRS, "%llu timed, %llu untimed",
                 (unsigned long long)n[DISP_GT_DRAW], (unsigned long long)untimed);
    /* totals waited for every result: the queries are free again */
    uint64_t before = n[DISP_GT_DRAW];
    for (int i = 0; i < PAIRS; i++) {
        disp_gpu_time_begin(t, DISP_GT_DRAW);
        work(1);
        disp_gpu_time_end(t);
        gl.Finish();
        disp_gpu_time_poll(t);
    }
    uint64_t untimed2;
    disp_gpu_time_totals(t, ms, n, &untimed2);
    cr_assert_eq(n[DISP_GT_DRAW], before + PAIRS, "polled after each pair: all timed");
    cr_assert_eq(untimed2, untimed);
    disp_gpu_time_free(t);
}

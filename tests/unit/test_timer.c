/* test_timer.c: the clocks of common/timer.h. The thread CPU clock counts
 * work and not waiting (the texture updates' pacing, master/dsync.c, relies
 * on it); the wall clock counts both. */
#include <criterion/criterion.h>

#include "common/timer.h"

Test(timer, thread_cpu_counts_work_not_sleep)
{
    double w0 = ct_now(), c0 = ct_thread_cpu();
    ct_sleep_us(50000);
    double w1 = ct_now(), c1 = ct_thread_cpu();
    cr_assert_geq(w1 - w0, 0.049, "slept %g s by the wall clock", w1 - w0);
    cr_assert_lt(c1 - c0, 0.025, "sleeping 50 ms cost %g s of CPU", c1 - c0);
    /* busy work: at least 20 ms of CPU, never more than the wall time */
    volatile double x = 0.0;
    double c2 = ct_thread_cpu(), w2 = ct_now();
    while (ct_thread_cpu() - c2 < 0.02) x += 1.0;
    double c3 = ct_thread_cpu(), w3 = ct_now();
    cr_assert_geq(c3 - c2, 0.02);
    cr_assert_leq(c3 - c2, w3 - w2 + 1e-3, "CPU %g s in %g s of wall time", c3 - c2, w3 - w2);
    cr_assert_gt(x, 0.0);
}

Test(timer, process_cpu_counts_the_threads_work)
{
    double c0 = ct_process_cpu();
    ct_sleep_us(30000);
    cr_assert_lt(ct_process_cpu() - c0, 0.02, "sleeping 30 ms cost CPU");
    volatile double x = 0.0;
    double t0 = ct_thread_cpu(), p0 = ct_process_cpu();
    while (ct_thread_cpu() - t0 < 0.02) x += 1.0;
    cr_assert_geq(ct_process_cpu() - p0, 0.019, "the calling thread's work not counted");
    cr_assert_gt(x, 0.0);
}

/* The poll loops' nap: doubles up to its bound, never past it; 0 stays 0
 * (a loop told to spin). */
Test(timer, nap_doubles_up_to_its_bound)
{
    unsigned nap = 20;
    unsigned want[] = {40, 80, 160, 320, 640, 1000, 1000};
    for (size_t i = 0; i < sizeof want / sizeof *want; i++) {
        ct_nap(&nap, 1000);
        cr_assert_eq(nap, want[i], "step %zu: %u", i, nap);
    }
    nap = 0;
    double w0 = ct_now();
    ct_nap(&nap, 1000);
    cr_assert_eq(nap, 0);
    cr_assert_lt(ct_now() - w0, 0.001, "a nap of 0 slept");
    nap = 5;
    ct_nap(&nap, 5);
    cr_assert_eq(nap, 5, "past its bound");
    nap = 3;
    ct_nap(&nap, 1000000000u);
    cr_assert_eq(nap, 6);
}

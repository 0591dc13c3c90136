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

/* timer.h: monotonic wall-clock time for stats and benchmarks, and a
 * thread's CPU time. */
#ifndef CT_TIMER_H
#define CT_TIMER_H

#include <stdint.h>

/* Seconds from an arbitrary fixed origin, monotonic. */
double ct_now(void);

/* Microseconds of the same clock (CLOCK_MONOTONIC: one origin for every
 * process of a host, so stamps of one program can be read by another). */
uint64_t ct_now_us(void);

/* Seconds of CPU time the calling thread has used (user and system):
 * what a piece of work cost, unlike the wall clock, which also counts the
 * time the thread waited for a core on a shared host. */
double ct_thread_cpu(void);

/* Sleeps us microseconds (a poll loop's nap). */
void ct_sleep_us(unsigned us);

#endif

/* timer.h: monotonic wall-clock time for stats and benchmarks, a thread's
 * and a process's CPU time, and the naps of poll loops. */
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

/* Seconds of CPU time the whole process has used (every thread: a
 * renderer's or MPI's too). */
double ct_process_cpu(void);

/* Sleeps us microseconds (a poll loop's nap). */
void ct_sleep_us(unsigned us);

/* A poll loop's growing nap: sleeps *nap microseconds (not at all when 0)
 * and doubles *nap up to most. Started small, it keeps a busy link fast;
 * grown, a waiting process leaves its core to those that work (MPI's
 * blocking waits spin, which hurts runs that share cores). */
void ct_nap(unsigned *nap, unsigned most);

#endif

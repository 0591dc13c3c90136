/* timer.h: monotonic wall-clock time for stats and benchmarks. */
#ifndef CT_TIMER_H
#define CT_TIMER_H

#include <stdint.h>

/* Seconds from an arbitrary fixed origin, monotonic. */
double ct_now(void);

/* Microseconds of the same clock (CLOCK_MONOTONIC: one origin for every
 * process of a host, so stamps of one program can be read by another). */
uint64_t ct_now_us(void);

/* Sleeps us microseconds (a poll loop's nap). */
void ct_sleep_us(unsigned us);

#endif

/* timer.h: monotonic wall-clock time for stats and benchmarks. */
#ifndef CT_TIMER_H
#define CT_TIMER_H

/* Seconds from an arbitrary fixed origin, monotonic. */
double ct_now(void);

#endif

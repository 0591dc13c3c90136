/* tport_local.h: the in-process tracer port (proto/tport.h): lanes in this
 * process that trace with the real tracer (tracer.h) on the thread pool. A
 * batch is traced when it is submitted, on every thread of the pool, in
 * screen order as a tracer rank traces it (screen_order.h), and its reply
 * waits for poll; more than one lane only changes how a lockstep
 * round is split, as over several MPI ranks. Used by corrtex converge and
 * by the tests of the master's loop. */
#ifndef CT_TRACER_TPORT_LOCAL_H
#define CT_TRACER_TPORT_LOCAL_H

#include "common/pool.h"
#include "proto/tport.h"
#include "tracer/tracer.h"

/* A port of `lanes` lanes tracing with t on pool (NULL: this thread). t and
 * pool must outlive the port. */
int tport_local_new(const trc_tracer *t, ct_pool *pool, int lanes, tport **out, ct_error *err);

/* The rays traced so far. */
trc_stats tport_local_stats(const tport *p);

#endif

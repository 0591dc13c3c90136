/* drive.h: the master's sample loop over a tracer port (proto/tport.h),
 * the one loop behind corrtex-render (master/sched.c, MPI ranks) and corrtex
 * converge (threads of the same process): requests from the session
 * (session.h) go out in batches, samples come back and go into the
 * session, and a sink (sink.h) hears of complete frames.
 *
 * Free running, every lane (tracer) keeps up to `window` batches of the
 * current view in flight (those of views left do not count: a tracer
 * answers them as soon as a newer one comes), each of about `batch_ms` of
 * its measured rate but no more than a window's share of how long views
 * last, handed out one per lane per pass from a rotating lane so that none
 * starves when the queue runs short; samples go in as they come. A lockstep frame of K samples is taken
 * in rounds of `round` requests, split evenly over the lanes; a round's
 * samples go in only when all are back, sorted by request id, so a frame
 * does not depend on the number of lanes (nor, by the session's design, on
 * the number of master threads).
 *
 * With `pop_ahead` (--pop-ahead), a lane's next batch (lockstep: the next
 * round) is popped as the answer goes in, ahead of that answer's reports
 * (session.h, sess_insert_next): on two or more master threads the pops
 * run beside the splats, and the batch goes out at once. What it hands out
 * then does not know of the answer's children: early lockstep frames lose
 * some adaptivity, and a still view's refinement picks its pixels from
 * older variances (docs/sampling.md), so it is for a master that many
 * tracers saturate, and off by default. Owns the drv_ prefix. */
#ifndef CT_MASTER_DRIVE_H
#define CT_MASTER_DRIVE_H

#include <stdbool.h>
#include <stdint.h>

#include "common/error.h"
#include "common/optab.h"
#include "master/session.h"
#include "master/sink.h"
#include "proto/tport.h"

/* The batching options (drv_options_table). */
typedef struct drv_options {
    int window;                 /* request batches in flight per lane */
    int batch_min, batch_max;   /* free-running batch size bounds (requests) */
    double batch_ms;            /* free-running: target tracing time of one batch */
    int round;                  /* lockstep: requests per round (independent of the lanes) */
    bool pop_ahead;             /* the next batch or round popped ahead of the reports (see above) */
} drv_options;

/* The option table: --window, --batch-min, --batch-max, --batch-ms, --round,
 * --pop-ahead. */
const optab *drv_options_table(size_t *n);

/* Per lane, for stats and batch sizing. */
typedef struct drv_lane {
    int inflight;               /* batches out, not answered */
    double rate;                /* samples/s, smoothed (batch sizing) */
    uint64_t samples;           /* samples returned since the start */
} drv_lane;

typedef struct drv drv;

/* A loop over session s and port p (both kept by the caller); k (copied)
 * hears of frames and, through the session, of samples. */
int drv_new(sess *s, tport *p, const sink *k, const drv_options *o, drv **out, ct_error *err);
void drv_free(drv *d);

/* Sets the view in the session and, when it is a new epoch, tells every
 * lane: 1 new epoch, 0 the same view, negative when the session refused it
 * (the engines' error) or the port failed (CT_EIO). */
int drv_set_view(drv *d, const ct_camera *cam, int width, int height, ct_error *err);

/* Starts a lockstep frame of k samples of the current view (k = UINT32_MAX:
 * until every pixel has been handed out); the sink's frame callback ends it.
 * Without a frame the loop runs free. */
void drv_begin_frame(drv *d, uint32_t k);

/* Ends the frame in progress after its current round (its samples still go
 * in and the sink still hears of the frame). */
void drv_cut_frame(drv *d);

bool drv_in_frame(const drv *d);

/* Lockstep mode: no free-running batches are handed out, also between
 * frames. */
void drv_set_lockstep(drv *d, bool on);

/* One turn: takes every answered batch into the session, then hands out
 * work. 1 when anything happened, 0 when not, negative on a failure of the
 * port or the session. */
int drv_step(drv *d, ct_error *err);

/* Takes every answered batch into the session: a loop about to change the
 * view calls it first, so that samples already here go in for the view
 * they were traced for. Running free it hands out a lane's next batch
 * (popped ahead) only with may_pop: false when the view may change next,
 * so that no batch goes out for a view about to be left. 1 when any was
 * taken. */
int drv_receive(drv *d, bool may_pop, ct_error *err);

/* Batches in flight over all lanes. */
int drv_inflight(const drv *d);

/* Lane i (0 .. lanes-1). */
const drv_lane *drv_lane_get(const drv *d, int i);

/* The watchdog: CT_EIO naming the lane (as "tracer rank i+1") when one has
 * had work out for more than timeout_s without answering. */
int drv_check(const drv *d, double now, double timeout_s, ct_error *err);

#endif

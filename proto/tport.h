/* tport.h: a tracer port: how the master's loop (master/drive.h) hands
 * request batches to tracers and gets their samples back, behind one small
 * table of operations, so that the same loop runs over MPI ranks
 * (tport_mpi_new, proto/tport_mpi.c), over threads of this process running
 * the real tracer (tracer/tport_local.h) or over recorded samples
 * (master/tport_replay.h). A port has `lanes` tracers (ranks); each answers
 * its batches in the order it got them. Owns the tport_ prefix. */
#ifndef CT_PROTO_TPORT_H
#define CT_PROTO_TPORT_H

#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "common/records.h"

/* The view requests are traced in: the loop's epoch (samples carry it back),
 * the image size and the camera. */
typedef struct tport_view {
    uint32_t epoch;
    uint32_t width, height;
    ct_camera cam;
} tport_view;

/* One answered batch: the samples of its requests (in request order; an
 * empty batch when the lane skipped it for an older epoch). */
typedef struct tport_reply {
    int lane;
    uint64_t batch;
    const ct_sample *samples;   /* valid until the next poll */
    uint32_t n;
} tport_reply;

typedef struct tport tport;

typedef struct tport_ops {
    /* A new view for every lane: batches of older epochs still queued may
     * be answered empty. */
    int (*view)(tport *p, const tport_view *v, ct_error *err);
    /* Hands lane `lane` a batch of n requests made for view v. */
    int (*submit)(tport *p, int lane, uint64_t batch, const tport_view *v, const ct_request *r, uint32_t n,
                  ct_error *err);
    /* The next answered batch: 1 with *out filled, 0 when none is ready,
     * negative on failure. Never blocks. */
    int (*poll)(tport *p, tport_reply *out, ct_error *err);
    /* Tells the lanes to stop, waits up to wait_s for what is in flight to
     * leave, and frees the port. */
    void (*close)(tport *p, double wait_s);
} tport_ops;

struct tport {
    const tport_ops *ops;
    int lanes;
};

/* Answered batches waiting for poll, for ports that answer in process:
 * push takes over a malloc'd sample array; pop hands it out until the
 * next pop (which frees it). */
typedef struct tport_fifo {
    tport_reply *q;
    size_t head, n, cap;
    ct_sample *last;
} tport_fifo;

int tport_fifo_push(tport_fifo *f, int lane, uint64_t batch, ct_sample *s, uint32_t n, ct_error *err);
int tport_fifo_pop(tport_fifo *f, tport_reply *out);
void tport_fifo_free(tport_fifo *f);

/* The MPI port of rank 0: lanes are ranks 1 .. ntracers (lane i is rank
 * i + 1), batches go out as WIRE_MPI_REQUESTS through proto/mpi_link.h and
 * come back as WIRE_MPI_SAMPLES, received by polled matched receives. */
int tport_mpi_new(int ntracers, tport **out, ct_error *err);

#endif

/* sink.h: where the master's results go: the display server
 * (master/dsink.h: texture updates, sample points, FRAME) or files
 * (master/fsink.h: images, the CSV of convergence, a recording of the
 * samples). The session (session.h) tells a sink which samples it inserted;
 * the loop (drive.h) tells it when a lockstep frame (a checkpoint, offline)
 * is complete. A sink reads the textures themselves from the session when it
 * needs them. Owns the sink_ prefix. */
#ifndef CT_MASTER_SINK_H
#define CT_MASTER_SINK_H

#include <stdint.h>

#include "common/error.h"
#include "common/records.h"

struct sess;

/* A lockstep frame that is complete. */
typedef struct sink_frame {
    uint32_t samples;     /* samples inserted in it */
    int short_of_k;       /* it ended early: every pixel of the view had been handed out */
} sink_frame;

typedef struct sink {
    void *user;
    /* Samples inserted into the session (stale ones left out), in the order
     * they went in; NULL: not wanted. */
    void (*samples)(void *user, const ct_sample *s, uint32_t n);
    /* A lockstep frame is complete; NULL: nothing to do. */
    int (*frame)(void *user, struct sess *s, const sink_frame *f, ct_error *err);
} sink;

#endif

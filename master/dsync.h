/* dsync.h: the master's side of keeping a display current (docs/protocol.md,
 * "Flow control"). An update is the pending texture events (ALLOC,
 * PROJECTION, FREE) followed by runs of unsent tiles read from the textures
 * at that moment (so newer texels replace older unsent ones in place, and
 * every texel goes out at most once per update), encoded straight into the
 * display's send queue, and closed by SYNC n. Free running, a new update is
 * made only while fewer than `window` are unacknowledged (the display ACKs
 * n once it has applied update n), at most every interval and within a
 * share of the master's time (dsync_due), and its size follows the rate at
 * which the display acknowledged the last ones: the display's pace sets
 * what is sent, never how fast the master samples. Lockstep frames take every
 * unsent tile before their FRAME. Owns the dsync_ prefix. */
#ifndef CT_MASTER_DSYNC_H
#define CT_MASTER_DSYNC_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/error.h"
#include "master/ctex.h"
#include "master/dsrv.h"

typedef struct dsync_options {
    uint32_t encoding;     /* wire_patch_enc of TEX_PATCH texels */
    int window;            /* updates in flight before the master waits for an ACK */
    int send_timeout_ms;   /* a control message waits this long for room in a full queue */
    double target_ms;      /* an update holds what the display takes in about this long */
    size_t min_bytes;      /* bounds of an update's texel bytes (raw) */
    size_t max_bytes;
    /* A texture with more than one texel a screen pixel on both axes (and
     * even sides) goes to the display as the means of 2 x 2 texels
     * (docs/protocol.md, "Texels at the display's rate"); false: every
     * texture as the master keeps it. */
    bool screen_rate;
    /* Free running, the next update is due interval_s after the last one
     * started and once the updates have had at most `share` (0-1] of the
     * master's time: an update that cost t (the CPU time of its encoding
     * and of the socket's reads and writes since the one before) holds the
     * next until t / share after its start, a second at most (dsync_due). */
    double interval_s;
    double share;
} dsync_options;

/* What was sent (dsync_stats). */
typedef struct dsync_stats {
    uint64_t updates, acked;   /* SYNCs sent / acknowledged on this connection */
    uint64_t patches;          /* TEX_PATCH messages since the start */
    uint64_t texel_bytes;      /* their raw texel bytes */
    uint64_t resized;          /* TEX_RESIZEs: exact resizes the display computed... */
    uint64_t resized_texels;   /* ...and their texels, which went unsent */
    uint64_t resized_whole;    /* exact resizes sent as TEX_ALLOC, all their tiles (2 x 2 means) */
    size_t budget;             /* texel bytes of the next update */
    double rate;               /* texel bytes/s the display acknowledged (smoothed) */
} dsync_stats;

typedef struct dsync dsync;

/* The defaults: LZ4 and at most one texel a screen pixel on TCP, raw and
 * every texel on a UNIX socket (docs/protocol.md); an update at most every
 * 10 ms and within a quarter of the master's time. */
void dsync_options_default(dsync_options *o, bool tcp);

/* CT_EINVAL for a share outside (0, 1] or a negative interval. */
int dsync_new(const dsync_options *o, dsync **out, ct_error *err);
void dsync_free(dsync *d);

/* A new display: nothing sent or in flight, update numbers from 1. The
 * caller marks every texel unsent (ctex_dirty_all). */
void dsync_reset(dsync *d);

/* A display that just got the scene: every visible texture's ALLOC and
 * PROJECTION, every texel marked unsent (they follow in updates), and
 * dsync_reset. *ntex: the textures announced. */
int dsync_send_state(dsync *d, dsrv *ds, ctex *tex, uint32_t *ntex, ct_error *err);

/* The display's epoch of the current camera (TEX_PROJECTION carries it). */
void dsync_set_epoch(dsync *d, uint32_t epoch);

/* Free running: when the window allows, sends one update (events, tiles
 * within the budget, SYNC) stamped `now_us` on the master's clock; `now` is
 * ct_now() at the call (the pacing counts from it). Returns 1 when one was
 * sent, 0 when none was due, negative on failure (a display that fails is
 * dropped by dsrv, which is not a failure). The caller asks dsync_due
 * first; this checks only the window. */
int dsync_update(dsync *d, dsrv *ds, ctex *tex, double now, uint64_t now_us, ct_error *err);

/* Lockstep: sends the events and every unsent tile now (no SYNC; FRAME
 * follows). *patches counts the TEX_PATCH messages. */
int dsync_flush_all(dsync *d, dsrv *ds, ctex *tex, uint32_t *patches, ct_error *err);

/* The display applied every update up to seq. CT_EPROTO (err filled) for a
 * number never sent. */
int dsync_ack(dsync *d, uint64_t seq, double now, ct_error *err);

/* Whether the window allows an update now (free running). */
bool dsync_can_send(const dsync *d);

/* How long the display has looked stuck (0: it has not): bytes waited in
 * its queue and none were written for this long, or an update's SYNC went
 * into its socket this long ago and is not acknowledged. Flow control sends
 * a display that stopped reading nothing more, so the full queue by which
 * dsrv_send finds a stuck display never comes (master/dsink.c drops it).
 * A slow link still writes; the clock of an update starts when its last
 * byte left the queue. Call it every turn (it notes the progress). */
double dsync_stalled_s(dsync *d, dsrv *ds, double now);

/* Whether an update is due at `now` (ct_now's clock): the window allows
 * one and the pacing of dsync_options (interval, share) has passed. */
bool dsync_due(const dsync *d, double now);

dsync_stats dsync_get_stats(const dsync *d);

#endif

/* dsink.h: the display sink (sink.h): what the master sends a connected
 * display, besides the handshake that the display server (dsrv.h) does: on
 * connection the start view, the scene (the radiosity mesh with the texture
 * hierarchy as its node table, content-hashed so a display may keep it
 * cached) and every live texture; then texture updates paced by the
 * display's ACKs (dsync.h) while running free, every unsent tile and FRAME
 * at the end of a lockstep frame, the droppable SAMPLES points and STATS.
 * Owns the dsink_ prefix. */
#ifndef CT_MASTER_DSINK_H
#define CT_MASTER_DSINK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/error.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "master/dsrv.h"
#include "master/dsync.h"
#include "master/session.h"
#include "master/sink.h"
#include "proto/wire.h"

typedef struct dsink_config {
    dsrv *ds;                   /* kept by the caller */
    const ct_radmesh *mesh;     /* the interactive solution (the SCENE) */
    const ct_scene *scene;      /* its cameras: the start view of a display without one */
    int send_timeout_ms;        /* a display whose full queue does not drain for this long is dropped */
    size_t queue_bytes;         /* the display's send queue bound; SAMPLES only while a quarter is free */
    int patch_encoding;         /* wire_patch_enc of TEX_PATCH, or -1: by transport (dsync.h) */
    int display_texels;         /* 1: at most one texel a screen pixel (dsync_options.screen_rate), 0: all, -1: by transport */
    double patch_s;             /* free running: updates at most this often (s; dsync_options.interval_s) */
    double patch_share;         /* and within this share of the master's time (dsync_options.share) */
} dsink_config;

typedef struct dsink dsink;

int dsink_new(const dsink_config *c, dsink **out, ct_error *err);
void dsink_free(dsink *k);

/* The sink the session and the loop call (samples: the SAMPLES points;
 * frame: every unsent tile, then FRAME). */
sink dsink_sink(dsink *k);

/* A display connected: the start view, the scene, every live texture; the
 * frame numbers start at 0. */
int dsink_connected(dsink *k, sess *s, const wire_settings *set, ct_error *err);

/* The display left. */
void dsink_disconnected(dsink *k);

/* The display's epoch for a camera it sent: the points so far belong to
 * the previous one and go out first. */
void dsink_set_epoch(dsink *k, uint32_t display_epoch);

/* The display acknowledged update seq; CT_EPROTO for one never sent. */
int dsink_ack(dsink *k, uint64_t seq, ct_error *err);

/* Free running: one texture update when the display's ACKs allow (with the
 * points collected before it). */
int dsink_update(dsink *k, sess *s, ct_error *err);

/* Whether a free-running update is due at `now` (ct_now's clock): the ACKs
 * allow one and the pacing (patch_s, patch_share) has passed. */
bool dsink_update_due(const dsink *k, double now);

/* Free running, every turn: drops a display that has looked stuck for
 * send_timeout_ms (dsync_stalled_s). */
void dsink_drop_stalled(dsink *k, double now);

/* Every turn, lockstep too: drops a display that has sent nothing for
 * send_timeout_ms, at least 3 s (dsrv_silent_s; corrtex-display PINGs once
 * a second). */
void dsink_drop_silent(dsink *k, double now);

/* The frame in progress belongs to a display that left: it ends without
 * FRAME. */
void dsink_orphan_frame(dsink *k);

/* Sends STATS (when a display is there). */
void dsink_stats(dsink *k, const wire_stats *st);

/* Points dropped since the start (back-pressure), seconds spent encoding
 * texture updates. */
uint64_t dsink_points_dropped(const dsink *k);
double dsink_take_encode_s(dsink *k);

/* What dsync sent (updates, patches, texel bytes). */
dsync_stats dsink_sync_stats(const dsink *k);

#endif

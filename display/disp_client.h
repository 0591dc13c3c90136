/* disp_client.h: the display's side of the socket protocol
 * (docs/protocol.md). Connects to the master (handshake, token) and sends
 * SETTINGS announcing the cached scene (disp_cache.h); from then on a
 * thread of its own reads, decodes and applies every message to the
 * disp_inbox as it arrives (so decoding never waits for a frame to be
 * drawn), acknowledges each texture update once it is in the inbox (the
 * master's flow control), measures the offset of the master's clock
 * (PING/PONG, for the lag statistics) and sends the cameras the render
 * thread hands it. A lost connection, a protocol error, or ERROR / BYE from
 * the master end the thread; disp_client_status then says why. */
#ifndef CT_DISP_CLIENT_H
#define CT_DISP_CLIENT_H

#include <stdbool.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "display/disp_cache.h"
#include "display/disp_inbox.h"

typedef struct disp_client_opts {
    const char *addr;             /* unix:PATH or tcp:HOST:PORT */
    const char *token_file;       /* NULL: $CORRTEX_TOKEN, or none */
    uint32_t samples_per_frame;   /* lockstep K (0: free running) */
    int connect_timeout_ms;       /* connect + handshake */
    int silent_ms;                /* a master that completes no message (nor 64 KiB of one) this long is gone (0: 30000) */
} disp_client_opts;

typedef struct disp_client disp_client;

/* Connects, authenticates, sends SETTINGS and starts the connection thread,
 * which fills inbox until disp_client_close. */
int disp_client_connect(const disp_client_opts *o, disp_scene_cache *cache, disp_inbox *inbox,
                        disp_client **out, ct_error *err);

/* Stops the thread, sends BYE (best effort, briefly) and closes. NULL is fine. */
void disp_client_close(disp_client *c);

/* Queues a CAMERA with the next epoch for a width x height image. */
int disp_client_send_camera(disp_client *c, const ct_camera *cam, int width, int height, ct_error *err);

/* The epoch of the last CAMERA queued (0 before any). */
uint32_t disp_client_epoch(const disp_client *c);

/* CT_OK while the connection lives; else how it ended: CT_EIO when it was
 * lost or the master ended the session (BYE), CT_EPROTO on a protocol
 * violation or an ERROR from the master; err says which. */
int disp_client_status(disp_client *c, ct_error *err);

/* Whether the master ended the session in order (BYE). */
bool disp_client_ended(disp_client *c);

/* The master's clock minus ours, in microseconds, from the PING/PONG with
 * the shortest round trip so far; false until a PONG arrived. */
bool disp_client_clock_offset(disp_client *c, int64_t *offset_us);

#endif

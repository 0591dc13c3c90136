/* disp_client.h: the display's side of the socket protocol
 * (docs/protocol.md): connects to the master (handshake, token), sends
 * SETTINGS and CAMERA, and turns every received message into disp_session
 * events (scene, texture allocation / projection / patch / free, sample
 * points, frame ends, statistics). Announces the cached scene
 * (disp_cache.h) and fills the cache with a received one. Lost connections and ERROR / BYE from the master come back as
 * errors whose message says what happened. */
#ifndef CT_DISP_CLIENT_H
#define CT_DISP_CLIENT_H

#include <stdbool.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "display/disp_cache.h"
#include "display/disp_session.h"

typedef struct disp_client_opts {
    const char *addr;             /* unix:PATH or tcp:HOST:PORT */
    const char *token_file;       /* NULL: $CORRTEX_TOKEN, or none */
    uint32_t samples_per_frame;   /* lockstep K (0: free running) */
    int connect_timeout_ms;       /* connect + handshake */
} disp_client_opts;

typedef struct disp_client disp_client;

/* Connects, authenticates and sends SETTINGS (announcing cache's scene). */
int disp_client_connect(const disp_client_opts *o, disp_scene_cache *cache, disp_client **out,
                        ct_error *err);

/* Sends BYE (best effort, briefly) and closes. NULL is fine. */
void disp_client_close(disp_client *c);

/* Sends a CAMERA with the next epoch for a width x height image. */
int disp_client_send_camera(disp_client *c, const ct_camera *cam, int width, int height,
                            ct_error *err);

/* The epoch of the last CAMERA sent (0 before any). */
uint32_t disp_client_epoch(const disp_client *c);

/* Waits up to timeout_ms for traffic, sends what is queued and applies every
 * message that arrived to s. CT_EIO when the connection is lost or the master
 * ended the session, CT_EPROTO on a protocol violation or an ERROR from the
 * master, CT_EAUTH on a failed handshake; err says which. */
int disp_client_service(disp_client *c, disp_session *s, int timeout_ms, ct_error *err);

/* Lockstep: true (and the frame number) when a FRAME of the current epoch
 * arrived after the one last taken; disp_client_take_frame marks it used. */
bool disp_client_frame_ready(const disp_client *c, uint64_t *frame);
void disp_client_take_frame(disp_client *c);

/* Whether the master ended the session in order (BYE). */
bool disp_client_ended(const disp_client *c);

/* Whether a scene has arrived on this connection. */
bool disp_client_has_scene(const disp_client *c);

/* The master's address as given. */
const char *disp_client_addr(const disp_client *c);

#endif

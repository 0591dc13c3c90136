/* disp_master.h: a scripted master peer for display tests: a child process
 * that speaks the real display protocol (proto/chan.h) over a UNIX socket:
 * accepts one display, checks its SETTINGS (lockstep K) and CAMERA (image
 * size), sends the box scene of disp_fixture.h (as CACHED when SETTINGS
 * announced its hash), one 8x6 texture on the back
 * wall (object-local parallel, fxm_wall_proj, contents fxm_tex_rgb) in two
 * patches and FRAME 0 of the display's epoch with 123 samples, then ends
 * the way the test asks. */
#ifndef CT_TESTS_DISP_MASTER_H
#define CT_TESTS_DISP_MASTER_H

#include <stdint.h>
#include <sys/types.h>

#include "common/vecmath.h"
#include "proto/xport.h"

typedef enum fxm_end {
    FXM_END_CLOSE = 0,   /* close the socket without a word */
    FXM_END_BYE   = 1,   /* send BYE (run finished), then close */
    FXM_END_STAY  = 2,   /* wait (up to 5 s) for the display's BYE */
    FXM_END_BAD   = 3,   /* send a patch for an unknown texture; expect the display's ERROR */
    FXM_END_ROUNDS = 4,  /* FXM_ROUNDS lockstep rounds: each CAMERA is answered with a
                          * 1024x1024 texture in 32x32 patches (6 MiB, many reads) and
                          * the next FRAME */
    FXM_END_CAMERAS = 5, /* read until the display's BYE; succeed when the last CAMERA
                          * before it has eye.x == FXM_LAST_X */
    FXM_END_STALL = 6,   /* send 10 bytes of a TEX_PATCH frame, then nothing (no PONG
                          * either) for 5 s */
    FXM_END_DEAF = 7,    /* stop reading (the display's next writes fail), 0.5 s
                          * later send SYNC and ERROR FXM_DEAF_TEXT, and close */
    FXM_END_TRICKLE = 8, /* send a TEX_PATCH frame one byte every 50 ms (no PONG), for
                          * up to 5 s or until the display hangs up */
    FXM_END_FRAME_AGAIN = 9, /* send FRAME 5 twice, then wait (up to 5 s) for the end */
    FXM_END_RESIZES = 10 /* a 2048x2048 texture, then 1,000 TEX_RESIZE, to 4096x4096 and
                          * back in turn (minutes of work for the display), then wait
                          * (up to 10 s) for the end */
} fxm_end;

#define FXM_ROUNDS 30
#define FXM_LAST_X 42.0f
#define FXM_DEAF_TEXT "the job is ending"

typedef struct fxm_peer {
    pid_t pid;
    xport_listener *l;   /* kept open by the parent: closing it removes the socket file */
    char addr[300];      /* "unix:DIR/sock" */
    char dir[64];
    char msg[256];       /* why fxm_start failed */
    const char *token;   /* set before fxm_start: listen on TCP (loopback) and require this token */
} fxm_peer;

/* Starts the master child on a UNIX socket (or on TCP with p->token); 0 or
 * -1 (msg says why). The child exits 0 when everything it checked and sent
 * went as planned. */
int fxm_start(fxm_peer *p, fxm_end end, uint32_t samples_per_frame, int width, int height);

/* Waits for the child, removes the socket; returns the child's exit status. */
int fxm_stop(fxm_peer *p);

/* The texture the master sends (8 x 6 RGB floats, exact in half) and its
 * projection (back wall of the box, x, y in [-1, 1] -> [0, 1]). */
const float *fxm_tex_rgb(void);
mat4 fxm_wall_proj(void);

#endif

/* disp_inbox.h: what the master sent and the render thread has not drawn
 * yet. The connection thread (disp_client) fills it as messages arrive: the
 * newest scene, each texture's latest allocation and projection and a CPU
 * copy of its texels (a patch replaces texels in place, so many patches of
 * one area between two frames cost one upload), the tiles changed since the
 * last frame, sample points, statistics, lockstep frame ends and the view
 * the master suggests. Before each frame the render thread takes it
 * (disp_inbox_apply): scene and texture changes go to the disp_session,
 * changed tiles are copied into a pixel buffer and uploaded from there, at
 * most once per tile per frame. One mutex; the render thread holds it only
 * while it copies. Messages that do not fit (a texture of an unknown node,
 * a patch outside its texture) are refused when they arrive, so the
 * connection thread can tell the master. Owns the disp_inbox_ prefix. */
#ifndef CT_DISP_INBOX_H
#define CT_DISP_INBOX_H

#include <stdbool.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"
#include "common/radmesh.h"
#include "common/vecmath.h"
#include "display/disp_session.h"
#include "display/disp_textures.h"

/* Texels one frame uploads at most (bytes of the upload buffer, RGBA
 * halves): a larger backlog (a reconnect's whole state) is spread over the
 * next frames. */
#define DISP_INBOX_FRAME_BYTES (96u << 20)
/* Texels the inbox keeps in all (a bound against a hostile master). */
#define DISP_INBOX_MAX_BYTES (3ull << 30)

/* A patch that reached the screen: for the lag statistics (disp_lag.h). */
typedef struct disp_inbox_stamp {
    uint64_t stamp_us;     /* master clock of its oldest change */
    uint32_t samples;      /* samples it carries */
} disp_inbox_stamp;

/* What a frame took out of the inbox. */
typedef struct disp_inbox_took {
    uint64_t texels, patches;    /* uploaded / received since the last take */
    uint64_t uploads;            /* texture uploads (glTexSubImage2D calls) that made them */
    size_t upload_buffer_bytes;  /* the pixel buffer's storage after the take (kept between takes) */
    uint32_t nstamps;            /* stamps of the patches now on the textures */
    const disp_inbox_stamp *stamps;
} disp_inbox_took;

/* Lockstep and status state for the render thread. */
typedef struct disp_inbox_state {
    bool have_scene;             /* a scene arrived on this connection */
    bool frame_seen;             /* a FRAME of the current epoch arrived... */
    uint64_t frame_last;         /* ...with this number */
    bool have_view;              /* the master suggested a camera */
    ct_camera view;
    uint64_t bytes;              /* bytes received, over every connection of the session */
} disp_inbox_state;

typedef struct disp_inbox disp_inbox;

/* An empty inbox; max_tex is the largest texture side the GL accepts. */
int disp_inbox_new(int max_tex, disp_inbox **out, ct_error *err);
void disp_inbox_free(disp_inbox *b);

/* A new connection: forgets the lockstep state and the suggested view
 * (scene and textures stay until the master replaces them). */
void disp_inbox_connection(disp_inbox *b);

/* --- the connection thread ------------------------------------------------ */

/* SCENE: takes the mesh (m is emptied); every texture is dropped. */
void disp_inbox_scene(disp_inbox *b, ct_radmesh *m);
int disp_inbox_tex_alloc(disp_inbox *b, uint32_t id, uint32_t node, int w, int h, disp_proj_kind kind,
                         ct_error *err);
int disp_inbox_tex_projection(disp_inbox *b, uint32_t id, const mat4 *world_to_tex, ct_error *err);
/* TEX_RESIZE: the live texture id at an exact new size, its texels computed
 * from the copy here (disp_rescale.h); every tile goes up with the next
 * frame. */
int disp_inbox_tex_resize(disp_inbox *b, uint32_t id, int w, int h, ct_error *err);
/* TEX_PATCH: rgb holds w*h*3 halves; stamp and samples feed the lag
 * statistics. */
int disp_inbox_tex_patch(disp_inbox *b, uint32_t id, int x, int y, int w, int h, const uint16_t *rgb,
                         uint64_t stamp_us, uint32_t samples, ct_error *err);
int disp_inbox_tex_free(disp_inbox *b, uint32_t id, ct_error *err);
void disp_inbox_points(disp_inbox *b, const float *xyz, uint32_t n, uint64_t dropped);
/* FRAME k of display epoch `epoch` (it counts for lockstep only when that
 * is the epoch of the last CAMERA, disp_inbox_new_epoch). */
void disp_inbox_frame_end(disp_inbox *b, uint64_t frame, uint32_t epoch, uint32_t samples, bool all_positive);
void disp_inbox_stats(disp_inbox *b, uint64_t samples_total, bool all_positive);
void disp_inbox_view(disp_inbox *b, const ct_camera *cam);
void disp_inbox_bytes(disp_inbox *b, uint64_t total);

/* --- the render thread ----------------------------------------------------- */

/* A CAMERA of this epoch is being sent: a FRAME of an older one no longer
 * counts. */
void disp_inbox_new_epoch(disp_inbox *b, uint32_t epoch);

/* Applies everything that arrived to s (GL context current): scene,
 * texture allocations, projections, frees, changed tiles (at most
 * DISP_INBOX_FRAME_BYTES), points, frame ends, statistics. *took says what
 * (its stamps stay valid until the next call). */
int disp_inbox_apply(disp_inbox *b, disp_session *s, disp_inbox_took *took, ct_error *err);

/* Whether texels arrived that no apply has taken yet. */
bool disp_inbox_pending(disp_inbox *b);

/* Lockstep and status state. */
disp_inbox_state disp_inbox_get_state(disp_inbox *b);

/* Lockstep: marks the last FRAME as drawn (the next one must be newer). */
void disp_inbox_take_frame(disp_inbox *b);
/* Whether a FRAME newer than the last drawn arrived (and its number). */
bool disp_inbox_frame_ready(disp_inbox *b, uint64_t *frame);

/* Frees the pixel buffer (GL context current); before the context goes. */
void disp_inbox_release_gl(disp_inbox *b);

#endif

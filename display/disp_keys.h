/* disp_keys.h: what the window's keys do to the view (debug views, passes,
 * exposure) and which other actions they ask for (help, camera print, quit).
 * The fly camera's keys are in disp_camera_control.h. */
#ifndef CT_DISP_KEYS_H
#define CT_DISP_KEYS_H

#include "display/disp_compositor.h"

typedef enum disp_key_action {
    DISP_KEY_NONE    = 0,   /* not a view key (maybe a camera key) */
    DISP_KEY_CHANGED = 1,   /* the render options changed */
    DISP_KEY_HELP    = 2,   /* show the key help */
    DISP_KEY_CAMERA  = 3,   /* print the camera */
    DISP_KEY_QUIT    = 4
} disp_key_action;

/* Exposure step of the + and - keys, in stops. */
#define DISP_EXPOSURE_STEP 0.5f
/* The keys keep the exposure within --exposure's range (+-30 stops; 400
 * presses had reached 2^200, infinite in float). */
#define DISP_EXPOSURE_MAX 30.0f

/* Applies one key press (gl_backend.h key code) to o. */
disp_key_action disp_keys_apply(int key, disp_render_opts *o);

/* The key help text. */
const char *disp_keys_help(void);

#endif

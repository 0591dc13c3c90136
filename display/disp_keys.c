#include "display/disp_keys.h"

#include <math.h>

#include "display/gl_backend.h"

disp_key_action disp_keys_apply(int key, disp_render_opts *o)
{
    if (key >= '1' && key < '1' + DISP_VIEW_COUNT) {
        o->view = (disp_view)(key - '1');
        return DISP_KEY_CHANGED;
    }
    switch (key) {
    case 'P': o->passes = o->passes == 1 ? 3 : 1; return DISP_KEY_CHANGED;
    case '+': o->exposure = fminf(o->exposure + DISP_EXPOSURE_STEP, DISP_EXPOSURE_MAX); return DISP_KEY_CHANGED;
    case '-': o->exposure = fmaxf(o->exposure - DISP_EXPOSURE_STEP, -DISP_EXPOSURE_MAX); return DISP_KEY_CHANGED;
    case '0': o->exposure = 0.0f; return DISP_KEY_CHANGED;
    case 'H': case '?': case GL_KEY_F1: return DISP_KEY_HELP;
    case 'C': return DISP_KEY_CAMERA;
    case GL_KEY_ESCAPE: return DISP_KEY_QUIT;
    default: return DISP_KEY_NONE;
    }
}

const char *disp_keys_help(void)
{
    return "keys (window):\n"
           "  W/S or Up/Down      move forward / back\n"
           "  A/D or Left/Right   move left / right\n"
           "  E/Q or PgUp/PgDn    move up / down (Shift: 4x faster)\n"
           "  mouse drag          look around;  scroll: change speed\n"
           "  1  full image (radiosity + corrections)\n"
           "  2  radiosity only\n"
           "  3  corrections only (grey = 0, brighter = positive, darker = negative)\n"
           "  4  texture assignment colours (paper Fig. 5)\n"
           "  5  the master's sample points of the last frames as dots (paper Fig. 7)\n"
           "  P  toggle 1-pass / 3-pass compositing\n"
           "  + / -  exposure up / down half a stop;  0  exposure 0\n"
           "  C  print the camera as a path keyframe line\n"
           "  H, F1 or ?  this help;  Esc  quit\n";
}

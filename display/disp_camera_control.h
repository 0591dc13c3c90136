/* disp_camera_control.h: the fly camera of the window: move with WASD or
 * the arrow keys (Q/E or PageDown/PageUp down/up, Shift 4x faster), look by
 * dragging with a mouse button held, scroll to change the speed. Yaw turns
 * about the starting camera's up vector so the horizon stays level; pitch
 * stops 85 degrees above or below the horizon. */
#ifndef CT_DISP_CAMERA_CONTROL_H
#define CT_DISP_CAMERA_CONTROL_H

#include <stdbool.h>

#include "common/camera.h"
#include "display/gl_backend.h"

typedef struct disp_fly {
    ct_camera cam;
    vec3 world_up;
    float speed;       /* world units per second */
    float speed_min, speed_max;   /* what the scroll wheel may reach */
    float look;        /* radians per pixel of mouse motion */
} disp_fly;

/* Starts at cam; speed is a quarter of the scene diagonal per second, and
 * the scroll wheel keeps it within 10^-6 to 100 diagonals per second. */
void disp_fly_init(disp_fly *f, const ct_camera *cam, bounds3 scene);

/* Applies dt seconds of input; true when the camera changed. The eye
 * stays within +-CT_COORD_MAX, the range a master takes. */
bool disp_fly_update(disp_fly *f, const gl_input *in, double dt);

/* A camera that sees all of bounds from the +z side with the given
 * vertical field of view in degrees. */
ct_camera disp_camera_overview(bounds3 b, float fov_deg);

#endif

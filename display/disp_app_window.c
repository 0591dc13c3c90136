/* disp_app_window.c: what the window shows of the run and takes from the
 * user (disp_app_internal.h): the title's statistics and status, and the
 * keys that change the view or print the camera. */
#include "display/disp_app_internal.h"

#include <stdio.h>

#include "common/timer.h"
#include "display/disp_keys.h"
#include "display/disp_session.h"
#include "display/gl_backend.h"

void app_set_title(app *a, double now, bool force)
{
    double dt = now - a->stat_t0;
    if (!force && dt < 0.5) return;
    disp_counters c = disp_session_counters(a->session);
    double fps = dt > 0 ? (double)a->stat_frames / dt : 0;
    if (c.samples != a->sps_samples) {
        if (a->sps_t > 0 && now > a->sps_t && c.samples > a->sps_samples)
            a->sps_shown = (double)(c.samples - a->sps_samples) / (now - a->sps_t);
        a->sps_samples = c.samples;
        a->sps_t = now;
    } else if (a->sps_t > 0 && now - a->sps_t > 3.0) {
        a->sps_shown = 0.0;   /* no word for 3 s: nothing is being inserted */
    }
    if (a->sps_t == 0) a->sps_t = now;
    double sps = a->sps_shown;
    double bps = dt > 0 ? (double)(c.bytes - a->stat_c0.bytes) / dt : 0;
    char title[320], points[80] = "";
    if (a->ropts.view == DISP_VIEW_SAMPLES) {
        const float *pa, *pb;
        uint32_t na, nb;
        disp_session_points(a->session, &pa, &na, &pb, &nb);
        snprintf(points, sizeof points, " | %u sample points (%llu dropped by the master)", na + nb,
                 (unsigned long long)c.points_dropped);
    }
    snprintf(title, sizeof title,
             "corrtex | %.1f fps | %.0f samples/s | %u textures | %.1f kB/s | %s, %d-pass, exp %+.1f%s%s%s | H: help",
             fps, sps, disp_textures_count(disp_session_textures(a->session)), bps / 1024.0,
             disp_view_name(a->ropts.view), a->ropts.passes, a->ropts.exposure, points,
             a->status[0] ? " | " : "", a->status);
    gl_backend_set_title(a->backend, title);
    a->stat_t0 = now;
    a->stat_frames = 0;
    a->stat_c0 = c;
}

/* Handles key presses; false when the user asked to quit. */
bool app_handle_keys(app *a, const gl_input *in)
{
    for (int i = 0; i < in->npresses; i++) {
        switch (disp_keys_apply(in->presses[i], &a->ropts)) {
        case DISP_KEY_CHANGED: app_set_title(a, ct_now(), true); break;
        case DISP_KEY_HELP: fputs(disp_keys_help(), stdout); fflush(stdout); break;
        case DISP_KEY_CAMERA: {
            vec3 f;
            cam_axes(&a->fly.cam, NULL, NULL, &f);
            vec3 t = v3_add(a->fly.cam.eye, f);
            /* The time since the start, so that the lines of several
             * presses make a path (every line said 0, and two of them were
             * refused: "time 0 not after 0"). */
            printf("%.3f  %.4f %.4f %.4f  %.4f %.4f %.4f  %.2f\n", ct_now() - a->t_run0, a->fly.cam.eye.x, a->fly.cam.eye.y,
                   a->fly.cam.eye.z, t.x, t.y, t.z, a->fly.cam.fov_y * 180.0f / CT_PI);
            fflush(stdout);
            break;
        }
        case DISP_KEY_QUIT: return false;
        case DISP_KEY_NONE: break;
        }
    }
    return !in->close;
}

#include "display/disp_app.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/campath.h"
#include "common/log.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/timer.h"
#include "display/disp_camera_control.h"
#include "display/disp_capture.h"
#include "display/disp_session.h"
#include "display/disp_synthetic.h"
#include "display/gl_load.h"

#define COMP "corrtex-display"

void disp_app_defaults(disp_app_opts *o)
{
    memset(o, 0, sizeof *o);
    o->backend = gl_backend_default();
    o->width = 1024;    /* §5: the paper displays at 1024x1024 */
    o->height = 1024;
    o->exposure = 0.0f;
    o->passes = 1;
    o->view = DISP_VIEW_FULL;
    o->vsync = true;
    o->float_format = GL_RGBA32F;
    o->ambient = 0.3f;
    o->reconnect = false;
}

const char *disp_app_keys_help(void)
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
           "  5  sample positions of the last frames (paper Fig. 7)\n"
           "  P  toggle 1-pass / 3-pass compositing\n"
           "  + / -  exposure up / down half a stop;  0  exposure 0\n"
           "  C  print the camera as a path keyframe line\n"
           "  H or F1  this help;  Esc  quit\n";
}

typedef struct app {
    const disp_app_opts *o;
    gl_backend *backend;
    disp_session *session;
    disp_compositor *comp;
    disp_capture *capture;
    ct_radmesh mesh;          /* kept for synthetic textures */
    bool have_mesh;
    ct_campath path;
    bool have_path;
    disp_fly fly;
    bool have_cam;            /* fly.cam was set from the options or the scene */
    disp_render_opts ropts;
    /* title statistics */
    double stat_t0;
    uint32_t stat_frames;
    disp_counters stat_c0;
    char status[160];
} app;

static int load_solution(app *a, ct_error *err)
{
    const disp_app_opts *o = a->o;
    int rc;
    if (o->mesh) {
        /* rmesh_load (common/radmesh_io.c) is not on main yet. */
        return ct_fail(err, CT_EINVAL, "--mesh %s: this build cannot read .ctmesh files yet "
                       "(use --scene for a stand-in radiosity)", o->mesh);
        a->have_mesh = true;
        ct_info(COMP, "%s: %u vertices, %u triangles, %u nodes", o->mesh, a->mesh.nverts,
                a->mesh.ntris, a->mesh.nnodes);
    } else if (o->scene) {
        ct_scene *s = NULL;
        rc = scene_load(o->scene, &s, err);
        if (rc) return rc;
        /* A stand-in interactive solution: constant radiance per material. */
        rc = rmesh_from_scene(s, v3s(o->ambient), &a->mesh, err);
        if (!rc) {
            a->have_mesh = true;
            if (!a->have_cam && (o->camera_name || s->ncams)) {
                int c = o->camera_name ? scene_find_camera(s, o->camera_name) : 0;
                if (c < 0)
                    rc = ct_fail(err, CT_EINVAL, "%s: no camera named '%s'", o->scene, o->camera_name);
                else {
                    a->fly.cam = s->cams[c].cam;
                    a->have_cam = true;
                }
            }
            ct_info(COMP, "%s: %u triangles, %u nodes (stand-in radiosity, ambient %.2f)", o->scene,
                    a->mesh.ntris, a->mesh.nnodes, o->ambient);
        }
        scene_free(s);
        if (rc) return rc;
    } else {
        return ct_fail(err, CT_EINVAL, "nothing to show: give --mesh, --scene or --connect");
    }
    return CT_OK;
}

static void set_title(app *a, double now, bool force)
{
    double dt = now - a->stat_t0;
    if (!force && dt < 0.5) return;
    disp_counters c = disp_session_counters(a->session);
    double fps = dt > 0 ? (double)a->stat_frames / dt : 0;
    double sps = dt > 0 ? (double)(c.samples - a->stat_c0.samples) / dt : 0;
    double bps = dt > 0 ? (double)(c.bytes - a->stat_c0.bytes) / dt : 0;
    char title[256];
    snprintf(title, sizeof title,
             "corrtex | %.1f fps | %.0f samples/s | %u textures | %.1f kB/s | %s, %d-pass, exp %+.1f%s%s | H: help",
             fps, sps, disp_textures_count(disp_session_textures(a->session)), bps / 1024.0,
             disp_view_name(a->ropts.view), a->ropts.passes, a->ropts.exposure,
             a->status[0] ? " | " : "", a->status);
    gl_backend_set_title(a->backend, title);
    a->stat_t0 = now;
    a->stat_frames = 0;
    a->stat_c0 = c;
}

/* Handles key presses; false when the user asked to quit. */
static bool handle_keys(app *a, const gl_input *in)
{
    for (int i = 0; i < in->npresses; i++) {
        int k = in->presses[i];
        if (k >= '1' && k <= '5') a->ropts.view = (disp_view)(k - '1');
        else if (k == 'P') a->ropts.passes = a->ropts.passes == 1 ? 3 : 1;
        else if (k == '+') a->ropts.exposure += 0.5f;
        else if (k == '-') a->ropts.exposure -= 0.5f;
        else if (k == '0') a->ropts.exposure = 0.0f;
        else if (k == 'H' || k == GL_KEY_F1 || k == '?') fputs(disp_app_keys_help(), stdout);
        else if (k == 'C') {
            vec3 f;
            cam_axes(&a->fly.cam, NULL, NULL, &f);
            vec3 t = v3_add(a->fly.cam.eye, f);
            printf("0  %.4f %.4f %.4f  %.4f %.4f %.4f  %.2f\n", a->fly.cam.eye.x, a->fly.cam.eye.y,
                   a->fly.cam.eye.z, t.x, t.y, t.z, a->fly.cam.fov_y * 180.0f / CT_PI);
            fflush(stdout);
        } else if (k == GL_KEY_ESCAPE) return false;
        if (k != 'C' && k != 'H' && k != GL_KEY_F1) set_title(a, ct_now(), true);
    }
    return !in->close;
}

static int run(app *a, ct_error *err)
{
    const disp_app_opts *o = a->o;
    bool window = gl_backend_is_window(a->backend);
    int nframes = o->frames;
    if (!window && nframes == 0 && !a->have_path && !o->connect) nframes = 1;
    double t_start = ct_now(), t_last = t_start;
    a->stat_t0 = t_start;
    a->stat_c0 = disp_session_counters(a->session);
    disp_counters prev = a->stat_c0;
    float dur = a->have_path ? campath_duration(&a->path) : 0.0f;
    float t_first = a->have_path ? a->path.keys[0].t : 0.0f;
    size_t npx = (size_t)o->width * (size_t)o->height;
    float *rgb = NULL;
    if (a->capture) {
        rgb = malloc(npx * 3 * sizeof *rgb);
        if (!rgb) return ct_fail(err, CT_ENOMEM, "out of memory for a %dx%d frame", o->width, o->height);
    }
    double render_ms_sum = 0, first_ms = 0;
    uint32_t k = 0;
    int rc = CT_OK;
    gl_input in;
    memset(&in, 0, sizeof in);
    set_title(a, t_start, true);
    for (;; k++) {
        if (nframes > 0 && k >= (uint32_t)nframes) break;
        double now = ct_now();
        double dt = now - t_last;
        t_last = now;
        gl_backend_poll(a->backend, &in);
        if (!handle_keys(a, &in)) break;
        if (o->max_seconds > 0 && now - t_start >= o->max_seconds) break;
        double ftime = now - t_start;
        ct_camera cam;
        if (a->have_path) {
            if (nframes > 0) {
                cam = campath_frame(&a->path, (int)k, nframes);
                ftime = nframes > 1 ? (double)dur * k / (double)(nframes - 1) : 0.0;
            } else {
                if (ftime > dur && k > 0) break;
                cam = campath_eval(&a->path, t_first + (float)ftime);
            }
        } else {
            disp_fly_update(&a->fly, &in, dt);
            cam = a->fly.cam;
        }
        double t0 = ct_now();
        disp_render_stats rs;
        a->ropts.all_positive = disp_session_all_positive(a->session);
        rc = disp_compositor_render(a->comp, disp_session_scene_of(a->session),
                                    disp_session_textures(a->session), &cam, &a->ropts, &rs, err);
        uint32_t nxy = 0;
        const float *xy = disp_session_sample_xy(a->session, &nxy);
        if (!rc) rc = disp_compositor_present(a->comp, &a->ropts, xy, nxy, window, in.fb_width, in.fb_height, err);
        if (rc) break;
        if (window) gl_backend_present(a->backend);
        else gl.Finish();
        double frame_ms = 1000.0 * (ct_now() - t0);
        /* The first frame pays for shader compilation (JIT on llvmpipe). */
        if (k == 0) first_ms = frame_ms;
        else render_ms_sum += frame_ms;
        a->stat_frames++;
        if (a->capture) {
            disp_counters c = disp_session_counters(a->session);
            disp_frame_info fi = {k, ftime, cam, frame_ms, c.samples - prev.samples, c.texels - prev.texels,
                                  c.bytes - prev.bytes, disp_textures_count(disp_session_textures(a->session))};
            prev = c;
            disp_compositor_read_linear(a->comp, rgb);
            double rmse = 0, psnr = 0;
            rc = disp_capture_frame(a->capture, &fi, rgb, o->width, o->height, &rmse, &psnr, err);
            if (rc) break;
            if (o->ref_dir) ct_info(COMP, "frame %u: rmse %.5f, psnr %.2f dB", k, rmse, psnr);
        }
        set_title(a, ct_now(), false);
        if (!window && nframes > 1) ct_progress(COMP, (double)(k + 1) / nframes, 0, "frame %u/%d", k + 1, nframes);
    }
    if (!window && nframes > 1) ct_progress(COMP, 1.0, 1, "frame %u/%d", k, nframes);
    double total = ct_now() - t_start;
    if (k > 0) {
        double steady = k > 1 ? render_ms_sum / (k - 1) : first_ms;
        printf("display: %u frames in %.3f s; first frame %.1f ms; steady %.3f ms per frame = %.2f fps "
               "(render + present); %u textures, %s view, %d-pass, %s\n",
               k, total, first_ms, steady, steady > 0 ? 1000.0 / steady : 0.0,
               disp_textures_count(disp_session_textures(a->session)), disp_view_name(a->ropts.view),
               a->ropts.passes, gl_backend_name(gl_backend_kind_of(a->backend)));
    }
    free(rgb);
    return rc;
}

int disp_app_run(const disp_app_opts *o, ct_error *err)
{
    app a;
    memset(&a, 0, sizeof a);
    a.o = o;
    a.ropts.passes = o->passes;
    a.ropts.view = o->view;
    a.ropts.exposure = o->exposure;
    int status = DISP_EXIT_ERROR;
    int rc = CT_OK;
    if (o->path) {
        rc = campath_load(o->path, &a.path, err);
        if (rc) return DISP_EXIT_USAGE;
        a.have_path = true;
    }
    /* Input files first, so bad input fails before any window opens. */
    if (o->has_camera) {
        a.fly.cam = o->camera;
        a.have_cam = true;
    }
    rc = load_solution(&a, err);
    if (rc && rc != CT_ENOMEM && rc != CT_ESYS) status = DISP_EXIT_USAGE;
    if (!rc) rc = gl_backend_open(o->backend, o->width, o->height, "corrtex", o->vsync, &a.backend, err);
    if (!rc) {
        ct_info(COMP, "backend %s: %s, %s", gl_backend_name(o->backend), (const char *)gl.GetString(GL_RENDERER),
                (const char *)gl.GetString(GL_VERSION));
        rc = disp_session_new(&a.session, err);
    }
    if (!rc) rc = disp_compositor_new(o->width, o->height, o->float_format, &a.comp, err);
    if (!rc && a.have_mesh) rc = disp_session_scene(a.session, &a.mesh, err);
    if (!rc) {
        const disp_scene *sc = disp_session_scene_of(a.session);
        if (!a.have_cam) a.fly.cam = disp_camera_overview(disp_scene_bounds(sc), 50.0f);
        disp_fly_init(&a.fly, &a.fly.cam, disp_scene_bounds(sc));
        if (o->synthetic && a.have_mesh) {
            ct_camera c0 = a.have_path ? campath_frame(&a.path, 0, o->frames > 0 ? o->frames : 2) : a.fly.cam;
            uint32_t made = 0;
            rc = disp_synthetic_textures(a.session, &a.mesh, &c0, o->width, o->height, o->synthetic,
                                         o->synthetic_positive, &made, err);
            if (!rc)
                ct_info(COMP, "%u synthetic correction textures (%llu texels)", made,
                        (unsigned long long)disp_textures_texels(disp_session_textures(a.session)));
        }
    }
    if (!rc && o->out_dir) {
        rc = disp_capture_open(o->out_dir, o->ref_dir, o->exposure, &a.capture, err);
        if (rc) status = DISP_EXIT_USAGE;
    }
    if (!rc) {
        if (gl_backend_is_window(a.backend)) fputs("H or F1 in the window prints the keys\n", stdout);
        rc = run(&a, err);
        if (!rc && a.capture) {
            rc = disp_capture_close(a.capture, err);
            a.capture = NULL;
        }
        if (!rc) status = DISP_EXIT_OK;
        else if (rc == CT_EPARSE || rc == CT_EINVAL || rc == CT_ESTALE) status = DISP_EXIT_USAGE;
    }
    if (a.capture) {
        ct_error e2;
        disp_capture_close(a.capture, &e2);
    }
    disp_compositor_free(a.comp);
    disp_session_free(a.session);
    gl_backend_close(a.backend);
    if (a.have_mesh) rmesh_free(&a.mesh);
    if (a.have_path) campath_free(&a.path);
    return status;
}

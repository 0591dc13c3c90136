#include "display/disp_app.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "common/campath.h"
#include "common/log.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/timer.h"
#include "display/disp_camera_control.h"
#include "display/disp_capture.h"
#include "display/disp_client.h"
#include "display/disp_inbox.h"
#include "display/disp_keys.h"
#include "display/disp_lag.h"
#include "display/disp_session.h"
#include "display/disp_synthetic.h"
#include "display/gl_load.h"
#include "display/gl_target.h"
#include "proto/auth.h"

#include "display/disp_app_internal.h"

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
    o->sample_frames = DISP_SAMPLE_FRAMES;
    o->sample_max = DISP_SAMPLE_MAX;
    o->cache_max_mb = DISP_CACHE_MAX_MB;
}

const char *disp_app_keys_help(void)
{
    return disp_keys_help();
}


/* --path with --scene: the scene's path of that name first, else a path
 * file, as corrtex reference and naive resolve it (scene_path_or_file); the
 * scene is freed after loading, so the path is copied. */
static int scene_path(app *a, const ct_scene *s, ct_error *err)
{
    const disp_app_opts *o = a->o;
    ct_campath own;
    memset(&own, 0, sizeof own);
    const ct_campath *p = scene_path_or_file(s, o->scene, o->path, &own, err);
    if (!p) return CT_EINVAL;   /* bad input, whatever the file's error was */
    if (p == &own) {
        a->path = own;
    } else {
        int rc = campath_from_keys(p->keys, p->nkeys, p->up, o->scene, &a->path, err);
        if (rc) return rc;
        memcpy(a->path.name, p->name, sizeof a->path.name);
    }
    a->have_path = true;
    return CT_OK;
}

static int load_solution(app *a, ct_error *err)
{
    const disp_app_opts *o = a->o;
    int rc;
    if (o->mesh) {
        /* Any solution hash is accepted: a viewer has no scene to compare with. */
        rc = rmesh_load(o->mesh, 0, &a->mesh, err);
        if (rc) return rc;
        a->have_mesh = true;
        ct_info(COMP, "%s: %u vertices, %u triangles, %u nodes", o->mesh, a->mesh.nverts,
                a->mesh.ntris, a->mesh.nnodes);
    } else if (o->scene) {
        ct_scene *s = NULL;
        rc = scene_load(o->scene, &s, err);
        if (rc) return rc;
        /* A stand-in interactive solution: constant radiance per material. */
        if (o->path) rc = scene_path(a, s, err);
        if (!rc) rc = rmesh_from_scene(s, v3s(o->ambient), &a->mesh, err);
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
    } else if (!o->connect) {
        return ct_fail(err, CT_EINVAL, "nothing to show: give --mesh, --scene or --connect");
    }
    return CT_OK;
}

/* The run loop; returns 0, a negative CT_E* code, or DISP_EXIT_LOST. */
static int run(app *a, ct_error *err)
{
    const disp_app_opts *o = a->o;
    bool window = gl_backend_is_window(a->backend);
    int nframes = o->frames;
    if (!window && nframes == 0 && !a->have_path && !o->connect) nframes = 1;
    double t_start = ct_now(), t_last = t_start;
    a->t_run0 = t_start;
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
    double render_ms_sum = 0, first_ms = 0, cpu_ms_sum = 0, t_captured = 0;
    uint32_t k = 0;
    /* What the last frame drawn showed. */
    uint64_t drawn_gen = 0;
    ct_camera drawn_cam;
    memset(&drawn_cam, 0, sizeof drawn_cam);
    disp_render_opts drawn_opts = a->ropts;
    int drawn_w = 0, drawn_h = 0;
    double t_drawn = 0;      /* when the last frame began */
    double frame_cpu = 0;    /* CPU seconds of the last frame, taking what arrived included */
    int rc = CT_OK;
    bool fly_ready = disp_session_scene_of(a->session) != NULL;
    /* The scene the fly camera was started over (its triangle count and
     * bounds stand for its identity): a reconnection that brings another
     * scene starts over without --camera, or the old scene's camera (far
     * outside the new one, a black window) and speed stayed. */
    const disp_scene *sc0 = disp_session_scene_of(a->session);
    uint64_t fly_serial = sc0 ? disp_scene_serial(sc0) : 0;
    uint32_t fly_ntris = sc0 ? disp_scene_ntris(sc0) : 0;
    bounds3 fly_bounds = sc0 ? disp_scene_bounds(sc0) : b3_empty();
    bool path_done = false;
    gl_input in;
    memset(&in, 0, sizeof in);
    app_set_title(a, t_start, true);
    while (nframes <= 0 || k < (uint32_t)nframes) {
        double now = ct_now();
        double c_top = o->texel_cpu > 0.0 ? ct_process_cpu() : 0.0;
        double dt = now - t_last;
        t_last = now;
        gl_backend_poll(a->backend, &in);
        if (!app_handle_keys(a, &in)) break;
        if (o->max_seconds > 0 && now - t_start >= o->max_seconds) break;
        if (o->stop && *o->stop) break;
        bool last = path_done, ended = false;
        /* --texel-fps, --texel-cpu: where the display shares its host with
         * tracers, each frame drawn for new texels alone is CPU the tracers
         * lose (docs/display.md, "Sharing a host with the tracers"). Until
         * the next such frame is allowed the inbox is left alone: the
         * texels collect there, each tile uploaded once when the frame
         * comes. A free-running view only; a moving camera is drawn at
         * once, with what arrived. --texel-cpu weighs the CPU the last
         * frame took (taking in texels, drawing, tone mapping; llvmpipe's
         * threads included, as process CPU over the frame) against that
         * many cores of the wall time since it began: a frame of a few CPU
         * ms (a GPU, a small window) is not held back, software GL at
         * 1024^2 is. */
        a->hold_texels = o->connect && k > 0 && nframes <= 0 && o->samples_per_frame == 0 && !o->continuous &&
                         ((o->texel_fps > 0.0 && now - t_drawn < 1.0 / o->texel_fps) ||
                          (o->texel_cpu > 0.0 && now - t_drawn < frame_cpu / o->texel_cpu));
        if (o->connect) {
            int st = app_connection_begin(a, err);
            if (st == STEP_END) {
                /* The master ended the run: draw (and capture) what arrived, then stop. */
                if (!disp_session_scene_of(a->session)) break;
                last = ended = true;
            } else if (st == STEP_LOST || st == STEP_ERROR) {
                rc = st == STEP_LOST ? DISP_EXIT_LOST : CT_EIO;
                break;
            }
        }
        const disp_scene *now_scene = disp_session_scene_of(a->session);
        if (fly_ready && now_scene && disp_scene_serial(now_scene) != fly_serial) {
            bounds3 nb = disp_scene_bounds(now_scene);
            bool other = disp_scene_ntris(now_scene) != fly_ntris || memcmp(&nb, &fly_bounds, sizeof nb) != 0;
            if (other && !o->has_camera && !a->have_path) {
                ct_info(COMP, "another scene arrived: starting at its view");
                a->have_cam = false;
                fly_ready = false;
            }
            fly_serial = disp_scene_serial(now_scene);   /* the same scene again: keep flying */
        }
        if (!fly_ready && now_scene) {
            fly_serial = disp_scene_serial(now_scene);
            fly_ntris = disp_scene_ntris(now_scene);
            fly_bounds = disp_scene_bounds(now_scene);
            /* The scene arrived: start the fly camera over it, at the view
             * the master suggested when the user gave none. */
            bounds3 b = disp_scene_bounds(disp_session_scene_of(a->session));
            if (!a->have_cam) {
                disp_inbox_state is = a->inbox ? disp_inbox_get_state(a->inbox) : (disp_inbox_state){0};
                a->fly.cam = is.have_view ? is.view : disp_camera_overview(b, 50.0f);
                a->have_cam = true;
            }
            disp_fly_init(&a->fly, &a->fly.cam, b);
            fly_ready = true;
        }
        double ftime = now - t_start;
        ct_camera cam;
        if (a->have_path) {
            if (nframes > 0) {
                cam = campath_frame(&a->path, (int)k, nframes);
                ftime = nframes > 1 ? (double)dur * k / (double)(nframes - 1) : 0.0;
            } else {
                /* Real time: the frame at or after the path's end is its
                 * last, or the camera stops there for --hold seconds. */
                if (ftime >= dur) {
                    path_done = last = ftime >= dur + o->hold_seconds;
                    ftime = dur;
                }
                cam = campath_eval(&a->path, t_first + (float)ftime);
            }
        } else {
            if (fly_ready) disp_fly_update(&a->fly, &in, dt);
            cam = a->fly.cam;
        }
        /* Lockstep asks for the next frame ahead when its camera is known:
         * the next of N frames of a path, or the same still or fly camera. */
        ct_camera next = cam;
        bool have_next = o->samples_per_frame > 0 && (nframes <= 0 || k + 1 < (uint32_t)nframes) &&
                         (!a->have_path || nframes > 0);
        if (have_next && a->have_path) next = campath_frame(&a->path, (int)k + 1, nframes);
        if (o->connect && !ended) {
            int st = app_connection_step(a, a->have_path || a->have_cam ? &cam : NULL, have_next ? &next : NULL, &in,
                                     t_start, err);
            if (st == STEP_QUIT) break;
            if (st == STEP_END) {
                if (!disp_session_scene_of(a->session)) break;
                last = true;
            } else if (st == STEP_LOST || st == STEP_ERROR) {
                rc = st == STEP_LOST ? DISP_EXIT_LOST : CT_EIO;
                break;
            } else if (st == STEP_WAIT) {
                /* Nothing to draw yet: a dark grey window, the title says why. */
                if (window) {
                    gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
                    gl.Viewport(0, 0, in.fb_width, in.fb_height);
                    gl.ClearColor(0.1f, 0.1f, 0.1f, 1.0f);
                    gl.Clear(GL_COLOR_BUFFER_BIT);
                    gl_backend_present(a->backend);
                }
                continue;
            }
        }
        a->ropts.all_positive = disp_session_all_positive(a->session);
        /* A still picture is not drawn again: free running, a frame is
         * drawn when what it shows may have changed (the session's texels,
         * the camera, the render options, the window's size), when a
         * capture is due, and in a window at least 4 times a second. A
         * scripted path (--frames), lockstep and --continuous draw every
         * frame. Software GL takes a core for a 1024^2 frame: a display
         * that redrew an unchanged view took it from the tracers. */
        uint64_t gen = disp_session_image_gen(a->session);
        bool capture_due = a->capture && (k == 0 || last || (o->out_every > 0 && now - t_captured >= o->out_every));
        /* While held nothing was taken; a change of gen then is the
         * samples view's oldest points leaving, which can wait as well. */
        bool texels_due = gen != drawn_gen && !a->hold_texels;
        bool draw = o->continuous || nframes > 0 || o->samples_per_frame > 0 || k == 0 || last || capture_due ||
                    texels_due || !cam_same(&cam, &drawn_cam) || a->ropts.passes != drawn_opts.passes ||
                    a->ropts.view != drawn_opts.view || a->ropts.exposure != drawn_opts.exposure ||
                    a->ropts.all_positive != drawn_opts.all_positive || in.fb_width != drawn_w ||
                    in.fb_height != drawn_h || (window && now - t_drawn >= 0.25);
        /* A minimised or unmapped window, free running, shows nothing: it
         * drew 90 frames a second there, 70 % of a core taken from the
         * tracers. The connection thread goes on acknowledging updates and
         * the inbox keeps the newest texels for the frame on restore. */
        if (draw && window && in.hidden && k > 0 && !capture_due && !o->continuous && nframes == 0 &&
            o->samples_per_frame == 0)
            draw = false;
        if (!draw) {
            bool waiting = a->hold_texels && a->inbox && disp_inbox_pending(a->inbox);
            ct_sleep_us(2000);
            *(waiting ? &a->t_held : &a->t_idle) += ct_now() - now;
            continue;
        }
        if (a->hold_texels) {
            if ((rc = app_take_inbox(a, err))) break;
            gen = disp_session_image_gen(a->session);
        }
        drawn_gen = gen;
        drawn_cam = cam;
        drawn_opts = a->ropts;
        drawn_w = in.fb_width;
        drawn_h = in.fb_height;
        t_drawn = now;
        double t0 = ct_now(), c0 = ct_process_cpu();
        disp_render_stats rs;
        if (a->ropts.view == DISP_VIEW_SAMPLES) {
            const float *pa, *pb;
            uint32_t na, nb;
            uint64_t v = disp_session_points(a->session, &pa, &na, &pb, &nb);
            if (!a->points_uploaded || v != a->points_version) {
                rc = disp_compositor_set_points(a->comp, pa, na, pb, nb, err);
                if (rc) break;
                a->points_version = v;
                a->points_uploaded = true;
            }
        }
        disp_gpu_time_begin(a->gt, DISP_GT_DRAW);
        rc = disp_compositor_render(a->comp, disp_session_scene_of(a->session),
                                    disp_session_textures(a->session), &cam, &a->ropts, &rs, err);
        disp_gpu_time_end(a->gt);
        disp_gpu_time_begin(a->gt, DISP_GT_PRESENT);
        if (!rc) rc = disp_compositor_present(a->comp, &a->ropts, window, in.fb_width, in.fb_height, err);
        disp_gpu_time_end(a->gt);
        if (rc) break;
        a->kept_frames += rs.base_reused;
        a->screen_frames += rs.screen_pass;
        a->screen_px += rs.screen_px;
        disp_session_frame_drawn(a->session);
        if (window) gl_backend_present(a->backend);
        else gl.Finish();
        disp_gpu_time_poll(a->gt);
        app_count_lag(a);
        /* (not the first frame's: compiling the shaders is paid once, and
         * at 0.05 cores its 160 ms under the sanitizers held the view for
         * three seconds) */
        if (o->texel_cpu > 0.0 && k > 0) frame_cpu = ct_process_cpu() - c_top;
        double frame_ms = 1000.0 * (ct_now() - t0);
        /* The first frame pays for shader compilation (JIT on llvmpipe). */
        if (k == 0) {
            first_ms = frame_ms;
        } else {
            render_ms_sum += frame_ms;
            cpu_ms_sum += 1000.0 * (ct_process_cpu() - c0);
        }
        a->stat_frames++;
        if (a->capture && (o->out_every <= 0 || k == 0 || last || ct_now() - t_captured >= o->out_every)) {
            t_captured = ct_now();
            double cap0 = t_captured;
            disp_counters c = disp_session_counters(a->session);
            /* Lockstep: the FRAME's own count (STATS arrive between frames). */
            uint64_t fs = o->samples_per_frame > 0 ? c.frame_samples - prev.frame_samples : c.samples - prev.samples;
            disp_frame_info fi = {k, ftime, cam, frame_ms, fs, c.texels - prev.texels,
                                  c.bytes - prev.bytes, disp_textures_count(disp_session_textures(a->session)),
                                  ct_now() - t_start};
            prev = c;
            /* frames.csv alone needs no pixels: no read-back. */
            bool pixels = disp_capture_needs_pixels(a->capture);
            if (pixels) {
                disp_compositor_read_linear(a->comp, rgb);
                /* A negative correction splatted from a darker neighbour can
                 * take a pixel below zero (-0.07 in the Cornell box); the
                 * screen shows it as black, as the paper's clamping frame
                 * buffer did, and so does the captured radiance. The
                 * corrections view keeps its signs. */
                if (a->ropts.view == DISP_VIEW_FULL)
                    for (size_t i = 0; i < (size_t)3 * (size_t)o->width * (size_t)o->height; i++)
                        rgb[i] = fmaxf(rgb[i], 0.0f);
            }
            rc = disp_capture_frame(a->capture, &fi, pixels ? rgb : NULL, o->width, o->height, err);
            a->t_capture += ct_now() - cap0;
            if (rc) break;
        }
        app_set_title(a, ct_now(), false);
        k++;
        if (!window && nframes > 1) ct_progress(COMP, (double)k / nframes, 0, "frame %u/%d", k, nframes);
        if (last) break;
    }
    if (!window && nframes > 1) ct_progress(COMP, (double)k / nframes, 1, "frame %u/%d", k, nframes);
    double total = ct_now() - t_start;
    if (k > 0) {
        double steady = k > 1 ? render_ms_sum / (k - 1) : first_ms;
        double cpu = k > 1 ? cpu_ms_sum / (k - 1) : 0.0;
        printf("display: %u frames in %.3f s; first frame %.1f ms; steady %.3f ms per frame = %.2f fps "
               "(render + present), %.3f CPU ms per frame; %u textures, %s view, %d-pass, %s\n",
               k, total, first_ms, steady, steady > 0 ? 1000.0 / steady : 0.0, cpu,
               disp_textures_count(disp_session_textures(a->session)), disp_view_name(a->ropts.view),
               a->ropts.passes, gl_backend_name(gl_backend_kind_of(a->backend)));
    }
    if (k > 0 && o->connect)
        printf("display: per frame besides drawing: %.1f ms waiting for lockstep frames, %.1f ms taking what "
               "arrived (texel uploads), %.1f ms capturing\n",
               1000.0 * a->t_wait / k, 1000.0 * a->t_take / k, 1000.0 * a->t_capture / k);
    if (k > 0 && a->gt) {
        double ms[DISP_GT_STAGES];
        uint64_t nt[DISP_GT_STAGES], untimed;
        disp_gpu_time_totals(a->gt, ms, nt, &untimed);
        printf("display: GPU time per frame (timer queries): %.2f ms taking in texels (%llu takes, %.0f uploads of "
               "%.0f texels a frame), %.2f ms drawing, %.2f ms tone mapping and presenting%s\n",
               ms[DISP_GT_TAKE] / k, (unsigned long long)nt[DISP_GT_TAKE], (double)a->uploads / k,
               a->uploads ? (double)a->uploaded / (double)a->uploads : 0.0, ms[DISP_GT_DRAW] / k,
               ms[DISP_GT_PRESENT] / k, untimed ? " (some stages untimed)" : "");
    }
    if (a->kept_frames)
        printf("display: %llu of %u frames reused a still camera's kept base; %llu drew the corrections in screen "
               "space, %.2f screens of tiles a frame\n",
               (unsigned long long)a->kept_frames, k, (unsigned long long)a->screen_frames,
               a->screen_frames ? (double)a->screen_px / (double)a->screen_frames / ((double)o->width * o->height)
                                : 0.0);
    if (a->t_idle > 0.05)
        printf("display: nothing new to draw for %.1f s of %.1f s (no frame drawn then)\n", a->t_idle, total);
    if (a->t_held > 0.05)
        printf("display: new texels held back for %.1f s of %.1f s by --texel-fps / --texel-cpu\n", a->t_held, total);
    if (a->lag && a->lag->n)
        printf("display: lag from insertion at the master to the screen: median %.0f ms, p90 %.0f ms, p99 %.0f ms, "
               "max %.0f ms over %llu samples\n",
               disp_lag_quantile(a->lag, 0.5), disp_lag_quantile(a->lag, 0.9), disp_lag_quantile(a->lag, 0.99),
               a->lag->max_ms, (unsigned long long)a->lag->n);
    free(rgb);
    return rc;
}

/* The float target's samples a pixel for --msaa want (0: auto). A software
 * rasteriser pays for every sample with CPU the tracers on the same host
 * would use (docs/display.md, "Antialiasing"), so auto is 1 there and 4 on
 * a GPU; more than the context allows is cut to what it allows. */
static bool soft_renderer(void)
{
    const char *r = (const char *)gl.GetString(GL_RENDERER);
    return r && (strstr(r, "llvmpipe") || strstr(r, "softpipe") || strstr(r, "swrast") || strstr(r, "SWR"));
}

static int msaa_samples(int want)
{
    int max = gl_target_max_samples();
    if (want == 0) return soft_renderer() ? 1 : (4 < max ? 4 : max);
    if (want > max) ct_warn(COMP, "--msaa %d: the GL context allows %d samples a pixel; using %d", want, max, max);
    return want < max ? want : max;
}

int disp_app_run(const disp_app_opts *o, ct_error *err)
{
    app a;
    memset(&a, 0, sizeof a);
    a.o = o;
    a.ropts.passes = o->passes;
    a.ropts.full_redraw = o->full_redraw;
    a.ropts.kept = (disp_kept_corr)o->kept_corrections;
    a.ropts.view = o->view;
    a.ropts.exposure = o->exposure;
    int status = DISP_EXIT_ERROR;
    int rc = CT_OK;
    /* With --scene, load_solution takes --path: it may name one of the
     * scene's paths. */
    if (o->path && !o->scene) {
        struct stat st;
        rc = campath_load(o->path, &a.path, err);
        if (rc && stat(o->path, &st) != 0 && !strchr(o->path, '/'))
            ct_fail(err, rc, "--path %s: no such path file (a scene's path name needs --scene; for --connect or "
                    "--mesh write it out: corrtex info SCENE --path NAME > NAME.path)", o->path);
        if (rc) return DISP_EXIT_USAGE;
        a.have_path = true;
    }
    /* Input files first, so bad input fails before any window opens; a bad
     * token file is bad input too, not a lost connection (exit 3). */
    if (o->connect) {
        auth_token tok;
        bool have;
        rc = auth_token_get(o->token_file, &tok, &have, err);
        auth_token_wipe(&tok);
        if (rc) return DISP_EXIT_USAGE;
    }
    if (o->has_camera) {
        a.fly.cam = o->camera;
        a.have_cam = true;
    }
    rc = load_solution(&a, err);
    if (rc && rc != CT_ENOMEM && rc != CT_ESYS) status = DISP_EXIT_USAGE;
    if (!rc) {
        rc = gl_backend_open(o->backend, o->width, o->height, "corrtex", o->vsync, &a.backend, err);
        if (rc == CT_EINVAL) status = DISP_EXIT_USAGE;   /* e.g. a malformed CORRTEX_EGL_DEVICE */
    }
    int samples = 1;
    if (!rc) {
        samples = msaa_samples(o->msaa);
        ct_info(COMP, "backend %s: %s, %s, %d sample%s a pixel", gl_backend_name(o->backend),
                (const char *)gl.GetString(GL_RENDERER), (const char *)gl.GetString(GL_VERSION), samples,
                samples > 1 ? "s" : "");
        rc = disp_session_new(&a.session, err);
        if (!rc) disp_session_set_sample_limits(a.session, o->sample_frames, o->sample_max);
    }
    if (!rc) rc = disp_compositor_new(o->width, o->height, o->float_format, samples, &a.comp, err);
    if (rc == CT_ESYS && samples > 1) {
        /* A large window's multisampled targets may not fit the GPU's memory:
         * an aliased image beats none. */
        ct_warn(COMP, "%d samples a pixel at %dx%d: %s; drawing with 1", samples, o->width, o->height, err->msg);
        ct_error_clear(err);
        rc = disp_compositor_new(o->width, o->height, o->float_format, 1, &a.comp, err);
    }
    /* The stages' GPU time: on a software rasteriser it is the CPU time the
     * frame line reports already, and llvmpipe's queries cost frames (3-6 %
     * fewer streaming table at 1024x1024, two interleaved pairs), so auto
     * leaves them off there. */
    if (!rc && (o->gpu_times == DISP_GPU_TIMES_ON || (o->gpu_times == DISP_GPU_TIMES_AUTO && !soft_renderer())))
        rc = disp_gpu_time_new(&a.gt, err);
    if (!rc && a.have_mesh) rc = disp_session_scene(a.session, &a.mesh, err);
    if (!rc && o->connect) {
        GLint max = 0;
        gl.GetIntegerv(GL_MAX_TEXTURE_SIZE, &max);
        rc = disp_inbox_new(max < DISP_TEX_MAX_SIZE ? (int)max : DISP_TEX_MAX_SIZE, &a.inbox, err);
        if (!rc && !(a.lag = calloc(1, sizeof *a.lag))) rc = ct_fail(err, CT_ENOMEM, "out of memory for lag statistics");
        if (!rc) rc = disp_scene_cache_new(o->cache_dir, (uint64_t)o->cache_max_mb << 20, &a.cache, err);
        ct_error e;
        ct_error_clear(&e);
        if (!rc && app_try_connect(&a, &e) && app_connection_lost(&a, &e, ct_now(), err)) {
            status = DISP_EXIT_LOST;
            rc = CT_EIO;
        }
    }
    if (!rc && disp_session_scene_of(a.session)) {
        const disp_scene *sc = disp_session_scene_of(a.session);
        if (!a.have_cam) a.fly.cam = disp_camera_overview(disp_scene_bounds(sc), 50.0f);
        disp_fly_init(&a.fly, &a.fly.cam, disp_scene_bounds(sc));
        if (o->synthetic && a.have_mesh) {
            ct_camera c0 = a.have_path ? campath_frame(&a.path, 0, o->frames > 0 ? o->frames : 2) : a.fly.cam;
            uint32_t made = 0;
            rc = disp_synthetic_textures(a.session, &a.mesh, &c0, o->width, o->height, o->synthetic,
                                         o->synthetic_tiles, o->synthetic_positive, &made, err);
            if (!rc)
                ct_info(COMP, "%u synthetic correction textures (%llu texels)", made,
                        (unsigned long long)disp_textures_texels(disp_session_textures(a.session)));
        }
    }
    /* --out last: disp_capture_open makes the folder, once the solution,
     * the connection and the reference image are known good (the folder
     * was made before them, and a bad scene or no master left it behind). */
    if (!rc && o->out_dir) {
        rc = disp_capture_open(o->out_dir, o->ref_dir, o->exposure, !o->no_images, &a.capture, err);
        if (rc) status = DISP_EXIT_USAGE;
    }
    if (!rc) {
        if (gl_backend_is_window(a.backend)) fputs("H, F1 or ? in the window prints the keys\n", stdout);
        rc = run(&a, err);
        if (rc == DISP_EXIT_LOST) status = DISP_EXIT_LOST;
        if (!rc && a.capture) {
            rc = disp_capture_close(a.capture, err);
            a.capture = NULL;
        }
        if (!rc && o->connect && (!a.ever_connected || !disp_session_scene_of(a.session))) {
            /* --reconnect kept trying until the run ended: it drew frames
             * (and wrote them), but none of them is what was asked for. A
             * connection the master refused (ERROR BUSY: it serves another
             * display) got through the handshake but was never served: no
             * scene came (that ended with status 0). */
            rc = ct_fail(err, CT_EIO, "never connected to %s (last: %s)", o->connect,
                         a.last_cause.msg[0] ? a.last_cause.msg : "no answer");
            status = DISP_EXIT_LOST;
        }
        if (!rc) status = DISP_EXIT_OK;
        else if (rc == CT_EPARSE || rc == CT_EINVAL || rc == CT_ESTALE) status = DISP_EXIT_USAGE;
    }
    if (a.capture) {
        ct_error e2;
        disp_capture_close(a.capture, &e2);
    }
    disp_client_close(a.client);
    if (a.inbox) disp_inbox_release_gl(a.inbox);
    disp_inbox_free(a.inbox);
    free(a.lag);
    disp_scene_cache_free(a.cache);
    disp_gpu_time_free(a.gt);
    disp_compositor_free(a.comp);
    disp_session_free(a.session);
    gl_backend_close(a.backend);
    if (a.have_mesh) rmesh_free(&a.mesh);
    if (a.have_path) campath_free(&a.path);
    return status;
}

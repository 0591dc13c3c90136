/* The display program's run loop (disp_app_run) against a scripted master
 * over a UNIX socket: lost connection -> status 3 with a clear message; BYE
 * -> status 0 with the last state drawn and captured; lockstep frames;
 * --reconnect keeps drawing the last image while it retries. */
#include <criterion/criterion.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "common/image.h"
#include "display/disp_app.h"
#include "tests/support/disp_fixture.h"
#include "tests/support/disp_master.h"

#define W 64
#define H 48

/* One display run against the scripted master: the master, the display's
 * options and its output folder (empty when it writes none). */
typedef struct app {
    fxm_peer p;
    disp_app_opts o;
    char out[64];
} app;

/* Starts the scripted master (ending as `end`, lockstep spf) and fills a->o
 * to connect to it; with with_out also a fresh output folder a->out. */
static void start(app *a, fxm_end end, uint32_t spf, bool with_out)
{
    memset(a, 0, sizeof *a);
    cr_assert_eq(fxm_start(&a->p, end, spf, W, H), 0, "%s", a->p.msg);
    disp_app_opts *o = &a->o;
    disp_app_defaults(o);
    o->backend = GL_BACKEND_OSMESA;
    o->width = W;
    o->height = H;
    o->connect = a->p.addr;
    o->has_camera = true;
    o->camera = fx_box_camera();
    if (with_out) {
        snprintf(a->out, sizeof a->out, "/tmp/ctdisp-out-XXXXXX");
        cr_assert(mkdtemp(a->out));
        o->out_dir = a->out;
    }
}

/* Runs the display; returns its exit status (err says why). */
static int run(const app *a, ct_error *err)
{
    ct_error_clear(err);
    return disp_app_run(&a->o, err);
}

/* The path of file `name` in the run's output folder. */
static const char *out_file(const app *a, const char *name, char *path, size_t cap)
{
    snprintf(path, cap, "%s/%s", a->out, name);
    return path;
}

/* Expects the master to have exited 0 (everything it checked went as
 * planned) and removes the output folder. */
static void finish(app *a)
{
    cr_expect_eq(fxm_stop(&a->p), 0);
    if (a->out[0]) {
        char cmd[400];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", a->out);
        cr_expect_eq(system(cmd), 0);
    }
}

static int count_lines(const char *path)
{
    FILE *f = fopen(path, "r");
    if (!f) return -1;
    int n = 0, c;
    while ((c = fgetc(f)) != EOF) n += c == '\n';
    fclose(f);
    return n;
}

Test(disp_app, lost_connection_exits_3)
{
    app a;
    start(&a, FXM_END_CLOSE, 0, false);
    ct_error err;
    int st = run(&a, &err);
    printf("exit %d: %s\n", st, err.msg);
    cr_expect_eq(st, DISP_EXIT_LOST);
    cr_expect(strstr(err.msg, "lost") && strstr(err.msg, a.p.addr), "message: %s", err.msg);
    finish(&a);
}

Test(disp_app, bye_draws_the_last_state_and_exits_0)
{
    app a;
    start(&a, FXM_END_BYE, 0, true);
    ct_error err;
    int st = run(&a, &err);
    cr_expect_eq(st, DISP_EXIT_OK, "exit %d: %s", st, err.msg);
    char path[200];
    int lines = count_lines(out_file(&a, "frames.csv", path, sizeof path));
    cr_expect_geq(lines, 2, "frames.csv has %d lines", lines);
    struct stat sb;
    cr_expect_eq(stat(out_file(&a, "frame_00000.png", path, sizeof path), &sb), 0, "no %s", path);
    /* The wall's texture has corrections down to -0.25, below the wall's
     * radiosity in places: the captured radiance is clamped at zero, as
     * the screen shows it (it held negative pixels). */
    ct_image img;
    cr_assert_eq(img_read_exr(out_file(&a, "frame_00000.exr", path, sizeof path), &img, &err), 0, "%s", err.msg);
    size_t neg = 0, zero = 0;
    for (size_t i = 0; i < (size_t)3 * (size_t)img.width * (size_t)img.height; i++) {
        neg += img.px[i] < 0.0f;
        zero += img.px[i] == 0.0f;
    }
    printf("metric: captured frame: %zu negative values, %zu zeros\n", neg, zero);
    cr_expect_eq(neg, 0, "%zu negative values in the captured radiance", neg);
    img_free(&img);
    finish(&a);
}

Test(disp_app, lockstep_frame_then_bye_from_display)
{
    app a;
    start(&a, FXM_END_STAY, 250, true);
    a.o.samples_per_frame = 250;
    a.o.frames = 1;
    ct_error err;
    int st = run(&a, &err);
    cr_expect_eq(st, DISP_EXIT_OK, "exit %d: %s", st, err.msg);
    char path[200];
    FILE *f = fopen(out_file(&a, "frames.csv", path, sizeof path), "r");
    cr_assert(f);
    char line[512] = "", row[512] = "";
    cr_assert(fgets(line, sizeof line, f));
    cr_assert(fgets(row, sizeof row, f));
    fclose(f);
    /* frame 0 carries the master's 123 samples, 48 texels and 1 texture. */
    int n = 0;
    char *save = NULL;
    const char *fields[16];
    for (char *t = strtok_r(row, ",\n", &save); t && n < 16; t = strtok_r(NULL, ",\n", &save)) fields[n++] = t;
    cr_assert_eq(n, 16, "row has %d fields", n);
    cr_expect_str_eq(fields[11], "123");
    cr_expect_str_eq(fields[12], "48");
    cr_expect_str_eq(fields[14], "1");
    /* The master exits 0 only when the display said BYE. */
    finish(&a);
}

Test(disp_app, reconnect_keeps_drawing_the_last_image)
{
    app a;
    start(&a, FXM_END_CLOSE, 0, true);
    a.o.reconnect = true;
    a.o.max_seconds = 1.5;
    /* Every frame drawn: the loop must not stall while reconnecting. */
    a.o.continuous = true;
    ct_error err;
    int st = run(&a, &err);
    cr_expect_eq(st, DISP_EXIT_OK, "exit %d: %s", st, err.msg);
    char path[200];
    int lines = count_lines(out_file(&a, "frames.csv", path, sizeof path));
    printf("frames drawn while reconnecting: %d\n", lines - 1);
    cr_expect_gt(lines, 3, "only %d frames drawn", lines - 1);
    /* The last frame still shows the corrected image: its texture count is 1. */
    FILE *f = fopen(path, "r");
    cr_assert(f);
    char line[512], last[512] = "";
    while (fgets(line, sizeof line, f)) snprintf(last, sizeof last, "%s", line);
    fclose(f);
    /* textures is the 15th column */
    const char *p = last;
    for (int i = 0; i < 14 && p; i++) {
        p = strchr(p, ',');
        if (p) p++;
    }
    cr_assert(p, "last row: %s", last);
    cr_expect_eq(atoi(p), 1, "last row: %s", last);
    finish(&a);
}

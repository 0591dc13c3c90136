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

#include "display/disp_app.h"
#include "tests/support/disp_fixture.h"
#include "tests/support/disp_master.h"

#define W 64
#define H 48

/* Starts the scripted master (ending as `end`, lockstep spf) and fills o
 * to connect to it; with out (64 bytes) also a fresh output folder there. */
static void start(fxm_peer *p, fxm_end end, uint32_t spf, disp_app_opts *o, char *out)
{
    cr_assert_eq(fxm_start(p, end, spf, W, H), 0, "%s", p->msg);
    disp_app_defaults(o);
    o->backend = GL_BACKEND_OSMESA;
    o->width = W;
    o->height = H;
    o->connect = p->addr;
    o->has_camera = true;
    o->camera = fx_box_camera();
    if (out) {
        snprintf(out, 64, "/tmp/ctdisp-out-XXXXXX");
        cr_assert(mkdtemp(out));
        o->out_dir = out;
    }
}

/* Runs the display; returns its exit status (err says why). */
static int run(const disp_app_opts *o, ct_error *err)
{
    ct_error_clear(err);
    return disp_app_run(o, err);
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

static void rm_out(const char *dir)
{
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    cr_expect_eq(system(cmd), 0);
}

Test(disp_app, lost_connection_exits_3)
{
    fxm_peer p = {0};
    disp_app_opts o;
    start(&p, FXM_END_CLOSE, 0, &o, NULL);
    ct_error err;
    int st = run(&o, &err);
    printf("exit %d: %s\n", st, err.msg);
    cr_expect_eq(st, DISP_EXIT_LOST);
    cr_expect(strstr(err.msg, "lost") && strstr(err.msg, p.addr), "message: %s", err.msg);
    cr_expect_eq(fxm_stop(&p), 0);
}

Test(disp_app, bye_draws_the_last_state_and_exits_0)
{
    fxm_peer p = {0};
    char out[64];
    disp_app_opts o;
    start(&p, FXM_END_BYE, 0, &o, out);
    ct_error err;
    int st = run(&o, &err);
    cr_expect_eq(st, DISP_EXIT_OK, "exit %d: %s", st, err.msg);
    char path[200];
    snprintf(path, sizeof path, "%s/frames.csv", out);
    int lines = count_lines(path);
    cr_expect_geq(lines, 2, "frames.csv has %d lines", lines);
    snprintf(path, sizeof path, "%s/frame_00000.png", out);
    struct stat sb;
    cr_expect_eq(stat(path, &sb), 0, "no %s", path);
    cr_expect_eq(fxm_stop(&p), 0);
    rm_out(out);
}

Test(disp_app, lockstep_frame_then_bye_from_display)
{
    fxm_peer p = {0};
    char out[64];
    disp_app_opts o;
    start(&p, FXM_END_STAY, 250, &o, out);
    o.samples_per_frame = 250;
    o.frames = 1;
    ct_error err;
    int st = run(&o, &err);
    cr_expect_eq(st, DISP_EXIT_OK, "exit %d: %s", st, err.msg);
    char path[200];
    snprintf(path, sizeof path, "%s/frames.csv", out);
    FILE *f = fopen(path, "r");
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
    cr_assert_eq(n, 15, "row has %d fields", n);
    cr_expect_str_eq(fields[11], "123");
    cr_expect_str_eq(fields[12], "48");
    cr_expect_str_eq(fields[14], "1");
    /* The master exits 0 only when the display said BYE. */
    cr_expect_eq(fxm_stop(&p), 0);
    rm_out(out);
}

Test(disp_app, reconnect_keeps_drawing_the_last_image)
{
    fxm_peer p = {0};
    char out[64];
    disp_app_opts o;
    start(&p, FXM_END_CLOSE, 0, &o, out);
    o.reconnect = true;
    o.max_seconds = 1.5;
    ct_error err;
    int st = run(&o, &err);
    cr_expect_eq(st, DISP_EXIT_OK, "exit %d: %s", st, err.msg);
    char path[200];
    snprintf(path, sizeof path, "%s/frames.csv", out);
    int lines = count_lines(path);
    printf("frames drawn while reconnecting: %d\n", lines - 1);
    cr_expect_gt(lines, 3, "only %d frames drawn", lines - 1);
    /* The last frame still shows the corrected image: its texture count is 1. */
    FILE *f = fopen(path, "r");
    cr_assert(f);
    char line[512], last[512] = "";
    while (fgets(line, sizeof line, f)) snprintf(last, sizeof last, "%s", line);
    fclose(f);
    const char *comma = strrchr(last, ',');
    cr_assert(comma);
    cr_expect_eq(atoi(comma + 1), 1, "last row: %s", last);
    cr_expect_eq(fxm_stop(&p), 0);
    rm_out(out);
}

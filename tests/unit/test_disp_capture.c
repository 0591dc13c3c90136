/* The display's frame output: frames queued faster than they are written
 * all land, in order, with their rows (and reference errors) in
 * frames.csv (zeros unsigned); a frame that cannot be written is reported by a later call
 * and by close, naming the file. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "common/image.h"
#include "common/metrics.h"
#include "display/disp_capture.h"

#define W 96
#define H 64
#define N 12

static char dir[64];

static void setup(void)
{
    snprintf(dir, sizeof dir, "/tmp/ctcap-XXXXXX");
    cr_assert(mkdtemp(dir));
}

static void teardown(void)
{
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    cr_expect_eq(system(cmd), 0);
}

static void fill(float *rgb, unsigned k)
{
    for (int i = 0; i < W * H * 3; i++) rgb[i] = (float)((i * 7 + (int)k * 13) % 97) / 97.0f;
}

static disp_frame_info info(unsigned k)
{
    disp_frame_info fi;
    memset(&fi, 0, sizeof fi);
    fi.frame = k;
    fi.time = 0.1 * k;
    fi.cam.orient.w = 1.0f;
    /* a camera looking down an axis: zeros with the sign bit */
    fi.cam.orient.x = -0.0f;
    fi.cam.eye.y = -0.0f;
    fi.cam.fov_y = 1.0f;
    fi.samples = 1000u + k;
    fi.wall = 0.2 * k;
    return fi;
}

static char *path_of(const char *name)
{
    static char p[256];
    snprintf(p, sizeof p, "%s/%s", dir, name);
    return p;
}

TestSuite(disp_capture, .init = setup, .fini = teardown);

Test(disp_capture, every_queued_frame_is_written_in_order_with_its_error)
{
    ct_error err;
    /* One reference for every frame: frame 0's image. */
    static float rgb[W * H * 3], ref_px[W * H * 3];
    fill(ref_px, 0);
    ct_image ref = {W, H, ref_px};
    char refpath[256];
    snprintf(refpath, sizeof refpath, "%s/ref.exr", dir);
    cr_assert_eq(img_write_exr(refpath, &ref, IMG_FLOAT, &err), 0, "%s", err.msg);
    char out[256];
    snprintf(out, sizeof out, "%s/out", dir);
    disp_capture *c = NULL;
    cr_assert_eq(disp_capture_open(out, refpath, 0.0f, true, &c, &err), 0, "%s", err.msg);
    double want_rmse[N];
    for (unsigned k = 0; k < N; k++) {
        fill(rgb, k);
        ct_image img = {W, H, rgb};
        img_metrics m;
        cr_assert_eq(metrics_compare(&img, &ref, &m, &err), 0);
        want_rmse[k] = m.rmse;
        disp_frame_info fi = info(k);
        cr_assert_eq(disp_capture_frame(c, &fi, rgb, W, H, &err), 0, "%s", err.msg);
        /* The caller's buffer is its own again at once. */
        memset(rgb, 0xff, sizeof rgb);
    }
    cr_assert_eq(disp_capture_close(c, &err), 0, "%s", err.msg);
    for (unsigned k = 0; k < N; k++) {
        char name[64];
        snprintf(name, sizeof name, "out/frame_%05u.exr", k);
        ct_image got;
        cr_assert_eq(img_read_exr(path_of(name), &got, &err), 0, "%s", err.msg);
        fill(rgb, k);
        double dmax = 0;
        for (int i = 0; i < W * H * 3; i++) dmax = fmax(dmax, fabs(got.px[i] - rgb[i]));
        cr_expect_lt(dmax, 1e-3, "frame %u: max difference %g (half precision)", k, dmax);
        img_free(&got);
        snprintf(name, sizeof name, "out/frame_%05u.png", k);
        struct stat st;
        cr_expect_eq(stat(path_of(name), &st), 0, "%s missing", name);
    }
    FILE *f = fopen(path_of("out/frames.csv"), "r");
    cr_assert(f);
    char line[1024];
    cr_assert(fgets(line, sizeof line, f));
    cr_expect(strstr(line, ",wall_s,rmse,psnr_db") != NULL, "%s", line);
    unsigned rows = 0;
    double worst = 0;
    while (fgets(line, sizeof line, f)) {
        unsigned frame = 0;
        cr_assert_eq(sscanf(line, "%u,", &frame), 1);
        cr_expect_eq(frame, rows, "rows in frame order");
        cr_expect(!strstr(line, ",-0,"), "a signed zero printed as -0: %s", line);
        const char *p = line;
        for (int comma = 0; comma < 16; comma++) p = strchr(p, ',') + 1;
        double rmse = atof(p);
        if (frame == 0) cr_expect_lt(rmse, 1e-6, "frame 0 is the reference");
        else worst = fmax(worst, fabs(rmse - want_rmse[frame]) / want_rmse[frame]);
        rows++;
    }
    fclose(f);
    cr_expect_eq(rows, N);
    printf("metric: %u frames written by the writer thread; rmse against the reference within %.2g (relative)\n", rows,
           worst);
    cr_expect_lt(worst, 1e-4, "rmse in frames.csv differs from the image's");
}

Test(disp_capture, a_frame_that_cannot_be_written_is_reported)
{
    ct_error err;
    char out[256];
    snprintf(out, sizeof out, "%s/out", dir);
    disp_capture *c = NULL;
    cr_assert_eq(disp_capture_open(out, NULL, 0.0f, true, &c, &err), 0, "%s", err.msg);
    /* A directory where frame 1's EXR should go: the rename onto it fails. */
    cr_assert_eq(mkdir(path_of("out/frame_00001.exr"), 0755), 0);
    static float rgb[W * H * 3];
    int rc = 0;
    unsigned k = 0;
    for (; k < 50 && !rc; k++) {
        fill(rgb, k);
        disp_frame_info fi = info(k);
        rc = disp_capture_frame(c, &fi, rgb, W, H, &err);
    }
    ct_error e2;
    int rc2 = disp_capture_close(c, &e2);
    if (!rc) {
        rc = rc2;
        err = e2;
    }
    printf("write error reported after queueing %u frames: %s\n", k, err.msg);
    cr_expect_neq(rc, 0);
    cr_expect_neq(rc2, 0, "close reports it too");
    cr_expect(strstr(err.msg, "frame_00001.exr") != NULL, "%s", err.msg);
    struct stat st;
    cr_expect_eq(stat(path_of("out/frame_00000.png"), &st), 0, "frame 0 was written");
    cr_expect_eq(stat(path_of("out/frames.csv"), &st), 0, "frames.csv is written at close");
}

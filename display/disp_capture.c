#include "display/disp_capture.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <sys/stat.h>

#include "common/fsutil.h"
#include "common/image.h"
#include "common/log.h"
#include "common/metrics.h"

/* frames.csv is rewritten every this many frames (and at the end). */
#define CSV_EVERY 25

/* Frames waiting for the writer: encoding a 1024^2 frame (EXR and PNG)
 * takes about 170 ms here, longer than drawing it, so it runs on its own
 * thread; a third frame waits for a free slot (output is never dropped). */
#define SLOTS 2

typedef struct cap_job {
    disp_frame_info fi;
    float *rgb;
    size_t cap;          /* floats allocated in rgb */
    int width, height;
} cap_job;

struct disp_capture {
    pthread_t writer;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    cap_job jobs[SLOTS];
    unsigned head, count; /* ring of queued jobs */
    bool writing;         /* the writer holds the job at head */
    bool stop;
    int rc;               /* the writer's first error (sticky) */
    ct_error err;
    char dir[2048];
    char ref_dir[2048];
    bool has_ref;
    ct_image ref_one;   /* one reference for every frame (ref_dir: its file) */
    metrics_ref *ref_prep; /* ref_one prepared: a frame's comparison tone-maps only the frame */
    bool images;
    float exposure;
    char *csv;          /* rows so far */
    size_t len, cap;
    uint32_t rows;
};

static void *writer_main(void *arg);

static const char *header =
    "frame,time_s,eye_x,eye_y,eye_z,q_w,q_x,q_y,q_z,fov_deg,frame_ms,samples,texels,bytes,textures,wall_s";

int disp_capture_open(const char *dir, const char *ref, float exposure, bool images, disp_capture **out,
                      ct_error *err)
{
    *out = NULL;
    int rc;
    disp_capture *c = calloc(1, sizeof *c);
    if (!c) return ct_fail(err, CT_ENOMEM, "out of memory for frame capture");
    snprintf(c->dir, sizeof c->dir, "%s", dir);
    struct stat st;
    if (ref && stat(ref, &st) == 0 && S_ISREG(st.st_mode)) {
        /* One image: a still view's converged reference. */
        if ((rc = img_read_exr(ref, &c->ref_one, err)) || (rc = metrics_ref_new(&c->ref_one, &c->ref_prep, err))) {
            ct_error_prefix(err, "reference");
            img_free(&c->ref_one);
            free(c);
            return rc;
        }
        snprintf(c->ref_dir, sizeof c->ref_dir, "%s", ref);   /* (its name, for messages) */
        c->has_ref = true;
    } else if (ref) {
        snprintf(c->ref_dir, sizeof c->ref_dir, "%s", ref);
        c->has_ref = true;
    }
    /* The folder once the reference image is read: a bad one leaves nothing. */
    if ((rc = fs_mkdirs(dir, err))) {
        metrics_ref_free(c->ref_prep);
        img_free(&c->ref_one);
        free(c);
        return rc;
    }
    c->images = images;
    c->exposure = exposure;
    pthread_mutex_init(&c->mu, NULL);
    pthread_cond_init(&c->cv, NULL);
    if (pthread_create(&c->writer, NULL, writer_main, c)) {
        pthread_mutex_destroy(&c->mu);
        pthread_cond_destroy(&c->cv);
        metrics_ref_free(c->ref_prep);
        img_free(&c->ref_one);
        free(c);
        return ct_fail(err, CT_ESYS, "cannot start the frame writer thread");
    }
    *out = c;
    return CT_OK;
}

static bool ref_exists(const char *dir, int k)
{
    char name[64], path[4096];
    struct stat st;
    snprintf(name, sizeof name, "frame_%05d.exr", k);
    fs_join(dir, name, path, sizeof path);
    return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

/* Checked before the first frame: a missing reference used to end the run
 * at that frame (exit 1, the frames before it drawn for nothing), and the
 * references of a walk of another frame count were compared with the
 * wrong cameras without a word (frame k of N is path time k/(N-1)). */
int disp_capture_check_refs(const char *dir, int frames, ct_error *err)
{
    int have = 0;
    while (have < frames && ref_exists(dir, have)) have++;
    if (have < frames)
        return ct_fail(err, CT_EINVAL,
                       "--reference %s: frame_%05d.exr missing: %d reference frame%s there, --frames %d needs %d "
                       "(corrtex reference --frames %d)",
                       dir, have, have, have == 1 ? "" : "s", frames, frames, frames);
    if (!ref_exists(dir, frames)) return CT_OK;
    /* (bounded as --frames is: a folder cannot hold more references than
     * any run could use) */
    while (have < 10000000 && ref_exists(dir, have)) have++;
    return ct_fail(err, CT_EINVAL,
                   "--reference %s: %d reference frames there, made for --frames %d, not %d: their cameras are not "
                   "these frames'",
                   dir, have, have, frames);
}

static int append(disp_capture *c, const char *s, ct_error *err)
{
    size_t n = strlen(s);
    if (c->len + n + 1 > c->cap) {
        size_t cap = c->cap ? c->cap : 4096;
        while (cap < c->len + n + 1) cap *= 2;
        char *p = realloc(c->csv, cap);
        if (!p) return ct_fail(err, CT_ENOMEM, "out of memory for frames.csv");
        c->csv = p;
        c->cap = cap;
    }
    memcpy(c->csv + c->len, s, n + 1);
    c->len += n;
    return CT_OK;
}

static int write_csv(disp_capture *c, ct_error *err)
{
    char path[4096];
    fs_join(c->dir, "frames.csv", path, sizeof path);
    fs_atomic a;
    int rc = fs_atomic_open(&a, path, err);
    if (rc) return rc;
    fprintf(a.f, "%s%s\n", header, c->has_ref ? ",rmse,psnr_db" : "");
    if (c->len) fwrite(c->csv, 1, c->len, a.f);
    return fs_atomic_commit(&a, err);
}

/* x with -0 as 0: a camera looking down an axis has quaternion parts of
 * -0, which printed "-0" in frames.csv and made diffs of equal paths. */
static double unsigned_zero(float x) { return (double)x + 0.0; }

static int write_frame(disp_capture *c, const disp_frame_info *fi, const float *rgb, int width, int height,
                       ct_error *err)
{
    char name[64], path[4096];
    ct_image img = {width, height, (float *)rgb};
    int rc;
    if (c->images) {
        snprintf(name, sizeof name, "frame_%05u.exr", fi->frame);
        fs_join(c->dir, name, path, sizeof path);
        if ((rc = img_write_exr(path, &img, IMG_HALF, err))) return rc;
        snprintf(name, sizeof name, "frame_%05u.png", fi->frame);
        fs_join(c->dir, name, path, sizeof path);
        if ((rc = img_write_png(path, &img, c->exposure, err))) return rc;
    }

    char row[768];
    int n = snprintf(row, sizeof row, "%u,%.6f,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.4g,%.3f,%llu,%llu,%llu,%u,%.6f",
                     fi->frame, fi->time, unsigned_zero(fi->cam.eye.x), unsigned_zero(fi->cam.eye.y),
                     unsigned_zero(fi->cam.eye.z), unsigned_zero(fi->cam.orient.w), unsigned_zero(fi->cam.orient.x),
                     unsigned_zero(fi->cam.orient.y), unsigned_zero(fi->cam.orient.z),
                     fi->cam.fov_y * 180.0f / CT_PI, fi->frame_ms, (unsigned long long)fi->samples,
                     (unsigned long long)fi->texels, (unsigned long long)fi->bytes, fi->textures, fi->wall);
    if (c->has_ref) {
        ct_image ref = {0, 0, NULL};
        if (c->ref_one.px) {
            ref = c->ref_one;
            snprintf(path, sizeof path, "%s", c->ref_dir);
        } else {
            snprintf(name, sizeof name, "frame_%05u.exr", fi->frame);
            fs_join(c->ref_dir, name, path, sizeof path);
            rc = img_read_exr(path, &ref, err);
            if (rc) {
                ct_error_prefix(err, "reference");
                return rc;
            }
        }
        /* The writer shares the display's cores: the CSV has no SSIM
         * column, so none is computed. */
        img_metrics m;
        metrics_ref *prep = c->ref_prep;
        rc = prep ? 0 : metrics_ref_new(&ref, &prep, err);
        if (!rc) rc = metrics_compare_ref(&img, prep, METRICS_NO_SSIM, &m, err);
        if (prep != c->ref_prep) metrics_ref_free(prep);
        if (!c->ref_one.px) img_free(&ref);
        if (rc) {
            ct_error_prefix(err, path);
            return rc;
        }
        ct_info("corrtex-display", "frame %u: rmse %.5f, psnr %.2f dB", fi->frame, m.rmse, m.psnr);
        snprintf(row + n, sizeof row - (size_t)n, ",%.6g,%.4f", m.rmse, isinf(m.psnr) ? 999.0 : m.psnr);
    }
    size_t len = strlen(row);
    if (len > sizeof row - 2) len = sizeof row - 2;
    row[len] = '\n';
    row[len + 1] = '\0';
    rc = append(c, row, err);
    if (rc) return rc;
    if (++c->rows % CSV_EVERY == 0) return write_csv(c, err);
    return CT_OK;
}

static void *writer_main(void *arg)
{
    disp_capture *c = arg;
    pthread_mutex_lock(&c->mu);
    for (;;) {
        while (!c->count && !c->stop) pthread_cond_wait(&c->cv, &c->mu);
        if (!c->count) break;
        cap_job *j = &c->jobs[c->head];
        c->writing = true;
        bool failed = c->rc != 0;
        pthread_mutex_unlock(&c->mu);
        ct_error e;
        /* After an error the rest is dropped: the caller stops at its next frame. */
        int rc = failed ? 0 : write_frame(c, &j->fi, j->rgb, j->width, j->height, &e);
        pthread_mutex_lock(&c->mu);
        if (rc && !c->rc) {
            c->rc = rc;
            c->err = e;
        }
        c->writing = false;
        c->head = (c->head + 1) % SLOTS;
        c->count--;
        pthread_cond_broadcast(&c->cv);
    }
    pthread_mutex_unlock(&c->mu);
    return NULL;
}

bool disp_capture_needs_pixels(const disp_capture *c)
{
    return c->images || c->has_ref;
}

int disp_capture_frame(disp_capture *c, const disp_frame_info *fi, const float *rgb, int width, int height,
                       ct_error *err)
{
    size_t n = rgb ? (size_t)width * (size_t)height * 3 : 0;
    if (!rgb && disp_capture_needs_pixels(c))
        return ct_fail(err, CT_EINVAL, "frame %u: no pixels to write", fi->frame);
    pthread_mutex_lock(&c->mu);
    while (c->count == SLOTS && !c->rc) pthread_cond_wait(&c->cv, &c->mu);
    if (c->rc) {
        *err = c->err;
        int rc = c->rc;
        pthread_mutex_unlock(&c->mu);
        return rc;
    }
    cap_job *j = &c->jobs[(c->head + c->count) % SLOTS];
    pthread_mutex_unlock(&c->mu);
    /* The slot is ours until count covers it: the writer never touches it. */
    if (j->cap < n) {
        float *p = realloc(j->rgb, n * sizeof *p);
        if (!p) return ct_fail(err, CT_ENOMEM, "out of memory for a %dx%d frame to write", width, height);
        j->rgb = p;
        j->cap = n;
    }
    if (n) memcpy(j->rgb, rgb, n * sizeof *rgb);
    j->fi = *fi;
    j->width = width;
    j->height = height;
    pthread_mutex_lock(&c->mu);
    c->count++;
    pthread_cond_broadcast(&c->cv);
    pthread_mutex_unlock(&c->mu);
    return CT_OK;
}

int disp_capture_close(disp_capture *c, ct_error *err)
{
    if (!c) return CT_OK;
    /* Every queued frame is written before frames.csv. */
    pthread_mutex_lock(&c->mu);
    c->stop = true;
    pthread_cond_broadcast(&c->cv);
    pthread_mutex_unlock(&c->mu);
    pthread_join(c->writer, NULL);
    int rc = c->rc;
    if (rc) *err = c->err;
    ct_error e;
    int rc2 = write_csv(c, rc ? &e : err);
    if (!rc) rc = rc2;
    pthread_mutex_destroy(&c->mu);
    pthread_cond_destroy(&c->cv);
    for (int i = 0; i < SLOTS; i++) free(c->jobs[i].rgb);
    metrics_ref_free(c->ref_prep);
    img_free(&c->ref_one);
    free(c->csv);
    free(c);
    return rc;
}

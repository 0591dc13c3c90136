/* corrtex montage -o SHEET.png IMAGE...: a contact sheet of walkthrough
 * frames (PNG or EXR), each scaled to a tile by area averaging in linear RGB,
 * laid out row by row and labelled with the frame number found in its file
 * name. Written here rather than depending on ImageMagick: common/image.h
 * already reads and writes both formats, and a fresh machine then needs no
 * extra package for `make demo`. Exit 0 ok, 2 bad input or usage. */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "cli/corrtex/commands.h"
#include "common/fsutil.h"
#include "common/image.h"
#include "common/log.h"
#include "common/optab.h"

#define COMPONENT "corrtex montage"

typedef struct montage_opts {
    const char *out;
    int columns;       /* 0: about square */
    int tile;          /* tile width in pixels */
    int gap;           /* pixels between tiles and around the sheet */
    int max_tiles;     /* 0: every input; else this many, evenly spaced */
    float exposure;    /* applied to the whole sheet when writing the PNG */
    bool no_labels, quiet;
} montage_opts;

#define OF(f) offsetof(montage_opts, f)
static const optab OPTS[] = {
    {"output", 'o', OPTAB_STRING, OF(out), 0, 0, NULL, "FILE", "the sheet (PNG, in a folder that exists; required)", NULL},
    {"columns", 0, OPTAB_INT, OF(columns), 0, 1000, "0", "C", "tiles per row (0: about square)", NULL},
    {"tile", 0, OPTAB_INT, OF(tile), 16, 4096, "256", "W", "tile width in pixels", NULL},
    {"gap", 0, OPTAB_INT, OF(gap), 0, 64, "4", "G", "pixels between tiles", NULL},
    {"max-tiles", 0, OPTAB_INT, OF(max_tiles), 0, 100000, "0", "N", "use N inputs, evenly spaced (0: all)", NULL},
    {"exposure", 0, OPTAB_FLOAT, OF(exposure), -30, 30, "0", "E", "stops applied when writing the PNG", NULL},
    {"no-labels", 0, OPTAB_FLAG, OF(no_labels), 0, 0, NULL, NULL, "no frame numbers on the tiles", NULL},
    {"quiet", 'q', OPTAB_FLAG, OF(quiet), 0, 0, NULL, NULL, "errors only", NULL},
};
#undef OF

static void usage(FILE *f)
{
    fprintf(f,
            "usage: corrtex montage -o SHEET.png [options] IMAGE...\n"
            "A contact sheet: every IMAGE (.png or .exr, same aspect expected) scaled to one\n"
            "tile by area averaging in linear RGB, row by row, labelled with the last number\n"
            "in its file name (frame_00012.png -> 12).\n\n"
            "options:\n");
    optab_usage(OPTS, OPTAB_COUNT(OPTS), NULL, f);
    fprintf(f, "  -h, --help                   this help\n"
               "exit status: 0 ok, 2 bad input or usage\n");
}

/* A 3x5 bitmap font for the digits 0-9: each row 3 bits, MSB left. */
static const unsigned char DIGITS[10][5] = {
    {7, 5, 5, 5, 7}, {2, 6, 2, 2, 7}, {7, 1, 7, 4, 7}, {7, 1, 7, 1, 7}, {5, 5, 7, 1, 1},
    {7, 4, 7, 1, 7}, {7, 4, 7, 5, 7}, {7, 1, 1, 1, 1}, {7, 5, 7, 5, 7}, {7, 5, 7, 1, 7}};

/* The last run of digits in the base name of path, or -1. */
static long label_of(const char *path)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    long v = -1;
    for (const char *p = base; *p;) {
        if (isdigit((unsigned char)*p)) {
            v = strtol(p, (char **)&p, 10);
        } else {
            p++;
        }
    }
    return v;
}

/* Draws the decimal number v at (x0, y0) in sheet with s-pixel dots: white
 * digits on a black box so they read on any frame. */
static void draw_label(ct_image *sheet, int x0, int y0, long v, int s)
{
    char txt[24];
    int n = snprintf(txt, sizeof txt, "%ld", v);
    int bw = (4 * n + 1) * s, bh = 7 * s;
    for (int y = y0; y < y0 + bh && y < sheet->height; y++)
        for (int x = x0; x < x0 + bw && x < sheet->width; x++) img_set(sheet, x, y, v3(0, 0, 0));
    for (int i = 0; i < n; i++) {
        const unsigned char *g = DIGITS[txt[i] - '0'];
        for (int r = 0; r < 5; r++)
            for (int c = 0; c < 3; c++) {
                if (!(g[r] & (4 >> c))) continue;
                for (int dy = 0; dy < s; dy++)
                    for (int dx = 0; dx < s; dx++) {
                        int x = x0 + (1 + 4 * i + c) * s + dx, y = y0 + (1 + r) * s + dy;
                        if (x < sheet->width && y < sheet->height) img_set(sheet, x, y, v3(1, 1, 1));
                    }
            }
    }
}

/* Reads a PNG or EXR by its extension into linear RGB. */
static int read_any(const char *path, ct_image *img, ct_error *err)
{
    size_t n = strlen(path);
    if (n >= 4 && strcasecmp(path + n - 4, ".exr") == 0) return img_read_exr(path, img, err);
    if (n >= 4 && strcasecmp(path + n - 4, ".png") == 0) return img_read_png(path, img, err);
    return ct_fail(err, CT_EINVAL, "%s: not a .png or .exr file", path);
}

/* Area-averages src into the tw x th tile at (x0, y0) of the sheet. */
static void place(ct_image *sheet, const ct_image *src, int x0, int y0, int tw, int th)
{
    double sx = (double)src->width / tw, sy = (double)src->height / th;
    for (int ty = 0; ty < th; ty++) {
        int ya = (int)floor(ty * sy), yb = (int)ceil((ty + 1) * sy);
        if (yb > src->height) yb = src->height;
        if (yb <= ya) yb = ya + 1;
        for (int tx = 0; tx < tw; tx++) {
            int xa = (int)floor(tx * sx), xb = (int)ceil((tx + 1) * sx);
            if (xb > src->width) xb = src->width;
            if (xb <= xa) xb = xa + 1;
            double r = 0, g = 0, b = 0;
            for (int y = ya; y < yb; y++)
                for (int x = xa; x < xb; x++) {
                    vec3 c = img_get(src, x, y);
                    r += c.x; g += c.y; b += c.z;
                }
            double k = 1.0 / ((double)(yb - ya) * (xb - xa));
            img_set(sheet, x0 + tx, y0 + ty, v3((float)(r * k), (float)(g * k), (float)(b * k)));
        }
    }
}

static int build(const montage_opts *o, const char *const *files, int nfiles, ct_error *err)
{
    int n = nfiles;
    if (o->max_tiles > 0 && o->max_tiles < n) n = o->max_tiles;
    ct_image first = {0, 0, NULL};
    int rc = read_any(files[0], &first, err);
    if (rc) return rc;
    int cols = o->columns > 0 ? o->columns : (int)ceil(sqrt((double)n));
    if (cols > n) cols = n;
    int rows = (n + cols - 1) / cols;
    int tw = o->tile;
    int th = (int)lround((double)tw * first.height / first.width);
    if (th < 1) th = 1;
    ct_image sheet = {0, 0, NULL};
    long sw = (long)cols * tw + (long)(cols + 1) * o->gap, sh = (long)rows * th + (long)(rows + 1) * o->gap;
    if (sw > 65536 || sh > 65536) {
        img_free(&first);
        return ct_fail(err, CT_ERANGE, "sheet of %ldx%ld pixels is too large (use --tile or --max-tiles)",
                       sw, sh);
    }
    rc = img_alloc(&sheet, (int)sw, (int)sh, err);
    if (rc) {
        img_free(&first);
        return rc;
    }
    for (size_t i = 0; i < (size_t)sheet.width * sheet.height * 3; i++) sheet.px[i] = 0.18f;
    int lscale = tw >= 256 ? 3 : tw >= 96 ? 2 : 1;
    for (int k = 0; k < n && !rc; k++) {
        /* evenly spaced picks, first and last included */
        int idx = n == nfiles ? k : (n > 1 ? (int)lround((double)k * (nfiles - 1) / (n - 1)) : 0);
        ct_image img = {0, 0, NULL};
        if (idx == 0) {
            img = first;
            first.px = NULL;
        } else {
            rc = read_any(files[idx], &img, err);
            if (rc) break;
        }
        if ((long)img.width * th != (long)img.height * tw &&
            labs((long)lround((double)tw * img.height / img.width) - th) > 1) {
            rc = ct_fail(err, CT_EINVAL, "%s: %dx%d does not have the aspect of %s", files[idx], img.width,
                         img.height, files[0]);
            img_free(&img);
            break;
        }
        int x0 = o->gap + (k % cols) * (tw + o->gap), y0 = o->gap + (k / cols) * (th + o->gap);
        place(&sheet, &img, x0, y0, tw, th);
        img_free(&img);
        long lab = label_of(files[idx]);
        if (!o->no_labels && lab >= 0) draw_label(&sheet, x0, y0, lab, lscale);
        if (k + 1 < n) ct_progress(COMPONENT, (double)(k + 1) / n, 0, "tile %d/%d", k + 1, n);   /* the last: below */
    }
    if (!rc) ct_progress(COMPONENT, 1.0, 1, "tile %d/%d", n, n);
    img_free(&first);
    if (!rc) rc = img_write_png(o->out, &sheet, o->exposure, err);
    if (!rc) ct_info(COMPONENT, "%s: %d tiles (%dx%d), %dx%d pixels", o->out, n, cols, rows, sheet.width,
                     sheet.height);
    img_free(&sheet);
    return rc;
}

int cmd_montage(int argc, char **argv)
{
    montage_opts o;
    ct_error err;
    optab_defaults(OPTS, OPTAB_COUNT(OPTS), &o, &err);
    optab_group g = {OPTS, OPTAB_COUNT(OPTS), &o};
    const char **pos = calloc((size_t)argc + 1, sizeof *pos);
    if (!pos) return 2;
    int npos = 0, rc = optab_parse(&g, 1, argc, argv, pos, argc, &npos, &err);
    if (o.quiet) ct_log_set_level(CT_LOG_ERROR);
    if (rc == 1) usage(stdout);
    else if (rc) ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
    else if (!o.out) ct_log(CT_LOG_ERROR, COMPONENT, "no output file: give -o SHEET.png (try --help)");
    else if (img_file_kind_of(o.out) != IMG_FILE_PNG)
        ct_log(CT_LOG_ERROR, COMPONENT, "-o %s: the sheet is written as PNG: give a name ending in .png", o.out);
    else if (!npos) ct_log(CT_LOG_ERROR, COMPONENT, "no input images (try --help)");
    /* (before the images are read: a missing folder of the sheet used to be
     * found only once it was made) */
    else if (fs_output_check(o.out, &err)) ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
    else if (build(&o, pos, npos, &err)) ct_log(CT_LOG_ERROR, COMPONENT, "%s", err.msg);
    else rc = 1;
    free(pos);
    return rc == 1 ? 0 : 2;
}

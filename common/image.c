/* image.c: images in memory, PNG files and the display's tone mapping
 * (image.h); EXR files are image_exr.c's. */
#include "common/image.h"
#include "common/fsutil.h"
#include "common/image_internal.h"

#include <math.h>
#include <png.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

int img_size_check(int width, int height, ct_error *err)
{
    if (width < 1 || height < 1 || width > IMG_MAX_SIDE || height > IMG_MAX_SIDE)
        return ct_fail(err, CT_ERANGE, "image size %dx%d outside 1..%d", width, height, IMG_MAX_SIDE);
    if ((size_t)width * (size_t)height > IMG_MAX_PIXELS)
        return ct_fail(err, CT_ERANGE, "image size %dx%d exceeds %zu pixels", width, height,
                       IMG_MAX_PIXELS);
    return CT_OK;
}

int img_alloc(ct_image *img, int width, int height, ct_error *err)
{
    memset(img, 0, sizeof *img);
    int rc = img_size_check(width, height, err);
    if (rc) return rc;
    size_t n = (size_t)width * (size_t)height;
    img->px = calloc(n * 3, sizeof *img->px);
    if (!img->px) return ct_fail(err, CT_ENOMEM, "out of memory for a %dx%d image", width, height);
    img->width = width;
    img->height = height;
    return CT_OK;
}

void img_free(ct_image *img)
{
    if (!img) return;
    free(img->px);
    memset(img, 0, sizeof *img);
}

/* --- PNG ------------------------------------------------------------------ */

float img_tonemap(float linear, float exposure)
{
    float v = linear * exp2f(exposure);
    if (!(v > 0.0f)) return 0.0f; /* negative and NaN */
    if (v >= 1.0f) return 1.0f;
    /* sRGB OETF (IEC 61966-2-1). */
    return v <= 0.0031308f ? 12.92f * v : 1.055f * powf(v, 1.0f / 2.4f) - 0.055f;
}

/* The sRGB curve above its linear part (v > 0.0031308 > 2^-9) in steps of
 * 2^-TM_STEP_BITS of an octave: floats from 2^-9 to 1 index the table by
 * their exponent and top mantissa bits, and the step between two entries
 * is linear (the curve is smooth enough there for 2e-7). */
#define TM_STEP_BITS 10
#define TM_OCTAVES 9
#define TM_LO_BITS 0x3b000000u   /* 2^-9 */
static float tm_table[(TM_OCTAVES << TM_STEP_BITS) + 1];
static pthread_once_t tm_once = PTHREAD_ONCE_INIT;

static void tm_init(void)
{
    for (uint32_t i = 0; i <= (TM_OCTAVES << TM_STEP_BITS); i++) {
        uint32_t bits = TM_LO_BITS + (i << (23 - TM_STEP_BITS));
        float v;
        memcpy(&v, &bits, sizeof v);
        tm_table[i] = (float)(1.055 * pow((double)v, 1.0 / 2.4) - 0.055);
    }
}

void img_tonemap_n(const float *linear, float *out, size_t n)
{
    pthread_once(&tm_once, tm_init);
    const float frac_scale = 1.0f / (float)(1u << (23 - TM_STEP_BITS));
    for (size_t i = 0; i < n; i++) {
        float v = linear[i];
        if (!(v > 0.0031308f)) {
            out[i] = v > 0.0f ? 12.92f * v : 0.0f;   /* negative and NaN: 0 */
            continue;
        }
        if (v >= 1.0f) {
            out[i] = 1.0f;
            continue;
        }
        uint32_t bits;
        memcpy(&bits, &v, sizeof bits);
        uint32_t off = bits - TM_LO_BITS;
        uint32_t k = off >> (23 - TM_STEP_BITS);
        float t = (float)(off & ((1u << (23 - TM_STEP_BITS)) - 1)) * frac_scale;
        out[i] = tm_table[k] + (tm_table[k + 1] - tm_table[k]) * t;
    }
}

float img_tonemap_slope(float linear)
{
    float v = linear < 1.0f ? linear : 1.0f;   /* NaN too */
    if (!(v > 0.0031308f)) return 12.92f;
    return (1.055f / 2.4f) * powf(v, 1.0f / 2.4f - 1.0f);
}

/* Inverse of the sRGB OETF on [0, 1]. */
static float srgb_to_linear(float s)
{
    return s <= 0.04045f ? s / 12.92f : powf((s + 0.055f) / 1.055f, 2.4f);
}

/* libpng reports errors by longjmp from its error callback; the message is
 * kept for the caller. */
typedef struct png_err {
    jmp_buf jb;
    char *why;
    size_t cap;
} png_err;

static void png_on_error(png_structp png, png_const_charp msg)
{
    png_err *pe = png_get_error_ptr(png);
    snprintf(pe->why, pe->cap, "%s", msg);
    longjmp(pe->jb, 1);
}

static void png_on_warning(png_structp png, png_const_charp msg)
{
    (void)png;
    (void)msg;
}

/* Writes 8-bit RGB rows to f. The simplified API (png_image_write_*) has no
 * compression setting and its default (zlib 6, every filter tried) took
 * 150 ms for a 1024^2 frame; zlib level 1 with the Sub/Up filters, which
 * suit rendered images, takes a fraction of that. Returns 1 or 0 (why). */
static int png_write_rgb8(FILE *f, const uint8_t *rgb, int width, int height, char *why, size_t cap)
{
    png_err pe = {.why = why, .cap = cap};
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &pe, png_on_error, png_on_warning);
    if (!png) {
        snprintf(why, cap, "out of memory");
        return 0;
    }
    png_infop info = png_create_info_struct(png);
    if (!info || setjmp(pe.jb)) {
        if (!info) snprintf(why, cap, "out of memory");
        png_destroy_write_struct(&png, info ? &info : NULL);
        return 0;
    }
    png_init_io(png, f);
    png_set_compression_level(png, IMG_ZIP_LEVEL);
    png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB | PNG_FILTER_UP);
    png_set_IHDR(png, info, (png_uint_32)width, (png_uint_32)height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_BASE, PNG_FILTER_TYPE_BASE);
    png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(png, info);
    for (int y = 0; y < height; y++) png_write_row(png, rgb + (size_t)y * (size_t)width * 3);
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    return 1;
}

int img_write_png(const char *path, const ct_image *img, float exposure, ct_error *err)
{
    int rc = img_check_writable(path, img, err);
    if (rc) return rc;
    if (!isfinite(exposure)) return ct_fail(err, CT_EINVAL, "%s: exposure is not finite", path);
    size_t n = (size_t)img->width * (size_t)img->height * 3;
    uint8_t *buf = malloc(n);
    if (!buf) return ct_fail(err, CT_ENOMEM, "%s: out of memory", path);
    for (size_t i = 0; i < n; i++)
        buf[i] = (uint8_t)(img_tonemap(img->px[i], exposure) * 255.0f + 0.5f);

    fs_atomic a;
    rc = fs_atomic_open(&a, path, err);
    if (rc) { free(buf); return rc; }
    char why[128] = "";
    int ok = png_write_rgb8(a.f, buf, img->width, img->height, why, sizeof why);
    free(buf);
    if (!ok) {
        fs_atomic_abort(&a);
        return ct_fail(err, CT_EIO, "%s: cannot write PNG: %s", path, why);
    }
    return fs_atomic_commit(&a, err);
}

int img_read_png(const char *path, ct_image *img, ct_error *err)
{
    memset(img, 0, sizeof *img);
    FILE *f;
    size_t size;
    int rc = fs_open_regular(path, &f, &size, err);
    if (rc) return rc;
    png_image pi;
    memset(&pi, 0, sizeof pi);
    pi.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_stdio(&pi, f)) {
        fclose(f);
        return ct_fail(err, CT_EPARSE, "%s: not a valid PNG file: %s", path, pi.message);
    }
    if (pi.width < 1 || pi.height < 1 || pi.width > IMG_MAX_SIDE || pi.height > IMG_MAX_SIDE) {
        png_image_free(&pi);
        fclose(f);
        return ct_fail(err, CT_ERANGE, "%s: PNG size %ux%u outside 1..%d", path, (unsigned)pi.width,
                       (unsigned)pi.height, IMG_MAX_SIDE);
    }
    pi.format = PNG_FORMAT_RGB;
    rc = img_alloc(img, (int)pi.width, (int)pi.height, err);
    if (rc) {
        png_image_free(&pi);
        fclose(f);
        ct_error_prefix(err, path);
        return rc;
    }
    size_t n = (size_t)img->width * (size_t)img->height * 3;
    uint8_t *buf = malloc(n);
    if (!buf) {
        png_image_free(&pi);
        fclose(f);
        img_free(img);
        return ct_fail(err, CT_ENOMEM, "%s: out of memory", path);
    }
    int ok = png_image_finish_read(&pi, NULL, buf, 0, NULL);
    fclose(f);
    if (!ok) {
        char msg[128];
        snprintf(msg, sizeof msg, "%s", pi.message);
        png_image_free(&pi);
        free(buf);
        img_free(img);
        return ct_fail(err, CT_EPARSE, "%s: corrupt PNG: %s", path, msg);
    }
    float lut[256];
    for (int i = 0; i < 256; i++) lut[i] = srgb_to_linear((float)i / 255.0f);
    for (size_t i = 0; i < n; i++) img->px[i] = lut[buf[i]];
    free(buf);
    return CT_OK;
}

img_file_kind img_file_kind_of(const char *path)
{
    size_t n = strlen(path);
    if (n > 4 && !strcasecmp(path + n - 4, ".exr")) return IMG_FILE_EXR;
    if (n > 4 && !strcasecmp(path + n - 4, ".png")) return IMG_FILE_PNG;
    return IMG_FILE_OTHER;
}

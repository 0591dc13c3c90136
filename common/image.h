/* image.h: linear RGB float images and their files. EXR through OpenEXR's C
 * API (OpenEXRCore; RGB half or float), PNG through libpng with exposure and
 * sRGB tone mapping. Rows are stored top to bottom. Writes are atomic.
 * image.c: memory, PNG and tone mapping; image_exr.c: EXR. */
#ifndef CT_IMAGE_H
#define CT_IMAGE_H

#include <stddef.h>

#include "common/error.h"
#include "common/vecmath.h"

typedef struct ct_image {
    int width, height;
    float *px;          /* width * height * 3 floats, row 0 at the top */
} ct_image;

typedef enum img_pixel_type {
    IMG_HALF  = 1,
    IMG_FLOAT = 2
} img_pixel_type;

/* Allocates a zeroed image (sides 1..65536, at most 2^28 pixels). */
int img_alloc(ct_image *img, int width, int height, ct_error *err);

/* CT_ERANGE with the reason when img_alloc would refuse width x height
 * (the size a reader accepts too): for a program to say so before its work. */
int img_size_check(int width, int height, ct_error *err);

/* Frees the pixels and zeroes the struct. */
void img_free(ct_image *img);

static inline vec3 img_get(const ct_image *img, int x, int y)
{
    const float *p = img->px + 3 * ((size_t)y * (size_t)img->width + (size_t)x);
    return v3(p[0], p[1], p[2]);
}

static inline void img_set(ct_image *img, int x, int y, vec3 c)
{
    float *p = img->px + 3 * ((size_t)y * (size_t)img->width + (size_t)x);
    p[0] = c.x; p[1] = c.y; p[2] = c.z;
}

/* Reads the R, G, B channels of an EXR file (any of half/float/uint). */
int img_read_exr(const char *path, ct_image *img, ct_error *err);

/* Writes an RGB EXR file (scanline, ZIP), atomically; half clamps to +-65504. */
int img_write_exr(const char *path, const ct_image *img, img_pixel_type type, ct_error *err);

/* sRGB-encoded display value in [0, 1] of a linear value times 2^exposure. */
float img_tonemap(float linear, float exposure);

/* img_tonemap at exposure 0 of n values (in and out may be the same
 * array): a table with linear steps in place of powf, within 2e-7 of
 * img_tonemap; for metrics over whole frames, where powf per channel cost
 * more than the rest of the comparison. */
void img_tonemap_n(const float *linear, float *out, size_t n);

/* The slope of img_tonemap at exposure 0, d(display) / d(linear), at
 * `linear` taken into [0, 1] (12.92 at and below 0.0031308, 0.44 at 1 and
 * above): how much a linear error moves what a viewer sees there. */
float img_tonemap_slope(float linear);

/* The image format a file name asks for by its extension (any case):
 * IMG_FILE_EXR (.exr), IMG_FILE_PNG (.png), else IMG_FILE_OTHER. The tools
 * check it before they work, so that x.png never holds an EXR. */
typedef enum img_file_kind { IMG_FILE_OTHER = 0, IMG_FILE_EXR, IMG_FILE_PNG } img_file_kind;
img_file_kind img_file_kind_of(const char *path);

/* Writes an 8-bit sRGB PNG of img scaled by 2^exposure, atomically. */
int img_write_png(const char *path, const ct_image *img, float exposure, ct_error *err);

/* Reads an 8-bit RGB/RGBA PNG back into linear values (for tests). */
int img_read_png(const char *path, ct_image *img, ct_error *err);

#endif

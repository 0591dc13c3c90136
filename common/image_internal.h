/* image_internal.h: what image.c (memory, PNG) and image_exr.c (EXR) share:
 * the size limits of an image and of a file's header, the zlib level, and
 * the check of an image about to be written. Not for other modules. */
#ifndef CT_IMAGE_INTERNAL_H
#define CT_IMAGE_INTERNAL_H

#include "common/image.h"

#define IMG_MAX_SIDE 65536
/* Total pixel cap (16384^2): a corrupt header claiming 65536x65536 must not
 * make us allocate 48 GiB before the first chunk fails to decode. */
#define IMG_MAX_PIXELS ((size_t)1 << 28)
/* zlib level of EXR chunks and PNG streams: see write_exr_ctx. */
#define IMG_ZIP_LEVEL 1
/* Largest finite half. */
#define IMG_HALF_MAX 65504.0f

static inline int img_check_writable(const char *path, const ct_image *img, ct_error *err)
{
    if (!img || !img->px || img->width < 1 || img->height < 1 || img->width > IMG_MAX_SIDE ||
        img->height > IMG_MAX_SIDE)
        return ct_fail(err, CT_EINVAL, "%s: invalid image to write", path);
    return CT_OK;
}

#endif

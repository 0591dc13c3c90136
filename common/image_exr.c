/* image_exr.c: EXR files (image.h) through OpenEXR's C API (OpenEXRCore):
 * RGB half or float, written atomically. */
#include "common/image.h"
#include "common/fsutil.h"
#include "common/image_internal.h"
#include "common/log.h"

#include <errno.h>
#include <math.h>
#include <openexr.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* --- EXR ------------------------------------------------------------------ */

/* OpenEXRCore reports details through a callback (by default printed to
 * stderr). Keep the last message of this thread so the one-line error we
 * return can carry it; contexts are used by one thread at a time here. */
static _Thread_local char exr_last_msg[160];

static void exr_capture(exr_const_context_t ctxt, exr_result_t code, const char *msg)
{
    (void)ctxt;
    snprintf(exr_last_msg, sizeof exr_last_msg, "%s",
             msg && msg[0] ? msg : exr_get_default_error_message(code));
}

static const char *exr_why(exr_result_t rv)
{
    return exr_last_msg[0] ? exr_last_msg : exr_get_default_error_message(rv);
}

static exr_context_initializer_t exr_init(void)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = exr_capture;
    init.max_image_width = IMG_MAX_SIDE;
    init.max_image_height = IMG_MAX_SIDE;
    /* A damaged offset table is an error, not something to guess around. */
    init.flags = EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
    return init;
}

/* Decodes one chunk into img at pixel (px, py) (relative to the data
 * window's origin): R, G and B become floats, other channels are skipped. */
static exr_result_t decode_chunk(exr_context_t ctx, const exr_chunk_info_t *ci, int px, int py,
                                 ct_image *img, exr_decode_pipeline_t *dec, int *initialized)
{
    exr_result_t rv;
    if (px < 0 || py < 0 || ci->width < 1 || ci->height < 1 || px + ci->width > img->width ||
        py + ci->height > img->height)
        return EXR_ERR_CORRUPT_CHUNK;
    rv = *initialized ? exr_decoding_update(ctx, 0, ci, dec) : exr_decoding_initialize(ctx, 0, ci, dec);
    if (rv != EXR_ERR_SUCCESS) return rv;
    for (int c = 0; c < dec->channel_count; c++) {
        exr_coding_channel_info_t *o = &dec->channels[c];
        const char *name = o->channel_name ? o->channel_name : "";
        int k = strcmp(name, "R") == 0 ? 0 : strcmp(name, "G") == 0 ? 1 : strcmp(name, "B") == 0 ? 2 : -1;
        o->decode_to_ptr = NULL;
        if (k < 0) continue;
        if (o->width != ci->width || o->height != ci->height) return EXR_ERR_CORRUPT_CHUNK;
        o->decode_to_ptr = (uint8_t *)(img->px + 3 * ((size_t)py * (size_t)img->width + (size_t)px) + k);
        o->user_pixel_stride = 3 * (int32_t)sizeof(float);
        o->user_line_stride = 3 * (int32_t)sizeof(float) * img->width;
        o->user_data_type = EXR_PIXEL_FLOAT;
        o->user_bytes_per_element = (int16_t)sizeof(float);
    }
    if (!*initialized) {
        rv = exr_decoding_choose_default_routines(ctx, 0, dec);
        if (rv != EXR_ERR_SUCCESS) return rv;
        *initialized = 1;
    }
    return exr_decoding_run(ctx, 0, dec);
}

/* Index of channel `name` in chlist, or -1. */
static int find_channel(const exr_attr_chlist_t *cl, const char *name)
{
    for (int i = 0; i < cl->num_channels; i++)
        if (cl->entries[i].name.str && strcmp(cl->entries[i].name.str, name) == 0) return i;
    return -1;
}

static int read_exr_ctx(const char *path, exr_context_t ctx, ct_image *img, ct_error *err)
{
    exr_result_t rv;
    exr_storage_t storage;
    if ((rv = exr_get_storage(ctx, 0, &storage)) != EXR_ERR_SUCCESS)
        return ct_fail(err, CT_EPARSE, "%s: corrupt EXR header: %s", path, exr_why(rv));
    if (storage != EXR_STORAGE_SCANLINE && storage != EXR_STORAGE_TILED)
        return ct_fail(err, CT_EPARSE, "%s: deep EXR images are not supported", path);

    exr_attr_box2i_t dw;
    if ((rv = exr_get_data_window(ctx, 0, &dw)) != EXR_ERR_SUCCESS)
        return ct_fail(err, CT_EPARSE, "%s: corrupt EXR header: %s", path, exr_why(rv));
    int64_t w64 = (int64_t)dw.max.x - dw.min.x + 1, h64 = (int64_t)dw.max.y - dw.min.y + 1;
    if (w64 < 1 || h64 < 1 || w64 > IMG_MAX_SIDE || h64 > IMG_MAX_SIDE)
        return ct_fail(err, CT_ERANGE, "%s: EXR data window %lldx%lld outside 1..%d", path,
                       (long long)w64, (long long)h64, IMG_MAX_SIDE);

    const exr_attr_chlist_t *cl = NULL;
    if ((rv = exr_get_channels(ctx, 0, &cl)) != EXR_ERR_SUCCESS || !cl)
        return ct_fail(err, CT_EPARSE, "%s: corrupt EXR channel list: %s", path, exr_why(rv));
    static const char *const names[3] = {"R", "G", "B"};
    int idx[3];
    char missing[16] = "";
    for (int k = 0; k < 3; k++) {
        idx[k] = find_channel(cl, names[k]);
        if (idx[k] < 0) {
            strcat(missing, missing[0] ? ", " : "");
            strcat(missing, names[k]);
        } else if (cl->entries[idx[k]].x_sampling != 1 || cl->entries[idx[k]].y_sampling != 1) {
            return ct_fail(err, CT_EPARSE, "%s: EXR channel %s is subsampled (not supported)", path,
                           names[k]);
        }
    }
    if (missing[0]) {
        char have[96] = "";
        for (int i = 0; i < cl->num_channels && strlen(have) < sizeof have - 24; i++) {
            if (i) strcat(have, " ");
            strncat(have, cl->entries[i].name.str ? cl->entries[i].name.str : "?", 16);
        }
        return ct_fail(err, CT_EPARSE, "%s: EXR has no channel %s (channels: %s)", path, missing,
                       have[0] ? have : "none");
    }

    int rc = img_alloc(img, (int)w64, (int)h64, err);
    if (rc) { ct_error_prefix(err, path); return rc; }

    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    int initialized = 0;
    rv = EXR_ERR_SUCCESS;
    if (storage == EXR_STORAGE_SCANLINE) {
        int32_t lines = 0;
        if ((rv = exr_get_scanlines_per_chunk(ctx, 0, &lines)) == EXR_ERR_SUCCESS && lines < 1)
            rv = EXR_ERR_INVALID_ATTR;
        for (int64_t y = dw.min.y; rv == EXR_ERR_SUCCESS && y <= dw.max.y; y += lines) {
            exr_chunk_info_t ci;
            rv = exr_read_scanline_chunk_info(ctx, 0, (int)y, &ci);
            if (rv != EXR_ERR_SUCCESS) break;
            rv = decode_chunk(ctx, &ci, 0, ci.start_y - dw.min.y, img, &dec, &initialized);
        }
    } else {
        uint32_t tw = 0, th = 0;
        exr_tile_level_mode_t lm;
        exr_tile_round_mode_t rm;
        rv = exr_get_tile_descriptor(ctx, 0, &tw, &th, &lm, &rm);
        if (rv == EXR_ERR_SUCCESS && (tw < 1 || th < 1)) rv = EXR_ERR_INVALID_ATTR;
        /* Level (0, 0) is the full-resolution image in every level mode. */
        int64_t ntx = rv ? 0 : (w64 + tw - 1) / tw, nty = rv ? 0 : (h64 + th - 1) / th;
        for (int64_t ty = 0; rv == EXR_ERR_SUCCESS && ty < nty; ty++)
            for (int64_t tx = 0; rv == EXR_ERR_SUCCESS && tx < ntx; tx++) {
                exr_chunk_info_t ci;
                rv = exr_read_tile_chunk_info(ctx, 0, (int)tx, (int)ty, 0, 0, &ci);
                if (rv != EXR_ERR_SUCCESS) break;
                rv = decode_chunk(ctx, &ci, (int)(tx * tw), (int)(ty * th), img, &dec, &initialized);
            }
    }
    exr_decoding_destroy(ctx, &dec);
    if (rv != EXR_ERR_SUCCESS) {
        img_free(img);
        return ct_fail(err, CT_EPARSE, "%s: corrupt or truncated EXR pixel data: %s", path, exr_why(rv));
    }
    return CT_OK;
}

int img_read_exr(const char *path, ct_image *img, ct_error *err)
{
    memset(img, 0, sizeof *img);
    /* Check the file ourselves first: the library's message for a missing
     * file does not carry errno's wording. */
    struct stat st;
    if (stat(path, &st) != 0) return ct_fail(err, CT_EIO, "%s: cannot open: %s", path, strerror(errno));
    if (!S_ISREG(st.st_mode)) return ct_fail(err, CT_EIO, "%s: not a regular file", path);
    if (access(path, R_OK) != 0) return ct_fail(err, CT_EIO, "%s: cannot open: %s", path, strerror(errno));

    exr_context_initializer_t init = exr_init();
    exr_context_t ctx = NULL;
    exr_last_msg[0] = '\0';
    exr_result_t rv = exr_start_read(&ctx, path, &init);
    if (rv != EXR_ERR_SUCCESS) {
        if (ctx) exr_finish(&ctx);
        if (rv == EXR_ERR_FILE_ACCESS)
            return ct_fail(err, CT_EIO, "%s: cannot read EXR: %s", path, exr_why(rv));
        return ct_fail(err, CT_EPARSE, "%s: not a valid EXR file (%s)", path, exr_why(rv));
    }
    int rc = read_exr_ctx(path, ctx, img, err);
    exr_finish(&ctx);
    return rc;
}

/* Channels are stored sorted by name: B, G, R (components 2, 1, 0). */
static const char *const exr_names[3] = {"B", "G", "R"};
static const int exr_comp[3] = {2, 1, 0};

/* Encodes and writes every scanline chunk of img into part. */
/* OpenEXRCore before 3.4.8 (Debian 12 has 3.1.5) keeps the zlib bytes of a
 * ZIP chunk whose compressed size equals its packed size, but readers take a
 * chunk of that size as stored raw (OpenEXR issue 2306): noisy float images
 * came back with a block of 16 garbage rows. This wrapper stores such a chunk
 * raw, as the fixed library does. */
typedef struct zip_guard {
    exr_result_t (*compress)(exr_encode_pipeline_t *enc);
} zip_guard;

static exr_result_t guarded_compress(exr_encode_pipeline_t *enc)
{
    const zip_guard *g = enc->encoding_user_data;
    exr_result_t rv = g->compress(enc);
    if (rv == EXR_ERR_SUCCESS && enc->compressed_buffer && enc->compressed_buffer != enc->packed_buffer &&
        enc->compressed_bytes == enc->packed_bytes && enc->packed_bytes > 0)
        memcpy(enc->compressed_buffer, enc->packed_buffer, enc->packed_bytes);
    return rv;
}

static exr_result_t write_chunks(exr_context_t ctx, int part, const ct_image *img)
{
    zip_guard guard = {NULL};
    int32_t lines = 0;
    exr_result_t rv = exr_get_scanlines_per_chunk(ctx, part, &lines);
    if (rv != EXR_ERR_SUCCESS) return rv;
    if (lines < 1) return EXR_ERR_INVALID_ATTR;
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    int initialized = 0;
    for (int y = 0; rv == EXR_ERR_SUCCESS && y < img->height; y += lines) {
        exr_chunk_info_t ci;
        if ((rv = exr_write_scanline_chunk_info(ctx, part, y, &ci)) != EXR_ERR_SUCCESS) break;
        rv = initialized ? exr_encoding_update(ctx, part, &ci, &enc)
                         : exr_encoding_initialize(ctx, part, &ci, &enc);
        if (rv != EXR_ERR_SUCCESS) break;
        for (int c = 0; c < enc.channel_count; c++) {
            exr_coding_channel_info_t *o = &enc.channels[c];
            int k = -1;
            for (int j = 0; j < 3; j++)
                if (strcmp(o->channel_name, exr_names[j]) == 0) k = exr_comp[j];
            if (k < 0) { rv = EXR_ERR_INVALID_ARGUMENT; break; }
            /* Float pixels in; the library converts to half when the
             * channel is half (round to nearest even). */
            o->encode_from_ptr = (const uint8_t *)(img->px + 3 * (size_t)ci.start_y * (size_t)img->width + k);
            o->user_pixel_stride = 3 * (int32_t)sizeof(float);
            o->user_line_stride = 3 * (int32_t)sizeof(float) * img->width;
            o->user_data_type = EXR_PIXEL_FLOAT;
            o->user_bytes_per_element = (int16_t)sizeof(float);
        }
        if (rv != EXR_ERR_SUCCESS) break;
        if (!initialized) {
            if ((rv = exr_encoding_choose_default_routines(ctx, part, &enc)) != EXR_ERR_SUCCESS) break;
            if (enc.compress_fn) {
                guard.compress = enc.compress_fn;
                enc.compress_fn = guarded_compress;
                enc.encoding_user_data = &guard;
            }
            initialized = 1;
        }
        rv = exr_encoding_run(ctx, part, &enc);
    }
    exr_encoding_destroy(ctx, &enc);
    return rv;
}

/* Declares the header (one scanline part, ZIP, channels B G R) and writes the pixels. */
static exr_result_t write_exr_ctx(exr_context_t ctx, const ct_image *img, img_pixel_type type)
{
    exr_result_t rv;
    int part = 0;
    exr_pixel_type_t pt = type == IMG_HALF ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT;
    if ((rv = exr_add_part(ctx, "rgb", EXR_STORAGE_SCANLINE, &part)) != EXR_ERR_SUCCESS) return rv;
    rv = exr_initialize_required_attr_simple(ctx, part, img->width, img->height, EXR_COMPRESSION_ZIP);
    if (rv != EXR_ERR_SUCCESS) return rv;
    /* The library's default level (6) took 300 ms for a 1024^2 frame here;
     * level 1 takes 90 ms for files 20% larger. Frames are written while a
     * walkthrough runs, so speed wins. */
    if ((rv = exr_set_zip_compression_level(ctx, part, IMG_ZIP_LEVEL)) != EXR_ERR_SUCCESS) return rv;
    for (int c = 0; c < 3; c++) {
        rv = exr_add_channel(ctx, part, exr_names[c], pt, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
        if (rv != EXR_ERR_SUCCESS) return rv;
    }
    if ((rv = exr_write_header(ctx)) != EXR_ERR_SUCCESS) return rv;
    return write_chunks(ctx, part, img);
}

/* The EXR bytes are assembled in memory and written with fs_write_atomic:
 * the library's own file writing would rename a temporary over a device or
 * FIFO target, and it seeks back to fill the chunk offset table, which a
 * FIFO cannot do. */
typedef struct exr_mem {
    unsigned char *data;
    size_t len, cap;
} exr_mem;

static int64_t exr_mem_write(exr_const_context_t ctxt, void *user, const void *buf, uint64_t sz, uint64_t offset,
                             exr_stream_error_func_ptr_t error_cb)
{
    exr_mem *m = user;
    if (offset > SIZE_MAX / 2 || sz > SIZE_MAX / 2 - offset) {
        error_cb(ctxt, EXR_ERR_WRITE_IO, "EXR larger than memory");
        return -1;
    }
    size_t end = (size_t)(offset + sz);
    if (end > m->cap) {
        size_t cap = m->cap ? m->cap : 1 << 16;
        while (cap < end) cap *= 2;
        unsigned char *p = realloc(m->data, cap);
        if (!p) {
            error_cb(ctxt, EXR_ERR_OUT_OF_MEMORY, "out of memory for the EXR bytes");
            return -1;
        }
        m->data = p;
        m->cap = cap;
    }
    if (offset > m->len) memset(m->data + m->len, 0, (size_t)offset - m->len);
    memcpy(m->data + offset, buf, (size_t)sz);
    if (end > m->len) m->len = end;
    return (int64_t)sz;
}

int img_write_exr(const char *path, const ct_image *img, img_pixel_type type, ct_error *err)
{
    int rc = img_check_writable(path, img, err);
    if (rc) return rc;
    if (type != IMG_HALF && type != IMG_FLOAT)
        return ct_fail(err, CT_EINVAL, "%s: unknown EXR pixel type %d", path, (int)type);

    /* Half overflows to infinity above 65504; a bright firefly should stay
     * a finite (clamped) value rather than poison every later metric. */
    ct_image clamped = {0, 0, NULL};
    const ct_image *src = img;
    if (type == IMG_HALF) {
        rc = img_alloc(&clamped, img->width, img->height, err);
        if (rc) { ct_error_prefix(err, path); return rc; }
        size_t n = (size_t)img->width * (size_t)img->height * 3, over = 0;
        for (size_t i = 0; i < n; i++) {
            float v = img->px[i];
            over += fabsf(v) > IMG_HALF_MAX;
            clamped.px[i] = v > IMG_HALF_MAX ? IMG_HALF_MAX : (v < -IMG_HALF_MAX ? -IMG_HALF_MAX : v);
        }
        src = &clamped;
        /* Only scenes with emission above the half range meet this (the
         * scene format allows 1e9), and then in every frame: said once. */
        static atomic_flag said = ATOMIC_FLAG_INIT;
        if (over && !atomic_flag_test_and_set(&said))
            ct_warn("image", "%s: %zu channel values beyond the half-float range +-65504 clamped to it "
                    "(later files are not mentioned)", path, over);
    }

    exr_mem mem = {NULL, 0, 0};
    exr_context_initializer_t init = exr_init();
    init.flags = 0;
    init.user_data = &mem;
    init.write_fn = exr_mem_write;
    exr_context_t ctx = NULL;
    exr_last_msg[0] = '\0';
    exr_result_t rv = exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv == EXR_ERR_SUCCESS) {
        rv = write_exr_ctx(ctx, src, type);
        /* exr_finish writes the chunk offset table; its failure is a write failure too. */
        exr_result_t frv = exr_finish(&ctx);
        if (rv == EXR_ERR_SUCCESS) rv = frv;
    } else if (ctx) {
        exr_finish(&ctx);
    }
    img_free(&clamped);
    if (rv != EXR_ERR_SUCCESS) rc = ct_fail(err, CT_EIO, "%s: cannot write EXR: %s", path, exr_why(rv));
    else rc = fs_write_atomic(path, mem.data, mem.len, err);
    free(mem.data);
    return rc;
}

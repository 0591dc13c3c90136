/* disp_capture.h: frame output for --out DIR: frame_NNNNN.exr (linear RGB,
 * half) and frame_NNNNN.png (exposure + sRGB, 8 bit) per frame (unless
 * images are off: --no-images), and frames.csv with one row per frame
 * (camera, timings, per-frame counts and, with --reference, the RMSE and
 * PSNR against DIR/frame_NNNNN.exr, or against one image FILE.exr for every
 * frame). Frames are written on a thread of their own. Every file is
 * written atomically; frames.csv is rewritten every few frames and at the
 * end so it is always complete up to some frame. */
#ifndef CT_DISP_CAPTURE_H
#define CT_DISP_CAPTURE_H

#include <stdbool.h>
#include <stdint.h>

#include "common/camera.h"
#include "common/error.h"

/* What one captured frame reports in frames.csv. */
typedef struct disp_frame_info {
    uint32_t frame;
    double time;          /* seconds since the run started (path time for paths) */
    ct_camera cam;
    double frame_ms;      /* render + present time of this frame */
    uint64_t samples;     /* samples inserted since the previous frame */
    uint64_t texels;      /* texels received since the previous frame */
    uint64_t bytes;       /* bytes received since the previous frame */
    uint32_t textures;    /* textures allocated now */
    double wall;          /* seconds since the run started (wall clock, also for paths) */
} disp_frame_info;

typedef struct disp_capture disp_capture;

/* Creates dir (mkdir -p), after reading ref: NULL, a folder of per-frame
 * references or one reference image (read now; a bad one makes nothing);
 * images: write each frame's EXR and PNG. */
int disp_capture_open(const char *dir, const char *ref, float exposure, bool images, disp_capture **out,
                      ct_error *err);

/* With --reference a folder and --frames N: whether it holds exactly
 * frame_00000.exr .. frame_{N-1}.exr, the references of these N frames
 * (those of another N are other cameras); CT_EINVAL with a line naming the
 * folder and the counts otherwise. */
int disp_capture_check_refs(const char *dir, int frames, ct_error *err);

/* Queues the frame (rgb: linear, 3 floats per pixel, top row first, copied)
 * for the writer thread, which writes its EXR and PNG and records its row;
 * with a reference also its RMSE and PSNR (logged). Waits only while two
 * frames are still being written. An error of an earlier frame's writing
 * is returned here (and by close). */
int disp_capture_frame(disp_capture *c, const disp_frame_info *info, const float *rgb, int width,
                       int height, ct_error *err);

/* Whether frames need their pixels (images or a reference); without,
 * disp_capture_frame takes rgb NULL and records the row only. */
bool disp_capture_needs_pixels(const disp_capture *c);

/* Writes every queued frame, then frames.csv (atomically), and frees c;
 * NULL is fine. */
int disp_capture_close(disp_capture *c, ct_error *err);

#endif

/* disp_gpu_time.h: the GPU time of the display's stages (taking in texels,
 * drawing, tone mapping and presenting) by GL timer queries, read back once
 * the GPU has finished them, never waiting for one. Why: a frame's CPU time
 * says when the driver returned, not what the GPU did. On a GPU a frame
 * while texels streamed took 22 ms against 9 ms with none and nothing the
 * display measured said where the difference went (docs/display.md, "Where
 * a frame's time goes"). One context; create, use and free with it current.
 * Owns the disp_gpu_time_ prefix. */
#ifndef CT_DISP_GPU_TIME_H
#define CT_DISP_GPU_TIME_H

#include <stdint.h>

#include "common/error.h"

typedef enum {
    DISP_GT_TAKE,      /* texture operations and texel uploads (disp_inbox_apply) */
    DISP_GT_DRAW,      /* the frame: radiosity or the kept base, corrections */
    DISP_GT_PRESENT,   /* tone mapping into the window or the presented image */
    DISP_GT_STAGES
} disp_gt_stage;

typedef struct disp_gpu_time disp_gpu_time;

int disp_gpu_time_new(disp_gpu_time **out, ct_error *err);

/* Times the GL commands between begin and end as stage s (added to the
 * stage's total; not the first pair's, which Mesa answers wrongly). Pairs
 * do not nest. Without a free query (the GPU is more than a few dozen
 * stages behind) the pair goes untimed and is counted. */
void disp_gpu_time_begin(disp_gpu_time *t, disp_gt_stage s);
void disp_gpu_time_end(disp_gpu_time *t);

/* Collects the results the GPU has ready. */
void disp_gpu_time_poll(disp_gpu_time *t);

/* Waits for every pending result (glFinish first), then the totals: ms[s]
 * and n[s] timed pairs per stage; *untimed: pairs that found no query or
 * whose result was not believable (over a minute). */
void disp_gpu_time_totals(disp_gpu_time *t, double ms[DISP_GT_STAGES], uint64_t n[DISP_GT_STAGES],
                          uint64_t *untimed);

void disp_gpu_time_free(disp_gpu_time *t);

#endif

/* fsink.h: the files sink (sink.h) of corrtex converge. At each checkpoint
 * (a lockstep frame of the loop, drive.h) it writes what the display would
 * draw (the software compositor, ctex_composite, over the view's primary
 * hits): corrected_N.exr/.png, the positions of the phase's samples
 * (samples_N.png, Fig. 7 right) and a row of convergence.csv with the
 * errors against a reference image and against the samples' own
 * high-quality values; at the end of a phase hq_samples.exr. File names
 * take the phase's prefix ("after_" after a camera move). Owns the fsink_
 * prefix; docs/textures.md lists the files and columns. */
#ifndef CT_MASTER_FSINK_H
#define CT_MASTER_FSINK_H

#include "common/error.h"
#include "master/ctex.h"
#include "master/session.h"
#include "master/sink.h"

typedef struct fsink_config {
    const char *out;       /* output folder (exists) */
    float exposure;        /* PNG exposure (stops) */
    int width, height;     /* the view's image size */
} fsink_config;

typedef struct fsink fsink;

/* Opens DIR/convergence.csv (written atomically by fsink_commit). */
int fsink_new(const fsink_config *c, fsink **out, ct_error *err);

/* Frees; an uncommitted convergence.csv is not written. */
void fsink_free(fsink *k);

sink fsink_sink(fsink *k);

/* A phase starts (its checkpoints count its samples from 0): the name in
 * the CSV ("still", "after"), the file prefix, the primary hits of its view
 * (width x height x spp, a pixel's spp hits one after the other, kept by
 * the caller; ctex_composite) and its reference image (NULL: none; it must
 * have the view's size). */
int fsink_phase(fsink *k, const char *phase, const char *prefix, const ctex_hit *hits, int spp, const char *ref,
                ct_error *err);

/* The image without this phase's samples: NAME.exr/.png and a CSV row of
 * phase NAME with 0 samples ("radiosity", "moved"). */
int fsink_snapshot(fsink *k, sess *s, const char *name, ct_error *err);

/* Fig. 5: each pixel in its texture's colour, shaded by the interactive
 * image: STEM.png. */
int fsink_assignment(fsink *k, sess *s, const char *stem, ct_error *err);

/* The end of a phase: PREFIXhq_samples.exr. */
int fsink_end_phase(fsink *k, ct_error *err);

/* Writes convergence.csv. */
int fsink_commit(fsink *k, const char **path, ct_error *err);

#endif

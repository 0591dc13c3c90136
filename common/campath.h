/* campath.h: camera paths for walkthroughs and benchmarks. A path is a list
 * of keyframes (time, eye, target, fov) with a global up vector; positions are
 * interpolated by a Catmull-Rom spline over time, orientations by slerp.
 * File format (docs/scene-format.md): plain text, one keyframe a line,
 *   t  ex ey ez  tx ty tz  [fov_deg]
 * '#' starts a comment; an optional line "up ux uy uz" sets the up vector. */
#ifndef CT_CAMPATH_H
#define CT_CAMPATH_H

#include <stdio.h>

#include "common/camera.h"
#include "common/error.h"

typedef struct campath_key {
    float t;        /* seconds, strictly increasing */
    vec3 eye;
    vec3 target;
    float fov_deg;
} campath_key;

typedef struct ct_campath {
    char name[64];
    vec3 up;
    int nkeys;
    campath_key *keys;
    ct_camera *cams;   /* the keyframes as cameras (orientation per key) */
} ct_campath;

/* Parses path text; `origin` names the source in error messages. */
int campath_parse(const char *text, const char *origin, ct_campath *out, ct_error *err);

/* Loads a path file. */
int campath_load(const char *path, ct_campath *out, ct_error *err);

/* Builds a path from keyframes (copied); validates them like the parser. */
int campath_from_keys(const campath_key *keys, int n, vec3 up, const char *origin,
                      ct_campath *out, ct_error *err);

/* Writes a path in the text format to f. */
void campath_write(const ct_campath *p, FILE *f);

/* Writes a path in the text format (atomically). */
int campath_save(const ct_campath *p, const char *path, ct_error *err);

/* Duration: time of the last keyframe minus that of the first. */
float campath_duration(const ct_campath *p);

/* Camera at time t (clamped to the path's time range). */
ct_camera campath_eval(const ct_campath *p, float t);

/* Camera at frame k of n, frames spread evenly over the whole path. */
ct_camera campath_frame(const ct_campath *p, int k, int n);

/* Releases the keyframes. */
void campath_free(ct_campath *p);

#endif

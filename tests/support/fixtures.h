/* fixtures.h: helpers shared by unit tests: temporary folders and files that
 * are removed (and their strings freed) when the test process exits, and
 * random test data. */
#ifndef CT_TEST_FIXTURES_H
#define CT_TEST_FIXTURES_H

#include "common/rng.h"
#include "common/vecmath.h"

/* Creates a fresh temporary folder; its path lives until exit. */
const char *fx_tmpdir(void);

/* Writes text to dir/name and returns the full path (lives until exit). */
const char *fx_write(const char *dir, const char *name, const char *text);

/* Joins dir/name into a string that lives until exit. */
const char *fx_path(const char *dir, const char *name);

/* A random unit vector (uniform in direction) drawn from r. */
vec3 fx_rand_unit(ct_rng *r);

#endif

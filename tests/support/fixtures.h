/* fixtures.h: helpers shared by unit tests: temporary folders and files. */
#ifndef CT_TEST_FIXTURES_H
#define CT_TEST_FIXTURES_H

#include <stddef.h>

/* Creates a fresh temporary folder and returns its path (static storage per call site is not needed: the string is heap-allocated and lives until exit). */
const char *fx_tmpdir(void);

/* Writes text to dir/name and returns the full path (heap, lives until exit). */
const char *fx_write(const char *dir, const char *name, const char *text);

#endif

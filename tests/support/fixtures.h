/* fixtures.h: helpers shared by unit tests: temporary folders and files that
 * are removed (and their strings freed) when the test process exits. */
#ifndef CT_TEST_FIXTURES_H
#define CT_TEST_FIXTURES_H

/* Creates a fresh temporary folder; its path lives until exit. */
const char *fx_tmpdir(void);

/* Writes text to dir/name and returns the full path (lives until exit). */
const char *fx_write(const char *dir, const char *name, const char *text);

/* Joins dir/name into a string that lives until exit. */
const char *fx_path(const char *dir, const char *name);

#endif

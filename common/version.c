#include "common/version.h"

/* CT_GIT_COMMIT: build/<config>/version/ct_commit.h, written by the Makefile
 * only when the commit changes, so that a new commit recompiles this file
 * alone (a -D in CFLAGS would rebuild every object). */
#include "ct_commit.h"

void ct_version_print(const char *prog, FILE *f)
{
    fprintf(f, "%s %s (git %s)\n", prog, CT_VERSION, CT_GIT_COMMIT);
}

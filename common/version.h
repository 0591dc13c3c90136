/* version.h: the programs' version, the one place it is defined: every
 * program's --version prints "PROGRAM 0.1.0 (git cefb384)", the release
 * number below and the git commit the build came from. The Makefile writes
 * that commit into build/<config>/version/ct_commit.h ("unknown" when the
 * tree is no git checkout, e.g. a tarball); scripts/corrtex-walk prints
 * the version of the programs it runs. Owns the ct_version prefix. */
#ifndef CT_VERSION_H
#define CT_VERSION_H

#include <stdio.h>

#define CT_VERSION "0.1.0"

/* Writes the one --version line, "PROG 0.1.0 (git cefb384)", to f. */
void ct_version_print(const char *prog, FILE *f);

#endif

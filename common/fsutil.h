/* fsutil.h: file helpers: atomic writes (write a temporary beside the target,
 * fsync, rename) so no reader ever sees a half-written output, whole-file
 * reads with a size cap, and directory creation. */
#ifndef CT_FSUTIL_H
#define CT_FSUTIL_H

#include <stdio.h>
#include <stddef.h>

#include "common/error.h"

typedef struct fs_atomic {
    FILE *f;
    char tmp[4096];
    char path[4096];
} fs_atomic;

/* Opens a temporary file beside path for writing. */
int fs_atomic_open(fs_atomic *a, const char *path, ct_error *err);

/* Flushes, syncs and renames the temporary onto path; on failure removes it. */
int fs_atomic_commit(fs_atomic *a, ct_error *err);

/* Writes len bytes to path atomically (fs_atomic_open / commit). */
int fs_write_atomic(const char *path, const void *data, size_t len, ct_error *err);

/* Closes and removes the temporary (the target is untouched). */
void fs_atomic_abort(fs_atomic *a);

/* A unique temporary name beside path (for libraries that open files themselves). */
void fs_temp_name(const char *path, char *out, size_t cap);

/* Renames tmp onto path after syncing it; removes tmp on failure. */
int fs_commit_temp(const char *tmp, const char *path, ct_error *err);

/* Reads a whole file (NUL-terminated copy in *data); fails over max bytes. */
int fs_read_all(const char *path, size_t max, char **data, size_t *len, ct_error *err);

/* mkdir -p. */
int fs_mkdirs(const char *path, ct_error *err);

/* Directory part of path ("." when none) into out. */
void fs_dirname(const char *path, char *out, size_t cap);

/* Joins dir and a relative name; an absolute name is copied as is. */
void fs_join(const char *dir, const char *name, char *out, size_t cap);

#endif

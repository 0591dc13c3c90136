/* fsutil.h: file helpers: atomic writes (write a temporary beside the target,
 * fsync, rename) so no reader ever sees a half-written output, whole-file
 * reads with a size cap, and directory creation. Only regular files are
 * read, and only regular files are replaced: a FIFO would block a reader for
 * good, and renaming over a device or FIFO would replace the node itself (as
 * root, /dev/null); those are written in place (docs/architecture.md). */
#ifndef CT_FSUTIL_H
#define CT_FSUTIL_H

#include <stdio.h>
#include <stddef.h>

#include "common/error.h"

typedef struct fs_atomic {
    FILE *f;
    char tmp[4096];    /* "" when path is a device or FIFO written in place */
    char path[4096];
} fs_atomic;

/* Opens a temporary file beside path for writing; when path is a character
 * device or a FIFO, opens path itself (a FIFO without a reader fails at
 * once). Other file types (folders, sockets, block devices) are refused. */
int fs_atomic_open(fs_atomic *a, const char *path, ct_error *err);

/* Flushes, syncs and renames the temporary onto path; on failure removes it. */
int fs_atomic_commit(fs_atomic *a, ct_error *err);

/* Fails now when fs_atomic_open(path) would (a refused file type, a folder
 * that cannot be written), without changing path or opening a FIFO: a
 * reader would take the close for the end of the output. */
int fs_output_check(const char *path, ct_error *err);

/* Fails (CT_EIO, "PATH: cannot create: its folder DIR does not exist")
 * when path's folder is missing, and checks nothing else: for an output
 * that may also be read, such as a cache in a read-only place. An output
 * file's folder is never made for it (docs/architecture.md, "Outputs");
 * fs_output_check and fs_atomic_open fail the same way. */
int fs_output_folder_check(const char *path, ct_error *err);

/* Fails (CT_EINVAL, "OPT DIR: not a folder") when dir exists and is no
 * folder: an output folder given as option opt, checked before any work
 * (fs_mkdirs finds it only when it is made, after the work's inputs). */
int fs_folder_check(const char *opt, const char *dir, ct_error *err);

/* Writes len bytes to path atomically (fs_atomic_open / commit). */
int fs_write_atomic(const char *path, const void *data, size_t len, ct_error *err);

/* Closes and removes the temporary (the target is untouched). */
void fs_atomic_abort(fs_atomic *a);

/* Opens a regular file for reading (anything else fails at once, a FIFO
 * included, without blocking); *size gets its size. */
int fs_open_regular(const char *path, FILE **f, size_t *size, ct_error *err);

/* Reads a whole file (NUL-terminated copy in *data); fails over max bytes. */
int fs_read_all(const char *path, size_t max, char **data, size_t *len, ct_error *err);

/* mkdir -p. */
int fs_mkdirs(const char *path, ct_error *err);

/* The user's cache folder for corrtex: $XDG_CACHE_HOME/corrtex, else
 * ~/.cache/corrtex, else /tmp/corrtex-cache (no HOME: a daemon). Every
 * program keeps its caches there (radiosity solutions, received scenes), so
 * each finds what another computed. With make, the folder is made when
 * missing (fails with the folder named when it cannot be). */
int fs_user_cache_dir(char *out, size_t cap, int make, ct_error *err);

/* Directory part of path ("." when none) into out. */
void fs_dirname(const char *path, char *out, size_t cap);

/* Joins dir and a relative name with one '/' (dir may end in one); an
 * absolute name is copied as is. */
void fs_join(const char *dir, const char *name, char *out, size_t cap);

#endif

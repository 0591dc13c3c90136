#include "common/fsutil.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* "a FIFO", "a folder", ... for messages about a file of the wrong type. */
static const char *type_name(mode_t m)
{
    if (S_ISDIR(m)) return "a folder";
    if (S_ISFIFO(m)) return "a FIFO";
    if (S_ISCHR(m)) return "a character device";
    if (S_ISBLK(m)) return "a block device";
    if (S_ISSOCK(m)) return "a socket";
    return "a special file";
}

/* Clears O_NONBLOCK, which was only wanted for the open itself. */
static int blocking(int fd)
{
    int fl = fcntl(fd, F_GETFL);
    return fl < 0 ? -1 : fcntl(fd, F_SETFL, fl & ~O_NONBLOCK);
}

static void temp_name(const char *path, char *out, size_t cap)
{
    static unsigned counter;
    unsigned n = __atomic_fetch_add(&counter, 1u, __ATOMIC_RELAXED);
    snprintf(out, cap, "%s.tmp.%ld.%u", path, (long)getpid(), n);
}

/* Opens a device or FIFO target in place. O_NONBLOCK makes the open of a
 * FIFO without a reader fail (ENXIO) instead of waiting for one for good. */
static int open_in_place(fs_atomic *a, const char *path, ct_error *err)
{
    int fd = open(path, O_WRONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) {
        if (errno == ENXIO) return ct_fail(err, CT_EIO, "%s: a FIFO without a reader", path);
        return ct_fail(err, CT_EIO, "%s: cannot open: %s", path, strerror(errno));
    }
    if (blocking(fd) != 0 || !(a->f = fdopen(fd, "wb"))) {
        int e = errno;
        close(fd);
        return ct_fail(err, CT_EIO, "%s: cannot open: %s", path, strerror(e));
    }
    return CT_OK;
}

/* 1 when path is a device or FIFO to write in place, 0 for a regular file
 * or none, or an error for a type that is refused. */
static int in_place(const char *path, ct_error *err)
{
    struct stat st;
    if (stat(path, &st) != 0 || S_ISREG(st.st_mode)) return 0;
    if (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode)) return 1;
    return ct_fail(err, CT_EINVAL, "%s: is %s; outputs go to regular files, character devices or FIFOs", path,
                   type_name(st.st_mode));
}

/* An output file's folder is not made for it (docs/architecture.md,
 * "Outputs"): the message says which one is missing. */
static int missing_folder(const char *path, ct_error *err)
{
    char dir[4096];
    fs_dirname(path, dir, sizeof dir);
    return ct_fail(err, CT_EIO, "%s: cannot create: its folder %s does not exist", path, dir);
}

int fs_output_folder_check(const char *path, ct_error *err)
{
    char dir[4096];
    fs_dirname(path, dir, sizeof dir);
    struct stat st;
    if (stat(dir, &st) != 0 && errno == ENOENT) return missing_folder(path, err);
    return CT_OK;
}

int fs_folder_check(const char *opt, const char *dir, ct_error *err)
{
    struct stat st;
    if (stat(dir, &st) == 0 && !S_ISDIR(st.st_mode)) return ct_fail(err, CT_EINVAL, "%s %s: not a folder", opt, dir);
    return CT_OK;
}

int fs_atomic_open(fs_atomic *a, const char *path, ct_error *err)
{
    memset(a, 0, sizeof *a);
    if (strlen(path) + 32 >= sizeof a->path)
        return ct_fail(err, CT_EINVAL, "%s: path too long", path);
    snprintf(a->path, sizeof a->path, "%s", path);
    int kind = in_place(path, err);
    if (kind < 0) return kind;
    if (kind) return open_in_place(a, path, err);
    temp_name(path, a->tmp, sizeof a->tmp);
    a->f = fopen(a->tmp, "wb");
    if (!a->f) {
        int e = errno;
        if (e == ENOENT) return missing_folder(path, err);
        return ct_fail(err, CT_EIO, "%s: cannot create: %s", path, strerror(e));
    }
    return CT_OK;
}

int fs_output_check(const char *path, ct_error *err)
{
    int kind = in_place(path, err);
    if (kind < 0) return kind;
    if (kind) {
        if (access(path, W_OK) != 0) return ct_fail(err, CT_EIO, "%s: cannot open: %s", path, strerror(errno));
        return CT_OK;
    }
    fs_atomic a;
    int rc = fs_atomic_open(&a, path, err);
    if (rc == CT_OK) fs_atomic_abort(&a);
    return rc;
}

static int commit_temp(const char *tmp, const char *path, ct_error *err)
{
    int fd = open(tmp, O_RDONLY);
    if (fd >= 0) { (void)fsync(fd); close(fd); }
    if (rename(tmp, path) != 0) {
        int e = errno;
        unlink(tmp);
        return ct_fail(err, CT_EIO, "%s: cannot write: %s", path, strerror(e));
    }
    return CT_OK;
}

int fs_atomic_commit(fs_atomic *a, ct_error *err)
{
    if (!a->f) return ct_fail(err, CT_EIO, "%s: not open", a->path);
    int bad = ferror(a->f) || fflush(a->f) != 0;
    int e = errno;
    /* A device or FIFO has nothing to sync (fsync fails with EINVAL there). */
    if (!bad && a->tmp[0]) bad = fsync(fileno(a->f)) != 0, e = errno;
    if (fclose(a->f) != 0 && !bad) bad = 1, e = errno;
    a->f = NULL;
    if (bad) {
        if (a->tmp[0]) unlink(a->tmp);
        return ct_fail(err, CT_EIO, "%s: write failed: %s", a->path, strerror(e));
    }
    return a->tmp[0] ? commit_temp(a->tmp, a->path, err) : CT_OK;
}

int fs_write_atomic(const char *path, const void *data, size_t len, ct_error *err)
{
    fs_atomic a;
    int rc = fs_atomic_open(&a, path, err);
    if (rc) return rc;
    if (fwrite(data, 1, len, a.f) != len) {
        fs_atomic_abort(&a);
        return ct_fail(err, CT_EIO, "%s: write failed", path);
    }
    return fs_atomic_commit(&a, err);
}

void fs_atomic_abort(fs_atomic *a)
{
    if (a->f) { fclose(a->f); a->f = NULL; }
    if (a->tmp[0]) unlink(a->tmp);
}

int fs_open_regular(const char *path, FILE **f, size_t *size, ct_error *err)
{
    *f = NULL;
    *size = 0;
    /* O_NONBLOCK: opening a FIFO for reading would wait for a writer. */
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) return ct_fail(err, CT_EIO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fd, &st) != 0) {
        int e = errno;
        close(fd);
        return ct_fail(err, CT_EIO, "%s: cannot open: %s", path, strerror(e));
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        return ct_fail(err, CT_EIO, "%s: is %s, not a regular file", path, type_name(st.st_mode));
    }
    if (blocking(fd) != 0 || !(*f = fdopen(fd, "rb"))) {
        int e = errno;
        close(fd);
        return ct_fail(err, CT_EIO, "%s: cannot open: %s", path, strerror(e));
    }
    *size = (size_t)st.st_size;
    return CT_OK;
}

int fs_read_all(const char *path, size_t max, char **data, size_t *len, ct_error *err)
{
    *data = NULL;
    if (len) *len = 0;
    FILE *f;
    size_t n;
    int rc = fs_open_regular(path, &f, &n, err);
    if (rc) return rc;
    if (n > max) {
        fclose(f);
        return ct_fail(err, CT_ERANGE, "%s: file too large (%zu bytes, limit %zu)", path, n, max);
    }
    char *buf = malloc(n + 1);
    if (!buf) { fclose(f); return ct_fail(err, CT_ENOMEM, "%s: out of memory", path); }
    size_t got = fread(buf, 1, n, f);
    int bad = ferror(f);
    fclose(f);
    if (bad || got != n) { free(buf); return ct_fail(err, CT_EIO, "%s: read failed", path); }
    buf[n] = '\0';
    *data = buf;
    if (len) *len = n;
    return CT_OK;
}

int fs_mkdirs(const char *path, ct_error *err)
{
    char tmp[4096];
    if (snprintf(tmp, sizeof tmp, "%s", path) >= (int)sizeof tmp)
        return ct_fail(err, CT_EINVAL, "%s: path too long", path);
    for (char *p = tmp + 1; *p; p++) {
        if (*p != '/') continue;
        *p = '\0';
        if (mkdir(tmp, 0777) != 0 && errno != EEXIST)
            return ct_fail(err, CT_EIO, "%s: cannot create directory: %s", tmp, strerror(errno));
        *p = '/';
    }
    if (mkdir(tmp, 0777) != 0 && errno != EEXIST)
        return ct_fail(err, CT_EIO, "%s: cannot create directory: %s", tmp, strerror(errno));
    return CT_OK;
}

int fs_user_cache_dir(char *out, size_t cap, int make, ct_error *err)
{
    const char *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    int n;
    if (xdg && *xdg) n = snprintf(out, cap, "%s/corrtex", xdg);
    else if (home && *home) n = snprintf(out, cap, "%s/.cache/corrtex", home);
    else n = snprintf(out, cap, "/tmp/corrtex-cache");
    if (n < 0 || (size_t)n >= cap) return ct_fail(err, CT_EINVAL, "the cache folder's path is too long");
    return make ? fs_mkdirs(out, err) : CT_OK;
}

void fs_dirname(const char *path, char *out, size_t cap)
{
    const char *slash = strrchr(path, '/');
    if (!slash) { snprintf(out, cap, "."); return; }
    if (slash == path) { snprintf(out, cap, "/"); return; }
    snprintf(out, cap, "%.*s", (int)(slash - path), path);
}

void fs_join(const char *dir, const char *name, char *out, size_t cap)
{
    if (name[0] == '/' || !dir || !dir[0]) {
        snprintf(out, cap, "%s", name);
        return;
    }
    /* dir/ from a user's tab completion: one separator in what we print */
    snprintf(out, cap, "%s%s%s", dir, dir[strlen(dir) - 1] == '/' ? "" : "/", name);
}

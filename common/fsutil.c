#include "common/fsutil.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

void fs_temp_name(const char *path, char *out, size_t cap)
{
    static unsigned counter;
    unsigned n = __atomic_fetch_add(&counter, 1u, __ATOMIC_RELAXED);
    snprintf(out, cap, "%s.tmp.%ld.%u", path, (long)getpid(), n);
}

int fs_atomic_open(fs_atomic *a, const char *path, ct_error *err)
{
    memset(a, 0, sizeof *a);
    if (strlen(path) + 32 >= sizeof a->path)
        return ct_fail(err, CT_EINVAL, "%s: path too long", path);
    snprintf(a->path, sizeof a->path, "%s", path);
    fs_temp_name(path, a->tmp, sizeof a->tmp);
    a->f = fopen(a->tmp, "wb");
    if (!a->f) return ct_fail(err, CT_EIO, "%s: cannot create: %s", path, strerror(errno));
    return CT_OK;
}

int fs_commit_temp(const char *tmp, const char *path, ct_error *err)
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
    if (!bad) bad = fsync(fileno(a->f)) != 0, e = errno;
    if (fclose(a->f) != 0 && !bad) bad = 1, e = errno;
    a->f = NULL;
    if (bad) {
        unlink(a->tmp);
        return ct_fail(err, CT_EIO, "%s: write failed: %s", a->path, strerror(e));
    }
    return fs_commit_temp(a->tmp, a->path, err);
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

int fs_read_all(const char *path, size_t max, char **data, size_t *len, ct_error *err)
{
    *data = NULL;
    if (len) *len = 0;
    FILE *f = fopen(path, "rb");
    if (!f) return ct_fail(err, CT_EIO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode)) {
        fclose(f);
        return ct_fail(err, CT_EIO, "%s: not a regular file", path);
    }
    if ((size_t)st.st_size > max) {
        fclose(f);
        return ct_fail(err, CT_ERANGE, "%s: file too large (%lld bytes, limit %zu)", path,
                       (long long)st.st_size, max);
    }
    size_t n = (size_t)st.st_size;
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

void fs_dirname(const char *path, char *out, size_t cap)
{
    const char *slash = strrchr(path, '/');
    if (!slash) { snprintf(out, cap, "."); return; }
    if (slash == path) { snprintf(out, cap, "/"); return; }
    snprintf(out, cap, "%.*s", (int)(slash - path), path);
}

void fs_join(const char *dir, const char *name, char *out, size_t cap)
{
    if (name[0] == '/' || !dir || !dir[0]) snprintf(out, cap, "%s", name);
    else snprintf(out, cap, "%s/%s", dir, name);
}

/* test_fsutil.c: the file helpers with files that are not regular: a FIFO
 * or folder given as input fails at once (a FIFO used to block the open for
 * good), and outputs replace only regular files: a FIFO or character device
 * is written in place and stays what it was, a FIFO without a reader and a
 * folder are refused with one line, and so is a file whose folder is
 * missing (it is not made); fs_join puts one separator. */
#include <criterion/criterion.h>
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include "common/fsutil.h"
#include "tests/support/fixtures.h"

static const char *g_dir;

static void make_dir(void) { g_dir = fx_tmpdir(); }

TestSuite(fsutil, .init = make_dir, .timeout = 10);

static const char *at(const char *name) { return fx_path(g_dir, name); }

static const char *fifo(const char *name)
{
    const char *p = at(name);
    cr_assert_eq(mkfifo(p, 0600), 0, "mkfifo %s: %s", p, strerror(errno));
    return p;
}

/* Entries in g_dir: a temporary left behind shows up here. */
static int entries(void)
{
    char cmd[300];
    snprintf(cmd, sizeof cmd, "ls -A '%s' | wc -l", g_dir);
    FILE *f = popen(cmd, "r");
    int n = -1;
    cr_assert(f && fscanf(f, "%d", &n) == 1);
    pclose(f);
    return n;
}

Test(fsutil, fifo_and_folder_inputs_fail_at_once)
{
    const char *p = fifo("scene.json");
    char *data = NULL;
    size_t len;
    ct_error err;
    cr_assert_eq(fs_read_all(p, 1 << 20, &data, &len, &err), CT_EIO);
    cr_assert_null(data);
    cr_assert(strstr(err.msg, p) && strstr(err.msg, "is a FIFO, not a regular file"), "%s", err.msg);
    cr_assert_eq(fs_read_all(g_dir, 1 << 20, &data, &len, &err), CT_EIO);
    cr_assert(strstr(err.msg, "is a folder"), "%s", err.msg);
    FILE *f;
    cr_assert_eq(fs_open_regular(p, &f, &len, &err), CT_EIO);
    cr_assert_null(f);
}

typedef struct reader {
    const char *path;
    char got[64];
    size_t n;
} reader;

static void *read_fifo(void *arg)
{
    reader *r = arg;
    int fd = open(r->path, O_RDONLY);
    if (fd < 0) return NULL;
    ssize_t k;
    while (r->n < sizeof r->got && (k = read(fd, r->got + r->n, sizeof r->got - r->n)) > 0) r->n += (size_t)k;
    close(fd);
    return NULL;
}

Test(fsutil, fifo_output_is_written_in_place)
{
    reader r = {.path = fifo("out.exr")};
    pthread_t th;
    cr_assert_eq(pthread_create(&th, NULL, read_fifo, &r), 0);
    /* Until the reader has opened its end, the writer is told there is none. */
    ct_error err;
    int rc;
    for (int i = 0; i < 500 && (rc = fs_write_atomic(r.path, "corrtex", 7, &err)) != CT_OK; i++) usleep(2000);
    cr_assert_eq(rc, CT_OK, "%s", err.msg);
    pthread_join(th, NULL);
    cr_assert_eq(r.n, 7);
    cr_assert_eq(memcmp(r.got, "corrtex", 7), 0);
    struct stat st;
    cr_assert_eq(stat(r.path, &st), 0);
    cr_assert(S_ISFIFO(st.st_mode), "the FIFO was replaced");
    cr_assert_eq(entries(), 1, "a temporary was left behind");
}

Test(fsutil, fifo_without_reader_and_folders_are_refused)
{
    const char *p = fifo("nobody.png");
    ct_error err;
    cr_assert_eq(fs_write_atomic(p, "x", 1, &err), CT_EIO);
    cr_assert(strstr(err.msg, p) && strstr(err.msg, "a FIFO without a reader"), "%s", err.msg);
    /* The early check does not open the FIFO: a reader would see its end. */
    cr_assert_eq(fs_output_check(p, &err), CT_OK, "%s", err.msg);

    const char *d = at("folder.exr");
    cr_assert_eq(mkdir(d, 0700), 0);
    cr_assert_eq(fs_write_atomic(d, "x", 1, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "is a folder; outputs go to regular files, character devices or FIFOs"), "%s",
              err.msg);
    cr_assert_eq(fs_output_check(d, &err), CT_EINVAL);
    struct stat st;
    cr_assert(stat(d, &st) == 0 && S_ISDIR(st.st_mode));
    cr_assert_eq(entries(), 2);
}

/* An output file's folder is not made for it (docs/architecture.md,
 * "Outputs"): the early check and the write both name the missing folder,
 * and nothing is created. */
Test(fsutil, output_in_a_missing_folder_names_the_folder)
{
    const char *p = at("no/such/x.exr");
    ct_error err;
    cr_assert_eq(fs_output_check(p, &err), CT_EIO);
    char want[512];
    snprintf(want, sizeof want, "%s: cannot create: its folder %s/no/such does not exist", p, g_dir);
    cr_assert_str_eq(err.msg, want);
    cr_assert_eq(fs_write_atomic(p, "x", 1, &err), CT_EIO);
    cr_assert_str_eq(err.msg, want);
    cr_assert_eq(fs_output_folder_check(p, &err), CT_EIO);
    cr_assert_str_eq(err.msg, want);
    cr_assert_eq(entries(), 0, "a folder was made for the output");
    /* a folder that exists passes, writable or not (a cache may be read-only) */
    cr_assert_eq(fs_output_folder_check(at("x.ctmesh"), &err), CT_OK, "%s", err.msg);
    cr_assert_eq(fs_output_folder_check("x.ctmesh", &err), CT_OK, "%s", err.msg);
}

Test(fsutil, character_device_output_stays_a_device)
{
    /* A node of /dev/null's numbers in our own folder: as root the old
     * rename replaced such a node (and /dev/null itself) with a file. */
    const char *p = at("null.exr");
    if (mknod(p, S_IFCHR | 0600, makedev(1, 3)) != 0) cr_skip_test("mknod needs root: %s", strerror(errno));
    ct_error err;
    cr_assert_eq(fs_write_atomic(p, "corrtex", 7, &err), CT_OK, "%s", err.msg);
    fs_atomic a;
    cr_assert_eq(fs_atomic_open(&a, p, &err), CT_OK, "%s", err.msg);
    fputs("more", a.f);
    cr_assert_eq(fs_atomic_commit(&a, &err), CT_OK, "%s", err.msg);
    struct stat st;
    cr_assert_eq(stat(p, &st), 0);
    cr_assert(S_ISCHR(st.st_mode), "the device node was replaced by a regular file");
    cr_assert_eq(entries(), 1, "a temporary was left behind");
}

Test(fsutil, regular_output_is_replaced_atomically)
{
    const char *p = at("out.txt");
    ct_error err;
    cr_assert_eq(fs_write_atomic(p, "old", 3, &err), CT_OK, "%s", err.msg);
    fs_atomic a;
    cr_assert_eq(fs_atomic_open(&a, p, &err), CT_OK, "%s", err.msg);
    fputs("new", a.f);
    char *data;
    size_t len;
    cr_assert_eq(fs_read_all(p, 100, &data, &len, &err), CT_OK);
    cr_assert_str_eq(data, "old", "the target changed before the commit");
    free(data);
    cr_assert_eq(fs_atomic_commit(&a, &err), CT_OK, "%s", err.msg);
    cr_assert_eq(fs_read_all(p, 100, &data, &len, &err), CT_OK);
    cr_assert_str_eq(data, "new");
    free(data);
    cr_assert_eq(entries(), 1);
}

Test(fsutil, join_puts_one_separator)
{
    char out[64];
    fs_join("ref", "frame_00000.exr", out, sizeof out);
    cr_assert_str_eq(out, "ref/frame_00000.exr");
    fs_join("ref/", "frame_00000.exr", out, sizeof out);
    cr_assert_str_eq(out, "ref/frame_00000.exr");
    fs_join("/", "x", out, sizeof out);
    cr_assert_str_eq(out, "/x");
    fs_join("", "x", out, sizeof out);
    cr_assert_str_eq(out, "x");
    fs_join("ref", "/abs/x", out, sizeof out);
    cr_assert_str_eq(out, "/abs/x");
    fs_join("a-long-folder-name", "frame.exr", out, 8);   /* cut, still a string */
    cr_assert_str_eq(out, "a-long-");
}

Test(fsutil, an_output_folder_that_is_a_file_is_refused)
{
    ct_error err;
    const char *f = at("notes.txt");
    cr_assert_eq(fs_write_atomic(f, "x", 1, &err), CT_OK, "%s", err.msg);
    cr_assert_eq(fs_folder_check("--out", f, &err), CT_EINVAL);
    char want[512];
    snprintf(want, sizeof want, "--out %s: not a folder", f);
    cr_assert_str_eq(err.msg, want);
    cr_assert_eq(fs_folder_check("--out", at(""), &err), CT_OK, "an existing folder refused");
    cr_assert_eq(fs_folder_check("--out", at("not-yet"), &err), CT_OK, "a folder still to be made refused");
}

/* Every program's caches in one folder: $XDG_CACHE_HOME/corrtex, else
 * ~/.cache/corrtex, else /tmp/corrtex-cache; made only when asked. */
Test(fsutil, the_user_cache_folder_follows_xdg_then_home)
{
    ct_error err;
    char out[4096], want[4096];
    const char *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    char *keep_xdg = xdg ? strdup(xdg) : NULL, *keep_home = home ? strdup(home) : NULL;

    setenv("XDG_CACHE_HOME", at("xdg"), 1);
    cr_assert_eq(fs_user_cache_dir(out, sizeof out, 0, &err), CT_OK, "%s", err.msg);
    snprintf(want, sizeof want, "%s/corrtex", at("xdg"));
    cr_assert_str_eq(out, want);
    struct stat st;
    cr_assert_neq(stat(out, &st), 0, "made without being asked");
    cr_assert_eq(fs_user_cache_dir(out, sizeof out, 1, &err), CT_OK, "%s", err.msg);
    cr_assert(stat(out, &st) == 0 && S_ISDIR(st.st_mode), "not made when asked");

    setenv("XDG_CACHE_HOME", "", 1);
    setenv("HOME", at("home"), 1);
    cr_assert_eq(fs_user_cache_dir(out, sizeof out, 0, &err), CT_OK, "%s", err.msg);
    snprintf(want, sizeof want, "%s/.cache/corrtex", at("home"));
    cr_assert_str_eq(out, want);

    unsetenv("XDG_CACHE_HOME");
    unsetenv("HOME");
    cr_assert_eq(fs_user_cache_dir(out, sizeof out, 0, &err), CT_OK, "%s", err.msg);
    cr_assert_str_eq(out, "/tmp/corrtex-cache");

    /* a folder that cannot be made is named */
    const char *f = at("a-file");
    cr_assert_eq(fs_write_atomic(f, "x", 1, &err), CT_OK, "%s", err.msg);
    setenv("XDG_CACHE_HOME", f, 1);
    cr_assert_eq(fs_user_cache_dir(out, sizeof out, 1, &err), CT_EIO);
    cr_assert(strstr(err.msg, "a-file/corrtex") != NULL, "%s", err.msg);
    char tiny[8];
    cr_assert_eq(fs_user_cache_dir(tiny, sizeof tiny, 0, &err), CT_EINVAL, "a path cut short was accepted");

    if (keep_xdg) setenv("XDG_CACHE_HOME", keep_xdg, 1); else unsetenv("XDG_CACHE_HOME");
    if (keep_home) setenv("HOME", keep_home, 1); else unsetenv("HOME");
    free(keep_xdg);
    free(keep_home);
}

/* .ctmesh cache: exact round trip, and a table of broken files each with
 * the message it must give (truncated, bad magic, wrong version, wrong
 * endianness, stale hash, corrupted bytes, out-of-range indices). */
#include <criterion/criterion.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

#include "common/fsutil.h"
#include "common/radmesh.h"

static char g_dir[256];

static void make_dir(void)
{
    snprintf(g_dir, sizeof g_dir, "/tmp/ct_rmesh_io_%ld", (long)getpid());
    ct_error err;
    cr_assert_eq(fs_mkdirs(g_dir, &err), 0, "%s", err.msg);
}

/* Whatever a test left there (it may stop at a failed assertion). */
static void remove_dir(void)
{
    if (!g_dir[0]) return;
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", g_dir);
}

TestSuite(radmesh_io, .fini = remove_dir);

static void path_of(char *out, size_t cap, const char *name) { snprintf(out, cap, "%s/%s", g_dir, name); }

/* A small mesh with every field set to a distinct value. */
static void sample_mesh(ct_radmesh *m)
{
    ct_error err;
    cr_assert_eq(rmesh_alloc(m, 5, 3, 3, &err), 0);
    for (uint32_t i = 0; i < 5; i++) {
        m->pos[i] = v3((float)i, 0.5f * (float)i, -1.25f);
        m->nrm[i] = v3(0, 1, 0);
        m->rad[i] = v3(0.1f * (float)i, 1.0f / 3.0f, 7.0f);
        m->rad_direct[i] = v3(0.05f * (float)i, 0.0f, 1e-20f);
    }
    uint32_t tris[9] = {0, 1, 2, 1, 3, 2, 2, 3, 4};
    memcpy(m->tris, tris, sizeof tris);
    for (uint32_t t = 0; t < 3; t++) {
        m->tri_node[t] = 1 + (t & 1);
        m->tri_mat[t] = t;
    }
    const char *names[3] = {"root", "part a", "part b"};
    int32_t parents[3] = {-1, 0, 0};
    uint32_t ends[3] = {3, 2, 3};
    for (uint32_t n = 0; n < 3; n++) {
        snprintf(m->nodes[n].name, sizeof m->nodes[n].name, "%s", names[n]);
        m->nodes[n].parent = parents[n];
        m->nodes[n].node_end = ends[n];
        m->nodes[n].material = n == 0 ? UINT32_MAX : n;
        m->nodes[n].bounds.lo = v3(-1, -2, -3);
        m->nodes[n].bounds.hi = v3(1, 2, 3);
    }
    m->mats = calloc(3, sizeof *m->mats);
    cr_assert_not_null(m->mats);
    m->nmats = 3;
    m->mats[1] = (rmesh_material){v3(0.9f, 0.5f, 0.25f), 1.5f};
    m->scene_hash = 0x0123456789abcdefULL;
}

static unsigned char *read_file(const char *path, size_t *len)
{
    char *d;
    ct_error err;
    cr_assert_eq(fs_read_all(path, 1 << 20, &d, len, &err), 0, "%s", err.msg);
    return (unsigned char *)d;
}

static void write_file(const char *path, const unsigned char *d, size_t len)
{
    FILE *f = fopen(path, "wb");
    cr_assert_not_null(f);
    cr_assert_eq(fwrite(d, 1, len, f), len);
    fclose(f);
}

Test(radmesh_io, round_trip_is_exact)
{
    make_dir();
    char p1[512], p2[512];
    path_of(p1, sizeof p1, "a.ctmesh");
    path_of(p2, sizeof p2, "b.ctmesh");
    ct_radmesh m, r;
    sample_mesh(&m);
    ct_error err;
    cr_assert_eq(rmesh_save(&m, p1, &err), 0, "%s", err.msg);
    cr_assert_eq(rmesh_load(p1, m.scene_hash, &r, &err), 0, "%s", err.msg);
    cr_assert_eq(r.nverts, m.nverts);
    cr_assert_eq(r.ntris, m.ntris);
    cr_assert_eq(r.nnodes, m.nnodes);
    cr_assert_eq(r.scene_hash, m.scene_hash);
    cr_assert_eq(r.nmats, 3u);
    cr_assert_eq(memcmp(r.mats, m.mats, 3 * sizeof *m.mats), 0);
    cr_assert(rmesh_is_glass(&r, 1) && !rmesh_is_glass(&r, 0) && !rmesh_is_glass(&r, 2) && !rmesh_is_glass(&r, 3));
    cr_assert_eq(memcmp(r.pos, m.pos, 5 * sizeof(vec3)), 0);
    cr_assert_eq(memcmp(r.nrm, m.nrm, 5 * sizeof(vec3)), 0);
    cr_assert_eq(memcmp(r.rad, m.rad, 5 * sizeof(vec3)), 0);
    cr_assert_eq(memcmp(r.rad_direct, m.rad_direct, 5 * sizeof(vec3)), 0);
    cr_assert_eq(memcmp(r.tris, m.tris, 9 * sizeof(uint32_t)), 0);
    cr_assert_eq(memcmp(r.tri_node, m.tri_node, 3 * sizeof(uint32_t)), 0);
    cr_assert_eq(memcmp(r.tri_mat, m.tri_mat, 3 * sizeof(uint32_t)), 0);
    for (uint32_t n = 0; n < 3; n++) {
        cr_assert_str_eq(r.nodes[n].name, m.nodes[n].name);
        cr_assert_eq(r.nodes[n].parent, m.nodes[n].parent);
        cr_assert_eq(r.nodes[n].node_end, m.nodes[n].node_end);
        cr_assert_eq(r.nodes[n].material, m.nodes[n].material);
        cr_assert_eq(memcmp(&r.nodes[n].bounds, &m.nodes[n].bounds, sizeof(bounds3)), 0);
    }
    /* Saving what was loaded gives the identical bytes. */
    cr_assert_eq(rmesh_save(&r, p2, &err), 0, "%s", err.msg);
    size_t l1, l2;
    unsigned char *d1 = read_file(p1, &l1), *d2 = read_file(p2, &l2);
    cr_assert_eq(l1, l2);
    cr_assert_eq(memcmp(d1, d2, l1), 0);
    /* Layout: 48-byte header, 48 per vertex, 20 per triangle, 100 per node,
     * 16 per material, 8 checksum. */
    cr_assert_eq(l1, 48u + 5 * 48 + 3 * 20 + 3 * 100 + 3 * 16 + 8);
    /* expect_hash 0 accepts any hash. */
    rmesh_free(&r);
    cr_assert_eq(rmesh_load(p1, 0, &r, &err), 0, "%s", err.msg);
    rmesh_free(&r);
    free(d1);
    free(d2);
    rmesh_free(&m);
    unlink(p1);
    unlink(p2);
}

typedef struct breakage {
    const char *what;
    size_t offset;       /* byte to change, or new length for truncation */
    int truncate;
    unsigned char value;
    int code;
    const char *msg;     /* substring of the error */
} breakage;

static uint64_t fnv(const unsigned char *p, size_t n)
{
    uint64_t h = 1469598103934665603ULL;
    for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * 1099511628211ULL;
    return h;
}

/* Rewrites the trailing checksum so a deliberate field change is checked by
 * the field's own test, not caught as corruption. */
static void fix_checksum(unsigned char *d, size_t len)
{
    uint64_t h = fnv(d, len - 8);
    for (int i = 0; i < 8; i++) d[len - 8 + (size_t)i] = (unsigned char)(h >> (8 * i));
}

Test(radmesh_io, broken_files_give_clear_errors)
{
    make_dir();
    char good[512], bad[512];
    path_of(good, sizeof good, "good.ctmesh");
    path_of(bad, sizeof bad, "bad.ctmesh");
    ct_radmesh m;
    sample_mesh(&m);
    ct_error err;
    cr_assert_eq(rmesh_save(&m, good, &err), 0, "%s", err.msg);
    size_t len;
    unsigned char *orig = read_file(good, &len);
    const size_t tri0 = 48 + 5 * 48, mat0 = tri0 + 3 * 20 + 3 * 100;
    const breakage cases[] = {
        {"empty file", 0, 1, 0, CT_EPARSE, "bad magic"},
        {"truncated header", 20, 1, 0, CT_EPARSE, "truncated header"},
        {"truncated body", 48 + 100, 1, 0, CT_EPARSE, "truncated"},
        {"one byte short", 0, 2, 0, CT_EPARSE, "truncated"},
        {"wrong magic", 0, 0, 'X', CT_EPARSE, "bad magic"},
        {"wrong version", 12, 0, 9, CT_EPARSE, "version 9 not supported"},
        {"byte-swapped", 16, 0, 1, CT_EPARSE, "endianness"},
        {"huge vertex count", 31, 0, 0x7f, CT_EPARSE, "out of range"},
        {"corrupted payload", 60, 0, 0xee, CT_EPARSE, "checksum"},
        {"vertex index out of range", tri0, 0, 200, CT_EPARSE, "vertex 200 out of range"},
        {"node out of range", tri0 + 12, 0, 9, CT_EPARSE, "node 9 out of range"},
        {"huge material count", 43, 0, 0x7f, CT_EPARSE, "out of range"},
        {"reserved header field", 44, 0, 1, CT_EPARSE, "reserved header field"},
        {"padding after the magic", 11, 0, 0x63, CT_EPARSE, "padding after the magic"},
        {"transmission over 1", mat0 + 16 + 3, 0, 0x7f, CT_EPARSE, "material 1: transmission"},
        {"negative index of refraction", mat0 + 32 + 15, 0, 0xbf, CT_EPARSE, "material 2: transmission"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const breakage *b = &cases[i];
        unsigned char *d = malloc(len);
        memcpy(d, orig, len);
        size_t n = len;
        if (b->truncate == 1) n = b->offset;
        else if (b->truncate == 2) n = len - 1;
        else {
            d[b->offset] = b->value;
            if (strcmp(b->what, "corrupted payload") != 0) fix_checksum(d, len);
        }
        write_file(bad, d, n);
        ct_radmesh r;
        int rc = rmesh_load(bad, 0, &r, &err);
        cr_assert_eq(rc, b->code, "%s: code %d (%s)", b->what, rc, err.msg);
        cr_assert(strstr(err.msg, b->msg) != NULL, "%s: message '%s' lacks '%s'", b->what, err.msg, b->msg);
        cr_assert(strstr(err.msg, bad) != NULL, "%s: message '%s' does not name the file", b->what, err.msg);
        cr_assert_eq(r.nverts, 0);
        free(d);
    }
    /* A stale hash: the file is fine but belongs to another scene or settings. */
    ct_radmesh r;
    int rc = rmesh_load(good, 0x1111ULL, &r, &err);
    cr_assert_eq(rc, CT_ESTALE, "%s", err.msg);
    cr_assert(strstr(err.msg, "stale") != NULL, "%s", err.msg);
    /* A missing file names the file too. */
    rc = rmesh_load(bad, 0, &r, &err);
    cr_assert_eq(rc, CT_EPARSE);
    unlink(bad);
    rc = rmesh_load(bad, 0, &r, &err);
    cr_assert_eq(rc, CT_EIO);
    cr_assert(strstr(err.msg, bad) != NULL);
    free(orig);
    rmesh_free(&m);
    unlink(good);
    rmdir(g_dir);
}

/* Peak resident memory of this test's process (Criterion runs each test in
 * its own process), in KiB. */
static long max_rss_kib(void)
{
    struct rusage ru;
    cr_assert_eq(getrusage(RUSAGE_SELF, &ru), 0);
    return ru.ru_maxrss;
}

Test(radmesh_io, large_bad_files_fail_on_their_header)
{
    /* 1 GiB sparse: once read in full (seconds, 1 GiB of memory) before the
     * magic was looked at. A good header whose counts do not match the size
     * fails as early. */
    make_dir();
    char p[512];
    path_of(p, sizeof p, "sparse.ctmesh");
    ct_radmesh m;
    sample_mesh(&m);
    unsigned char *enc;
    size_t enc_len;
    ct_error err;
    cr_assert_eq(rmesh_encode(&m, &enc, &enc_len, &err), 0, "%s", err.msg);
    const struct { size_t head; const char *msg; } cases[] = {{0, "bad magic"}, {48, "trailing bytes"}};
    long before = max_rss_kib();
    for (int i = 0; i < 2; i++) {
        FILE *f = fopen(p, "wb");
        cr_assert_not_null(f);
        cr_assert_eq(fwrite(enc, 1, cases[i].head, f), cases[i].head);
        cr_assert_eq(ftruncate(fileno(f), (off_t)1 << 30), 0);
        fclose(f);
        ct_radmesh r;
        cr_assert_eq(rmesh_load(p, 0, &r, &err), CT_EPARSE, "%s", err.msg);
        cr_assert(strstr(err.msg, cases[i].msg) && strstr(err.msg, p), "%s", err.msg);
    }
    long grown = max_rss_kib() - before;
    cr_assert_lt(grown, 64 << 10, "loading grew the resident memory by %ld KiB", grown);
    free(enc);
    rmesh_free(&m);
    unlink(p);
    rmdir(g_dir);
}

Test(radmesh_io, save_is_atomic_and_leaves_no_temporary)
{
    make_dir();
    char p[512];
    path_of(p, sizeof p, "c.ctmesh");
    ct_radmesh m;
    sample_mesh(&m);
    ct_error err;
    cr_assert_eq(rmesh_save(&m, p, &err), 0, "%s", err.msg);
    cr_assert_eq(rmesh_save(&m, p, &err), 0, "%s", err.msg);
    int files = 0;
    char cmd[600];
    snprintf(cmd, sizeof cmd, "ls %s | wc -l", g_dir);
    FILE *f = popen(cmd, "r");
    cr_assert_not_null(f);
    cr_assert_eq(fscanf(f, "%d", &files), 1);
    pclose(f);
    cr_assert_eq(files, 1, "temporaries left beside the cache");
    /* An unwritable target fails with the path in the message. */
    cr_assert_neq(rmesh_save(&m, "/nonexistent-dir/x.ctmesh", &err), 0);
    cr_assert(strstr(err.msg, "/nonexistent-dir/x.ctmesh") != NULL, "%s", err.msg);
    rmesh_free(&m);
    unlink(p);
    rmdir(g_dir);
}

Test(radmesh_io, decode_encode_round_trip_and_fuzz_corpus)
{
    ct_radmesh m, r;
    sample_mesh(&m);
    unsigned char *a, *b;
    size_t la, lb;
    ct_error err;
    cr_assert_eq(rmesh_encode(&m, &a, &la, &err), 0, "%s", err.msg);
    cr_assert_eq(rmesh_decode(a, la, "mem", m.scene_hash, &r, &err), 0, "%s", err.msg);
    cr_assert_eq(rmesh_encode(&r, &b, &lb, &err), 0, "%s", err.msg);
    cr_assert_eq(la, lb);
    cr_assert_eq(memcmp(a, b, la), 0);
    /* Garbage after a node name's NUL would not survive re-encoding: refused. */
    size_t name1 = 48 + 5 * 48 + 3 * 20 + 100 + 10;
    a[name1] = 'x';
    uint64_t h = fnv(a, la - 8);
    for (int i = 0; i < 8; i++) a[la - 8 + (size_t)i] = (unsigned char)(h >> (8 * i));
    rmesh_free(&r);
    cr_assert_eq(rmesh_decode(a, la, "mem", 0, &r, &err), CT_EPARSE);
    cr_assert(strstr(err.msg, "NUL-padded") != NULL, "%s", err.msg);
    free(a);
    free(b);
    rmesh_free(&m);
    /* The fuzz target's property on its corpus (make fuzz runs it with libFuzzer). */
    FILE *ls = popen("ls tests/fuzz/corpus/ctmesh 2>/dev/null", "r");
    cr_assert_not_null(ls);
    char name[256];
    int files = 0;
    while (fgets(name, sizeof name, ls)) {
        name[strcspn(name, "\n")] = '\0';
        char path[512];
        snprintf(path, sizeof path, "tests/fuzz/corpus/ctmesh/%s", name);
        size_t len;
        unsigned char *d = read_file(path, &len);
        if (rmesh_decode(d, len, path, 0, &r, &err) == 0) {
            cr_assert_eq(rmesh_encode(&r, &b, &lb, &err), 0);
            cr_assert(lb == len && memcmp(b, d, len) == 0, "%s does not re-encode to itself", path);
            free(b);
            rmesh_free(&r);
        }
        free(d);
        files++;
    }
    pclose(ls);
    cr_assert_geq(files, 1, "tests/fuzz/corpus/ctmesh is empty (run from the repository root)");
}

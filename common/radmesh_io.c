/* radmesh_io.c: the .ctmesh cache file (docs/radiosity.md, "Cache file"):
 * a fixed header (magic, version, endianness check, scene hash, counts),
 * vertex, triangle and node records, and an FNV-1a checksum, all explicit
 * little-endian field by field. Loading checks every count against the file
 * size and a cap before allocating. */
#include "common/radmesh.h"

#include <stdio.h>
#include <sys/stat.h>
#include <stdlib.h>
#include <string.h>

#include "common/fsutil.h"

#define RMESH_MAGIC       "CTMESH\r\n\x1a\n"   /* 10 bytes: catches text-mode and truncating transfers */
#define RMESH_MAGIC_LEN   10
#define RMESH_VERSION     2u   /* 2: the material table (see-through glass) */
#define RMESH_ENDIAN      0x01020304u
#define RMESH_HEADER      48
#define RMESH_VERT_BYTES  48
#define RMESH_TRI_BYTES   20
#define RMESH_NODE_BYTES  (SCENE_NAME_LEN + 12 + 24)
#define RMESH_MAT_BYTES   16
#define RMESH_MAX_VERTS   (1u << 28)
#define RMESH_MAX_TRIS    (1u << 28)
#define RMESH_MAX_NODES   (1u << 24)
#define RMESH_MAX_FILE    ((size_t)1 << 34)

static uint64_t fnv(uint64_t h, const unsigned char *p, size_t n)
{
    for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * 1099511628211ULL;
    return h;
}

static unsigned char *wu32(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)v;
    p[1] = (unsigned char)(v >> 8);
    p[2] = (unsigned char)(v >> 16);
    p[3] = (unsigned char)(v >> 24);
    return p + 4;
}

static unsigned char *wu64(unsigned char *p, uint64_t v) { return wu32(wu32(p, (uint32_t)v), (uint32_t)(v >> 32)); }

static unsigned char *wf32(unsigned char *p, float f)
{
    uint32_t v;
    memcpy(&v, &f, 4);
    return wu32(p, v);
}

static unsigned char *wvec(unsigned char *p, vec3 v) { return wf32(wf32(wf32(p, v.x), v.y), v.z); }

int rmesh_encode(const ct_radmesh *m, unsigned char **out, size_t *len, ct_error *err)
{
    *out = NULL;
    *len = 0;
    if (m->nverts > RMESH_MAX_VERTS || m->ntris > RMESH_MAX_TRIS || m->nnodes > RMESH_MAX_NODES ||
        m->nmats > RMESH_MAX_MATS)
        return ct_fail(err, CT_ERANGE, "mesh too large to encode (%u vertices, %u triangles, %u nodes, %u materials)",
                       m->nverts, m->ntris, m->nnodes, m->nmats);
    size_t n = (size_t)RMESH_HEADER + (size_t)m->nverts * RMESH_VERT_BYTES + (size_t)m->ntris * RMESH_TRI_BYTES +
               (size_t)m->nnodes * RMESH_NODE_BYTES + (size_t)m->nmats * RMESH_MAT_BYTES + 8;
    unsigned char *buf = malloc(n), *p = buf;
    if (!buf) return ct_fail(err, CT_ENOMEM, "out of memory for a %zu-byte mesh", n);
    memcpy(p, RMESH_MAGIC, RMESH_MAGIC_LEN);
    p += RMESH_MAGIC_LEN;
    *p++ = 0;
    *p++ = 0;
    p = wu32(p, RMESH_VERSION);
    p = wu32(p, RMESH_ENDIAN);
    p = wu64(p, m->scene_hash);
    p = wu32(p, m->nverts);
    p = wu32(p, m->ntris);
    p = wu32(p, m->nnodes);
    p = wu32(p, m->nmats);
    p = wu32(p, 0);
    for (uint32_t i = 0; i < m->nverts; i++) {
        p = wvec(p, m->pos[i]);
        p = wvec(p, m->nrm[i]);
        p = wvec(p, m->rad[i]);
        p = wvec(p, m->rad_direct[i]);
    }
    for (uint32_t t = 0; t < m->ntris; t++) {
        for (int k = 0; k < 3; k++) p = wu32(p, m->tris[3 * (size_t)t + (size_t)k]);
        p = wu32(p, m->tri_node[t]);
        p = wu32(p, m->tri_mat[t]);
    }
    for (uint32_t i = 0; i < m->nnodes; i++) {
        const rmesh_node *d = &m->nodes[i];
        /* NUL-padded: the bytes after the name are zero, so encoding is a
         * function of the mesh alone. */
        memset(p, 0, SCENE_NAME_LEN);
        memcpy(p, d->name, strnlen(d->name, SCENE_NAME_LEN - 1));
        p += SCENE_NAME_LEN;
        p = wu32(p, (uint32_t)d->parent);
        p = wu32(p, d->node_end);
        p = wu32(p, d->material);
        p = wvec(p, d->bounds.lo);
        p = wvec(p, d->bounds.hi);
    }
    for (uint32_t i = 0; i < m->nmats; i++) {
        p = wvec(p, m->mats[i].transmission);
        p = wf32(p, m->mats[i].ior);
    }
    p = wu64(p, fnv(1469598103934665603ULL, buf, (size_t)(p - buf)));
    *out = buf;
    *len = (size_t)(p - buf);
    return CT_OK;
}

int rmesh_output_check(const char *path, ct_error *err)
{
    int rc = fs_output_check(path, err);
    if (rc) return rc;
    /* A cache path is written over without asking, so a slip (the scene
     * file itself as -o, a --radiosity-cache naming a document) used to
     * replace that file with a mesh. Only a .ctmesh, an empty file or a
     * special file (written in place) may be replaced. */
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISREG(st.st_mode) || st.st_size == 0) return CT_OK;
    FILE *f = fopen(path, "rb");
    if (!f) return CT_OK;   /* fs_output_check found it writable; the write will say more */
    unsigned char head[RMESH_MAGIC_LEN];
    size_t got = fread(head, 1, sizeof head, f);
    fclose(f);
    if (got == sizeof head && memcmp(head, RMESH_MAGIC, RMESH_MAGIC_LEN) == 0) return CT_OK;
    return ct_fail(err, CT_EINVAL,
                   "%s: exists and is not a corrtex mesh (.ctmesh): not replaced (remove it or give another name)",
                   path);
}

int rmesh_save(const ct_radmesh *m, const char *path, ct_error *err)
{
    int rc = rmesh_output_check(path, err);
    if (rc) return rc;
    unsigned char *buf;
    size_t len;
    rc = rmesh_encode(m, &buf, &len, err);
    if (rc) {
        ct_error_prefix(err, path);
        return rc;
    }
    rc = fs_write_atomic(path, buf, len, err);
    free(buf);
    return rc;
}

static uint32_t ru32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t ru64(const unsigned char *p) { return (uint64_t)ru32(p) | (uint64_t)ru32(p + 4) << 32; }

static float rf32(const unsigned char *p)
{
    uint32_t v = ru32(p);
    float f;
    memcpy(&f, &v, 4);
    return f;
}

static vec3 rvec(const unsigned char *p) { return v3(rf32(p), rf32(p + 4), rf32(p + 8)); }

/* The checks the fixed header allows (avail of its bytes are in d): magic,
 * version, byte order, counts, and the size they imply against the file's
 * size, so that a file that is no mesh cache fails before it is read in
 * full. */
static int check_header(const unsigned char *d, size_t avail, uint64_t file_len, const char *path, ct_error *err)
{
    if (avail < RMESH_MAGIC_LEN || memcmp(d, RMESH_MAGIC, RMESH_MAGIC_LEN) != 0) {
        return ct_fail(err, CT_EPARSE, "%s: not a corrtex mesh cache (bad magic)", path);
    }
    if (avail < RMESH_HEADER) {
        return ct_fail(err, CT_EPARSE, "%s: truncated header (%zu bytes, need %d)", path, avail, RMESH_HEADER);
    }
    /* The two bytes after the magic are padding the encoder zeroes; a
     * decoder that ignored them would accept files it cannot write back. */
    if (d[RMESH_MAGIC_LEN] != 0 || d[RMESH_MAGIC_LEN + 1] != 0) {
        return ct_fail(err, CT_EPARSE, "%s: header padding after the magic is not zero", path);
    }
    uint32_t version = ru32(d + 12), endian = ru32(d + 16);
    if (version != RMESH_VERSION) {
        return ct_fail(err, CT_EPARSE, "%s: mesh cache version %u not supported (this build reads %u)",
                       path, version, RMESH_VERSION);
    }
    if (endian != RMESH_ENDIAN) {
        return ct_fail(err, CT_EPARSE, "%s: endianness check 0x%08x, expected 0x%08x (written byte-swapped?)",
                       path, endian, RMESH_ENDIAN);
    }
    uint32_t nv = ru32(d + 28), nt = ru32(d + 32), nn = ru32(d + 36), nm = ru32(d + 40);
    if (ru32(d + 44) != 0) {
        return ct_fail(err, CT_EPARSE, "%s: reserved header field is not zero", path);
    }
    if (nv > RMESH_MAX_VERTS || nt > RMESH_MAX_TRIS || nn > RMESH_MAX_NODES || nm > RMESH_MAX_MATS) {
        return ct_fail(err, CT_EPARSE, "%s: counts out of range (%u vertices, %u triangles, %u nodes, %u materials)",
                       path, nv, nt, nn, nm);
    }
    uint64_t need = (uint64_t)RMESH_HEADER + (uint64_t)nv * RMESH_VERT_BYTES +
                    (uint64_t)nt * RMESH_TRI_BYTES + (uint64_t)nn * RMESH_NODE_BYTES +
                    (uint64_t)nm * RMESH_MAT_BYTES + 8;
    if (file_len != need) {
        return ct_fail(err, CT_EPARSE, "%s: %s (%llu bytes, header says %llu)", path,
                       file_len < need ? "truncated" : "trailing bytes", (unsigned long long)file_len,
                       (unsigned long long)need);
    }
    return CT_OK;
}

int rmesh_decode(const unsigned char *d, size_t len, const char *path, uint64_t expect_hash, ct_radmesh *m,
                 ct_error *err)
{
    memset(m, 0, sizeof *m);
    int rc = check_header(d, len, len, path, err);
    if (rc) return rc;
    uint64_t hash = ru64(d + 20);
    uint32_t nv = ru32(d + 28), nt = ru32(d + 32), nn = ru32(d + 36), nm = ru32(d + 40);
    if (fnv(1469598103934665603ULL, d, len - 8) != ru64(d + len - 8)) {
        return ct_fail(err, CT_EPARSE, "%s: checksum mismatch (corrupted cache)", path);
    }
    if (expect_hash && hash != expect_hash) {
        return ct_fail(err, CT_ESTALE, "%s: stale cache (solution hash %016llx, expected %016llx: another scene, other solver parameters or another solver version)", path,
                       (unsigned long long)hash, (unsigned long long)expect_hash);
    }
    rc = rmesh_alloc(m, nv, nt, nn, err);
    if (rc) {
        return rc;
    }
    m->scene_hash = hash;
    const unsigned char *p = d + RMESH_HEADER;
    for (uint32_t i = 0; i < nv; i++, p += RMESH_VERT_BYTES) {
        m->pos[i] = rvec(p);
        m->nrm[i] = rvec(p + 12);
        m->rad[i] = rvec(p + 24);
        m->rad_direct[i] = rvec(p + 36);
        if (!v3_in_range(m->pos[i]) || !v3_finite(m->rad[i]) || !v3_finite(m->rad_direct[i])) {
            rc = ct_fail(err, CT_EPARSE, "%s: vertex %u is not finite or outside the coordinate range +-%g", path, i,
                         (double)CT_COORD_MAX);
            goto fail;
        }
    }
    for (uint32_t t = 0; t < nt; t++, p += RMESH_TRI_BYTES) {
        for (int k = 0; k < 3; k++) {
            uint32_t v = ru32(p + 4 * k);
            if (v >= nv) {
                rc = ct_fail(err, CT_EPARSE, "%s: triangle %u: vertex %u out of range (%u vertices)", path, t, v, nv);
                goto fail;
            }
            m->tris[3 * (size_t)t + (size_t)k] = v;
        }
        m->tri_node[t] = ru32(p + 12);
        m->tri_mat[t] = ru32(p + 16);
        if (m->tri_node[t] >= nn) {
            rc = ct_fail(err, CT_EPARSE, "%s: triangle %u: node %u out of range (%u nodes)", path, t,
                         m->tri_node[t], nn);
            goto fail;
        }
    }
    for (uint32_t n = 0; n < nn; n++, p += RMESH_NODE_BYTES) {
        rmesh_node *q = &m->nodes[n];
        memcpy(q->name, p, SCENE_NAME_LEN);
        const char *nul = memchr(q->name, '\0', SCENE_NAME_LEN);
        int padded = nul != NULL;
        for (const char *z = nul; padded && z < q->name + SCENE_NAME_LEN; z++) padded = *z == '\0';
        if (!padded) {
            rc = ct_fail(err, CT_EPARSE, "%s: node %u: name not NUL-terminated and NUL-padded", path, n);
            goto fail;
        }
        q->parent = (int32_t)ru32(p + SCENE_NAME_LEN);
        q->node_end = ru32(p + SCENE_NAME_LEN + 4);
        q->material = ru32(p + SCENE_NAME_LEN + 8);
        q->bounds.lo = rvec(p + SCENE_NAME_LEN + 12);
        q->bounds.hi = rvec(p + SCENE_NAME_LEN + 24);
        if (q->parent < -1 || q->parent >= (int32_t)n || q->node_end <= n || q->node_end > nn) {
            rc = ct_fail(err, CT_EPARSE, "%s: node %u: parent %d or end %u out of range", path, n,
                         q->parent, q->node_end);
            goto fail;
        }
    }
    if (!(m->mats = calloc(nm ? nm : 1, sizeof *m->mats))) {
        rc = ct_fail(err, CT_ENOMEM, "%s: out of memory for %u materials", path, nm);
        goto fail;
    }
    m->nmats = nm;
    for (uint32_t i = 0; i < nm; i++, p += RMESH_MAT_BYTES) {
        rmesh_material *x = &m->mats[i];
        x->transmission = rvec(p);
        x->ior = rf32(p + 12);
        if (!rmesh_material_ok(x)) {
            rc = ct_fail(err, CT_EPARSE, "%s: material %u: transmission or index of refraction out of range", path, i);
            goto fail;
        }
    }
    return CT_OK;
fail:
    rmesh_free(m);
    return rc;
}

int rmesh_load(const char *path, uint64_t expect_hash, ct_radmesh *m, ct_error *err)
{
    memset(m, 0, sizeof *m);
    FILE *f;
    size_t len;
    int rc = fs_open_regular(path, &f, &len, err);
    if (rc) return rc;
    unsigned char hdr[RMESH_HEADER];
    size_t got = fread(hdr, 1, sizeof hdr, f);
    unsigned char *data = NULL;
    if (len > RMESH_MAX_FILE)
        rc = ct_fail(err, CT_ERANGE, "%s: file too large (%zu bytes, limit %zu)", path, len, RMESH_MAX_FILE);
    else rc = check_header(hdr, got, len, path, err);
    if (rc == CT_OK) {
        if (!(data = malloc(len))) {
            rc = ct_fail(err, CT_ENOMEM, "%s: out of memory for %zu bytes", path, len);
        } else {
            memcpy(data, hdr, got);
            if (fread(data + got, 1, len - got, f) != len - got)
                rc = ct_fail(err, CT_EIO, "%s: read failed", path);
        }
    }
    fclose(f);
    if (rc == CT_OK) rc = rmesh_decode(data, len, path, expect_hash, m, err);
    free(data);
    return rc;
}

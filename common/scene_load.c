/* Scene import: the JSON scene file (cJSON) and the mesh files it names
 * (assimp). The format is specified in docs/scene-format.md. Over 600 lines
 * on purpose: one parser of one file format, every key checked where it is
 * read, with the error naming the file and the key. */
#include "common/fsutil.h"
#include "common/hash.h"
#include "common/log.h"
#include "common/mesh_precheck.h"
#include "common/scene.h"

#include <assimp/cfileio.h>
#include <assimp/cimport.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define SCENE_JSON_MAX  (64u << 20)
#define MESH_FILE_MAX   (1ull << 30)

typedef struct loader {
    ct_scene *s;
    const char *path;       /* the scene file, for messages */
    char dir[4096];         /* its folder: relative paths start here */
    uint64_t hash;
    ct_error *err;
    /* Files a mesh file names (an OBJ's mtllib) that assimp asked for while
     * importing the current mesh entry: assimp goes on without one it cannot
     * open, so the loader keeps the first failure to report it. */
    const char *mesh_file;  /* the mesh file itself (assimp opens it too) */
    ct_error unread;        /* the first companion that could not be read, "" if none */
    char unread_base[256];  /* its file name, '\\' read as '/' */
    int companions_read;    /* companions that could */
    struct import_slot *imports;    /* one per mesh file the entries name */
    int nimports;
} loader;

/* One import per mesh file. A scene that places one model many times names
 * its file once per entry, and assimp's OBJ importer alone clears 8 MB of
 * line buffers per import: 3,000 entries of a 12-triangle file took 10 s.
 * An import is kept while later entries still name the file, so memory
 * stays that of one import at a time when every file is named once. */
typedef struct import_slot {
    char *path;                     /* as joined to the scene's folder */
    const struct aiScene *ai;       /* NULL until imported, and after the last use */
    uint64_t digest;                /* the scene hash after the first import: stands in for the bytes read */
    int uses_left;                  /* entries still to come that name it */
    ct_error unread;                /* the first import's companions, for resolve_material */
    int companions_read;
} import_slot;

/* --- JSON helpers ---------------------------------------------------------- */

static int bad(loader *L, const char *ctx, const char *what)
{
    return ct_fail(L->err, CT_EPARSE, "%s: %s: %s", L->path, ctx, what);
}

/* Fails on any key of obj not in allowed (NULL-terminated). */
static int check_keys(loader *L, const cJSON *obj, const char *ctx, const char *const *allowed)
{
    for (const cJSON *it = obj->child; it; it = it->next) {
        int ok = 0;
        for (const char *const *a = allowed; *a; a++)
            if (it->string && strcmp(it->string, *a) == 0) { ok = 1; break; }
        if (!ok)
            return ct_fail(L->err, CT_EPARSE, "%s: %s: unknown key '%s'", L->path, ctx,
                           it->string ? it->string : "?");
    }
    return CT_OK;
}

static int get_num(loader *L, const cJSON *obj, const char *key, const char *ctx, int required,
                   float def, float *out)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!v) {
        if (required) return ct_fail(L->err, CT_EPARSE, "%s: %s: missing '%s'", L->path, ctx, key);
        *out = def;
        return CT_OK;
    }
    if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble))
        return ct_fail(L->err, CT_EPARSE, "%s: %s: '%s' must be a finite number", L->path, ctx, key);
    *out = (float)v->valuedouble;
    if (!isfinite(*out))
        return ct_fail(L->err, CT_EPARSE, "%s: %s: '%s' out of range", L->path, ctx, key);
    return CT_OK;
}

static int get_floats(loader *L, const cJSON *v, const char *key, const char *ctx, float *out, int n)
{
    if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != n)
        return ct_fail(L->err, CT_EPARSE, "%s: %s: '%s' must be an array of %d numbers", L->path,
                       ctx, key, n);
    int i = 0;
    for (const cJSON *e = v->child; e; e = e->next, i++) {
        if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble) || !isfinite((float)e->valuedouble))
            return ct_fail(L->err, CT_EPARSE, "%s: %s: '%s' element %d is not a finite number",
                           L->path, ctx, key, i);
        out[i] = (float)e->valuedouble;
    }
    return CT_OK;
}

static int get_vec3(loader *L, const cJSON *obj, const char *key, const char *ctx, int required,
                    vec3 def, vec3 *out)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!v) {
        if (required) return ct_fail(L->err, CT_EPARSE, "%s: %s: missing '%s'", L->path, ctx, key);
        *out = def;
        return CT_OK;
    }
    float f[3];
    int rc = get_floats(L, v, key, ctx, f, 3);
    if (rc) return rc;
    *out = v3(f[0], f[1], f[2]);
    return CT_OK;
}

static int get_str(loader *L, const cJSON *obj, const char *key, const char *ctx, int required,
                   const char **out)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    *out = NULL;
    if (!v) {
        if (required) return ct_fail(L->err, CT_EPARSE, "%s: %s: missing '%s'", L->path, ctx, key);
        return CT_OK;
    }
    if (!cJSON_IsString(v) || !v->valuestring[0])
        return ct_fail(L->err, CT_EPARSE, "%s: %s: '%s' must be a non-empty string", L->path, ctx, key);
    if (strlen(v->valuestring) >= SCENE_NAME_LEN && strcmp(key, "file") != 0)
        return ct_fail(L->err, CT_EPARSE, "%s: %s: '%s' longer than %d characters", L->path, ctx,
                       key, SCENE_NAME_LEN - 1);
    *out = v->valuestring;
    return CT_OK;
}

static int check_albedo(loader *L, vec3 c, const char *ctx, const char *key)
{
    if (c.x < 0 || c.y < 0 || c.z < 0)
        return ct_fail(L->err, CT_EPARSE, "%s: %s: '%s' must not be negative", L->path, ctx, key);
    if (c.x > 1 || c.y > 1 || c.z > 1)
        return ct_fail(L->err, CT_EPARSE, "%s: %s: '%s' above 1 would create energy", L->path, ctx, key);
    return CT_OK;
}

/* Emission above this is refused: with coordinates up to CT_COORD_MAX an
 * emitter's power then stays finite in float (1e38 per channel passed the
 * JSON checks, and the radiosity solve wrote an infinite mesh and image). */
#define EMISSION_MAX 1e9f

static bool emission_ok(vec3 e)
{
    return e.x >= 0 && e.y >= 0 && e.z >= 0 && e.x <= EMISSION_MAX && e.y <= EMISSION_MAX && e.z <= EMISSION_MAX;
}

/* --- materials ------------------------------------------------------------- */

static int parse_material(loader *L, const cJSON *j, const char *name, scene_material *m)
{
    char ctx[128];
    snprintf(ctx, sizeof ctx, "material '%s'", name);
    if (!cJSON_IsObject(j)) return bad(L, ctx, "must be an object");
    static const char *const keys[] = {"diffuse", "phong", "ward", "mirror", "dielectric", "emission", NULL};
    int rc = check_keys(L, j, ctx, keys);
    if (rc) return rc;
    *m = scene_material_default(name);
    if ((rc = get_vec3(L, j, "diffuse", ctx, 0, v3s(0), &m->diffuse))) return rc;
    if ((rc = check_albedo(L, m->diffuse, ctx, "diffuse"))) return rc;
    if ((rc = get_vec3(L, j, "mirror", ctx, 0, v3s(0), &m->mirror))) return rc;
    if ((rc = check_albedo(L, m->mirror, ctx, "mirror"))) return rc;
    if ((rc = get_vec3(L, j, "emission", ctx, 0, v3s(0), &m->emission))) return rc;
    if (m->emission.x < 0 || m->emission.y < 0 || m->emission.z < 0)
        return bad(L, ctx, "'emission' must not be negative");
    if (!emission_ok(m->emission)) return bad(L, ctx, "'emission' above 1e9");

    const cJSON *phong = cJSON_GetObjectItemCaseSensitive(j, "phong");
    const cJSON *ward = cJSON_GetObjectItemCaseSensitive(j, "ward");
    if (phong && ward) return bad(L, ctx, "has both 'phong' and 'ward' (one glossy lobe only)");
    if (phong) {
        char c2[160];
        snprintf(c2, sizeof c2, "%s.phong", ctx);
        static const char *const pk[] = {"rho_s", "exponent", NULL};
        if (!cJSON_IsObject(phong)) return bad(L, c2, "must be an object");
        if ((rc = check_keys(L, phong, c2, pk))) return rc;
        m->glossy = SCENE_GLOSSY_PHONG;
        if ((rc = get_vec3(L, phong, "rho_s", c2, 1, v3s(0), &m->specular))) return rc;
        if ((rc = check_albedo(L, m->specular, c2, "rho_s"))) return rc;
        if ((rc = get_num(L, phong, "exponent", c2, 1, 0, &m->phong_exp))) return rc;
        if (!(m->phong_exp >= 0.0f)) return bad(L, c2, "'exponent' must be >= 0");
    }
    if (ward) {
        char c2[160];
        snprintf(c2, sizeof c2, "%s.ward", ctx);
        static const char *const wk[] = {"rho_s", "alpha_x", "alpha_y", "tangent", NULL};
        if (!cJSON_IsObject(ward)) return bad(L, c2, "must be an object");
        if ((rc = check_keys(L, ward, c2, wk))) return rc;
        m->glossy = SCENE_GLOSSY_WARD;
        if ((rc = get_vec3(L, ward, "rho_s", c2, 1, v3s(0), &m->specular))) return rc;
        if ((rc = check_albedo(L, m->specular, c2, "rho_s"))) return rc;
        if ((rc = get_num(L, ward, "alpha_x", c2, 1, 0, &m->ward_ax))) return rc;
        if ((rc = get_num(L, ward, "alpha_y", c2, 1, 0, &m->ward_ay))) return rc;
        if (!(m->ward_ax > 0.0f) || !(m->ward_ay > 0.0f)) return bad(L, c2, "'alpha_x' and 'alpha_y' must be > 0");
        if ((rc = get_vec3(L, ward, "tangent", c2, 0, v3(1, 0, 0), &m->ward_tangent))) return rc;
        if (v3_len2(m->ward_tangent) <= 0.0f) return bad(L, c2, "'tangent' must not be zero");
        m->ward_tangent = v3_norm(m->ward_tangent);
    }
    const cJSON *die = cJSON_GetObjectItemCaseSensitive(j, "dielectric");
    if (die) {
        char c2[160];
        snprintf(c2, sizeof c2, "%s.dielectric", ctx);
        static const char *const dk[] = {"ior", "transmission", NULL};
        if (!cJSON_IsObject(die)) return bad(L, c2, "must be an object");
        if ((rc = check_keys(L, die, c2, dk))) return rc;
        m->dielectric = 1;
        if ((rc = get_num(L, die, "ior", c2, 1, 1.5f, &m->ior))) return rc;
        if (!(m->ior >= 1.0f && m->ior <= 4.0f)) return bad(L, c2, "'ior' must be in [1, 4]");
        if ((rc = get_vec3(L, die, "transmission", c2, 0, v3s(1), &m->transmission))) return rc;
        if ((rc = check_albedo(L, m->transmission, c2, "transmission"))) return rc;
    }
    vec3 sum = v3_add(v3_add(m->diffuse, m->specular), m->mirror);
    if (v3_maxc(sum) > 1.0f)
        ct_warn("scene", "%s: %s: diffuse + glossy + mirror reflectance %.3g exceeds 1 (not energy conserving)",
                L->path, ctx, (double)v3_maxc(sum));
    return CT_OK;
}

/* MTL (and other assimp formats) to corrtex materials; docs/scene-format.md.
 * A value that is not a finite number (Kd nan, Ke 1e39 past float's range)
 * or an emission past EMISSION_MAX is an error naming file and material. */
static int convert_ai_material(const struct aiMaterial *am, const char *name, const char *file, scene_material *out,
                               ct_error *err)
{
    scene_material m = scene_material_default(name);
    struct aiColor4D c;
    vec3 kd = v3s(0), ks = v3s(0), ke = v3s(0), tf = v3s(1);
    if (aiGetMaterialColor(am, AI_MATKEY_COLOR_DIFFUSE, &c) == aiReturn_SUCCESS) kd = v3(c.r, c.g, c.b);
    if (aiGetMaterialColor(am, AI_MATKEY_COLOR_SPECULAR, &c) == aiReturn_SUCCESS) ks = v3(c.r, c.g, c.b);
    if (aiGetMaterialColor(am, AI_MATKEY_COLOR_EMISSIVE, &c) == aiReturn_SUCCESS) ke = v3(c.r, c.g, c.b);
    if (aiGetMaterialColor(am, AI_MATKEY_COLOR_TRANSPARENT, &c) == aiReturn_SUCCESS) tf = v3(c.r, c.g, c.b);
    ai_real ns = 0, ni = 1, d = 1;
    unsigned int one = 1;
    aiGetMaterialFloatArray(am, AI_MATKEY_SHININESS, &ns, &one);
    one = 1;
    aiGetMaterialFloatArray(am, AI_MATKEY_REFRACTI, &ni, &one);
    one = 1;
    aiGetMaterialFloatArray(am, AI_MATKEY_OPACITY, &d, &one);
    if (!v3_finite(kd) || !v3_finite(ks) || !v3_finite(ke) || !v3_finite(tf) || !isfinite(ns) || !isfinite(ni) ||
        !isfinite(d))
        return ct_fail(err, CT_EPARSE, "%s: material '%s' has a value that is not a finite number", file, name);
    if (!emission_ok(v3_max(ke, v3s(0))))
        return ct_fail(err, CT_EPARSE, "%s: material '%s': emission above %g", file, name, (double)EMISSION_MAX);
    int illum = -1;
    one = 1;
    aiGetMaterialIntegerArray(am, "$mat.illum", 0, 0, &illum, &one);

    /* Clamp imported reflectances into [0,1]: exporters write Ks = 1 with
     * Kd > 0 freely; we never create energy. */
    kd = v3_min(v3_max(kd, v3s(0)), v3s(1));
    ks = v3_min(v3_max(ks, v3s(0)), v3s(1));
    tf = v3_min(v3_max(tf, v3s(0)), v3s(1));
    m.emission = v3_max(ke, v3s(0));
    if (illum == 4 || illum == 6 || illum == 7 || d < 1.0f) {
        m.dielectric = 1;
        m.ior = ni > 1.0f ? (float)ni : 1.5f;
        m.transmission = tf;
    } else if (illum == 3 || illum == 5) {
        m.diffuse = kd;
        m.mirror = v3_maxc(ks) > 0.0f ? ks : v3s(1);
    } else {
        m.diffuse = kd;
        if (illum != 0 && illum != 1 && v3_maxc(ks) > 0.0f) {
            m.glossy = SCENE_GLOSSY_PHONG;
            m.specular = ks;
            m.phong_exp = ns > 0 ? (float)ns : 1.0f;
        }
    }
    /* Keep diffuse + specular <= 1 per channel by scaling the diffuse part. */
    vec3 sum = v3_add(v3_add(m.diffuse, m.specular), m.mirror);
    float mx = v3_maxc(sum);
    if (mx > 1.0f) {
        float room = fmaxf(0.0f, 1.0f - v3_maxc(v3_add(m.specular, m.mirror)));
        float dm = v3_maxc(m.diffuse);
        if (dm > 0.0f) m.diffuse = v3_scale(m.diffuse, room / dm);
    }
    *out = m;
    return CT_OK;
}

/* --- assimp file I/O hook: every file assimp reads goes into the hash ------ */

typedef struct mem_file {
    char *data;
    size_t len, pos;
} mem_file;

static size_t mf_read(struct aiFile *f, char *buf, size_t size, size_t count)
{
    mem_file *m = (mem_file *)f->UserData;
    if (size == 0) return 0;
    size_t avail = (m->len - m->pos) / size;
    size_t n = count < avail ? count : avail;
    memcpy(buf, m->data + m->pos, n * size);
    m->pos += n * size;
    return n;
}

static size_t mf_write(struct aiFile *f, const char *buf, size_t size, size_t count)
{
    (void)f; (void)buf; (void)size; (void)count;
    return 0;
}

static size_t mf_tell(struct aiFile *f) { return ((mem_file *)f->UserData)->pos; }
static size_t mf_size(struct aiFile *f) { return ((mem_file *)f->UserData)->len; }
static void mf_flush(struct aiFile *f) { (void)f; }

static enum aiReturn mf_seek(struct aiFile *f, size_t off, enum aiOrigin origin)
{
    mem_file *m = (mem_file *)f->UserData;
    size_t base = origin == aiOrigin_SET ? 0 : origin == aiOrigin_CUR ? m->pos : m->len;
    if (base + off > m->len) return aiReturn_FAILURE;
    m->pos = base + off;
    return aiReturn_SUCCESS;
}

/* The file name of path, a Windows path's too (an OBJ exported there names
 * `mtllib C:\\proj\\m.mtl`). */
static void file_name_of(const char *path, char *out, size_t cap)
{
    const char *b = path;
    for (const char *p = path; *p; p++)
        if (*p == '/' || *p == '\\') b = p + 1;
    snprintf(out, cap, "%s", b);
}

static struct aiFile *mf_open(struct aiFileIO *io, const char *path, const char *mode)
{
    if (!mode || mode[0] != 'r') return NULL;
    loader *L = (loader *)io->UserData;
    char *data;
    size_t len;
    ct_error e;
    bool companion = !L->mesh_file || strcmp(path, L->mesh_file) != 0;
    if (fs_read_all(path, MESH_FILE_MAX, &data, &len, &e) != CT_OK) {
        if (companion && !L->unread.msg[0]) {
            L->unread = e;
            file_name_of(path, L->unread_base, sizeof L->unread_base);
        }
        return NULL;
    }
    if (companion) {
        L->companions_read++;
        /* assimp tries a library as named, then in the mesh's folder: found
         * there, the first try was no missing file. */
        char base[256];
        file_name_of(path, base, sizeof base);
        if (L->unread.msg[0] && strcmp(base, L->unread_base) == 0) ct_error_clear(&L->unread);
    }
    L->hash = ct_hash_bytes(L->hash, data, len);
    struct aiFile *f = calloc(1, sizeof *f);
    mem_file *m = calloc(1, sizeof *m);
    if (!f || !m) { free(f); free(m); free(data); return NULL; }
    m->data = data;
    m->len = len;
    f->ReadProc = mf_read;
    f->WriteProc = mf_write;
    f->TellProc = mf_tell;
    f->FileSizeProc = mf_size;
    f->SeekProc = mf_seek;
    f->FlushProc = mf_flush;
    f->UserData = (aiUserData)m;
    return f;
}

static void mf_close(struct aiFileIO *io, struct aiFile *f)
{
    (void)io;
    if (!f) return;
    mem_file *m = (mem_file *)f->UserData;
    free(m->data);
    free(m);
    free(f);
}

/* --- geometry -------------------------------------------------------------- */

typedef struct mesh_ctx {
    loader *L;
    const char *file;           /* mesh file path, for messages */
    const struct aiScene *ai;
    int *matmap;                /* assimp material -> scene material, -1 = not yet */
} mesh_ctx;

static mat4 ai_to_m4(const struct aiMatrix4x4 *a)
{
    mat4 m;
    m.m[0][0] = a->a1; m.m[0][1] = a->a2; m.m[0][2] = a->a3; m.m[0][3] = a->a4;
    m.m[1][0] = a->b1; m.m[1][1] = a->b2; m.m[1][2] = a->b3; m.m[1][3] = a->b4;
    m.m[2][0] = a->c1; m.m[2][1] = a->c2; m.m[2][2] = a->c3; m.m[2][3] = a->c4;
    m.m[3][0] = a->d1; m.m[3][1] = a->d2; m.m[3][2] = a->d3; m.m[3][3] = a->d4;
    return m;
}

static float det3(const mat4 *m)
{
    return m->m[0][0] * (m->m[1][1] * m->m[2][2] - m->m[1][2] * m->m[2][1]) -
           m->m[0][1] * (m->m[1][0] * m->m[2][2] - m->m[1][2] * m->m[2][0]) +
           m->m[0][2] * (m->m[1][0] * m->m[2][1] - m->m[1][1] * m->m[2][0]);
}

static int import_mesh(mesh_ctx *C, const struct aiMesh *am, const mat4 *xf)
{
    loader *L = C->L;
    ct_scene *s = L->s;
    mat4 inv;
    if (!m4_invert(*xf, &inv))
        return ct_fail(L->err, CT_EPARSE, "%s: singular transform", C->file);
    int flip = det3(xf) < 0.0f;
    int has_n = am->mNormals != NULL;
    uint32_t base = s->nverts;
    const char *mname = am->mName.length ? am->mName.data : "mesh";

    for (unsigned i = 0; i < am->mNumVertices; i++) {
        vec3 p = v3(am->mVertices[i].x, am->mVertices[i].y, am->mVertices[i].z);
        if (!v3_finite(p))
            return ct_fail(L->err, CT_EPARSE, "%s: mesh '%s': vertex %u has a non-finite coordinate",
                           C->file, mname, i + 1);
        vec3 wp = m4_point(xf, p);
        if (!v3_in_range(wp))
            return ct_fail(L->err, CT_ERANGE,
                           "%s: mesh '%s': vertex %u at (%g, %g, %g) in the scene is outside the coordinate range +-%g",
                           C->file, mname, i + 1, (double)wp.x, (double)wp.y, (double)wp.z, (double)CT_COORD_MAX);
        if (!has_n) continue;
        vec3 n = v3(am->mNormals[i].x, am->mNormals[i].y, am->mNormals[i].z);
        vec3 wn = v3_finite(n) && v3_len2(n) > 0.0f ? m4_normal(&inv, n) : v3s(0);
        int64_t r = scene_add_vertex(s, wp, wn, L->err);
        if (r < 0) return (int)r;
    }

    uint32_t stackidx[64];
    for (unsigned f = 0; f < am->mNumFaces; f++) {
        const struct aiFace *face = &am->mFaces[f];
        unsigned n = face->mNumIndices;
        if (n < 3) continue;   /* points and lines carry no surface */
        uint32_t *idx = n <= 64 ? stackidx : malloc(n * sizeof *idx);
        uint32_t verts_before = s->nverts, tris_before = s->ntris;
        if (!idx) return ct_fail(L->err, CT_ENOMEM, "%s: out of memory", C->file);
        int rc = CT_OK;
        for (unsigned k = 0; k < n && rc == CT_OK; k++) {
            unsigned src = face->mIndices[flip ? n - 1 - k : k];
            if (src >= am->mNumVertices) {
                rc = ct_fail(L->err, CT_ERANGE, "%s: mesh '%s' face %u: vertex index %u out of range (%u vertices)",
                             C->file, mname, f + 1, src + 1, am->mNumVertices);
                break;
            }
            if (has_n) {
                idx[k] = base + src;
            } else {
                vec3 p = m4_point(xf, v3(am->mVertices[src].x, am->mVertices[src].y, am->mVertices[src].z));
                int64_t r = scene_add_vertex(s, p, v3s(0), L->err);
                if (r < 0) rc = (int)r;
                else idx[k] = (uint32_t)r;
            }
        }
        if (rc == CT_OK) {
            vec3 fn = scene_polygon_normal(s, idx, (int)n);
            /* Flat shading for files without normals; repair for broken ones. */
            for (unsigned k = 0; k < n; k++)
                if (v3_len2(s->nrm[idx[k]]) == 0.0f) s->nrm[idx[k]] = fn;
            rc = scene_add_polygon(s, idx, (int)n, L->err);
            if (rc) ct_error_prefix(L->err, C->file);
            /* A dropped (degenerate) polygon leaves no orphan vertex behind. */
            if (rc == CT_OK && !has_n && s->ntris == tris_before) s->nverts = verts_before;
        }
        if (idx != stackidx) free(idx);
        if (rc) return rc;
    }
    return CT_OK;
}

/* Scene material for an assimp material, added on first use so unused
 * materials of a file (assimp's DefaultMaterial, say) do not appear. A name
 * the JSON (or an earlier file) defined wins: that is the override rule. */
static int resolve_material(mesh_ctx *C, unsigned ai_index)
{
    const struct aiMaterial *am = C->ai->mMaterials[ai_index];
    struct aiString an;
    char mname[SCENE_NAME_LEN];
    if (aiGetMaterialString(am, AI_MATKEY_NAME, &an) == aiReturn_SUCCESS && an.length)
        snprintf(mname, sizeof mname, "%s", an.data);
    else
        snprintf(mname, sizeof mname, "material%u", ai_index);
    int idx = scene_find_material(C->L->s, mname);
    /* A material the file's library would define, when no library could be
     * read: assimp made it up (grey diffuse), and the scene would be lit
     * with it without a word. Assimp's own DefaultMaterial (faces before any
     * usemtl) comes from no library. */
    if (idx < 0 && C->L->unread.msg[0] && C->L->companions_read == 0 && strcmp(mname, AI_DEFAULT_MATERIAL_NAME) != 0)
        return ct_fail(C->L->err, CT_EIO, "%s: material '%s': its library cannot be read (%s)", C->file, mname,
                       C->L->unread.msg);
    if (idx < 0) {
        scene_material m;
        int rc = convert_ai_material(am, mname, C->file, &m, C->L->err);
        if (rc) return rc;
        idx = scene_add_material(C->L->s, &m, C->L->err);
    }
    if (idx >= 0) C->matmap[ai_index] = idx;
    return idx;
}

static unsigned subtree_meshes(const struct aiNode *n)
{
    unsigned c = n->mNumMeshes;
    for (unsigned i = 0; i < n->mNumChildren; i++) c += subtree_meshes(n->mChildren[i]);
    return c;
}

static int import_node(mesh_ctx *C, const struct aiNode *an, mat4 parent_xf, int is_root)
{
    loader *L = C->L;
    ct_scene *s = L->s;
    mat4 xf = m4_mul(parent_xf, ai_to_m4(&an->mTransformation));
    int rc;
    if (!is_root) {
        if (subtree_meshes(an) == 0) return CT_OK;
        const char *nm = an->mName.length ? an->mName.data : "group";
        if ((rc = scene_begin_node(s, nm, SCENE_NODE_GROUP, UINT32_MAX, L->err)) < 0) return rc;
    }
    for (unsigned i = 0; i < an->mNumMeshes; i++) {
        if (an->mMeshes[i] >= C->ai->mNumMeshes)
            return ct_fail(L->err, CT_EPARSE, "%s: node references mesh %u of %u", C->file,
                           an->mMeshes[i], C->ai->mNumMeshes);
        const struct aiMesh *am = C->ai->mMeshes[an->mMeshes[i]];
        if (am->mMaterialIndex >= C->ai->mNumMaterials)
            return ct_fail(L->err, CT_EPARSE, "%s: mesh references material %u of %u", C->file,
                           am->mMaterialIndex, C->ai->mNumMaterials);
        int mat = C->matmap[am->mMaterialIndex];
        if (mat < 0 && (mat = resolve_material(C, am->mMaterialIndex)) < 0) return mat;
        /* Parts are named by their material: assimp names only some meshes. */
        if ((rc = scene_begin_node(s, s->mats[mat].name, SCENE_NODE_PART, (uint32_t)mat, L->err)) < 0)
            return rc;
        if ((rc = import_mesh(C, am, &xf))) return rc;
        if ((rc = scene_end_node(s, L->err))) return rc;
    }
    for (unsigned i = 0; i < an->mNumChildren; i++)
        if ((rc = import_node(C, an->mChildren[i], xf, 0))) return rc;
    if (!is_root && (rc = scene_end_node(s, L->err))) return rc;
    return CT_OK;
}

/* node: the file node's name, for messages. */
static int parse_transform(loader *L, const cJSON *entry, const char *ctx, const char *node, mat4 *out)
{
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(entry, "transform");
    const cJSON *m = cJSON_GetObjectItemCaseSensitive(entry, "matrix");
    *out = m4_identity();
    if (t && m) return bad(L, ctx, "has both 'transform' and 'matrix'");
    int rc;
    if (m) {
        float f[16];
        if ((rc = get_floats(L, m, "matrix", ctx, f, 16))) return rc;
        /* Points are transformed as affine (m4_point): a projective bottom
         * row was dropped without a word. Rounding noise of a computed
         * matrix (an inverse, a product) is not projective: snapped. */
        const float tol = 1e-6f;
        if (fabsf(f[12]) <= tol && fabsf(f[13]) <= tol && fabsf(f[14]) <= tol && fabsf(f[15] - 1.0f) <= tol) {
            f[12] = f[13] = f[14] = 0.0f;
            f[15] = 1.0f;
        }
        if (f[12] != 0.0f || f[13] != 0.0f || f[14] != 0.0f || f[15] != 1.0f)
            return ct_fail(L->err, CT_EPARSE,
                           "%s: %s ('%s'): 'matrix' bottom row is (%g, %g, %g, %g), not (0, 0, 0, 1): projective "
                           "transforms are not supported", L->path, ctx, node, (double)f[12], (double)f[13],
                           (double)f[14], (double)f[15]);
        for (int i = 0; i < 16; i++) out->m[i / 4][i % 4] = f[i];
    } else if (t) {
        char c2[160];
        snprintf(c2, sizeof c2, "%s.transform", ctx);
        if (!cJSON_IsObject(t)) return bad(L, c2, "must be an object");
        static const char *const tk[] = {"scale", "rotate", "translate", NULL};
        if ((rc = check_keys(L, t, c2, tk))) return rc;
        vec3 sc = v3s(1), tr = v3s(0);
        const cJSON *sj = cJSON_GetObjectItemCaseSensitive(t, "scale");
        if (sj && cJSON_IsNumber(sj)) {
            float u;
            if ((rc = get_num(L, t, "scale", c2, 1, 1, &u))) return rc;
            sc = v3s(u);
        } else if ((rc = get_vec3(L, t, "scale", c2, 0, v3s(1), &sc))) {
            return rc;
        }
        if (sc.x == 0.0f || sc.y == 0.0f || sc.z == 0.0f) return bad(L, c2, "'scale' must not be zero");
        if ((rc = get_vec3(L, t, "translate", c2, 0, v3s(0), &tr))) return rc;
        mat4 rot = m4_identity();
        const cJSON *rj = cJSON_GetObjectItemCaseSensitive(t, "rotate");
        if (rj) {
            float r[4];
            if ((rc = get_floats(L, rj, "rotate", c2, r, 4))) return rc;
            if (r[0] == 0.0f && r[1] == 0.0f && r[2] == 0.0f) return bad(L, c2, "'rotate' axis is zero");
            rot = m4_rotate(v3(r[0], r[1], r[2]), r[3] * CT_PI / 180.0f);
        }
        *out = m4_mul(m4_translate(tr), m4_mul(rot, m4_scale(sc)));
    }
    if (!m4_invert(*out, &(mat4){0})) return bad(L, ctx, "transform is singular");
    return CT_OK;
}

static void basename_noext(const char *path, char *out, size_t cap)
{
    const char *b = strrchr(path, '/');
    snprintf(out, cap, "%s", b ? b + 1 : path);
    char *dot = strrchr(out, '.');
    if (dot && dot != out) *dot = '\0';
}

static import_slot *import_slot_of(loader *L, const char *full)
{
    for (int i = 0; i < L->nimports; i++)
        if (strcmp(L->imports[i].path, full) == 0) return &L->imports[i];
    return NULL;
}

/* Counts the entries naming each file before any is imported. A slot that
 * cannot be made (out of memory) only costs the sharing: the file is then
 * imported per entry as before. */
static void plan_imports(loader *L, const cJSON *meshes)
{
    int n = cJSON_GetArraySize(meshes);
    L->imports = calloc(n > 0 ? (size_t)n : 1, sizeof *L->imports);
    if (!L->imports) return;
    for (const cJSON *m = meshes->child; m; m = m->next) {
        const cJSON *f = cJSON_GetObjectItemCaseSensitive(m, "file");
        if (!cJSON_IsString(f) || !f->valuestring[0]) continue;
        char full[4096];
        fs_join(L->dir, f->valuestring, full, sizeof full);
        import_slot *slot = import_slot_of(L, full);
        if (!slot) {
            char *p = strdup(full);
            if (!p) continue;
            slot = &L->imports[L->nimports++];
            slot->path = p;
        }
        slot->uses_left++;
    }
}

static void free_imports(loader *L)
{
    for (int i = 0; i < L->nimports; i++) {
        if (L->imports[i].ai) aiReleaseImport(L->imports[i].ai);
        free(L->imports[i].path);
    }
    free(L->imports);
    L->imports = NULL;
    L->nimports = 0;
}

/* One entry is done with ai: the last one of its file frees it. */
static void release_use(import_slot *slot, const struct aiScene *ai)
{
    if (!slot) {
        aiReleaseImport(ai);
        return;
    }
    if (--slot->uses_left > 0) return;
    aiReleaseImport(slot->ai);
    slot->ai = NULL;
}

/* Imports the file of entry ctx ("meshes[2]"), named `file` in the scene
 * and found at `full`. */
static int import_file(loader *L, const char *ctx, const char *file, const char *full, const struct aiScene **out)
{
    /* Checked here because assimp's own message for a file it cannot open
     * does not say why; a FIFO fails at once instead of blocking. A file
     * that cannot be opened is the scene's error: named as the scene names
     * it, with its entry (there was only the joined path). */
    FILE *probe;
    size_t size;
    int rc = fs_open_regular(full, &probe, &size, L->err);
    if (rc) {
        struct stat st;
        if (stat(full, &st) != 0)
            return ct_fail(L->err, rc, "%s: %s: cannot open '%s': %s", L->path, ctx, file, strerror(errno));
        char where[300];
        snprintf(where, sizeof where, "%s: %s", L->path, ctx);
        ct_error_prefix(L->err, where);
        return rc;
    }
    rc = mesh_precheck(probe, full, size, L->err);
    fclose(probe);
    if (rc) return rc;

    struct aiFileIO io = {mf_open, mf_close, (aiUserData)L};
    L->mesh_file = full;
    ct_error_clear(&L->unread);
    L->companions_read = 0;
    const struct aiScene *ai = aiImportFileEx(full, aiProcess_ValidateDataStructure, &io);
    L->mesh_file = NULL;
    if (!ai) return ct_fail(L->err, CT_EPARSE, "%s: %s", full, aiGetErrorString());
    if (!ai->mRootNode || (ai->mFlags & AI_SCENE_FLAGS_INCOMPLETE)) {
        aiReleaseImport(ai);
        return ct_fail(L->err, CT_EPARSE, "%s: incomplete mesh file (no geometry)", full);
    }
    *out = ai;
    return CT_OK;
}

static int import_mesh_entry(loader *L, const cJSON *entry, int index)
{
    char ctx[64];
    snprintf(ctx, sizeof ctx, "meshes[%d]", index);
    if (!cJSON_IsObject(entry)) return bad(L, ctx, "must be an object");
    static const char *const keys[] = {"file", "name", "transform", "matrix", "material", NULL};
    int rc = check_keys(L, entry, ctx, keys);
    if (rc) return rc;
    const char *file, *name, *matname;
    if ((rc = get_str(L, entry, "file", ctx, 1, &file))) return rc;
    if ((rc = get_str(L, entry, "name", ctx, 0, &name))) return rc;
    if ((rc = get_str(L, entry, "material", ctx, 0, &matname))) return rc;
    char nodename[SCENE_NAME_LEN];
    if (name) snprintf(nodename, sizeof nodename, "%s", name);
    else basename_noext(file, nodename, sizeof nodename);
    mat4 xf;
    if ((rc = parse_transform(L, entry, ctx, nodename, &xf))) return rc;
    int forced = -1;
    if (matname && (forced = scene_find_material(L->s, matname)) < 0)
        return ct_fail(L->err, CT_EPARSE, "%s: %s: unknown material '%s'", L->path, ctx, matname);

    char full[4096];
    fs_join(L->dir, file, full, sizeof full);
    import_slot *slot = import_slot_of(L, full);
    const struct aiScene *ai;
    bool again = slot && slot->ai;
    if (again) {
        ai = slot->ai;
        L->hash = ct_hash_bytes(L->hash, &slot->digest, sizeof slot->digest);
        L->unread = slot->unread;
        L->companions_read = slot->companions_read;
    } else if ((rc = import_file(L, ctx, file, full, &ai))) {
        return rc;
    } else if (slot) {
        slot->ai = ai;
        slot->digest = L->hash;
        slot->unread = L->unread;
        slot->companions_read = L->companions_read;
    }
    int *matmap = calloc(ai->mNumMaterials ? ai->mNumMaterials : 1, sizeof *matmap);
    if (!matmap) { release_use(slot, ai); return ct_fail(L->err, CT_ENOMEM, "%s: out of memory", full); }
    for (unsigned i = 0; i < ai->mNumMaterials; i++) matmap[i] = forced;
    uint32_t dropped_before = L->s->dropped_degenerate, tris_before = L->s->ntris;
    if (rc == CT_OK && (rc = scene_begin_node(L->s, nodename, SCENE_NODE_FILE, UINT32_MAX, L->err)) >= 0) {
        mesh_ctx C = {L, full, ai, matmap};
        rc = import_node(&C, ai->mRootNode, xf, 1);
        if (rc == CT_OK) rc = scene_end_node(L->s, L->err);
    }
    free(matmap);
    release_use(slot, ai);
    if (rc < 0) return rc;
    /* Every material came from the scene (or a fallback library assimp
     * found): the import is right, but the file names one that is gone. */
    if (L->unread.msg[0] && !again) ct_warn("scene", "%s: cannot read a file it names (%s)", full, L->unread.msg);
    uint32_t dropped = L->s->dropped_degenerate - dropped_before;
    if (dropped) ct_warn("scene", "%s: dropped %u degenerate triangle%s", full, dropped, dropped == 1 ? "" : "s");
    /* Likely the wrong file (points or lines only): say so rather than
     * render a scene without it. */
    if (L->s->ntris == tris_before) ct_warn("scene", "%s: no triangles: it adds nothing to the scene", full);
    return CT_OK;
}

/* --- lights, cameras, paths ------------------------------------------------- */

static int import_lights(loader *L, const cJSON *lights)
{
    if (!cJSON_IsArray(lights)) return bad(L, "lights", "must be an array");
    if (cJSON_GetArraySize(lights) == 0) return CT_OK;
    int rc = scene_begin_node(L->s, "lights", SCENE_NODE_FILE, UINT32_MAX, L->err);
    if (rc < 0) return rc;
    int i = 0;
    for (const cJSON *l = lights->child; l; l = l->next, i++) {
        char ctx[64];
        snprintf(ctx, sizeof ctx, "lights[%d]", i);
        if (!cJSON_IsObject(l)) return bad(L, ctx, "must be an object");
        static const char *const keys[] = {"name", "type", "corner", "edge1", "edge2", "emission", "material", NULL};
        if ((rc = check_keys(L, l, ctx, keys))) return rc;
        const char *type, *name, *matname;
        if ((rc = get_str(L, l, "type", ctx, 1, &type))) return rc;
        if (strcmp(type, "quad") != 0)
            return ct_fail(L->err, CT_EPARSE, "%s: %s: unknown light type '%s' (expected 'quad')", L->path, ctx, type);
        if ((rc = get_str(L, l, "name", ctx, 0, &name))) return rc;
        if ((rc = get_str(L, l, "material", ctx, 0, &matname))) return rc;
        vec3 p, e1, e2, em;
        if ((rc = get_vec3(L, l, "corner", ctx, 1, v3s(0), &p))) return rc;
        if ((rc = get_vec3(L, l, "edge1", ctx, 1, v3s(0), &e1))) return rc;
        if ((rc = get_vec3(L, l, "edge2", ctx, 1, v3s(0), &e2))) return rc;
        vec3 corners[4] = {p, v3_add(p, e1), v3_add(v3_add(p, e1), e2), v3_add(p, e2)};
        for (int k = 0; k < 4; k++)
            if (!v3_in_range(corners[k]))
                return ct_fail(L->err, CT_ERANGE, "%s: %s: corner %d at (%g, %g, %g) is outside the coordinate range +-%g",
                               L->path, ctx, k, (double)corners[k].x, (double)corners[k].y, (double)corners[k].z,
                               (double)CT_COORD_MAX);
        vec3 n = v3_cross(e1, e2);
        if (!(v3_len2(n) > 0.0f)) return bad(L, ctx, "edges are parallel or zero (no area)");
        char lname[SCENE_NAME_LEN];
        if (name) snprintf(lname, sizeof lname, "%s", name);
        else snprintf(lname, sizeof lname, "light%d", i);
        int mat;
        if (matname) {
            if (cJSON_GetObjectItemCaseSensitive(l, "emission"))
                return bad(L, ctx, "has both 'material' and 'emission'");
            if ((mat = scene_find_material(L->s, matname)) < 0)
                return ct_fail(L->err, CT_EPARSE, "%s: %s: unknown material '%s'", L->path, ctx, matname);
            if (v3_maxc(L->s->mats[mat].emission) <= 0.0f)
                return ct_fail(L->err, CT_EPARSE, "%s: %s: material '%s' has no emission", L->path, ctx, matname);
        } else {
            if ((rc = get_vec3(L, l, "emission", ctx, 1, v3s(0), &em))) return rc;
            if (em.x < 0 || em.y < 0 || em.z < 0 || v3_maxc(em) <= 0.0f)
                return bad(L, ctx, "'emission' must be non-negative and not all zero");
            if (!emission_ok(em)) return bad(L, ctx, "'emission' above 1e9");
            char mname[SCENE_NAME_LEN];
            snprintf(mname, sizeof mname, "light:%s", lname);
            scene_material m = scene_material_default(mname);
            m.emission = em;
            if ((mat = scene_add_material(L->s, &m, L->err)) < 0) return mat;
        }
        if ((rc = scene_begin_node(L->s, lname, SCENE_NODE_PART, (uint32_t)mat, L->err)) < 0) return rc;
        vec3 nn = v3_norm(n);
        uint32_t idx[4];
        for (int k = 0; k < 4; k++) {
            int64_t r = scene_add_vertex(L->s, corners[k], nn, L->err);
            if (r < 0) return (int)r;
            idx[k] = (uint32_t)r;
        }
        uint32_t before = L->s->ntris;
        if ((rc = scene_add_polygon(L->s, idx, 4, L->err))) return rc;
        /* Some area, but too thin for its length: the scene drops such
         * slivers, and the light was gone with no word (a black image). */
        if (L->s->ntris == before) return bad(L, ctx, "too thin: its area is a sliver of its edges' lengths");
        if ((rc = scene_end_node(L->s, L->err))) return rc;
    }
    return scene_end_node(L->s, L->err);
}

static int import_cameras(loader *L, const cJSON *cams)
{
    if (!cJSON_IsArray(cams)) return bad(L, "cameras", "must be an array");
    int i = 0, rc;
    for (const cJSON *c = cams->child; c; c = c->next, i++) {
        char ctx[64];
        snprintf(ctx, sizeof ctx, "cameras[%d]", i);
        if (!cJSON_IsObject(c)) return bad(L, ctx, "must be an object");
        static const char *const keys[] = {"name", "eye", "target", "up", "fov", NULL};
        if ((rc = check_keys(L, c, ctx, keys))) return rc;
        const char *name;
        vec3 eye, target, up;
        float fov;
        if ((rc = get_str(L, c, "name", ctx, 1, &name))) return rc;
        if ((rc = get_vec3(L, c, "eye", ctx, 1, v3s(0), &eye))) return rc;
        if ((rc = get_vec3(L, c, "target", ctx, 1, v3s(0), &target))) return rc;
        if ((rc = get_vec3(L, c, "up", ctx, 0, v3(0, 1, 0), &up))) return rc;
        if ((rc = get_num(L, c, "fov", ctx, 0, 45.0f, &fov))) return rc;
        /* (a zero up, or one along the view, left the camera's roll to
         * chance; scene_add_camera names eyes and targets out of range) */
        vec3 view = v3_sub(target, eye);
        if (v3_in_range(eye) && v3_in_range(target) &&
            (!(v3_len2(up) > 0.0f) ||
             (v3_len2(view) > 0.0f && !(v3_len2(v3_cross(v3_norm(view), v3_norm(up))) > 1e-12f))))
            return ct_fail(L->err, CT_EPARSE, "%s: camera '%s': 'up' is zero or along the view direction", L->path,
                           name);
        if ((rc = scene_add_camera(L->s, name, eye, target, up, fov, L->err))) {
            ct_error_prefix(L->err, L->path);
            return rc;
        }
    }
    return CT_OK;
}

static int import_paths(loader *L, const cJSON *paths)
{
    if (!cJSON_IsArray(paths)) return bad(L, "paths", "must be an array");
    int i = 0, rc;
    for (const cJSON *p = paths->child; p; p = p->next, i++) {
        char ctx[64];
        snprintf(ctx, sizeof ctx, "paths[%d]", i);
        if (!cJSON_IsObject(p)) return bad(L, ctx, "must be an object");
        static const char *const keys[] = {"name", "file", "keys", "up", NULL};
        if ((rc = check_keys(L, p, ctx, keys))) return rc;
        const char *name, *file;
        if ((rc = get_str(L, p, "name", ctx, 1, &name))) return rc;
        if ((rc = get_str(L, p, "file", ctx, 0, &file))) return rc;
        const cJSON *keysj = cJSON_GetObjectItemCaseSensitive(p, "keys");
        if (!!file == !!keysj) return bad(L, ctx, "needs exactly one of 'file' and 'keys'");
        ct_campath path;
        if (file) {
            if (cJSON_GetObjectItemCaseSensitive(p, "up")) return bad(L, ctx, "'up' belongs in the path file");
            char full[4096];
            fs_join(L->dir, file, full, sizeof full);
            char *text;
            size_t len;
            if ((rc = fs_read_all(full, 16u << 20, &text, &len, L->err))) return rc;
            L->hash = ct_hash_bytes(L->hash, text, len);
            rc = campath_parse(text, full, &path, L->err);
            free(text);
            if (rc) return rc;
        } else {
            vec3 up;
            if ((rc = get_vec3(L, p, "up", ctx, 0, v3(0, 1, 0), &up))) return rc;
            if (!cJSON_IsArray(keysj)) return bad(L, ctx, "'keys' must be an array");
            int n = cJSON_GetArraySize(keysj), k = 0;
            if (n > 100000) return bad(L, ctx, "too many keys");
            campath_key *keys_arr = calloc(n ? (size_t)n : 1, sizeof *keys_arr);
            if (!keys_arr) return ct_fail(L->err, CT_ENOMEM, "%s: out of memory", L->path);
            for (const cJSON *kj = keysj->child; kj; kj = kj->next, k++) {
                float f[8];
                int cnt = cJSON_GetArraySize(kj);
                char kc[96];
                snprintf(kc, sizeof kc, "%s.keys[%d]", ctx, k);
                if (cnt != 7 && cnt != 8) { free(keys_arr); return bad(L, kc, "needs 7 or 8 numbers"); }
                f[7] = 45.0f;
                if ((rc = get_floats(L, kj, "key", kc, f, cnt))) { free(keys_arr); return rc; }
                keys_arr[k] = (campath_key){f[0], v3(f[1], f[2], f[3]), v3(f[4], f[5], f[6]), f[7]};
            }
            char origin[256];
            snprintf(origin, sizeof origin, "%s: %s", L->path, ctx);
            rc = campath_from_keys(keys_arr, n, up, origin, &path, L->err);
            free(keys_arr);
            if (rc) return rc;
        }
        snprintf(path.name, sizeof path.name, "%s", name);
        if ((rc = scene_add_path(L->s, &path, L->err))) {
            campath_free(&path);
            ct_error_prefix(L->err, L->path);
            return rc;
        }
    }
    return CT_OK;
}

/* --- the scene file ---------------------------------------------------------- */

static void line_col(const char *text, const char *at, int *line, int *col)
{
    *line = 1;
    *col = 1;
    for (const char *p = text; p < at && *p; p++) {
        if (*p == '\n') { (*line)++; *col = 1; }
        else (*col)++;
    }
}

static int by_name(const void *a, const void *b)
{
    return strcmp(*(const char *const *)a, *(const char *const *)b);
}

/* Fails on a key that appears twice in one object, anywhere in the tree:
 * cJSON keeps both and every lookup finds the first, so the second would be
 * dropped without a word. Sorting keeps a hostile object of many keys
 * O(n log n). where names the enclosing key ("in 'oak'"). */
static int check_duplicates(loader *L, const cJSON *j, const char *where)
{
    if (cJSON_IsObject(j)) {
        size_t n = 0;
        for (const cJSON *it = j->child; it; it = it->next) n++;
        if (n > 1) {
            const char **names = malloc(n * sizeof *names);
            if (!names) return ct_fail(L->err, CT_ENOMEM, "%s: out of memory", L->path);
            size_t k = 0;
            for (const cJSON *it = j->child; it; it = it->next) names[k++] = it->string ? it->string : "";
            qsort(names, n, sizeof *names, by_name);
            const char *dup = NULL;
            for (k = 1; k < n && !dup; k++)
                if (strcmp(names[k - 1], names[k]) == 0) dup = names[k];
            int rc = dup ? ct_fail(L->err, CT_EPARSE, "%s: duplicate key '%s' %s", L->path, dup, where) : CT_OK;
            free(names);
            if (rc) return rc;
        }
    }
    for (const cJSON *it = j->child; it; it = it->next) {
        char inner[96];
        if (it->string) snprintf(inner, sizeof inner, "in '%.80s'", it->string);
        else snprintf(inner, sizeof inner, "%s", where);
        int rc = check_duplicates(L, it, inner);
        if (rc) return rc;
    }
    return CT_OK;
}

/* Warns once for each name that more than one file node (mesh entry, and
 * the lights' node) carries. Nothing looks nodes up by name (programs
 * address them by index; cameras and paths, which are looked up by name,
 * refuse duplicates), so this is no error: placing one file twice without
 * a "name" is fine, but `corrtex info --tree` cannot tell the two apart. */
static int warn_duplicate_names(loader *L)
{
    const ct_scene *s = L->s;
    size_t n = 0;
    for (uint32_t i = 0; i < s->nnodes; i++) n += s->nodes[i].kind == SCENE_NODE_FILE;
    if (n < 2) return CT_OK;
    const char **names = malloc(n * sizeof *names);
    if (!names) return ct_fail(L->err, CT_ENOMEM, "%s: out of memory", L->path);
    size_t k = 0;
    for (uint32_t i = 0; i < s->nnodes; i++)
        if (s->nodes[i].kind == SCENE_NODE_FILE) names[k++] = s->nodes[i].name;
    qsort(names, n, sizeof *names, by_name);
    for (size_t a = 0, b; a < n; a = b) {
        for (b = a + 1; b < n && strcmp(names[a], names[b]) == 0; b++) {
        }
        if (b - a > 1)
            ct_warn("scene", "%s: %zu nodes are named '%s': give each its own \"name\" to tell them apart", L->path,
                    b - a, names[a]);
    }
    free(names);
    return CT_OK;
}

static int load_json(loader *L, const char *text, size_t len)
{
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithLengthOpts(text, len, &end, 0);
    if (!root) {
        int line, col;
        line_col(text, end ? end : text + len, &line, &col);
        return ct_fail(L->err, CT_EPARSE, "%s:%d:%d: JSON syntax error", L->path, line, col);
    }
    while (end && end < text + len && (*end == ' ' || *end == '\t' || *end == '\n' || *end == '\r')) end++;
    int rc = CT_OK;
    if (end && end < text + len) {
        int line, col;
        line_col(text, end, &line, &col);
        rc = ct_fail(L->err, CT_EPARSE, "%s:%d:%d: trailing characters after the JSON value", L->path, line, col);
        goto done;
    }
    if ((rc = check_duplicates(L, root, "at the top level"))) goto done;
    if (!cJSON_IsObject(root)) {
        rc = bad(L, "top level", "must be a JSON object");
        goto done;
    }
    static const char *const keys[] = {"name", "meshes", "materials", "lights", "cameras", "paths", NULL};
    if ((rc = check_keys(L, root, "top level", keys))) goto done;
    const char *name;
    if ((rc = get_str(L, root, "name", "top level", 0, &name))) goto done;
    if (name) {
        snprintf(L->s->name, sizeof L->s->name, "%s", name);
        snprintf(L->s->nodes[0].name, sizeof L->s->nodes[0].name, "%s", name);
    }

    const cJSON *mats = cJSON_GetObjectItemCaseSensitive(root, "materials");
    if (mats) {
        if (!cJSON_IsObject(mats)) { rc = bad(L, "materials", "must be an object"); goto done; }
        for (const cJSON *m = mats->child; m; m = m->next) {
            if (strlen(m->string) >= SCENE_NAME_LEN || !m->string[0]) {
                rc = bad(L, "materials", "material names must have 1 to 63 characters");
                goto done;
            }
            if (scene_find_material(L->s, m->string) >= 0) {
                rc = ct_fail(L->err, CT_EPARSE, "%s: materials: '%s' defined twice", L->path, m->string);
                goto done;
            }
            scene_material sm;
            if ((rc = parse_material(L, m, m->string, &sm))) goto done;
            if ((rc = scene_add_material(L->s, &sm, L->err)) < 0) goto done;
            rc = CT_OK;
        }
    }
    const cJSON *meshes = cJSON_GetObjectItemCaseSensitive(root, "meshes");
    if (meshes) {
        if (!cJSON_IsArray(meshes)) { rc = bad(L, "meshes", "must be an array"); goto done; }
        plan_imports(L, meshes);
        int i = 0;
        for (const cJSON *m = meshes->child; m; m = m->next, i++)
            if ((rc = import_mesh_entry(L, m, i))) break;
        free_imports(L);
        if (rc) goto done;
    }
    const cJSON *lights = cJSON_GetObjectItemCaseSensitive(root, "lights");
    if (lights && (rc = import_lights(L, lights))) goto done;
    const cJSON *cams = cJSON_GetObjectItemCaseSensitive(root, "cameras");
    if (cams && (rc = import_cameras(L, cams))) goto done;
    const cJSON *paths = cJSON_GetObjectItemCaseSensitive(root, "paths");
    if (paths && (rc = import_paths(L, paths))) goto done;
    rc = warn_duplicate_names(L);
done:
    cJSON_Delete(root);
    return rc;
}

int scene_load(const char *path, ct_scene **out, ct_error *err)
{
    *out = NULL;
    char *text;
    size_t len;
    int rc = fs_read_all(path, SCENE_JSON_MAX, &text, &len, err);
    if (rc) return rc;
    char name[SCENE_NAME_LEN];
    basename_noext(path, name, sizeof name);
    ct_scene *s = scene_new(name);
    if (!s) {
        free(text);
        return ct_fail(err, CT_ENOMEM, "%s: out of memory", path);
    }
    loader L = {.s = s, .path = path, .err = err};
    fs_dirname(path, L.dir, sizeof L.dir);
    L.hash = ct_hash_bytes(CT_HASH_INIT, text, len);
    rc = load_json(&L, text, len);
    free(text);
    if (rc == CT_OK) {
        rc = scene_finalize(s, err);
        if (rc) ct_error_prefix(err, path);
    }
    if (rc) {
        scene_free(s);
        return rc < 0 ? rc : CT_EPARSE;
    }
    snprintf(s->source, sizeof s->source, "%s", path);
    s->source_hash = L.hash;
    *out = s;
    return CT_OK;
}

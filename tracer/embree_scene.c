#include "tracer/embree_scene.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

_Static_assert(sizeof(emb_tri) == 128, "emb_tri must fill two cache lines");
_Static_assert(offsetof(emb_tri, na) == 64, "emb_tri's second cache line must start at na");

struct emb_scene {
    emb_mesh mesh;
    RTCDevice device;
    RTCScene scene;
    float *verts;         /* padded copy of the positions (Embree reads 16 bytes) */
    uint32_t *index;      /* triangles grouped by part node */
    uint32_t *order;      /* grouped position -> mesh triangle (build only) */
    uint32_t *geom_base;  /* geomID -> first grouped position */
    uint32_t ngeoms;
    emb_tri *recs;        /* per grouped position: the triangle's shading record */
    uint64_t *curved;     /* per grouped position, a bit: the record is not flat */
    ct_error dev_err;     /* last device error (filled by the callback) */
    int dev_code;
};

emb_mesh emb_mesh_of_scene(const ct_scene *s)
{
    emb_mesh m;
    m.nverts = s->nverts;
    m.pos = s->pos;
    m.nrm = s->nrm;
    m.ntris = s->ntris;
    m.tris = s->tris;
    m.tri_node = s->tri_node;
    m.tri_mat = s->tri_mat;
    m.nnodes = s->nnodes;
    m.nmats = s->nmats;
    m.mats = s->mats;
    m.vertex_reads = false;
    return m;
}

emb_mesh emb_mesh_of_radmesh(const ct_radmesh *r, const ct_scene *s)
{
    emb_mesh m;
    m.nverts = r->nverts;
    m.pos = r->pos;
    m.nrm = r->nrm;
    m.ntris = r->ntris;
    m.tris = r->tris;
    m.tri_node = r->tri_node;
    m.tri_mat = r->tri_mat;
    m.nnodes = r->nnodes;
    m.nmats = s->nmats;
    m.mats = s->mats;
    m.vertex_reads = true;
    return m;
}

static const char *rtc_error_name(enum RTCError code)
{
    switch (code) {
    case RTC_ERROR_NONE: return "none";
    case RTC_ERROR_UNKNOWN: return "unknown error";
    case RTC_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case RTC_ERROR_INVALID_OPERATION: return "invalid operation";
    case RTC_ERROR_OUT_OF_MEMORY: return "out of memory";
    case RTC_ERROR_UNSUPPORTED_CPU: return "unsupported CPU";
    case RTC_ERROR_CANCELLED: return "cancelled";
    }
    return "error";
}

/* Embree calls this on every device error; we keep the first one so the
 * builder can report it as one ct_error line. */
static void device_error(void *user, enum RTCError code, const char *str)
{
    emb_scene *e = user;
    if (e->dev_code) return;
    e->dev_code = code == RTC_ERROR_OUT_OF_MEMORY ? CT_ENOMEM : CT_ESYS;
    ct_fail(&e->dev_err, e->dev_code, "embree: %s: %s", rtc_error_name(code), str ? str : "");
}

static int check_device(emb_scene *e, ct_error *err, const char *what)
{
    if (!e->dev_code && rtcGetDeviceError(e->device) == RTC_ERROR_NONE) return CT_OK;
    if (!e->dev_code) {
        e->dev_code = CT_ESYS;
        ct_fail(&e->dev_err, CT_ESYS, "embree: error");
    }
    ct_fail(err, e->dev_code, "%s while %s", e->dev_err.msg, what);
    return e->dev_code;
}

static int validate(const emb_mesh *m, ct_error *err)
{
    if (m->ntris == 0) return ct_fail(err, CT_EEMPTY, "mesh has no triangles");
    if (m->nmats == 0) return ct_fail(err, CT_EINVAL, "mesh has no materials");
    for (uint32_t v = 0; v < m->nverts; v++)
        if (!v3_in_range(m->pos[v]))
            return ct_fail(err, CT_EINVAL, "vertex %u: position not finite or outside +-%g", v, (double)CT_COORD_MAX);
    for (uint32_t t = 0; t < m->ntris; t++) {
        for (int k = 0; k < 3; k++)
            if (m->tris[3 * (size_t)t + k] >= m->nverts)
                return ct_fail(err, CT_ERANGE, "triangle %u: vertex index %u out of range (%u vertices)",
                               t, m->tris[3 * (size_t)t + k], m->nverts);
        if (m->tri_mat[t] >= m->nmats)
            return ct_fail(err, CT_ERANGE, "triangle %u: material %u out of range (%u materials)", t,
                           m->tri_mat[t], m->nmats);
        if (m->tri_node[t] >= m->nnodes)
            return ct_fail(err, CT_ERANGE, "triangle %u: node %u out of range (%u nodes)", t,
                           m->tri_node[t], m->nnodes);
    }
    return CT_OK;
}

/* Whether r's shading normal may be taken as its geometric one: every vertex
 * normal within 1e-6 of ng in cosine (0.08 degrees), as on the faces of boxes
 * and walls; their interpolation differs from ng by rounding alone. */
static bool flat_normals(const emb_tri *r)
{
    const vec3 n[3] = {r->na, r->nb, r->nc};
    for (int k = 0; k < 3; k++) {
        float l2 = v3_len2(n[k]);
        if (!(l2 > 1e-12f) || !(v3_dot(n[k], r->ng) > (1.0f - 1e-6f) * sqrtf(l2))) return false;
    }
    return true;
}

/* Groups the triangles by part node (counting sort, stable) so each node's
 * triangles form one Embree geometry. */
static int group_by_node(emb_scene *e, ct_error *err)
{
    const emb_mesh *m = &e->mesh;
    uint32_t *count = calloc((size_t)m->nnodes + 1, sizeof *count);
    e->order = malloc((size_t)m->ntris * sizeof *e->order);
    e->index = malloc((size_t)m->ntris * 3 * sizeof *e->index);
    if (!count || !e->order || !e->index) {
        free(count);
        return ct_fail(err, CT_ENOMEM, "out of memory grouping %u triangles", m->ntris);
    }
    for (uint32_t t = 0; t < m->ntris; t++) count[m->tri_node[t] + 1]++;
    uint32_t used = 0;
    for (uint32_t n = 0; n < m->nnodes; n++) used += count[n + 1] > 0;
    for (uint32_t n = 0; n < m->nnodes; n++) count[n + 1] += count[n];
    for (uint32_t t = 0; t < m->ntris; t++) {
        uint32_t at = count[m->tri_node[t]]++;
        e->order[at] = t;
        memcpy(e->index + 3 * (size_t)at, m->tris + 3 * (size_t)t, 3 * sizeof(uint32_t));
    }
    free(count);
    e->geom_base = malloc(((size_t)used + 1) * sizeof *e->geom_base);
    if (!e->geom_base) return ct_fail(err, CT_ENOMEM, "out of memory for %u geometries", used);
    /* Geometry boundaries: where the node changes in the grouped order. */
    uint32_t g = 0;
    for (uint32_t i = 0; i < m->ntris; i++)
        if (i == 0 || m->tri_node[e->order[i]] != m->tri_node[e->order[i - 1]]) e->geom_base[g++] = i;
    e->geom_base[g] = m->ntris;
    e->ngeoms = g;
    return CT_OK;
}

int emb_new(const emb_mesh *mesh, const char *device_config, emb_scene **out, ct_error *err)
{
    *out = NULL;
    int rc = validate(mesh, err);
    if (rc) return rc;
    emb_scene *e = calloc(1, sizeof *e);
    if (!e) return ct_fail(err, CT_ENOMEM, "out of memory");
    e->mesh = *mesh;
    rc = group_by_node(e, err);
    if (rc) goto fail;
    e->verts = malloc(((size_t)mesh->nverts * 3 + 4) * sizeof(float));
    if (!e->verts) {
        rc = ct_fail(err, CT_ENOMEM, "out of memory for %u vertices", mesh->nverts);
        goto fail;
    }
    for (uint32_t v = 0; v < mesh->nverts; v++) {
        e->verts[3 * (size_t)v] = mesh->pos[v].x;
        e->verts[3 * (size_t)v + 1] = mesh->pos[v].y;
        e->verts[3 * (size_t)v + 2] = mesh->pos[v].z;
    }
    memset(e->verts + 3 * (size_t)mesh->nverts, 0, 4 * sizeof(float));

    /* Cache-line aligned, so a record spans exactly two lines. */
    size_t rec_bytes = ((size_t)mesh->ntris * sizeof *e->recs + 63) / 64 * 64;
    e->recs = aligned_alloc(64, rec_bytes);
    if (!e->recs) {
        rc = ct_fail(err, CT_ENOMEM, "out of memory for %u triangles", mesh->ntris);
        goto fail;
    }
    e->curved = calloc((size_t)mesh->ntris / 64 + 1, sizeof *e->curved);
    if (!e->curved) {
        rc = ct_fail(err, CT_ENOMEM, "out of memory for %u triangles", mesh->ntris);
        goto fail;
    }
    for (uint32_t i = 0; i < mesh->ntris; i++) {
        uint32_t t = e->order[i];
        const uint32_t *vi = mesh->tris + 3 * (size_t)t;
        emb_tri *r = &e->recs[i];
        r->a = mesh->pos[vi[0]];
        r->e1 = v3_sub(mesh->pos[vi[1]], r->a);
        r->e2 = v3_sub(mesh->pos[vi[2]], r->a);
        r->ng = emb_tri_normal(mesh, t);
        vec3 zero = v3s(0.0f);
        r->na = mesh->nrm ? mesh->nrm[vi[0]] : zero;
        r->nb = mesh->nrm ? mesh->nrm[vi[1]] : zero;
        r->nc = mesh->nrm ? mesh->nrm[vi[2]] : zero;
        r->tri = t;
        r->node = mesh->tri_node[t];
        r->mat = mesh->tri_mat[t];
        memcpy(r->v, vi, sizeof r->v);
        memset(r->pad, 0, sizeof r->pad);
        r->flat = !mesh->nrm || flat_normals(r);
        if (!r->flat) e->curved[i / 64] |= 1ull << (i % 64);
    }
    free(e->order);   /* the records carry the mesh triangle */
    e->order = NULL;

    e->device = rtcNewDevice(device_config && *device_config ? device_config : NULL);
    if (!e->device) {
        enum RTCError code = rtcGetDeviceError(NULL);
        rc = ct_fail(err, CT_ESYS, "embree: cannot create a device (%s) with config '%s'",
                     rtc_error_name(code), device_config ? device_config : "");
        goto fail;
    }
    rtcSetDeviceErrorFunction(e->device, device_error, e);
    e->scene = rtcNewScene(e->device);
    if ((rc = check_device(e, err, "creating the scene"))) goto fail;
    /* Robust mode off (watertight-enough for closed meshes, faster); high
     * quality build: the scene is static and traced millions of times. */
    rtcSetSceneFlags(e->scene, RTC_SCENE_FLAG_NONE);
    rtcSetSceneBuildQuality(e->scene, RTC_BUILD_QUALITY_HIGH);
    for (uint32_t g = 0; g < e->ngeoms; g++) {
        uint32_t first = e->geom_base[g], n = e->geom_base[g + 1] - first;
        RTCGeometry geom = rtcNewGeometry(e->device, RTC_GEOMETRY_TYPE_TRIANGLE);
        if ((rc = check_device(e, err, "creating a geometry"))) goto fail;
        rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_HIGH);
        rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, e->verts, 0,
                                   3 * sizeof(float), mesh->nverts);
        rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, e->index,
                                   (size_t)first * 3 * sizeof(uint32_t), 3 * sizeof(uint32_t), n);
        rtcCommitGeometry(geom);
        rtcAttachGeometryByID(e->scene, geom, g);
        rtcReleaseGeometry(geom);
        if ((rc = check_device(e, err, "adding a geometry"))) goto fail;
    }
    rtcCommitScene(e->scene);
    if ((rc = check_device(e, err, "building the BVH"))) goto fail;
    *out = e;
    return CT_OK;
fail:
    emb_free(e);
    return rc;
}

void emb_free(emb_scene *e)
{
    if (!e) return;
    if (e->scene) rtcReleaseScene(e->scene);
    if (e->device) rtcReleaseDevice(e->device);
    free(e->verts);
    free(e->index);
    free(e->order);
    free(e->geom_base);
    free(e->recs);
    free(e->curved);
    free(e);
}

const emb_mesh *emb_get_mesh(const emb_scene *e) { return &e->mesh; }

static inline void make_ray(struct RTCRay *r, vec3 o, vec3 d, float tnear, float tfar)
{
    r->org_x = o.x;
    r->org_y = o.y;
    r->org_z = o.z;
    r->tnear = tnear;
    r->dir_x = d.x;
    r->dir_y = d.y;
    r->dir_z = d.z;
    r->time = 0.0f;
    r->tfar = tfar;
    r->mask = 0xffffffffu;
    r->id = 0;
    r->flags = 0;
}

bool emb_intersect_start(const emb_scene *e, vec3 o, vec3 d, float tnear, float tfar, emb_hit *hit)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRayHit rh;
    make_ray(&rh.ray, o, d, tnear, tfar);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(e->scene, &ctx, &rh);
    hit->rec = NULL;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    const uint32_t i = e->geom_base[rh.hit.geomID] + rh.hit.primID;
    const emb_tri *r = &e->recs[i];
    __builtin_prefetch(r);
    /* the second line only when it will be read (a small bitset says so
     * before the record arrives) */
    if (e->mesh.vertex_reads || (e->curved[i / 64] >> (i % 64) & 1u)) __builtin_prefetch((const char *)r + 64);
    hit->t = rh.ray.tfar;
    hit->u = rh.hit.u;
    hit->v = rh.hit.v;
    hit->rec = r;
    return true;
}

bool emb_intersect(const emb_scene *e, vec3 o, vec3 d, float tnear, float tfar, emb_hit *hit)
{
    if (!emb_intersect_start(e, o, d, tnear, tfar, hit)) return false;
    emb_hit_finish(hit);
    return true;
}

bool emb_occluded(const emb_scene *e, vec3 o, vec3 d, float tnear, float tfar)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRay r;
    make_ray(&r, o, d, tnear, tfar);
    rtcOccluded1(e->scene, &ctx, &r);
    return r.tfar < 0.0f;
}

/* Fills lane i of an SoA ray packet (RTCRay4 and RTCRay8 share the layout). */
#define PACKET_LANE(r, i, o, d, tf)                                                      \
    do {                                                                                 \
        (r).org_x[i] = (o).x, (r).org_y[i] = (o).y, (r).org_z[i] = (o).z;                \
        (r).dir_x[i] = (d).x, (r).dir_y[i] = (d).y, (r).dir_z[i] = (d).z;                \
        (r).tnear[i] = 0.0f, (r).tfar[i] = (tf), (r).time[i] = 0.0f;                     \
        (r).mask[i] = 0xffffffffu, (r).id[i] = 0, (r).flags[i] = 0;                      \
    } while (0)

void emb_occluded_batch(const emb_scene *e, int n, const vec3 *o, const vec3 *d, const float *tfar,
                        bool *blocked)
{
    if (n <= 0) return;
    if (n == 1) {
        blocked[0] = emb_occluded(e, o[0], d[0], 0.0f, tfar[0]);
        return;
    }
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    if (n <= 4) {
        _Alignas(16) int valid[4];
        _Alignas(16) struct RTCRay4 r;
        for (int i = 0; i < 4; i++) {
            valid[i] = i < n ? -1 : 0;
            int k = i < n ? i : 0;
            PACKET_LANE(r, i, o[k], d[k], tfar[k]);
        }
        rtcOccluded4(valid, e->scene, &ctx, &r);
        for (int i = 0; i < n; i++) blocked[i] = r.tfar[i] < 0.0f;
        return;
    }
    _Alignas(32) int valid[8];
    _Alignas(32) struct RTCRay8 r;
    for (int i = 0; i < 8; i++) {
        valid[i] = i < n ? -1 : 0;
        int k = i < n ? i : 0;
        PACKET_LANE(r, i, o[k], d[k], tfar[k]);
    }
    rtcOccluded8(valid, e->scene, &ctx, &r);
    for (int i = 0; i < n && i < 8; i++) blocked[i] = r.tfar[i] < 0.0f;
}

float emb_raw_intersect(const emb_scene *e, vec3 o, vec3 d, float tnear, float tfar)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRayHit rh;
    make_ray(&rh.ray, o, d, tnear, tfar);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(e->scene, &ctx, &rh);
    return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? INFINITY : rh.ray.tfar;
}

bool emb_raw_occluded(const emb_scene *e, vec3 o, vec3 d, float tnear, float tfar)
{
    return emb_occluded(e, o, d, tnear, tfar);
}

vec3 emb_shading_normal(const emb_hit *h)
{
    const emb_tri *r = h->rec;
    if (!r->flat) {
        float u = h->u, v = h->v, w = 1.0f - u - v;
        vec3 na = r->na, nb = r->nb, nc = r->nc;
        vec3 n = v3(w * na.x + u * nb.x + v * nc.x, w * na.y + u * nb.y + v * nc.y,
                    w * na.z + u * nb.z + v * nc.z);
        float l2 = v3_len2(n);
        if (l2 > 1e-12f && isfinite(l2)) return v3_scale(n, 1.0f / sqrtf(l2));
    }
    return r->ng;
}

vec3 emb_tri_normal(const emb_mesh *m, uint32_t t)
{
    const uint32_t *i = m->tris + 3 * (size_t)t;
    return v3_norm(v3_cross(v3_sub(m->pos[i[1]], m->pos[i[0]]), v3_sub(m->pos[i[2]], m->pos[i[0]])));
}

float emb_tri_area(const emb_mesh *m, uint32_t t)
{
    const uint32_t *i = m->tris + 3 * (size_t)t;
    return 0.5f * v3_len(v3_cross(v3_sub(m->pos[i[1]], m->pos[i[0]]), v3_sub(m->pos[i[2]], m->pos[i[0]])));
}

vec3 emb_tri_point(const emb_mesh *m, uint32_t t, float u, float v)
{
    const uint32_t *i = m->tris + 3 * (size_t)t;
    vec3 a = m->pos[i[0]], b = m->pos[i[1]], c = m->pos[i[2]];
    return v3_add(a, v3_add(v3_scale(v3_sub(b, a), u), v3_scale(v3_sub(c, a), v)));
}

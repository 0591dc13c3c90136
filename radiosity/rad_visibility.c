/* rad_visibility.c: the radiosity solver's own Embree scenes and segment
 * transmission queries: the opaque triangles in one scene, glass (the
 * dielectric materials) in another, which a segment passes attenuated by
 * each crossing's transmission and Fresnel factor as the tracer's shadow
 * rays do (docs/radiosity.md, "Glass"). Kept separate from the tracer's
 * scene so the solver can run without it; a successor may share one. */
#include "radiosity/rad_internal.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct rad_vis {
    RTCDevice dev;
    RTCScene scn;        /* opaque triangles */
    RTCScene glass;      /* dielectric triangles; NULL without any */
    rmesh_material *gmat;   /* per glass primitive: its material... */
    vec3 *gn;               /* ...and unit normal */
    vec3 *on;               /* per opaque primitive: its normal (winding's side) */
    atomic_int_fast64_t bytes;
    ct_error *err;
};

static void on_error(void *user, enum RTCError code, const char *str)
{
    rad_vis *v = user;
    if (v && v->err) ct_fail(v->err, CT_ESYS, "embree: error %d: %s", (int)code, str ? str : "");
}

static bool on_memory(void *user, ssize_t bytes, bool post)
{
    (void)post;
    rad_vis *v = user;
    atomic_fetch_add(&v->bytes, (int_fast64_t)bytes);
    return true;
}

/* A scene of the triangles of s whose material is (glass) or is not
 * dielectric; prim[i] receives the scene triangle of primitive i. NULL with
 * *n = 0 when there are none. */
static RTCScene build_scene(rad_vis *v, const ct_scene *s, bool glass, uint32_t *prim, uint32_t *n)
{
    *n = 0;
    for (uint32_t t = 0; t < s->ntris; t++)
        if (s->mats[s->tri_mat[t]].dielectric == glass) prim[(*n)++] = t;
    if (*n == 0) return NULL;
    RTCScene scn = rtcNewScene(v->dev);
    rtcSetSceneBuildQuality(scn, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry g = rtcNewGeometry(v->dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                        s->nverts);
    unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), *n);
    if (!vb || !ib) {
        rtcReleaseGeometry(g);
        rtcReleaseScene(scn);
        return NULL;
    }
    for (uint32_t i = 0; i < s->nverts; i++) {
        vb[3 * i] = s->pos[i].x;
        vb[3 * i + 1] = s->pos[i].y;
        vb[3 * i + 2] = s->pos[i].z;
    }
    for (uint32_t i = 0; i < *n; i++) memcpy(ib + 3 * (size_t)i, s->tris + 3 * (size_t)prim[i], 3 * sizeof(unsigned));
    rtcCommitGeometry(g);
    rtcAttachGeometry(scn, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scn);
    return scn;
}

int rad_vis_new(const ct_scene *s, int threads, rad_vis **out, ct_error *err)
{
    *out = NULL;
    rad_vis *v = calloc(1, sizeof *v);
    uint32_t *prim = malloc((s->ntris ? s->ntris : 1) * sizeof *prim);
    if (!v || !prim) {
        free(v);
        free(prim);
        return ct_fail(err, CT_ENOMEM, "radiosity: out of memory for the Embree scene");
    }
    char cfg[64];
    snprintf(cfg, sizeof cfg, "threads=%d", threads > 0 ? threads : 1);
    v->err = err;
    v->dev = rtcNewDevice(cfg);
    if (!v->dev) {
        free(v);
        free(prim);
        return ct_fail(err, CT_ESYS, "embree: cannot create a device (error %d)", (int)rtcGetDeviceError(NULL));
    }
    rtcSetDeviceErrorFunction(v->dev, on_error, v);
    rtcSetDeviceMemoryMonitorFunction(v->dev, on_memory, v);
    uint32_t n;
    v->scn = build_scene(v, s, false, prim, &n);
    if (!v->scn && n == 0) {
        /* All glass: nothing opaque. */
        v->scn = rtcNewScene(v->dev);
        rtcCommitScene(v->scn);
    }
    int rc = CT_OK;
    if (n) {
        v->on = malloc(n * sizeof *v->on);
        if (!v->on) rc = CT_ENOMEM;
        for (uint32_t i = 0; i < n && !rc; i++) {
            const uint32_t *vi = s->tris + 3 * (size_t)prim[i];
            v->on[i] = v3_cross(v3_sub(s->pos[vi[1]], s->pos[vi[0]]), v3_sub(s->pos[vi[2]], s->pos[vi[0]]));
        }
    }
    v->glass = build_scene(v, s, true, prim, &n);
    if (n && v->glass) {
        v->gmat = malloc(n * sizeof *v->gmat);
        v->gn = malloc(n * sizeof *v->gn);
        if (!v->gmat || !v->gn) rc = CT_ENOMEM;
        for (uint32_t i = 0; i < n && !rc; i++) {
            uint32_t t = prim[i];
            const uint32_t *vi = s->tris + 3 * (size_t)t;
            v->gmat[i] = rmesh_material_of(&s->mats[s->tri_mat[t]]);
            v->gn[i] = v3_norm(v3_cross(v3_sub(s->pos[vi[1]], s->pos[vi[0]]), v3_sub(s->pos[vi[2]], s->pos[vi[0]])));
        }
    }
    free(prim);
    if (rc || !v->scn || (n && !v->glass) || rtcGetDeviceError(v->dev) != RTC_ERROR_NONE) {
        rad_vis_free(v);
        return rc ? ct_fail(err, CT_ENOMEM, "radiosity: out of memory for the visibility tables")
                  : ct_fail(err, CT_ESYS, "embree: building the visibility scene failed");
    }
    v->err = NULL;   /* later errors would come from worker threads */
    *out = v;
    return CT_OK;
}

void rad_vis_free(rad_vis *v)
{
    if (!v) return;
    if (v->scn) rtcReleaseScene(v->scn);
    if (v->glass) rtcReleaseScene(v->glass);
    if (v->dev) rtcReleaseDevice(v->dev);
    free(v->gmat);
    free(v->gn);
    free(v->on);
    free(v);
}

/* The segment's last share is not traced from a: there Embree's t, whose
 * rounding grows with the segment's length, cannot tell b's own surface
 * (just behind b) from one just in front of it. A second, short ray from b
 * back towards a covers that stretch twice over, from an origin lifted off
 * its surface. Without it the untested end was a share of the length: 14 cm
 * of a segment from a 1.4 km ground plane to a wall, through the room's
 * floor where the two meet, and the ground got light from inside a closed
 * room (docs/radiosity.md, "Scale"). */
#define SEG_END 1e-4f

static void segment_ray(struct RTCRay *r, vec3 a, vec3 b, float tnear)
{
    r->org_x = a.x;
    r->org_y = a.y;
    r->org_z = a.z;
    r->dir_x = b.x - a.x;
    r->dir_y = b.y - a.y;
    r->dir_z = b.z - a.z;
    r->tnear = tnear;
    r->tfar = 1.0f - SEG_END;
    r->time = 0.0f;
    r->mask = 0xFFFFFFFFu;
    r->id = 0;
    r->flags = 0;
}

float rad_vis_transmit(const rad_vis *v, vec3 a, vec3 b)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRay r;
    segment_ray(&r, a, b, 0.0f);
    rtcOccluded1(v->scn, &ctx, &r);
    if (r.tfar < 0.0f) return 0.0f;
    segment_ray(&r, b, a, 0.0f);
    r.tfar = 2.0f * SEG_END;
    rtcOccluded1(v->scn, &ctx, &r);
    if (r.tfar < 0.0f) return 0.0f;
    if (!v->glass) return 1.0f;
    segment_ray(&r, a, b, 0.0f);
    rtcOccluded1(v->glass, &ctx, &r);
    if (!(r.tfar < 0.0f)) return 1.0f;
    /* Through glass: each crossing in order (closest hits), its factor at
     * the segment's angle (rmesh_glass_pass, the mean of its channels). */
    vec3 d = v3_norm(v3_sub(b, a));
    float t0 = 0.0f, tr = 1.0f;
    for (int k = 0; k < RMESH_MAX_GLASS_CROSSINGS; k++) {
        struct RTCRayHit rh;
        segment_ray(&rh.ray, a, b, t0);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(v->glass, &ctx, &rh);
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return tr;
        uint32_t i = rh.hit.primID;
        tr *= v3_avg(rmesh_glass_pass(&v->gmat[i], v3_dot(d, v->gn[i])));
        if (!(tr > 0.0f)) return 0.0f;
        /* Just past this crossing (the segment runs over t in [0, 1]). */
        t0 = rh.ray.tfar + 1e-5f;
    }
    return 0.0f;
}

bool rad_vis_hits_back(const rad_vis *v, vec3 o, vec3 d)
{
    if (!v->on) return false;
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRayHit rh;
    segment_ray(&rh.ray, o, v3_add(o, d), 0.0f);
    rh.ray.tfar = INFINITY;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(v->scn, &ctx, &rh);
    return rh.hit.geomID != RTC_INVALID_GEOMETRY_ID && v3_dot(v->on[rh.hit.primID], d) > 0.0f;
}

uint64_t rad_vis_bytes(const rad_vis *v)
{
    int_fast64_t b = atomic_load(&((rad_vis *)v)->bytes);
    return b > 0 ? (uint64_t)b : 0;
}

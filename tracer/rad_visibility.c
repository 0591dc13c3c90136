/* rad_visibility.c: the radiosity solver's own Embree scene (every scene
 * triangle, all opaque) and segment occlusion queries. Kept separate from the
 * tracer's scene so the solver can run without it; a successor may share one. */
#include "tracer/rad_internal.h"

#include <embree3/rtcore.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct rad_vis {
    RTCDevice dev;
    RTCScene scn;
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

int rad_vis_new(const ct_scene *s, int threads, rad_vis **out, ct_error *err)
{
    *out = NULL;
    rad_vis *v = calloc(1, sizeof *v);
    if (!v) return ct_fail(err, CT_ENOMEM, "radiosity: out of memory for the Embree scene");
    char cfg[64];
    snprintf(cfg, sizeof cfg, "threads=%d", threads > 0 ? threads : 1);
    v->err = err;
    v->dev = rtcNewDevice(cfg);
    if (!v->dev) {
        free(v);
        return ct_fail(err, CT_ESYS, "embree: cannot create a device (error %d)", (int)rtcGetDeviceError(NULL));
    }
    rtcSetDeviceErrorFunction(v->dev, on_error, v);
    rtcSetDeviceMemoryMonitorFunction(v->dev, on_memory, v);
    v->scn = rtcNewScene(v->dev);
    rtcSetSceneBuildQuality(v->scn, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry g = rtcNewGeometry(v->dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                        3 * sizeof(float), s->nverts);
    unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                           3 * sizeof(unsigned), s->ntris);
    if (!vb || !ib) {
        rtcReleaseGeometry(g);
        rad_vis_free(v);
        return ct_fail(err, CT_ENOMEM, "embree: out of memory for %u triangles", s->ntris);
    }
    for (uint32_t i = 0; i < s->nverts; i++) {
        vb[3 * i] = s->pos[i].x;
        vb[3 * i + 1] = s->pos[i].y;
        vb[3 * i + 2] = s->pos[i].z;
    }
    memcpy(ib, s->tris, (size_t)s->ntris * 3 * sizeof(unsigned));
    rtcCommitGeometry(g);
    rtcAttachGeometry(v->scn, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(v->scn);
    if (rtcGetDeviceError(v->dev) != RTC_ERROR_NONE) {
        rad_vis_free(v);
        return ct_fail(err, CT_ESYS, "embree: building the visibility scene failed");
    }
    v->err = NULL;   /* later errors would come from worker threads */
    *out = v;
    return CT_OK;
}

void rad_vis_free(rad_vis *v)
{
    if (!v) return;
    if (v->scn) rtcReleaseScene(v->scn);
    if (v->dev) rtcReleaseDevice(v->dev);
    free(v);
}

int rad_vis_occluded(const rad_vis *v, vec3 a, vec3 b)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRay r;
    r.org_x = a.x;
    r.org_y = a.y;
    r.org_z = a.z;
    r.dir_x = b.x - a.x;
    r.dir_y = b.y - a.y;
    r.dir_z = b.z - a.z;
    r.tnear = 0.0f;
    r.tfar = 1.0f - 1e-4f;
    r.time = 0.0f;
    r.mask = 0xFFFFFFFFu;
    r.id = 0;
    r.flags = 0;
    rtcOccluded1(v->scn, &ctx, &r);
    return r.tfar < 0.0f;
}

uint64_t rad_vis_bytes(const rad_vis *v)
{
    int_fast64_t b = atomic_load(&((rad_vis *)v)->bytes);
    return b > 0 ? (uint64_t)b : 0;
}

/* rad_view.c: renders a radiosity mesh as the display shows it (Gouraud
 * interpolation of the per-vertex radiance at the primary hit, rmesh_eval;
 * through see-through glass, the surface behind it times each crossing's
 * rmesh_glass_pass),
 * by ray casting with Embree: a preview image for users and the image the
 * tests compare against a path-traced reference. */
#include "radiosity/radiosity.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/pool.h"
#include "common/rng.h"

typedef struct view_job {
    RTCScene scn;
    const ct_radmesh *m;
    const ct_camera *cam;
    ct_image *img;
    int spp, which;
    float scale;   /* plane offsets' unit (plane_key) */
} view_job;

/* The plane of triangle t, as three floats exact in an image: its part node
 * + 1, its first vertex's normal (the scene's shading normal, the same at
 * every vertex of a flat-shaded surface; a triangle's own normal would vary
 * with its rounding) quantized to 1/64 per axis, and its distance from the
 * origin along that normal in units of 1/256 of the bounding radius of the
 * mesh's vertices. */
static vec3 plane_key(const ct_radmesh *m, uint32_t t, float scale)
{
    const uint32_t *i = m->tris + 3 * (size_t)t;
    vec3 n = m->nrm[i[0]], a = m->pos[i[0]];
    float q[3] = {roundf(n.x * 64.0f) + 64.0f, roundf(n.y * 64.0f) + 64.0f, roundf(n.z * 64.0f) + 64.0f};
    float code = (q[0] * 129.0f + q[1]) * 129.0f + q[2];
    float off = roundf(v3_dot(n, a) * scale);
    return v3((float)m->tri_node[t] + 1.0f, code + 1.0f, off);
}

/* One row of the image (a pool task): its own random stream, so the image
 * is the same for any thread count. */
static void view_row(void *arg, int worker, size_t row)
{
    (void)worker;
    const view_job *j = arg;
    int W = j->img->width, H = j->img->height, y = (int)row;
    int m = 1;
    while (m * m < j->spp) m++;
    ct_rng g = rng_make(0x76696577u, (uint64_t)y, 0, 0);
    cam_rays cr;
    cam_rays_init(&cr, j->cam, W, H);
    for (int x = 0; x < W; x++) {
        vec3 sum = v3s(0.0f), key = v3s(0.0f);
        int same = 1;
        for (int s = 0; s < j->spp; s++) {
            float px = (float)x + (j->spp == 1 ? 0.5f : ((float)(s % m) + rng_float(&g)) / (float)m);
            float py = (float)y + (j->spp == 1 ? 0.5f : ((float)((s / m) % m) + rng_float(&g)) / (float)m);
            vec3 d = cam_rays_dir(&cr, px, py);
            struct RTCIntersectContext ctx;
            rtcInitIntersectContext(&ctx);
            struct RTCRayHit rh;
            memset(&rh, 0, sizeof rh);
            rh.ray.org_x = j->cam->eye.x;
            rh.ray.org_y = j->cam->eye.y;
            rh.ray.org_z = j->cam->eye.z;
            rh.ray.dir_x = d.x;
            rh.ray.dir_y = d.y;
            rh.ray.dir_z = d.z;
            rh.ray.tfar = INFINITY;
            rh.ray.mask = 0xFFFFFFFFu;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(j->scn, &ctx, &rh);
            vec3 att = v3s(1.0f);
            for (int k = 0; rh.hit.geomID != RTC_INVALID_GEOMETRY_ID; k++) {
                uint32_t mat = j->m->tri_mat[rh.hit.primID];
                if (!rmesh_is_glass(j->m, mat)) break;
                if (k == RMESH_MAX_GLASS_CROSSINGS) {   /* black, as the tracer */
                    att = v3s(0.0f);
                    break;
                }
                vec3 ng = v3_norm(v3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z));
                att = v3_mul(att, rmesh_glass_pass(&j->m->mats[mat], v3_dot(d, ng)));
                /* On along the same ray, just past this surface. */
                rh.ray.tnear = rh.ray.tfar * (1.0f + 1e-5f);
                rh.ray.tfar = INFINITY;
                rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                rtcIntersect1(j->scn, &ctx, &rh);
            }
            if (j->which == RAD_VIEW_PLANES) {
                vec3 k = rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? v3s(0.0f) : plane_key(j->m, rh.hit.primID, j->scale);
                if (s == 0) key = k;
                else same = same && k.x == key.x && k.y == key.y && k.z == key.z;
                continue;
            }
            if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
            vec3 v = j->which == RAD_VIEW_DIRECT ? rmesh_eval_direct(j->m, rh.hit.primID, rh.hit.u, rh.hit.v)
                                                 : rmesh_eval(j->m, rh.hit.primID, rh.hit.u, rh.hit.v);
            sum = v3_add(sum, v3_mul(att, v));
        }
        if (j->which == RAD_VIEW_PLANES) img_set(j->img, x, y, same ? key : v3s(0.0f));
        else img_set(j->img, x, y, v3_scale(sum, 1.0f / (float)j->spp));
    }
}

int rad_render_view(const ct_radmesh *m, const ct_camera *cam, int spp, int which, int threads,
                    ct_image *img, ct_error *err)
{
    if (spp < 1 || threads < 1) return ct_fail(err, CT_EINVAL, "radiosity view: spp and threads must be >= 1");
    if (m->ntris == 0) return ct_fail(err, CT_EEMPTY, "radiosity view: the mesh has no triangles");
    RTCDevice dev = rtcNewDevice(NULL);
    if (!dev) return ct_fail(err, CT_ESYS, "embree: cannot create a device (error %d)", (int)rtcGetDeviceError(NULL));
    RTCScene scn = rtcNewScene(dev);
    RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m->nverts);
    unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m->ntris);
    if (!vb || !ib) {
        rtcReleaseGeometry(g);
        rtcReleaseScene(scn);
        rtcReleaseDevice(dev);
        return ct_fail(err, CT_ENOMEM, "embree: out of memory for %u triangles", m->ntris);
    }
    for (uint32_t i = 0; i < m->nverts; i++) {
        vb[3 * i] = m->pos[i].x;
        vb[3 * i + 1] = m->pos[i].y;
        vb[3 * i + 2] = m->pos[i].z;
    }
    memcpy(ib, m->tris, (size_t)m->ntris * 3 * sizeof(unsigned));
    rtcCommitGeometry(g);
    rtcAttachGeometry(scn, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scn);
    int rc = CT_OK;
    if (rtcGetDeviceError(dev) != RTC_ERROR_NONE) {
        rc = ct_fail(err, CT_ESYS, "embree: building the view scene failed");
    } else {
        float radius = 0.0f;
        for (uint32_t i = 0; i < m->nverts; i++) radius = fmaxf(radius, v3_len(m->pos[i]));
        view_job job = {scn, m, cam, img, spp, which, radius > 0.0f ? 256.0f / radius : 1.0f};
        ct_pool *pool = NULL;
        /* Without worker threads the caller renders alone (pool NULL). */
        if (threads > 1 && pool_new(threads < POOL_MAX_THREADS ? threads : POOL_MAX_THREADS, &pool, err) != CT_OK)
            pool = NULL;
        pool_run(pool, (size_t)img->height, view_row, &job);
        pool_free(pool);
    }
    rtcReleaseScene(scn);
    rtcReleaseDevice(dev);
    return rc;
}

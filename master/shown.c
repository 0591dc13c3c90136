/* shown.c: the item buffer of the radiosity mesh (shown.h). Vertices are
 * taken to eye space and the image once; each triangle is drawn with edge
 * functions at the pixel centres it may cover (a triangle that crosses the
 * near plane is clipped in eye space first), depth compared as 1/z, which is
 * linear on the screen. */
#include "master/shown.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#if defined(__AVX__)
#include <immintrin.h>
#endif

/* Per vertex: image position, 1/z, and its eye-space coordinates. */
typedef struct vtx {
    float sx, sy, iz;
    float xe, ye, ze;
} vtx;

struct shown_buf {
    const ct_radmesh *mesh;   /* the mesh znear was measured on */
    float znear;
    vtx *v;
    uint32_t vcap;
    float *iz;                /* per task: 1/z of the nearest triangle (0: none) */
    uint32_t *tri;            /* per task: that triangle */
    size_t plane_cap;         /* pixels * tasks allocated */
};

typedef struct job {
    const ct_radmesh *m;
    shown_buf *b;
    int w, h;
    size_t npx;
    size_t stride;            /* of one task's planes: npx and room for a vector past the last pixel */
    int ntasks;
    vec3 eye, r, u, f;
    float tw, th;
    uint32_t none;
    uint32_t *out;
} job;

enum { VERTS_PER_TASK = 8192, ROWS_PER_TASK = 16, LANES = 8 };

/* Triangles are drawn in at most this many groups, each into its own depth
 * and triangle planes (merged by rows after): a plane per thread of a
 * many-core master would take 8 bytes a pixel each (half a GiB at 1024²
 * on 64 threads) for a pass of tens of milliseconds. */
enum { MAX_PLANES = 4 };

static int planes_for(int threads) { return threads < 1 ? 1 : threads > MAX_PLANES ? MAX_PLANES : threads; }

void shown_buf_free(shown_buf *b)
{
    if (!b) return;
    free(b->v);
    free(b->iz);
    free(b->tri);
    free(b);
}

static vtx project(const job *j, float xe, float ye, float ze)
{
    vtx o = {0, 0, 0, xe, ye, ze};
    if (ze > 0.0f) {
        o.iz = 1.0f / ze;
        o.sx = 0.5f * (xe * o.iz / j->tw + 1.0f) * (float)j->w;
        o.sy = 0.5f * (1.0f - ye * o.iz / j->th) * (float)j->h;
    }
    return o;
}

static void vertex_task(void *ctx, int worker, size_t task)
{
    (void)worker;
    const job *j = ctx;
    size_t a = task * VERTS_PER_TASK, e = a + VERTS_PER_TASK < j->m->nverts ? a + VERTS_PER_TASK : j->m->nverts;
    for (size_t i = a; i < e; i++) {
        vec3 d = v3_sub(j->m->pos[i], j->eye);
        j->b->v[i] = project(j, v3_dot(d, j->r), v3_dot(d, j->u), v3_dot(d, j->f));
    }
}

static inline float edge(float ax, float ay, float bx, float by, float px, float py)
{
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
}

/* Draws screen triangle a, b, c (both sides) as triangle t into one task's
 * planes; a nearer or equal-depth earlier triangle keeps its pixel. */
static void draw(const job *j, float *izp, uint32_t *trip, const vtx *a, const vtx *b, const vtx *c, uint32_t t)
{
    float minx = fminf(a->sx, fminf(b->sx, c->sx)), maxx = fmaxf(a->sx, fmaxf(b->sx, c->sx));
    float miny = fminf(a->sy, fminf(b->sy, c->sy)), maxy = fmaxf(a->sy, fmaxf(b->sy, c->sy));
    /* pixel centres x + 0.5 inside [minx, maxx] */
    float fx0 = ceilf(minx - 0.5f), fx1 = floorf(maxx - 0.5f);
    float fy0 = ceilf(miny - 0.5f), fy1 = floorf(maxy - 0.5f);
    if (!(fx0 <= fx1 && fy0 <= fy1)) return;   /* covers no centre (or NaN) */
    if (fx0 < 0.0f) fx0 = 0.0f;
    if (fy0 < 0.0f) fy0 = 0.0f;
    if (fx1 > (float)(j->w - 1)) fx1 = (float)(j->w - 1);
    if (fy1 > (float)(j->h - 1)) fy1 = (float)(j->h - 1);
    if (fx0 > fx1 || fy0 > fy1) return;
    float area = edge(a->sx, a->sy, b->sx, b->sy, c->sx, c->sy);
    if (area == 0.0f || !isfinite(area)) return;
    float inv = 1.0f / area;   /* its sign makes either winding count */
    int x0 = (int)fx0, x1 = (int)fx1, y0 = (int)fy0, y1 = (int)fy1;
    /* Barycentric weights are linear along a row: evaluated at the row's
     * first centre of the bounding box, then at x0 + k by one multiply-add
     * per pixel (the same values whatever the task). */
    float d0 = (c->sy - b->sy) * -inv, d1 = (a->sy - c->sy) * -inv, d2 = (b->sy - a->sy) * -inv;
    float diz = d0 * a->iz + d1 * b->iz + d2 * c->iz;
    for (int y = y0; y <= y1; y++) {
        float py = (float)y + 0.5f, px = (float)x0 + 0.5f;
        float w0 = edge(b->sx, b->sy, c->sx, c->sy, px, py) * inv;
        float w1 = edge(c->sx, c->sy, a->sx, a->sy, px, py) * inv;
        float w2 = edge(a->sx, a->sy, b->sx, b->sy, px, py) * inv;
        float iz = w0 * a->iz + w1 * b->iz + w2 * c->iz;
        float *zr = izp + (size_t)y * (size_t)j->w;
        uint32_t *tr = trip + (size_t)y * (size_t)j->w;
        int x = x0;
#if defined(__AVX__)
        /* Eight pixels at a time, blended: lanes past x1 keep what they
         * hold (they lie in this row, the next one, or the plane's padding,
         * all this task's own). */
        const __m256 lane = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7), zero = _mm256_setzero_ps();
        const __m256 vw0 = _mm256_set1_ps(w0), vw1 = _mm256_set1_ps(w1), vw2 = _mm256_set1_ps(w2);
        const __m256 vd0 = _mm256_set1_ps(d0), vd1 = _mm256_set1_ps(d1), vd2 = _mm256_set1_ps(d2);
        const __m256 viz = _mm256_set1_ps(iz), vdiz = _mm256_set1_ps(diz), vlast = _mm256_set1_ps((float)(x1 - x0));
        const __m256 vt = _mm256_castsi256_ps(_mm256_set1_epi32((int)t));
        for (; x <= x1; x += LANES) {
            __m256 k = _mm256_add_ps(_mm256_set1_ps((float)(x - x0)), lane);
            __m256 e0 = _mm256_add_ps(vw0, _mm256_mul_ps(k, vd0));
            __m256 e1 = _mm256_add_ps(vw1, _mm256_mul_ps(k, vd1));
            __m256 e2 = _mm256_add_ps(vw2, _mm256_mul_ps(k, vd2));
            __m256 z = _mm256_add_ps(viz, _mm256_mul_ps(k, vdiz));
            __m256 old = _mm256_loadu_ps(zr + x);
            __m256 in = _mm256_and_ps(_mm256_and_ps(_mm256_cmp_ps(e0, zero, _CMP_GE_OQ), _mm256_cmp_ps(e1, zero, _CMP_GE_OQ)),
                                      _mm256_and_ps(_mm256_cmp_ps(e2, zero, _CMP_GE_OQ), _mm256_cmp_ps(z, old, _CMP_GT_OQ)));
            in = _mm256_and_ps(in, _mm256_cmp_ps(k, vlast, _CMP_LE_OQ));
            if (_mm256_testz_ps(in, in)) continue;
            _mm256_storeu_ps(zr + x, _mm256_blendv_ps(old, z, in));
            __m256 ot = _mm256_loadu_ps((const float *)(const void *)(tr + x));
            _mm256_storeu_ps((float *)(void *)(tr + x), _mm256_blendv_ps(ot, vt, in));
        }
#else
        for (; x <= x1; x++) {
            float k = (float)(x - x0);
            float e0 = w0 + k * d0, e1 = w1 + k * d1, e2 = w2 + k * d2, z = iz + k * diz;
            if (e0 >= 0.0f && e1 >= 0.0f && e2 >= 0.0f && z > zr[x]) {
                zr[x] = z;
                tr[x] = t;
            }
        }
#endif
    }
}

/* A triangle with vertices behind the near plane: clipped in eye space
 * (at most four vertices remain), then drawn as a fan. */
static void draw_clipped(const job *j, float *izp, uint32_t *trip, const vtx *in[3], uint32_t t)
{
    float zn = j->b->znear;
    vtx poly[4];
    int n = 0;
    for (int k = 0; k < 3; k++) {
        const vtx *p = in[k], *q = in[(k + 1) % 3];
        int pin = p->ze >= zn, qin = q->ze >= zn;
        if (pin) poly[n++] = *p;
        if (pin != qin && n < 4) {
            float s = (zn - p->ze) / (q->ze - p->ze);
            poly[n++] = project(j, p->xe + s * (q->xe - p->xe), p->ye + s * (q->ye - p->ye), zn);
        }
    }
    for (int k = 1; k + 1 < n; k++) draw(j, izp, trip, &poly[0], &poly[k], &poly[k + 1], t);
}

static void raster_task(void *ctx, int worker, size_t task)
{
    (void)worker;
    const job *j = ctx;
    float *izp = j->b->iz + task * j->stride;
    uint32_t *trip = j->b->tri + task * j->stride;
    memset(izp, 0, j->stride * sizeof *izp);   /* the padding too: vector loads read it */
    uint32_t nt = j->m->ntris, per = (uint32_t)(((uint64_t)nt + (uint64_t)j->ntasks - 1) / (uint64_t)j->ntasks);
    uint32_t t0 = (uint32_t)task * per, t1 = t0 + per < nt ? t0 + per : nt;
    float zn = j->b->znear;
    for (uint32_t t = t0; t < t1; t++) {
        const uint32_t *ix = &j->m->tris[3 * (size_t)t];
        const vtx *v[3] = {&j->b->v[ix[0]], &j->b->v[ix[1]], &j->b->v[ix[2]]};
        int front = (v[0]->ze >= zn) + (v[1]->ze >= zn) + (v[2]->ze >= zn);
        if (front == 3) draw(j, izp, trip, v[0], v[1], v[2], t);
        else if (front > 0) draw_clipped(j, izp, trip, v, t);
    }
}

static void merge_task(void *ctx, int worker, size_t task)
{
    (void)worker;
    const job *j = ctx;
    size_t a = task * ROWS_PER_TASK * (size_t)j->w, e = a + ROWS_PER_TASK * (size_t)j->w;
    if (e > j->npx) e = j->npx;
    for (size_t i = a; i < e; i++) {
        float best = 0.0f;
        uint32_t bt = UINT32_MAX;
        for (int k = 0; k < j->ntasks; k++) {
            float iz = j->b->iz[(size_t)k * j->stride + i];
            uint32_t t = j->b->tri[(size_t)k * j->stride + i];
            if (iz > best || (iz == best && iz > 0.0f && t < bt)) {
                best = iz;
                bt = t;
            }
        }
        j->out[i] = bt == UINT32_MAX ? j->none : j->m->tri_node[bt];
    }
}

uint64_t shown_bytes(int width, int height, int threads)
{
    uint64_t stride = (uint64_t)width * (uint64_t)height + LANES;
    return stride * (uint64_t)planes_for(threads) * (sizeof(float) + sizeof(uint32_t));
}

int shown_render(const ct_radmesh *m, const ct_camera *cam, int width, int height, ct_pool *pool, shown_buf **bp,
                 uint32_t none, uint32_t *out, ct_error *err)
{
    if (!*bp && !(*bp = calloc(1, sizeof **bp))) return ct_fail(err, CT_ENOMEM, "out of memory for the item buffer");
    shown_buf *b = *bp;
    job j = {.m = m, .b = b, .w = width, .h = height, .npx = (size_t)width * (size_t)height,
             .ntasks = planes_for(pool_threads(pool)), .eye = cam->eye, .none = none, .out = out};
    if (m->ntris < (uint32_t)j.ntasks * 64u) j.ntasks = 1;   /* not worth a plane each */
    if (b->mesh != m) {
        bounds3 bb = b3_empty();
        for (uint32_t i = 0; i < m->nverts; i++) bb = b3_add(bb, m->pos[i]);
        /* The display's near plane (CT_NEAR_SHARE): depth is compared as
         * 1/z in float, which keeps its relative precision at any distance.
         * At 10^-4 of the diagonal a panel 5 cm ahead in a scene 20 km wide
         * was clipped here but drawn there (test_shown). */
        b->znear = m->nverts ? CT_NEAR_SHARE * fmaxf(v3_len(b3_extent(bb)), 1e-6f) : 1e-6f;
        b->mesh = m;
    }
    if (m->nverts > b->vcap) {
        vtx *v = realloc(b->v, (size_t)m->nverts * sizeof *v);
        if (!v) return ct_fail(err, CT_ENOMEM, "out of memory for the item buffer's %u vertices", m->nverts);
        b->v = v;
        b->vcap = m->nverts;
    }
    j.stride = j.npx + LANES;
    size_t planes = j.stride * (size_t)j.ntasks;
    if (planes > b->plane_cap) {
        free(b->iz);
        free(b->tri);
        b->iz = malloc(planes * sizeof *b->iz);
        b->tri = malloc(planes * sizeof *b->tri);
        b->plane_cap = b->iz && b->tri ? planes : 0;
        if (!b->plane_cap) return ct_fail(err, CT_ENOMEM, "out of memory for a %dx%d item buffer", width, height);
    }
    cam_axes(cam, &j.r, &j.u, &j.f);
    j.th = tanf(0.5f * cam->fov_y);
    j.tw = j.th * (float)width / (float)height;
    pool_run(pool, (m->nverts + VERTS_PER_TASK - 1) / VERTS_PER_TASK, vertex_task, &j);
    pool_run(pool, (size_t)j.ntasks, raster_task, &j);
    pool_run(pool, ((size_t)height + ROWS_PER_TASK - 1) / ROWS_PER_TASK, merge_task, &j);
    return CT_OK;
}

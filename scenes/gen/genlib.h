/* genlib.h: the small OBJ writer and shape library shared by the scene
 * generators (scenes/gen/NAME.c). Header-only with `static inline` functions so
 * every generator stays one standalone C file that needs only libc and libm
 * (the Makefile compiles scenes/gen/NAME.c alone): that is also why it is
 * over 600 lines.
 *
 * Conventions: y is up; shapes are built in local coordinates and placed by
 * the current transform (gen_push/gen_pop). Every polygon is written with
 * vertex normals, and its winding is made to agree with them (counter-
 * clockwise seen from the side the normals point to), so front faces and
 * normals never disagree. Output files are written to a temporary name and
 * renamed when complete. All output is a pure function of the generator's
 * code: no clock, no environment, a fixed-seed random generator. */
#ifndef CT_GENLIB_H
#define CT_GENLIB_H

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* --- vectors and rigid transforms ----------------------------------------- */

typedef struct gv3 { double x, y, z; } gv3;

static inline gv3 g3(double x, double y, double z) { gv3 v = {x, y, z}; return v; }
static inline gv3 gadd(gv3 a, gv3 b) { return g3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline gv3 gsub(gv3 a, gv3 b) { return g3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline gv3 gmul(gv3 a, double s) { return g3(a.x * s, a.y * s, a.z * s); }
static inline double gdot(gv3 a, gv3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline gv3 gcross(gv3 a, gv3 b)
{
    return g3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double glen(gv3 a) { return sqrt(gdot(a, a)); }
static inline gv3 gnorm(gv3 a)
{
    double l = glen(a);
    return l > 0 ? gmul(a, 1.0 / l) : g3(0, 1, 0);
}

/* Rotation (columns = images of the local axes) plus translation. */
typedef struct gxf { gv3 ax, ay, az, t; } gxf;

static inline gxf gxf_identity(void)
{
    gxf m = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, 0}};
    return m;
}
static inline gv3 gxf_dir(const gxf *m, gv3 d)
{
    return gadd(gadd(gmul(m->ax, d.x), gmul(m->ay, d.y)), gmul(m->az, d.z));
}
static inline gv3 gxf_point(const gxf *m, gv3 p) { return gadd(gxf_dir(m, p), m->t); }
/* a then b: the transform that applies b first, then a. */
static inline gxf gxf_mul(const gxf *a, const gxf *b)
{
    gxf m;
    m.ax = gxf_dir(a, b->ax);
    m.ay = gxf_dir(a, b->ay);
    m.az = gxf_dir(a, b->az);
    m.t = gxf_point(a, b->t);
    return m;
}
/* Translation to t and rotation by deg degrees about +y. */
static inline gxf gxf_at(gv3 t, double yaw_deg)
{
    double a = yaw_deg * M_PI / 180.0, c = cos(a), s = sin(a);
    gxf m = {{c, 0, -s}, {0, 1, 0}, {s, 0, c}, t};
    return m;
}
/* A frame at origin whose local +y is dir (for cylinders along any axis). */
static inline gxf gxf_axis(gv3 origin, gv3 dir)
{
    gxf m;
    m.ay = gnorm(dir);
    gv3 h = fabs(m.ay.y) < 0.9 ? g3(0, 1, 0) : g3(1, 0, 0);
    m.ax = gnorm(gcross(h, m.ay));
    m.az = gcross(m.ax, m.ay);
    m.t = origin;
    return m;
}
/* Rotation by deg degrees about local +x (tilts). */
static inline gxf gxf_rotx(double deg)
{
    double a = deg * M_PI / 180.0, c = cos(a), s = sin(a);
    gxf m = {{1, 0, 0}, {0, c, s}, {0, -s, c}, {0, 0, 0}};
    return m;
}
/* Rotation by deg degrees about local +z. */
static inline gxf gxf_rotz(double deg)
{
    double a = deg * M_PI / 180.0, c = cos(a), s = sin(a);
    gxf m = {{c, s, 0}, {-s, c, 0}, {0, 0, 1}, {0, 0, 0}};
    return m;
}

/* --- deterministic random numbers (PCG32, fixed seed per generator) -------- */

typedef struct grng { uint64_t state, inc; } grng;

static inline uint32_t grng_u32(grng *r)
{
    uint64_t old = r->state;
    r->state = old * 6364136223846793005ULL + r->inc;
    uint32_t xs = (uint32_t)(((old >> 18u) ^ old) >> 27u);
    uint32_t rot = (uint32_t)(old >> 59u);
    return (xs >> rot) | (xs << ((-rot) & 31u));
}
static inline grng grng_seed(uint64_t seed, uint64_t stream)
{
    grng r = {0, (stream << 1u) | 1u};
    grng_u32(&r);
    r.state += seed;
    grng_u32(&r);
    return r;
}
/* Uniform in [a, b). */
static inline double grng_range(grng *r, double a, double b)
{
    return a + (b - a) * (grng_u32(r) / 4294967296.0);
}
/* Uniform integer in [0, n). */
static inline int grng_int(grng *r, int n) { return (int)(grng_u32(r) % (uint32_t)n); }

/* --- the OBJ writer -------------------------------------------------------- */

#define GEN_MAX_DEPTH 32

typedef struct gobj {
    FILE *f;
    char path[1024], tmp[1100];
    long nv, nvn;             /* vertices / normals written so far */
    gv3 *pos;                 /* world positions of the vertices (for winding) */
    long cap_pos;
    gv3 *nrm;                 /* world normals written */
    long cap_nrm;
    long prims, tris, quads, ngons, objects, parts;
    gxf xf;                   /* current local -> world transform */
    gxf stack[GEN_MAX_DEPTH];
    int depth;
    int failed;
} gobj;

/* Writes one printf-formatted line; remembers write errors. */
static inline void gen_printf(gobj *o, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    if (vfprintf(o->f, fmt, ap) < 0) o->failed = 1;
    va_end(ap);
}

/* Opens dir/file for writing through a temporary; header lines name the
 * generator and the material library. */
static inline int gen_open(gobj *o, const char *dir, const char *file, const char *mtllib,
                           const char *generator)
{
    memset(o, 0, sizeof *o);
    o->xf = gxf_identity();
    snprintf(o->path, sizeof o->path, "%s/%s", dir, file);
    snprintf(o->tmp, sizeof o->tmp, "%s.tmp", o->path);
    o->f = fopen(o->tmp, "w");
    if (!o->f) {
        fprintf(stderr, "error %s: cannot write %s: %s\n", generator, o->tmp, strerror(errno));
        return -1;
    }
    gen_printf(o, "# %s: generated by scenes/gen/%s.c (do not edit; run make scenes)\n", file,
               generator);
    if (mtllib) gen_printf(o, "mtllib %s\n", mtllib);
    return 0;
}

/* Closes and renames the file onto its final name; on any error removes the
 * temporary and returns -1. */
static inline int gen_close(gobj *o, const char *generator)
{
    int bad = o->failed;
    if (o->depth != 0) {
        fprintf(stderr, "error %s: %s: unbalanced transform stack\n", generator, o->path);
        bad = 1;
    }
    if (fflush(o->f) != 0 || ferror(o->f)) bad = 1;
    if (fclose(o->f) != 0) bad = 1;
    free(o->pos);
    free(o->nrm);
    o->pos = o->nrm = NULL;
    if (!bad && rename(o->tmp, o->path) != 0) bad = 1;
    if (bad) {
        fprintf(stderr, "error %s: writing %s failed: %s\n", generator, o->path, strerror(errno));
        remove(o->tmp);
        return -1;
    }
    return 0;
}

/* Starts a named object (OBJ `o`): one node of the scene hierarchy. */
static inline void gen_object(gobj *o, const char *fmt, ...)
{
    char name[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(name, sizeof name, fmt, ap);
    va_end(ap);
    gen_printf(o, "o %s\n", name);
    o->objects++;
}

/* Selects the material of the following faces (OBJ `usemtl`). */
static inline void gen_material(gobj *o, const char *name) { gen_printf(o, "usemtl %s\n", name); }

/* Pushes the current transform and composes it with m (m applied first). */
static inline void gen_push(gobj *o, gxf m)
{
    if (o->depth >= GEN_MAX_DEPTH) { o->failed = 1; return; }
    o->stack[o->depth++] = o->xf;
    o->xf = gxf_mul(&o->xf, &m);
}
static inline void gen_pop(gobj *o)
{
    if (o->depth <= 0) { o->failed = 1; return; }
    o->xf = o->stack[--o->depth];
}

/* Stores w as element n of the growing array *arr (capacity *cap); 0, or -1
 * (and o->failed set) when out of memory. */
static inline int gen_keep(gobj *o, gv3 **arr, long *cap, long n, gv3 w)
{
    if (n >= *cap) {
        long c = *cap ? *cap * 2 : 4096;
        gv3 *q = realloc(*arr, (size_t)c * sizeof *q);
        if (!q) { o->failed = 1; return -1; }
        *arr = q;
        *cap = c;
    }
    (*arr)[n] = w;
    return 0;
}

/* A vertex at local position p; returns its 1-based OBJ index. */
static inline long gen_v(gobj *o, gv3 p)
{
    gv3 w = gxf_point(&o->xf, p);
    if (gen_keep(o, &o->pos, &o->cap_pos, o->nv, w)) return 1;
    gen_printf(o, "v %.5f %.5f %.5f\n", w.x, w.y, w.z);
    return ++o->nv;
}

/* A normal along local direction n; returns its 1-based OBJ index. */
static inline long gen_vn(gobj *o, gv3 n)
{
    gv3 w = gnorm(gxf_dir(&o->xf, n));
    if (gen_keep(o, &o->nrm, &o->cap_nrm, o->nvn, w)) return 1;
    gen_printf(o, "vn %.5f %.5f %.5f\n", w.x, w.y, w.z);
    return ++o->nvn;
}

/* A face of n vertices (1-based indices) with per-corner normals. The
 * winding is reversed when its geometric normal (Newell) disagrees with the
 * corners' normals, so the front side is always the normals' side. */
static inline void gen_face(gobj *o, int n, const long *v, const long *vn)
{
    gv3 g = g3(0, 0, 0), s = g3(0, 0, 0);
    for (int i = 0; i < n; i++) {
        gv3 a = o->pos[v[i] - 1], b = o->pos[v[(i + 1) % n] - 1];
        g.x += (a.y - b.y) * (a.z + b.z);
        g.y += (a.z - b.z) * (a.x + b.x);
        g.z += (a.x - b.x) * (a.y + b.y);
        s = gadd(s, o->nrm[vn[i] - 1]);
    }
    int rev = gdot(g, s) < 0;
    gen_printf(o, "f");
    for (int k = 0; k < n; k++) {
        int i = rev ? n - 1 - k : k;
        gen_printf(o, " %ld//%ld", v[i], vn[i]);
    }
    gen_printf(o, "\n");
    o->prims++;
    if (n == 3) o->tris++;
    else if (n == 4) o->quads++;
    else o->ngons++;
}

/* A flat polygon through local points p[0..n-1] facing local normal nrm. */
static inline void gen_flat(gobj *o, int n, const gv3 *p, gv3 nrm)
{
    long v[16], vn[16];
    if (n > 16) { o->failed = 1; return; }
    long k = gen_vn(o, nrm);
    for (int i = 0; i < n; i++) {
        v[i] = gen_v(o, p[i]);
        vn[i] = k;
    }
    gen_face(o, n, v, vn);
}

/* A flat quad with corners c, c+e1, c+e1+e2, c+e2 facing the side `facing`
 * points to. */
static inline void gen_quad(gobj *o, gv3 c, gv3 e1, gv3 e2, gv3 facing)
{
    gv3 p[4] = {c, gadd(c, e1), gadd(gadd(c, e1), e2), gadd(c, e2)};
    gv3 n = gnorm(gcross(e1, e2));
    if (gdot(n, facing) < 0) n = gmul(n, -1);
    gen_flat(o, 4, p, n);
}

/* Faces of a box, for leaving out hidden ones. */
enum {
    GEN_XN = 1, GEN_XP = 2, GEN_YN = 4, GEN_YP = 8, GEN_ZN = 16, GEN_ZP = 32,
    GEN_ALL = 63, GEN_NOBOTTOM = 63 & ~4
};

/* An axis-aligned (in local coordinates) box [lo, hi]; faces selects which of
 * its six quads to write (outward normals, 8 shared corners). */
static inline void gen_box(gobj *o, gv3 lo, gv3 hi, int faces)
{
    long c[8];
    for (int i = 0; i < 8; i++)
        c[i] = gen_v(o, g3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z));
    static const int quad[6][4] = {
        {0, 2, 6, 4}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 5, 7, 6}};
    static const double dir[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    for (int f = 0; f < 6; f++) {
        if (!(faces & (1 << f))) continue;
        long n = gen_vn(o, g3(dir[f][0], dir[f][1], dir[f][2]));
        long v[4] = {c[quad[f][0]], c[quad[f][1]], c[quad[f][2]], c[quad[f][3]]};
        long vn[4] = {n, n, n, n};
        gen_face(o, 4, v, vn);
    }
}

/* Number of primitives gen_box writes for a face mask. */
static inline int gen_box_prims(int faces)
{
    int n = 0;
    for (int f = 0; f < 6; f++) n += (faces >> f) & 1;
    return n;
}

/* A surface of revolution about local +y: the profile (r[i], y[i]), i < m,
 * swept through `segs` steps. Walk the profile with the solid on the left
 * (outer surfaces bottom to top, inner ones top to bottom); normals point to
 * the right of that walk. Points with r == 0 are on the axis and close the
 * surface with triangles; everything else gives quads. Normals are smooth
 * where consecutive profile segments meet at less than crease_deg, split
 * otherwise. Returns the number of primitives written. */
static inline long gen_lathe(gobj *o, int m, const double *r, const double *y, int segs,
                             double crease_deg)
{
    long before = o->prims;
    if (m < 2 || segs < 3 || m > 4096) { o->failed = 1; return 0; }
    /* segment normals in the (r, y) plane */
    double sn[4096][2];
    for (int i = 0; i + 1 < m; i++) {
        double dr = r[i + 1] - r[i], dy = y[i + 1] - y[i];
        double l = sqrt(dr * dr + dy * dy);
        sn[i][0] = l > 0 ? dy / l : 0;
        sn[i][1] = l > 0 ? -dr / l : 1;
    }
    double cosc = cos(crease_deg * M_PI / 180.0);
    /* position rings and normal rings: for each profile point the normal
     * used by the segment before it (in) and after it (out) */
    long *pv = malloc((size_t)m * sizeof *pv);
    long *nin = malloc((size_t)m * sizeof *nin), *nout = malloc((size_t)m * sizeof *nout);
    if (!pv || !nin || !nout) { free(pv); free(nin); free(nout); o->failed = 1; return 0; }
    for (int i = 0; i < m; i++) {
        int axis = r[i] <= 0.0;
        pv[i] = o->nv + 1;
        if (axis) {
            gen_v(o, g3(0, y[i], 0));
        } else {
            for (int j = 0; j < segs; j++) {
                double a = 2 * M_PI * j / segs;
                gen_v(o, g3(r[i] * cos(a), y[i], r[i] * sin(a)));
            }
        }
        double a2[2][2];
        int na = 0;
        if (i > 0) { a2[na][0] = sn[i - 1][0]; a2[na][1] = sn[i - 1][1]; na++; }
        if (i + 1 < m) { a2[na][0] = sn[i][0]; a2[na][1] = sn[i][1]; na++; }
        int split = na == 2 && a2[0][0] * a2[1][0] + a2[0][1] * a2[1][1] < cosc;
        for (int side = 0; side < (split ? 2 : 1); side++) {
            double nr, ny;
            if (split) { nr = a2[side][0]; ny = a2[side][1]; }
            else if (na == 2) { nr = a2[0][0] + a2[1][0]; ny = a2[0][1] + a2[1][1]; }
            else { nr = a2[0][0]; ny = a2[0][1]; }
            double l = sqrt(nr * nr + ny * ny);
            if (l <= 0) { nr = 0; ny = 1; l = 1; }
            nr /= l; ny /= l;
            long first = o->nvn + 1;
            if (axis) {
                gen_vn(o, g3(0, ny >= 0 ? 1 : -1, 0));
            } else {
                for (int j = 0; j < segs; j++) {
                    double a = 2 * M_PI * j / segs;
                    gen_vn(o, g3(nr * cos(a), ny, nr * sin(a)));
                }
            }
            if (side == 0) nin[i] = nout[i] = first;
            else nout[i] = first;
        }
    }
    for (int i = 0; i + 1 < m; i++) {
        int a0 = r[i] <= 0.0, a1 = r[i + 1] <= 0.0;
        if (a0 && a1) continue;
        for (int j = 0; j < segs; j++) {
            int j1 = (j + 1) % segs;
            long v[4], vn[4];
            int n = 0;
            if (a0) { v[n] = pv[i]; vn[n++] = nout[i]; }
            else {
                v[n] = pv[i] + j; vn[n++] = nout[i] + j;
                v[n] = pv[i] + j1; vn[n++] = nout[i] + j1;
            }
            if (a1) { v[n] = pv[i + 1]; vn[n++] = nin[i + 1]; }
            else {
                v[n] = pv[i + 1] + j1; vn[n++] = nin[i + 1] + j1;
                v[n] = pv[i + 1] + j; vn[n++] = nin[i + 1] + j;
            }
            gen_face(o, n, v, vn);
        }
    }
    free(pv);
    free(nin);
    free(nout);
    return o->prims - before;
}

/* Primitives gen_lathe writes for a profile (for expected counts). */
static inline long gen_lathe_prims(int m, const double *r, int segs)
{
    long n = 0;
    for (int i = 0; i + 1 < m; i++)
        if (!(r[i] <= 0.0 && r[i + 1] <= 0.0)) n += segs;
    return n;
}

/* A closed cylinder of radius rad from local y0 to y1 (flat caps). */
static inline void gen_cylinder(gobj *o, double rad, double y0, double y1, int segs)
{
    double r[4] = {0, rad, rad, 0}, y[4] = {y0, y0, y1, y1};
    gen_lathe(o, 4, r, y, segs, 45);
}

/* A closed cylinder from local point a to b. */
static inline void gen_rod(gobj *o, gv3 a, gv3 b, double rad, int segs)
{
    gen_push(o, gxf_axis(a, gsub(b, a)));
    gen_cylinder(o, rad, 0, glen(gsub(b, a)), segs);
    gen_pop(o);
}

/* A sphere of radius rad centred at local c: `stacks` bands, `slices`
 * around; smooth radial normals (the averaged chord normals of a regular
 * profile are radial by symmetry). */
static inline void gen_sphere(gobj *o, gv3 c, double rad, int stacks, int slices)
{
    double r[256], y[256];
    if (stacks > 255) { o->failed = 1; return; }
    for (int i = 0; i <= stacks; i++) {
        double a = -M_PI / 2 + M_PI * i / stacks;
        r[i] = i == 0 || i == stacks ? 0.0 : rad * cos(a);
        y[i] = rad * sin(a);
    }
    gen_push(o, gxf_at(c, 0));
    gen_lathe(o, stacks + 1, r, y, slices, 90);
    gen_pop(o);
}

/* An object `name`: a ceiling light of w x d centred at (x, z): a housing
 * box of material `housing`, 3 cm wider on each side, from y0 up to the
 * ceiling at y1 (no top face), and an emissive quad of material `panel` at
 * height y facing down. */
static inline void gen_ceiling_light(gobj *o, const char *name, const char *housing, const char *panel, double x,
                                     double z, double w, double d, double y0, double y1, double y)
{
    gen_object(o, "%s", name);
    gen_material(o, housing);
    gen_box(o, g3(x - w / 2 - 0.03, y0, z - d / 2 - 0.03), g3(x + w / 2 + 0.03, y1, z + d / 2 + 0.03),
            GEN_ALL & ~GEN_YP);
    gen_material(o, panel);
    gen_quad(o, g3(x - w / 2, y, z - d / 2), g3(w, 0, 0), g3(0, 0, d), g3(0, -1, 0));
}

/* --- lathe profiles -------------------------------------------------------- */

#define GEN_PROF_MAX 1024

/* A profile in the (r, y) half-plane under construction. */
typedef struct gprof { double r[GEN_PROF_MAX], y[GEN_PROF_MAX]; int n; } gprof;

/* Appends a point (r < 0 is clamped to the axis). */
static inline void prof_add(gprof *p, double r, double y)
{
    if (p->n >= GEN_PROF_MAX) return;
    p->r[p->n] = r > 0 ? r : 0;
    p->y[p->n] = y;
    p->n++;
}

/* Appends a Catmull-Rom curve through control points c[0..nc-1] (r, y),
 * `steps` points per span; the first control point is included. */
static inline void prof_spline(gprof *p, const double (*c)[2], int nc, int steps)
{
    for (int i = 0; i + 1 < nc; i++) {
        const double *p0 = c[i > 0 ? i - 1 : 0], *p1 = c[i], *p2 = c[i + 1];
        const double *p3 = c[i + 2 < nc ? i + 2 : nc - 1];
        for (int k = 0; k < steps; k++) {
            double t = (double)k / steps, t2 = t * t, t3 = t2 * t;
            double v[2];
            for (int d = 0; d < 2; d++)
                v[d] = 0.5 * (2 * p1[d] + (-p0[d] + p2[d]) * t +
                              (2 * p0[d] - 5 * p1[d] + 4 * p2[d] - p3[d]) * t2 +
                              (-p0[d] + 3 * p1[d] - 3 * p2[d] + p3[d]) * t3);
            prof_add(p, v[0], v[1]);
        }
    }
    prof_add(p, c[nc - 1][0], c[nc - 1][1]);
}

/* Sweeps a profile (see gen_lathe). */
static inline long gen_prof(gobj *o, const gprof *p, int segs, double crease_deg)
{
    return gen_lathe(o, p->n, p->r, p->y, segs, crease_deg);
}

/* Sweeps the profile through the points (r, y) * scale, i < n (see
 * prof_add and gen_lathe). */
static inline long gen_prof_points(gobj *o, const double (*pts)[2], int n, double scale, int segs,
                                   double crease_deg)
{
    gprof p = {{0}, {0}, 0};
    for (int i = 0; i < n; i++) prof_add(&p, pts[i][0] * scale, pts[i][1] * scale);
    return gen_prof(o, &p, segs, crease_deg);
}

/* --- counts manifest ------------------------------------------------------- */

/* What a generator wrote, summed over its files: the tests compare the
 * loaded scene against these independent counts (NAME.counts). */
typedef struct gcounts { long files, objects, prims, quads, tris, ngons; } gcounts;

/* Adds one finished file's counts (call before gen_close). */
static inline void gen_count(gcounts *c, const gobj *o)
{
    c->files++;
    c->objects += o->objects;
    c->prims += o->prims;
    c->quads += o->quads;
    c->tris += o->tris;
    c->ngons += o->ngons;
}

/* Writes text to dir/file atomically (temporary + rename); one error line
 * naming the file on failure. */
static inline int gen_write_file(const char *dir, const char *file, const char *generator,
                                 const char *text)
{
    char path[1024], tmp[1100];
    snprintf(path, sizeof path, "%s/%s", dir, file);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    FILE *f = fopen(tmp, "w");
    if (!f) {
        fprintf(stderr, "error %s: cannot write %s: %s\n", generator, tmp, strerror(errno));
        return -1;
    }
    fputs(text, f);
    int bad = ferror(f) != 0;
    if (fclose(f) != 0) bad = 1;
    if (bad || rename(tmp, path) != 0) {
        fprintf(stderr, "error %s: writing %s failed\n", generator, path);
        remove(tmp);
        return -1;
    }
    return 0;
}

/* Writes dir/name.counts atomically: one "key value" line per count. */
static inline int gen_write_counts(const char *dir, const char *name, const gcounts *c)
{
    char file[256], text[1024];
    snprintf(file, sizeof file, "%s.counts", name);
    snprintf(text, sizeof text,
             "# %s.counts: what scenes/gen/%s.c wrote (input polygons; run make scenes)\n"
             "files %ld\nobjects %ld\nprimitives %ld\nquads %ld\ntriangles %ld\nngons %ld\n",
             name, name, c->files, c->objects, c->prims, c->quads, c->tris, c->ngons);
    return gen_write_file(dir, file, name, text);
}

/* --- materials and the generator's frame ----------------------------------- */

/* The mirror and glass every scene defines alike (the scene's JSON may
 * refine them by name): the last entries of an MTL body. */
#define GEN_MTL_MIRROR_GLASS \
    "newmtl mirror\nKd 0 0 0\nKs 0.95 0.95 0.95\nillum 3\n\n" \
    "newmtl glass\nKd 0 0 0\nKs 1 1 1\nNi 1.5\nd 0\nTf 1 1 1\nillum 7\n"

/* The six book cover colours the bookshelves of table and office share
 * (book_red, book_blue, book_green, book_cream, book_brown, book_black). */
#define GEN_MTL_BOOKS \
    "newmtl book_red\nKd 0.5 0.08 0.07\n\n" \
    "newmtl book_blue\nKd 0.08 0.14 0.4\n\n" \
    "newmtl book_green\nKd 0.1 0.3 0.12\n\n" \
    "newmtl book_cream\nKd 0.75 0.7 0.55\n\n" \
    "newmtl book_brown\nKd 0.35 0.2 0.1\n\n" \
    "newmtl book_black\nKd 0.06 0.06 0.06\n\n"

/* Writes dir/GENERATOR.mtl atomically: a header line naming the generator,
 * then body (the newmtl entries). */
static inline int gen_write_mtl(const char *dir, const char *generator, const char *body)
{
    char file[256];
    snprintf(file, sizeof file, "%s.mtl", generator);
    const char *fmt = "# %s: generated by scenes/gen/%s.c (do not edit; run make scenes)\n%s";
    size_t n = strlen(fmt) + strlen(file) + strlen(generator) + strlen(body) + 1;
    char *text = malloc(n);
    if (!text) {
        fprintf(stderr, "error %s: out of memory writing %s\n", generator, file);
        return -1;
    }
    snprintf(text, n, fmt, file, generator, body);
    int rc = gen_write_file(dir, file, generator, text);
    free(text);
    return rc;
}

/* The output folder from the command line (GENERATOR OUTDIR), or NULL after
 * printing the usage line. */
static inline const char *gen_outdir(int argc, char **argv, const char *generator)
{
    if (argc != 2) {
        fprintf(stderr, "usage: %s OUTDIR\n", generator);
        return NULL;
    }
    return argv[1];
}

/* Ends a generator that writes one OBJ file: closes it, then writes the
 * material library (write_mtl) and GENERATOR.counts. 0 or -1. */
static inline int gen_finish(gobj *o, const char *dir, const char *generator,
                             int (*write_mtl)(const char *dir))
{
    gcounts c = {0, 0, 0, 0, 0, 0};
    gen_count(&c, o);
    if (gen_close(o, generator) || write_mtl(dir) || gen_write_counts(dir, generator, &c)) return -1;
    return 0;
}

#endif

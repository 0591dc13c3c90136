#include "tests/support/testscenes.h"

#include <math.h>

static int add_quad(ct_scene *s, vec3 a, vec3 b, vec3 c, vec3 d, ct_error *err)
{
    vec3 n = v3_norm(v3_cross(v3_sub(b, a), v3_sub(d, a)));
    uint32_t idx[4];
    vec3 p[4] = {a, b, c, d};
    for (int i = 0; i < 4; i++) {
        int64_t v = scene_add_vertex(s, p[i], n, err);
        if (v < 0) return (int)v;
        idx[i] = (uint32_t)v;
    }
    return scene_add_polygon(s, idx, 4, err);
}

int ts_quad(ct_scene *s, const char *name, uint32_t mat, vec3 c, vec3 e1, vec3 e2, ct_error *err)
{
    int node = scene_begin_node(s, name, SCENE_NODE_PART, mat, err);
    if (node < 0) return node;
    int rc = add_quad(s, c, v3_add(c, e1), v3_add(v3_add(c, e1), e2), v3_add(c, e2), err);
    if (rc) return rc;
    rc = scene_end_node(s, err);
    return rc ? rc : node;
}

int ts_box(ct_scene *s, const char *name, uint32_t mat, vec3 lo, vec3 hi, bool inward, ct_error *err)
{
    int node = scene_begin_node(s, name, SCENE_NODE_PART, mat, err);
    if (node < 0) return node;
    vec3 c[8];
    for (int i = 0; i < 8; i++) c[i] = b3_corner((bounds3){lo, hi}, i);
    /* Faces listed counter-clockwise seen from outside (outward normals). */
    static const int f[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (int k = 0; k < 6; k++) {
        int rc = inward ? add_quad(s, c[f[k][3]], c[f[k][2]], c[f[k][1]], c[f[k][0]], err)
                        : add_quad(s, c[f[k][0]], c[f[k][1]], c[f[k][2]], c[f[k][3]], err);
        if (rc) return rc;
    }
    int rc = scene_end_node(s, err);
    return rc ? rc : node;
}

static vec3 sph(vec3 o, float r, int i, int nu, int j, int nv)
{
    float th = CT_PI * (float)j / (float)nv, ph = 2.0f * CT_PI * (float)i / (float)nu;
    return v3(o.x + r * sinf(th) * cosf(ph), o.y + r * cosf(th), o.z + r * sinf(th) * sinf(ph));
}

int ts_sphere(ct_scene *s, const char *name, uint32_t mat, vec3 centre, float radius, int nu, int nv,
              bool inward, ct_error *err)
{
    int node = scene_begin_node(s, name, SCENE_NODE_PART, mat, err);
    if (node < 0) return node;
    for (int j = 0; j < nv; j++)
        for (int i = 0; i < nu; i++) {
            vec3 p[4] = {sph(centre, radius, i, nu, j, nv), sph(centre, radius, i, nu, j + 1, nv),
                         sph(centre, radius, i + 1, nu, j + 1, nv), sph(centre, radius, i + 1, nu, j, nv)};
            /* Split into two triangles; pole quads degenerate to one. */
            for (int t = 0; t < 2; t++) {
                vec3 a = p[0], b = t ? p[2] : p[1], c = t ? p[3] : p[2];
                vec3 n = v3_cross(v3_sub(b, a), v3_sub(c, a));
                if (v3_len2(n) <= 1e-12f * radius * radius * radius * radius) continue;
                /* Wind so the front side faces out (or in) of the centre. */
                vec3 mid = v3_scale(v3_add(a, v3_add(b, c)), 1.0f / 3.0f);
                if ((v3_dot(n, v3_sub(mid, centre)) < 0.0f) != inward) {
                    vec3 x = b; b = c; c = x;
                    n = v3_neg(n);
                }
                n = v3_norm(n);
                uint32_t idx[3];
                vec3 q[3] = {a, b, c};
                for (int k = 0; k < 3; k++) {
                    int64_t v = scene_add_vertex(s, q[k], n, err);
                    if (v < 0) return (int)v;
                    idx[k] = (uint32_t)v;
                }
                int rc = scene_add_polygon(s, idx, 3, err);
                if (rc) return rc;
            }
        }
    int rc = scene_end_node(s, err);
    return rc ? rc : node;
}

int ts_smooth_sphere(ct_scene *s, const char *name, uint32_t mat, vec3 centre, float radius, int nu, int nv,
                     ct_error *err)
{
    int node = scene_begin_node(s, name, SCENE_NODE_PART, mat, err);
    if (node < 0) return node;
    uint32_t base = s->nverts;
    for (int j = 0; j <= nv; j++)
        for (int i = 0; i < nu; i++) {
            vec3 p = sph(centre, radius, i, nu, j, nv);
            int64_t v = scene_add_vertex(s, p, v3_norm(v3_sub(p, centre)), err);
            if (v < 0) return (int)v;
        }
    for (int j = 0; j < nv; j++)
        for (int i = 0; i < nu; i++) {
            uint32_t a = base + (uint32_t)(j * nu + i), b = base + (uint32_t)(j * nu + (i + 1) % nu);
            /* counter-clockwise seen from outside: j runs down from the
             * north pole, i east */
            uint32_t q[4] = {a, b, b + (uint32_t)nu, a + (uint32_t)nu};
            /* the poles' quads have two corners in one place: triangles */
            uint32_t t[3] = {a, j == 0 ? q[2] : b, q[3]};
            int rc = j == 0 || j == nv - 1 ? scene_add_polygon(s, t, 3, err) : scene_add_polygon(s, q, 4, err);
            if (rc) return rc;
        }
    int rc = scene_end_node(s, err);
    return rc ? rc : node;
}

int ts_diffuse(ct_scene *s, const char *name, vec3 rho, vec3 le, ct_error *err)
{
    scene_material m = scene_material_default(name);
    m.diffuse = rho;
    m.emission = le;
    return scene_add_material(s, &m, err);
}

int ts_glass(ct_scene *s, const char *name, float ior, vec3 transmission, ct_error *err)
{
    scene_material m = scene_material_default(name);
    m.dielectric = 1;
    m.ior = ior;
    m.transmission = transmission;
    return scene_add_material(s, &m, err);
}

ct_scene *ts_room(ct_error *err)
{
    ct_scene *s = scene_new("room");
    if (!s) {
        ct_fail(err, CT_ENOMEM, "out of memory");
        return NULL;
    }
    scene_material ward = scene_material_default("brushed");
    ward.diffuse = v3(0.2f, 0.1f, 0.05f);
    ward.glossy = SCENE_GLOSSY_WARD;
    ward.specular = v3s(0.6f);
    ward.ward_ax = 0.05f;
    ward.ward_ay = 0.3f;
    ward.ward_tangent = v3(1, 0, 0);
    scene_material phong = scene_material_default("plastic");
    phong.diffuse = v3(0.1f, 0.4f, 0.1f);
    phong.glossy = SCENE_GLOSSY_PHONG;
    phong.specular = v3s(0.4f);
    phong.phong_exp = 50.0f;
    scene_material mirror = scene_material_default("mirror");
    mirror.mirror = v3s(0.9f);
    scene_material glass = scene_material_default("glass");
    glass.dielectric = 1;
    glass.ior = 1.5f;
    glass.transmission = v3(0.9f, 0.95f, 1.0f);
    int walls = ts_diffuse(s, "walls", v3(0.6f, 0.6f, 0.55f), v3s(0.0f), err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3(20, 18, 14), err);
    int mw = scene_add_material(s, &ward, err), mp = scene_add_material(s, &phong, err);
    int mm = scene_add_material(s, &mirror, err), mg = scene_add_material(s, &glass, err);
    if (walls < 0 || lamp < 0 || mw < 0 || mp < 0 || mm < 0 || mg < 0) goto fail;
    if (ts_box(s, "walls", (uint32_t)walls, v3(-2, 0, -2), v3(2, 3, 2), true, err) < 0) goto fail;
    if (ts_quad(s, "light", (uint32_t)lamp, v3(-0.5f, 2.99f, -0.5f), v3(1, 0, 0), v3(0, 0, 1), err) < 0) goto fail;
    if (ts_sphere(s, "sphere", (uint32_t)mw, v3(-0.8f, 0.6f, 0.5f), 0.6f, 24, 12, false, err) < 0) goto fail;
    if (ts_box(s, "block", (uint32_t)mp, v3(0.5f, 0, 0.6f), v3(1.3f, 0.9f, 1.4f), false, err) < 0) goto fail;
    if (ts_quad(s, "mirror", (uint32_t)mm, v3(-1.5f, 0.3f, 1.98f), v3(0, 2, 0), v3(3, 0, 0), err) < 0) goto fail;
    if (ts_box(s, "glass", (uint32_t)mg, v3(0.2f, 0, -0.8f), v3(0.8f, 1.2f, -0.2f), false, err) < 0) goto fail;
    if (scene_add_camera(s, "main", v3(0, 1.5f, -1.9f), v3(0, 0.8f, 1.0f), v3(0, 1, 0), 70.0f, err)) goto fail;
    if (scene_finalize(s, err)) goto fail;
    return s;
fail:
    scene_free(s);
    return NULL;
}

/* Form factor from a point to a parallel rectangle [0,a]x[0,b] at height c
 * whose corner lies straight above it; odd in a and b. */
static double ff_corner(double a, double b, double c)
{
    double x = a / c, y = b / c;
    return (x / sqrt(1 + x * x) * atan(y / sqrt(1 + x * x)) + y / sqrt(1 + y * y) * atan(x / sqrt(1 + y * y))) /
           (2 * M_PI);
}

double ts_ff_rect(double px, double pz, double x0, double x1, double z0, double z1, double c)
{
    return ff_corner(x1 - px, z1 - pz, c) - ff_corner(x0 - px, z1 - pz, c) - ff_corner(x1 - px, z0 - pz, c) +
           ff_corner(x0 - px, z0 - pz, c);
}


ct_scene *ts_mirror_lamp(bool split, bool cover, bool diffuse_ceiling, ct_error *err)
{
    ct_scene *s = scene_new("mirrorlamp");
    if (!s) {
        ct_fail(err, CT_ENOMEM, "out of memory");
        return NULL;
    }
    int floor_m = ts_diffuse(s, "floor", v3s(0.5f), v3s(0.0f), err);
    int lamp = ts_diffuse(s, "lamp", v3s(0.0f), v3(10, 5, 2), err);
    int black = ts_diffuse(s, "black", v3s(0.0f), v3s(0.0f), err);
    scene_material mm = scene_material_default("ceiling");
    mm.diffuse = diffuse_ceiling ? v3s(0.8f) : v3s(0.0f);
    if (!diffuse_ceiling) mm.mirror = v3(0.8f, 0.6f, 0.4f);
    int ceil_m = scene_add_material(s, &mm, err);
    bool ok = floor_m >= 0 && lamp >= 0 && black >= 0 && ceil_m >= 0;
    /* The floor in 0.5 m tiles: vertices for the radiosity test to read
     * (the mirror light does not drive the solver's subdivision). */
    ok = ok && scene_begin_node(s, "floor", SCENE_NODE_PART, (uint32_t)floor_m, err) >= 0;
    for (int i = 0; i < 40 && ok; i++)
        for (int j = 0; j < 40 && ok; j++) {
            vec3 c = v3(-10.0f + 0.5f * (float)i, 0, -10.0f + 0.5f * (float)j);
            ok = add_quad(s, c, v3_add(c, v3(0, 0, 0.5f)), v3_add(c, v3(0.5f, 0, 0.5f)), v3_add(c, v3(0.5f, 0, 0)),
                          err) == 0;
        }
    ok = ok && scene_end_node(s, err) == 0;
    /* A diffuse wall at x = -6 facing +x, (0,2,0) x (0,0,20) = (40,0,0). */
    ok = ok && ts_quad(s, "side_wall", (uint32_t)floor_m, v3(-6, 0, -10), v3(0, 2, 0), v3(0, 0, 20), err) >= 0;
    /* Front (0,0,0.6) x (0.6,0,0) = up. */
    ok = ok && ts_quad(s, "lamp", (uint32_t)lamp, v3(1.5f, 1, -0.3f), v3(0, 0, 0.6f), v3(0.6f, 0, 0), err) >= 0;
    if (split) {
        ok = ok && ts_quad(s, "ceiling_a", (uint32_t)ceil_m, v3(-10, 2, -10), v3(13, 0, 0), v3(0, 0, 20), err) >= 0;
        ok = ok && ts_quad(s, "ceiling_b", (uint32_t)ceil_m, v3(3, 2, -10), v3(7, 0, 0), v3(0, 0, 20), err) >= 0;
        ok = ok && ts_quad(s, "wall", (uint32_t)ceil_m, v3(-9, 0, 5), v3(0, 1.5f, 0), v3(2, 0, 0), err) >= 0;
    } else {
        ok = ok && ts_quad(s, "ceiling", (uint32_t)ceil_m, v3(-10, 2, -10), v3(20, 0, 0), v3(0, 0, 20), err) >= 0;
    }
    if (cover)
        ok = ok && ts_quad(s, "plate", (uint32_t)black, v3(1.4f, 1.05f, -0.4f), v3(0, 0, 0.8f), v3(0.8f, 0, 0),
                           err) >= 0;
    if (!ok || scene_finalize(s, err) != CT_OK) {
        scene_free(s);
        return NULL;
    }
    return s;
}

vec3 ts_mirror_lamp_floor(float x, float z)
{
    float f = (float)ts_ff_rect(x, z, 1.5, 2.1, -0.3, 0.3, 3.0);
    return v3_scale(v3(0.5f * 0.8f * 10.0f, 0.5f * 0.6f * 5.0f, 0.5f * 0.4f * 2.0f), f);
}

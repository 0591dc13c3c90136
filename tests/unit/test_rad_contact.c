/* Mesh vertices hidden under an object standing on their surface
 * (radiosity/rad_contact.c): the L room's box stands on its floor without a
 * bottom face, and the floor's quadtree elements straddle the box's edges.
 * Their corners under the box used to keep the darkness the final gather
 * finds there (about a fifteenth of the floor's light just outside), which
 * Gouraud shading smeared over the visible part of the element. */
#include <criterion/criterion.h>
#include <stdlib.h>

#include "radiosity/radiosity.h"

/* The box's footprint on the floor (tests/data/radiosity/lroom.obj). */
#define BOX_X0 1.75f
#define BOX_X1 2.15f
#define BOX_Z0 0.4f
#define BOX_Z1 1.0f
/* A band this wide on either side of the footprint's edges: an element of
 * the floor there is about 2.3 cm wide. */
#define BAND 0.03f

/* Distance of floor point (x, z) from the footprint's boundary, negative
 * inside it. */
static float edge_distance(float x, float z)
{
    float dx = fmaxf(BOX_X0 - x, x - BOX_X1), dz = fmaxf(BOX_Z0 - z, z - BOX_Z1);
    if (dx <= 0.0f && dz <= 0.0f) return fmaxf(dx, dz);
    return sqrtf(fmaxf(dx, 0.0f) * fmaxf(dx, 0.0f) + fmaxf(dz, 0.0f) * fmaxf(dz, 0.0f));
}

Test(rad_contact, hidden_corners_take_the_light_at_the_contact_line, .timeout = 240)
{
    ct_scene *s;
    ct_error err;
    cr_assert_eq(scene_load("tests/data/radiosity/lroom.json", &s, &err), 0, "%s", err.msg);
    rad_params p;
    rad_params_default(&p);
    p.threads = 2;
    ct_radmesh m;
    rad_stats st;
    cr_assert_eq(rad_solve(s, &p, NULL, NULL, &m, &st, &err), 0, "%s", err.msg);
    cr_assert_gt(st.contact_vertices, 0u, "no hidden vertex was given the light at its contact line");
    /* Floor vertices under the box that share a triangle with one outside
     * it (the corners Gouraud shading spreads over the visible floor), and
     * the floor outside within BAND of the edges. */
    bool *straddles = calloc(m.nverts, sizeof *straddles);
    cr_assert_not_null(straddles);
    for (uint32_t t = 0; t < m.ntris; t++) {
        const uint32_t *i = m.tris + 3 * (size_t)t;
        bool outside = false;
        for (int k = 0; k < 3; k++)
            outside |= m.pos[i[k]].y == 0.0f && edge_distance(m.pos[i[k]].x, m.pos[i[k]].z) > 1e-4f;
        for (int k = 0; k < 3 && outside; k++) straddles[i[k]] = true;
    }
    double in = 0.0, out = 0.0;
    int nin = 0, nout = 0;
    for (uint32_t v = 0; v < m.nverts; v++) {
        vec3 q = m.pos[v];
        if (q.y != 0.0f || m.nrm[v].y < 0.99f) continue;   /* the floor's vertices */
        float d = edge_distance(q.x, q.z);
        /* Away from the footprint's corners, where the box's two faces meet. */
        bool near_x = fabsf(q.x - BOX_X0) < BAND || fabsf(q.x - BOX_X1) < BAND;
        bool near_z = fabsf(q.z - BOX_Z0) < BAND || fabsf(q.z - BOX_Z1) < BAND;
        if (fabsf(d) > BAND || (near_x && near_z)) continue;
        float y = v3_luminance(m.rad[v]);
        if (d < -1e-4f && straddles[v]) {
            in += y;
            nin++;
        } else if (d > 1e-4f) {
            out += y;
            nout++;
        }
    }
    free(straddles);
    cr_assert_gt(nin, 10, "only %d floor vertices just under the box's edges", nin);
    cr_assert_gt(nout, 10, "only %d floor vertices just outside the box's edges", nout);
    in /= nin;
    out /= nout;
    cr_log_info("floor within %.0f cm of the box's edges: under it, in elements reaching out, %.4f (%d vertices), outside %.4f (%d); %u moved",
                100.0 * BAND, in, nin, out, nout, st.contact_vertices);
    /* At the contact line the floor is darker than a few cm out (the box
     * hides half its hemisphere), but nowhere near black. */
    cr_assert_gt(in, 0.5 * out, "hidden floor vertices at %.4f against %.4f just outside: they would darken the "
                                "floor next to the box", in, out);
    cr_assert_lt(in, 1.1 * out, "hidden floor vertices at %.4f, brighter than the floor outside (%.4f)", in, out);
    rmesh_free(&m);
    scene_free(s);
}

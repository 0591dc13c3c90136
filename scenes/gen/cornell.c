/* cornell: writes scenes/cornell/cornell.obj and cornell.mtl, the Cornell box
 * at its published dimensions (the Cornell Program of Computer Graphics'
 * "Cornell Box" data, millimetres, y up, the open side at z = 0) with:
 *   - the ceiling cut around the light's opening (8 quads, no T-junctions) and
 *     the light quad 343.0 548.8 227.0 .. 213.0 548.8 332.0 filling it, facing
 *     down, so light and ceiling never overlap;
 *   - the short block (white) carrying a glass sphere;
 *   - the tall block in brushed metal (Ward anisotropic via cornell.json);
 *   - a mirror sphere on the floor in front of the tall block.
 * Spheres are UV spheres of CORNELL_STACKS x CORNELL_SLICES with smooth
 * normals. Usage: cornell OUTDIR. Counts (docs/scenes.md, tests): 12 wall
 * quads + 1 light + 2 x 5 block quads + 2 spheres x 800 = 1623 primitives. */
#include "genlib.h"

#define GEN_NAME "cornell"
#define CORNELL_STACKS 20
#define CORNELL_SLICES 40

/* A published quad; its normal faces the side `toward` lies on. */
static void quad_toward(gobj *o, const double q[4][3], gv3 toward)
{
    gv3 p[4];
    gv3 c = g3(0, 0, 0);
    for (int i = 0; i < 4; i++) {
        p[i] = g3(q[i][0], q[i][1], q[i][2]);
        c = gadd(c, gmul(p[i], 0.25));
    }
    gv3 n = gnorm(gcross(gsub(p[1], p[0]), gsub(p[2], p[0])));
    if (gdot(n, gsub(toward, c)) < 0) n = gmul(n, -1);
    gen_flat(o, 4, p, n);
}

/* An object `name` of material mat holding one published quad facing the
 * side `toward` lies on. */
static void named_quad(gobj *o, const char *name, const char *mat, const double q[4][3], gv3 toward)
{
    gen_object(o, "%s", name);
    gen_material(o, mat);
    quad_toward(o, q, toward);
}

/* A block: the published top quad and four sides, normals pointing out of
 * its centre (no bottom: it stands on the floor). */
static void block(gobj *o, const double q[5][4][3], gv3 centre)
{
    for (int f = 0; f < 5; f++) {
        gv3 c = g3(0, 0, 0);
        for (int i = 0; i < 4; i++) c = gadd(c, gmul(g3(q[f][i][0], q[f][i][1], q[f][i][2]), 0.25));
        /* a point outside the face: its centre pushed away from the block's */
        quad_toward(o, q[f], gadd(c, gsub(c, centre)));
    }
}

static int write_mtl(const char *dir)
{
    /* Reflectances: the usual RGB fit of the published spectral data. The
     * light, metal, mirror and glass get their real definitions from
     * cornell.json (overrides by name); these are what an MTL can say. */
    return gen_write_mtl(dir, GEN_NAME,
            "newmtl white\nKd 0.725 0.71 0.68\n\n"
            "newmtl red\nKd 0.63 0.065 0.05\n\n"
            "newmtl green\nKd 0.14 0.45 0.091\n\n"
            "newmtl light\nKd 0.78 0.78 0.78\nKe 17 12 4\n\n"
            "newmtl brushed_metal\nKd 0.05 0.05 0.05\nKs 0.6 0.58 0.55\nNs 200\nillum 2\n\n"
            GEN_MTL_MIRROR_GLASS);
}

int main(int argc, char **argv)
{
    const char *dir = gen_outdir(argc, argv, GEN_NAME);
    if (!dir) return 2;
    gobj o;
    if (gen_open(&o, dir, "cornell.obj", "cornell.mtl", GEN_NAME)) return 1;
    gv3 inside = g3(278, 274, 280);

    /* Published walls (Cornell Box data). */
    static const double floor_q[4][3] = {
        {552.8, 0, 0}, {0, 0, 0}, {0, 0, 559.2}, {549.6, 0, 559.2}};
    static const double back_q[4][3] = {
        {549.6, 0, 559.2}, {0, 0, 559.2}, {0, 548.8, 559.2}, {556.0, 548.8, 559.2}};
    static const double right_q[4][3] = {  /* x = 0: green, on the camera's right */
        {0, 0, 559.2}, {0, 0, 0}, {0, 548.8, 0}, {0, 548.8, 559.2}};
    static const double left_q[4][3] = {   /* x ~ 555: red, on the camera's left */
        {552.8, 0, 0}, {549.6, 0, 559.2}, {556.0, 548.8, 559.2}, {556.0, 548.8, 0}};

    named_quad(&o, "floor", "white", floor_q, inside);

    /* Ceiling 556.0 x 559.2 at y = 548.8 with the light's opening
     * x 213..343, z 227..332: a 3 x 3 grid without its centre cell. */
    gen_object(&o, "ceiling");
    gen_material(&o, "white");
    static const double cx[4] = {0.0, 213.0, 343.0, 556.0};
    static const double cz[4] = {0.0, 227.0, 332.0, 559.2};
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) {
            if (i == 1 && k == 1) continue;
            const double q[4][3] = {{cx[i], 548.8, cz[k]}, {cx[i + 1], 548.8, cz[k]},
                                    {cx[i + 1], 548.8, cz[k + 1]}, {cx[i], 548.8, cz[k + 1]}};
            quad_toward(&o, q, inside);
        }

    named_quad(&o, "back_wall", "white", back_q, inside);
    named_quad(&o, "left_wall", "red", left_q, inside);
    named_quad(&o, "right_wall", "green", right_q, inside);

    /* The published light, emitting down. */
    static const double light_q[4][3] = {
        {343.0, 548.8, 227.0}, {343.0, 548.8, 332.0}, {213.0, 548.8, 332.0}, {213.0, 548.8, 227.0}};
    named_quad(&o, "light", "light", light_q, g3(278, 0, 280));

    static const double short_q[5][4][3] = {
        {{130.0, 165.0, 65.0}, {82.0, 165.0, 225.0}, {240.0, 165.0, 272.0}, {290.0, 165.0, 114.0}},
        {{290.0, 0.0, 114.0}, {290.0, 165.0, 114.0}, {240.0, 165.0, 272.0}, {240.0, 0.0, 272.0}},
        {{130.0, 0.0, 65.0}, {130.0, 165.0, 65.0}, {290.0, 165.0, 114.0}, {290.0, 0.0, 114.0}},
        {{82.0, 0.0, 225.0}, {82.0, 165.0, 225.0}, {130.0, 165.0, 65.0}, {130.0, 0.0, 65.0}},
        {{240.0, 0.0, 272.0}, {240.0, 165.0, 272.0}, {82.0, 165.0, 225.0}, {82.0, 0.0, 225.0}}};
    static const double tall_q[5][4][3] = {
        {{423.0, 330.0, 247.0}, {265.0, 330.0, 296.0}, {314.0, 330.0, 456.0}, {472.0, 330.0, 406.0}},
        {{423.0, 0.0, 247.0}, {423.0, 330.0, 247.0}, {472.0, 330.0, 406.0}, {472.0, 0.0, 406.0}},
        {{472.0, 0.0, 406.0}, {472.0, 330.0, 406.0}, {314.0, 330.0, 456.0}, {314.0, 0.0, 456.0}},
        {{314.0, 0.0, 456.0}, {314.0, 330.0, 456.0}, {265.0, 330.0, 296.0}, {265.0, 0.0, 296.0}},
        {{265.0, 0.0, 296.0}, {265.0, 330.0, 296.0}, {423.0, 330.0, 247.0}, {423.0, 0.0, 247.0}}};
    gen_object(&o, "short_block");
    gen_material(&o, "white");
    block(&o, short_q, g3(185.5, 82.5, 169.0));
    gen_object(&o, "tall_block");
    gen_material(&o, "brushed_metal");
    block(&o, tall_q, g3(368.5, 165.0, 351.25));

    /* Glass sphere resting on the short block's top (centre of its top face,
     * y = 165), mirror sphere on the floor in front of the tall block. */
    gen_object(&o, "glass_sphere");
    gen_material(&o, "glass");
    gen_sphere(&o, g3(185.5, 165.0 + 70.0, 169.0), 70.0, CORNELL_STACKS, CORNELL_SLICES);
    gen_object(&o, "mirror_sphere");
    gen_material(&o, "mirror");
    gen_sphere(&o, g3(400.0, 80.0, 140.0), 80.0, CORNELL_STACKS, CORNELL_SLICES);

    long prims = o.prims, quads = o.quads, tris = o.tris;
    if (gen_finish(&o, dir, GEN_NAME, write_mtl)) return 1;
    printf("  " GEN_NAME ": %ld primitives (%ld quads, %ld triangles), %ld render triangles\n",
           prims, quads, tris, tris + 2 * quads);
    return 0;
}

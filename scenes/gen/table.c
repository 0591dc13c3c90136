/* table: writes scenes/table/table.obj and table.mtl, a small dining room
 * in the spirit of the paper's Figs. 1 and 5: a table carrying an hourglass
 * and two wine glasses (glass), a brushed-metal plate (Ward anisotropic),
 * two glossy vases (Phong), a bowl with oranges and a stack of books
 * (diffuse); a framed wall mirror behind the table, a bookshelf, two chairs
 * and two ceiling light panels. Metres, y up; the room spans x 0..5,
 * y 0..2.8, z 0..4.5 and the table stands at x 1.7..3.3, z 2.35..3.25.
 * Deterministic: fixed-seed random book sizes and colours.
 * Usage: table OUTDIR. docs/scenes.md lists the objects and counts. */
#include "genlib.h"

#define GEN_NAME "table"

#define ROOM_X 5.0
#define ROOM_Y 2.8
#define ROOM_Z 4.5
#define CELL 0.5          /* wall, floor and ceiling panels */
#define TABLE_TOP 0.76    /* height of the table's upper surface */
/* Glass never touches what it stands on: a face of glass lying in the plane
 * of an opaque face makes every ray there hit one or the other by rounding,
 * so the see-through interactive image (and the display's depth test) and
 * the traced samples speckle black and bright across the contact (the wine
 * glasses' feet on the table, the hourglass' glass on its frame). 0.5 mm is
 * far above the tracer's ray offsets (256 float steps, about 0.08 mm at
 * 2.6 m) and below what the camera resolves. */
#define GLASS_GAP 0.0005

#define HG_SEGS 36        /* hourglass: steps around */
#define HG_HALF 14        /* hourglass: profile points per bulb */
#define GLASS_SEGS 40     /* wine glasses */
#define VASE_SEGS 40
#define SHELF_BOOKS 26    /* books per bookshelf board */
#define SHELF_LEVELS 4

/* A wall, floor or ceiling: the rectangle c + [0,1]u + [0,1]v split into
 * panels of about CELL, facing `facing`. */
static void panels(gobj *o, gv3 c, gv3 u, gv3 v, gv3 facing)
{
    int nu = (int)ceil(glen(u) / CELL - 1e-9), nv = (int)ceil(glen(v) / CELL - 1e-9);
    for (int i = 0; i < nu; i++)
        for (int k = 0; k < nv; k++)
            gen_quad(o, gadd(gadd(c, gmul(u, (double)i / nu)), gmul(v, (double)k / nv)),
                     gmul(u, 1.0 / nu), gmul(v, 1.0 / nv), facing);
}

static void room(gobj *o)
{
    gen_object(o, "floor");
    gen_material(o, "floor_wood");
    panels(o, g3(0, 0, 0), g3(ROOM_X, 0, 0), g3(0, 0, ROOM_Z), g3(0, 1, 0));
    gen_object(o, "ceiling");
    gen_material(o, "ceiling_white");
    panels(o, g3(0, ROOM_Y, 0), g3(ROOM_X, 0, 0), g3(0, 0, ROOM_Z), g3(0, -1, 0));
    gen_object(o, "walls");
    gen_material(o, "wall_paint");
    panels(o, g3(0, 0, 0), g3(ROOM_X, 0, 0), g3(0, ROOM_Y, 0), g3(0, 0, 1));          /* front */
    panels(o, g3(0, 0, ROOM_Z), g3(ROOM_X, 0, 0), g3(0, ROOM_Y, 0), g3(0, 0, -1));    /* back */
    panels(o, g3(0, 0, 0), g3(0, 0, ROOM_Z), g3(0, ROOM_Y, 0), g3(1, 0, 0));          /* left */
    panels(o, g3(ROOM_X, 0, 0), g3(0, 0, ROOM_Z), g3(0, ROOM_Y, 0), g3(-1, 0, 0));    /* right */
}

/* A ceiling light: a white housing with an emissive panel 1 mm below it. */
static void ceiling_light(gobj *o, const char *name, double x, double z, double w, double d)
{
    gen_ceiling_light(o, name, "fixture", "light", x, z, w, d, ROOM_Y - 0.06, ROOM_Y, ROOM_Y - 0.061);
}

static void table(gobj *o)
{
    gen_object(o, "table");
    gen_material(o, "oak");
    double x0 = 1.7, x1 = 3.3, z0 = 2.35, z1 = 3.25;
    gen_box(o, g3(x0, TABLE_TOP - 0.04, z0), g3(x1, TABLE_TOP, z1), GEN_ALL);
    for (int i = 0; i < 4; i++) {
        double lx = i & 1 ? x1 - 0.1 : x0 + 0.04, lz = i & 2 ? z1 - 0.1 : z0 + 0.04;
        gen_box(o, g3(lx, 0, lz), g3(lx + 0.06, TABLE_TOP - 0.04, lz + 0.06), GEN_NOBOTTOM & ~GEN_YP);
    }
    /* aprons under the top, between the legs */
    gen_box(o, g3(x0 + 0.1, TABLE_TOP - 0.14, z0 + 0.05), g3(x1 - 0.1, TABLE_TOP - 0.04, z0 + 0.07),
            GEN_ALL & ~GEN_YP);
    gen_box(o, g3(x0 + 0.1, TABLE_TOP - 0.14, z1 - 0.07), g3(x1 - 0.1, TABLE_TOP - 0.04, z1 - 0.05),
            GEN_ALL & ~GEN_YP);
}

/* Hourglass outer glass radius at height h above its base (0..0.26). */
static double hg_radius(double h)
{
    double u = fabs(h - 0.13) / 0.13;   /* 0 at the neck, 1 at the ends */
    if (u > 1) u = 1;
    return 0.006 + 0.046 * pow(sin(M_PI * (0.08 + 0.84 * u)), 0.7) * (u < 0.999 ? 1 : 0.9);
}

/* Height in the hourglass's frame of a glass or sand profile point at y in
 * 0.02..0.28: the same shape, kept GLASS_GAP off both walnut discs. */
static double hg_y(double y)
{
    return 0.02 + GLASS_GAP + (y - 0.02) * (0.26 - 2 * GLASS_GAP) / 0.26;
}

static void hourglass(gobj *o, gv3 at)
{
    gen_push(o, gxf_at(at, 0));
    gen_object(o, "hourglass_frame");
    gen_material(o, "walnut");
    gen_cylinder(o, 0.075, 0.0, 0.02, HG_SEGS);
    gen_cylinder(o, 0.075, 0.28, 0.30, HG_SEGS);
    for (int i = 0; i < 3; i++) {
        double a = 2 * M_PI * i / 3 + 0.3;
        gv3 b = g3(0.064 * cos(a), 0.02, 0.064 * sin(a));
        gen_rod(o, b, gadd(b, g3(0, 0.26, 0)), 0.005, 12);
    }

    /* glass: a 2 mm shell from y 0.02 to 0.28 (outer surface walked up,
     * cavity walked down so its normals face the cavity) */
    gen_object(o, "hourglass_glass");
    gen_material(o, "glass");
    gprof out = {{0}, {0}, 0}, in = {{0}, {0}, 0};
    prof_add(&out, 0, hg_y(0.02));
    for (int i = 0; i <= 2 * HG_HALF; i++) {
        double h = 0.26 * i / (2 * HG_HALF);
        prof_add(&out, hg_radius(h), hg_y(0.02 + h));
    }
    prof_add(&out, 0, hg_y(0.28));
    gen_prof(o, &out, HG_SEGS, 50);
    prof_add(&in, 0, hg_y(0.278));
    for (int i = 2 * HG_HALF; i >= 0; i--) {
        double h = 0.26 * i / (2 * HG_HALF);
        double hh = h < 0.002 ? 0.002 : h > 0.258 ? 0.258 : h;
        prof_add(&in, hg_radius(h) - 0.002, hg_y(0.02 + hh));
    }
    prof_add(&in, 0, hg_y(0.022));
    gen_prof(o, &in, HG_SEGS, 50);

    /* sand: a pile in the lower bulb, the rest in the upper one, a thin
     * stream through the neck; 1.5 mm inside the cavity everywhere */
    gen_object(o, "hourglass_sand");
    gen_material(o, "sand");
    gprof lo = {{0}, {0}, 0}, up = {{0}, {0}, 0};
    prof_add(&lo, 0, hg_y(0.0235));
    for (int i = 0; i <= 6; i++) {
        double h = 0.0035 + 0.035 * i / 6;
        prof_add(&lo, hg_radius(h) - 0.0035, hg_y(0.02 + h));
    }
    prof_add(&lo, 0, hg_y(0.02 + 0.0385 + 0.022));
    gen_prof(o, &lo, HG_SEGS, 35);
    prof_add(&up, 0, hg_y(0.02 + 0.145));
    for (int i = 0; i <= 6; i++) {
        double h = 0.145 + 0.05 * i / 6;
        prof_add(&up, hg_radius(h) - 0.0035, hg_y(0.02 + h));
    }
    prof_add(&up, 0, hg_y(0.02 + 0.183));
    gen_prof(o, &up, HG_SEGS, 35);
    gen_cylinder(o, 0.0012, hg_y(0.02 + 0.0385 + 0.021), hg_y(0.02 + 0.146), 8);
    gen_pop(o);
}

static void wine_glass(gobj *o, const char *name, gv3 at)
{
    gen_push(o, gxf_at(at, 0));
    gen_object(o, "%s", name);
    gen_material(o, "glass");
    gprof p = {{0}, {0}, 0};
    prof_add(&p, 0, 0);
    prof_add(&p, 0.034, 0);
    prof_add(&p, 0.035, 0.002);
    static const double stem[][2] = {
        {0.034, 0.0035}, {0.02, 0.005}, {0.007, 0.009}, {0.0042, 0.02}, {0.004, 0.06},
        {0.0045, 0.088}, {0.009, 0.097}};
    prof_spline(&p, stem, (int)(sizeof stem / sizeof stem[0]), 2);
    /* tulip bowl from y 0.097 to 0.205 */
    const int nb = 14;
    double rb[16], yb[16];
    for (int i = 1; i <= nb; i++) {
        double v = (double)i / nb;
        rb[i] = 0.041 * sin(v * M_PI * 0.58 + 0.22);
        yb[i] = 0.097 + 0.108 * v;
        prof_add(&p, rb[i], yb[i]);
    }
    /* rim 1.5 mm, then the inside down to a bottom at y 0.105 */
    for (int i = nb; i >= 3; i--) prof_add(&p, rb[i] - 0.0015, yb[i]);
    prof_add(&p, 0.006, 0.106);
    prof_add(&p, 0, 0.105);
    gen_prof(o, &p, GLASS_SEGS, 50);
    gen_pop(o);
}

/* A glossy vase: outer surface through control points, a 6 mm rim, and a cup
 * 8 cm deep inside that follows the outer surface 6 mm in. */
static void vase(gobj *o, const char *name, const char *mat, gv3 at, const double (*c)[2], int nc)
{
    gen_push(o, gxf_at(at, 0));
    gen_object(o, "%s", name);
    gen_material(o, mat);
    gprof p = {{0}, {0}, 0};
    prof_add(&p, 0, 0);
    prof_spline(&p, c, nc, 4);
    const double wall = 0.006, depth = 0.08;
    double ht = c[nc - 1][1];
    int top = p.n - 1, k = top;
    while (k > 1 && p.y[k - 1] >= ht - depth) k--;
    for (int i = top; i >= k; i--) prof_add(&p, p.r[i] - wall, p.y[i]);
    prof_add(&p, 0, p.y[k] - 0.004);
    gen_prof(o, &p, VASE_SEGS, 40);
    gen_pop(o);
}

static void plate(gobj *o, gv3 at)
{
    gen_push(o, gxf_at(at, 0));
    gen_object(o, "metal_plate");
    gen_material(o, "brushed_steel");
    static const double plate_prof[][2] = {{0, 0},         {0.10, 0},       {0.14, 0.014},
                                           {0.147, 0.018}, {0.143, 0.0195}, {0.135, 0.016},
                                           {0.10, 0.004},  {0, 0.004}};
    gen_prof_points(o, plate_prof, 8, 1.0, 48, 30);
    gen_pop(o);
}

static void bowl_with_oranges(gobj *o, gv3 at)
{
    gen_push(o, gxf_at(at, 0));
    gen_object(o, "bowl");
    gen_material(o, "ceramic");
    gprof p = {{0}, {0}, 0};
    prof_add(&p, 0, 0);
    prof_add(&p, 0.045, 0);
    prof_add(&p, 0.05, 0.008);
    static const double outer[][2] = {{0.05, 0.008}, {0.09, 0.03}, {0.115, 0.06}, {0.125, 0.085}};
    prof_spline(&p, outer + 1, 3, 4);
    prof_add(&p, 0.118, 0.085);
    static const double inner[][2] = {{0.118, 0.085}, {0.108, 0.06}, {0.08, 0.032}, {0.045, 0.016}};
    prof_spline(&p, inner + 1, 3, 4);
    prof_add(&p, 0, 0.014);
    gen_prof(o, &p, 40, 40);
    gen_object(o, "oranges");
    gen_material(o, "orange_peel");
    gen_sphere(o, g3(0.03, 0.014 + 0.036, 0.0), 0.036, 12, 20);
    gen_sphere(o, g3(-0.035, 0.014 + 0.036, 0.025), 0.036, 12, 20);
    gen_sphere(o, g3(-0.01, 0.014 + 0.036, -0.045), 0.036, 12, 20);
    gen_pop(o);
}

static const char *const book_mats[] = {"book_red", "book_blue", "book_green", "book_cream",
                                        "book_brown", "book_black"};
#define NBOOKMATS ((int)(sizeof book_mats / sizeof book_mats[0]))

static void book_stack(gobj *o, gv3 at)
{
    gen_object(o, "book_stack");
    static const double dims[3][3] = {{0.24, 0.045, 0.17}, {0.22, 0.03, 0.16}, {0.19, 0.035, 0.13}};
    static const double yaw[3] = {8, -5, 20};
    double y = 0;
    for (int i = 0; i < 3; i++) {
        gen_push(o, gxf_at(gadd(at, g3(0, y, 0)), yaw[i]));
        gen_material(o, book_mats[(i * 2 + 1) % NBOOKMATS]);
        gen_box(o, g3(-dims[i][0] / 2, 0, -dims[i][2] / 2), g3(dims[i][0] / 2, dims[i][1], dims[i][2] / 2),
                GEN_NOBOTTOM);
        gen_pop(o);
        y += dims[i][1];
    }
}

static void mirror(gobj *o)
{
    gen_object(o, "wall_mirror");
    double x0 = 1.9, x1 = 3.1, y0 = 1.05, y1 = 1.9, z = ROOM_Z - 0.02, f = 0.05;
    gen_material(o, "walnut");
    gen_box(o, g3(x0 - f, y0 - f, z - 0.012), g3(x1 + f, y0, ROOM_Z), GEN_ALL & ~GEN_ZP);
    gen_box(o, g3(x0 - f, y1, z - 0.012), g3(x1 + f, y1 + f, ROOM_Z), GEN_ALL & ~GEN_ZP);
    gen_box(o, g3(x0 - f, y0, z - 0.012), g3(x0, y1, ROOM_Z), GEN_XN | GEN_XP | GEN_ZN);
    gen_box(o, g3(x1, y0, z - 0.012), g3(x1 + f, y1, ROOM_Z), GEN_XN | GEN_XP | GEN_ZN);
    gen_material(o, "mirror");
    gen_quad(o, g3(x0, y0, z), g3(x1 - x0, 0, 0), g3(0, y1 - y0, 0), g3(0, 0, -1));
}

static void chair(gobj *o, const char *name, gv3 at, double yaw)
{
    gen_push(o, gxf_at(at, yaw));
    gen_object(o, "%s", name);
    gen_material(o, "oak");
    gen_box(o, g3(-0.22, 0.43, -0.22), g3(0.22, 0.47, 0.22), GEN_ALL);
    for (int i = 0; i < 4; i++) {
        double lx = i & 1 ? 0.17 : -0.21, lz = i & 2 ? 0.17 : -0.21;
        double top = i & 2 ? 0.98 : 0.43;   /* back legs carry the backrest */
        gen_box(o, g3(lx, 0, lz), g3(lx + 0.04, top, lz + 0.04), i & 2 ? GEN_NOBOTTOM : GEN_NOBOTTOM & ~GEN_YP);
    }
    for (int k = 0; k < 3; k++)
        gen_box(o, g3(-0.17, 0.6 + 0.13 * k, 0.18), g3(0.17, 0.66 + 0.13 * k, 0.2), GEN_ALL & ~GEN_XN & ~GEN_XP);
    gen_material(o, "cushion");
    gen_box(o, g3(-0.2, 0.47, -0.2), g3(0.2, 0.5, 0.16), GEN_NOBOTTOM);
    gen_pop(o);
}

static void bookshelf(gobj *o, grng *rng)
{
    /* against the right wall (x = 5), facing -x */
    double x0 = ROOM_X - 0.34, x1 = ROOM_X, z0 = 0.9, z1 = 2.1;
    gen_object(o, "bookshelf");
    gen_material(o, "walnut");
    gen_box(o, g3(x0, 0, z0), g3(x1, 1.9, z0 + 0.02), GEN_NOBOTTOM & ~GEN_XP);
    gen_box(o, g3(x0, 0, z1 - 0.02), g3(x1, 1.9, z1), GEN_NOBOTTOM & ~GEN_XP);
    for (int k = 0; k <= SHELF_LEVELS; k++) {
        double y = 0.05 + 0.45 * k;
        gen_box(o, g3(x0, y - 0.02, z0 + 0.02), g3(x1, y, z1 - 0.02), GEN_ALL & ~GEN_XP & ~GEN_ZN & ~GEN_ZP);
    }
    /* books: sizes first, then written grouped by material so each colour
     * is one mesh part */
    gen_object(o, "shelf_books");
    static double bx[SHELF_LEVELS * SHELF_BOOKS][6];
    static int bm[SHELF_LEVELS * SHELF_BOOKS];
    int nb = 0;
    for (int k = 0; k < SHELF_LEVELS; k++) {
        double y = 0.05 + 0.45 * k, z = z0 + 0.03;
        for (int b = 0; b < SHELF_BOOKS; b++, nb++) {
            double t = grng_range(rng, 0.02, 0.045), h = grng_range(rng, 0.22, 0.36);
            double d = grng_range(rng, 0.17, 0.25);
            bm[nb] = grng_int(rng, NBOOKMATS);
            const double box[6] = {x1 - 0.02 - d, y, z, x1 - 0.02, y + h, z + t};
            memcpy(bx[nb], box, sizeof box);
            z += t + 0.001;
        }
    }
    for (int m = 0; m < NBOOKMATS; m++) {
        gen_material(o, book_mats[m]);
        for (int i = 0; i < nb; i++)
            if (bm[i] == m)
                gen_box(o, g3(bx[i][0], bx[i][1], bx[i][2]), g3(bx[i][3], bx[i][4], bx[i][5]), GEN_NOBOTTOM);
    }
}

static int write_mtl(const char *dir)
{
    /* Ward, mirror, glass and the lights are (re)defined in table.json; the
     * rest is plain MTL: Kd diffuse, Ks/Ns a Phong lobe. */
    return gen_write_mtl(dir, GEN_NAME,
            "newmtl floor_wood\nKd 0.42 0.28 0.16\n\n"
            "newmtl ceiling_white\nKd 0.8 0.8 0.78\n\n"
            "newmtl wall_paint\nKd 0.7 0.66 0.58\n\n"
            "newmtl fixture\nKd 0.8 0.8 0.8\n\n"
            "newmtl light\nKd 0.8 0.8 0.8\nKe 9 8.5 7.5\n\n"
            "newmtl oak\nKd 0.5 0.34 0.18\nKs 0.08 0.08 0.08\nNs 60\nillum 2\n\n"
            "newmtl walnut\nKd 0.22 0.13 0.07\n\n"
            "newmtl cushion\nKd 0.45 0.12 0.1\n\n"
            "newmtl sand\nKd 0.76 0.62 0.38\n\n"
            "newmtl ceramic\nKd 0.75 0.74 0.7\n\n"
            "newmtl orange_peel\nKd 0.8 0.35 0.05\n\n"
            "newmtl vase_blue\nKd 0.05 0.12 0.35\nKs 0.35 0.35 0.35\nNs 150\nillum 2\n\n"
            "newmtl vase_red\nKd 0.4 0.06 0.04\nKs 0.3 0.3 0.3\nNs 60\nillum 2\n\n"
            GEN_MTL_BOOKS
            "newmtl brushed_steel\nKd 0.03 0.03 0.03\nKs 0.7 0.7 0.7\nNs 300\nillum 2\n\n"
            GEN_MTL_MIRROR_GLASS);
}

int main(int argc, char **argv)
{
    const char *dir = gen_outdir(argc, argv, GEN_NAME);
    if (!dir) return 2;
    gobj o;
    if (gen_open(&o, dir, "table.obj", "table.mtl", GEN_NAME)) return 1;
    grng rng = grng_seed(20000, 1);

    room(&o);
    ceiling_light(&o, "light_left", 1.9, 2.8, 0.8, 0.4);
    ceiling_light(&o, "light_right", 3.1, 2.8, 0.8, 0.4);
    table(&o);
    hourglass(&o, g3(2.3, TABLE_TOP, 2.85));
    wine_glass(&o, "wine_glass_1", g3(2.62, TABLE_TOP + GLASS_GAP, 2.62));
    wine_glass(&o, "wine_glass_2", g3(2.8, TABLE_TOP + GLASS_GAP, 2.86));
    plate(&o, g3(1.98, TABLE_TOP, 2.6));
    static const double tall[][2] = {
        {0.045, 0.0}, {0.07, 0.06}, {0.085, 0.15}, {0.06, 0.25}, {0.035, 0.31}, {0.045, 0.36}};
    static const double round_[][2] = {
        {0.04, 0.0}, {0.08, 0.05}, {0.085, 0.11}, {0.05, 0.17}, {0.035, 0.2}, {0.04, 0.22}};
    vase(&o, "vase_tall", "vase_blue", g3(2.98, TABLE_TOP, 3.05), tall, 6);
    vase(&o, "vase_round", "vase_red", g3(3.12, TABLE_TOP, 2.62), round_, 6);
    bowl_with_oranges(&o, g3(1.92, TABLE_TOP, 3.02));
    book_stack(&o, g3(2.6, TABLE_TOP, 3.1));
    mirror(&o);
    chair(&o, "chair_left", g3(1.35, 0, 2.8), 90);
    chair(&o, "chair_right", g3(3.65, 0, 2.8), -90);
    bookshelf(&o, &rng);

    long prims = o.prims, quads = o.quads, tris = o.tris, ngons = o.ngons, objs = o.objects;
    if (gen_finish(&o, dir, GEN_NAME, write_mtl)) return 1;
    printf("  " GEN_NAME ": %ld objects, %ld primitives (%ld quads, %ld triangles, %ld other), "
           "%ld render triangles\n", objs, prims, quads, tris, ngons, tris + 2 * quads);
    return 0;
}

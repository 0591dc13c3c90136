/* (Over 600 lines on purpose: a generator is one standalone C file, see
 * genlib.h.)
 * office: writes the office floor of scenes/office/: a corridor with
 * OFFICES_PER_SIDE offices on each side, one OBJ file per room sharing
 * office.mtl, so the scene hierarchy is scene -> room file -> furniture
 * object -> material part. Every office has two desks (brushed-metal legs,
 * monitor, keyboard, mouse, desk lamp with an emissive bulb, mug, books),
 * two desk chairs, a round meeting table with four chairs, three bookshelves
 * full of books, a plant, a framed mirror, a whiteboard, two ceiling light
 * panels, and a glass partition beside its door onto the corridor. The
 * corridor has ceiling lights, benches, plants, a painting and a large
 * mirror at its far end. Metres, y up; the corridor runs along +x at
 * z -1.1..1.1, offices span z 1.2..6.2 (north) and -6.2..-1.2 (south).
 * Deterministic (fixed-seed PCG). Usage: office OUTDIR. */
#include "genlib.h"

#define GEN_NAME "office"

#define OFFICES_PER_SIDE 4
#define OFFICE_W 6.0        /* office pitch along the corridor (walls 0.1) */
#define OFFICE_D 5.0        /* office depth */
#define HEIGHT 3.0
#define WALL 0.1
#define COR_HALF 1.1        /* corridor half width */
#define COR_LEN (OFFICES_PER_SIDE * OFFICE_W)
#define IN_W (OFFICE_W - WALL)  /* office inner width 5.9 */

#define DOOR_X0 0.6         /* door opening in office-local x */
#define DOOR_X1 1.6
#define DOOR_H 2.1
#define WIN_X0 2.4          /* glass partition opening */
#define WIN_X1 5.4
#define WIN_Y0 0.9
#define WIN_Y1 2.4

#define SHELF_LEVELS 6
#define PLANT_LEAVES 56

typedef struct opening { double u0, u1, v0, v1; } opening;

static const char *const book_mats[] = {"book_red", "book_blue", "book_green", "book_cream",
                                        "book_brown", "book_black", "book_orange", "book_grey"};
#define NBOOKMATS ((int)(sizeof book_mats / sizeof book_mats[0]))

static int cmpd(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Rectangle c + [0,a]u + [0,b]v (u, v unit) split into panels of at most
 * `cell`, facing `facing`. */
static void panel_rect(gobj *o, gv3 c, gv3 u, gv3 v, double a, double b, double cell, gv3 facing)
{
    int nu = (int)ceil(a / cell - 1e-9), nv = (int)ceil(b / cell - 1e-9);
    if (nu < 1) nu = 1;
    if (nv < 1) nv = 1;
    for (int i = 0; i < nu; i++)
        for (int k = 0; k < nv; k++)
            gen_quad(o, gadd(gadd(c, gmul(u, a * i / nu)), gmul(v, b * k / nv)), gmul(u, a / nu),
                     gmul(v, b / nv), facing);
}

/* A wall face c + [0,len]u + [0,HEIGHT]y minus rectangular openings,
 * tiled in panels of about 1 m without covering any opening. */
static void wall_face(gobj *o, gv3 c, gv3 u, double len, gv3 facing, const opening *h, int nh)
{
    double cuts[2 + 2 * 16];
    int nc = 0;
    if (nh > 16) {
        o->failed = 1;
        return;
    }
    cuts[nc++] = 0;
    cuts[nc++] = len;
    for (int i = 0; i < nh; i++) {
        cuts[nc++] = h[i].u0;
        cuts[nc++] = h[i].u1;
    }
    qsort(cuts, (size_t)nc, sizeof cuts[0], cmpd);
    gv3 up = g3(0, 1, 0);
    for (int i = 0; i + 1 < nc; i++) {
        double a = cuts[i], b = cuts[i + 1];
        if (b - a < 1e-9) continue;
        double v0 = 0.0;
        double hv[4][2];
        int nhv = 0;
        for (int k = 0; k < nh; k++)
            if (h[k].u0 <= a + 1e-9 && h[k].u1 >= b - 1e-9) {
                hv[nhv][0] = h[k].v0;
                hv[nhv][1] = h[k].v1;
                nhv++;
            }
        /* openings in one wall never overlap vertically here: at most one */
        if (nhv == 1) {
            if (hv[0][0] > v0)
                panel_rect(o, gadd(c, gmul(u, a)), u, up, b - a, hv[0][0], 1.0, facing);
            v0 = hv[0][1];
        }
        if (HEIGHT - v0 > 1e-9)
            panel_rect(o, gadd(gadd(c, gmul(u, a)), gmul(up, v0)), u, up, b - a, HEIGHT - v0, 1.0,
                       facing);
    }
}

/* The reveals of an opening through a wall of thickness `t` (from plane c
 * along -n, n = the face's normal): quads facing into the opening. */
static void reveals(gobj *o, gv3 c, gv3 u, gv3 n, double t, opening h)
{
    gv3 up = g3(0, 1, 0), back = gmul(n, -t);
    gv3 p00 = gadd(gadd(c, gmul(u, h.u0)), gmul(up, h.v0));
    double w = h.u1 - h.u0, hh = h.v1 - h.v0;
    if (h.v0 > 0) gen_quad(o, p00, gmul(u, w), back, up);                             /* sill */
    gen_quad(o, gadd(p00, gmul(up, hh)), gmul(u, w), back, gmul(up, -1));              /* head */
    gen_quad(o, p00, gmul(up, hh), back, u);                                           /* left */
    gen_quad(o, gadd(p00, gmul(u, w)), gmul(up, hh), back, gmul(u, -1));               /* right */
}

/* A ceiling light panel: housing and an emissive quad 1 mm below it. */
static void ceiling_light(gobj *o, const char *name, double x, double z, double w, double d)
{
    gen_ceiling_light(o, name, "light_housing", "light_panel", x, z, w, d, HEIGHT - 0.05, HEIGHT, HEIGHT - 0.051);
}

/* An office chair at the origin facing +z (the backrest at -z). */
static void office_chair(gobj *o, const char *fabric)
{
    gen_material(o, "plastic_black");
    for (int i = 0; i < 5; i++) {
        gen_push(o, gxf_at(g3(0, 0, 0), 72.0 * i + 18));
        gen_box(o, g3(0, 0.06, -0.02), g3(0.3, 0.095, 0.02), GEN_ALL);
        gen_sphere(o, g3(0.28, 0.03, 0), 0.03, 6, 8);
        gen_pop(o);
    }
    gen_box(o, g3(-0.03, 0.47, -0.26), g3(0.03, 0.62, -0.23), GEN_ALL);            /* back support */
    for (int s = -1; s <= 1; s += 2) {                                             /* armrests */
        gen_box(o, g3(s * 0.25 - 0.015, 0.5, -0.05), g3(s * 0.25 + 0.015, 0.68, -0.02), GEN_NOBOTTOM);
        gen_box(o, g3(s * 0.25 - 0.03, 0.68, -0.18), g3(s * 0.25 + 0.03, 0.705, 0.12), GEN_ALL);
    }
    gen_material(o, "metal_brushed");
    gen_cylinder(o, 0.025, 0.095, 0.44, 16);
    gen_material(o, fabric);
    gen_box(o, g3(-0.24, 0.44, -0.22), g3(0.24, 0.52, 0.24), GEN_ALL);
    gen_box(o, g3(-0.23, 0.62, -0.29), g3(0.23, 1.1, -0.23), GEN_ALL);
}

/* A desk lamp standing at the origin, its shade leaning towards +z. */
static void desk_lamp(gobj *o, const char *shade)
{
    gen_material(o, "metal_brushed");
    gen_cylinder(o, 0.08, 0.0, 0.02, 24);
    gv3 j0 = g3(0, 0.02, -0.02), j1 = g3(0, 0.36, -0.08), j2 = g3(0, 0.46, 0.12);
    gen_rod(o, j0, j1, 0.008, 10);
    gen_rod(o, j1, j2, 0.008, 10);
    gen_sphere(o, j1, 0.014, 6, 10);
    /* shade: a closed conical shell around its axis, open side down */
    gen_push(o, gxf_axis(gadd(j2, g3(0, -0.07, 0.03)), g3(0, 1, -0.35)));
    gen_material(o, shade);
    static const double shade_prof[][2] = {
        {0, 0.105}, {0.03, 0.103}, {0.085, 0.0}, {0.09, 0.0}, {0.035, 0.11}, {0, 0.115}};
    gen_prof_points(o, shade_prof, 6, 1.0, 24, 30);
    gen_material(o, "lamp_bulb");
    gen_quad(o, g3(-0.03, 0.06, -0.03), g3(0.06, 0, 0), g3(0, 0, 0.06), g3(0, -1, 0));
    gen_pop(o);
}

static void mug(gobj *o, const char *mat)
{
    gen_material(o, mat);
    static const double mug_prof[][2] = {{0, 0}, {0.04, 0}, {0.04, 0.1}, {0.036, 0.1}, {0.036, 0.008}, {0, 0.008}};
    gen_prof_points(o, mug_prof, 6, 1.0, 20, 30);
    gen_box(o, g3(0.04, 0.025, -0.006), g3(0.07, 0.035, 0.006), GEN_ALL & ~GEN_XN);
    gen_box(o, g3(0.06, 0.035, -0.006), g3(0.07, 0.075, 0.006), GEN_XP | GEN_ZN | GEN_ZP);
    gen_box(o, g3(0.04, 0.075, -0.006), g3(0.07, 0.085, 0.006), GEN_ALL & ~GEN_XN);
}

/* Books of one bookshelf, collected row by row and then written grouped by
 * material so each colour is one mesh part of the shelf. */
typedef struct books { double box[1024][6]; int mat[1024]; int n; } books;

/* Appends books standing in a row from `at` along +x, their spines in the
 * plane z = at.z and their bodies towards -z. */
static void book_row(books *bk, grng *rng, gv3 at, double len, double maxh, double depth_max)
{
    double x = 0.005;
    while (bk->n < 1024) {
        double t = grng_range(rng, 0.018, 0.05);
        if (x + t > len - 0.005) break;
        double h = grng_range(rng, 0.6, 1.0) * maxh, d = grng_range(rng, 0.7, 1.0) * depth_max;
        if (grng_int(rng, 14) == 0) {   /* a gap now and then */
            x += t;
            continue;
        }
        bk->mat[bk->n] = grng_int(rng, NBOOKMATS);
        const double b[6] = {at.x + x, at.y, at.z - d, at.x + x + t, at.y + h, at.z};
        memcpy(bk->box[bk->n], b, sizeof b);
        bk->n++;
        x += t + 0.0015;
    }
}

static void write_books(gobj *o, const books *bk)
{
    for (int m = 0; m < NBOOKMATS; m++) {
        int any = 0;
        for (int i = 0; i < bk->n; i++) {
            if (bk->mat[i] != m) continue;
            if (!any) gen_material(o, book_mats[m]);
            any = 1;
            const double *b = bk->box[i];
            gen_box(o, g3(b[0], b[1], b[2]), g3(b[3], b[4], b[5]), GEN_NOBOTTOM);
        }
    }
}

/* A bookshelf 1 m wide, 0.35 deep, 2.2 high with its back at local z = 0,
 * open towards +z, full of books. */
static void bookshelf(gobj *o, grng *rng, const char *name)
{
    const double w = 1.0, d = 0.35, h = 2.2, t = 0.02;
    gen_object(o, "%s", name);
    gen_material(o, "wood_shelf");
    gen_box(o, g3(0, 0, 0), g3(t, h, d), GEN_NOBOTTOM);
    gen_box(o, g3(w - t, 0, 0), g3(w, h, d), GEN_NOBOTTOM);
    gen_box(o, g3(t, 0, 0.005), g3(w - t, h, 0.015), GEN_ZP);                        /* back */
    gen_box(o, g3(t, 0, d - 0.02), g3(w - t, 0.08, d), GEN_ZP | GEN_YP);             /* plinth */
    double pitch = (h - 0.08) / SHELF_LEVELS;
    for (int k = 0; k <= SHELF_LEVELS; k++) {
        double y = 0.08 + pitch * k;
        gen_box(o, g3(t, y - t, 0.015), g3(w - t, y, d), GEN_YN | GEN_YP | GEN_ZP);
    }
    gen_object(o, "%s_books", name);
    static books bk;
    bk.n = 0;
    for (int k = 0; k < SHELF_LEVELS; k++)
        book_row(&bk, rng, g3(t, 0.08 + pitch * k, d - 0.02), w - 2 * t, pitch - 0.06, d - 0.05);
    write_books(o, &bk);
}

/* A plant in a terracotta pot: PLANT_LEAVES two-sided arching leaves. */
static void plant(gobj *o, grng *rng, const char *name, double scale)
{
    gen_object(o, "%s", name);
    gen_material(o, "terracotta");
    static const double pot_prof[][2] = {{0, 0}, {0.11, 0}, {0.15, 0.3}, {0.16, 0.3}, {0.16, 0.34},
                                         {0.14, 0.34}, {0.137, 0.3}, {0, 0.3}};
    gen_prof_points(o, pot_prof, 8, scale, 28, 30);
    gen_material(o, "soil");
    double rs[2] = {0.135 * scale, 0}, ys[2] = {0.302 * scale, 0.302 * scale};
    gen_lathe(o, 2, rs, ys, 28, 30);   /* walked inwards: a disc facing up */
    gen_material(o, "leaf");
    for (int l = 0; l < PLANT_LEAVES; l++) {
        double az = grng_range(rng, 0, 2 * M_PI), br = grng_range(rng, 0, 0.06) * scale;
        double len = grng_range(rng, 0.3, 0.6) * scale, lift = grng_range(rng, 0.7, 1.4);
        double wid = grng_range(rng, 0.025, 0.045) * scale;
        gv3 dh = g3(cos(az), 0, sin(az)), side = g3(-sin(az), 0, cos(az));
        gv3 base = g3(br * cos(az + 0.5), 0.3 * scale, br * sin(az + 0.5));
        enum { ST = 6 };
        gv3 c[ST + 1], nn[ST + 1];
        double w[ST + 1];
        for (int i = 0; i <= ST; i++) {
            double s = (double)i / ST;
            c[i] = gadd(base, gadd(gmul(dh, len * 0.55 * s), g3(0, len * lift * (0.9 * s - 0.55 * s * s), 0)));
            gv3 tan = gadd(gmul(dh, len * 0.55), g3(0, len * lift * (0.9 - 1.1 * s), 0));
            nn[i] = gnorm(gcross(side, tan));   /* upper side */
            w[i] = i == ST ? 0 : wid * (0.25 + 0.75 * sin(M_PI * (0.15 + 0.85 * s)));
        }
        for (int face = 0; face < 2; face++) {
            double sgn = face ? -1 : 1;
            long vl[ST + 1], vr[ST + 1], vn[ST + 1];
            for (int i = 0; i <= ST; i++) {
                gv3 off = gmul(nn[i], sgn * 0.0008);
                vl[i] = gen_v(o, gadd(gadd(c[i], gmul(side, -w[i])), off));
                vr[i] = i == ST ? vl[i] : gen_v(o, gadd(gadd(c[i], gmul(side, w[i])), off));
                vn[i] = gen_vn(o, gmul(nn[i], sgn));
            }
            for (int i = 0; i < ST; i++) {
                if (i + 1 == ST) {
                    long v[3] = {vl[i], vr[i], vl[ST]}, n[3] = {vn[i], vn[i], vn[ST]};
                    gen_face(o, 3, v, n);
                } else {
                    long v[4] = {vl[i], vr[i], vr[i + 1], vl[i + 1]};
                    long n[4] = {vn[i], vn[i], vn[i + 1], vn[i + 1]};
                    gen_face(o, 4, v, n);
                }
            }
        }
    }
}

/* A desk at local origin (front edge at z = 0, back at z = 0.8, width
 * along x) with its equipment; the sitter is at -z. */
static void desk(gobj *o, grng *rng, const char *name, const char *lamp_shade, const char *mug_mat)
{
    const double w = 1.6, d = 0.8, top = 0.75;
    gen_object(o, "%s", name);
    gen_material(o, "wood_desk");
    gen_box(o, g3(0, top - 0.03, 0), g3(w, top, d), GEN_ALL);
    gen_box(o, g3(w - 0.45, 0.02, 0.05), g3(w - 0.05, top - 0.1, d - 0.02), GEN_ALL);   /* drawers */
    gen_material(o, "metal_brushed");
    for (int i = 0; i < 4; i++) {
        double lx = i & 1 ? w - 0.05 : 0.05, lz = i & 2 ? d - 0.05 : 0.05;
        if (i & 1) continue;   /* the drawer unit carries the right side */
        gen_push(o, gxf_at(g3(lx, 0, lz), 0));
        gen_cylinder(o, 0.025, 0, top - 0.03, 16);
        gen_pop(o);
    }
    for (int k = 0; k < 3; k++) {
        double y = 0.1 + 0.2 * k;
        gen_rod(o, g3(w - 0.32, y + 0.08, 0.03), g3(w - 0.18, y + 0.08, 0.03), 0.006, 8);
        gen_rod(o, g3(w - 0.32, y + 0.08, 0.05), g3(w - 0.32, y + 0.08, 0.03), 0.005, 8);
        gen_rod(o, g3(w - 0.18, y + 0.08, 0.05), g3(w - 0.18, y + 0.08, 0.03), 0.005, 8);
    }

    gen_object(o, "%s_monitor", name);
    gen_push(o, gxf_at(g3(0.75, top, 0.55), 0));
    gen_material(o, "plastic_black");
    gen_box(o, g3(-0.12, 0, -0.09), g3(0.12, 0.015, 0.09), GEN_NOBOTTOM);
    gen_box(o, g3(-0.02, 0.015, 0.02), g3(0.02, 0.25, 0.05), GEN_ALL & ~GEN_YN & ~GEN_YP);
    gen_box(o, g3(-0.28, 0.12, -0.02), g3(0.28, 0.46, 0.02), GEN_ALL);
    gen_material(o, "screen");
    gen_quad(o, g3(-0.265, 0.135, -0.021), g3(0.53, 0, 0), g3(0, 0.31, 0), g3(0, 0, -1));
    gen_pop(o);

    gen_object(o, "%s_keyboard", name);
    gen_push(o, gxf_at(g3(0.75, top, 0.2), 0));
    gen_material(o, "plastic_black");
    gen_box(o, g3(-0.22, 0, -0.07), g3(0.22, 0.018, 0.07), GEN_NOBOTTOM);
    gen_material(o, "plastic_grey");
    for (int r = 0; r < 5; r++)
        for (int k = 0; k < 14; k++) {
            double x0 = -0.205 + 0.0293 * k, z0 = -0.06 + 0.0245 * r;
            gen_box(o, g3(x0, 0.018, z0), g3(x0 + 0.025, 0.03, z0 + 0.021), GEN_NOBOTTOM);
        }
    gen_pop(o);
    gen_push(o, gxf_at(g3(1.05, top, 0.2), 0));
    gen_material(o, "plastic_white");
    double mr[5] = {0, 0.028, 0.026, 0.016, 0}, my[5] = {0, 0, 0.02, 0.032, 0.035};
    gen_lathe(o, 5, mr, my, 16, 40);
    gen_pop(o);

    gen_object(o, "%s_lamp", name);
    gen_push(o, gxf_at(g3(0.2, top, 0.6), 160));
    desk_lamp(o, lamp_shade);
    gen_pop(o);

    gen_object(o, "%s_things", name);
    gen_push(o, gxf_at(g3(0.35, top, 0.25), grng_range(rng, 0, 360)));
    mug(o, mug_mat);
    gen_pop(o);
    gen_material(o, "paper");
    gen_push(o, gxf_at(g3(1.3, top, 0.4), grng_range(rng, -20, 20)));
    gen_box(o, g3(-0.105, 0, -0.15), g3(0.105, 0.004, 0.15), GEN_NOBOTTOM);
    gen_box(o, g3(-0.095, 0.004, -0.14), g3(0.115, 0.008, 0.16), GEN_NOBOTTOM);
    gen_pop(o);
    double y = 0;
    for (int b = 0; b < 3; b++) {
        double t = grng_range(rng, 0.025, 0.045);
        gen_push(o, gxf_at(g3(1.35, top + y, 0.66), grng_range(rng, -15, 15)));
        gen_material(o, book_mats[grng_int(rng, NBOOKMATS)]);
        gen_box(o, g3(-0.11, 0, -0.08), g3(0.11, t, 0.08), GEN_NOBOTTOM);
        gen_pop(o);
        y += t;
    }
}

static void round_table(gobj *o, grng *rng, const char *name, const char *fabric)
{
    gen_object(o, "%s", name);
    gen_material(o, "wood_desk");
    double r[5] = {0, 0.6, 0.6, 0.58, 0}, y[5] = {0.71, 0.71, 0.74, 0.75, 0.75};
    gen_lathe(o, 5, r, y, 48, 40);
    gen_material(o, "metal_brushed");
    double rb[6] = {0, 0.3, 0.3, 0.04, 0.04, 0}, yb[6] = {0, 0, 0.02, 0.03, 0.71, 0.71};
    gen_lathe(o, 6, rb, yb, 24, 40);
    for (int c = 0; c < 4; c++) {
        double a = 2 * M_PI * c / 4 + 0.4 + grng_range(rng, -0.15, 0.15);
        gen_object(o, "%s_chair_%d", name, c + 1);
        /* chairs face the table: local +z points to the centre */
        double yaw = 270 - a * 180 / M_PI;
        gen_push(o, gxf_at(g3(0.85 * cos(a), 0, 0.85 * sin(a)), yaw));
        office_chair(o, fabric);
        gen_pop(o);
    }
}

static void mirror_on_wall(gobj *o, double w, double h)
{
    /* local: wall at z = 0, the mirror faces +z, centred on x = 0, bottom y 0 */
    gen_material(o, "frame_alu");
    const double f = 0.04, t = 0.025;
    gen_box(o, g3(-w / 2 - f, -f, 0), g3(w / 2 + f, 0, t), GEN_ALL & ~GEN_ZN);
    gen_box(o, g3(-w / 2 - f, h, 0), g3(w / 2 + f, h + f, t), GEN_ALL & ~GEN_ZN);
    gen_box(o, g3(-w / 2 - f, 0, 0), g3(-w / 2, h, t), GEN_XN | GEN_XP | GEN_ZP);
    gen_box(o, g3(w / 2, 0, 0), g3(w / 2 + f, h, t), GEN_XN | GEN_XP | GEN_ZP);
    gen_material(o, "mirror");
    gen_quad(o, g3(-w / 2, 0, t - 0.005), g3(w, 0, 0), g3(0, h, 0), g3(0, 0, 1));
}

/* One office in its local frame: x 0..IN_W along the corridor, z 0..OFFICE_D
 * away from it (the corridor wall's office face at z = 0), y up. */
static int office(const char *dir, int idx, gxf place, grng *rng, gcounts *cnt)
{
    static const char *const paints[] = {"paint_white", "paint_sage", "paint_sand"};
    static const char *const carpets[] = {"carpet_grey", "carpet_blue"};
    static const char *const fabrics[] = {"fabric_blue", "fabric_red", "fabric_green"};
    static const char *const shades[] = {"shade_red", "shade_yellow", "shade_teal"};
    static const char *const mugs[] = {"mug_white", "mug_blue"};
    char file[64];
    snprintf(file, sizeof file, "office_%d.obj", idx);
    gobj o;
    if (gen_open(&o, dir, file, "office.mtl", GEN_NAME)) return -1;
    gen_push(&o, place);

    const char *paint = paints[idx % 3];
    gen_object(&o, "floor");
    gen_material(&o, carpets[idx % 2]);
    panel_rect(&o, g3(0, 0, 0), g3(1, 0, 0), g3(0, 0, 1), IN_W, OFFICE_D, 0.5, g3(0, 1, 0));
    gen_object(&o, "ceiling");
    gen_material(&o, "ceiling_tile");
    panel_rect(&o, g3(0, HEIGHT, 0), g3(1, 0, 0), g3(0, 0, 1), IN_W, OFFICE_D, 0.6, g3(0, -1, 0));
    gen_object(&o, "walls");
    gen_material(&o, paint);
    opening holes[2] = {{DOOR_X0, DOOR_X1, 0, DOOR_H}, {WIN_X0, WIN_X1, WIN_Y0, WIN_Y1}};
    wall_face(&o, g3(0, 0, 0), g3(1, 0, 0), IN_W, g3(0, 0, 1), holes, 2);            /* corridor side */
    wall_face(&o, g3(0, 0, OFFICE_D), g3(1, 0, 0), IN_W, g3(0, 0, -1), NULL, 0);      /* outside wall */
    wall_face(&o, g3(0, 0, 0), g3(0, 0, 1), OFFICE_D, g3(1, 0, 0), NULL, 0);          /* left */
    wall_face(&o, g3(IN_W, 0, 0), g3(0, 0, 1), OFFICE_D, g3(-1, 0, 0), NULL, 0);      /* right */
    reveals(&o, g3(0, 0, 0), g3(1, 0, 0), g3(0, 0, 1), WALL, holes[0]);
    reveals(&o, g3(0, 0, 0), g3(1, 0, 0), g3(0, 0, 1), WALL, holes[1]);
    gen_material(&o, carpets[idx % 2]);   /* the door's threshold closes the floor */
    gen_quad(&o, g3(DOOR_X0, 0, -WALL), g3(DOOR_X1 - DOOR_X0, 0, 0), g3(0, 0, WALL), g3(0, 1, 0));

    gen_object(&o, "partition_glass");
    gen_material(&o, "glass");
    gen_box(&o, g3(WIN_X0, WIN_Y0, -WALL / 2 - 0.005), g3(WIN_X1, WIN_Y1, -WALL / 2 + 0.005), GEN_ALL);

    ceiling_light(&o, "ceiling_light_1", 1.6, 2.5, 1.2, 0.6);
    ceiling_light(&o, "ceiling_light_2", 4.3, 2.5, 1.2, 0.6);

    /* two desks against the outside wall, chairs in front of them */
    for (int k = 0; k < 2; k++) {
        char name[32];
        snprintf(name, sizeof name, "desk_%d", k + 1);
        gen_push(&o, gxf_at(g3(0.6 + 2.8 * k, 0, OFFICE_D - 0.85), 0));
        desk(&o, rng, name, shades[(idx + k) % 3], mugs[k % 2]);
        gen_pop(&o);
        gen_object(&o, "desk_chair_%d", k + 1);
        gen_push(&o, gxf_at(g3(1.35 + 2.8 * k, 0, OFFICE_D - 1.35), grng_range(rng, -25, 25)));
        office_chair(&o, fabrics[(idx + k) % 3]);
        gen_pop(&o);
    }

    gen_push(&o, gxf_at(g3(3.4, 0, 2.05), 0));
    round_table(&o, rng, "meeting_table", fabrics[(idx + 2) % 3]);
    gen_pop(&o);

    /* three bookshelves on the left wall, their backs against it */
    for (int k = 0; k < 3; k++) {
        char name[32];
        snprintf(name, sizeof name, "bookshelf_%d", k + 1);
        gen_push(&o, gxf_at(g3(0.0, 0, 0.95 + 1.05 * k + 1.0), 90));
        bookshelf(&o, rng, name);
        gen_pop(&o);
    }

    gen_push(&o, gxf_at(g3(IN_W - 0.45, 0, OFFICE_D - 0.45), 0));
    plant(&o, rng, "plant", 1.0);
    gen_pop(&o);

    gen_object(&o, "mirror");
    gen_push(&o, gxf_at(g3(IN_W, 1.0, 1.0), -90));
    mirror_on_wall(&o, 0.7, 1.0);
    gen_pop(&o);

    gen_object(&o, "whiteboard");
    gen_push(&o, gxf_at(g3(IN_W, 0.9, 2.9), -90));
    gen_material(&o, "frame_alu");
    gen_box(&o, g3(-0.82, -0.02, 0), g3(0.82, 1.12, 0.02), GEN_ALL & ~GEN_ZN);
    gen_box(&o, g3(-0.6, -0.06, 0), g3(0.6, -0.02, 0.07), GEN_ALL & ~GEN_ZN);
    gen_material(&o, "whiteboard");
    gen_quad(&o, g3(-0.8, 0, 0.021), g3(1.6, 0, 0), g3(0, 1.1, 0), g3(0, 0, 1));
    gen_pop(&o);

    gen_pop(&o);
    long prims = o.prims;
    gen_count(cnt, &o);
    if (gen_close(&o, GEN_NAME)) return -1;
    return (int)prims;
}

static int corridor(const char *dir, grng *rng, gcounts *cnt)
{
    gobj o;
    if (gen_open(&o, dir, "corridor.obj", "office.mtl", GEN_NAME)) return -1;
    gen_object(&o, "floor");
    gen_material(&o, "linoleum");
    panel_rect(&o, g3(0, 0, -COR_HALF), g3(1, 0, 0), g3(0, 0, 1), COR_LEN, 2 * COR_HALF, 0.5,
               g3(0, 1, 0));
    gen_object(&o, "ceiling");
    gen_material(&o, "ceiling_tile");
    panel_rect(&o, g3(0, HEIGHT, -COR_HALF), g3(1, 0, 0), g3(0, 0, 1), COR_LEN, 2 * COR_HALF, 0.6,
               g3(0, -1, 0));
    gen_object(&o, "walls");
    gen_material(&o, "paint_white");
    /* corridor faces of the office walls; north offices run +x from x = 0,
     * south ones are turned by 180 degrees so their openings mirror */
    opening hn[2 * OFFICES_PER_SIDE], hs[2 * OFFICES_PER_SIDE];
    for (int k = 0; k < OFFICES_PER_SIDE; k++) {
        double x0 = OFFICE_W * k + WALL / 2;
        hn[2 * k] = (opening){x0 + DOOR_X0, x0 + DOOR_X1, 0, DOOR_H};
        hn[2 * k + 1] = (opening){x0 + WIN_X0, x0 + WIN_X1, WIN_Y0, WIN_Y1};
        double x1 = OFFICE_W * (k + 1) - WALL / 2;
        hs[2 * k] = (opening){x1 - DOOR_X1, x1 - DOOR_X0, 0, DOOR_H};
        hs[2 * k + 1] = (opening){x1 - WIN_X1, x1 - WIN_X0, WIN_Y0, WIN_Y1};
    }
    wall_face(&o, g3(0, 0, COR_HALF), g3(1, 0, 0), COR_LEN, g3(0, 0, -1), hn, 2 * OFFICES_PER_SIDE);
    wall_face(&o, g3(0, 0, -COR_HALF), g3(1, 0, 0), COR_LEN, g3(0, 0, 1), hs, 2 * OFFICES_PER_SIDE);
    wall_face(&o, g3(0, 0, -COR_HALF), g3(0, 0, 1), 2 * COR_HALF, g3(1, 0, 0), NULL, 0);
    wall_face(&o, g3(COR_LEN, 0, -COR_HALF), g3(0, 0, 1), 2 * COR_HALF, g3(-1, 0, 0), NULL, 0);

    for (int k = 0; k < 2 * OFFICES_PER_SIDE; k++) {
        char name[32];
        snprintf(name, sizeof name, "ceiling_light_%d", k + 1);
        ceiling_light(&o, name, 1.5 + 3.0 * k, 0, 1.2, 0.4);
    }

    for (int k = 0; k < 2; k++) {
        gen_object(&o, "bench_%d", k + 1);
        double x = 2.05 + 12.0 * k;   /* in front of south windows */
        gen_material(&o, "wood_desk");
        for (int s = 0; s < 4; s++)
            gen_box(&o, g3(x - 0.7, 0.42, -COR_HALF + 0.06 + 0.085 * s),
                    g3(x + 0.7, 0.45, -COR_HALF + 0.13 + 0.085 * s), GEN_ALL);
        gen_material(&o, "metal_brushed");
        for (int l = 0; l < 4; l++)
            gen_rod(&o, g3(x + (l & 1 ? 0.6 : -0.6), 0, -COR_HALF + (l & 2 ? 0.33 : 0.1)),
                    g3(x + (l & 1 ? 0.6 : -0.6), 0.42, -COR_HALF + (l & 2 ? 0.33 : 0.1)), 0.018, 12);
    }
    static const double px[3] = {0.55, COR_LEN - 0.55, COR_LEN / 2};
    static const double pz[3] = {COR_HALF - 0.55, -COR_HALF + 0.55, COR_HALF - 0.55};
    for (int k = 0; k < 3; k++) {
        char name[32];
        snprintf(name, sizeof name, "plant_%d", k + 1);
        gen_push(&o, gxf_at(g3(px[k], 0, pz[k]), 37.0 * k));
        plant(&o, rng, name, 1.2);
        gen_pop(&o);
    }

    gen_object(&o, "end_mirror");
    gen_push(&o, gxf_at(g3(COR_LEN, 0.3, 0), -90));
    mirror_on_wall(&o, 1.6, 2.2);
    gen_pop(&o);

    gen_object(&o, "painting");
    gen_push(&o, gxf_at(g3(0, 1.0, 0), 90));
    gen_material(&o, "frame_alu");
    gen_box(&o, g3(-0.7, -0.05, 0), g3(0.7, 1.05, 0.03), GEN_ALL & ~GEN_ZN);
    static const char *const cols[] = {"book_red", "book_blue", "book_orange", "book_cream"};
    for (int k = 0; k < 4; k++) {
        gen_material(&o, cols[k]);
        gen_quad(&o, g3(-0.65 + 0.325 * k, 0.0, 0.031), g3(0.325, 0, 0), g3(0, 1.0, 0), g3(0, 0, 1));
    }
    gen_pop(&o);

    long prims = o.prims;
    gen_count(cnt, &o);
    if (gen_close(&o, GEN_NAME)) return -1;
    return (int)prims;
}

static int write_mtl(const char *dir)
{
    /* Ward (metal_brushed, frame_alu), mirror, glass and the emitters are
     * (re)defined in office.json; the rest is plain MTL (Kd; Ks/Ns with illum 2
     * a Phong lobe: assimp reports a missing illum as 1, no highlight). */
    return gen_write_mtl(dir, GEN_NAME,
            "newmtl carpet_grey\nKd 0.32 0.32 0.33\n\n"
            "newmtl carpet_blue\nKd 0.16 0.2 0.32\n\n"
            "newmtl linoleum\nKd 0.55 0.5 0.42\nKs 0.12 0.12 0.12\nNs 40\nillum 2\n\n"
            "newmtl ceiling_tile\nKd 0.82 0.82 0.8\n\n"
            "newmtl paint_white\nKd 0.78 0.77 0.74\n\n"
            "newmtl paint_sage\nKd 0.55 0.62 0.5\n\n"
            "newmtl paint_sand\nKd 0.72 0.63 0.48\n\n"
            "newmtl light_housing\nKd 0.8 0.8 0.8\n\n"
            "newmtl light_panel\nKd 0.8 0.8 0.8\nKe 10 9.5 8.5\n\n"
            "newmtl lamp_bulb\nKd 0.8 0.8 0.8\nKe 40 34 25\n\n"
            "newmtl wood_desk\nKd 0.55 0.38 0.22\nKs 0.1 0.1 0.1\nNs 80\nillum 2\n\n"
            "newmtl wood_shelf\nKd 0.35 0.22 0.12\n\n"
            "newmtl plastic_black\nKd 0.04 0.04 0.04\nKs 0.25 0.25 0.25\nNs 90\nillum 2\n\n"
            "newmtl plastic_grey\nKd 0.3 0.3 0.3\nKs 0.15 0.15 0.15\nNs 60\nillum 2\n\n"
            "newmtl plastic_white\nKd 0.75 0.75 0.74\nKs 0.2 0.2 0.2\nNs 120\nillum 2\n\n"
            "newmtl screen\nKd 0.01 0.01 0.015\nKs 0.3 0.3 0.3\nNs 800\nillum 2\n\n"
            "newmtl whiteboard\nKd 0.8 0.8 0.8\nKs 0.15 0.15 0.15\nNs 400\nillum 2\n\n"
            "newmtl fabric_blue\nKd 0.1 0.15 0.4\n\n"
            "newmtl fabric_red\nKd 0.45 0.08 0.07\n\n"
            "newmtl fabric_green\nKd 0.12 0.32 0.14\n\n"
            "newmtl shade_red\nKd 0.55 0.05 0.04\nKs 0.3 0.3 0.3\nNs 100\nillum 2\n\n"
            "newmtl shade_yellow\nKd 0.6 0.5 0.05\nKs 0.3 0.3 0.3\nNs 100\nillum 2\n\n"
            "newmtl shade_teal\nKd 0.05 0.35 0.35\nKs 0.3 0.3 0.3\nNs 100\nillum 2\n\n"
            "newmtl mug_white\nKd 0.8 0.8 0.78\nKs 0.25 0.25 0.25\nNs 200\nillum 2\n\n"
            "newmtl mug_blue\nKd 0.1 0.2 0.5\nKs 0.25 0.25 0.25\nNs 200\nillum 2\n\n"
            "newmtl paper\nKd 0.85 0.85 0.82\n\n"
            GEN_MTL_BOOKS
            "newmtl book_orange\nKd 0.7 0.35 0.06\n\n"
            "newmtl book_grey\nKd 0.4 0.4 0.42\n\n"
            "newmtl terracotta\nKd 0.55 0.27 0.15\n\n"
            "newmtl soil\nKd 0.12 0.08 0.05\n\n"
            "newmtl leaf\nKd 0.1 0.35 0.08\n\n"
            "newmtl metal_brushed\nKd 0.04 0.04 0.04\nKs 0.6 0.6 0.6\nNs 300\nillum 2\n\n"
            "newmtl frame_alu\nKd 0.1 0.1 0.1\nKs 0.5 0.5 0.5\nNs 200\nillum 2\n\n"
            GEN_MTL_MIRROR_GLASS);
}

int main(int argc, char **argv)
{
    const char *dir = gen_outdir(argc, argv, GEN_NAME);
    if (!dir) return 2;
    long total = 0;
    if (write_mtl(dir)) return 1;
    grng rng = grng_seed(20000, 7);
    gcounts cnt = {0, 0, 0, 0, 0, 0};
    int n = corridor(dir, &rng, &cnt);
    if (n < 0) return 1;
    total += n;
    for (int side = 0; side < 2; side++)
        for (int k = 0; k < OFFICES_PER_SIDE; k++) {
            int idx = side * OFFICES_PER_SIDE + k + 1;
            /* north offices: local x along +x, z away from the corridor;
             * south ones turned by 180 degrees about y */
            gxf place = side == 0
                            ? gxf_at(g3(OFFICE_W * k + WALL / 2, 0, COR_HALF + WALL), 0)
                            : gxf_at(g3(OFFICE_W * (k + 1) - WALL / 2, 0, -COR_HALF - WALL), 180);
            grng r = grng_seed(20000 + (uint64_t)idx, 11);
            n = office(dir, idx, place, &r, &cnt);
            if (n < 0) return 1;
            total += n;
        }
    if (gen_write_counts(dir, GEN_NAME, &cnt)) return 1;
    printf("  " GEN_NAME ": %ld primitives in %d rooms\n", total, 2 * OFFICES_PER_SIDE + 1);
    return 0;
}

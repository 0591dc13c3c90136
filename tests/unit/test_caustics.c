/* Tests of the lamps' reflective caustics (tracer/caustics.h) against the
 * closed form of a lamp seen in a mirror ceiling (tests/support
 * testscenes.h, ts_mirror_lamp). */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/radmesh.h"
#include "tests/support/testscenes.h"
#include "tracer/caustics.h"
#include "tracer/embree_scene.h"
#include "tracer/lights.h"
#include "tracer/mirror_lights.h"

#define CHECK(x) do { int rc_ = (x); cr_assert_eq(rc_, 0, "%s: %s", #x, err.msg); } while (0)

typedef struct fixture {
    ct_scene *s;
    ct_radmesh rad;
    emb_scene *e;
} fixture;

static void open_scene(fixture *f)
{
    ct_error err;
    f->s = ts_mirror_lamp(false, false, false, &err);
    cr_assert(f->s, "%s", err.msg);
    CHECK(rmesh_from_scene(f->s, v3s(0.0f), &f->rad, &err));
    emb_mesh m = emb_mesh_of_radmesh(&f->rad, f->s);
    CHECK(emb_new(&m, NULL, &f->e, &err));
}

static void close_scene(fixture *f)
{
    emb_free(f->e);
    rmesh_free(&f->rad);
    scene_free(f->s);
}

/* The floor under a mirror ceiling sees the lamp's image: its caustic
 * irradiance is pi R L_e F(image), F the form factor to the image
 * (ts_mirror_lamp_floor is rho times that). Checked at the floor's vertices
 * well away from the lamp's own shadow and the floor's edges, where the
 * density estimate's disc lies on the floor and the light is smooth. */
Test(caustics, a_lamp_in_a_mirror_ceiling_lights_the_floor_as_its_image)
{
    fixture f;
    open_scene(&f);
    ct_error err;
    vec3 *E;
    caus_stats st;
    CHECK(caus_build(f.e, NULL, 2000000, 1, NULL, 0, &E, &st, &err));
    cr_assert(E, "photons must land on the floor");
    double sum_ratio = 0.0, sum2 = 0.0, worst = 0.0;
    int n = 0;
    for (uint32_t i = 0; i < f.rad.nverts; i++) {
        vec3 p = f.rad.pos[i];
        bool away = (p.x <= 0.5f || p.x >= 3.5f) && p.x >= -3.0f && p.x <= 6.0f && fabsf(p.z) <= 3.0f;
        if (fabsf(p.y) > 1e-6f || !away || f.rad.nrm[i].y < 0.99f) continue;
        vec3 want = v3_scale(ts_mirror_lamp_floor(p.x, p.z), (float)M_PI / 0.5f);
        double r = (double)E[i].x / (double)want.x;
        /* the channels keep the lamp's colour times the mirror's */
        double rz = (double)E[i].z / (double)want.z;
        sum_ratio += r;
        sum2 += (r - 1.0) * (r - 1.0);
        n++;
        if (fabs(r - 1.0) > worst) worst = fabs(r - 1.0);
        if (fabs(rz - 1.0) > worst) worst = fabs(rz - 1.0);
    }
    double rms = sqrt(sum2 / n);
    printf("metric: caustic under a mirror ceiling: %d floor vertices, mean ratio %.4f, rms %.4f, worst %.4f; %llu "
           "photons, %llu landed, %.2f s\n",
           n, sum_ratio / n, rms, worst, (unsigned long long)st.photons, (unsigned long long)st.deposits, st.seconds);
    cr_assert(n >= 50, "only %d floor vertices checked", n);
    /* A density estimate of about CAUS_KNN photons: about 9 % noise a
     * vertex, and its mean unbiased where the light is smooth */
    cr_expect(fabs(sum_ratio / n - 1.0) < 0.03, "mean ratio %.4f", sum_ratio / n);
    cr_expect(rms < 0.12, "rms deviation %.4f", rms);
    cr_expect(worst < 0.35, "worst ratio off by %.4f", worst);
    free(E);
    close_scene(&f);
}

/* Where drt samples the lamp's image in a plane mirror (mirror_lights.h),
 * a photon's one reflection by that mirror is not a caustic: counting it
 * again would double the floor's light. */
Test(caustics, one_reflection_by_a_sampled_plane_mirror_is_left_out)
{
    fixture f;
    open_scene(&f);
    ct_error err;
    light_set *lights;
    mlight_set *ms;
    CHECK(light_build(f.e, &lights, &err));
    CHECK(mlight_build(f.e, lights, &ms, &err));
    cr_assert_eq(mlight_count(ms), 1, "the ceiling is one sampled mirror");
    vec3 *E;
    caus_stats st;
    CHECK(caus_build(f.e, ms, 200000, 1, NULL, 0, &E, &st, &err));
    printf("metric: a sampled plane mirror alone: %llu photons shot, %llu kept\n", (unsigned long long)st.photons,
           (unsigned long long)st.deposits);
    cr_expect_eq(st.deposits, 0, "%llu photons kept", (unsigned long long)st.deposits);
    cr_expect(E == NULL, "no caustic");
    free(E);
    mlight_free(ms);
    light_free(lights);
    close_scene(&f);
}

/* No mirror and no glass: nothing is shot. */
Test(caustics, a_scene_without_mirrors_or_glass_has_none)
{
    ct_error err;
    ct_scene *s = ts_mirror_lamp(false, false, true, &err);
    cr_assert(s, "%s", err.msg);
    ct_radmesh rad;
    CHECK(rmesh_from_scene(s, v3s(0.0f), &rad, &err));
    emb_mesh m = emb_mesh_of_radmesh(&rad, s);
    emb_scene *e;
    CHECK(emb_new(&m, NULL, &e, &err));
    vec3 *E = (vec3 *)&err;
    caus_stats st;
    CHECK(caus_build(e, NULL, 1000, 1, NULL, 0, &E, &st, &err));
    cr_expect(E == NULL && st.photons == 0, "a diffuse ceiling makes no caustic");
    emb_free(e);
    rmesh_free(&rad);
    scene_free(s);
}

/* The photons are shot and the vertices estimated in pieces of a fixed size
 * whatever the threads, the deposits joined in photon order: the same
 * caustic, bit for bit, on one thread and on several (a photon count that
 * leaves the last piece short). */
Test(caustics, the_same_on_any_number_of_threads)
{
    fixture f;
    open_scene(&f);
    ct_error err;
    vec3 *E1, *E3;
    caus_stats s1, s3;
    CHECK(caus_build(f.e, NULL, 100001, 7, NULL, 1, &E1, &s1, &err));
    CHECK(caus_build(f.e, NULL, 100001, 7, NULL, 3, &E3, &s3, &err));
    cr_assert(E1 && E3, "photons must land on the floor");
    cr_expect_eq(s1.deposits, s3.deposits, "%llu deposits on one thread, %llu on three",
                 (unsigned long long)s1.deposits, (unsigned long long)s3.deposits);
    uint32_t lit = 0;
    for (uint32_t i = 0; i < f.rad.nverts; i++) lit += E1[i].x > 0.0f;
    cr_expect(lit > 0, "no vertex lit");
    cr_expect(memcmp(E1, E3, f.rad.nverts * sizeof *E1) == 0, "the caustics differ between one and three threads");
    free(E1);
    free(E3);
    close_scene(&f);
}

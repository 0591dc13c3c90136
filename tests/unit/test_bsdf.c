/* Reflection models: energy bounds of the glossy lobes, pdf normalization,
 * sampling consistent with evaluation, Fresnel. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <xmmintrin.h>

#include "common/rng.h"
#include "tracer/bsdf.h"

static vec3 dir_theta(float th) { return v3(sinf(th), 0.0f, cosf(th)); }

static bsdf make(const scene_material *m, float theta_o)
{
    bsdf b;
    bsdf_init(&b, m, v3(0, 0, 1), v3(0, 0, 1), dir_theta(theta_o));
    return b;
}

/* Numerical hemisphere integrals (midpoint rule in theta, phi) of the glossy
 * lobe's f cos (albedo) and of its sampling pdf. */
static void integrate(const bsdf *b, vec3 wo, double *albedo, double *pdf_mass)
{
    const int nt = 1024, np = 2048;
    double a = 0.0, p = 0.0;
    for (int i = 0; i < nt; i++) {
        double th = (i + 0.5) * (M_PI / 2) / nt;
        double dw = sin(th) * (M_PI / 2 / nt) * (2 * M_PI / np);
        for (int j = 0; j < np; j++) {
            double ph = (j + 0.5) * 2 * M_PI / np;
            vec3 wi = v3((float)(sin(th) * cos(ph)), (float)(sin(th) * sin(ph)), (float)cos(th));
            vec3 f = bsdf_eval_glossy(b, wo, wi);
            a += f.x * cos(th) * dw;
            p += bsdf_pdf_glossy(b, wo, wi) * dw;
        }
    }
    *albedo = a;
    *pdf_mass = p;
}

/* Mean sampling weight (an estimate of the albedo through the sampler). */
static double sampled_albedo(const bsdf *b, vec3 wo, int n)
{
    ct_rng r = rng_make(7, 1, 2, 3);
    double sum = 0.0;
    for (int i = 0; i < n; i++) {
        bsdf_sample s;
        float u1 = rng_float(&r), u2 = rng_float(&r);
        if (bsdf_sample_glossy(b, wo, u1, u2, &s)) sum += s.weight.x;
    }
    return sum / n;
}

static void check_lobe(const scene_material *m, const char *what)
{
    static const float angles[] = {0.0f, 15.0f, 30.0f, 45.0f, 60.0f, 75.0f, 85.0f, 89.0f};
    float rho = m->specular.x;
    for (size_t k = 0; k < sizeof angles / sizeof angles[0]; k++) {
        float th = angles[k] * CT_PI / 180.0f;
        bsdf b = make(m, th);
        vec3 wo = dir_theta(th);
        double albedo, mass;
        integrate(&b, wo, &albedo, &mass);
        cr_expect(albedo <= rho * 1.005, "%s at %g deg: albedo %g > rho_s %g", what, (double)angles[k],
                  albedo, (double)rho);
        cr_expect(mass <= 1.005, "%s at %g deg: pdf integrates to %g > 1", what, (double)angles[k], mass);
        double est = sampled_albedo(&b, wo, 200000);
        cr_expect(fabs(est - albedo) <= 0.02 * rho + 0.01 * albedo,
                  "%s at %g deg: sampled albedo %g vs integrated %g", what, (double)angles[k], est, albedo);
        if (angles[k] == 0.0f) {
            /* At normal incidence the whole lobe is above the horizon. */
            cr_expect(mass > 0.97, "%s: pdf mass %g at normal incidence", what, mass);
        }
    }
}

Test(bsdf, phong_lobe_conserves_energy)
{
    static const float exps[] = {1.0f, 10.0f, 100.0f, 1000.0f};
    for (size_t i = 0; i < sizeof exps / sizeof exps[0]; i++) {
        scene_material m = scene_material_default("phong");
        m.glossy = SCENE_GLOSSY_PHONG;
        m.specular = v3s(0.8f);
        m.phong_exp = exps[i];
        char what[64];
        snprintf(what, sizeof what, "phong n=%g", (double)exps[i]);
        check_lobe(&m, what);
        /* Normalized: at normal incidence the albedo is exactly rho_s. */
        bsdf b = make(&m, 0.0f);
        double albedo, mass;
        integrate(&b, dir_theta(0.0f), &albedo, &mass);
        cr_expect(fabs(albedo - 0.8) < 0.01, "%s: normal-incidence albedo %g != 0.8", what, albedo);
    }
}

Test(bsdf, ward_lobe_conserves_energy)
{
    static const float ax[] = {0.05f, 0.1f, 0.3f, 0.05f, 0.5f};
    static const float ay[] = {0.05f, 0.1f, 0.3f, 0.3f, 0.2f};
    for (size_t i = 0; i < sizeof ax / sizeof ax[0]; i++) {
        scene_material m = scene_material_default("ward");
        m.glossy = SCENE_GLOSSY_WARD;
        m.specular = v3s(0.9f);
        m.ward_ax = ax[i];
        m.ward_ay = ay[i];
        m.ward_tangent = v3(1, 1, 0);   /* projected onto the surface: diagonal */
        char what[64];
        snprintf(what, sizeof what, "ward ax=%g ay=%g", (double)ax[i], (double)ay[i]);
        check_lobe(&m, what);
    }
}

Test(bsdf, diffuse_sampling_matches_albedo)
{
    scene_material m = scene_material_default("d");
    m.diffuse = v3(0.25f, 0.5f, 0.75f);
    bsdf b = make(&m, 0.3f);
    ct_rng r = rng_make(1, 2, 3, 4);
    double sum = 0.0;
    for (int i = 0; i < 10000; i++) {
        bsdf_sample s;
        float u0 = rng_float(&r), u1 = rng_float(&r), u2 = rng_float(&r);
        cr_assert(bsdf_sample_all(&b, dir_theta(0.3f), u0, u1, u2, &s));
        cr_assert(s.wi.z > 0.0f);
        sum += s.weight.y;
    }
    cr_expect(fabs(sum / 10000 - 0.5) < 1e-4, "diffuse weight %g", sum / 10000);
}

Test(bsdf, fresnel_limits)
{
    float ct;
    float f0 = bsdf_fresnel(1.0f, 1.0f / 1.5f, &ct);
    cr_expect(fabsf(f0 - 0.04f) < 1e-5f, "normal-incidence F %g != 0.04", (double)f0);
    cr_expect(fabsf(ct - 1.0f) < 1e-6f);
    /* Leaving glass beyond the critical angle asin(1/1.5) = 41.8 deg: TIR. */
    float f = bsdf_fresnel(cosf(45.0f * CT_PI / 180.0f), 1.5f, &ct);
    cr_expect(f == 1.0f && ct == 0.0f, "no total internal reflection: F %g", (double)f);
    /* Symmetry: F entering at theta_i equals F leaving at theta_t. */
    float ci = cosf(60.0f * CT_PI / 180.0f);
    float fin = bsdf_fresnel(ci, 1.0f / 1.5f, &ct);
    float ct2, fout = bsdf_fresnel(ct, 1.5f, &ct2);
    cr_expect(fabsf(fin - fout) < 1e-5f, "F in %g != F out %g", (double)fin, (double)fout);
    cr_expect(fabsf(ct2 - ci) < 1e-5f);
}

Test(bsdf, dielectric_refraction_obeys_snell)
{
    scene_material m = scene_material_default("glass");
    m.dielectric = 1;
    m.ior = 1.5f;
    m.transmission = v3s(1.0f);
    float th = 50.0f * CT_PI / 180.0f;
    bsdf b = make(&m, th);
    vec3 wr, wt;
    bool ok;
    float f = bsdf_dielectric(&b, dir_theta(th), &wr, &wt, &ok);
    cr_assert(ok);
    cr_expect(f > 0.0f && f < 1.0f);
    float sin_t = sqrtf(wt.x * wt.x + wt.y * wt.y);
    cr_expect(fabsf(sinf(th) - 1.5f * sin_t) < 1e-5f, "Snell violated");
    cr_expect(wt.z < 0.0f && wt.x < 0.0f, "refracted ray must continue through the surface");
    cr_expect(fabsf(wr.x + sinf(th)) < 1e-6f && fabsf(wr.z - cosf(th)) < 1e-6f);
}

/* Checks every value the lobes return at (wo, wi) is finite and >= 0. */
static void expect_finite(const bsdf *b, vec3 wo, vec3 wi, const char *what, float co)
{
    vec3 f = bsdf_eval_glossy(b, wo, wi);
    float p = bsdf_pdf_glossy(b, wo, wi), pa;
    vec3 fa = bsdf_eval(b, wo, wi, &pa);
    cr_assert(isfinite(f.x) && f.x >= 0.0f, "%s: f = %g at cos %g", what, (double)f.x, (double)co);
    cr_assert(isfinite(p) && p >= 0.0f, "%s: pdf = %g at cos %g", what, (double)p, (double)co);
    cr_assert(isfinite(fa.x) && isfinite(pa), "%s: eval %g pdf %g at cos %g", what, (double)fa.x, (double)pa,
              (double)co);
}

/* Ward at grazing angles (the cause of a NaN once seen in a drt reference):
 * with wi and wo within 1e-10 of the horizon near the mirror direction,
 * (h.n)^4 underflows and f became inf (then inf * 0 = NaN in the
 * estimators). Every value must stay finite, with and without the tracer's
 * flush-to-zero mode. */
Test(bsdf, ward_is_finite_at_grazing_angles)
{
    const float coss[] = {1e-3f, 1e-6f, 1e-8f, 1e-10f, 1e-12f, 1e-20f, 1e-30f, 1e-40f, 0.0f};
    scene_material m = scene_material_default("brushed");
    m.diffuse = v3s(0.04f);
    m.glossy = SCENE_GLOSSY_WARD;
    m.specular = v3(0.62f, 0.6f, 0.56f);
    m.ward_tangent = v3(0.1f, 1.0f, 0.1f);
    const float alphas[][2] = {{0.04f, 0.25f}, {1e-5f, 0.5f}, {0.3f, 0.3f}};
    unsigned csr = _mm_getcsr();
    for (int ftz = 0; ftz < 2; ftz++) {
        _mm_setcsr(ftz ? csr | 0x8040u : csr & ~0x8040u);
        for (int a = 0; a < 3; a++) {
            m.ward_ax = alphas[a][0];
            m.ward_ay = alphas[a][1];
            for (size_t i = 0; i < sizeof coss / sizeof *coss; i++) {
                float c = coss[i], s = sqrtf(1.0f - c * c);
                for (int k = 0; k < 8; k++) {
                    float ph = 2.0f * CT_PI * (float)k / 8.0f;
                    vec3 wo = v3(s * cosf(ph), s * sinf(ph), c);
                    vec3 mirror = v3(-wo.x, -wo.y, wo.z);
                    vec3 side = v3(-s * sinf(ph), s * cosf(ph), c);
                    bsdf b;
                    bsdf_init(&b, &m, v3(0, 0, 1), v3(0, 0, 1), wo);
                    expect_finite(&b, wo, mirror, "mirror direction", c);
                    expect_finite(&b, wo, wo, "retro direction", c);
                    expect_finite(&b, wo, side, "sideways", c);
                    expect_finite(&b, wo, v3(0, 0, 1), "normal", c);
                    ct_rng g = rng_make(11, (uint64_t)i, (uint64_t)k, (uint64_t)a);
                    for (int n = 0; n < 200; n++) {
                        bsdf_sample sm;
                        float u0 = rng_float(&g), u1 = rng_float(&g), u2 = rng_float(&g);
                        if (bsdf_sample_glossy(&b, wo, u1, u2, &sm))
                            cr_assert(isfinite(sm.weight.x) && isfinite(sm.pdf) && sm.pdf > 0.0f,
                                      "glossy sample weight %g pdf %g at cos %g", (double)sm.weight.x,
                                      (double)sm.pdf, (double)c);
                        if (bsdf_sample_all(&b, wo, u0, u1, u2, &sm))
                            cr_assert(isfinite(sm.weight.x) && isfinite(sm.pdf),
                                      "sample weight %g pdf %g at cos %g", (double)sm.weight.x, (double)sm.pdf,
                                      (double)c);
                    }
                }
            }
        }
    }
    _mm_setcsr(csr);
}

/* The MIS power heuristic stays in [0, 1] when a squared pdf overflows (a
 * light seen at a grazing angle): inf / inf would be NaN. */
Test(bsdf, power_heuristic_survives_overflow)
{
    cr_expect_float_eq(bsdf_power_heuristic(1.0f, 1.0f), 0.5f, 1e-7f);
    cr_expect_float_eq(bsdf_power_heuristic(3.0f, 4.0f), 9.0f / 25.0f, 1e-7f);
    cr_expect_eq(bsdf_power_heuristic(0.0f, 0.0f), 0.0f);
    cr_expect_eq(bsdf_power_heuristic(2.0f, 0.0f), 1.0f);
    const float big[][2] = {{1e20f, 1.0f}, {1.0f, 1e20f}, {1e20f, 3e19f}, {3e19f, 1e20f}, {INFINITY, 1.0f},
                            {1.0f, INFINITY}, {INFINITY, INFINITY}, {3e38f, 3e38f}};
    for (size_t i = 0; i < sizeof big / sizeof *big; i++) {
        float w = bsdf_power_heuristic(big[i][0], big[i][1]), v = bsdf_power_heuristic(big[i][1], big[i][0]);
        cr_assert(w >= 0.0f && w <= 1.0f, "w(%g, %g) = %g", (double)big[i][0], (double)big[i][1], (double)w);
        cr_expect(fabsf(w + v - 1.0f) < 1e-6f, "w(a,b) + w(b,a) = %g", (double)(w + v));
    }
    cr_expect_float_eq(bsdf_power_heuristic(1e20f, 3e19f), 1.0f / (1.0f + 0.09f), 1e-6f);
    cr_expect_eq(bsdf_power_heuristic(NAN, 1.0f), 0.0f);
}

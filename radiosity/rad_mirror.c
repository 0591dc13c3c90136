/* rad_mirror.c: the radiosity solution's light from lamps seen in plane
 * mirrors (rad_internal.h). Radiosity has no specular transport, so a
 * mirror is black in it; but on a scene like `table` most of the light on
 * the floor under the table comes from the ceiling lamps by way of the wall
 * mirror (docs/radiosity.md). That light is a source term: each leaf's
 * irradiance from the lamps' mirror images (sampled as drt samples them,
 * tracer/mirror_lights.h) is added to what its links gather, so it is
 * reflected on through the links like any direct light, and the final
 * gather adds it again at each vertex, sampled there. It counts as direct
 * light (rad_direct): drt, which samples the same light at its hits, takes
 * the mesh's indirect part as rad - rad_direct. The sampling needs a tracer
 * scene of the scene's triangles next to the solver's own visibility scene
 * (only when the scene has a plane mirror). */
#include "radiosity/rad_internal.h"

#include <stdlib.h>

#include "common/rng.h"
#include "tracer/embree_scene.h"
#include "tracer/lights.h"
#include "tracer/mirror_lights.h"

/* The third stream id of the mirror samples' random numbers. */
#define RAD_MIRROR_STREAM 0x6d6972726f72ULL

/* The patches on a plane mirror whose lamp images are sampled: their
 * mirror layer passes the lamps' light on by those images, so it must not
 * pass it on again through their radiosity (rho_ml, push_pull). */
static void mark_mirror_patches(rad_ctx *c)
{
    for (uint32_t pi = 0; pi < c->npatches; pi++) {
        rad_patch *p = &c->patches[pi];
        const scene_material *m = &c->scene->mats[p->mat];
        if (!mlight_material(m)) continue;
        vec3 x = rad_el(c, p->root)->c;
        for (uint32_t i = 0; i < mlight_count(c->mirrors); i++) {
            const mlight_plane *pl = mlight_get(c->mirrors, i);
            if (!mlight_same_kind(pl, p->mat, p->n) || fabsf(mlight_side(pl, x)) > 1e3f * rad_pos_tol(x, rad_el(c, p->root)->radius) || !mlight_in_bounds(pl, x))
                continue;
            p->rho_ml = v3_min(v3_max(m->mirror, v3s(0.0f)), p->rho_t);
            break;
        }
    }
}

int rad_mirror_new(rad_ctx *c, ct_error *err)
{
    const ct_scene *s = c->scene;
    if (c->prm.mirror_samples <= 0) return CT_OK;
    bool any = false;
    for (uint32_t i = 0; i < s->nmats && !any; i++)
        any = mlight_material(&s->mats[i]);
    if (!any) return CT_OK;
    emb_mesh m = emb_mesh_of_scene(s);
    int rc = emb_new(&m, NULL, &c->memb, err);
    if (!rc) rc = light_build(c->memb, &c->mlamps, err);
    if (!rc) rc = mlight_build(c->memb, c->mlamps, &c->mirrors, err);
    if (rc || mlight_count(c->mirrors) == 0 || light_count(c->mlamps) == 0) {
        rad_mirror_free(c);
        return rc;
    }
    mark_mirror_patches(c);
    return CT_OK;
}

void rad_mirror_free(rad_ctx *c)
{
    mlight_free(c->mirrors);
    light_free(c->mlamps);
    emb_free(c->memb);
    c->mirrors = NULL;
    c->mlamps = NULL;
    c->memb = NULL;
}

vec3 rad_mirror_leaf(const rad_ctx *c, const rad_elem *e)
{
    int n = c->prm.mirror_samples;
    vec3 nx = c->patches[e->patch].n, sum = v3s(0.0f);
    ct_rng r = rng_make(c->prm.seed, e->key, RAD_MIRROR_STREAM, 0);
    for (int k = 0; k < n; k++) {
        float u = rng_float(&r), v = rng_float(&r);
        vec3 x = rad_elem_point(e, u, v);
        sum = v3_add(sum, mlight_irradiance(c->mirrors, c->memb, c->mlamps, x, nx, emb_offset_ray(x, nx), 1, &r));
    }
    return v3_scale(sum, 1.0f / (float)n);
}

vec3 rad_mirror_point(const rad_ctx *c, vec3 x, vec3 n, uint64_t key)
{
    ct_rng r = rng_make(c->prm.seed, key, RAD_MIRROR_STREAM, 1);
    return mlight_irradiance(c->mirrors, c->memb, c->mlamps, x, n, emb_offset_ray(x, n), c->prm.mirror_samples, &r);
}

/* radmesh.h: the interactive solution as a triangle mesh with per-vertex
 * radiosity: what the display draws (Gouraud), what tracer ranks intersect
 * and what L_base is interpolated on. Radiosity is stored as outgoing
 * radiance (B / pi), total and its direct part (light straight from
 * emitters), per vertex. The node table mirrors the scene's, so node ids in
 * samples, textures and the display agree. The .ctmesh cache format is
 * specified in docs/radiosity.md and implemented in radmesh_io.c. */
#ifndef CT_RADMESH_H
#define CT_RADMESH_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/error.h"
#include "common/scene.h"
#include "common/vecmath.h"

typedef struct rmesh_node {
    char name[SCENE_NAME_LEN];
    int32_t parent;
    uint32_t node_end;
    uint32_t material;
    bounds3 bounds;
} rmesh_node;

/* What the display needs of a material to draw it: glass (a dielectric) is
 * see-through in the interactive solution, the surfaces behind it drawn
 * times transmission * (1 - F) per crossing (F: Fresnel reflectance at the
 * crossing's angle on the outside, rmesh_glass_pass); every other material
 * is opaque (ior 0). docs/radiosity.md, "Glass". */
typedef struct rmesh_material {
    vec3 transmission;   /* per crossing, before Fresnel */
    float ior;           /* index of refraction inside; 0: opaque */
} rmesh_material;

typedef struct ct_radmesh {
    uint32_t nverts;
    vec3 *pos;
    vec3 *nrm;
    vec3 *rad;          /* total outgoing radiance per vertex */
    vec3 *rad_direct;   /* its direct-lighting part */
    uint32_t ntris;
    uint32_t *tris;     /* 3 indices per triangle */
    uint32_t *tri_node; /* scene part node per triangle */
    uint32_t *tri_mat;  /* scene material per triangle */
    uint32_t nnodes;
    rmesh_node *nodes;
    uint32_t nmats;       /* materials; tri_mat beyond them draws opaque */
    rmesh_material *mats;
    uint64_t scene_hash;  /* hash of the scene file and solver parameters */
} ct_radmesh;

/* Most materials a mesh may carry (file and wire). */
#define RMESH_MAX_MATS (1u << 16)

/* Glass surfaces a straight ray crosses at most: beyond them the tracer's
 * shadow rays and L_base, and the radiosity view, take the ray as blocked. */
#define RMESH_MAX_GLASS_CROSSINGS 16

/* Allocates a mesh with the given counts (arrays zeroed). */
int rmesh_alloc(ct_radmesh *m, uint32_t nverts, uint32_t ntris, uint32_t nnodes, ct_error *err);

/* What the interactive solution draws of scene material x: a dielectric
 * see-through (an unset index of refraction taken as 1, as the tracer does:
 * a surface that only tints), anything else opaque. */
static inline rmesh_material rmesh_material_of(const scene_material *x)
{
    rmesh_material r = {{0.0f, 0.0f, 0.0f}, 0.0f};
    if (x->dielectric) {
        r.transmission = x->transmission;
        r.ior = x->ior > 0.0f ? x->ior : 1.0f;
    }
    return r;
}

/* Sets m's material table from the scene's materials (rmesh_material_of);
 * replaces any table m had. */
int rmesh_set_materials(ct_radmesh *m, const ct_scene *s, ct_error *err);

/* A material read from a file or the wire is usable: a finite index of
 * refraction (0 or positive) and a finite transmission in [0, 1]. */
static inline bool rmesh_material_ok(const rmesh_material *x)
{
    vec3 t = x->transmission;
    bool unit = t.x >= 0.0f && t.x <= 1.0f && t.y >= 0.0f && t.y <= 1.0f && t.z >= 0.0f && t.z <= 1.0f;
    return unit && x->ior >= 0.0f && x->ior <= 1e6f;
}

/* Exact unpolarized Fresnel reflectance of a dielectric for cos_i >= 0 and
 * eta = n_i / n_t; *cos_t receives the refracted cosine (0 on total internal
 * reflection, where the result is 1). The tracer's dielectric (bsdf_fresnel)
 * and the glass of the interactive solution share it. */
float rmesh_fresnel(float cos_i, float eta, float *cos_t);

/* What one straight crossing of glass x passes at cos = d . n (either
 * side): transmission * (1 - F), F at the crossing's angle on the outside
 * (air) side, leaving as well as entering: the light a straight ray stands
 * for is refracted into a pane and out of it at the same outside angle, and
 * by reciprocity the exit loses what the entry did. The display's glass
 * pass computes the same in GLSL. */
static inline vec3 rmesh_glass_pass(const rmesh_material *x, float cos)
{
    float ct, f = rmesh_fresnel(fabsf(cos), 1.0f / x->ior, &ct);
    return v3_scale(x->transmission, 1.0f - f);
}

/* Whether material mat of m is see-through glass. */
static inline bool rmesh_is_glass(const ct_radmesh *m, uint32_t mat)
{
    return mat < m->nmats && m->mats[mat].ior > 0.0f;
}

/* Frees the arrays and zeroes the struct. */
void rmesh_free(ct_radmesh *m);

/* Whether m is a solution of scene s: the node tables agree (count, names,
 * materials), or node ids and materials would refer to another scene's
 * parts. CT_ESTALE naming the first difference otherwise. */
int rmesh_check_nodes(const ct_radmesh *m, const ct_scene *s, ct_error *err);

/* A mesh with the scene's own triangles and a constant radiance per vertex
 * taken from each material (emission + diffuse * ambient): a stand-in
 * interactive solution for tests and for runs before radiosity exists. */
int rmesh_from_scene(const ct_scene *s, vec3 ambient, ct_radmesh *m, ct_error *err);

/* Writes the mesh as a .ctmesh cache file, atomically (radmesh_io.c),
 * after rmesh_output_check. */
int rmesh_save(const ct_radmesh *m, const char *path, ct_error *err);

/* Whether path may receive a .ctmesh: fs_output_check, and an existing
 * regular file must be empty or a .ctmesh (CT_EINVAL naming it otherwise),
 * so a slip of the output name does not replace a scene or a document. */
int rmesh_output_check(const char *path, ct_error *err);

/* Reads a .ctmesh file; checks magic, version, endianness and sizes. When
 * expect_hash is not 0, a file whose scene_hash differs fails with CT_ESTALE. */
int rmesh_load(const char *path, uint64_t expect_hash, ct_radmesh *m, ct_error *err);

/* The .ctmesh bytes of m in a new buffer (*out, freed by the caller). */
int rmesh_encode(const ct_radmesh *m, unsigned char **out, size_t *len, ct_error *err);

/* Decodes .ctmesh bytes with every check of rmesh_load; name (a path) goes
 * into error messages. */
int rmesh_decode(const unsigned char *data, size_t len, const char *name, uint64_t expect_hash,
                 ct_radmesh *m, ct_error *err);

/* Gouraud interpolation on triangle t at Embree barycentrics (u, v):
 * (1-u-v) * v0 + u * v1 + v * v2, exactly the value GL draws there. */
static inline vec3 rmesh_eval(const ct_radmesh *m, uint32_t t, float u, float v)
{
    const uint32_t *i = m->tris + 3 * (size_t)t;
    float w = 1.0f - u - v;
    vec3 a = m->rad[i[0]], b = m->rad[i[1]], c = m->rad[i[2]];
    return v3(w * a.x + u * b.x + v * c.x, w * a.y + u * b.y + v * c.y, w * a.z + u * b.z + v * c.z);
}

/* The same for the direct part. */
static inline vec3 rmesh_eval_direct(const ct_radmesh *m, uint32_t t, float u, float v)
{
    const uint32_t *i = m->tris + 3 * (size_t)t;
    float w = 1.0f - u - v;
    vec3 a = m->rad_direct[i[0]], b = m->rad_direct[i[1]], c = m->rad_direct[i[2]];
    return v3(w * a.x + u * b.x + v * c.x, w * a.y + u * b.y + v * c.y, w * a.z + u * b.z + v * c.z);
}

#endif

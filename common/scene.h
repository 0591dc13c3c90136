/* scene.h: the scene model every program shares. Geometry is flattened to
 * world space: vertices (position, normal) and triangles, each triangle
 * carrying its mesh-part node, its material and the input polygon it came
 * from (a quad gives two triangles with one primitive id). Nodes keep the
 * modeling hierarchy: root (scene file) -> file (one mesh file instance) ->
 * group (object/group inside the file, nested) -> part (one material's
 * triangles of a mesh). Nodes are stored in depth-first pre-order and
 * triangles in the order of their part nodes, so every node's subtree is the
 * node range [id, node_end) and the triangle range [tri_begin, tri_end).
 * Import from JSON scene files is in scene_load.c (docs/scene-format.md). */
#ifndef CT_SCENE_H
#define CT_SCENE_H

#include <stddef.h>
#include <stdint.h>

#include "common/campath.h"
#include "common/camera.h"
#include "common/error.h"
#include "common/vecmath.h"

#define SCENE_NAME_LEN 64

typedef enum scene_node_kind {
    SCENE_NODE_ROOT  = 0,
    SCENE_NODE_FILE  = 1,
    SCENE_NODE_GROUP = 2,
    SCENE_NODE_PART  = 3
} scene_node_kind;

typedef struct scene_node {
    char name[SCENE_NAME_LEN];
    scene_node_kind kind;
    int32_t parent;        /* -1 for the root */
    uint32_t node_end;     /* one past the last descendant */
    uint32_t tri_begin, tri_end;
    uint32_t material;     /* parts: their material; others: UINT32_MAX */
    bounds3 bounds;
} scene_node;

/* Glossy lobe of a material. */
typedef enum scene_glossy {
    SCENE_GLOSSY_NONE  = 0,
    SCENE_GLOSSY_PHONG = 1,   /* normalized Phong lobe around the mirror direction */
    SCENE_GLOSSY_WARD  = 2    /* Ward 1992 anisotropic */
} scene_glossy;

/* A layered material: every layer may be present at once (e.g. diffuse +
 * Phong from an MTL file); reflectances are RGB albedos in [0, 1]. */
typedef struct scene_material {
    char name[SCENE_NAME_LEN];
    vec3 diffuse;          /* Lambertian rho_d */
    scene_glossy glossy;
    vec3 specular;         /* rho_s of the glossy lobe */
    float phong_exp;       /* Phong exponent */
    float ward_ax, ward_ay;/* Ward roughness along tangent / bitangent */
    vec3 ward_tangent;     /* world direction projected onto the surface */
    vec3 mirror;           /* perfect mirror rho_m */
    int dielectric;        /* 1: refractive interface */
    float ior;             /* index of refraction inside */
    vec3 transmission;     /* transmission colour (per crossing) */
    vec3 emission;         /* L_e, radiance emitted from the front side */
} scene_material;

/* Primary kind of a material for statistics ("diffuse", "phong", "ward",
 * "mirror", "dielectric", "emissive"). */
const char *scene_material_kind(const scene_material *m);

/* A material with all layers zero and the given name. */
scene_material scene_material_default(const char *name);

/* Maximum glossiness in [0, 1] (0 = diffuse, 1 = mirror/glass): how fast a
 * material's appearance changes with the view direction (§3.5 aging). */
float scene_material_glossiness(const scene_material *m);

typedef struct scene_named_camera {
    char name[SCENE_NAME_LEN];
    ct_camera cam;
    vec3 target;   /* for round-tripping and info */
    vec3 up;
    float fov_deg;
} scene_named_camera;

typedef struct ct_scene {
    char name[SCENE_NAME_LEN];
    char source[1024];          /* path of the scene file (or "" when built) */
    uint64_t source_hash;       /* content hash of the scene and its meshes */

    uint32_t nverts, cap_verts;
    vec3 *pos, *nrm;

    uint32_t ntris, cap_tris;
    uint32_t *tris;             /* 3 vertex indices per triangle */
    uint32_t *tri_node;         /* part node of each triangle */
    uint32_t *tri_mat;          /* material of each triangle */
    uint32_t *tri_prim;         /* input polygon of each triangle */
    uint32_t nprims;            /* input polygons (triangles, quads, n-gons) */
    uint32_t nquads;            /* of which quads */

    uint32_t nnodes, cap_nodes;
    scene_node *nodes;

    uint32_t nmats, cap_mats;
    scene_material *mats;

    uint32_t ncams;
    scene_named_camera *cams;

    uint32_t npaths;
    ct_campath *paths;

    uint32_t nemitters;         /* triangles with emission > 0 */
    uint32_t *emitters;
    uint32_t dropped_degenerate;/* degenerate triangles dropped on import */

    bounds3 bounds;

    /* builder state */
    int32_t open_stack[64];
    int open_depth;
} ct_scene;

/* --- lifecycle ------------------------------------------------------------ */

/* An empty scene with a root node named `name` open for building. */
ct_scene *scene_new(const char *name);

/* Frees the scene and everything it owns (NULL is fine). */
void scene_free(ct_scene *s);

/* Loads a JSON scene file and the meshes it names (docs/scene-format.md). */
int scene_load(const char *path, ct_scene **out, ct_error *err);

/* --- building (used by the loader, generators and tests) ------------------ */

/* Adds a material; returns its index or a negative error code. */
int scene_add_material(ct_scene *s, const scene_material *m, ct_error *err);

/* Index of the material with that name, or -1. */
int scene_find_material(const ct_scene *s, const char *name);

/* Opens a child node of the currently open node; returns its id or < 0. */
int scene_begin_node(ct_scene *s, const char *name, scene_node_kind kind, uint32_t material,
                     ct_error *err);

/* Closes the currently open node (fills node_end, triangle range, bounds). */
int scene_end_node(ct_scene *s, ct_error *err);

/* Adds a vertex; returns its index or < 0. */
int64_t scene_add_vertex(ct_scene *s, vec3 pos, vec3 nrm, ct_error *err);

/* Adds a polygon of n >= 3 vertex indices to the open part node (quads and
 * n-gons count as one primitive): a convex polygon is fanned from its first
 * vertex (a quad as (0,1,2), (0,2,3)), a concave one cut into ears in the
 * plane of its normal. Degenerate triangles are dropped and counted.
 * Returns 0 or < 0. */
int scene_add_polygon(ct_scene *s, const uint32_t *idx, int n, ct_error *err);

/* Newell's normal of a polygon (unit; robust for non-planar ones). */
vec3 scene_polygon_normal(const ct_scene *s, const uint32_t *idx, int n);

/* Adds a named camera. */
int scene_add_camera(ct_scene *s, const char *name, vec3 eye, vec3 target, vec3 up,
                     float fov_deg, ct_error *err);

/* Adds a camera path (the scene takes ownership of p's keyframes). */
int scene_add_path(ct_scene *s, ct_campath *p, ct_error *err);

/* Closes the root, computes bounds and the emitter list, validates (non-empty,
 * finite). Call once after building. */
int scene_finalize(ct_scene *s, ct_error *err);

/* --- queries -------------------------------------------------------------- */

/* Index of the camera with that name, or -1. */
int scene_find_camera(const ct_scene *s, const char *name);

/* Index of the path with that name, or -1. */
int scene_find_path(const ct_scene *s, const char *name);

/* A --path value: the scene's path of that name first, else a path file
 * loaded into *own (freed by the caller with campath_free when its keys are
 * set). A folder or file named like a scene path (walk/ of an earlier run)
 * does not hide the path. NULL with err naming both tries when neither
 * works; scene_file names the scene in that message. */
const ct_campath *scene_path_or_file(const ct_scene *s, const char *scene_file, const char *name, ct_campath *own,
                                     ct_error *err);

/* Geometric (face) normal and area of triangle t. */
vec3 scene_tri_normal(const ct_scene *s, uint32_t t);
float scene_tri_area(const ct_scene *s, uint32_t t);

/* Number of children of node n and iteration over them. */
uint32_t scene_first_child(const ct_scene *s, uint32_t n);   /* == node_end if none */
uint32_t scene_next_sibling(const ct_scene *s, uint32_t c);  /* == parent's node_end if last */

#endif

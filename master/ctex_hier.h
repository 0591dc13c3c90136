/* ctex_hier.h: the texture hierarchy (§3.3): the scene's modeling hierarchy
 * (the radiosity mesh's node table) refined, wherever a node has more than
 * two children, by a bounding-volume hierarchy that groups children by space
 * and by material ("a modified hierarchical bounding volume method"). Leaves
 * are single mesh parts, or, for a part with more than cluster_tris
 * triangles, clusters of its triangles (split by normal, then by space). Nodes are in depth-first pre-order, so a subtree is
 * the node range [id, end), its leaves the range [leaf_begin, leaf_end) and
 * its triangles the range [tri_begin, tri_end) of the permuted arrays. Each
 * node carries what assignment and projection need: bounds, area-weighted
 * average normal, normal spread, coplanarity, the object-local frame of flat
 * nodes, and the maximum glossiness of its materials. */
#ifndef CT_MASTER_CTEX_HIER_H
#define CT_MASTER_CTEX_HIER_H

#include <stdint.h>

#include "common/error.h"
#include "common/radmesh.h"
#include "common/scene.h"
#include "common/vecmath.h"

typedef struct ctex_hnode {
    bounds3 bounds;
    int32_t parent;        /* -1 for the root */
    uint32_t end;          /* one past the last descendant */
    uint32_t leaf_begin, leaf_end;
    uint32_t tri_begin, tri_end;
    int32_t scene_node;    /* modeling node, -1 for a BVH node */
    uint32_t material;     /* the single material of the subtree, UINT32_MAX if mixed */
    float gloss;           /* max scene_material_glossiness below (§3.5) */
    vec3 normal;           /* area-weighted average unit normal (0 if none) */
    float spread_deg;      /* max angle between a triangle normal and `normal` */
    float area;            /* surface area */
    int flat;              /* §3.2: object-local projection applies */
    /* object-local frame of a flat node: p = o + t*u + b*v, u, v in [0,1] */
    vec3 o, t, b;
} ctex_hnode;

typedef struct ctex_hier {
    uint32_t nnodes;
    ctex_hnode *nodes;     /* [0] is the root */
    uint32_t nleaves;
    uint32_t *leaf_node;   /* leaf index -> hierarchy node */
    uint32_t *leaf_part;   /* leaf index -> scene part node */
    uint32_t npart_map;
    int32_t *part_leaf;    /* scene node id -> leaf index; -1 not a part, -2 split into clusters */
    int32_t *part_hnode;   /* scene node id -> its hierarchy node (leaf or cluster root), -1 */
    uint32_t ntris;
    uint32_t *tris;        /* mesh triangle ids, grouped by leaf in leaf order */
    uint32_t *tri_leaf;    /* mesh triangle id -> leaf index */
} ctex_hier;

/* Builds the hierarchy. flat_deg / flat_thickness: §3.2 flatness test;
 * mat_weight: BVH cost factor for groups mixing materials; cluster_tris:
 * largest part kept as one leaf (0: parts are never split). */
int ctex_hier_build(const ct_radmesh *m, const scene_material *mats, uint32_t nmats,
                    float flat_deg, float flat_thickness, float mat_weight, uint32_t cluster_tris,
                    ctex_hier *h, ct_error *err);

/* Frees the arrays. */
void ctex_hier_free(ctex_hier *h);

#endif

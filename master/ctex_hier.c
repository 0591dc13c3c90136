/* ctex_hier.c: builds the texture hierarchy (ctex_hier.h): modeling
 * hierarchy from the mesh's node table, BVH refinement by space and material
 * where a node has more than two children, and per-node geometry. Over 600
 * lines on purpose: one recursive build over one builder state (items,
 * keys, the node array); its steps call each other both ways. */
#include "master/ctex_hier.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MIXED UINT32_MAX
#define MINF(a, b) ((a) < (b) ? (a) : (b))
#define MAXF(a, b) ((a) > (b) ? (a) : (b))

/* Per modeling node: statistics of its own triangles and of its subtree. */
typedef struct mstat {
    uint32_t own, total;      /* triangle counts */
    bounds3 own_b, sub_b;
    uint32_t own_mat, sub_mat;/* single material or MIXED (UINT32_MAX - 1 = none yet) */
    float own_gloss, sub_gloss;
} mstat;

#define NOMAT (UINT32_MAX - 1)
/* A cluster this deep in its part's tree stays whole: a bound on the
 * recursion, far above what the balanced gap cuts reach. */
#define CLUSTER_DEPTH_MAX 256

static uint32_t mat_merge(uint32_t a, uint32_t b)
{
    if (a == NOMAT) return b;
    if (b == NOMAT) return a;
    return a == b ? a : MIXED;
}

/* An entry of a child list: a modeling node (own = 0) or a node's own
 * triangles as a pseudo leaf (own = 1). */
typedef struct item {
    uint32_t node;
    int own;
    bounds3 b;
    vec3 c;
    uint32_t mat;
    float gloss;
} item;

typedef struct builder {
    const ct_radmesh *m;
    mstat *st;
    ctex_hier *h;
    uint32_t cap;
    float mat_weight;
    int32_t *leaf_of_node;    /* modeling node -> leaf index of its own triangles */
    uint32_t *sorted;         /* mesh triangles grouped by node */
    uint32_t *node_start;     /* first entry of each node in sorted */
    uint32_t fill;            /* triangles placed in h->tris so far */
    uint32_t cluster_max;     /* split parts with more triangles (0: never) */
    float flat_cos;           /* cos(flat_deg): normal agreement of a flat cluster */
    float flat_thickness;     /* coplanarity of a flat cluster */
    float normal_gap;         /* 2 sin(flat_deg / 2): normal components of faces flat_deg apart */
    struct tkey { float k; uint32_t t; } *keys;   /* scratch for partitioning */
    ct_error *err;
} builder;

static int new_node(builder *B, int32_t parent, int32_t snode, uint32_t *id)
{
    if (B->h->nnodes >= B->cap) {
        /* clusters split at gaps are not bounded by cluster_max: grow */
        if (B->cap >= UINT32_MAX / 4) return ct_fail(B->err, CT_ERANGE, "texture hierarchy overflow");
        uint32_t ncap = 2 * B->cap;
        ctex_hnode *nodes = realloc(B->h->nodes, (size_t)ncap * sizeof *nodes);
        if (nodes) B->h->nodes = nodes;
        uint32_t *ln = nodes ? realloc(B->h->leaf_node, (size_t)ncap * sizeof *ln) : NULL;
        if (ln) B->h->leaf_node = ln;
        uint32_t *lp = ln ? realloc(B->h->leaf_part, (size_t)ncap * sizeof *lp) : NULL;
        if (!lp) return ct_fail(B->err, CT_ENOMEM, "out of memory building the texture hierarchy");
        B->h->leaf_part = lp;
        B->cap = ncap;
    }
    *id = B->h->nnodes++;
    ctex_hnode *n = &B->h->nodes[*id];
    memset(n, 0, sizeof *n);
    n->parent = parent;
    n->scene_node = snode;
    n->leaf_begin = B->h->nleaves;
    return CT_OK;
}

static int emit_items(builder *B, item *it, uint32_t k, int32_t parent, int depth);

/* A leaf over triangles [begin, end) of h->tris, of scene part `part`. */
static int tri_leaf(builder *B, uint32_t part, int32_t snode, uint32_t begin, uint32_t end, int32_t parent)
{
    uint32_t id = 0;
    int rc = new_node(B, parent, snode, &id);
    if (rc) return rc;
    uint32_t li = B->h->nleaves++;
    B->h->leaf_node[li] = id;
    B->h->leaf_part[li] = part;
    ctex_hnode *n = &B->h->nodes[id];
    n->tri_begin = begin;
    n->tri_end = end;
    n->end = B->h->nnodes;
    n->leaf_end = B->h->nleaves;
    return CT_OK;
}

/* Quickselect: reorders keys[0, n) so that keys[k] is in sorted position. */
static void select_k(struct tkey *a, uint32_t n, uint32_t k)
{
    uint32_t lo = 0, hi = n - 1;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        /* median of three as pivot */
        if (a[mid].k < a[lo].k) { struct tkey t = a[mid]; a[mid] = a[lo]; a[lo] = t; }
        if (a[hi].k < a[lo].k) { struct tkey t = a[hi]; a[hi] = a[lo]; a[lo] = t; }
        if (a[hi].k < a[mid].k) { struct tkey t = a[hi]; a[hi] = a[mid]; a[mid] = t; }
        float piv = a[mid].k;
        uint32_t i = lo, j = hi;
        while (i <= j) {
            while (a[i].k < piv) i++;
            while (a[j].k > piv) j--;
            if (i <= j) {
                struct tkey t = a[i]; a[i] = a[j]; a[j] = t;
                i++;
                if (j == 0) break;
                j--;
            }
        }
        if (k <= j) hi = j;
        else if (k >= i) lo = i;
        else break;
    }
}

/* Whether triangles [begin, end) of h->tris are flat: their unit normals'
 * mean is longer than cos(flat_deg) and they are coplanar (extent along it at
 * most flat_thickness times the largest box extent). A flat set stays one
 * leaf whatever its size: its clusters would interleave (a radiosity mesh
 * has long slivers) and split one object-local texture into strips. */
static int tris_flat(const builder *B, uint32_t begin, uint32_t end)
{
    const ct_radmesh *m = B->m;
    const uint32_t *tris = B->h->tris;
    vec3 nsum = v3s(0.0f);
    bounds3 bb = b3_empty();
    for (uint32_t i = begin; i < end; i++) {
        const uint32_t *v = m->tris + 3 * (size_t)tris[i];
        vec3 a = m->pos[v[0]], b = m->pos[v[1]], c = m->pos[v[2]];
        nsum = v3_add(nsum, v3_norm(v3_cross(v3_sub(b, a), v3_sub(c, a))));
        bb = b3_add(b3_add(b3_add(bb, a), b), c);
    }
    vec3 mean = v3_scale(nsum, 1.0f / (float)(end - begin));
    if (!(v3_len(mean) >= B->flat_cos)) return 0;
    vec3 n = v3_norm(mean);
    float dmin = INFINITY, dmax = -INFINITY;
    for (uint32_t i = begin; i < end; i++) {
        const uint32_t *v = m->tris + 3 * (size_t)tris[i];
        for (int k = 0; k < 3; k++) {
            float d = v3_dot(m->pos[v[k]], n);
            dmin = MINF(dmin, d);
            dmax = MAXF(dmax, d);
        }
    }
    return dmax - dmin <= B->flat_thickness * v3_maxc(b3_extent(bb));
}

static vec3 tri_normal(const ct_radmesh *m, uint32_t t)
{
    const uint32_t *v = m->tris + 3 * (size_t)t;
    vec3 a = m->pos[v[0]], b = m->pos[v[1]], c = m->pos[v[2]];
    return v3_norm(v3_cross(v3_sub(b, a), v3_sub(c, a)));
}

static vec3 tri_centroid(const ct_radmesh *m, uint32_t t)
{
    const uint32_t *v = m->tris + 3 * (size_t)t;
    return v3_scale(v3_add(m->pos[v[0]], v3_add(m->pos[v[1]], m->pos[v[2]])), 1.0f / 3.0f);
}

static int key_less(const void *a, const void *b)
{
    const struct tkey *x = a, *y = b;
    if (x->k != y->k) return x->k < y->k ? -1 : 1;
    return x->t < y->t ? -1 : (x->t > y->t);
}

/* Sorts keys[0, n) (so that the result does not depend on the triangles'
 * order) and looks at the gaps between consecutive values: returns the
 * widest one's width and, in *cut, the middle of the gap at least min_gap
 * wide that divides the keys most evenly (a balanced tree when a part has
 * many parallel faces; *cut is NAN when no gap is that wide). */
static float split_gap(struct tkey *k, uint32_t n, float min_gap, float *cut)
{
    qsort(k, n, sizeof *k, key_less);
    float widest = 0.0f;
    uint32_t best_off = UINT32_MAX;
    *cut = NAN;
    for (uint32_t i = 0; i + 1 < n; i++) {
        float g = k[i + 1].k - k[i].k;
        widest = MAXF(widest, g);
        if (!(g >= min_gap)) continue;
        uint32_t below = i + 1, off = below > n / 2 ? below - n / 2 : n / 2 - below;
        if (off < best_off) { best_off = off; *cut = k[i].k + 0.5f * g; }
    }
    return widest;
}

/* Moves the keys below cut to the front; returns how many there are. */
static uint32_t partition_keys(struct tkey *k, uint32_t n, float cut)
{
    uint32_t lo = 0;
    for (uint32_t i = 0; i < n; i++)
        if (k[i].k < cut) { struct tkey t = k[i]; k[i] = k[lo]; k[lo] = t; lo++; }
    return lo;
}

enum { KEY_NORMAL_X, KEY_NORMAL_Y, KEY_NORMAL_Z, KEY_OFFSET };

/* keys[i] := the key of triangle begin + i: a normal component, or the
 * offset of its centroid along dir. */
static void fill_keys(builder *B, uint32_t begin, uint32_t end, int what, vec3 dir)
{
    const uint32_t *tris = B->h->tris;
    for (uint32_t i = begin; i < end; i++) {
        uint32_t t = tris[i];
        float k = what == KEY_OFFSET ? v3_dot(tri_centroid(B->m, t), dir)
                                     : v3_get(tri_normal(B->m, t), what);
        B->keys[i - begin].k = k;
        B->keys[i - begin].t = t;
    }
}

/* Chooses how a cluster [begin, end) of a large part splits, reordering its
 * triangles so that [begin, *mid) and [*mid, end) are the halves; returns 0
 * when it stays one leaf. In this order:
 *   1. a gap of at least 2 sin(flat_deg / 2) in the sorted values of the
 *      normal component with the widest gap: two groups of faces at least
 *      flat_deg apart (the walls, reveals and faces of a box-like part), at
 *      any size. Cutting at
 *      a gap, never inside a group of equal normals, keeps each face whole:
 *      a cut at a fixed value (0 between walls facing +x and -x) would split
 *      the faces perpendicular to them by rounding noise, and their
 *      triangles would draw two textures interleaved;
 *   2. a flat set (tris_flat) stays whole, whatever its size;
 *   3. normals that agree but faces that are not coplanar (parallel faces at
 *      different offsets: a wall and the reveals of its doors): a gap in the
 *      centroids' offsets along the mean normal wider than flat_thickness
 *      times the set's extent, at any size, so that the wall stays flat;
 * (of several such gaps, the one that halves the set most evenly);
 *   4. above cluster_max triangles: the median centroid along the longest
 *      axis (a curved surface, which has no gaps). */
static int choose_split(builder *B, uint32_t begin, uint32_t end, int depth, uint32_t *mid)
{
    uint32_t n = end - begin;
    if (n < 2 || depth > CLUSTER_DEPTH_MAX) return 0;
    uint32_t *tris = B->h->tris;
    struct tkey *k = B->keys;
    int best = -1;
    float best_gap = 0.0f, best_cut = NAN, cut;
    for (int axis = KEY_NORMAL_X; axis <= KEY_NORMAL_Z; axis++) {
        fill_keys(B, begin, end, axis, v3s(0.0f));
        float g = split_gap(k, n, B->normal_gap, &cut);
        if (g > best_gap) { best_gap = g; best_cut = cut; best = axis; }
    }
    int what = -1;
    vec3 dir = v3s(0.0f);
    float at = 0.0f;
    if (best >= 0 && !isnan(best_cut)) {
        what = best;
        at = best_cut;
    } else if (!tris_flat(B, begin, end)) {
        vec3 nsum = v3s(0.0f);
        bounds3 bb = b3_empty();
        for (uint32_t i = begin; i < end; i++) {
            nsum = v3_add(nsum, tri_normal(B->m, tris[i]));
            bb = b3_add(bb, tri_centroid(B->m, tris[i]));
        }
        if (v3_len(nsum) >= B->flat_cos * (float)n) {
            dir = v3_norm(nsum);
            fill_keys(B, begin, end, KEY_OFFSET, dir);
            (void)split_gap(k, n, B->flat_thickness * v3_maxc(b3_extent(bb)), &cut);
            if (!isnan(cut)) {
                what = KEY_OFFSET;
                at = cut;
            }
        }
        if (what < 0 && n > B->cluster_max) {
            vec3 e = b3_extent(bb);
            int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
            for (uint32_t i = begin; i < end; i++) {
                k[i - begin].k = v3_get(tri_centroid(B->m, tris[i]), axis);
                k[i - begin].t = tris[i];
            }
            select_k(k, n, n / 2);
            for (uint32_t i = 0; i < n; i++) tris[begin + i] = k[i].t;
            *mid = begin + n / 2;
            return 1;
        }
    }
    if (what < 0) return 0;
    fill_keys(B, begin, end, what, dir);
    uint32_t lo = partition_keys(k, n, at);
    if (lo == 0 || lo == n) return 0;   /* cannot happen for a cut inside a gap */
    for (uint32_t i = 0; i < n; i++) tris[begin + i] = k[i].t;
    *mid = begin + lo;
    return 1;
}

/* Emits the halves [begin, mid) and [mid, end) of a split cluster below
 * parent: a leaf for a half that choose_split keeps whole, else a node over
 * the clusters of that half. */
static int emit_split(builder *B, uint32_t part, uint32_t begin, uint32_t mid, uint32_t end,
                      int32_t parent, int depth)
{
    for (int side = 0; side < 2; side++) {
        uint32_t a = side ? mid : begin, b = side ? end : mid, m2 = 0;
        if (!choose_split(B, a, b, depth + 1, &m2)) {
            int rc = tri_leaf(B, part, -1, a, b, parent);
            if (rc) return rc;
            continue;
        }
        uint32_t id = 0;
        int rc = new_node(B, parent, -1, &id);
        if (!rc) rc = emit_split(B, part, a, m2, b, (int32_t)id, depth + 1);
        if (rc) return rc;
        B->h->nodes[id].end = B->h->nnodes;
        B->h->nodes[id].leaf_end = B->h->nleaves;
    }
    return CT_OK;
}

/* The clusters of a large part's triangles [begin, end) below parent. */
static int emit_tris(builder *B, uint32_t part, uint32_t begin, uint32_t end, int32_t parent)
{
    uint32_t mid = 0;
    if (!choose_split(B, begin, end, 0, &mid)) return tri_leaf(B, part, -1, begin, end, parent);
    return emit_split(B, part, begin, mid, end, parent, 0);
}

/* A leaf for node's own triangles, or a node over clusters of them when
 * there are more than cluster_max. */
static int emit_leaf(builder *B, uint32_t node, int32_t parent)
{
    uint32_t count = B->st[node].own, begin = B->fill;
    memcpy(B->h->tris + begin, B->sorted + B->node_start[node], count * sizeof(uint32_t));
    B->fill += count;
    if (!B->cluster_max || count <= B->cluster_max || tris_flat(B, begin, begin + count)) {
        B->leaf_of_node[node] = (int32_t)B->h->nleaves;
        B->h->part_hnode[node] = (int32_t)B->h->nnodes;
        return tri_leaf(B, node, (int32_t)node, begin, begin + count, parent);
    }
    uint32_t id = 0;
    int rc = new_node(B, parent, (int32_t)node, &id);
    if (rc) return rc;
    B->leaf_of_node[node] = -2;   /* split: leaves by triangle */
    B->h->part_hnode[node] = (int32_t)id;
    rc = emit_tris(B, node, begin, begin + count, (int32_t)id);
    if (rc) return rc;
    B->h->nodes[id].end = B->h->nnodes;
    B->h->nodes[id].leaf_end = B->h->nleaves;
    return CT_OK;
}

/* Child items of modeling node n (non-empty subtrees, plus own triangles). */
static uint32_t gather(builder *B, uint32_t n, item *out)
{
    const ct_radmesh *m = B->m;
    uint32_t k = 0;
    if (B->st[n].own > 0) {
        out[k].node = n; out[k].own = 1; out[k].b = B->st[n].own_b;
        out[k].mat = B->st[n].own_mat; out[k].gloss = B->st[n].own_gloss; k++;
    }
    for (uint32_t c = n + 1; c < m->nodes[n].node_end && c < m->nnodes; c = m->nodes[c].node_end) {
        if (m->nodes[c].node_end <= c) break;   /* malformed table: stop */
        if (B->st[c].total == 0) continue;
        out[k].node = c; out[k].own = 0; out[k].b = B->st[c].sub_b;
        out[k].mat = B->st[c].sub_mat; out[k].gloss = B->st[c].sub_gloss; k++;
    }
    for (uint32_t i = 0; i < k; i++) out[i].c = b3_center(out[i].b);
    return k;
}

static int emit_modeling(builder *B, uint32_t n, int32_t parent, int depth)
{
    if (depth > 200) return ct_fail(B->err, CT_ERANGE, "modeling hierarchy deeper than 200 levels");
    /* a pure part: a leaf */
    if (B->st[n].own == B->st[n].total) return emit_leaf(B, n, parent);
    uint32_t nch = 0;
    for (uint32_t c = n + 1; c < B->m->nodes[n].node_end && c < B->m->nnodes; c = B->m->nodes[c].node_end) {
        if (B->m->nodes[c].node_end <= c) break;
        nch++;
    }
    item *it = malloc((nch + 1) * sizeof *it);
    if (!it) return ct_fail(B->err, CT_ENOMEM, "out of memory building the texture hierarchy");
    uint32_t k = gather(B, n, it);
    uint32_t id = 0;
    int rc = new_node(B, parent, (int32_t)n, &id);
    if (!rc) rc = emit_items(B, it, k, (int32_t)id, depth + 1);
    free(it);
    if (rc) return rc;
    B->h->nodes[id].end = B->h->nnodes;
    B->h->nodes[id].leaf_end = B->h->nleaves;
    return CT_OK;
}

static int emit_item(builder *B, const item *x, int32_t parent, int depth)
{
    if (x->own) return emit_leaf(B, x->node, parent);
    return emit_modeling(B, x->node, parent, depth);
}

typedef struct okey { double k1, k2, k3; uint32_t i; } okey;

static int okey_cmp(const void *a, const void *b)
{
    const okey *x = a, *y = b;
    if (x->k1 != y->k1) return x->k1 < y->k1 ? -1 : 1;
    if (x->k2 != y->k2) return x->k2 < y->k2 ? -1 : 1;
    if (x->k3 != y->k3) return x->k3 < y->k3 ? -1 : 1;
    return x->i < y->i ? -1 : (x->i > y->i);
}

/* Splits items into two groups minimizing the BVH cost
 * area(A) nA (1 + w mixA) + area(B) nB (1 + w mixB) over the orders by x, y,
 * z centroid and by (glossiness, material, longest axis). Reorders `it` so
 * that the first *na items form group A. */
static int split_items(builder *B, item *it, uint32_t k, int depth, uint32_t *na)
{
    okey *keys = malloc(k * sizeof *keys);
    okey *best_keys = malloc(k * sizeof *keys);
    float *suffix = malloc(k * sizeof *suffix);
    uint32_t *smat = malloc(k * sizeof *smat);
    if (!keys || !best_keys || !suffix || !smat) {
        free(keys); free(best_keys); free(suffix); free(smat);
        return ct_fail(B->err, CT_ENOMEM, "out of memory building the texture hierarchy");
    }
    bounds3 all = b3_empty();
    for (uint32_t i = 0; i < k; i++) all = b3_union(all, it[i].b);
    vec3 ext = b3_extent(all);
    int longest = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    double best = INFINITY;
    uint32_t best_na = k / 2;
    int have = 0;
    /* Degenerate recursion guard: fall back to a median split on the longest axis. */
    int norders = depth > 48 ? 1 : 4;
    for (int ord = 0; ord < norders; ord++) {
        int axis = depth > 48 ? longest : ord;
        for (uint32_t i = 0; i < k; i++) {
            keys[i].i = i;
            if (axis < 3) {
                keys[i].k1 = v3_get(it[i].c, axis); keys[i].k2 = 0; keys[i].k3 = 0;
            } else {
                keys[i].k1 = it[i].gloss;
                keys[i].k2 = it[i].mat == MIXED ? 1e12 : (double)it[i].mat;
                keys[i].k3 = v3_get(it[i].c, longest);
            }
        }
        qsort(keys, k, sizeof *keys, okey_cmp);
        if (depth > 48) {
            memcpy(best_keys, keys, k * sizeof *keys);
            best_na = k / 2;
            have = 1;
            break;
        }
        /* suffix areas and materials */
        bounds3 sb = b3_empty();
        uint32_t sm = NOMAT;
        for (uint32_t i = k; i-- > 0;) {
            sb = b3_union(sb, it[keys[i].i].b);
            sm = mat_merge(sm, it[keys[i].i].mat);
            suffix[i] = b3_area(sb);
            smat[i] = sm;
        }
        bounds3 pb = b3_empty();
        uint32_t pm = NOMAT;
        for (uint32_t i = 0; i + 1 < k; i++) {
            pb = b3_union(pb, it[keys[i].i].b);
            pm = mat_merge(pm, it[keys[i].i].mat);
            double ca = (double)b3_area(pb) * (double)(i + 1) * (1.0 + B->mat_weight * (pm == MIXED));
            double cb = (double)suffix[i + 1] * (double)(k - i - 1) * (1.0 + B->mat_weight * (smat[i + 1] == MIXED));
            double cost = ca + cb;
            if (cost < best) {
                best = cost;
                best_na = i + 1;
                memcpy(best_keys, keys, k * sizeof *keys);
                have = 1;
            }
        }
    }
    if (have) {
        item *tmp = malloc(k * sizeof *tmp);
        if (!tmp) {
            free(keys); free(best_keys); free(suffix); free(smat);
            return ct_fail(B->err, CT_ENOMEM, "out of memory building the texture hierarchy");
        }
        for (uint32_t i = 0; i < k; i++) tmp[i] = it[best_keys[i].i];
        memcpy(it, tmp, k * sizeof *tmp);
        free(tmp);
    }
    *na = best_na;
    free(keys); free(best_keys); free(suffix); free(smat);
    return CT_OK;
}

static int emit_group(builder *B, item *it, uint32_t k, int32_t parent, int depth)
{
    if (k == 1) return emit_item(B, it, parent, depth);
    uint32_t id = 0;
    int rc = new_node(B, parent, -1, &id);
    if (!rc) rc = emit_items(B, it, k, (int32_t)id, depth + 1);
    if (rc) return rc;
    B->h->nodes[id].end = B->h->nnodes;
    B->h->nodes[id].leaf_end = B->h->nleaves;
    return CT_OK;
}

/* Emits k items as children of parent: directly when k <= 2, otherwise as
 * the two halves of a BVH split. */
static int emit_items(builder *B, item *it, uint32_t k, int32_t parent, int depth)
{
    if (depth > 400) return ct_fail(B->err, CT_ERANGE, "texture hierarchy deeper than 400 levels");
    if (k <= 2) {
        for (uint32_t i = 0; i < k; i++) {
            int rc = emit_item(B, &it[i], parent, depth);
            if (rc) return rc;
        }
        return CT_OK;
    }
    uint32_t na = 0;
    int rc = split_items(B, it, k, depth, &na);
    if (rc) return rc;
    rc = emit_group(B, it, na, parent, depth);
    if (!rc) rc = emit_group(B, it + na, k - na, parent, depth);
    return rc;
}


/* Stores what leaf and inner nodes sum alike: bounds, area, material,
 * glossiness and the normal of the normal sum ns. Returns false (spread
 * 180 degrees) when that normal is undefined, true when the caller must
 * compute the spread. */
static bool store_sums(ctex_hnode *n, bounds3 b, vec3 ns, double area, uint32_t mat, float gloss)
{
    n->bounds = b;
    n->area = (float)area;
    n->material = mat == NOMAT ? MIXED : mat;
    n->gloss = gloss;
    n->normal = v3_len2(ns) > 0.0f ? v3_norm(ns) : v3s(0.0f);
    if (v3_is_zero(n->normal) || area <= 0.0) {
        n->spread_deg = 180.0f;
        return false;
    }
    return true;
}

/* The angle in degrees whose cosine is c (clamped to [-1, 1]). */
static float angle_deg(float c)
{
    return acosf(MAXF(-1.0f, MINF(1.0f, c))) * 180.0f / CT_PI;
}

/* Leaf geometry from its triangles: bounds, area, normal (and nsum, the
 * area-weighted normal sum), exact normal spread, material, glossiness. */
static void leaf_geometry(const ct_radmesh *m, const scene_material *mats, uint32_t nmats,
                          const ctex_hier *h, ctex_hnode *n, vec3 *nsum)
{
    bounds3 b = b3_empty();
    vec3 ns = v3s(0.0f);
    double area = 0.0;
    uint32_t mat = NOMAT;
    float gloss = 0.0f;
    uint32_t last_mat = UINT32_MAX;
    for (uint32_t i = n->tri_begin; i < n->tri_end; i++) {
        const uint32_t *v = m->tris + 3 * (size_t)h->tris[i];
        vec3 a = m->pos[v[0]], bb = m->pos[v[1]], c = m->pos[v[2]];
        b = b3_add(b3_add(b3_add(b, a), bb), c);
        vec3 cr = v3_cross(v3_sub(bb, a), v3_sub(c, a));  /* 2 * area * normal */
        ns = v3_add(ns, cr);
        area += 0.5 * (double)v3_len(cr);
        uint32_t tm = m->tri_mat[h->tris[i]];
        if (tm != last_mat) {
            last_mat = tm;
            mat = mat_merge(mat, tm);
            if (tm < nmats) gloss = MAXF(gloss, scene_material_glossiness(&mats[tm]));
        }
    }
    *nsum = ns;
    if (!store_sums(n, b, ns, area, mat, gloss)) return;
    float mincos = 1.0f;
    for (uint32_t i = n->tri_begin; i < n->tri_end; i++) {
        const uint32_t *v = m->tris + 3 * (size_t)h->tris[i];
        vec3 a = m->pos[v[0]];
        vec3 cr = v3_cross(v3_sub(m->pos[v[1]], a), v3_sub(m->pos[v[2]], a));
        float l2 = v3_len2(cr);
        if (!(l2 > 0.0f)) continue;
        float c = v3_dot(cr, n->normal) / sqrtf(l2);
        if (c < mincos) mincos = c;
    }
    n->spread_deg = angle_deg(mincos);
}

/* Inner node from its children: bounds, area, normal, material and
 * glossiness combine exactly; the spread is the merged normal cones'
 * (max over children of the angle to the new normal plus the child's
 * spread), a bound that is exact for single-normal children. */
static void inner_geometry(ctex_hier *h, uint32_t id, vec3 *nsum)
{
    ctex_hnode *n = &h->nodes[id];
    bounds3 b = b3_empty();
    vec3 ns = v3s(0.0f);
    double area = 0.0;
    uint32_t mat = NOMAT;
    float gloss = 0.0f;
    for (uint32_t c = id + 1; c < n->end; c = h->nodes[c].end) {
        const ctex_hnode *k = &h->nodes[c];
        b = b3_union(b, k->bounds);
        ns = v3_add(ns, nsum[c]);
        area += k->area;
        mat = mat_merge(mat, k->material);
        gloss = MAXF(gloss, k->gloss);
    }
    nsum[id] = ns;
    if (!store_sums(n, b, ns, area, mat, gloss)) return;
    float spread = 0.0f;
    for (uint32_t c = id + 1; c < n->end; c = h->nodes[c].end) {
        const ctex_hnode *k = &h->nodes[c];
        if (k->area <= 0.0f) continue;
        spread = MAXF(spread, angle_deg(v3_dot(k->normal, n->normal)) + k->spread_deg);
    }
    n->spread_deg = MINF(spread, 180.0f);
}

/* §3.2: flat test (normal spread, coplanarity) and the object-local frame. */
static void flat_frame(const ct_radmesh *m, const ctex_hier *h, ctex_hnode *n, float flat_deg,
                       float flat_thickness)
{
    n->flat = 0;
    if (!(n->spread_deg < flat_deg)) return;
    /* In-plane principal axis (2D covariance of the vertices) gives a tight
     * rectangle for rotated parts. */
    vec3 t0, b0;
    v3_basis(n->normal, &t0, &b0);
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0, cnt = 0;
    float dmin = INFINITY, dmax = -INFINITY;
    for (uint32_t i = n->tri_begin; i < n->tri_end; i++) {
        const uint32_t *v = m->tris + 3 * (size_t)h->tris[i];
        for (int k = 0; k < 3; k++) {
            vec3 p = m->pos[v[k]];
            double x = v3_dot(p, t0), y = v3_dot(p, b0);
            float d = v3_dot(p, n->normal);
            sx += x; sy += y; sxx += x * x; syy += y * y; sxy += x * y; cnt += 1;
            dmin = MINF(dmin, d); dmax = MAXF(dmax, d);
        }
    }
    double mx = sx / cnt, my = sy / cnt;
    double cxx = sxx / cnt - mx * mx, cyy = syy / cnt - my * my, cxy = sxy / cnt - mx * my;
    /* Candidate in-plane axes: the principal axis, and the edges of the
     * first triangles (a square's covariance has no principal axis); the
     * smallest rectangle wins. */
    float best_area = INFINITY;
    vec3 tu = t0, tv = b0;
    float umin = 0, umax = 0, vmin = 0, vmax = 0;
    uint32_t ncand = n->tri_end - n->tri_begin < 8 ? n->tri_end - n->tri_begin : 8;
    for (uint32_t cidx = 0; cidx <= 3 * ncand; cidx++) {
        vec3 cu;
        if (cidx == 0) {
            float ang = 0.5f * (float)atan2(2.0 * cxy, cxx - cyy);
            cu = v3_add(v3_scale(t0, cosf(ang)), v3_scale(b0, sinf(ang)));
        } else {
            const uint32_t *v = m->tris + 3 * (size_t)h->tris[n->tri_begin + (cidx - 1) / 3];
            int e = (int)((cidx - 1) % 3);
            vec3 d = v3_sub(m->pos[v[(e + 1) % 3]], m->pos[v[e]]);
            d = v3_sub(d, v3_scale(n->normal, v3_dot(d, n->normal)));
            if (!(v3_len2(d) > 0.0f)) continue;
            cu = v3_norm(d);
        }
        vec3 cv = v3_cross(n->normal, cu);
        float a0 = INFINITY, a1 = -INFINITY, b0m = INFINITY, b1 = -INFINITY;
        for (uint32_t i = n->tri_begin; i < n->tri_end; i++) {
            const uint32_t *v = m->tris + 3 * (size_t)h->tris[i];
            for (int k = 0; k < 3; k++) {
                vec3 p = m->pos[v[k]];
                float u = v3_dot(p, cu), w = v3_dot(p, cv);
                a0 = MINF(a0, u); a1 = MAXF(a1, u);
                b0m = MINF(b0m, w); b1 = MAXF(b1, w);
            }
        }
        float rect = (a1 - a0) * (b1 - b0m);
        if (rect < best_area * 0.999f) {
            best_area = rect;
            tu = cu; tv = cv;
            umin = a0; umax = a1; vmin = b0m; vmax = b1;
        }
    }
    float us = umax - umin, vs = vmax - vmin, ext = fmaxf(us, vs);
    if (!(ext > 0.0f)) return;
    if (dmax - dmin > flat_thickness * ext) return;   /* parallel but not coplanar */
    /* keep the frame non-degenerate for thin strips */
    if (us < 1e-4f * ext) { umin -= 0.5e-4f * ext; us = 1e-4f * ext; }
    if (vs < 1e-4f * ext) { vmin -= 0.5e-4f * ext; vs = 1e-4f * ext; }
    float dmid = 0.5f * (dmin + dmax);
    n->flat = 1;
    n->o = v3_add(v3_add(v3_scale(tu, umin), v3_scale(tv, vmin)), v3_scale(n->normal, dmid));
    n->t = v3_scale(tu, us);
    n->b = v3_scale(tv, vs);
}

int ctex_hier_build(const ct_radmesh *m, const scene_material *mats, uint32_t nmats,
                    float flat_deg, float flat_thickness, float mat_weight, uint32_t cluster_tris,
                    ctex_hier *h, ct_error *err)
{
    memset(h, 0, sizeof *h);
    if (m->nnodes == 0 || m->ntris == 0)
        return ct_fail(err, CT_EEMPTY, "radiosity mesh has no nodes or no triangles");
    uint32_t N = m->nnodes;
    for (uint32_t i = 0; i < N; i++) {
        if (m->nodes[i].node_end <= i || m->nodes[i].node_end > N)
            return ct_fail(err, CT_EPARSE, "mesh node %u has a bad subtree end %u", i, m->nodes[i].node_end);
        if (i > 0 && (m->nodes[i].parent < 0 || (uint32_t)m->nodes[i].parent >= i))
            return ct_fail(err, CT_EPARSE, "mesh node %u has a bad parent %d", i, m->nodes[i].parent);
    }
    if (m->nodes[0].node_end != N)
        return ct_fail(err, CT_EPARSE, "mesh node 0 does not span the node table");
    mstat *st = calloc(N, sizeof *st);
    int32_t *leaf_of_node = malloc(N * sizeof *leaf_of_node);
    if (!st || !leaf_of_node) {
        free(st); free(leaf_of_node);
        return ct_fail(err, CT_ENOMEM, "out of memory building the texture hierarchy");
    }
    for (uint32_t i = 0; i < N; i++) {
        st[i].own_b = st[i].sub_b = b3_empty();
        st[i].own_mat = st[i].sub_mat = NOMAT;
        leaf_of_node[i] = -1;
    }
    for (uint32_t t = 0; t < m->ntris; t++) {
        uint32_t n = m->tri_node[t];
        if (n >= N) {
            free(st); free(leaf_of_node);
            return ct_fail(err, CT_EPARSE, "mesh triangle %u names node %u of %u", t, n, N);
        }
        const uint32_t *v = m->tris + 3 * (size_t)t;
        for (int k = 0; k < 3; k++) {
            if (v[k] >= m->nverts) {
                free(st); free(leaf_of_node);
                return ct_fail(err, CT_EPARSE, "mesh triangle %u names vertex %u of %u", t, v[k], m->nverts);
            }
            st[n].own_b = b3_add(st[n].own_b, m->pos[v[k]]);
        }
        st[n].own++;
        if (m->tri_mat[t] != st[n].own_mat) {
            st[n].own_mat = mat_merge(st[n].own_mat, m->tri_mat[t]);
            if (m->tri_mat[t] < nmats)
                st[n].own_gloss = fmaxf(st[n].own_gloss, scene_material_glossiness(&mats[m->tri_mat[t]]));
        }
    }
    for (uint32_t i = 0; i < N; i++) {
        st[i].total = st[i].own; st[i].sub_b = st[i].own_b;
        st[i].sub_mat = st[i].own_mat; st[i].sub_gloss = st[i].own_gloss;
    }
    for (uint32_t i = N; i-- > 1;) {
        uint32_t p = (uint32_t)m->nodes[i].parent;
        st[p].total += st[i].total;
        st[p].sub_b = b3_union(st[p].sub_b, st[i].sub_b);
        st[p].sub_mat = mat_merge(st[p].sub_mat, st[i].sub_mat);
        st[p].sub_gloss = fmaxf(st[p].sub_gloss, st[i].sub_gloss);
    }
    builder B = {0};
    B.m = m; B.st = st; B.h = h; B.mat_weight = mat_weight; B.leaf_of_node = leaf_of_node; B.err = err;
    B.cluster_max = cluster_tris;
    B.flat_cos = cosf(flat_deg * CT_PI / 180.0f);
    B.flat_thickness = flat_thickness;
    B.normal_gap = 2.0f * sinf(0.5f * flat_deg * CT_PI / 180.0f);
    /* nodes: modeling ones, BVH nodes above them, pseudo leaves, and at most
     * 2 n / cluster_max cluster nodes per split part */
    size_t cap = 3 * (size_t)N + 2 + (cluster_tris ? 4 * ((size_t)m->ntris / cluster_tris + N) : 0);
    B.cap = cap > UINT32_MAX / 2 ? UINT32_MAX / 2 : (uint32_t)cap;
    h->nodes = calloc(B.cap, sizeof *h->nodes);
    h->leaf_node = calloc(B.cap, sizeof *h->leaf_node);
    h->leaf_part = calloc(B.cap, sizeof *h->leaf_part);
    h->part_leaf = malloc(N * sizeof *h->part_leaf);
    h->part_hnode = malloc(N * sizeof *h->part_hnode);
    h->tris = malloc((size_t)m->ntris * sizeof *h->tris);
    h->tri_leaf = malloc((size_t)m->ntris * sizeof *h->tri_leaf);
    B.sorted = malloc((size_t)m->ntris * sizeof *B.sorted);
    B.node_start = calloc((size_t)N + 1, sizeof *B.node_start);
    B.keys = cluster_tris ? malloc((size_t)m->ntris * sizeof *B.keys) : NULL;
    int rc = CT_OK;
    if (!h->nodes || !h->leaf_node || !h->leaf_part || !h->part_leaf || !h->part_hnode || !h->tris ||
        !h->tri_leaf || !B.sorted || !B.node_start || (cluster_tris && !B.keys))
        rc = ct_fail(err, CT_ENOMEM, "out of memory building the texture hierarchy");
    if (!rc) {
        /* triangles grouped by node (counting sort, stable) */
        for (uint32_t t = 0; t < m->ntris; t++) B.node_start[m->tri_node[t] + 1]++;
        for (uint32_t i = 0; i < N; i++) B.node_start[i + 1] += B.node_start[i];
        uint32_t *fill = malloc(((size_t)N + 1) * sizeof *fill);
        if (!fill) rc = ct_fail(err, CT_ENOMEM, "out of memory building the texture hierarchy");
        else {
            memcpy(fill, B.node_start, ((size_t)N + 1) * sizeof *fill);
            for (uint32_t t = 0; t < m->ntris; t++) B.sorted[fill[m->tri_node[t]]++] = t;
            free(fill);
        }
        for (uint32_t i = 0; i < N; i++) h->part_hnode[i] = -1;
    }
    if (!rc) rc = emit_modeling(&B, 0, -1, 0);
    if (!rc) {
        h->npart_map = N;
        h->ntris = m->ntris;
        for (uint32_t i = 0; i < N; i++) h->part_leaf[i] = leaf_of_node[i];
        for (uint32_t l = 0; l < h->nleaves; l++) {
            const ctex_hnode *n = &h->nodes[h->leaf_node[l]];
            for (uint32_t i = n->tri_begin; i < n->tri_end; i++) h->tri_leaf[h->tris[i]] = l;
        }
        /* inner nodes: the triangles of their leaves, which are contiguous */
        for (uint32_t i = 0; i < h->nnodes; i++) {
            ctex_hnode *n = &h->nodes[i];
            if (n->end == i + 1) continue;
            n->tri_begin = h->nodes[h->leaf_node[n->leaf_begin]].tri_begin;
            n->tri_end = h->nodes[h->leaf_node[n->leaf_end - 1]].tri_end;
        }
        vec3 *nsum = malloc(h->nnodes * sizeof *nsum);
        if (!nsum) rc = ct_fail(err, CT_ENOMEM, "out of memory building the texture hierarchy");
        else {
            /* children before parents: reverse pre-order */
            for (uint32_t i = h->nnodes; i-- > 0;) {
                if (h->nodes[i].end == i + 1) leaf_geometry(m, mats, nmats, h, &h->nodes[i], &nsum[i]);
                else inner_geometry(h, i, nsum);
                flat_frame(m, h, &h->nodes[i], flat_deg, flat_thickness);
            }
            free(nsum);
        }
    }
    free(B.sorted);
    free(B.node_start);
    free(B.keys);
    free(st);
    free(leaf_of_node);
    if (rc) ctex_hier_free(h);
    return rc;
}

void ctex_hier_free(ctex_hier *h)
{
    free(h->nodes);
    free(h->leaf_node);
    free(h->leaf_part);
    free(h->part_leaf);
    free(h->part_hnode);
    free(h->tris);
    free(h->tri_leaf);
    memset(h, 0, sizeof *h);
}

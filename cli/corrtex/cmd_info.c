/* corrtex info SCENE [--json]: counts and bounds of a scene; with --path
 * NAME, one of its camera paths in the path file format instead. */
#include <cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/corrtex/commands.h"
#include "common/log.h"
#include "common/optab.h"
#include "common/scene.h"

/* Names come from the scene's files: a control character (an escape
 * sequence in a name) is printed as '?', not sent to the terminal. Four
 * buffers in turn, so that one printf can show four names. */
static const char *shown(const char *name)
{
    static char buf[4][256];
    static int k;
    char *o = buf[k = (k + 1) & 3];
    size_t n = 0;
    for (; name[n] && n + 1 < sizeof buf[0]; n++) {
        unsigned char c = (unsigned char)name[n];
        o[n] = c < 0x20 || c == 0x7f ? '?' : (char)c;
    }
    o[n] = '\0';
    return o;
}

static const char *const KINDS[] = {"diffuse", "phong", "ward", "mirror", "dielectric", "emissive"};
#define NKINDS ((int)(sizeof KINDS / sizeof KINDS[0]))

typedef struct info_opts {
    bool json, tree, quiet;
    const char *path;
} info_opts;

#define OF(f) offsetof(info_opts, f)
static const optab OPTS[] = {
    {"json", 'j', OPTAB_FLAG, OF(json), 0, 0, NULL, NULL,
     "machine-readable output (keys: nodes, primitives, triangles, materials, emitters, cameras, paths, bounds, ...)",
     NULL},
    {"tree", 't', OPTAB_FLAG, OF(tree), 0, 0, NULL, NULL, "also print the node hierarchy (plain output: not with --json)", NULL},
    {"quiet", 'q', OPTAB_FLAG, OF(quiet), 0, 0, NULL, NULL, "errors only", NULL},
    /* A path defined inline (keys) exists in the scene file alone: programs
     * that take only a path file (corrtex-display with --connect, which has
     * no scene) get it through this. */
    {"path", 0, OPTAB_STRING, OF(path), 0, 0, NULL, "NAME",
     "print the scene's camera path NAME as a path file (docs/scene-format.md) instead of the summary", NULL},
};
#undef OF

static void usage(FILE *f)
{
    fprintf(f, "usage: corrtex info SCENE.json [--json | --tree] [--quiet]\n"
               "       corrtex info SCENE.json --path NAME\n"
               "  Loads a scene and prints its counts and bounds, or one of its camera paths.\n");
    optab_usage(OPTS, OPTAB_COUNT(OPTS), NULL, f);
}

static cJSON *vec_json(vec3 v)
{
    double a[3] = {v.x, v.y, v.z};
    return cJSON_CreateDoubleArray(a, 3);
}

static void print_tree(const ct_scene *s, uint32_t n, int depth)
{
    static const char *const kind[] = {"root", "file", "group", "part"};
    const scene_node *nd = &s->nodes[n];
    printf("%*s%s [%s] %u triangles", 2 * depth, "", shown(nd->name), kind[nd->kind], nd->tri_end - nd->tri_begin);
    if (nd->kind == SCENE_NODE_PART) printf(", material %s", shown(s->mats[nd->material].name));
    printf("\n");
    for (uint32_t c = scene_first_child(s, n); c < nd->node_end; c = scene_next_sibling(s, c))
        print_tree(s, c, depth + 1);
}

int cmd_info(int argc, char **argv)
{
    info_opts opt;
    ct_error err;
    optab_defaults(OPTS, OPTAB_COUNT(OPTS), &opt, &err);
    optab_group g = {OPTS, OPTAB_COUNT(OPTS), &opt};
    const char *pos[1];
    int npos = 0, prc = optab_parse(&g, 1, argc, argv, pos, 1, &npos, &err);
    if (prc == 1) {
        usage(stdout);
        return 0;
    }
    if (opt.quiet) ct_log_set_level(CT_LOG_ERROR);
    if (prc) {
        ct_log(CT_LOG_ERROR, "corrtex info", "%s", err.msg);
        return 2;
    }
    if (npos != 1) {
        ct_log(CT_LOG_ERROR, "corrtex info", "expected one scene file (got %d arguments)", npos);
        return 2;
    }
    if (opt.path && (opt.json || opt.tree)) {
        ct_log(CT_LOG_ERROR, "corrtex info", "--path prints a path file: not with %s", opt.json ? "--json" : "--tree");
        return 2;
    }
    /* The hierarchy is printed with the plain summary only: with --json it
     * used to be dropped without a word. */
    if (opt.tree && opt.json) {
        ct_log(CT_LOG_ERROR, "corrtex info", "--tree prints the node hierarchy with the plain summary: not with --json");
        return 2;
    }
    ct_scene *s;
    if (scene_load(pos[0], &s, &err) != CT_OK) {
        ct_log(CT_LOG_ERROR, "corrtex info", "%s", err.msg);
        return 2;
    }
    if (opt.path) {
        int pi = scene_find_path(s, opt.path);
        if (pi < 0) {
            char names[512] = "";
            size_t len = 0;
            for (uint32_t i = 0; i < s->npaths && len + 1 < sizeof names; i++)
                len += (size_t)snprintf(names + len, sizeof names - len, "%s%s", i ? ", " : "",
                                        shown(s->paths[i].name));
            ct_log(CT_LOG_ERROR, "corrtex info", "--path %s: %s has no camera path of that name (%s%s)",
                   shown(opt.path), pos[0], s->npaths ? "its paths: " : "it has none", names);
            scene_free(s);
            return 2;
        }
        campath_write(&s->paths[pi], stdout);
        scene_free(s);
        /* a full disk or a closed pipe: the file is not a path */
        if (fflush(stdout) || ferror(stdout)) {
            ct_log(CT_LOG_ERROR, "corrtex info", "--path %s: cannot write the path to the standard output",
                   shown(opt.path));
            return 1;
        }
        return 0;
    }
    int kinds[NKINDS] = {0};
    for (uint32_t i = 0; i < s->nmats; i++) {
        const char *k = scene_material_kind(&s->mats[i]);
        for (int j = 0; j < NKINDS; j++)
            if (strcmp(k, KINDS[j]) == 0) kinds[j]++;
    }
    uint32_t by_kind[4] = {0};
    for (uint32_t n = 0; n < s->nnodes; n++) by_kind[s->nodes[n].kind]++;

    if (opt.json) {
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "scene", s->name);
        cJSON_AddStringToObject(o, "file", s->source);
        char hash[32];
        snprintf(hash, sizeof hash, "%016llx", (unsigned long long)s->source_hash);
        cJSON_AddStringToObject(o, "hash", hash);
        cJSON_AddNumberToObject(o, "nodes", s->nnodes);
        cJSON *nk = cJSON_AddObjectToObject(o, "nodes_by_kind");
        cJSON_AddNumberToObject(nk, "root", by_kind[0]);
        cJSON_AddNumberToObject(nk, "file", by_kind[1]);
        cJSON_AddNumberToObject(nk, "group", by_kind[2]);
        cJSON_AddNumberToObject(nk, "part", by_kind[3]);
        cJSON_AddNumberToObject(o, "primitives", s->nprims);
        cJSON_AddNumberToObject(o, "quads", s->nquads);
        cJSON_AddNumberToObject(o, "triangles", s->ntris);
        cJSON_AddNumberToObject(o, "vertices", s->nverts);
        cJSON_AddNumberToObject(o, "dropped_degenerate", s->dropped_degenerate);
        cJSON *mk = cJSON_AddObjectToObject(o, "materials");
        cJSON_AddNumberToObject(mk, "total", s->nmats);
        for (int j = 0; j < NKINDS; j++) cJSON_AddNumberToObject(mk, KINDS[j], kinds[j]);
        cJSON_AddNumberToObject(o, "emitters", s->nemitters);
        cJSON *cams = cJSON_AddArrayToObject(o, "cameras");
        for (uint32_t i = 0; i < s->ncams; i++) cJSON_AddItemToArray(cams, cJSON_CreateString(s->cams[i].name));
        cJSON *paths = cJSON_AddArrayToObject(o, "paths");
        for (uint32_t i = 0; i < s->npaths; i++) {
            cJSON *p = cJSON_CreateObject();
            cJSON_AddStringToObject(p, "name", s->paths[i].name);
            cJSON_AddNumberToObject(p, "keyframes", s->paths[i].nkeys);
            cJSON_AddNumberToObject(p, "seconds", campath_duration(&s->paths[i]));
            cJSON_AddItemToArray(paths, p);
        }
        cJSON *b = cJSON_AddObjectToObject(o, "bounds");
        cJSON_AddItemToObject(b, "min", vec_json(s->bounds.lo));
        cJSON_AddItemToObject(b, "max", vec_json(s->bounds.hi));
        char *txt = cJSON_Print(o);
        printf("%s\n", txt);
        free(txt);
        cJSON_Delete(o);
    } else {
        printf("scene       %s (%s)\n", shown(s->name), shown(s->source));
        printf("nodes       %u (%u files, %u groups, %u parts)\n", s->nnodes, by_kind[1], by_kind[2], by_kind[3]);
        printf("primitives  %u (%u quads)\n", s->nprims, s->nquads);
        printf("triangles   %u (%u vertices, %u degenerate dropped)\n", s->ntris, s->nverts, s->dropped_degenerate);
        printf("materials   %u:", s->nmats);
        for (int j = 0; j < NKINDS; j++) printf(" %d %s%s", kinds[j], KINDS[j], j + 1 < NKINDS ? "," : "\n");
        printf("emitters    %u triangles\n", s->nemitters);
        printf("cameras     %u:", s->ncams);
        for (uint32_t i = 0; i < s->ncams; i++) printf(" %s", shown(s->cams[i].name));
        printf("\npaths       %u:", s->npaths);
        for (uint32_t i = 0; i < s->npaths; i++)
            printf(" %s (%d keys, %.1f s)", shown(s->paths[i].name), s->paths[i].nkeys, (double)campath_duration(&s->paths[i]));
        printf("\nbounds      [%g %g %g] .. [%g %g %g]\n", (double)s->bounds.lo.x, (double)s->bounds.lo.y,
               (double)s->bounds.lo.z, (double)s->bounds.hi.x, (double)s->bounds.hi.y, (double)s->bounds.hi.z);
        if (opt.tree) print_tree(s, 0, 0);
    }
    scene_free(s);
    return 0;
}

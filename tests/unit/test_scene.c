/* Scene import: the mini test scene's counts, the MTL mapping, overrides,
 * transforms, cameras and paths, and every bad-input case with its message. */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>
#include <sys/stat.h>

#include "common/log.h"
#include "common/scene.h"
#include "tests/support/fixtures.h"

#define MINI "tests/data/scenes/mini.json"

static ct_scene *load_ok(const char *path)
{
    ct_error err;
    ct_scene *s = NULL;
    int rc = scene_load(path, &s, &err);
    cr_assert_eq(rc, CT_OK, "loading %s failed: %s", path, err.msg);
    return s;
}

static const scene_material *mat(const ct_scene *s, const char *name)
{
    int i = scene_find_material(s, name);
    cr_assert_geq(i, 0, "material %s missing", name);
    return &s->mats[i];
}

/* A scene file s.json with the given text in a fresh temporary folder, next
 * to mesh_file holding mesh_text (none when mesh_file is NULL); returns the
 * scene file's path. */
static const char *write_scene(const char *mesh_file, const char *mesh_text, const char *json)
{
    const char *d = fx_tmpdir();
    if (mesh_file) fx_write(d, mesh_file, mesh_text);
    return fx_write(d, "s.json", json);
}

/* A scene whose only mesh is a.obj with the given OBJ text. */
static const char *one_mesh_scene(const char *obj)
{
    return write_scene("a.obj", obj, "{\"meshes\":[{\"file\":\"a.obj\"}]}");
}

static void quiet(void) { ct_log_set_level(CT_LOG_ERROR); }

TestSuite(scene, .init = quiet);
TestSuite(scene_bad, .init = quiet);

Test(scene, mini_counts)
{
    ct_scene *s = load_ok(MINI);
    cr_expect_str_eq(s->name, "mini");
    cr_expect_eq(s->nprims, 8);      /* 6 triangles + floor quad + light quad */
    cr_expect_eq(s->nquads, 2);
    cr_expect_eq(s->ntris, 10);
    cr_expect_eq(s->dropped_degenerate, 1);
    cr_expect_eq(s->nnodes, 14);
    cr_expect_eq(s->nmats, 9);       /* 6 used MTL + JSON brushed + unused mirror + light */
    cr_expect_eq(s->nemitters, 3);   /* glow triangle + light quad */
    cr_expect_eq(s->ncams, 2);
    cr_expect_eq(s->npaths, 2);
    cr_expect_eq(s->nodes[0].kind, SCENE_NODE_ROOT);
    cr_expect_eq(s->nodes[0].node_end, s->nnodes);
    cr_expect_eq(s->nodes[0].tri_end, s->ntris);
    scene_free(s);
}

Test(scene, hierarchy_ranges_nest)
{
    ct_scene *s = load_ok(MINI);
    for (uint32_t n = 1; n < s->nnodes; n++) {
        const scene_node *c = &s->nodes[n], *p = &s->nodes[c->parent];
        cr_assert_lt((uint32_t)c->parent, n);
        cr_expect_leq(p->tri_begin, c->tri_begin);
        cr_expect_geq(p->tri_end, c->tri_end);
        cr_expect_leq(c->node_end, p->node_end);
        if (c->kind == SCENE_NODE_PART)
            for (uint32_t t = c->tri_begin; t < c->tri_end; t++) {
                cr_expect_eq(s->tri_node[t], n);
                cr_expect_eq(s->tri_mat[t], c->material);
            }
    }
    /* modeling hierarchy: file "stuff" contains the groups of the OBJ */
    cr_expect_str_eq(s->nodes[1].name, "stuff");
    cr_expect_eq(s->nodes[1].kind, SCENE_NODE_FILE);
    cr_expect_eq(s->nodes[2].kind, SCENE_NODE_GROUP);
    scene_free(s);
}

Test(scene, mtl_mapping)
{
    ct_scene *s = load_ok(MINI);
    const scene_material *m = mat(s, "matte");
    cr_expect_str_eq(scene_material_kind(m), "diffuse");
    cr_expect_float_eq(m->diffuse.x, 0.5f, 1e-6);
    cr_expect_eq(m->glossy, SCENE_GLOSSY_NONE);

    m = mat(s, "plastic");
    cr_expect_eq(m->glossy, SCENE_GLOSSY_PHONG);
    cr_expect_float_eq(m->specular.x, 0.3f, 1e-6);
    cr_expect_float_eq(m->phong_exp, 80.0f, 1e-6);

    m = mat(s, "chrome");                 /* illum 3: mirror = Ks */
    cr_expect_str_eq(scene_material_kind(m), "mirror");
    cr_expect_float_eq(m->mirror.x, 0.8f, 1e-6);
    cr_expect_float_eq(m->diffuse.x, 0.1f, 1e-6);

    m = mat(s, "glass");                  /* illum 7: dielectric, ior = Ni, transmission = Tf */
    cr_expect(m->dielectric);
    cr_expect_float_eq(m->ior, 1.52f, 1e-6);
    cr_expect_float_eq(m->transmission.y, 0.95f, 1e-6);
    cr_expect_float_eq(m->diffuse.x, 0.0f, 1e-6);

    m = mat(s, "tinted");                 /* d < 1: dielectric */
    cr_expect(m->dielectric);
    cr_expect_float_eq(m->ior, 1.33f, 1e-6);

    m = mat(s, "glow");
    cr_expect_str_eq(scene_material_kind(m), "emissive");
    cr_expect_float_eq(m->emission.x, 4.0f, 1e-6);
    scene_free(s);
}

Test(scene, json_override_replaces_mtl)
{
    ct_scene *s = load_ok(MINI);
    const scene_material *m = mat(s, "brushed");
    cr_expect_eq(m->glossy, SCENE_GLOSSY_WARD);
    cr_expect_float_eq(m->specular.x, 0.7f, 1e-6);
    cr_expect_float_eq(m->ward_ax, 0.05f, 1e-6);
    cr_expect_float_eq(m->ward_ay, 0.3f, 1e-6);
    cr_expect_float_eq(m->diffuse.x, 0.1f, 1e-6);
    scene_free(s);
}

Test(scene, transform_and_normals)
{
    ct_scene *s = load_ok(MINI);
    /* floor corner (1,0,1): scale 2, rotate 90 deg about y, translate (0,1,0) -> (2,1,-2) */
    int found = 0;
    for (uint32_t v = 0; v < s->nverts; v++)
        if (fabsf(s->pos[v].x - 2.0f) < 1e-5f && fabsf(s->pos[v].y - 1.0f) < 1e-5f &&
            fabsf(s->pos[v].z + 2.0f) < 1e-5f)
            found = 1;
    cr_expect(found, "transformed floor corner not found");
    for (uint32_t t = 0; t < 3 * s->ntris; t++) cr_expect_float_eq(v3_len(s->nrm[s->tris[t]]), 1.0f, 1e-4);
    /* floor faces up after the transform (OBJ winding 1 4 3 2 is CCW from above) */
    uint32_t floor = s->nodes[3].tri_begin;
    cr_expect_gt(scene_tri_normal(s, floor).y, 0.99f);
    /* the light emits downwards: edge1 x edge2 = (0,0,1) x (1,0,0) = (0,1,0)... */
    uint32_t lt = s->emitters[s->nemitters - 1];
    cr_expect_gt(scene_tri_normal(s, lt).y, 0.99f);
    cr_expect_float_eq(s->bounds.hi.y, 3.0f, 1e-5);
    scene_free(s);
}

Test(scene, cameras_and_paths)
{
    ct_scene *s = load_ok(MINI);
    int c = scene_find_camera(s, "front");
    cr_assert_geq(c, 0);
    vec3 f;
    cam_axes(&s->cams[c].cam, NULL, NULL, &f);
    cr_expect_float_eq(f.z, -1.0f, 1e-5);
    cr_expect_float_eq(s->cams[c].cam.fov_y, 50.0f * CT_PI / 180.0f, 1e-5);
    cr_expect_float_eq(s->cams[scene_find_camera(s, "top")].fov_deg, 45.0f, 1e-6);
    int p = scene_find_path(s, "walk");
    cr_assert_geq(p, 0);
    cr_expect_eq(s->paths[p].nkeys, 3);
    cr_expect_float_eq(campath_duration(&s->paths[p]), 4.0f, 1e-6);
    ct_camera mid = campath_eval(&s->paths[p], 2.0f);
    cr_expect_float_eq(mid.eye.x, 2.0f, 1e-5);
    int q = scene_find_path(s, "inline");
    cr_assert_geq(q, 0);
    cr_expect_float_eq(s->paths[q].keys[1].fov_deg, 30.0f, 1e-6);
    scene_free(s);
}

Test(scene, hash_changes_with_content)
{
    const char *d = fx_tmpdir();
    const char *obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    fx_write(d, "a.obj", obj);
    const char *p = fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\"}]}");
    ct_scene *s1 = load_ok(p);
    fx_write(d, "a.obj", "v 0 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\n");
    ct_scene *s2 = load_ok(p);
    cr_expect_neq(s1->source_hash, s2->source_hash, "mesh content must be part of the scene hash");
    scene_free(s1);
    scene_free(s2);
}

/* A file named by several entries is imported once (scene_load.c's import
 * slots) and placed once per entry: each copy with its own transform and
 * material, in entry order, and the scene hash still follows the file. */
Test(scene, repeated_mesh_file_is_placed_per_entry)
{
    const char *d = fx_tmpdir();
    fx_write(d, "a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    const char *p = fx_write(d, "s.json",
        "{\"materials\":{\"red\":{\"diffuse\":[0.5,0,0]},\"blue\":{\"diffuse\":[0,0,0.5]}},"
        "\"meshes\":[{\"file\":\"a.obj\",\"material\":\"red\"},"
        "{\"file\":\"./a.obj\",\"material\":\"blue\",\"transform\":{\"translate\":[10,0,0]}},"
        "{\"file\":\"a.obj\",\"material\":\"blue\",\"transform\":{\"translate\":[20,0,0]}},"
        "{\"file\":\"a.obj\",\"material\":\"red\",\"transform\":{\"scale\":2,\"translate\":[30,0,0]}}]}");
    ct_scene *s = load_ok(p);
    cr_assert_eq(s->ntris, 4);
    const float x0[4] = {0, 10, 20, 30}, x1[4] = {1, 11, 21, 32};
    const char *m[4] = {"red", "blue", "blue", "red"};
    for (uint32_t t = 0; t < 4; t++) {
        float lo = 1e30f, hi = -1e30f;
        for (int k = 0; k < 3; k++) {
            float x = s->pos[s->tris[3 * t + k]].x;
            lo = fminf(lo, x);
            hi = fmaxf(hi, x);
        }
        cr_expect_float_eq(lo, x0[t], 1e-5, "triangle %u starts at x %g", t, (double)lo);
        cr_expect_float_eq(hi, x1[t], 1e-5, "triangle %u ends at x %g", t, (double)hi);
        cr_expect_str_eq(s->mats[s->tri_mat[t]].name, m[t], "triangle %u", t);
    }
    fx_write(d, "a.obj", "v 0 0 0\nv 1 0 0\nv 0 2 0\nf 1 2 3\n");
    ct_scene *s2 = load_ok(p);
    cr_expect_neq(s->source_hash, s2->source_hash, "the file's content is part of the hash of every copy");
    ct_scene *s3 = load_ok(p);
    cr_expect_eq(s2->source_hash, s3->source_hash);
    scene_free(s);
    scene_free(s2);
    scene_free(s3);
}

/* --- bad input: each case gives one line naming the file and the problem --- */

static void expect_fail(const char *path, int code, const char *needle1, const char *needle2)
{
    ct_error err;
    ct_error_clear(&err);
    ct_scene *s = (ct_scene *)1;
    int rc = scene_load(path, &s, &err);
    cr_assert_eq(rc, code, "%s: expected code %d (%s), got %d: %s", path, code, ct_strerror(code), rc, err.msg);
    cr_expect_null(s);
    cr_expect(strstr(err.msg, needle1) != NULL, "message '%s' lacks '%s'", err.msg, needle1);
    if (needle2) cr_expect(strstr(err.msg, needle2) != NULL, "message '%s' lacks '%s'", err.msg, needle2);
    cr_expect(strchr(err.msg, '\n') == NULL, "message is not one line");
}

Test(scene_bad, missing_file)
{
    expect_fail("tests/data/scenes/nope.json", CT_EIO, "nope.json", "cannot open");
}

Test(scene_bad, json_syntax_error_line_col)
{
    const char *p = write_scene(NULL, NULL, "{\n  \"meshes\": [\n    { \"file\": \"a.obj\" ,, }\n  ]\n}\n");
    expect_fail(p, CT_EPARSE, "s.json:3:", "JSON syntax error");
}

/* cJSON stops at the end of the first value and keeps every copy of a key
 * (a lookup finds the first): both were accepted silently. */
Test(scene_bad, json_trailing_garbage_and_duplicate_keys)
{
    const char *d = fx_tmpdir();
    fx_write(d, "a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    expect_fail(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\"}]}\n\n  ]\n"), CT_EPARSE, "s.json:3:3:",
                "trailing characters after the JSON value");
    expect_fail(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\",\"name\":\"a\",\"file\":\"b.obj\"}]}"),
                CT_EPARSE, "s.json: duplicate key 'file' in 'meshes'", NULL);
    expect_fail(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\"}],\"name\":\"x\",\"name\":\"y\"}"),
                CT_EPARSE, "s.json: duplicate key 'name' at the top level", NULL);
    ct_scene *s = load_ok(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\"}]}\n \t\n"));
    scene_free(s);
}

Test(scene_bad, obj_index_out_of_range)
{
    const char *p = one_mesh_scene("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
    expect_fail(p, CT_EPARSE, "a.obj", "out of range");
}

Test(scene_bad, nan_coordinate)
{
    const char *p = one_mesh_scene("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
    expect_fail(p, CT_EPARSE, "a.obj", "non-finite");
}

Test(scene_bad, infinite_coordinate)
{
    const char *p = one_mesh_scene("v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n");
    expect_fail(p, CT_EPARSE, "a.obj", "non-finite");
}

Test(scene_bad, degenerate_only_is_empty)
{
    const char *p = one_mesh_scene("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n");
    expect_fail(p, CT_EEMPTY, "s.json", "no triangles");
}

Test(scene_bad, degenerate_dropped_and_counted)
{
    const char *p = one_mesh_scene("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 3 3 3\n");
    ct_scene *s = load_ok(p);
    cr_expect_eq(s->ntris, 1);
    cr_expect_eq(s->dropped_degenerate, 2);
    scene_free(s);
}

Test(scene_bad, unknown_material_key)
{
    const char *p = write_scene("a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
                                "{\"meshes\":[{\"file\":\"a.obj\"}],\"materials\":{\"m\":{\"difuse\":[1,1,1]}}}");
    expect_fail(p, CT_EPARSE, "material 'm'", "unknown key 'difuse'");
}

Test(scene_bad, unknown_top_level_key)
{
    const char *p = write_scene(NULL, NULL, "{\"mesh\":[]}");
    expect_fail(p, CT_EPARSE, "s.json", "unknown key 'mesh'");
}

Test(scene_bad, empty_scene)
{
    const char *p = write_scene(NULL, NULL, "{\"name\":\"empty\"}");
    expect_fail(p, CT_EEMPTY, "s.json", "no triangles");
}

/* A mesh file that is not there is named as the scene names it, with its
 * entry (the message used to give the joined path alone); one that is no
 * file names its entry too. */
Test(scene_bad, missing_mesh_file)
{
    const char *p = write_scene("a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
                                "{\"meshes\":[{\"file\":\"a.obj\"},{\"file\":\"a.obj\"},{\"file\":\"gone.obj\"}]}");
    expect_fail(p, CT_EIO, "s.json: meshes[2]: cannot open 'gone.obj': No such file or directory", NULL);
    const char *d = fx_tmpdir();
    cr_assert_eq(mkdir(fx_path(d, "dir.obj"), 0700), 0);
    expect_fail(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"dir.obj\"}]}"), CT_EIO, "s.json: meshes[0]: ",
                "dir.obj: is a folder, not a regular file");
}

Test(scene_bad, garbage_mesh_file)
{
    const char *p = write_scene("a.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n",
                                "{\"meshes\":[{\"file\":\"a.ply\"}]}");
    ct_error err;
    ct_scene *s = NULL;
    cr_expect_neq(scene_load(p, &s, &err), CT_OK);
    cr_expect(strstr(err.msg, "a.ply") != NULL, "%s", err.msg);
}

Test(scene_bad, wrong_types_and_values)
{
    const char *d = fx_tmpdir();
    fx_write(d, "a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    struct { const char *json; const char *needle; } cases[] = {
        {"{\"meshes\":[{\"file\":\"a.obj\",\"material\":\"nope\"}]}", "unknown material 'nope'"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"cameras\":[{\"name\":\"c\",\"eye\":[0,0,0],\"target\":[0,0,0]}]}", "coincide"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"cameras\":[{\"name\":\"c\",\"eye\":[0,0,1],\"target\":[0,0,0],\"fov\":200}]}", "fov"},
        /* Inside (0, 180) but not a camera the wires carry (the master could
         * not send its first CAMERA, so no display could connect). */
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"cameras\":[{\"name\":\"c\",\"eye\":[0,0,1],\"target\":[0,0,0],\"fov\":179.9999}]}", "fov 179.9999 outside"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"cameras\":[{\"name\":\"c\",\"eye\":[0,0,1],\"target\":[0,0,0],\"fov\":1e-30}]}", "fov 1e-30 outside"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"materials\":{\"m\":{\"diffuse\":[2,0,0]}}}", "energy"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"materials\":{\"m\":{\"diffuse\":[0.5,0.5]}}}", "array of 3"},
        {"{\"meshes\":[{\"file\":\"a.obj\",\"transform\":{\"scale\":0}}]}", "zero"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"lights\":[{\"type\":\"disc\"}]}", "unknown light type"},
        /* Area, but a sliver: the scene dropped both triangles and the light was gone. */
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"lights\":[{\"type\":\"quad\",\"corner\":[0,2,0],\"edge1\":[8,0,0],"
         "\"edge2\":[0,0,1e-7],\"emission\":[1,1,1]}]}", "lights[0]: too thin"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"paths\":[{\"name\":\"p\",\"keys\":[[1,0,0,1,0,0,0],[0,0,0,2,0,0,0]]}]}", "not after"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"paths\":[{\"name\":\"p\",\"file\":\"x.path\"}]}", "x.path"},
        {"{\"meshes\":{}}", "must be an array"},
        {"[1,2]", "must be a JSON object"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const char *p = fx_write(d, "s.json", cases[i].json);
        ct_error err;
        ct_scene *s = NULL;
        int rc = scene_load(p, &s, &err);
        cr_expect_neq(rc, CT_OK, "case %zu loaded", i);
        cr_expect(strstr(err.msg, cases[i].needle) != NULL, "case %zu: '%s' lacks '%s'", i, err.msg, cases[i].needle);
    }
}

/* Points are transformed as affine: a 'matrix' whose bottom row is not
 * (0, 0, 0, 1) lost its projective part without a word. Now one line names
 * the file, the entry and its node; an affine matrix still loads. */
Test(scene_bad, projective_matrix)
{
    const char *d = fx_tmpdir();
    fx_write(d, "a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    expect_fail(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\",\"name\":\"tbl\","
                                      "\"matrix\":[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0.5,1]}]}"),
                CT_EPARSE, "s.json: meshes[0] ('tbl'): 'matrix' bottom row is (0, 0, 0.5, 1), not (0, 0, 0, 1)",
                "projective");
    expect_fail(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\","
                                      "\"matrix\":[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,2]}]}"),
                CT_EPARSE, "s.json: meshes[0] ('a'): 'matrix' bottom row is (0, 0, 0, 2)", NULL);
    ct_scene *s = load_ok(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\","
                                                "\"matrix\":[1,0,0,5, 0,1,0,0, 0,0,1,0, -0,0,0,1]}]}"));
    cr_expect_float_eq(s->bounds.lo.x, 5.0f, 1e-6);
    scene_free(s);
    /* the rounding noise of a computed matrix is no projection */
    s = load_ok(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\","
                                      "\"matrix\":[1,0,0,5, 0,1,0,0, 0,0,1,0, 1e-17,-2e-9,0,1.0000001]}]}"));
    cr_expect_float_eq(s->bounds.lo.x, 5.0f, 1e-6);
    scene_free(s);
}

/* An OBJ whose mtllib cannot be read: assimp goes on with grey default
 * materials under the usemtl names. A material that only the library would
 * have defined is an error naming the OBJ, the material and the library;
 * when the scene defines it (or the mesh entry's 'material' replaces it),
 * the scene loads (with a warning, checked in tests/e2e/info_bad_input.sh). */
Test(scene_bad, missing_mtl_library)
{
    const char *d = fx_tmpdir();
    fx_write(d, "a.obj", "mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl wood\nf 1 2 3\n");
    expect_fail(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\"}]}"), CT_EIO,
                "a.obj: material 'wood': its library cannot be read (", "gone.mtl: cannot open");
    ct_scene *s = load_ok(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\"}],"
                                                "\"materials\":{\"wood\":{\"diffuse\":[0.4,0.3,0.2]}}}"));
    cr_expect_float_eq(mat(s, "wood")->diffuse.x, 0.4f, 1e-6);
    scene_free(s);
    s = load_ok(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\",\"material\":\"m\"}],"
                                      "\"materials\":{\"m\":{\"diffuse\":[0.5,0.5,0.5]}}}"));
    scene_free(s);
    /* A later entry of the same file without a material of its own must not
     * take the made-up material the first (forced) entry left unused. */
    expect_fail(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\",\"material\":\"m\"},{\"file\":\"a.obj\"}],"
                                      "\"materials\":{\"m\":{\"diffuse\":[0.5,0.5,0.5]}}}"),
                CT_EIO, "a.obj: material 'wood': its library cannot be read (", "gone.mtl: cannot open");
    /* assimp's fallback, the library named after the OBJ, defines it */
    fx_write(d, "a.mtl", "newmtl wood\nKd 0.1 0.2 0.3\n");
    s = load_ok(fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\"}]}"));
    cr_expect_float_eq(mat(s, "wood")->diffuse.z, 0.3f, 1e-6);
    scene_free(s);
}

/* Every coordinate that reaches a ray is bounded (CT_COORD_MAX): a camera eye
 * at -1e30 made the tracer abort inside Embree, a light edge of 1e30 gave an
 * all-black image. Each such scene fails with one line naming the place. */
Test(scene_bad, coordinates_out_of_range)
{
    const char *d = fx_tmpdir();
    fx_write(d, "a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    fx_write(d, "far.obj", "v 0 0 0\nv 2e9 0 0\nv 0 1 0\nf 1 2 3\n");
    fx_write(d, "far.path", "0  0 1 -1e30  0 1 0\n1  0 1 4  0 1 0\n");
    struct { const char *json; const char *needle; } cases[] = {
        {"{\"meshes\":[{\"file\":\"far.obj\"}]}", "far.obj: mesh 'defaultobject': vertex 2 at (2e+09, 0, 0)"},
        {"{\"meshes\":[{\"file\":\"a.obj\",\"transform\":{\"scale\":1e30}}]}", "vertex 2 at (1e+30, 0, 0) in the scene"},
        {"{\"meshes\":[{\"file\":\"a.obj\",\"transform\":{\"translate\":[0,-1e10,0]}}]}", "outside the coordinate range"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"lights\":[{\"type\":\"quad\",\"corner\":[0,2,0],\"edge1\":[1e30,0,0],"
         "\"edge2\":[0,0,1],\"emission\":[1,1,1]}]}", "lights[0]: corner 1 at (1e+30, 2, 0)"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"cameras\":[{\"name\":\"c\",\"eye\":[0,1,-1e30],\"target\":[0,1,0]}]}",
         "camera 'c': eye or target outside the coordinate range"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"cameras\":[{\"name\":\"c\",\"eye\":[0,1,4],\"target\":[0,1,-2e9]}]}",
         "camera 'c': eye or target outside"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"paths\":[{\"name\":\"p\",\"keys\":[[0,0,1,4,0,1,0],[1,0,1,4,0,1e20,0]]}]}",
         "paths[0]: keyframe 2: eye or target outside the coordinate range"},
        {"{\"meshes\":[{\"file\":\"a.obj\"}],\"paths\":[{\"name\":\"p\",\"file\":\"far.path\"}]}",
         "far.path:1: eye or target outside"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const char *p = fx_write(d, "s.json", cases[i].json);
        ct_error err;
        ct_scene *s = NULL;
        int rc = scene_load(p, &s, &err);
        cr_expect_eq(rc, CT_ERANGE, "case %zu: rc %d: %s", i, rc, err.msg);
        cr_expect(strstr(err.msg, cases[i].needle) != NULL, "case %zu: '%s' lacks '%s'", i, err.msg, cases[i].needle);
        cr_expect(strchr(err.msg, '\n') == NULL);
        scene_free(s);
    }
    /* The range's edge itself is fine, also for a builder that bypasses the loader. */
    const char *p = fx_write(d, "s.json", "{\"meshes\":[{\"file\":\"a.obj\"}],\"cameras\":[{\"name\":\"c\","
                                          "\"eye\":[0,1,-1e9],\"target\":[0,1,0]}]}");
    ct_scene *s = load_ok(p);
    ct_error err;
    cr_expect_eq(scene_add_vertex(s, v3(0, 0, 1e9f), v3(0, 1, 0), &err), (int64_t)s->nverts - 1);
    cr_expect_eq(scene_add_vertex(s, v3(0, -1.5e9f, 0), v3(0, 1, 0), &err), CT_ERANGE);
    cr_expect(strstr(err.msg, "outside the coordinate range"), "%s", err.msg);
    cr_expect_eq(scene_add_vertex(s, v3(NAN, 0, 0), v3(0, 1, 0), &err), CT_ERANGE);
    scene_free(s);
}

/* Sum of the scene's triangle areas, and whether every triangle faces +z. */
static double area_facing_up(const ct_scene *s, int *flipped)
{
    double a = 0.0;
    *flipped = 0;
    for (uint32_t t = 0; t < s->ntris; t++) {
        a += scene_tri_area(s, t);
        *flipped += scene_tri_normal(s, t).z < 0.9f;
    }
    return a;
}

/* Concave polygons are cut into ears, not fanned: a ring-shaped face (a
 * square with a square hole, joined by a bridge) was drawn as a filled
 * disc, and a fan of a chevron has a triangle outside the shape. */
Test(scene, concave_polygons_keep_their_shape)
{
    struct { const char *obj; double area; const char *what; } cases[] = {
        /* Outer square 4 x 4 counter-clockwise, bridge to the inner 2 x 2
         * hole, the hole clockwise, back over the bridge: area 16 - 4. */
        {"v 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\nv 1 1 0\nv 3 1 0\nv 3 3 0\nv 1 3 0\n"
         "f 1 2 3 4 1 5 8 7 6 5\n", 12.0, "ring"},
        /* A chevron: the first corner's fan leaves the shape. */
        {"v 0 0 0\nv 2 1 0\nv 4 0 0\nv 2 3 0\nf 1 2 3 4\n", 4.0, "chevron"},
        /* A comb of 7 teeth: 30 corners, 18 of them concave. */
        {"v 0 0 0\nv 13 0 0\nv 13 3 0\nv 12 3 0\nv 12 1 0\nv 11 1 0\nv 11 3 0\nv 10 3 0\nv 10 1 0\nv 9 1 0\n"
         "v 9 3 0\nv 8 3 0\nv 8 1 0\nv 7 1 0\nv 7 3 0\nv 6 3 0\nv 6 1 0\nv 5 1 0\nv 5 3 0\nv 4 3 0\nv 4 1 0\n"
         "v 3 1 0\nv 3 3 0\nv 2 3 0\nv 2 1 0\nv 1 1 0\nv 1 3 0\nv 0 3 0\n"
         "f 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28\n", 13.0 + 7 * 2.0, "comb"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        ct_scene *s = load_ok(one_mesh_scene(cases[i].obj));
        int flipped;
        double a = area_facing_up(s, &flipped);
        cr_expect(fabs(a - cases[i].area) < 1e-4, "%s: triangles cover %g, the polygon %g", cases[i].what, a,
                  cases[i].area);
        cr_expect_eq(flipped, 0, "%s: %d triangles face away from the polygon", cases[i].what, flipped);
        cr_expect_eq(s->nprims, 1u, "%s: one input polygon", cases[i].what);
        scene_free(s);
    }
    /* A concave polygon too large to cut into ears is refused, not fanned. */
    ct_scene *big = scene_new("big");
    ct_error err;
    scene_material m = scene_material_default("m");
    cr_assert_geq(scene_add_material(big, &m, &err), 0);
    cr_assert_geq(scene_begin_node(big, "part", SCENE_NODE_PART, 0, &err), 0);
    enum { NB = 1100 };
    static uint32_t ring[NB];
    for (int i = 0; i < NB; i++) {
        float r = i % 2 ? 1.0f : 2.0f, phi = 2.0f * CT_PI * (float)i / NB;
        ring[i] = (uint32_t)scene_add_vertex(big, v3(r * cosf(phi), r * sinf(phi), 0), v3(0, 0, 1), &err);
    }
    cr_expect_eq(scene_add_polygon(big, ring, NB, &err), CT_ERANGE);
    cr_expect(strstr(err.msg, "concave polygon of 1100 vertices (at most 1024"), "%s", err.msg);
    scene_free(big);
    /* A convex quad is still fanned from its first corner (radiosity patches
     * recognise a quad by that shape). */
    ct_scene *s = load_ok(one_mesh_scene("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"));
    cr_assert_eq(s->ntris, 2u);
    cr_expect(s->tris[0] == s->tris[3] && s->tris[2] == s->tris[4], "quad not fanned as (0,1,2), (0,2,3)");
    scene_free(s);
}

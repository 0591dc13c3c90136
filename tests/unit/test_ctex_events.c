/* What the corrective textures hand the display and the files (master/ctex.h):
 * events and unsent tiles, the memory cap, the software compositor, the
 * options, a bad mesh, the node table and display mesh. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/half.h"
#include "common/pool.h"
#include "common/radmesh.h"
#include "common/rng.h"
#include "common/scene.h"
#include "master/ctex.h"
#include "master/ctex_hier.h"
#include "master/ctex_tex.h"
#include "tests/support/ctex_scenes.h"

static ct_error err;

Test(ctex_events, events_alloc_proj_free_and_unsent_tiles)
{
    tcx_scene t;
    ctex *c = tcx_leaf_engine(&t, 64, 64);
    ct_camera cam = tcx_front_cam();
    size_t n;
    const ctex_event *ev = ctex_events(c, &n);
    int alloc = 0, proj = 0;
    for (size_t i = 0; i < n; i++) {
        alloc += ev[i].kind == CTEX_EV_ALLOC;
        proj += ev[i].kind == CTEX_EV_PROJ;
        if (ev[i].kind == CTEX_EV_ALLOC) cr_assert(ev[i].w >= 4 && ev[i].h >= 4);
    }
    cr_assert_eq(alloc, 8);
    cr_assert_eq(proj, 8);
    ctex_events_clear(c);
    /* new textures are unsent as a whole; the display server sends them */
    for (uint32_t id = 0; id < ctex_slot_count(c); id++) {
        struct ctex_tex *vt = ctex_visible_texture(c, id);
        if (!vt) continue;
        int x0, y0, x1, y1;
        cr_assert(ctex_dirty_bounds(&vt->d, vt->w, vt->h, &x0, &y0, &x1, &y1));
        cr_assert(x0 == 0 && y0 == 0 && x1 == vt->w && y1 == vt->h, "texture %u wholly unsent", id);
        ctex_dirty_clear_all(&vt->d);
    }
    ctex_set_clock(c, 4242);
    ctex_insert_info info;
    ct_sample s = tcx_sample((uint32_t)t.floor, v3(1, 0, 2), v3s(1.0f), v3s(0.5f));
    ctex_insert(c, &s, &info);
    ctex_insert(c, &s, &info);
    ctex_events(c, &n);
    cr_assert_eq(n, 0, "texels are not events");
    for (uint32_t id = 0; id < ctex_slot_count(c); id++) {
        struct ctex_tex *vt = ctex_visible_texture(c, id);
        if (!vt) continue;
        int x0, y0, x1, y1;
        bool any = ctex_dirty_bounds(&vt->d, vt->w, vt->h, &x0, &y0, &x1, &y1);
        cr_assert_eq(any, id == (uint32_t)info.tex, "only the sample's texture has unsent texels (%u)", id);
        if (!any) continue;
        /* the unsent tiles hold the splat, stamped with the clock, counting both samples */
        float u, v;
        cr_assert(ctex_tex_project(vt, s.hit, &u, &v));
        int ci = (int)(u * (float)vt->w), cj = (int)(v * (float)vt->h);
        cr_assert(ci >= x0 && ci < x1 && cj >= y0 && cj < y1);
        cr_assert_eq(vt->d.row_t[cj >> CTEX_TILE_SHIFT], 4242u);
        cr_assert_eq(vt->d.row_n[cj >> CTEX_TILE_SHIFT], 2u);
        float buf[3 * 64 * 64];
        cr_assert_eq(ctex_read_patch(c, id, x0, y0, x1 - x0, y1 - y0, buf, &err), 0);
        cr_assert_lt(ctex_read_patch(c, id, 0, 0, 9999, 1, buf, &err), 0);
    }
    cr_assert_eq(ctex_visible_texture(c, 9999), NULL);
    /* looking away frees (parks) the floor's texture for the display */
    ct_camera away = cam_look_at(v3(0, 1, 20), v3(0, 1, 40), v3(0, 1, 0), 30.0f);
    cr_assert_eq(ctex_set_camera(c, &away, 64, 64, &err), 0);
    ev = ctex_events(c, &n);
    int freed = 0;
    for (size_t i = 0; i < n; i++) freed += ev[i].kind == CTEX_EV_FREE && ev[i].tex == (uint32_t)info.tex;
    cr_assert_eq(freed, 1);
    cr_assert_eq(ctex_get_stats(c).parked, 8, "parked %u", ctex_get_stats(c).parked);
    /* coming back reuses the parked texture with its contents */
    ctex_events_clear(c);
    cr_assert_eq(ctex_set_camera(c, &cam, 64, 64, &err), 0);
    cr_assert_eq(ctex_owner(c, (uint32_t)t.floor, UINT32_MAX, v3s(0.0f)), info.tex);
    cr_assert_float_eq(ctex_lookup(c, (uint32_t)t.floor, UINT32_MAX, v3(1, 0, 2)).x, 0.5f, 1e-6);
    ctex_free(c);
    tcx_release(&t);
}

Test(ctex_events, memory_cap_evicts_invisible_first)
{
    tcx_scene t;
    ctex_options o = ctex_options_default();
    o.eps = 0.0f;
    o.mem_mb = 0.05;   /* ~3,300 texels */
    o.tex_init = 8;
    ctex *c = tcx_front_engine(&t, o, 256, 256);
    int32_t fl = ctex_owner(c, (uint32_t)t.floor, UINT32_MAX, v3s(0.0f));
    ct_camera away = cam_look_at(v3(0, 1, 20), v3(0, 1, 40), v3(0, 1, 0), 30.0f);
    cr_assert_eq(ctex_set_camera(c, &away, 256, 256, &err), 0);
    cr_assert_gt(ctex_get_stats(c).parked, 0);
    /* the visible box grows by dense samples until the cap bites */
    int32_t id = ctex_owner(c, (uint32_t)t.behind, UINT32_MAX, v3s(0.0f));
    cr_assert_geq(id, 0);
    ctex_insert_info info;
    for (int k = 0; k < 20000; k++) {
        float x = -1.0f + 2.0f * (float)(k % 141) / 140.0f, y = 2.0f * (float)((k / 141) % 141) / 140.0f;
        ct_sample s = tcx_sample((uint32_t)t.behind, v3(x, y, 30), v3s((float)(k % 7)), v3s(0.0f));
        ctex_insert(c, &s, &info);
    }
    ctex_stats st = ctex_get_stats(c);
    cr_assert_leq(st.bytes, (size_t)(0.05 * 1048576.0), "bytes %zu over the cap", st.bytes);
    cr_assert_gt(st.evictions, 0, "parked textures were evicted");
    uint32_t hn;
    cr_assert_eq(ctex_texture_info(c, (uint32_t)id, &hn, NULL, NULL, NULL, NULL, NULL), 1, "visible texture kept");
    (void)fl;
    ctex_free(c);
    tcx_release(&t);
}

Test(ctex_events, compositor_adds_bilinear_correction)
{
    tcx_scene t;
    ctex *c = tcx_leaf_engine(&t, 8, 8);
    tcx_fill_floor(c, (uint32_t)t.floor, 0.25f, 0.0f);
    ctex_hit hits[64];
    for (int i = 0; i < 64; i++) {
        hits[i].node = i % 2 ? UINT32_MAX : (uint32_t)t.floor;
        hits[i].tri = UINT32_MAX;
        hits[i].p = v3(0.1f * (float)i - 3.0f, 0.0f, 1.0f);
        hits[i].l_base = v3s(0.1f);
    }
    /* (built by hand: the compositor only needs the pixel array) */
    ct_image img = {8, 8, calloc(8 * 8 * 3, sizeof(float))};
    cr_assert_eq(ctex_composite(c, hits, 1, 8, 8, &img, &err), 0);
    for (int i = 0; i < 64; i++) {
        vec3 v = img_get(&img, i % 8, i / 8);
        float expect = i % 2 ? 0.1f : 0.35f;
        cr_assert_float_eq(v.x, expect, 1e-5, "pixel %d: %g", i, (double)v.x);
    }
    ct_image bad = {4, 4, calloc(4 * 4 * 3, sizeof(float))};
    cr_assert_lt(ctex_composite(c, hits, 1, 8, 8, &bad, &err), 0);
    /* Two hits a pixel (a multisampling display, converge --aa): each
     * pixel of the 4 x 8 image averages a corrected and an uncorrected hit. */
    ct_image half = {4, 8, calloc(4 * 8 * 3, sizeof(float))};
    cr_assert_eq(ctex_composite(c, hits, 2, 4, 8, &half, &err), 0, "%s", err.msg);
    for (int i = 0; i < 32; i++)
        cr_assert_float_eq(img_get(&half, i % 4, i / 4).x, 0.225f, 1e-5, "pixel %d", i);
    cr_assert_lt(ctex_composite(c, hits, 0, 4, 8, &half, &err), 0, "0 hits a pixel");
    free(half.px);
    free(bad.px);
    free(img.px);
    ctex_free(c);
    tcx_release(&t);
}

Test(ctex_events, options_parse_and_reject)
{
    ctex_options o = ctex_options_default();
    cr_assert_float_eq(o.eps, 0.3f, 1e-7);
    cr_assert_eq(ctex_options_parse(&o, "--eps", "0.5", &err), 1);
    cr_assert_float_eq(o.eps, 0.5f, 1e-7);
    cr_assert_eq(ctex_options_parse(&o, "--tex-min", "8", &err), 1);
    cr_assert_eq(o.tex_min, 8);
    cr_assert_eq(ctex_options_parse(&o, "--width", "8", &err), 0);
    cr_assert_lt(ctex_options_parse(&o, "--eps", "abc", &err), 0);
    cr_assert_lt(ctex_options_parse(&o, "--tex-min", "2.5", &err), 0);
    cr_assert_lt(ctex_options_parse(&o, "--flat-deg", "-1", &err), 0);
    cr_assert_lt(ctex_options_parse(&o, "--eps", NULL, &err), 0);
    /* mix 0 would freeze every texel at its first sample */
    cr_assert_lt(ctex_options_parse(&o, "--mix", "0", &err), 0);
    cr_assert_lt(ctex_options_parse(&o, "--mix", "1.5", &err), 0);
    cr_assert_eq(ctex_options_parse(&o, "--mix", "1", &err), 1);
    cr_assert_float_eq(o.mix, 1.0f, 1e-7);
    /* --splat-aniso is a switch */
    cr_assert_eq(o.splat_aniso, 1);
    cr_assert_lt(ctex_options_parse(&o, "--splat-aniso", "2", &err), 0);
    cr_assert(strstr(err.msg, "--splat-aniso") != NULL, "the error names the option: %s", err.msg);
    cr_assert_lt(ctex_options_parse(&o, "--splat-aniso", "0.5", &err), 0);
    cr_assert_eq(ctex_options_parse(&o, "--splat-aniso", "0", &err), 1);
    cr_assert_eq(o.splat_aniso, 0);
    /* a margin is a fraction of the screen */
    cr_assert_float_eq(o.proj_margin, 0.125f, 1e-7);
    cr_assert_lt(ctex_options_parse(&o, "--projector-margin", "1.5", &err), 0);
    cr_assert(strstr(err.msg, "--projector-margin") != NULL, "the error names the option: %s", err.msg);
    cr_assert_lt(ctex_options_parse(&o, "--projector-margin", "-0.1", &err), 0);
    cr_assert_lt(ctex_options_parse(&o, "--projector-margin", "nan", &err), 0);
    cr_assert_eq(ctex_options_parse(&o, "--projector-margin", "0", &err), 1);
    cr_assert_eq(o.proj_margin, 0.0f);
}

Test(ctex_events, bad_mesh_is_rejected)
{
    tcx_scene t;
    tcx_build(&t);
    t.m.tri_node[0] = 12345;
    ctex *c = NULL;
    cr_assert_eq(ctex_new(&t.m, t.s->mats, t.s->nmats, NULL, &c, &err), CT_EPARSE);
    cr_assert_null(c);
    tcx_release(&t);
}

Test(ctex_events, exported_node_table_for_the_display)
{
    tcx_scene t;
    tcx_build(&t);
    ctex *c = tcx_engine(&t, ctex_options_default());
    uint32_t n = ctex_get_stats(c).hier_nodes;
    rmesh_node *nodes = calloc(n, sizeof *nodes);
    ctex_export_nodes(c, nodes);
    cr_assert_eq(nodes[0].parent, -1);
    cr_assert_eq(nodes[0].node_end, n);
    for (uint32_t i = 1; i < n; i++) {
        cr_assert(nodes[i].parent >= 0 && (uint32_t)nodes[i].parent < i, "pre-order parent of %u", i);
        cr_assert(nodes[i].node_end > i && nodes[i].node_end <= nodes[nodes[i].parent].node_end);
    }
    /* every part maps to a leaf whose exported name is the part's, and a
     * node's subtree holds exactly the parts ctex_node_parts lists */
    for (uint32_t p = 0; p < t.s->nnodes; p++) {
        uint32_t h = ctex_hnode_of_part(c, p);
        if (t.s->nodes[p].kind != SCENE_NODE_PART) {
            cr_assert_eq(h, UINT32_MAX);
            continue;
        }
        cr_assert_lt(h, n);
        cr_assert_eq(nodes[h].node_end, h + 1, "leaf");
        cr_assert_str_eq(nodes[h].name, t.s->nodes[p].name);
    }
    for (uint32_t h = 0; h < n; h++) {
        uint32_t np;
        const uint32_t *parts = ctex_node_parts(c, h, &np);
        uint32_t inside = 0;
        for (uint32_t p = 0; p < t.s->nnodes; p++) {
            uint32_t l = ctex_hnode_of_part(c, p);
            if (l != UINT32_MAX && l >= h && l < nodes[h].node_end) inside++;
        }
        cr_assert_eq(inside, np, "node %u", h);
        for (uint32_t k = 0; k < np; k++) {
            uint32_t l = ctex_hnode_of_part(c, parts[k]);
            cr_assert(l >= h && l < nodes[h].node_end);
        }
    }
    cr_assert_eq(ctex_hnode_of_part(c, 99999), UINT32_MAX);
    free(nodes);
    ctex_free(c);
    tcx_release(&t);
}

/* One part: a floor of n x n quads and a back wall of n x n quads meeting
 * at a corner (an L), one material. */

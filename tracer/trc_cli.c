/* trc_cli.c: the tracer's command-line options (trc_cli.h). */
#include "tracer/trc_cli.h"

static const int MODES[] = {TRC_MODE_DRT, TRC_MODE_REUSE, TRC_MODE_PATH};
static const int INDIRECT[] = {TRC_INDIRECT_MESH, TRC_INDIRECT_GATHER};
static const int GATHER_DIRECT[] = {TRC_GATHER_DIRECT_TRACE, TRC_GATHER_DIRECT_MESH};
static const int GLASS_LIGHT[] = {TRC_GLASS_STRAIGHT, TRC_GLASS_REFRACTED, TRC_GLASS_AUTO};

#define OF(f) offsetof(trc_cli, f)
static const optab ROWS[] = {
    {"mode", 0, OPTAB_CHOICE, OF(mode), 0, 0, "drt", "drt|reuse-diffuse|path",
     "tracer mode: distributed ray tracing, drt with the diffuse light of the radiosity mesh, or path tracing "
     "(docs/tracer.md)", MODES},
    {"shadow-rays", 0, OPTAB_INT, OF(shadow_rays), 1, 4096, NULL, "K",
     "light samples per shading point (default: the mode's, path 1, drt 4)", NULL},
    {"branch", 0, OPTAB_INT, OF(branch), 1, 4096, NULL, "B", "drt: rays per glossy lobe (default: the mode's, 4)",
     NULL},
    {"branch-depth", 0, OPTAB_INT, OF(branch_depth), -1, 1024, "-1", "L",
     "drt: levels that split into B glossy rays (-1: the mode's, 1)", NULL},
    {"fresnel-depth", 0, OPTAB_INT, OF(fresnel_depth), -1, 1024, "-1", "F",
     "drt: levels that trace both the reflection and the refraction at glass; below, the stronger and the weaker "
     "by chance (-1: the mode's, drt 3, path 1)", NULL},
    {"depth", 0, OPTAB_INT, OF(depth), -1, 1024, "-1", "D",
     "drt: recursion depth; path: maximum bounces (-1: the mode's, drt 8, path 64)", NULL},
    {"indirect", 0, OPTAB_CHOICE, OF(indirect), 0, 0, "gather", "mesh|gather",
     "drt's indirect light: the mesh read at the hit, or a final gather of the mesh (docs/tracer.md)", INDIRECT},
    {"gather-rays", 0, OPTAB_INT, OF(gather_rays), 1, 4096, "4", "G", "rays of --indirect gather per shading point",
     NULL},
    {"gather-direct", 0, OPTAB_CHOICE, OF(gather_direct), 0, 0, "trace", "trace|mesh",
     "--indirect gather: the lamps' light where a gather ray lands, by one traced lamp sample (the mesh's indirect "
     "part beside it) or read from the mesh (faster; its shadows are blurred, docs/tracer.md)", GATHER_DIRECT},
    {"caustic-photons", 0, OPTAB_INT, OF(caustic_photons), -1, TRC_CAUSTIC_PHOTONS_MAX, "-1", "N",
     "drt with a radiosity mesh: photons shot from the lamps for their reflective caustics, the light mirrors and "
     "glass faces throw onto diffuse surfaces (0: none; -1: the mode's, drt 1000000; docs/tracer.md)", NULL},
    {"glass-light", 0, OPTAB_CHOICE, OF(glass_light), 0, 0, "auto", "straight|refracted|auto",
     "the lamps' light through glass: by shadow rays that pass it attenuated (the paper's model), only by refracted "
     "paths (path, drt: glass blocks shadow rays; drt with a mesh takes that light from refracted photons), or auto: "
     "straight through flat glass (panes, sheets), refracted through glass that bends light (reuse-diffuse: straight "
     "everywhere; docs/tracer.md)",
     GLASS_LIGHT},
};
#undef OF

const optab *trc_cli_table(size_t *n)
{
    *n = OPTAB_COUNT(ROWS);
    return ROWS;
}

void trc_cli_apply(const trc_cli *c, trc_options *o)
{
    trc_options_default(o, (trc_mode)c->mode);
    if (c->shadow_rays > 0) o->shadow_rays = c->shadow_rays;
    if (c->branch > 0) o->branch = c->branch;
    if (c->branch_depth >= 0) o->branch_depth = c->branch_depth;
    if (c->fresnel_depth >= 0) o->fresnel_depth = c->fresnel_depth;
    if (c->depth >= 0) o->depth = c->depth;
    o->indirect = (trc_indirect)c->indirect;
    o->gather_rays = c->gather_rays;
    o->gather_direct = (trc_gather_direct)c->gather_direct;
    if (c->caustic_photons >= 0) o->caustic_photons = c->caustic_photons;
    o->glass_light = (trc_glass_light)c->glass_light;
}

int trc_cli_check(const trc_cli *c, ct_error *err)
{
    trc_options o;
    trc_cli_apply(c, &o);
    return trc_options_check(&o, err);
}

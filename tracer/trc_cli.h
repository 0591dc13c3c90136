/* trc_cli.h: the tracer's options as every program takes them on the
 * command line (corrtex-render, corrtex reference, converge, naive): one
 * option table, so that the programs accept the same names and ranges and
 * say "the mode's default" the same way, and one function that turns the
 * choices into trc_options. Owns the trc_cli_ prefix. */
#ifndef CT_TRACER_TRC_CLI_H
#define CT_TRACER_TRC_CLI_H

#include <stddef.h>

#include "common/optab.h"
#include "tracer/tracer.h"

/* What the command line chose. A count left at 0 (shadow rays, branch) or
 * a level left at -1 (depth, branch depth) takes the mode's default, which
 * differs between path and drt. */
typedef struct trc_cli {
    int mode;           /* trc_mode */
    int shadow_rays;    /* K; 0: the mode's */
    int branch;         /* B; 0: the mode's */
    int branch_depth;   /* -1: the mode's */
    int fresnel_depth;  /* -1: the mode's */
    int depth;          /* D; -1: the mode's */
    int indirect;       /* trc_indirect */
    int gather_rays;    /* G */
    int gather_direct;  /* trc_gather_direct */
    int caustic_photons;   /* -1: the mode's */
    int glass_light;       /* trc_glass_light */
} trc_cli;

/* The rows (optab.h) filling a trc_cli: --mode (default drt),
 * --shadow-rays, --branch, --branch-depth, --depth, --indirect,
 * --gather-rays, --gather-direct, --caustic-photons, --glass-light. */
const optab *trc_cli_table(size_t *n);

/* The options of c's mode with what c sets over them (the seed and the
 * device configuration stay the mode's defaults). */
void trc_cli_apply(const trc_cli *c, trc_options *o);

/* trc_options_check of what c gives: a combination the rows cannot refuse
 * one by one (--glass-light refracted with reuse-diffuse). */
int trc_cli_check(const trc_cli *c, ct_error *err);

#endif

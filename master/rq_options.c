/* rq_options.c: the sampler's options table: defaults, parsing by name and
 * the --help lines, so every driver (corrtex converge, corrtex-render)
 * exposes the same options with the same defaults. */
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "master/sampler.h"

void rq_options_default(rq_options *o)
{
    memset(o, 0, sizeof *o);
    o->children = 4;               /* §3.7: N = 4 children per sample */
    o->min_priority = 1.0f / 512;  /* half an 8-bit display step over a 1-pixel domain */
    o->min_radius = 1.0f;          /* below one pixel a domain is already at image resolution */
    o->n_sig = 500;                /* §3.7: n_sig (the paper gives no value) */
    o->seed_spacing = 32.0f;       /* 1,024 initial requests at 1024x1024 (§5: 1,000-4,000 per frame) */
    o->global_batch = 64;
    o->global_tries = 16;
    o->coverage_switch = 0.9f;     /* §3.7: "if most pixels are covered" */
    o->norm = RQ_NORM_MAX;
    o->prio_reproject = 4e9f;      /* §3.7: high priority, above every |E| * s */
    o->prio_seed = 2e9f;           /* §3.7: high priority */
    o->prio_mismatch = 1e9f;
    /* Fig. 4 starts a new view from the reprojected samples alone and adds
     * global requests when the queue runs dry; while the camera moves it
     * never does, and what comes into view is never sampled (docs/sampling.md). */
    o->reseed = 1;
    o->max_queue = 0;
    /* Past full coverage a still view goes on being sampled where a pixel's
     * mean is least certain, until its standard error (luminance of the
     * correction) is under half an 8-bit step of a mid-grey display value. */
    o->refine_error = 0.002f;
    o->refine_max = 256;
}

enum { T_INT, T_FLOAT, T_LONG, T_NORM };

typedef struct optdesc {
    const char *name;
    int type;
    size_t off;
    const char *arg;
    const char *help;
} optdesc;

static const optdesc opts[] = {
    {"children", T_INT, offsetof(rq_options, children), "N",
     "children per returned sample, radius s/sqrt(N) (paper 3.7)"},
    {"min-priority", T_FLOAT, offsetof(rq_options, min_priority), "P",
     "discard children whose priority |E|*s_c is below P"},
    {"min-radius", T_FLOAT, offsetof(rq_options, min_radius), "PX",
     "no children with a domain radius below PX pixels"},
    {"n-sig", T_INT, offsetof(rq_options, n_sig), "N",
     "most significant samples reprojected on a camera change (paper 3.7)"},
    {"seed-spacing", T_FLOAT, offsetof(rq_options, seed_spacing), "PX",
     "spacing of the initial jittered grid of requests"},
    {"global-batch", T_INT, offsetof(rq_options, global_batch), "N",
     "random global requests added when the queue runs dry"},
    {"global-tries", T_INT, offsetof(rq_options, global_tries), "N",
     "random positions tried per global request before giving up"},
    {"coverage-switch", T_FLOAT, offsetof(rq_options, coverage_switch), "F",
     "pixel coverage (0..1) at which the shuffled list of remaining pixels takes over"},
    {"error-norm", T_NORM, offsetof(rq_options, norm), "max|lum|avg",
     "RGB norm of the sample error E"},
    {"prio-reproject", T_FLOAT, offsetof(rq_options, prio_reproject), "P",
     "priority of reprojected significant samples"},
    {"prio-seed", T_FLOAT, offsetof(rq_options, prio_seed), "P",
     "priority of initial, global and remaining-list requests"},
    {"prio-mismatch", T_FLOAT, offsetof(rq_options, prio_mismatch), "P",
     "priority of children of samples that hit another node than shown"},
    {"reseed", T_INT, offsetof(rq_options, reseed), "0|1",
     "queue a fresh initial grid on every camera change too"},
    {"max-queue", T_LONG, offsetof(rq_options, max_queue), "N",
     "cap on queued requests (0 = one per pixel)"},
    {"refine-error", T_FLOAT, offsetof(rq_options, refine_error), "E",
     "after full coverage keep sampling pixels whose mean's standard error is over E (0: stop at one sample)"},
    {"refine-max", T_INT, offsetof(rq_options, refine_max), "N",
     "at most N samples per pixel when refining (1..65535)"},
};

static const char *norm_names[] = {"max", "lum", "avg"};

bool rq_options_has(const char *name)
{
    for (size_t i = 0; i < sizeof opts / sizeof opts[0]; i++)
        if (strcmp(opts[i].name, name) == 0) return true;
    return false;
}

int rq_options_set(rq_options *o, const char *name, const char *value, ct_error *err)
{
    for (size_t i = 0; i < sizeof opts / sizeof opts[0]; i++) {
        const optdesc *d = &opts[i];
        if (strcmp(d->name, name) != 0) continue;
        char *end = NULL;
        void *field = (char *)o + d->off;
        errno = 0;
        switch (d->type) {
        case T_INT: {
            long v = strtol(value, &end, 10);
            if (errno || end == value || *end || v < -2147483647L || v > 2147483647L) break;
            *(int *)field = (int)v;
            return 0;
        }
        case T_LONG: {
            long v = strtol(value, &end, 10);
            if (errno || end == value || *end) break;
            *(long *)field = v;
            return 0;
        }
        case T_FLOAT: {
            float v = strtof(value, &end);
            if (errno || end == value || *end || !isfinite(v)) break;
            *(float *)field = v;
            return 0;
        }
        case T_NORM:
            for (int k = 0; k < 3; k++)
                if (strcmp(value, norm_names[k]) == 0) {
                    *(rq_norm *)field = (rq_norm)k;
                    return 0;
                }
            break;
        }
        return ct_fail(err, CT_EINVAL, "sampler option --%s: bad value '%s' (expected %s)", name,
                       value, d->arg);
    }
    return ct_fail(err, CT_EINVAL, "unknown sampler option --%s", name);
}

void rq_options_usage(FILE *f)
{
    rq_options def;
    rq_options_default(&def);
    for (size_t i = 0; i < sizeof opts / sizeof opts[0]; i++) {
        const optdesc *d = &opts[i];
        const void *field = (const char *)&def + d->off;
        char flag[64], dv[32];
        snprintf(flag, sizeof flag, "--%s %s", d->name, d->arg);
        switch (d->type) {
        case T_INT: snprintf(dv, sizeof dv, "%d", *(const int *)field); break;
        case T_LONG: snprintf(dv, sizeof dv, "%ld", *(const long *)field); break;
        case T_FLOAT: snprintf(dv, sizeof dv, "%g", (double)*(const float *)field); break;
        default: snprintf(dv, sizeof dv, "%s", norm_names[*(const rq_norm *)field]); break;
        }
        fprintf(f, "  %-30s %s (default %s)\n", flag, d->help, dv);
    }
}

int rq_options_check(const rq_options *o, ct_error *err)
{
    if (o->children < 1 || o->children > 64)
        return ct_fail(err, CT_EINVAL, "sampler option --children %d: must be 1..64", o->children);
    if (!(o->min_priority >= 0.0f) || !isfinite(o->min_priority))
        return ct_fail(err, CT_EINVAL, "sampler option --min-priority %g: must be >= 0",
                       (double)o->min_priority);
    if (!(o->min_radius > 0.0f) || !isfinite(o->min_radius))
        return ct_fail(err, CT_EINVAL, "sampler option --min-radius %g: must be > 0",
                       (double)o->min_radius);
    if (o->n_sig < 0 || o->n_sig > 10000000)
        return ct_fail(err, CT_EINVAL, "sampler option --n-sig %d: must be 0..10000000", o->n_sig);
    if (!(o->seed_spacing >= 1.0f) || !isfinite(o->seed_spacing))
        return ct_fail(err, CT_EINVAL, "sampler option --seed-spacing %g: must be >= 1",
                       (double)o->seed_spacing);
    if (o->global_batch < 1 || o->global_batch > 1000000)
        return ct_fail(err, CT_EINVAL, "sampler option --global-batch %d: must be 1..1000000",
                       o->global_batch);
    if (o->global_tries < 1 || o->global_tries > 1000)
        return ct_fail(err, CT_EINVAL, "sampler option --global-tries %d: must be 1..1000",
                       o->global_tries);
    if (!(o->coverage_switch >= 0.0f && o->coverage_switch <= 1.0f))
        return ct_fail(err, CT_EINVAL, "sampler option --coverage-switch %g: must be 0..1",
                       (double)o->coverage_switch);
    if ((unsigned)o->norm > RQ_NORM_AVG)
        return ct_fail(err, CT_EINVAL, "sampler option --error-norm: unknown norm %d", (int)o->norm);
    const float pr[3] = {o->prio_reproject, o->prio_seed, o->prio_mismatch};
    const char *pn[3] = {"prio-reproject", "prio-seed", "prio-mismatch"};
    for (int i = 0; i < 3; i++)
        if (!(pr[i] >= 0.0f) || !isfinite(pr[i]))
            return ct_fail(err, CT_EINVAL, "sampler option --%s %g: must be finite and >= 0", pn[i],
                           (double)pr[i]);
    if (o->reseed != 0 && o->reseed != 1)
        return ct_fail(err, CT_EINVAL, "sampler option --reseed %d: must be 0 or 1", o->reseed);
    if (o->max_queue < 0)
        return ct_fail(err, CT_EINVAL, "sampler option --max-queue %ld: must be >= 0", o->max_queue);
    if (!(o->refine_error >= 0.0f) || !isfinite(o->refine_error))
        return ct_fail(err, CT_EINVAL, "sampler option --refine-error %g: must be finite and >= 0",
                       (double)o->refine_error);
    if (o->refine_max < 1 || o->refine_max > 65535)
        return ct_fail(err, CT_EINVAL, "sampler option --refine-max %d: must be 1..65535", o->refine_max);
    return 0;
}

/* rq_options.c: the sampler's option table (common/optab.h): defaults,
 * parsing by name and the --help lines from one row per option, so every
 * driver (corrtex converge, corrtex-render) exposes the same options with the
 * same defaults; rq_options_check for values set in code. */
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "common/optab.h"
#include "master/sampler.h"

#define OF(f) offsetof(rq_options, f)
static const optab OPTS[] = {
    /* §3.7: N = 4 children per sample */
    {"children", 0, OPTAB_INT, OF(children), 1, 64, "4", "N",
     "children per returned sample, radius s/sqrt(N) (paper 3.7)", NULL},
    /* half an 8-bit display step over a 1-pixel domain */
    {"min-priority", 0, OPTAB_FLOAT, OF(min_priority), 0, 3e38, "0.001953125", "P",
     "discard children whose priority |E|*s_c is below P", NULL},
    /* below one pixel a domain is already at image resolution */
    {"min-radius", 0, OPTAB_FLOAT, OF(min_radius), 1e-30, 3e38, "1", "PX",
     "no children with a domain radius below PX pixels", NULL},
    /* §3.7: n_sig (the paper gives no value) */
    {"n-sig", 0, OPTAB_INT, OF(n_sig), 0, 10000000, "500", "N",
     "most significant samples reprojected on a camera change (paper 3.7)", NULL},
    /* 1,024 initial requests at 1024x1024 (§5: 1,000-4,000 per frame) */
    {"seed-spacing", 0, OPTAB_FLOAT, OF(seed_spacing), 1, 3e38, "32", "PX",
     "spacing of the initial jittered grid of requests", NULL},
    {"global-batch", 0, OPTAB_INT, OF(global_batch), 1, 1000000, "64", "N",
     "random global requests added when the queue runs dry", NULL},
    {"global-tries", 0, OPTAB_INT, OF(global_tries), 1, 1000, "16", "N",
     "random positions tried per global request before giving up", NULL},
    /* §3.7: "if most pixels are covered" */
    {"coverage-switch", 0, OPTAB_FLOAT, OF(coverage_switch), 0, 1, "0.9", "F",
     "pixel coverage (0..1) at which the shuffled list of remaining pixels takes over", NULL},
    {"error-norm", 0, OPTAB_CHOICE, OF(norm), 0, 0, "max", "max|lum|avg", "RGB norm of the sample error E", NULL},
    /* §3.7: high priority, above every |E| * s */
    {"prio-reproject", 0, OPTAB_FLOAT, OF(prio_reproject), 0, 3e38, "4e9", "P",
     "priority of reprojected significant samples", NULL},
    /* §3.7: high priority */
    {"prio-seed", 0, OPTAB_FLOAT, OF(prio_seed), 0, 3e38, "2e9", "P",
     "priority of initial, global and remaining-list requests", NULL},
    {"prio-mismatch", 0, OPTAB_FLOAT, OF(prio_mismatch), 0, 3e38, "1e9", "P",
     "priority of children of samples that hit another node than shown", NULL},
    /* Fig. 4 starts a new view from the reprojected samples alone and adds
     * global requests when the queue runs dry; while the camera moves it
     * never does, and what comes into view is never sampled (docs/sampling.md). */
    {"reseed", 0, OPTAB_INT, OF(reseed), 0, 1, "1", "0|1", "queue a fresh initial grid on every camera change too",
     NULL},
    {"max-queue", 0, OPTAB_LONG, OF(max_queue), 0, 9e18, "0", "N", "cap on queued requests (0 = one per pixel)",
     NULL},
    /* Past full coverage a still view goes on being sampled where a pixel's
     * mean is least certain, until its standard error, as displayed (sRGB at
     * exposure 0), is under half an 8-bit step. */
    {"refine-error", 0, OPTAB_FLOAT, OF(refine_error), 0, 3e38, "0.002", "E",
     "after full coverage keep sampling pixels whose mean's standard error as displayed (sRGB, exposure 0) is over "
     "E (0: stop at one sample)",
     NULL},
    {"refine-max", 0, OPTAB_INT, OF(refine_max), 1, 65535, "256", "N",
     "at most N samples per pixel when refining (1..65535)", NULL},
};
#undef OF

const optab *rq_options_table(size_t *n)
{
    *n = OPTAB_COUNT(OPTS);
    return OPTS;
}

void rq_options_default(rq_options *o)
{
    memset(o, 0, sizeof *o);
    ct_error err;
    optab_defaults(OPTS, OPTAB_COUNT(OPTS), o, &err);   /* the table's defaults parse (test_sampler) */
}

int rq_options_set(rq_options *o, const char *name, const char *value, ct_error *err)
{
    int rc = optab_set(OPTS, OPTAB_COUNT(OPTS), o, name, value, err);
    if (rc == 0) return ct_fail(err, CT_EINVAL, "unknown sampler option --%s", name);
    return rc < 0 ? rc : 0;
}

void rq_options_usage(FILE *f)
{
    optab_usage(OPTS, OPTAB_COUNT(OPTS), NULL, f);
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

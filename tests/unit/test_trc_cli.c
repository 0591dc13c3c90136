/* The tracer's command-line options (tracer/trc_cli.h), the one table
 * corrtex-render, corrtex reference, converge and naive share: defaults are
 * the mode's, given values override them (0 levels included), bad values
 * are refused naming the option and its range. */
#include <criterion/criterion.h>
#include <string.h>

#include "tracer/trc_cli.h"

/* Parses argv (NULL-terminated, without a program name) into c. */
static int parse(trc_cli *c, const char *const *args, ct_error *err)
{
    size_t n;
    const optab *t = trc_cli_table(&n);
    cr_assert_eq(optab_defaults(t, n, c, err), 0, "%s", err->msg);
    char prog[] = "prog";
    char *argv[32] = {prog};
    int argc = 1;
    for (; args[argc - 1]; argc++) argv[argc] = (char *)args[argc - 1];
    optab_group g = {t, n, c};
    int npos = 0;
    return optab_parse(&g, 1, argc, argv, NULL, 0, &npos, err);
}

Test(trc_cli, defaults_are_the_modes)
{
    trc_cli c;
    ct_error err;
    const char *none[] = {NULL};
    cr_assert_eq(parse(&c, none, &err), 0, "%s", err.msg);
    trc_options got, want;
    trc_cli_apply(&c, &got);
    trc_options_default(&want, TRC_MODE_DRT);
    cr_expect_eq(got.mode, TRC_MODE_DRT);
    cr_expect_eq(got.shadow_rays, want.shadow_rays);
    cr_expect_eq(got.branch, want.branch);
    cr_expect_eq(got.branch_depth, want.branch_depth);
    cr_expect_eq(got.fresnel_depth, want.fresnel_depth);
    cr_expect_eq(got.fresnel_depth, 3);
    cr_expect_eq(got.depth, want.depth);
    cr_expect_eq(got.indirect, want.indirect);
    cr_expect_eq(got.gather_rays, want.gather_rays);
    cr_expect_eq(got.gather_direct, want.gather_direct);
    cr_expect_eq(got.gather_direct, TRC_GATHER_DIRECT_TRACE);
    /* path's own defaults, not drt's, when only the mode is given */
    const char *path[] = {"--mode", "path", NULL};
    cr_assert_eq(parse(&c, path, &err), 0, "%s", err.msg);
    trc_cli_apply(&c, &got);
    trc_options_default(&want, TRC_MODE_PATH);
    cr_expect_eq(got.mode, TRC_MODE_PATH);
    cr_expect_eq(got.depth, want.depth);
    cr_expect_eq(got.shadow_rays, want.shadow_rays);
}

Test(trc_cli, given_values_override_the_mode_and_zero_levels_count)
{
    trc_cli c;
    ct_error err;
    const char *a[] = {"--mode", "reuse-diffuse", "--shadow-rays", "9", "--branch", "3", "--branch-depth", "0",
                       "--fresnel-depth", "0", "--depth", "0", "--indirect", "mesh", "--gather-rays", "7",
                       "--gather-direct", "mesh", NULL};
    cr_assert_eq(parse(&c, a, &err), 0, "%s", err.msg);
    trc_options o;
    trc_cli_apply(&c, &o);
    cr_expect_eq(o.mode, TRC_MODE_REUSE);
    cr_expect_eq(o.shadow_rays, 9);
    cr_expect_eq(o.branch, 3);
    cr_expect_eq(o.branch_depth, 0, "--branch-depth 0 is a level, not 'the default'");
    cr_expect_eq(o.fresnel_depth, 0, "--fresnel-depth 0 is a level, not 'the default'");
    cr_expect_eq(o.depth, 0, "--depth 0 is a depth, not 'the default'");
    cr_expect_eq(o.indirect, TRC_INDIRECT_MESH);
    cr_expect_eq(o.gather_rays, 7);
    cr_expect_eq(o.gather_direct, TRC_GATHER_DIRECT_MESH);
    const char *m1[] = {"--depth", "-1", NULL};
    cr_assert_eq(parse(&c, m1, &err), 0, "%s", err.msg);
    trc_cli_apply(&c, &o);
    cr_expect_eq(o.depth, 8, "-1: the mode's depth");
}

Test(trc_cli, bad_values_name_the_option)
{
    static const struct {
        const char *opt, *val, *says;
    } bad[] = {
        {"--mode", "whitted", "whitted"},
        {"--shadow-rays", "0", "--shadow-rays: '0'"},
        {"--shadow-rays", "4097", "[1, 4096]"},
        {"--branch", "x", "--branch: 'x'"},
        {"--depth", "-2", "--depth: '-2'"},
        {"--branch-depth", "1025", "--branch-depth"},
        {"--fresnel-depth", "-2", "--fresnel-depth: '-2'"},
        {"--indirect", "path", "path"},
        {"--gather-rays", "0", "--gather-rays: '0'"},
        {"--gather-direct", "path", "path"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        trc_cli c;
        ct_error err;
        const char *a[] = {bad[i].opt, bad[i].val, NULL};
        cr_expect_eq(parse(&c, a, &err), CT_EINVAL, "%s %s accepted", bad[i].opt, bad[i].val);
        cr_expect(strstr(err.msg, bad[i].says) != NULL, "%s %s: '%s' does not say '%s'", bad[i].opt, bad[i].val,
                  err.msg, bad[i].says);
    }
}

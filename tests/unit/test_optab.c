/* The option tables (common/optab.h): defaults come from the rows, values are
 * checked against each row's type and range with one error line naming the
 * option, argv parsing tells an unknown option from a missing value, and
 * every engine's table has defaults that parse. */
#include <criterion/criterion.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/optab.h"
#include "master/ctex.h"
#include "master/drive.h"
#include "master/sampler.h"
#include "master/sched.h"
#include "master/session.h"

typedef struct toy {
    int n;
    long l;
    uint64_t seed;
    size_t mb;
    float x;
    double d;
    bool flag;
    int mode;
    const char *file;
} toy;

static const int MODE_CODES[] = {7, -1, 3};

#define OF(f) offsetof(toy, f)
static const optab TOY[] = {
    {"count", 'n', OPTAB_INT, OF(n), 1, 64, "4", "N", "a count", NULL},
    {"big", 0, OPTAB_LONG, OF(l), -5, 9e18, "-2", "N", "a long", NULL},
    {"seed", 0, OPTAB_U64, OF(seed), 0, 1.8446744073709552e19, "1", "S", "a seed", NULL},
    {"queue-mb", 0, OPTAB_SIZE, OF(mb), 1, 65536, "64", "N", "a size", NULL},
    {"rate", 0, OPTAB_FLOAT, OF(x), 0.01, 64, "2", "X", "a float", NULL},
    {"ms", 0, OPTAB_DOUBLE, OF(d), 0, 1e4, "0.5", "X", "a double", NULL},
    {"quick", 'q', OPTAB_FLAG, OF(flag), 0, 0, NULL, NULL, "a flag", NULL},
    {"enc", 0, OPTAB_CHOICE, OF(mode), 0, 0, "auto", "raw|auto|lz4", "a choice", MODE_CODES},
    {"out", 'o', OPTAB_STRING, OF(file), 0, 0, NULL, "DIR", "a string", NULL},
};
#undef OF

Test(optab, defaults_come_from_the_rows)
{
    toy t;
    memset(&t, 0xab, sizeof t);
    ct_error err;
    cr_assert_eq(optab_defaults(TOY, OPTAB_COUNT(TOY), &t, &err), 0, "%s", err.msg);
    cr_assert_eq(t.n, 4);
    cr_assert_eq(t.l, -2);
    cr_assert_eq(t.seed, 1u);
    cr_assert_eq(t.mb, 64u);
    cr_assert_eq(t.x, 2.0f);
    cr_assert_eq(t.d, 0.5);
    cr_assert(!t.flag);
    cr_assert_eq(t.mode, -1, "a choice stores its code");
    cr_assert_null(t.file);
}

Test(optab, values_set_and_checked)
{
    toy t;
    ct_error err;
    optab_defaults(TOY, OPTAB_COUNT(TOY), &t, &err);
    size_t n = OPTAB_COUNT(TOY);
    cr_assert_eq(optab_set(TOY, n, &t, "count", "64", &err), 1);
    cr_assert_eq(t.n, 64);
    cr_assert_eq(optab_set(TOY, n, &t, "seed", "18446744073709551615", &err), 1, "%s", err.msg);
    cr_assert_eq(t.seed, UINT64_MAX, "every digit of a 64-bit seed is kept");
    cr_assert_eq(optab_set(TOY, n, &t, "enc", "lz4", &err), 1);
    cr_assert_eq(t.mode, 3);
    cr_assert_eq(optab_set(TOY, n, &t, "big", "-5", &err), 1);
    cr_assert_eq(t.l, -5);
    cr_assert_eq(optab_set(TOY, n, &t, "nope", "1", &err), 0, "not in the table");

    /* bad values: the field keeps its value, the message names the option */
    static const struct {
        const char *name, *value, *msg;
    } bad[] = {
        {"count", "65", "--count: '65' is not an integer in [1, 64]"},
        {"count", "0", "--count: '0' is not an integer in [1, 64]"},
        {"count", "4x", "--count: '4x' is not an integer in [1, 64]"},
        {"count", "2.5", "--count: '2.5' is not an integer in [1, 64]"},
        {"count", "", "--count: '' is not an integer in [1, 64]"},
        {"seed", "-1", "--seed: '-1' is not an integer"},
        {"seed", "18446744073709551616", "--seed: '18446744073709551616' is not an integer"},
        {"queue-mb", "0", "--queue-mb: '0' is not an integer in [1, 65536]"},
        {"big", "-6", "--big: '-6' is not an integer"},
        {"rate", "nan", "--rate: 'nan' is not a number in [0.01, 64]"},
        {"rate", "inf", "--rate: 'inf' is not a number in [0.01, 64]"},
        {"rate", "0.001", "--rate: '0.001' is not a number in [0.01, 64]"},
        {"rate", "1e999", "--rate: '1e999' is not a number in [0.01, 64]"},
        {"ms", "5 ", "--ms: '5 ' is not a number in [0, 10000]"},
        /* leading blanks too: strto* skip them, a quoting slip is no number */
        {"ms", " 5", "--ms: ' 5' is not a number in [0, 10000]"},
        {"count", " 5", "--count: ' 5' is not an integer in [1, 64]"},
        {"seed", "\t7", "--seed: '\t7' is not an integer"},
        {"big", " -1", "--big: ' -1' is not an integer"},
        {"enc", "LZ4", "--enc: 'LZ4' is not one of raw|auto|lz4"},
        {"enc", "raw|auto", "--enc: 'raw|auto' is not one of raw|auto|lz4"},
        {"count", NULL, "option --count needs a value"},
        /* an empty string names no file: it used to pass for none, or fail
         * after the work ("corrtex radiosity -o ''") */
        {"out", "", "--out: the value is empty (give DIR)"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        toy before = t;
        ct_error_clear(&err);
        cr_assert_eq(optab_set(TOY, n, &t, bad[i].name, bad[i].value, &err), CT_EINVAL, "%s %s", bad[i].name,
                     bad[i].value ? bad[i].value : "(none)");
        cr_assert(strstr(err.msg, bad[i].msg), "got '%s', want '%s'", err.msg, bad[i].msg);
        cr_assert(memcmp(&before, &t, sizeof t) == 0, "a bad value changed the options");
    }
}

/* argv (NULL-terminated) refused with CT_EINVAL and, when msg is given,
 * exactly that message. */
static void refused(const optab_group *g, const char *const *argv, const char *msg)
{
    int argc = 0;
    while (argv[argc]) argc++;
    const char *pos[2];
    int np = 0;
    ct_error err;
    ct_error_clear(&err);
    cr_assert_eq(optab_parse(g, 1, argc, (char **)argv, pos, 2, &np, &err), CT_EINVAL, "%s", argv[1]);
    if (msg) cr_assert_str_eq(err.msg, msg);
}

Test(optab, argv_parse)
{
    toy t;
    ct_error err;
    optab_defaults(TOY, OPTAB_COUNT(TOY), &t, &err);
    optab_group g = {TOY, OPTAB_COUNT(TOY), &t};
    const char *pos[2];
    int np = 0;
    const char *ok[] = {"prog", "scene.json", "-n", "3", "--quick", "-o", "dir", "--rate", "0.5", NULL};
    cr_assert_eq(optab_parse(&g, 1, 9, (char **)ok, pos, 2, &np, &err), 0, "%s", err.msg);
    cr_assert_eq(np, 1);
    cr_assert_str_eq(pos[0], "scene.json");
    cr_assert_eq(t.n, 3);
    cr_assert(t.flag);
    cr_assert_str_eq(t.file, "dir");
    cr_assert_eq(t.x, 0.5f);

    const char *help[] = {"prog", "--count", "2", "-h"};
    cr_assert_eq(optab_parse(&g, 1, 4, (char **)help, pos, 2, &np, &err), 1);

    refused(&g, (const char *[]){"prog", "--bogus", NULL}, "unknown option '--bogus' (try --help)");
    refused(&g, (const char *[]){"prog", "--count", NULL}, "option --count needs a value (try --help)");
    refused(&g, (const char *[]){"prog", "a", "b", "c", NULL}, "unexpected argument 'c' (try --help)");
    const char *badval[] = {"prog", "--count", "many"};
    cr_assert_eq(optab_parse(&g, 1, 3, (char **)badval, pos, 2, &np, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "--count: 'many' is not an integer"), "%s", err.msg);

    /* --name=value, and "--" before arguments that look like options */
    const char *eq[] = {"prog", "--count=7", "--rate=0.25", "--", "-file.json"};
    cr_assert_eq(optab_parse(&g, 1, 5, (char **)eq, pos, 2, &np, &err), 0, "%s", err.msg);
    cr_assert_eq(t.n, 7);
    cr_assert_eq(t.x, 0.25f);
    cr_assert_eq(np, 1);
    cr_assert_str_eq(pos[0], "-file.json");
    refused(&g, (const char *[]){"prog", "--quick=1", NULL}, "option --quick takes no value");
    refused(&g, (const char *[]){"prog", "--bogus=3", NULL}, "unknown option '--bogus' (try --help)");
    refused(&g, (const char *[]){"prog", "--count=-5", NULL}, NULL);
    refused(&g, (const char *[]){"prog", "--out=", NULL}, "--out: the value is empty (give DIR)");
    refused(&g, (const char *[]){"prog", "", NULL}, "an empty argument (try --help)");
}

/* Whether an option was on the command line, also at its default value
 * (programs refuse one that another option makes meaningless). */
Test(optab, given_options)
{
    toy t;
    ct_error err;
    optab_defaults(TOY, OPTAB_COUNT(TOY), &t, &err);
    optab_group g = {TOY, OPTAB_COUNT(TOY), &t};
    const char *a[] = {"prog", "--count", "0", "--rate=0.5", "--quick", "--", "--out", NULL};
    char **argv = (char **)a;
    int argc = 7;
    cr_assert(optab_given(&g, 1, argc, argv, "count"), "--count 0 (its default) not seen");
    cr_assert(optab_given(&g, 1, argc, argv, "rate"), "--rate=0.5 not seen");
    cr_assert(optab_given(&g, 1, argc, argv, "quick"));
    cr_assert_not(optab_given(&g, 1, argc, argv, "out"), "a positional '--out' after '--' taken for the option");
    cr_assert_not(optab_given(&g, 1, argc, argv, "seed"));
    cr_assert_not(optab_given(&g, 1, argc, argv, "nosuch"));
    /* a value that looks like an option is the value, not the option */
    const char *v[] = {"prog", "-o", "--quick", NULL};
    char **val = (char **)v;
    cr_assert_not(optab_given(&g, 1, 3, val, "quick"));
    cr_assert(optab_given(&g, 1, 3, val, "out"));
}

/* A default that does not parse (or lies outside its range) is a broken table. */
Test(optab, every_engine_table_has_valid_defaults)
{
    const struct {
        const char *what;
        const optab *(*table)(size_t *n);
        size_t size;
    } tables[] = {
        {"request queue", rq_options_table, sizeof(rq_options)},
        {"corrective textures", ctex_options_table, sizeof(ctex_options)},
        {"session", sess_options_table, sizeof(sess_options)},
        {"loop", drv_options_table, sizeof(drv_options)},
        {"scheduling loop", sched_options_table, sizeof(sched_options)},
    };
    for (size_t k = 0; k < sizeof tables / sizeof tables[0]; k++) {
        size_t n = 0;
        const optab *t = tables[k].table(&n);
        cr_assert_gt(n, 0);
        char buf[512];
        ct_error err;
        cr_assert_eq(optab_defaults(t, n, buf, &err), 0, "%s: %s", tables[k].what, err.msg);
        for (size_t i = 0; i < n; i++) {
            cr_assert_lt(t[i].off, tables[k].size, "%s: --%s outside its struct", tables[k].what, t[i].name);
            for (size_t j = i + 1; j < n; j++)
                cr_assert(strcmp(t[i].name, t[j].name), "%s: --%s twice", tables[k].what, t[i].name);
        }
    }
    toy t;
    const optab broken[] = {{"count", 0, OPTAB_INT, offsetof(toy, n), 1, 64, "100", "N", "out of range", NULL}};
    ct_error err;
    cr_assert_eq(optab_defaults(broken, 1, &t, &err), CT_EINVAL);
    cr_assert(strstr(err.msg, "default: --count: '100'"), "%s", err.msg);
}

/* --help shows a choice without a default of its own by the word of the
 * value in the defaults struct (corrtex-display's come from code), and none
 * when the value is no word's (a default resolved later). */
Test(optab, usage_shows_a_choice_default_from_the_struct)
{
    static const optab ROW[] = {
        {"enc", 0, OPTAB_CHOICE, offsetof(toy, mode), 0, 0, NULL, "raw|auto|lz4", "a choice", MODE_CODES},
    };
    toy t;
    memset(&t, 0, sizeof t);
    char *text = NULL;
    size_t len = 0;
    const int values[] = {3, 99};
    const char *want[] = {"(default lz4)", NULL};
    for (int i = 0; i < 2; i++) {
        t.mode = values[i];
        FILE *f = open_memstream(&text, &len);
        cr_assert_not_null(f);
        optab_usage(ROW, 1, &t, f);
        fclose(f);
        if (want[i]) cr_assert(strstr(text, want[i]) != NULL, "value %d: %s", values[i], text);
        else cr_assert(strstr(text, "default") == NULL, "value %d: %s", values[i], text);
        free(text);
        text = NULL;
    }
}

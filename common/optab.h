/* optab.h: command-line options described by tables: one row per option
 * gives its name, the type and place of its field in an options struct,
 * its range, its default and its help text, so that parsing, defaults,
 * range checks and --help lines all come from that one row. Every option
 * parser of the engines (request queue, corrective textures, the master's
 * loop and session) and of the programs goes through it. Owns the optab_
 * prefix. */
#ifndef CT_COMMON_OPTAB_H
#define CT_COMMON_OPTAB_H

#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>

#include "common/error.h"

typedef enum optab_type {
    OPTAB_INT = 1,   /* int: a whole number in [lo, hi] */
    OPTAB_LONG,      /* long: the same */
    OPTAB_U32,       /* uint32_t: the same (lo >= 0) */
    OPTAB_U64,       /* uint64_t: the same (lo >= 0) */
    OPTAB_SIZE,      /* size_t: the same (lo >= 0) */
    OPTAB_FLOAT,     /* float: a finite number in [lo, hi] */
    OPTAB_DOUBLE,    /* double: the same */
    OPTAB_FLAG,      /* bool: set by the option alone, it takes no value */
    OPTAB_CHOICE,    /* int: one of the words of `arg` ("max|lum|avg"), stored
                        as codes[k] of word k, or k when codes is NULL */
    OPTAB_STRING     /* const char *: the value as given (NULL when unset) */
} optab_type;

typedef struct optab {
    const char *name;     /* without "--" */
    char short_name;      /* "-x" alias, 0 for none */
    optab_type type;
    size_t off;           /* offsetof the field in the options struct */
    double lo, hi;        /* numbers: the accepted range */
    const char *def;      /* the default, written as on the command line (NULL: zero, false, NULL) */
    const char *arg;      /* the value's name in --help ("N", "X", "FILE", the choices) */
    const char *help;
    const int *codes;     /* OPTAB_CHOICE: the stored value of each word, or NULL */
} optab;

/* A table and the struct it fills. */
typedef struct optab_group {
    const optab *rows;
    size_t n;
    void *base;
} optab_group;

#define OPTAB_COUNT(t) (sizeof(t) / sizeof((t)[0]))

/* Writes every row's default into base. CT_EINVAL (naming the option) when
 * a default does not parse: a broken table. */
int optab_defaults(const optab *t, size_t n, void *base, ct_error *err);

/* The row named `name` (without "--"), or NULL. */
const optab *optab_find(const optab *t, size_t n, const char *name);

/* Sets option `name` from value (NULL for a flag): 1 when it is one of the
 * table's, 0 when not, CT_EINVAL for a bad or missing value ("--tex-rate:
 * 'x' is not a number in [0.01, 64]"; an empty string is no value of any
 * type). */
int optab_set(const optab *t, size_t n, void *base, const char *name, const char *value, ct_error *err);

/* One "  --name ARG   help (default X)" line per row. A row without a
 * default of its own (def NULL: the field's default is set in code, e.g. by
 * an engine's *_default function) shows its value in `defaults` when that
 * is given. */
void optab_usage(const optab *t, size_t n, const void *defaults, FILE *f);

/* Parses argv[1 .. argc) against the groups, in order: "--name VALUE" (or
 * "-x VALUE"), flags, and up to maxpos positional arguments into pos[]
 * (*npos of them; an empty one is refused: they name files). "-h" and "--help" return 1 at once. An unknown option
 * is named as unknown, also when given last; a known one given last
 * without its value is reported as missing it. 0 or CT_EINVAL. */
int optab_parse(const optab_group *g, int ng, int argc, char **argv, const char **pos, int maxpos, int *npos,
                ct_error *err);

/* Whether option `name` of the groups is on the command line (as
 * optab_parse reads it): a program that refuses an option another makes
 * meaningless must know it was given, also at its default value. */
bool optab_given(const optab_group *g, int ng, int argc, char **argv, const char *name);

#endif

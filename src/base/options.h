/* fogpipe: option tables (after FFmpeg's AVOption and GEGL's property
 * lists).  One table per stage declares name, type, field, default, hard
 * range and help; parsing, range checks, --help, the README reference and
 * preset files all read the tables, so there is one source of truth.
 *
 * This header is the tables' form, which every stage uses to declare its
 * own; the whole set of tables and what reads them (parsing, presets,
 * looks, --help) sit above the stages, in lib/options_all.h. */
#ifndef FP_OPTIONS_H
#define FP_OPTIONS_H

#include <stddef.h>
#include <stdio.h>
#include "params.h"

typedef enum {
    FP_OPT_FLAG,     /* no argument on the CLI; "1/0/true/false/yes/no" in presets */
    FP_OPT_INT,
    FP_OPT_REAL,
    FP_OPT_STRING,
    FP_OPT_ENUM,     /* one of `choices` ("a|b|c"), stored as its index (int) */
    FP_OPT_VEC       /* min_count..count comma-separated reals */
} fp_opt_type_t;

struct fp_option_t;
typedef int (*fp_opt_setter_t)(fp_params_t *p, const struct fp_option_t *o,
                               const char *value);

typedef struct fp_option_t {
    const char *name;       /* long name, without "--" */
    char short_name;        /* or 0 */
    fp_opt_type_t type;
    size_t offset;          /* field in fp_params_t */
    int count, min_count;   /* FP_OPT_VEC */
    const char *def;        /* default, written as a user would; NULL: unset */
    double min, max;        /* hard range (each component) */
    const char *choices;    /* FP_OPT_ENUM */
    const char *metavar;    /* "X,Y,Z" */
    const char *help;
    fp_opt_setter_t set;    /* custom parser: aliases such as --visibility */
    unsigned flags;
} fp_option_t;

enum {
    FP_OPTF_CLI_ONLY = 1,   /* a command, not allowed in preset files */
    FP_OPTF_HIDDEN = 2      /* not in --help */
};

typedef struct fp_option_group_t {
    const char *title;
    const fp_option_t *options;  /* ends with a row whose name is NULL */
} fp_option_group_t;

/* Whether the user set option `name` (the command line, a preset or a
 * look; src/base/option_table.c). */
int fp_options_given(const fp_params_t *p, const char *name);
/* The row named `name` of one table (ending with FP_OPT_END), or NULL. */
const fp_option_t *fp_option_lookup(const fp_option_t *table, const char *name);

#define FP_OPT_END { NULL, 0, 0, 0, 0, 0, NULL, 0, 0, NULL, NULL, NULL, NULL, 0 }

#endif

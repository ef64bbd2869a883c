/* fogpipe: option tables (after FFmpeg's AVOption and GEGL's property
 * lists).  One table per stage declares name, type, field, default, hard
 * range and help; parsing, range checks, --help, the README reference and
 * preset files all read the tables, so there is one source of truth. */
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

extern const fp_option_group_t fp_option_groups[];

/* Set every field to its default. */
int fp_options_defaults(fp_params_t *p);
/* Parse argv (after defaults): --preset FILE lines first, then the CLI,
 * which wins.  Returns FP_EUSAGE with a message on a bad option or value. */
int fp_options_parse(int argc, char **argv, fp_params_t *p);
/* Apply one "name" = "value" (value NULL for a flag on the CLI). `origin`
 * labels messages ("command line", "preset.fp:12"). */
int fp_options_apply(fp_params_t *p, const char *name, const char *value,
                     const char *origin);
int fp_options_load_preset(fp_params_t *p, const char *path);
/* The look a frame or a rig file carries (src/rig.h): "fogpipe-look 1
 * name=value ..." (whitespace or ';' between pairs, names as the long
 * options), applied as a preset's lines are but under the command line and
 * --preset (an option already set there, or through an alias of its field,
 * is left as it is).  Only the fog's look is taken (the Fog, Light, Fog
 * buffers and Animation groups, no file names): anything else is an error
 * naming `origin`. */
int fp_options_apply_look(fp_params_t *p, const char *text, const char *origin);
const fp_option_t *fp_options_find(const char *name);
int fp_options_given(const fp_params_t *p, const char *name);
/* --help, generated from the tables; markdown=1 writes the README table. */
void fp_options_print_help(FILE *out, int markdown);
void fp_options_free(fp_params_t *p);

#define FP_OPT_END { NULL, 0, 0, 0, 0, 0, NULL, 0, 0, NULL, NULL, NULL, NULL, 0 }

#endif

/* fogpipe: the option tables of every stage together (lib/options.c):
 * parsing the command line, preset files and looks, --help.  Above the
 * stages, since it lists each stage's table; a stage sees only its own
 * table's form (src/base/options.h). */
#ifndef FP_OPTIONS_ALL_H
#define FP_OPTIONS_ALL_H

#include <stdio.h>

#include "options.h"
#include "params.h"

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
/* The look a frame or a rig file carries (src/scene/rig.h): "fogpipe-look 1
 * name=value ..." (whitespace or ';' between pairs, names as the long
 * options), applied as a preset's lines are but under the command line and
 * --preset (an option already set there, or through an alias of its field,
 * is left as it is).  Only the fog's look is taken (the Fog, Light, Fog
 * buffers and Animation groups, no file names): anything else is an error
 * naming `origin`. */
int fp_options_apply_look(fp_params_t *p, const char *text, const char *origin);
const fp_option_t *fp_options_find(const char *name);
/* --help, generated from the tables; markdown=1 writes the README table. */
void fp_options_print_help(FILE *out, int markdown);
void fp_options_free(fp_params_t *p);

#endif

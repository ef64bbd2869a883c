/* fogpipe: what a stage asks of the option tables (src/base/options.h):
 * whether the user set an option, and a row of its own table.  The
 * parsing of all tables together is lib/options.c. */
#include "options.h"

#include <string.h>

int fp_options_given(const fp_params_t *p, const char *name)
{
    for (int i = 0; i < p->num_given; i++)
        if (strcmp(p->given[i], name) == 0)
            return 1;
    return 0;
}

const fp_option_t *fp_option_lookup(const fp_option_t *table, const char *name)
{
    for (const fp_option_t *o = table; o->name; o++)
        if (strcmp(o->name, name) == 0)
            return o;
    return NULL;
}

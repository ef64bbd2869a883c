/* The scatter stage's pieces shared by its files (filters/scatter.c: the
 * options, the commit and the C reference; filters/lights.c: the lights'
 * parsing, checks and table; filters/scatter_frame.c: the per-frame
 * shadow map, depth buffer and self-shadow grid bounds;
 * filters/scatter_cl.c: the OpenCL launch).  Not part of the library's
 * interface. */
#ifndef FP_SCATTER_INTERNAL_H
#define FP_SCATTER_INTERNAL_H

#include "options.h"
#include "scatter.h"

#include <stddef.h>

/* --light's option setter (the row in fp_scatter_options). */
int fp_scatter_set_light(fp_params_t *p, const fp_option_t *o, const char *value);

/* The lights' table (kernels/light_core.h FP_LL_*) in d->lights, fog
 * space, local lights first; d->nlights, FP_LT_NLIGHTS and FP_LT_NDIR. */
int fp_scatter_pack_lights(const fp_params_t *p, fp_scatter_data_t *d);

/* Whether d looks up a self-shadow grid, and its number of nodes. */
int fp_scatter_uses_grid(const fp_scatter_data_t *d);
size_t fp_scatter_grid_nodes(const double *lt);

/* 1 when the grid filled from k is the one d and fog ask for; else k
 * becomes theirs (the caller fills the grid, and clears k->valid if that
 * fails). */
int fp_scatter_grid_current(fp_grid_key_t *k, const fp_scatter_data_t *d,
                            const fp_integrate_data_t *fog);

/* Unit vector in place (v non-zero). */
void fp_scatter_normalize3(double v[3]);

#endif

/* fogpipe stage "fogmap": the wavelet fogmap (seed 000): load the image
 * (OpenImageIO, as data), decompose it into B-spline wavelet levels
 * (filters/wavelet.c, OpenCL or the C reference), and lay the levels out
 * for the integrator (coefficients, level table, occupancy blocks for
 * sparse skipping). */
#ifndef FP_FOGMAP_H
#define FP_FOGMAP_H

#include "clrt.h"
#include "integrate.h"
#include "params.h"
#include "wavelet.h"

typedef struct fp_fogmap_stage_t {
    fp_fogmap_t map;
    fp_fog_tables_t tables;
    double decompose_ms;      /* time of the decomposition */
    int used_cl;              /* the decomposition ran in OpenCL */
} fp_fogmap_stage_t;

/* Load and decompose --fogmap (nothing when it is not set: *active = 0),
 * fill the fogmap entries of `d` and point it at the tables.  `cl` may be
 * NULL (C reference). */
int fp_fogmap_commit(const fp_params_t *p, fp_cl_t *cl, fp_fogmap_stage_t *s,
                     fp_integrate_data_t *d, int *active);

/* The same from pixels in memory (w x h, row 0 at the fogmap's first row):
 * what fp_fogmap_commit does after loading. */
int fp_fogmap_setup(const fp_params_t *p, fp_cl_t *cl, const float *img, int w, int h,
                    fp_fogmap_stage_t *s, fp_integrate_data_t *d);

/* Per-frame parameters that depend on the camera (--lod-footprint). */
void fp_fogmap_frame(const fp_params_t *p, const fp_view_t *v, fp_integrate_data_t *d);

/* --fogmap-preview DIR: one PNG per level and the reconstructed fogmap. */
int fp_fogmap_preview(const fp_fogmap_stage_t *s, const char *dir);

void fp_fogmap_release(fp_fogmap_stage_t *s);

#endif

/* fogpipe: the fogmap image, before it is decomposed: its values
 * checked and cleaned, as one fogmap or each key of a sequence.  Below
 * both the fogmap stage (filters/fogmap.c), which loads a still fogmap,
 * and the animation (filters/animate.c), which loads a sequence's keys and
 * is driven by the fogmap stage. */
#ifndef FP_FOGMAP_IMAGE_H
#define FP_FOGMAP_IMAGE_H

#include "params.h"

/* Negative fogmap values (noise often dips below 0) set to 0, as an offline
 * renderer clamps density, with one warning: how many, the lowest. */
void fp_fogmap_clamp_negative(const char *name, float *img, int w, int h);

/* The fogmap's values are finite, >= 0 and small enough that their optical
 * depth stays meaningful in single precision (one error line otherwise,
 * naming the pixel and the figures); `od_scale` from fp_fogmap_od_scale. */
int fp_fogmap_check_values(const char *name, const float *img, int w, int h, double od_scale);

/* Optical depth across one fogmap pixel (w x h) per unit of fogmap value:
 * --density times the pixel's shorter side in scene units. */
double fp_fogmap_od_scale(const fp_params_t *p, int w, int h);

#endif

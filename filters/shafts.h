/* fogpipe: the sun's shadow map packed for the exact shaft walk
 * (kernels/shafts_core.h): biased depths and their min-max pyramid. */
#ifndef FP_SHAFTS_H
#define FP_SHAFTS_H

#include <stddef.h>

/* The bias of each texel, in scene units: half the depth's change across
 * the texel on the surface it shows (the smaller of its two one-sided
 * differences per axis, so a caster's edge does not take the depth jump
 * behind it for a slope), at most `max_slope_bias`, plus `user_bias`, plus
 * float rounding's share of the depth.  +inf and NaN texels see nothing
 * (+inf).  Then levels 1..L of 2^l x 2^l blocks' min and max, up to one
 * block.  *out (malloc'd) holds W H + 2 sum(blocks) floats; *levels = L.
 * Returns 0, or -1 when out of memory. */
int fp_shafts_build(const float *z, int w, int h, double max_slope_bias, double user_bias,
                    float **out, size_t *n, int *levels);

/* The same pyramid over z as it is (NaN: +inf), no bias: the depth
 * buffer's scene z for --shadows screen. */
int fp_shafts_pyramid(const float *z, int w, int h, float **out, size_t *n, int *levels);

/* Levels of the pyramid for a W x H map (one block at the last). */
int fp_shafts_levels(int w, int h);

/* Floats of a W x H map packed with its `levels` levels
 * (kernels/light_core.h fp_pyr_size). */
size_t fp_shafts_size(int w, int h, int levels);

#endif

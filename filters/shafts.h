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
 * (+inf).  Then levels 1..L of 2^l x 2^l blocks, up to one block: bounds
 * of the residual zb - ga U - gb V (the ground plane, fp_shafts_plane)
 * over every point of the block's texels, the least rounded down and the
 * largest up.  *out (malloc'd) holds W H + 2 sum(blocks) floats;
 * *levels = L.  Returns 0, or -1 when out of memory. */
int fp_shafts_build(const float *z, int w, int h, double max_slope_bias, double user_bias,
                    double ga, double gb, float **out, size_t *n, int *levels);

/* The ground plane of a w x h map whose fog point -> NDC matrix is ndc
 * (16, row vector, w = 1) and z row cz (4): the map's z of a level
 * surface (y = const) is ga U + gb V + const over texel coordinates;
 * ga, gb are float values (the kernel's), 0 where the sun is at the
 * horizon. */
void fp_shafts_plane(const double *ndc, const double *cz, int w, int h, double *ga, double *gb);

/* The same pyramid over z as it is (NaN: +inf), no bias: the depth
 * buffer's scene z for --shadows screen. */
int fp_shafts_pyramid(const float *z, int w, int h, float **out, size_t *n, int *levels);

/* Levels of the pyramid for a W x H map (one block at the last). */
int fp_shafts_levels(int w, int h);

/* Floats of a W x H map packed with its `levels` levels
 * (kernels/light_core.h fp_pyr_size). */
size_t fp_shafts_size(int w, int h, int levels);

#endif

/* fogpipe stage "aov": the fog as layers that a compositor grades and
 * merges, beside (--aov) or instead of (--aov-only) the composite:
 *
 *   fog.R, fog.G, fog.B     in-scattered light S, premultiplied (it is what
 *                           the fog adds), in the output color space;
 *   fog.A                   1 - mean transmittance (1 - tau: the fog's
 *                           transmittance is grey);
 *   transmittance.R, .G, .B tau (a factor, not a color: not converted).
 *
 * So that "fog over plate", plate * (1 - fog.A) + fog.RGB, is the composite
 * tau * plate + S, in any compositor (Nuke's Merge over, oiiotool --over).
 * Layers are 32-bit float, added to the color's part. */
#ifndef FP_AOV_H
#define FP_AOV_H

#include <stddef.h>

#include "color.h"
#include "exrio.h"
#include "params.h"

#define FP_AOV_LAYERS 7

typedef struct fp_aov_frame_t {
    float *planes;                       /* FP_AOV_LAYERS planes of n floats */
    fp_exr_extra_t extra[FP_AOV_LAYERS];
    int num;                             /* 0: no layers asked for */
} fp_aov_frame_t;
#define FP_AOV_FRAME_INITIALIZER { NULL, { { NULL, NULL } }, 0 }


/* The layers of one frame from its fog layer (S.r, S.g, S.b, tau per pixel,
 * in the working space), S converted to the output space.  Nothing (num 0)
 * without --aov / --aov-only. */
int fp_aov_make(const fp_params_t *p, const fp_color_frame_t *cf, const float *fog, size_t n,
                const char *where, long frame, fp_aov_frame_t *a);
/* Add the layers to the write options (and, for --aov-only, drop every
 * other channel). */
void fp_aov_write_opts(const fp_params_t *p, const fp_aov_frame_t *a, fp_exr_write_opts_t *w);
void fp_aov_free(fp_aov_frame_t *a);

/* Merge the layers over a plate (n RGBA pixels): out.rgb = fog.rgb +
 * plate.rgb * (1 - fog.A), alpha kept.  The judge of the layers in tests. */
void fp_aov_over(const fp_aov_frame_t *a, const float *plate, size_t n, float *out);

#endif

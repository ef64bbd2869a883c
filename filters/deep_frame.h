/* fogpipe stage "deep", one frame (filters/deep.h has the rules): the
 * deep image of a frame, for the pipeline (--deep) and the library's deep
 * result. */
#ifndef FP_DEEP_FRAME_H
#define FP_DEEP_FRAME_H

#include "color.h"
#include "deep.h"
#include "exr_deep.h"

/* The deep image of a flat plate (its RGBA `rgba` in the input space and
 * its `depth`; `plate`, when given, for its other channels; din NULL) or
 * of a deep input `din` (plate and rgba NULL; f->depth its front depth,
 * fp_deep_front_depth): R G B A Z ZBack in the output space, then the
 * input's other channels (on the plate's surface sample; on the deep
 * input's samples and their pieces), 0 on the fog's samples.  `info`:
 * the frame's size and header (camera, windows).  Rows are computed on one
 * thread per core; -v reports the frame's samples a pixel.  Errors name
 * `where` and `frame`. */
int fp_deep_frame(const fp_deep_fog_t *f, const fp_color_frame_t *color,
                  const fp_frame_info_t *info, const fp_frame_t *plate, const float *rgba,
                  const fp_deep_image_t *din, const char *where, long frame,
                  fp_deep_image_t **out, fp_deep_stats_t *st);

/* A deep input's flat depth for the light stage (screen-space shadows,
 * the view): the nearest opaque sample's Z per pixel, sky (inf, or 0 for
 * inverse depth) where none, in the plate's depth convention.  malloc'd. */
float *fp_deep_front_depth(const fp_deep_image_t *din, int depth_kind);

#endif

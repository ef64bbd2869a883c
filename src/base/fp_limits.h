/* fogpipe: the one budget for every image fogpipe reads.
 *
 * Every reader (the EXR C path, the OpenEXR C++ codec path, images read
 * through the OpenImageIO module) checks an image's size from its header
 * against these limits before it allocates or decodes anything, so a small
 * hostile file cannot make fogpipe allocate gigabytes.  `--max-image-pixels`
 * raises them for the rare legitimate giant. */
#ifndef FP_LIMITS_H
#define FP_LIMITS_H

#include <stdint.h>

#include "fp_ctx.h"

#ifdef __cplusplus
extern "C" {
#endif

/* fp_image_limits_t: the budget, kept by the context (src/base/fp_ctx.h). */

/* Defaults: 2^28 pixels (16384 x 16384), 2^20 along an axis, 1024
 * channels, 4096 parts, 1 GiB a line. */
#define FP_LIMIT_PIXELS      ((int64_t) 1 << 28)
#define FP_LIMIT_DIM         ((int64_t) 1 << 20)
#define FP_LIMIT_LINE_BYTES  ((int64_t) 1 << 30)
#define FP_LIMIT_CHANNELS    1024
#define FP_LIMIT_PARTS       4096

/* The limits in force in the current context (src/base/fp_ctx.h; the
 * defaults until fp_image_limits_set is called in it). */
const fp_image_limits_t *fp_image_limits(void);
void fp_image_limits_set(const fp_image_limits_t *l);
void fp_image_limits_default(fp_image_limits_t *l);

/* The limits for a budget of `max_pixels` pixels: the other limits
 * scale with it (an axis: max_pixels / 256, at least FP_LIMIT_DIM, at
 * most max_pixels and 2^31 - 1; a line: 1024 bytes a pixel of the
 * longest axis); channels and parts stay. */
void fp_image_limits_scaled(fp_image_limits_t *l, int64_t max_pixels);

/* Parse a pixel count: digits with an optional K, M or G (powers of
 * 1024: "256M" is 268435456).  FP_OK, or FP_ERR without a message. */
int fp_image_limits_parse(const char *text, int64_t *max_pixels);

/* --max-image-pixels TEXT: parse it and put the scaled limits in force
 * (NULL: the defaults).  A usage error names the option. */
int fp_image_limits_apply(const char *text);

/* Check one image's size against the limits in force: 0, or FP_ERR with a
 * one-line message "FILE: frame N: KIND WxH with C channels exceeds ...
 * (--max-image-pixels raises it)".  `frame` < 0 leaves the frame out (a
 * fogmap); `kind` names the image ("data window", "fogmap", ...). */
int fp_image_limits_check(const char *file, long frame, const char *kind,
                          int64_t width, int64_t height, int64_t channels,
                          int64_t bytes_per_sample);

#ifdef __cplusplus
}
#endif

#endif

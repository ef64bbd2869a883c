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

typedef struct fp_image_limits_t {
    int64_t max_pixels;      /* pixels in one image (one EXR part) */
    int64_t max_dim;         /* pixels along one axis */
    int64_t max_line_bytes;  /* decoded bytes of one scanline, all channels */
    int max_channels;        /* channels in one image */
    int max_parts;           /* parts in one EXR file */
} fp_image_limits_t;

/* Defaults: 2^28 pixels (16384 x 16384), 2^20 along an axis, 1024
 * channels, 4096 parts, 1 GiB a line. */
#define FP_LIMIT_PIXELS      ((int64_t) 1 << 28)
#define FP_LIMIT_DIM         ((int64_t) 1 << 20)
#define FP_LIMIT_LINE_BYTES  ((int64_t) 1 << 30)
#define FP_LIMIT_CHANNELS    1024
#define FP_LIMIT_PARTS       4096

/* The limits in force (process-wide, as fp_exr_set_threads; the defaults
 * until fp_image_limits_set is called). */
const fp_image_limits_t *fp_image_limits(void);
void fp_image_limits_set(const fp_image_limits_t *l);
void fp_image_limits_default(fp_image_limits_t *l);

/* Check one image's size against the limits in force: 0, or FP_ERR with a
 * one-line message "FILE: frame N: KIND WxH with C channels exceeds ...
 * (--max-image-pixels raises it)".  `frame` < 0 leaves the frame out (a
 * fogmap); `kind` names the image ("data window", "fogmap", ...). */
int fp_image_limits_check(const char *file, long frame, const char *kind,
                          int64_t width, int64_t height, int64_t channels,
                          int64_t bytes_per_sample);

#endif

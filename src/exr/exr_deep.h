/* fogpipe: deep scanline EXR frames in and out (OpenEXR 2's deep data,
 * through OpenEXR's C API at the chunk level: exr_read_deep_chunk and
 * exr_write_deep_scanline_chunk, with the chunk codecs deep files allow --
 * none, RLE and ZIPS -- done here: OpenEXR 3.1's C pipeline does not
 * unpack deep samples).
 *
 * A deep image holds, per pixel, a count of samples and per channel that
 * many values, pixels in row-major order over the data window.  Values
 * are kept as 32 bits: float for HALF and FLOAT channels, the integer for
 * UINT ones.  Ownership: an fp_deep_image_t owns everything it points to
 * (fp_deep_free); reentrant like exrio.h. */
#ifndef FP_EXR_DEEP_H
#define FP_EXR_DEEP_H

#include "exrio.h"

#include <stddef.h>
#include <stdint.h>

/* The channels deep compositing reads, by role. */
enum { FP_DCH_R, FP_DCH_G, FP_DCH_B, FP_DCH_A, FP_DCH_Z, FP_DCH_ZBACK, FP_DCH_COUNT };

typedef struct fp_deep_chan_t {
    char name[256];
    int type;                  /* exr_pixel_type_t: 0 UINT, 1 HALF, 2 FLOAT */
} fp_deep_chan_t;

typedef struct fp_deep_src_t fp_deep_src_t;

typedef struct fp_deep_image_t {
    fp_frame_info_t info;      /* windows, camera attributes, compression */
    int nchan;
    fp_deep_chan_t *chans;
    int role[FP_DCH_COUNT];    /* channel index, or -1 */
    size_t npix;               /* info.width * info.height */
    uint32_t *counts;          /* samples of each pixel */
    uint64_t *offsets;         /* npix + 1: pixel i's samples are offsets[i] .. offsets[i+1] */
    uint64_t total;
    uint32_t **data;           /* per channel, `total` values */
    fp_deep_src_t *src;        /* the file read (its header's attributes), or NULL */
} fp_deep_image_t;

/* The largest number of samples one pixel may hold in a file read. */
#define FP_DEEP_MAX_PIXEL_SAMPLES (1 << 20)

/* 1 when the EXR image in memory has a deep part (a walk over its header,
 * nothing decoded), else 0. */
int fp_exr_is_deep(const void *buf, size_t size);

/* Decode a deep scanline image held in memory (its first part; one part
 * only).  Takes ownership of `buf`, also on failure.  Needs R, G, B (A
 * optional: 1), Z (ZBack optional: = Z); the image budget (fp_limits.h)
 * bounds its pixels and its total samples (as pixels).  Errors: one line
 * naming `where_file` and `frame` and what was expected. */
int fp_deep_read_memory(void *buf, size_t size, const char *where_file, long frame,
                        fp_deep_image_t **out);

/* An empty image of npix pixels (counts 0) with the channels given,
 * roles found by name; info copied. */
int fp_deep_alloc(const fp_frame_info_t *info, const fp_deep_chan_t *chans, int nchan,
                  fp_deep_image_t **out);
/* Set the counts (npix of them) and allocate the values. */
int fp_deep_alloc_samples(fp_deep_image_t *d, const uint32_t *counts);

void fp_deep_free(fp_deep_image_t *d);

/* Encode a deep image as a one-part deep scanline EXR in memory.  The
 * header's attributes (camera, chromaticities, the renderer's own) come
 * from `plate`'s main part when given, else from the deep file read; its
 * windows from d->info.  opts: compression (-1: the input's when deep
 * files allow it, else ZIPS; only none, rle and zips are allowed),
 * set_chromaticities; R G B A Z ZBack are written FLOAT (a flattened pixel
 * sums every sample's rounding), other channels in their own type.
 * *out is malloc'd. */
int fp_deep_encode(const fp_deep_image_t *d, const fp_frame_t *plate,
                   const fp_exr_write_opts_t *opts, const char *where_file, long frame,
                   void **out, size_t *out_size);

/* The plate's channels a deep output carries on its surface sample: those
 * of the colour's part at full resolution, other than colour and depth.
 * *out (malloc'd, *n entries; NULL when none) points into the frame. */
typedef struct fp_deep_pass_t {
    fp_deep_chan_t chan;
    const uint8_t *raw;        /* width * height values of `bpe` bytes, host order */
    int bpe;
} fp_deep_pass_t;
int fp_deep_plate_pass(const fp_frame_t *f, fp_deep_pass_t **out, int *n);
/* Value k of a pass-through channel as a deep value (float bits / UINT). */
uint32_t fp_deep_pass_value(const fp_deep_pass_t *p, size_t k);

/* 1 when deep files can be written with this exr_compression_t. */
int fp_deep_compression_ok(int compression);

#endif

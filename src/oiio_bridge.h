/* fogpipe: a thin extern "C" bridge to OpenImageIO (C++), for every image
 * format other than the EXR frames: fogmaps in, previews out.
 * No C++ exception crosses this boundary; failures print one line naming
 * the file and return non-zero. */
#ifndef FP_OIIO_BRIDGE_H
#define FP_OIIO_BRIDGE_H

#ifdef __cplusplus
extern "C" {
#endif

/* Read one channel of any image OpenImageIO reads, as data: no color
 * conversion, unassociated alpha, integer types mapped linearly to [0,1]
 * (8-bit 128 is 128/255).  `channel` NULL or "" means the first channel.
 * Row 0 is the image's top row; the data window's pixels are returned.
 * *data is malloc'd (the caller frees it). */
int fp_oiio_read_channel(const char *path, const char *channel, float **data, int *width,
                         int *height);

/* Write an 8- or 16-bit image (format by the file's extension) from
 * display-referred floats in [0,1] (clamped), nchannels 1, 3 or 4
 * interleaved, with a deterministic +-1/2 step dither when `dither` is set
 * (no banding, same bytes every run).  Atomic: temporary file + rename. */
int fp_oiio_write_preview(const char *path, const float *pixels, int width, int height,
                          int nchannels, int bits, int dither);

#ifdef __cplusplus
}
#endif

#endif

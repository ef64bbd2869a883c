/* fogpipe: a thin extern "C" bridge to OpenImageIO (C++), for every image
 * format other than the EXR frames: fogmaps in, previews and contact sheets
 * out.
 *
 * Every function returns 0 (FP_OK) on success, or non-zero after printing
 * one line through fp_error() that names the file and says what was
 * expected.  No C++ exception crosses this boundary.  The functions keep no
 * state: they may be called from several threads at once on different
 * files. */
#ifndef FP_OIIO_BRIDGE_H
#define FP_OIIO_BRIDGE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Read one channel of any image OpenImageIO reads (PNG, TIFF, EXR, JPEG...)
 * as data, not color: no color conversion, no linearization, alpha left
 * unassociated, CMYK/YCbCr left as stored.  8- and 16-bit unsigned integers
 * map linearly to [0,1] exactly (8-bit 128 is 128.0f/255.0f, 16-bit 65535 is
 * 1.0f); other integer types as OpenImageIO converts them (signed ones to
 * [-1,1]); half and float values are returned as stored, unclamped.
 *
 * `channel` is a channel name ("G", "density", "depth.Z"); NULL or "" means
 * the first channel.  Only the first subimage is read.
 *
 * The image's size is checked from its header against the image budget
 * (src/base/fp_limits.h) before any pixel is read; the read is an error when
 * OpenImageIO reports one, even with pixels (a truncated TIFF or JPEG), and
 * a PNG's chunks are checked whole (CRCs, IEND) before libpng reads it.
 *
 * The pixels returned are the whole data window, which may be smaller or
 * larger than the display window (EXR) and whose origin is dropped: a
 * warning is printed when the two windows differ.  Row 0 is the image's top
 * row as displayed: a TIFF/JPEG "Orientation" other than 1 is applied, so
 * *width and *height are the displayed size.
 *
 * On success *data is a malloc'd array of *width x *height floats, row by
 * row, which the caller frees with free(); on failure the outputs are left
 * untouched. */
int fp_oiio_read_channel(const char *path, const char *channel, float **data, int *width,
                         int *height);

/* Write an 8- or 16-bit integer image, the format chosen by the extension of
 * `path` (.png, .tif/.tiff, .jpg...), from display-referred floats:
 * `nchannels` (1 = gray, 3 = RGB, 4 = RGBA with straight, unassociated
 * alpha) interleaved per pixel, rows top to bottom.  Values are clamped to
 * [0,1] (NaN is written as 0) and written as they are, tagged sRGB, with no
 * further conversion.
 *
 * `dither` non-zero adds a deterministic per-pixel threshold before
 * rounding, so that a smooth gradient shows no banding; no value moves by a
 * whole step or more, 0 and 1 stay exact, and the same input gives the same
 * bytes (TIFFs get no time stamp).  With `dither` zero values are rounded to
 * the nearest code.
 *
 * A format that cannot store the request is an error: 16 bits in JPEG, 4
 * channels in JPEG.  The write is atomic: the image is encoded in memory
 * (TIFF excepted: libtiff checks its writes), written with every write
 * checked, under a
 * temporary name in the same directory (".<name>.tmp.<pid>.<ext>") and
 * renamed over `path`; on failure nothing is left behind. */
int fp_oiio_write_preview(const char *path, const float *pixels, int width, int height,
                          int nchannels, int bits, int dither);

/* Contact sheet: read `count` preview images (which must all have the same
 * size and number of channels; the first odd one is named in the error),
 * tile them left to right, top to bottom in `columns` columns and
 * ceil(count / columns) rows, with no gaps (cells past the last image stay
 * black and transparent), and write the sheet atomically to `out_path` as
 * fp_oiio_write_preview() does, without dither.  The sheet has 16 bits per
 * channel if any input has more than 8 and the output format can store 16,
 * else 8.  Cells are scaled down (OpenImageIO's resize filter, kept in
 * [0, 1]) so that the sheet's longer side is at most `max_size` pixels;
 * unscaled cells carry their integer codes over exactly. */
int fp_oiio_tile_sheet(const char *const *paths, int count, int columns, int max_size,
                       const char *out_path);

/* The bridge is a module (fogpipe_oiio.so, built from src/bridges/oiio_bridge.cpp
 * and installed in $(pkglibdir)), loaded by the functions above
 * (src/bridges/oiio_load.c) the first time an image other than an EXR frame is
 * read or written: OpenImageIO links some 260 libraries, whose loading
 * cost every fogpipe process 0.2-0.3 s of CPU at start-up, most of which
 * never touch anything but EXR.  The module prints through the host's
 * messages (fp_error and fp_warn, passed in: per-thread sinks, the
 * library's emitter) and returns its entry points. */
#define FP_OIIO_ABI 2
typedef int (*fp_oiio_error_fn)(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
typedef void (*fp_oiio_warn_fn)(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* The host's fp_image_limits_check (src/base/fp_limits.h): the module checks
 * every image's size from its header with it before reading any pixel, so
 * that the budget (--max-image-pixels) is the library's, one for all. */
typedef int (*fp_oiio_limits_fn)(const char *file, long frame, const char *kind,
                                 int64_t width, int64_t height, int64_t channels,
                                 int64_t bytes_per_sample);
typedef struct fp_oiio_module_t {
    int abi;             /* FP_OIIO_ABI of the module */
    const char *version; /* PACKAGE_VERSION it was built with */
    int (*read_channel)(const char *path, const char *channel, float **data, int *width,
                        int *height);
    int (*write_preview)(const char *path, const float *pixels, int width, int height,
                         int nchannels, int bits, int dither);
    int (*tile_sheet)(const char *const *paths, int count, int columns, int max_size,
                      const char *out_path);
} fp_oiio_module_t;
/* The module's version, a const data symbol (FP_OIIO_ABI_SYMBOL) that the
 * loader reads before it calls anything in the module. */
typedef struct fp_oiio_abi_t {
    int abi;           /* FP_OIIO_ABI of the module */
    char version[60];  /* PACKAGE_VERSION it was built with, NUL-terminated */
} fp_oiio_abi_t;
#define FP_OIIO_ABI_SYMBOL "fp_oiio_module_abi"
/* The module's entry point (FP_OIIO_ENTRY): called once, with the host's
 * message functions and its image budget, after its version matched. */
#define FP_OIIO_ENTRY "fp_oiio_module"
typedef const fp_oiio_module_t *(*fp_oiio_entry_fn)(fp_oiio_error_fn error, fp_oiio_warn_fn warn,
                                                    fp_oiio_limits_fn limits);

/* The loader's check of a module file before dlopen trusts it (a cut
 * file makes the dynamic loader touch pages past its end: SIGBUS): a
 * regular file, an ELF shared object of the host's class, byte order and
 * machine, whose program headers, segments, section headers and sections
 * all lie inside the file.  0, or -1 with the reason in `why`. */
int fp_oiio_module_check(const char *path, char *why, size_t n);

#ifdef __cplusplus
}
#endif

#endif

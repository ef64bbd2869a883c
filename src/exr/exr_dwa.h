/* fogpipe: DWAA/DWAB through OpenEXR's C++ library (extern "C" bridge).
 *
 * OpenEXR 3.1's C library (openexr.h), which src/exrio.c uses, has no DWA
 * codec; the C++ library of the same package has.  This bridge transcodes
 * whole EXR images held in memory, so the C path stays as it is:
 *
 * - reading: fp_dwa_probe says whether a part is DWA-compressed (or B44,
 *   see there); then
 *   fp_dwa_decode rewrites the image with those parts uncompressed (NONE,
 *   tiled parts as scanlines of their level 0, the only level the C path
 *   reads) and every other part's chunks copied as they are, and reports
 *   each part's original compression;
 * - writing: the C path encodes the parts meant for DWA uncompressed, and
 *   fp_dwa_encode rewrites those parts as DWAA/DWAB.
 *
 * Both keep every part in order with its header: every attribute (custom
 * ones and unknown types included), channel list, pixel types, sampling,
 * data and display windows and line order.  No C++ exception leaves this
 * bridge: failures print one line naming the file and frame (fp_error) and
 * return FP_ERR.  Reentrant: frames may be transcoded on several threads. */
#ifndef FP_EXR_DWA_H
#define FP_EXR_DWA_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The compression level DWA uses when neither --dwa-level nor the input's
 * dwaCompressionLevel attribute gives one (OpenEXR's default). */
#define FP_DWA_DEFAULT_LEVEL 45.0f

/* 1 when the EXR image in memory has a part the C library must not decode,
 * else 0 (also for bytes it cannot parse: the C reader then says what is
 * wrong): DWAA and DWAB, and B44/B44A, whose OpenEXR 3.1 C decoder misreads
 * float channels of files written by the C++ library (OpenImageIO, Nuke).
 * A walk over the header bytes; nothing is decoded. */
int fp_dwa_probe(const void *buf, size_t size);
/* fp_dwa_probe's answers besides 0: a DWA part (only the C++ library can
 * decode it), or B44/B44A with float channels (only the C++ library
 * decodes them right). */
#define FP_DWA_PREFERRED 1
#define FP_DWA_REQUIRED 2

/* Rewrite the image `buf` with its DWA (and B44) parts uncompressed (see
 * above).  *out is malloc'd; *part_comp (malloc'd, *num_parts entries)
 * holds each part's compression in the input (exr_compression_t).  `where`
 * and `frame` label messages.  `verdict` is fp_dwa_probe's answer; it
 * names the codec in messages.  A failure of the C++ library is an error
 * either way (one line, FP_ERR): the C decoder is no fallback for float
 * B44, which it misreads. */
int fp_dwa_decode(const void *buf, size_t size, int verdict, const char *where,
                  long frame, void **out, size_t *out_size, int **part_comp,
                  int *num_parts);

/* Rewrite the image `buf` (as the C writer made it) with part p compressed
 * as part_comp[p] where that is DWAA or DWAB; other parts are copied
 * unchanged.  num_parts must be the image's part count.  level >= 0 is the
 * DWA compression level; level < 0 takes the part's dwaCompressionLevel
 * attribute, else FP_DWA_DEFAULT_LEVEL.  The level used is written as the
 * part's dwaCompressionLevel attribute.  *out is malloc'd. */
int fp_dwa_encode(const void *buf, size_t size, const int *part_comp,
                  int num_parts, float level, const char *where, long frame,
                  void **out, size_t *out_size);

#ifdef __cplusplus
}
#endif

#endif

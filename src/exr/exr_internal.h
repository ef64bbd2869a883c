/* fogpipe: what the EXR code shares, private to it (the public interface
 * is exrio.h).  One file per job:
 *   exr_common.c  glue to OpenEXR's C API (error handler, in-memory read
 *                 and write callbacks), the chunk workers, compression
 *                 names;
 *   exr_read.c    reading a frame held in memory: channels found by name,
 *                 chunks decoded, colour and depth as floats, every other
 *                 channel kept as bytes;
 *   exr_write.c   encoding a frame to memory and writing files atomically;
 *   exr_zip.c     the ZIP / ZIPS codec of the chunk workers (libdeflate);
 *   exr_stream.c  stream framing: one EXR file at a time from a pipe;
 *   exr_check.c   an image's bytes checked against the image budget and
 *                 against its own size before anything is decoded;
 *   exr_rig.c     the rig's attributes picked up from a header (src/scene/rig.h). */
#ifndef FP_EXR_INTERNAL_H
#define FP_EXR_INTERNAL_H

#include "exrio.h"

#include <openexr.h>

#include <stddef.h>
#include <stdint.h>
#include <string.h>

/* Sanity limits of the file's structure against corrupt headers; the
 * image's size (pixels, axis, channels, parts) is the image budget's
 * (src/base/fp_limits.h), checked by fp_exr_check_image. */
#define FP_EXR_MAX_ATTR_SIZE  ((int64_t) 1 << 28)  /* one attribute value */
#define FP_EXR_MAX_ATTRS      100000               /* attributes in one header */
#define FP_EXR_MAX_CHUNKS     ((int64_t) 1 << 26)  /* offset table entries */
#define FP_EXR_MAX_FILE       ((uint64_t) 1 << 40) /* bytes in one frame */

#define FP_EXR_MAGIC 20000630
/* Chunk workers: at most this many, and none below this many pixels. */
#define FP_EXR_MAX_THREADS    64
#define FP_EXR_PAR_MIN_PIXELS ((int64_t) 1 << 16)
/* Longest attribute or channel name without the long-names flag; with it,
 * 255 (OpenEXR's EXR_SHORTNAME_MAXLEN and EXR_LONGNAME_MAXLEN). */
#define FP_EXR_SHORT_NAME 31
#define FP_EXR_LONG_NAME 255
#define FP_EXR_MSG_LEN 512

/* One channel of a part, as read. */
typedef struct fp_chan_t {
    const char *name;    /* owned by the read context */
    int type;            /* exr_pixel_type_t */
    int p_linear;
    int xs, ys;          /* sub-sampling */
    int w, h;            /* samples per line, lines */
    size_t bpe;          /* bytes per sample */
    uint8_t *raw;        /* w*h samples, host byte order; NULL once consumed */
} fp_chan_t;

typedef struct fp_part_t {
    int storage;         /* exr_storage_t of the input */
    exr_attr_box2i_t dw, disp;
    int compression;
    int lineorder;
    int num_chans;
    fp_chan_t *chans;    /* in the order of the part's (sorted) channel list */
} fp_part_t;

/* The library's data for a context: the memory image read from, the
 * buffer written to, and the text of the library's last complaint. */
typedef struct fp_exr_io_t {
    const uint8_t *rd;
    size_t rd_size;
    uint8_t *wr;
    size_t wr_size, wr_cap;
    int wr_failed;
    char msg[FP_EXR_MSG_LEN];
} fp_exr_io_t;

struct fp_frame_t {
    void *buf;           /* the file's bytes, read through io */
    size_t size;
    fp_exr_io_t io;
    exr_context_t ctx;
    int num_parts;
    fp_part_t *parts;
    int main_part;       /* colour's part, else depth's, else 0 */
    int color_part, color_chan[4];
    int depth_part, depth_chan;
    float *rgba;         /* page-aligned inside rgba_mem (alloc_aligned, exr_read.c) */
    float *depth;        /* page-aligned inside depth_mem */
    void *rgba_mem, *depth_mem;   /* the blocks free() takes */
    fp_frame_info_t info;
    int *dwa_comp;       /* each part's compression in a DWA input (exr_dwa.h), else NULL */
    char *src;           /* the input's name (messages about its attributes) */
    int dwa_num_parts;
};

/* ------------------------------------------------------------ library glue
 * (exr_common.c) */

/* The message buffer of the call in progress on this thread (see
 * fp_exr_lib_error_handler). */
extern _Thread_local char *fp_exr_tl_msg;

/* The error handler every context is made with: keeps the library's first
 * message of a call in *fp_exr_tl_msg. */
void fp_exr_lib_error_handler(exr_const_context_t ctxt, exr_result_t code,
                              const char *msg);
/* The library's text for a failure: what its handler said, else the
 * generic text of the code.  Clears io->msg for the next call. */
const char *fp_exr_lib_text(fp_exr_io_t *io, exr_result_t rv, char *out, size_t n);
/* The reason a chunk failed: `why` (a worker's message) when there is one,
 * else the library's text; clears io->msg either way. */
const char *fp_exr_fail_text(fp_exr_io_t *io, const char *why, exr_result_t rv, char *out,
                             size_t n);
/* The allocator of the write context: malloc and free, except that a
 * request for 0 bytes gets a static byte that free leaves alone.
 * OpenEXR 3.1 mallocs 0 bytes for an empty opaque attribute
 * (exr_attr_set_user with size 0, as copied from an input) and never
 * frees them, because it frees only what has a size. */
void *fp_exr_alloc(size_t n);
void fp_exr_free(void *p);
/* Read callbacks serving io->rd, and the write callback filling io->wr
 * (pwrite semantics). */
int64_t fp_exr_mem_read(exr_const_context_t ctxt, void *userdata, void *buffer,
                        uint64_t sz, uint64_t offset,
                        exr_stream_error_func_ptr_t error_cb);
int64_t fp_exr_mem_size(exr_const_context_t ctxt, void *userdata);
int64_t fp_exr_mem_write(exr_const_context_t ctxt, void *userdata,
                         const void *buffer, uint64_t sz, uint64_t offset,
                         exr_stream_error_func_ptr_t error_cb);

/* A read context over io (an image in memory, io->rd), its header read
 * strictly and within the image budget's axis: FP_OK, or one line
 * naming the file and frame with the library's reason (*ctx NULL). */
int fp_exr_start_read(fp_exr_io_t *io, exr_context_t *ctx, const char *where, long frame);

/* ------------------------------------------------------------ chunk workers
 * (exr_common.c) */

/* How many workers a part of `pixels` pixels in `chunks` chunks gets. */
int fp_exr_workers(int64_t pixels, int64_t chunks);
/* One thread's share of a frame's chunks (decode or encode): the job they
 * share, and where it failed first. */
typedef struct fp_exr_worker_t {
    void *job;
    int64_t fail;                /* first chunk it failed on, or -1 */
    exr_result_t rv;
    char msg[FP_EXR_MSG_LEN];
} fp_exr_worker_t;

/* Run fn on the n workers wk[] (each given `job`), n - 1 of them on new
 * threads; returns when all are done, with the worker that failed on the
 * earliest chunk (so the error does not depend on the thread count), or
 * NULL. */
fp_exr_worker_t *fp_exr_run_workers(void *(*fn)(void *), void *job, fp_exr_worker_t *wk, int n);

/* ------------------------------------------------------------ header copy
 * (exr_write.c; the deep writer, exr_deep.c, copies headers the same way) */

/* 1 for attributes the writer sets itself (channels, windows, type...). */
int fp_exr_is_structural_attr(const char *name);
/* Copy one attribute of an input header to part op of an output. */
exr_result_t fp_exr_copy_attr(exr_context_t o, int op, const exr_attribute_t *a);

/* ------------------------------------------------------------ ZIP codec
 * (exr_zip.c) */

/* One chunk worker's deflate state: libdeflate's compressor and
 * decompressor are not thread-safe, so each worker has its own, made on
 * first use and freed by fp_zip_release.  Starts zeroed. */
typedef struct fp_zip_t {
    struct libdeflate_compressor *comp;
    struct libdeflate_decompressor *dec;
    uint8_t *scratch;
    size_t scratch_cap;
} fp_zip_t;

/* Whether a part's compression is one this codec handles (ZIP, ZIPS). */
int fp_zip_is_zip(int compression);
/* Whether ZIP / ZIPS chunks go through this codec (1, the default) or
 * through OpenEXR's own zlib routines (0), the current context's (src/base/fp_ctx.h): for
 * tests/bench_zip's before-and-after figures, taken in one program. */
void fp_zip_set_enabled(int on);
int fp_zip_enabled(void);
void fp_zip_release(fp_zip_t *z);
/* Install the codec on a pipeline right after its default routines are
 * chosen and before it first runs (the encoder's buffers then come from
 * malloc through the pipeline's alloc_fn / free_fn); z must outlive it. */
void fp_zip_use_encoder(exr_encode_pipeline_t *enc, fp_zip_t *z);
void fp_zip_use_decoder(exr_decode_pipeline_t *dec, fp_zip_t *z);
/* The codec's compress_fn and decompress_fn (user data: an fp_zip_t). */
exr_result_t fp_zip_compress(exr_encode_pipeline_t *enc);
exr_result_t fp_zip_decompress(exr_decode_pipeline_t *dec);
/* OpenEXR's ZIP pre-processing of n bytes, raw -> out (both n bytes,
 * apart), and its inverse: s (modified) -> out. */
void fp_zip_deconstruct(uint8_t *out, const uint8_t *raw, size_t n);
void fp_zip_reconstruct(uint8_t *out, uint8_t *s, size_t n);

/* ------------------------------------------------------------ header walk
 * (exr_check.c) */

/* What the checks need of one part's header. */
typedef struct fp_exr_hpart_t {
    int has_dw, has_tiles, has_cc, deep, tiled;
    int32_t dw[4];             /* min x, min y, max x, max y */
    int compression;           /* -1 when absent */
    uint32_t tx, ty;
    int level_mode, round_mode;
    int64_t chunk_count;       /* the chunkCount attribute (has_cc) */
    const uint8_t *chans;      /* the channels attribute's value, or NULL */
    uint32_t chans_size;
    /* the values of the attributes a multipart file's parts must share
     * (OpenEXR's MultiPartInputFile refuses a file whose parts differ in
     * them), or NULL: displayWindow (box2i), pixelAspectRatio (float), and
     * when present chromaticities and timecode, as the C++ library names
     * them */
    const uint8_t *disp, *aspect, *chroma, *timecode;
} fp_exr_hpart_t;

/* Note one attribute (name, type, `size` bytes of value at v). */
void fp_exr_hpart_take(fp_exr_hpart_t *sp, const char *name, const char *type,
                       const uint8_t *v, uint32_t size);
/* Scanlines in one chunk of a compression, or -1 if it is unknown. */
int fp_exr_lines_per_chunk(int compression);
/* Offset table entries the part's header implies (every level of a tiled
 * part), -1 if it cannot say; *level0 (if not NULL): those of the highest
 * resolution, which come first. */
int64_t fp_exr_count_chunks(const fp_exr_hpart_t *sp, int64_t *level0);
/* Check an EXR image in memory before anything is allocated for its
 * pixels: every part against the image budget (src/base/fp_limits.h); the file
 * against what its headers claim (offset tables and chunk headers fit;
 * the decoded bytes are within the codec's largest ratio times its
 * size); each chunk of the highest resolution against the bytes of its
 * pixels.  FP_OK, or FP_ERR with one line naming the file and frame.
 * Bytes it cannot frame pass (FP_OK): the library reports them. */
int fp_exr_check_image(const void *buf, size_t size, const char *where, long frame);

/* ------------------------------------------------------------ small helpers */

static inline int64_t floordiv(int64_t a, int64_t b)
{
    int64_t q = a / b;
    if ((a % b) != 0 && ((a < 0) != (b < 0)))
        q--;
    return q;
}

/* How many v in [lo, hi) have v mod s == 0: the samples a sub-sampled
 * channel holds over that range (OpenEXR samples at multiples of s). */
static inline int64_t sampled_count(int64_t lo, int64_t hi, int s)
{
    if (hi <= lo)
        return 0;
    return floordiv(hi - 1, s) - floordiv(lo - 1, s);
}

static inline size_t type_size(int type)
{
    return type == EXR_PIXEL_HALF ? 2 : 4;
}

/* Little-endian integers of an EXR file's bytes (the header walks of
 * exr_check.c and exr_stream.c). */
static inline uint32_t fp_exr_rd_u32(const uint8_t *p)
{
    return (uint32_t) p[0] | (uint32_t) p[1] << 8 | (uint32_t) p[2] << 16 |
           (uint32_t) p[3] << 24;
}

static inline int32_t fp_exr_rd_i32(const uint8_t *p)
{
    uint32_t u = fp_exr_rd_u32(p);
    int32_t v;
    memcpy(&v, &u, sizeof v);
    return v;
}

static inline uint64_t fp_exr_rd_u64(const uint8_t *p)
{
    return (uint64_t) fp_exr_rd_u32(p) | (uint64_t) fp_exr_rd_u32(p + 4) << 32;
}

/* exr_rig.c: one attribute of a header into the frame's rig attributes:
 * 1 when it is one of the typed fogpipe* attributes (kept, or its wrong
 * type kept as an error), 0 otherwise; a string attribute holding the
 * rig's or the look's text form is kept too (and 0 returned). */
int fp_exr_rig_attr(const exr_attribute_t *a, fp_rig_attrs_t *r);
void fp_exr_rig_attrs_free(fp_rig_attrs_t *r);

/* ------------------------------------------------------------ channels
 * (src/exr/exr_select.c) */

/* Channel `name` of part `pt`, or -1. */
int fp_exr_find_in_part(const fp_part_t *pt, const char *name);
/* Find the frame's colour and depth channels as `sel` asks (one error
 * line naming the file, the frame and what was looked for). */
int fp_exr_select_channels(fp_frame_t *f, const fp_exr_select_t *sel, const char *where,
                           long frame);

#endif

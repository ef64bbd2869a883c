/* fogpipe's ZIP / ZIPS codec (src/exr/exr_zip.c: libdeflate in place of the
 * zlib inside OpenEXR 3.1's C API) against OpenEXR's own:
 * - the byte split and predictor against OpenEXR 3.1.5's loops
 *   (internal_zip.c), and their inverse, on every length up to 600;
 * - frames written by OpenEXR's zlib path, read by fogpipe: every sample
 *   bit-exact; written again by fogpipe, read back by OpenEXR's default
 *   decoder (a pipeline without fogpipe's decompress_fn) and by fogpipe:
 *   bit-exact again; the bytes the same from run to run and from 1 to 3
 *   chunk threads; half and float, ZIP and ZIPS, widths 1 to 130, a last
 *   chunk with fewer lines, 3 colour channels and no alpha, smooth content
 *   (chunks that deflate) and noise (chunks stored raw);
 * - damaged chunks (checksum, a stream that inflates short or long): the
 *   one-line error naming file, frame and pixel, with OpenEXR's words,
 *   and OpenEXR's decoder refusing the same chunks. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <libdeflate.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <openexr.h>

#include "exr_internal.h"
#include "exrio.h"
#include "fp.h"

#include "exr_testutil.h"

/* ------------------------------------------------------------ pre-processing */

/* OpenEXR 3.1.5's apply_zip_impl loops, as they are (the judge). */
static void ref_deconstruct(uint8_t *scratch, const uint8_t *source, size_t count)
{
    uint8_t *t1 = scratch, *t2 = t1 + (count + 1) / 2;
    const uint8_t *raw = source, *stop = raw + count;
    while (raw < stop) {
        *(t1++) = *(raw++);
        if (raw < stop)
            *(t2++) = *(raw++);
    }
    t1 = scratch;
    t2 = t1 + count;
    t1++;
    int p = (int) t1[-1];
    while (t1 < t2) {
        int d = (int) (t1[0]) - p + (128 + 256);
        p = (int) t1[0];
        t1[0] = (uint8_t) d;
        ++t1;
    }
}

static void test_zip_preprocess(void **state)
{
    (void) state;
    uint32_t seed = 12345;
    for (size_t n = 1; n <= 600; ++n)
        for (int rep = 0; rep < 6; ++rep) {
            /* each buffer exactly n bytes, so that a read or write past
             * its end shows under valgrind or ASan */
            uint8_t *raw = malloc(n), *a = malloc(n), *b = malloc(n), *c = malloc(n);
            assert_true(raw && a && b && c);
            for (size_t i = 0; i < n; ++i) {
                seed = seed * 1664525u + 1013904223u;
                raw[i] = rep < 3 ? (uint8_t) (seed >> 24)
                         : rep == 3 ? (uint8_t) (i * 7 / 3)
                         : rep == 4 ? 0xff : (uint8_t) (i & 1 ? 0x3c : 0x00);
            }
            ref_deconstruct(a, raw, n);
            fp_zip_deconstruct(b, raw, n);
            if (memcmp(a, b, n) != 0)
                fail_msg("deconstruct differs from OpenEXR's at n = %zu (pattern %d)", n, rep);
            fp_zip_reconstruct(c, b, n);
            if (memcmp(c, raw, n) != 0)
                fail_msg("reconstruct does not invert deconstruct at n = %zu (pattern %d)", n,
                         rep);
            free(raw);
            free(a);
            free(b);
            free(c);
        }
}

/* ------------------------------------------------------------ test files */

/* A frame of R, G, B (no alpha) and N.x in `type`, and Z in float. */
enum { NCH = 5 };
static const char *const ch_names[NCH] = { "B", "G", "N.x", "R", "Z" };

typedef struct img_t {
    int w, h, type;
    void *plane[NCH];   /* in the order of ch_names (the file's, sorted) */
} img_t;

static int ch_type(const img_t *im, int c)
{
    return strcmp(ch_names[c], "Z") == 0 ? EXR_PIXEL_FLOAT : im->type;
}

/* Random samples of bounded magnitude (no NaN or infinity, so that a half
 * that goes through float and back is the same bits): incompressible. */
static void *noise_plane(int type, int w, int h, uint32_t *seed)
{
    size_t n = (size_t) w * h;
    uint8_t *p = malloc(n * tsize(type));
    assert_non_null(p);
    for (size_t i = 0; i < n; ++i) {
        *seed = *seed * 1664525u + 1013904223u;
        uint32_t r = *seed;
        if (type == EXR_PIXEL_HALF) {
            uint16_t hv = (uint16_t) ((r >> 16) & 0xbbff); /* exponent < 31 */
            memcpy(p + i * 2, &hv, 2);
        } else {
            uint32_t fv = (r & 0x803fffffu) | ((64u + ((r >> 22) & 63u)) << 23);
            memcpy(p + i * 4, &fv, 4);
        }
    }
    return p;
}

static void img_make(img_t *im, int type, int w, int h, int noise)
{
    uint32_t seed = (uint32_t) (w * 7919 + h * 31 + type + noise);
    im->w = w;
    im->h = h;
    im->type = type;
    for (int c = 0; c < NCH; ++c)
        im->plane[c] = noise ? noise_plane(ch_type(im, c), w, h, &seed)
                             : mkplane(ch_type(im, c), w, h, c + 1);
}

static void img_free(img_t *im)
{
    for (int c = 0; c < NCH; ++c)
        free(im->plane[c]);
}

/* A compress_fn for the test writer that deflates only part of a chunk
 * (short > 0: the first half) or more than the chunk (short < 0: the chunk
 * and 100 bytes more), so that the stream is well formed but inflates to
 * the wrong size. */
static int bad_stream;

static exr_result_t odd_compress(exr_encode_pipeline_t *enc)
{
    size_t n = (size_t) enc->packed_bytes;
    size_t in_n = bad_stream > 0 ? n / 2 : n + 100;
    uint8_t *in = calloc(in_n, 1);
    struct libdeflate_compressor *c = libdeflate_alloc_compressor(6);
    assert_true(in && c);
    memcpy(in, enc->packed_buffer, in_n < n ? in_n : n);
    size_t cap = libdeflate_zlib_compress_bound(c, in_n);
    if (enc->compressed_alloc_size < cap) {
        free(enc->compressed_buffer);
        enc->compressed_buffer = malloc(cap);
        assert_non_null(enc->compressed_buffer);
        enc->compressed_alloc_size = cap;
    }
    size_t got = libdeflate_zlib_compress(c, in, in_n, enc->compressed_buffer, cap);
    assert_true(got > 0 && got < n);
    enc->compressed_bytes = got;
    libdeflate_free_compressor(c);
    free(in);
    return EXR_ERR_SUCCESS;
}

/* Write with OpenEXR's C API and its default routines (zlib), or with
 * odd_compress on the chunk at line bad_y when bad_stream is set. */
static void write_default(const char *path, const img_t *im, int comp, int bad_y)
{
    exr_context_t ctx = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = quiet_handler;
    exr_attr_v2f_t swc = { { { 0.0f, 0.0f } } };
    exr_attr_box2i_t b = box(0, 0, im->w - 1, im->h - 1);
    int idx = -1;
    assert_int_equal(exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init), 0);
    assert_int_equal(exr_add_part(ctx, "", EXR_STORAGE_SCANLINE, &idx), 0);
    assert_int_equal(exr_initialize_required_attr(ctx, idx, &b, &b, 1.0f, &swc, 1.0f,
                                                  EXR_LINEORDER_INCREASING_Y,
                                                  (exr_compression_t) comp),
                     0);
    for (int c = 0; c < NCH; ++c)
        assert_int_equal(exr_add_channel(ctx, idx, ch_names[c],
                                         (exr_pixel_type_t) ch_type(im, c),
                                         EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1),
                         0);
    assert_int_equal(exr_write_header(ctx), 0);
    int32_t lpc = 0;
    assert_int_equal(exr_get_scanlines_per_chunk(ctx, idx, &lpc), 0);
    for (int y = 0; y < im->h; y += lpc) {
        exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
        exr_chunk_info_t ci;
        assert_int_equal(exr_write_scanline_chunk_info(ctx, idx, y, &ci), 0);
        assert_int_equal(exr_encoding_initialize(ctx, idx, &ci, &enc), 0);
        assert_int_equal(enc.channel_count, NCH);
        for (int c = 0; c < NCH; ++c) {
            exr_coding_channel_info_t *cc = &enc.channels[c];
            assert_string_equal(cc->channel_name, ch_names[c]);
            size_t bpe = tsize(ch_type(im, c));
            cc->encode_from_ptr = (uint8_t *) im->plane[c] + (size_t) y * im->w * bpe;
            cc->user_pixel_stride = (int32_t) bpe;
            cc->user_line_stride = (int32_t) (im->w * bpe);
            cc->user_bytes_per_element = (int16_t) bpe;
            cc->user_data_type = (uint16_t) ch_type(im, c);
        }
        assert_int_equal(exr_encoding_choose_default_routines(ctx, idx, &enc), 0);
        if (bad_stream && y == bad_y) {
            /* the test's own buffers: freed by it, not by the pipeline */
            enc.compress_fn = odd_compress;
        }
        assert_int_equal(exr_encoding_run(ctx, idx, &enc), 0);
        if (bad_stream && y == bad_y) {
            free(enc.compressed_buffer);
            enc.compressed_buffer = NULL;
            enc.compressed_alloc_size = 0;
        }
        exr_encoding_destroy(ctx, &enc);
    }
    assert_int_equal(exr_finish(&ctx), 0);
}

/* The library's first complaint, for the default decoder's failures. */
static char lib_msg[512];

static void keep_handler(exr_const_context_t c, exr_result_t code, const char *msg)
{
    (void) c;
    (void) code;
    if (!lib_msg[0])
        snprintf(lib_msg, sizeof lib_msg, "%s", msg ? msg : "");
}

/* Decode every channel of a file with OpenEXR's default routines (its
 * zlib inflate), in the file's types; returns the first failure's code
 * (lib_msg: its message) and the line of the failing chunk. */
static exr_result_t read_default(const char *path, img_t *out, int *fail_y)
{
    exr_context_t ctx = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = keep_handler;
    lib_msg[0] = '\0';
    exr_result_t rv = exr_start_read(&ctx, path, &init);
    assert_int_equal(rv, 0);
    exr_attr_box2i_t dw;
    assert_int_equal(exr_get_data_window(ctx, 0, &dw), 0);
    out->w = dw.max.x - dw.min.x + 1;
    out->h = dw.max.y - dw.min.y + 1;
    const exr_attr_chlist_t *cl;
    assert_int_equal(exr_get_channels(ctx, 0, &cl), 0);
    assert_int_equal(cl->num_channels, NCH);
    for (int c = 0; c < NCH; ++c) {
        assert_string_equal(cl->entries[c].name.str, ch_names[c]);
        if (strcmp(ch_names[c], "Z") != 0)
            out->type = cl->entries[c].pixel_type;
        out->plane[c] = calloc((size_t) out->w * out->h, tsize(cl->entries[c].pixel_type));
        assert_non_null(out->plane[c]);
    }
    int32_t lpc = 0;
    assert_int_equal(exr_get_scanlines_per_chunk(ctx, 0, &lpc), 0);
    for (int y = 0; y < out->h && rv == 0; y += lpc) {
        exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
        exr_chunk_info_t ci;
        *fail_y = y;
        rv = exr_read_scanline_chunk_info(ctx, 0, y, &ci);
        if (rv == 0)
            rv = exr_decoding_initialize(ctx, 0, &ci, &dec);
        if (rv != 0)
            break;
        for (int c = 0; c < NCH; ++c) {
            exr_coding_channel_info_t *cc = &dec.channels[c];
            size_t bpe = tsize(cc->data_type);
            cc->decode_to_ptr = (uint8_t *) out->plane[c] + (size_t) y * out->w * bpe;
            cc->user_pixel_stride = (int32_t) bpe;
            cc->user_line_stride = (int32_t) (out->w * bpe);
            cc->user_bytes_per_element = (int16_t) bpe;
            cc->user_data_type = cc->data_type;
        }
        rv = exr_decoding_choose_default_routines(ctx, 0, &dec);
        if (rv == 0)
            rv = exr_decoding_run(ctx, 0, &dec);
        exr_decoding_destroy(ctx, &dec);
    }
    exr_finish(&ctx);
    return rv;
}

/* Chunks of a file stored compressed and stored raw. */
static void chunk_kinds(const char *path, int *compressed, int *raw)
{
    exr_context_t ctx = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = quiet_handler;
    assert_int_equal(exr_start_read(&ctx, path, &init), 0);
    exr_attr_box2i_t dw;
    int32_t lpc = 0;
    assert_int_equal(exr_get_data_window(ctx, 0, &dw), 0);
    assert_int_equal(exr_get_scanlines_per_chunk(ctx, 0, &lpc), 0);
    *compressed = *raw = 0;
    for (int y = dw.min.y; y <= dw.max.y; y += lpc) {
        exr_chunk_info_t ci;
        assert_int_equal(exr_read_scanline_chunk_info(ctx, 0, y, &ci), 0);
        assert_true(ci.packed_size <= ci.unpacked_size);
        if (ci.packed_size < ci.unpacked_size)
            (*compressed)++;
        else
            (*raw)++;
    }
    exr_finish(&ctx);
}

static void assert_same_img(const img_t *a, const img_t *b, const char *what)
{
    assert_int_equal(a->w, b->w);
    assert_int_equal(a->h, b->h);
    for (int c = 0; c < NCH; ++c) {
        size_t n = (size_t) a->w * a->h * tsize(ch_type(a, c));
        if (memcmp(a->plane[c], b->plane[c], n) != 0)
            fail_msg("%s: channel %s differs", what, ch_names[c]);
    }
}

/* fogpipe's frame (floats) against the image's samples, bit for bit. */
static void assert_frame_is(fp_frame_t *f, const img_t *im, const char *what)
{
    const fp_frame_info_t *in = fp_frame_info(f);
    assert_int_equal(in->width, im->w);
    assert_int_equal(in->height, im->h);
    const float *rgba = fp_frame_rgba(f), *z = fp_frame_depth(f);
    const int role_ch[3] = { 3, 1, 0 }; /* R, G, B in ch_names */
    for (size_t i = 0; i < (size_t) im->w * im->h; ++i) {
        for (int k = 0; k < 3; ++k) {
            float v = pget(im->type, im->plane[role_ch[k]], i);
            if (memcmp(&rgba[i * 4 + k], &v, 4) != 0)
                fail_msg("%s: pixel %zu channel %d: %g, expected %g", what, i, k,
                         (double) rgba[i * 4 + k], (double) v);
        }
        assert_true(rgba[i * 4 + 3] == 1.0f);
        if (memcmp(&z[i], (const float *) im->plane[4] + i, 4) != 0)
            fail_msg("%s: depth of pixel %zu differs", what, i);
    }
}

static void test_zip_roundtrip(void **state)
{
    (void) state;
    /* (w, h): a last ZIP chunk of 3 lines, one column, a single line, 16
     * lines exactly, a last chunk of one line */
    static const int sizes[][2] = { { 61, 35 }, { 1, 37 }, { 7, 1 }, { 130, 16 }, { 33, 17 } };
    static const int comps[] = { EXR_COMPRESSION_ZIP, EXR_COMPRESSION_ZIPS };
    static const int types[] = { EXR_PIXEL_HALF, EXR_PIXEL_FLOAT };
    char in[4200], out[4200], out2[4200];
    path_in(in, sizeof in, "in.exr");
    path_in(out, sizeof out, "out.exr");
    path_in(out2, sizeof out2, "out2.exr");
    int deflated = 0, stored = 0;
    for (size_t s = 0; s < FP_ARRAY_LEN(sizes); ++s)
        for (int ci = 0; ci < 2; ++ci)
            for (int ti = 0; ti < 2; ++ti)
                for (int noise = 0; noise < 2; ++noise) {
                    char what[128];
                    snprintf(what, sizeof what, "%dx%d %s %s %s", sizes[s][0], sizes[s][1],
                             fp_exr_compression_name(comps[ci]),
                             types[ti] == EXR_PIXEL_HALF ? "half" : "float",
                             noise ? "noise" : "smooth");
                    img_t im, back;
                    img_make(&im, types[ti], sizes[s][0], sizes[s][1], noise);
                    write_default(in, &im, comps[ci], -1);

                    /* OpenEXR's zlib chunks, read by fogpipe */
                    fp_frame_t *f = NULL;
                    assert_int_equal(fp_exr_read_file(in, 1, NULL, &f), FP_OK);
                    assert_frame_is(f, &im, what);

                    /* fogpipe's chunks, read by OpenEXR's decoder */
                    fp_exr_write_opts_t o = FP_EXR_WRITE_OPTS_INITIALIZER;
                    o.use_float = types[ti] == EXR_PIXEL_FLOAT;
                    fp_exr_set_threads(1);
                    assert_int_equal(fp_exr_write_file(f, NULL, &o, out, 1), FP_OK);
                    fp_exr_set_threads(3);
                    assert_int_equal(fp_exr_write_file(f, NULL, &o, out2, 1), FP_OK);
                    /* the same bytes from run to run and thread count */
                    void *again = NULL;
                    size_t na = 0;
                    assert_int_equal(fp_exr_encode(f, NULL, &o, out, 1, &again, &na), FP_OK);
                    fp_exr_set_threads(0);
                    fp_frame_free(f);
                    size_t n1, n2;
                    uint8_t *b1 = slurp_file(out, &n1), *b2 = slurp_file(out2, &n2);
                    assert_int_equal(n1, n2);
                    assert_memory_equal(b1, b2, n1);
                    assert_int_equal(n1, na);
                    assert_memory_equal(b1, again, n1);
                    free(again);
                    free(b2);
                    free(b1);
                    int fy = -1;
                    if (read_default(out, &back, &fy) != 0)
                        fail_msg("%s: OpenEXR cannot read fogpipe's output at line %d (%s)", what,
                                 fy, lib_msg);
                    assert_same_img(&im, &back, what);
                    img_free(&back);
                    int nc, nr;
                    chunk_kinds(out, &nc, &nr);
                    deflated += nc;
                    stored += nr;
                    int zc, zr;
                    chunk_kinds(in, &zc, &zr);
                    /* libdeflate shrinks every chunk zlib does (these ones) */
                    if (nc < zc)
                        fail_msg("%s: %d chunks deflated, zlib deflates %d", what, nc, zc);

                    /* and fogpipe's own chunks read by fogpipe */
                    assert_int_equal(fp_exr_read_file(out, 1, NULL, &f), FP_OK);
                    assert_frame_is(f, &im, what);
                    fp_frame_free(f);
                    img_free(&im);
                }
    /* both branches of the codec were taken: deflated chunks, and noise
     * chunks that deflate cannot shrink, stored as they are */
    assert_true(deflated > 0);
    assert_true(stored > 0);
    unlink(in);
    unlink(out);
    unlink(out2);
}

/* A damaged chunk: fogpipe's one line names the file, the frame and the
 * chunk's first pixel, with OpenEXR's words for it; OpenEXR's own decoder
 * refuses the same chunk with the same words. */
static void expect_bad_chunk(const char *path, int y, const char *how)
{
    char want[512], line[600];
    img_t back;
    int fy = -1;
    exr_result_t rv = read_default(path, &back, &fy);
    img_free(&back);
    if (rv == 0)
        fail_msg("%s: OpenEXR's decoder read the damaged chunk", how);
    assert_int_equal(fy, y);
    snprintf(want, sizeof want, "%s", lib_msg);
    assert_true(strncmp(want, "Unable to decompress image data ", 32) == 0);

    fp_frame_t *f = NULL;
    cap_begin();
    int rc = fp_exr_read_file(path, 7, NULL, &f);
    const char *msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_null(f);
    snprintf(line, sizeof line, "%s: frame 7: part 0: cannot decode pixels at 0,%d (%s)\n",
             path, y, want);
    if (!strstr(msg, line) || strchr(msg, '\n') != msg + strlen(msg) - 1)
        fail_msg("%s: expected the one line \"%s\", got \"%s\"", how, line, msg);
}

static void test_zip_corrupt(void **state)
{
    (void) state;
    char in[4200], bad[4200];
    path_in(in, sizeof in, "good.exr");
    path_in(bad, sizeof bad, "bad.exr");
    img_t im;
    img_make(&im, EXR_PIXEL_HALF, 64, 48, 0);
    write_default(in, &im, EXR_COMPRESSION_ZIP, -1);
    size_t n;
    uint8_t *b = slurp_file(in, &n);
    exr_context_t c = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = quiet_handler;
    assert_int_equal(exr_start_read(&c, in, &init), 0);
    exr_chunk_info_t ci;
    assert_int_equal(exr_read_scanline_chunk_info(c, 0, 16, &ci), 0);
    exr_finish(&c);
    assert_true(ci.packed_size > 8 && ci.packed_size < ci.unpacked_size);

    /* the zlib checksum of the chunk at line 16 */
    b[ci.data_offset + ci.packed_size - 1] ^= 0x5a;
    spit_file(bad, b, n);
    expect_bad_chunk(bad, 16, "checksum");
    b[ci.data_offset + ci.packed_size - 1] ^= 0x5a;

    /* the deflate data in the middle of it */
    for (size_t k = ci.packed_size / 2; k < ci.packed_size / 2 + 4; ++k)
        b[ci.data_offset + k] ^= 0xa5;
    spit_file(bad, b, n);
    expect_bad_chunk(bad, 16, "deflate data");
    free(b);

    /* well-formed streams of the wrong length at line 32 */
    for (bad_stream = 1; bad_stream >= -1; bad_stream -= 2) {
        write_default(bad, &im, EXR_COMPRESSION_ZIP, 32);
        expect_bad_chunk(bad, 32, bad_stream > 0 ? "short stream" : "long stream");
    }
    bad_stream = 0;
    img_free(&im);
    unlink(in);
    unlink(bad);
}

static int setup_group(void **state)
{
    (void) state;
    return tdir_make("test_zip");
}

static int teardown_group(void **state)
{
    (void) state;
    return tdir_remove();
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_zip_preprocess),
        cmocka_unit_test(test_zip_roundtrip),
        cmocka_unit_test(test_zip_corrupt),
    };
    return cmocka_run_group_tests(tests, setup_group, teardown_group);
}

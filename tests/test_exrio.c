/* Unit tests for exrio.h (src/exr/exr_read.c, exr_write.c, exr_stream.c):
 * EXR read/write round trips, channel selection, stream framing, chunk
 * threads and error paths.
 *
 * Input files are made here with OpenEXR's C API writer, in a temporary
 * directory under $FP_TMP (or /tmp) that is removed at the end.  Outputs
 * are checked with an independent reader built on the same C API, so a
 * bug in exrio's decoder cannot hide one in its encoder. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <openexr.h>

#include "exrio.h"
#include "fp.h"

#include "exr_testutil.h"

/* ------------------------------------------------------------ test writer */

typedef struct tchan_t {
    const char *name;
    int type;
    int xs, ys;
    const void *data; /* planar samples over the (sub-sampled) data window */
} tchan_t;

typedef struct tpart_t {
    const char *name;
    int tiled, tw, th, level_mode, round_mode;
    exr_attr_box2i_t dw, disp;
    int compression;
    int lineorder;
    int nch;
    tchan_t ch[16];
    void (*attrs)(exr_context_t, int);
} tpart_t;

#define TRY(x)                                                                 \
    do {                                                                       \
        rv = (x);                                                              \
        if (rv != EXR_ERR_SUCCESS)                                             \
            goto out;                                                          \
    } while (0)

/* Point each channel of a chunk at its samples; (x0, y0) is the chunk's
 * first pixel relative to the data window. */
static void set_ptrs(exr_coding_channel_info_t *chans, int n, const tpart_t *tp,
                     int64_t y0, int64_t x0, int lx, int ly)
{
    for (int c = 0; c < n; ++c) {
        exr_coding_channel_info_t *cc = &chans[c];
        const tchan_t *t = NULL;
        for (int k = 0; k < tp->nch; ++k)
            if (strcmp(tp->ch[k].name, cc->channel_name) == 0)
                t = &tp->ch[k];
        assert_non_null(t);
        size_t bpe = tsize(t->type);
        if (lx || ly) {
            /* Lower mip/rip levels are zeros: OpenEXR 3.1's C writer
             * sizes their edge tiles as full tiles and would read past
             * the image.  Only level 0 is ever read back. */
            static const uint8_t zeros[1 << 16];
            assert_true((size_t) tp->tw * tp->th * bpe <= sizeof zeros);
            cc->encode_from_ptr = zeros;
            cc->user_pixel_stride = (int32_t) bpe;
            cc->user_line_stride = (int32_t) ((size_t) tp->tw * bpe);
            cc->user_bytes_per_element = (int16_t) bpe;
            cc->user_data_type = (uint16_t) t->type;
            continue;
        }
        int64_t sw = scount(tp->dw.min.x, (int64_t) tp->dw.max.x + 1, t->xs);
        int64_t row = scount(tp->dw.min.y, tp->dw.min.y + y0, t->ys);
        int64_t col = scount(tp->dw.min.x, tp->dw.min.x + x0, t->xs);
        cc->encode_from_ptr = (const uint8_t *) t->data + ((size_t) row * (size_t) sw + (size_t) col) * bpe;
        cc->user_pixel_stride = (int32_t) bpe;
        cc->user_line_stride = (int32_t) ((size_t) sw * bpe);
        cc->user_bytes_per_element = (int16_t) bpe;
        cc->user_data_type = (uint16_t) t->type;
    }
}

/* Names up to 255 characters in what try_write_exr writes next. */
static int tw_long_names;

/* Write parts with the C API; returns the library's result (the file is
 * removed on failure), so a test can probe what this library supports. */
static exr_result_t try_write_exr(const char *path, const tpart_t *parts, int np)
{
    exr_context_t ctx = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    exr_result_t rv;
    int inited = 0;
    exr_attr_v2f_t swc;
    swc.x = 0.0f;
    swc.y = 0.0f;
    init.error_handler_fn = quiet_handler;
    TRY(exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init));
    if (tw_long_names)
        TRY(exr_set_longname_support(ctx, 1));
    for (int p = 0; p < np; ++p) {
        const tpart_t *tp = &parts[p];
        int idx;
        TRY(exr_add_part(ctx, tp->name,
                         tp->tiled ? EXR_STORAGE_TILED : EXR_STORAGE_SCANLINE, &idx));
        TRY(exr_initialize_required_attr(ctx, p, &tp->disp, &tp->dw, 1.0f, &swc, 1.0f,
                                         (exr_lineorder_t) tp->lineorder,
                                         (exr_compression_t) tp->compression));
        if (tp->tiled)
            TRY(exr_set_tile_descriptor(ctx, p, (uint32_t) tp->tw, (uint32_t) tp->th,
                                        (exr_tile_level_mode_t) tp->level_mode,
                                        (exr_tile_round_mode_t) tp->round_mode));
        for (int c = 0; c < tp->nch; ++c)
            TRY(exr_add_channel(ctx, p, tp->ch[c].name, (exr_pixel_type_t) tp->ch[c].type,
                                EXR_PERCEPTUALLY_LOGARITHMIC, tp->ch[c].xs,
                                tp->ch[c].ys));
        if (tp->attrs)
            tp->attrs(ctx, p);
    }
    TRY(exr_write_header(ctx));
    for (int p = 0; p < np; ++p) {
        const tpart_t *tp = &parts[p];
        exr_chunk_info_t ci;
        int H = tp->dw.max.y - tp->dw.min.y + 1;
        if (inited)
            exr_encoding_destroy(ctx, &enc);
        memset(&enc, 0, sizeof enc);
        inited = 0;
        if (!tp->tiled) {
            int32_t lpc;
            TRY(exr_get_scanlines_per_chunk(ctx, p, &lpc));
            /* increasing chunk index, whatever the line order: the C
             * library insists */
            for (int k = 0; k < (H + lpc - 1) / lpc; ++k) {
                TRY(exr_write_scanline_chunk_info(ctx, p, tp->dw.min.y + k * lpc, &ci));
                int first = !inited;
                TRY(inited ? exr_encoding_update(ctx, p, &ci, &enc)
                           : exr_encoding_initialize(ctx, p, &ci, &enc));
                inited = 1;
                set_ptrs(enc.channels, enc.channel_count, tp,
                         ci.start_y - tp->dw.min.y, 0, 0, 0);
                if (first)
                    TRY(exr_encoding_choose_default_routines(ctx, p, &enc));
                TRY(exr_encoding_run(ctx, p, &enc));
            }
        } else {
            int32_t nlx, nly;
            TRY(exr_get_tile_levels(ctx, p, &nlx, &nly));
            for (int ly = 0; ly < nly; ++ly)
                for (int lx = 0; lx < nlx; ++lx) {
                    if (tp->level_mode == EXR_TILE_MIPMAP_LEVELS && lx != ly)
                        continue;
                    int32_t lw, lh;
                    TRY(exr_get_level_sizes(ctx, p, lx, ly, &lw, &lh));
                    int ntx = (lw + tp->tw - 1) / tp->tw, nty = (lh + tp->th - 1) / tp->th;
                    for (int ty = 0; ty < nty; ++ty)
                        for (int tx = 0; tx < ntx; ++tx) {
                            TRY(exr_write_tile_chunk_info(ctx, p, tx, ty, lx, ly, &ci));
                            int first = !inited;
                            TRY(inited ? exr_encoding_update(ctx, p, &ci, &enc)
                                       : exr_encoding_initialize(ctx, p, &ci, &enc));
                            inited = 1;
                            set_ptrs(enc.channels, enc.channel_count, tp,
                                     (int64_t) ty * tp->th, (int64_t) tx * tp->tw, lx, ly);
                            if (first)
                                TRY(exr_encoding_choose_default_routines(ctx, p, &enc));
                            TRY(exr_encoding_run(ctx, p, &enc));
                        }
                }
        }
    }
out:
    if (inited)
        exr_encoding_destroy(ctx, &enc);
    if (ctx) {
        exr_result_t frv = exr_finish(&ctx);
        if (rv == EXR_ERR_SUCCESS)
            rv = frv;
    }
    return rv;
}

static void write_exr(const char *path, const tpart_t *parts, int np)
{
    assert_int_equal(try_write_exr(path, parts, np), EXR_ERR_SUCCESS);
}

/* ------------------------------------------------------------ test reader */

/* Decode one channel of a part (scanline or tiled level 0) as raw samples. */
static void *rd_chan(const char *path, int part, const char *name, int *type_out,
                     size_t *n_out)
{
    exr_context_t c;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = quiet_handler;
    if (exr_start_read(&c, path, &init) != 0)
        return NULL;
    exr_attr_box2i_t dw;
    const exr_attr_chlist_t *cl;
    exr_storage_t st;
    uint8_t *plane = NULL;
    assert_int_equal(exr_get_data_window(c, part, &dw), 0);
    assert_int_equal(exr_get_channels(c, part, &cl), 0);
    assert_int_equal(exr_get_storage(c, part, &st), 0);
    const exr_attr_chlist_entry_t *e = NULL;
    for (int i = 0; i < cl->num_channels; ++i)
        if (strcmp(cl->entries[i].name.str, name) == 0)
            e = &cl->entries[i];
    if (!e) {
        exr_finish(&c);
        return NULL;
    }
    size_t bpe = tsize(e->pixel_type);
    int64_t sw = scount(dw.min.x, (int64_t) dw.max.x + 1, e->x_sampling);
    int64_t sh = scount(dw.min.y, (int64_t) dw.max.y + 1, e->y_sampling);
    plane = calloc((size_t) (sw * sh) * bpe + 1, 1);
    assert_non_null(plane);
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    exr_chunk_info_t ci;
    int inited = 0;
    int W = dw.max.x - dw.min.x + 1, H = dw.max.y - dw.min.y + 1;
    int32_t lpc = 1, tw = W, th = H;
    if (st == EXR_STORAGE_SCANLINE)
        assert_int_equal(exr_get_scanlines_per_chunk(c, part, &lpc), 0);
    else
        assert_int_equal(exr_get_tile_sizes(c, part, 0, 0, &tw, &th), 0);
    int ntx = st == EXR_STORAGE_SCANLINE ? 1 : (W + tw - 1) / tw;
    int nty = st == EXR_STORAGE_SCANLINE ? (H + lpc - 1) / lpc : (H + th - 1) / th;
    for (int ty = 0; ty < nty; ++ty)
        for (int tx = 0; tx < ntx; ++tx) {
            int64_t x0 = dw.min.x, y0;
            if (st == EXR_STORAGE_SCANLINE) {
                y0 = dw.min.y + (int64_t) ty * lpc;
                assert_int_equal(exr_read_scanline_chunk_info(c, part, (int) y0, &ci), 0);
            } else {
                x0 = dw.min.x + (int64_t) tx * tw;
                y0 = dw.min.y + (int64_t) ty * th;
                assert_int_equal(exr_read_tile_chunk_info(c, part, tx, ty, 0, 0, &ci), 0);
            }
            if (inited)
                assert_int_equal(exr_decoding_update(c, part, &ci, &dec), 0);
            else
                assert_int_equal(exr_decoding_initialize(c, part, &ci, &dec), 0);
            for (int k = 0; k < dec.channel_count; ++k) {
                exr_coding_channel_info_t *cc = &dec.channels[k];
                if (strcmp(cc->channel_name, name) != 0) {
                    cc->decode_to_ptr = NULL;
                    continue;
                }
                int64_t row = scount(dw.min.y, y0, e->y_sampling);
                int64_t col = scount(dw.min.x, x0, e->x_sampling);
                cc->decode_to_ptr = plane + ((size_t) row * sw + (size_t) col) * bpe;
                cc->user_pixel_stride = (int32_t) bpe;
                cc->user_line_stride = (int32_t) (sw * bpe);
                cc->user_bytes_per_element = (int16_t) bpe;
                cc->user_data_type = cc->data_type;
            }
            if (!inited) {
                assert_int_equal(exr_decoding_choose_default_routines(c, part, &dec), 0);
                inited = 1;
            }
            assert_int_equal(exr_decoding_run(c, part, &dec), 0);
        }
    exr_decoding_destroy(c, &dec);
    *type_out = e->pixel_type;
    *n_out = (size_t) (sw * sh);
    exr_finish(&c);
    return plane;
}

/* The channel's bytes in two files are identical. */
static void assert_same_chan(const char *a, int pa, const char *b, int pb,
                             const char *name)
{
    int ta, tb;
    size_t na, nb;
    void *da = rd_chan(a, pa, name, &ta, &na);
    void *db = rd_chan(b, pb, name, &tb, &nb);
    if (!da || !db)
        print_error("channel %s missing (%p %p)\n", name, da, db);
    assert_non_null(da);
    assert_non_null(db);
    assert_int_equal(ta, tb);
    assert_int_equal(na, nb);
    assert_memory_equal(da, db, na * tsize(ta));
    free(da);
    free(db);
}

static exr_context_t open_hdr(const char *path)
{
    exr_context_t c;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = quiet_handler;
    assert_int_equal(exr_start_read(&c, path, &init), 0);
    return c;
}

/* ------------------------------------------------------------ fixtures */

#define W0 64
#define H0 48

typedef struct std_img_t {
    void *r, *g, *b, *a, *z, *id, *nx;
    int ctype;
} std_img_t;

static void std_img_make(std_img_t *im, int ctype, int w, int h)
{
    im->ctype = ctype;
    im->r = mkplane(ctype, w, h, 1);
    im->g = mkplane(ctype, w, h, 2);
    im->b = mkplane(ctype, w, h, 3);
    im->a = mkplane(ctype, w, h, 4);
    im->z = mkplane(EXR_PIXEL_FLOAT, w, h, 5);
    im->id = mkplane(EXR_PIXEL_UINT, w, h, 6);
    im->nx = mkplane(EXR_PIXEL_FLOAT, w, h, 7);
}

static void std_img_free(std_img_t *im)
{
    free(im->r);
    free(im->g);
    free(im->b);
    free(im->a);
    free(im->z);
    free(im->id);
    free(im->nx);
}

/* R,G,B[,A] + Z float + id uint + N.X float */
static tpart_t std_part(const std_img_t *im, int comp, exr_attr_box2i_t dw,
                        exr_attr_box2i_t disp, int alpha)
{
    tpart_t tp;
    memset(&tp, 0, sizeof tp);
    tp.dw = dw;
    tp.disp = disp;
    tp.compression = comp;
    tp.lineorder = EXR_LINEORDER_INCREASING_Y;
    int n = 0;
    tp.ch[n++] = (tchan_t) { "R", im->ctype, 1, 1, im->r };
    tp.ch[n++] = (tchan_t) { "G", im->ctype, 1, 1, im->g };
    tp.ch[n++] = (tchan_t) { "B", im->ctype, 1, 1, im->b };
    if (alpha)
        tp.ch[n++] = (tchan_t) { "A", im->ctype, 1, 1, im->a };
    tp.ch[n++] = (tchan_t) { "Z", EXR_PIXEL_FLOAT, 1, 1, im->z };
    tp.ch[n++] = (tchan_t) { "id", EXR_PIXEL_UINT, 1, 1, im->id };
    tp.ch[n++] = (tchan_t) { "N.X", EXR_PIXEL_FLOAT, 1, 1, im->nx };
    tp.nch = n;
    return tp;
}

static int setup_group(void **state)
{
    (void) state;
    const char *base = getenv("FP_TMP");
    if (!base || !*base)
        base = "/tmp";
    snprintf(tdir, sizeof tdir, "%s/test_exrio.XXXXXX", base);
    if (!mkdtemp(tdir))
        return -1;
    return 0;
}

static void rm_tree(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        char p[8192];
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        struct stat st;
        if (lstat(p, &st) == 0 && S_ISDIR(st.st_mode))
            rm_tree(p);
        else
            unlink(p);
    }
    closedir(d);
    rmdir(dir);
}

static int teardown_group(void **state)
{
    (void) state;
    rm_tree(tdir);
    return 0;
}

/* No temporary left behind in the test directory. */
static void assert_no_temporaries(void)
{
    DIR *d = opendir(tdir);
    assert_non_null(d);
    struct dirent *e;
    while ((e = readdir(d)))
        if (strstr(e->d_name, ".tmp."))
            fail_msg("temporary left: %s", e->d_name);
    closedir(d);
}

/* ------------------------------------------------------------ tests */

static void test_compression_names(void **state)
{
    (void) state;
    const char *names[] = { "none", "rle", "zips", "zip", "piz", "pxr24",
                            "b44", "b44a", "dwaa", "dwab" };
    for (int i = 0; i < 10; ++i) {
        assert_int_equal(fp_exr_compression_from_name(names[i]), i);
        assert_string_equal(fp_exr_compression_name(i), names[i]);
    }
    assert_int_equal(fp_exr_compression_from_name("ZIP"), EXR_COMPRESSION_ZIP);
    assert_int_equal(fp_exr_compression_from_name("lzw"), -1);
    assert_int_equal(fp_exr_compression_from_name(NULL), -1);
    assert_string_equal(fp_exr_compression_name(42), "unknown");
}

static int is_lossy(int comp)
{
    return comp == EXR_COMPRESSION_B44 || comp == EXR_COMPRESSION_B44A ||
           comp == EXR_COMPRESSION_DWAA || comp == EXR_COMPRESSION_DWAB;
}

/* Every compression: colour (half RGBA) read and written back, bit-exact
 * for lossless codecs; b44/b44a/dwaa/dwab within 2% + 0.01 absolute (the
 * content is smooth, in [0.05, 0.95]); Z, id and N.X passed through with
 * their bytes unchanged (pxr24 is lossy for floats, so its float input is
 * compared with what was decoded, which re-encodes to the same bytes). */
static void test_roundtrip_compressions(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    for (int comp = 0; comp < EXR_COMPRESSION_LAST_TYPE; ++comp) {
        char in[4200], out[4200];
        char name[64];
        snprintf(name, sizeof name, "rt_%s.exr", fp_exr_compression_name(comp));
        path_in(in, sizeof in, name);
        snprintf(name, sizeof name, "rt_%s.out.exr", fp_exr_compression_name(comp));
        path_in(out, sizeof out, name);
        tpart_t tp = std_part(&im, comp, box(3, 2, 3 + W0 - 1, 2 + H0 - 1),
                              box(0, 0, W0 + 5, H0 + 3), 1);
        exr_result_t wrv = try_write_exr(in, &tp, 1);
        if (wrv == EXR_ERR_FEATURE_NOT_IMPLEMENTED) {
            /* OpenEXR 3.1's C library has no DWA codec to make the input
             * with: DWAA/DWAB in and out are tested in tests/test_dwa.c */
            assert_true(comp == EXR_COMPRESSION_DWAA || comp == EXR_COMPRESSION_DWAB);
            continue;
        }
        assert_int_equal(wrv, EXR_ERR_SUCCESS);

        fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
        fp_frame_t *f = NULL;
        assert_int_equal(fp_exr_read_file(in, 1, &sel, &f), FP_OK);
        const fp_frame_info_t *info = fp_frame_info(f);
        assert_int_equal(info->width, W0);
        assert_int_equal(info->height, H0);
        assert_int_equal(info->data_x0, 3);
        assert_int_equal(info->data_y0, 2);
        assert_int_equal(info->disp_w, W0 + 6);
        assert_int_equal(info->disp_h, H0 + 4);
        assert_int_equal(info->compression, comp);
        assert_int_equal(info->num_parts, 1);
        assert_int_equal(info->has_alpha, 1);
        assert_string_equal(info->color_names[0], "R");
        assert_string_equal(info->color_names[3], "A");
        assert_string_equal(info->depth_name, "Z");
        assert_true(info->pixel_aspect == 1.0f);

        const float *rgba = fp_frame_rgba(f);
        const float *depth = fp_frame_depth(f);
        assert_non_null(rgba);
        assert_non_null(depth);
        const void *src[4] = { im.r, im.g, im.b, im.a };
        for (size_t i = 0; i < (size_t) W0 * H0; ++i) {
            for (int k = 0; k < 4; ++k) {
                float want = pget(EXR_PIXEL_HALF, src[k], i);
                if (is_lossy(comp)) {
                    if (fabsf(rgba[i * 4 + k] - want) > 0.01f + 0.02f * fabsf(want))
                        fail_msg("%s: pixel %zu.%d: %g vs %g", name, i, k,
                                 rgba[i * 4 + k], want);
                } else if (rgba[i * 4 + k] != want) {
                    fail_msg("%s: pixel %zu.%d: %g vs %g", name, i, k,
                             rgba[i * 4 + k], want);
                }
            }
            float zw = pget(EXR_PIXEL_FLOAT, im.z, i);
            if (comp == EXR_COMPRESSION_PXR24)
                assert_true(fabsf(depth[i] - zw) <= 1e-4f * fabsf(zw));
            else
                assert_true(depth[i] == zw);
        }

        assert_int_equal(fp_exr_write_file(f, NULL, NULL, out, 1), FP_OK);
        fp_frame_free(f);

        /* header of the output */
        exr_context_t c = open_hdr(out);
        exr_compression_t oc;
        exr_attr_box2i_t dw, disp;
        exr_storage_t st;
        assert_int_equal(exr_get_compression(c, 0, &oc), 0);
        assert_int_equal((int) oc, comp);
        assert_int_equal(exr_get_data_window(c, 0, &dw), 0);
        assert_int_equal(exr_get_display_window(c, 0, &disp), 0);
        assert_int_equal(exr_get_storage(c, 0, &st), 0);
        assert_int_equal(st, EXR_STORAGE_SCANLINE);
        assert_int_equal(dw.min.x, 3);
        assert_int_equal(dw.max.y, 2 + H0 - 1);
        assert_int_equal(disp.max.x, W0 + 5);
        const exr_attr_chlist_t *cl;
        assert_int_equal(exr_get_channels(c, 0, &cl), 0);
        assert_int_equal(cl->num_channels, 7);
        for (int i = 1; i < cl->num_channels; ++i)
            assert_true(strcmp(cl->entries[i - 1].name.str, cl->entries[i].name.str) < 0);
        exr_finish(&c);

        /* colour as half, pass-through unchanged */
        const char *cn[4] = { "R", "G", "B", "A" };
        for (int k = 0; k < 4; ++k) {
            int t;
            size_t n;
            void *d = rd_chan(out, 0, cn[k], &t, &n);
            assert_non_null(d);
            assert_int_equal(t, EXR_PIXEL_HALF);
            assert_int_equal(n, (size_t) W0 * H0);
            if (!is_lossy(comp)) {
                assert_memory_equal(d, src[k], n * 2);
            } else {
                for (size_t i = 0; i < n; ++i) {
                    float want = pget(EXR_PIXEL_HALF, src[k], i);
                    float got = pget(EXR_PIXEL_HALF, d, i);
                    /* two lossy generations */
                    if (fabsf(got - want) > 0.02f + 0.04f * fabsf(want))
                        fail_msg("%s out: pixel %zu.%d: %g vs %g", name, i, k, got, want);
                }
            }
            free(d);
        }
        assert_same_chan(in, 0, out, 0, "Z");
        assert_same_chan(in, 0, out, 0, "id");
        assert_same_chan(in, 0, out, 0, "N.X");
    }
    std_img_free(&im);
}

/* --compression overrides the input's. */
static void test_compression_override(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char in[4200], out[4200];
    path_in(in, sizeof in, "ovr.exr");
    path_in(out, sizeof out, "ovr.out.exr");
    tpart_t tp = std_part(&im, EXR_COMPRESSION_ZIP, box(0, 0, W0 - 1, H0 - 1),
                          box(0, 0, W0 - 1, H0 - 1), 1);
    write_exr(in, &tp, 1);
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_file(in, 2, NULL, &f), FP_OK);
    fp_exr_write_opts_t o = FP_EXR_WRITE_OPTS_INITIALIZER;
    o.compression = EXR_COMPRESSION_PIZ;
    assert_int_equal(fp_exr_write_file(f, NULL, &o, out, 2), FP_OK);
    fp_frame_free(f);
    exr_context_t c = open_hdr(out);
    exr_compression_t oc;
    assert_int_equal(exr_get_compression(c, 0, &oc), 0);
    assert_int_equal(oc, EXR_COMPRESSION_PIZ);
    exr_finish(&c);
    assert_same_chan(in, 0, out, 0, "R");
    assert_same_chan(in, 0, out, 0, "id");
    std_img_free(&im);
}

/* Float colour without alpha: A reads as 1; --float writes it back exactly;
 * the default writes half (relative error <= 2^-11) and no alpha. */
static void test_float_color(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_FLOAT, W0, H0);
    char in[4200], out[4200], outh[4200];
    path_in(in, sizeof in, "flt.exr");
    path_in(out, sizeof out, "flt.float.exr");
    path_in(outh, sizeof outh, "flt.half.exr");
    tpart_t tp = std_part(&im, EXR_COMPRESSION_ZIPS, box(0, 0, W0 - 1, H0 - 1),
                          box(0, 0, W0 - 1, H0 - 1), 0);
    write_exr(in, &tp, 1);
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_file(in, 3, NULL, &f), FP_OK);
    assert_int_equal(fp_frame_info(f)->has_alpha, 0);
    assert_string_equal(fp_frame_info(f)->color_names[3], "");
    const float *rgba = fp_frame_rgba(f);
    for (size_t i = 0; i < (size_t) W0 * H0; ++i) {
        assert_true(rgba[i * 4 + 0] == pget(EXR_PIXEL_FLOAT, im.r, i));
        assert_true(rgba[i * 4 + 2] == pget(EXR_PIXEL_FLOAT, im.b, i));
        assert_true(rgba[i * 4 + 3] == 1.0f);
    }
    fp_exr_write_opts_t o = FP_EXR_WRITE_OPTS_INITIALIZER;
    o.use_float = 1;
    assert_int_equal(fp_exr_write_file(f, NULL, &o, out, 3), FP_OK);
    assert_int_equal(fp_exr_write_file(f, NULL, NULL, outh, 3), FP_OK);
    fp_frame_free(f);
    assert_same_chan(in, 0, out, 0, "R");
    assert_same_chan(in, 0, out, 0, "G");
    assert_same_chan(in, 0, out, 0, "B");
    int t;
    size_t n;
    assert_null(rd_chan(out, 0, "A", &t, &n));
    assert_null(rd_chan(outh, 0, "A", &t, &n));
    void *d = rd_chan(outh, 0, "G", &t, &n);
    assert_non_null(d);
    assert_int_equal(t, EXR_PIXEL_HALF);
    for (size_t i = 0; i < n; ++i) {
        float want = pget(EXR_PIXEL_FLOAT, im.g, i), got = pget(t, d, i);
        assert_true(fabsf(got - want) <= fabsf(want) * (1.0f / 2048.0f));
    }
    free(d);
    assert_same_chan(in, 0, outh, 0, "Z");
    std_img_free(&im);
}

/* Tiled input (one level, and mipmapped): level 0 read, scanline written,
 * the "tiles" attribute gone. */
static void test_tiled_input(void **state)
{
    (void) state;
    const int w = 56, h = 44;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, w, h);
    for (int mode = 0; mode < 2; ++mode) {
        char in[4200], out[4200], name[64];
        snprintf(name, sizeof name, "tiled%d.exr", mode);
        path_in(in, sizeof in, name);
        snprintf(name, sizeof name, "tiled%d.out.exr", mode);
        path_in(out, sizeof out, name);
        tpart_t tp = std_part(&im, mode == 1 ? EXR_COMPRESSION_PIZ : EXR_COMPRESSION_ZIP,
                              box(5, -3, 5 + w - 1, -3 + h - 1), box(0, 0, 63, 47), 1);
        tp.tiled = 1;
        tp.tw = 16;
        tp.th = 12;
        tp.level_mode = mode; /* ONE_LEVEL, MIPMAP */
        tp.round_mode = mode == 1 ? EXR_TILE_ROUND_UP : EXR_TILE_ROUND_DOWN;
        write_exr(in, &tp, 1);
        fp_frame_t *f = NULL;
        assert_int_equal(fp_exr_read_file(in, 4, NULL, &f), FP_OK);
        assert_int_equal(fp_frame_info(f)->width, w);
        assert_int_equal(fp_frame_info(f)->data_y0, -3);
        const float *rgba = fp_frame_rgba(f);
        for (size_t i = 0; i < (size_t) w * h; ++i)
            assert_true(rgba[i * 4 + 1] == pget(EXR_PIXEL_HALF, im.g, i));
        assert_true(fp_frame_depth(f)[w * h - 1] == pget(EXR_PIXEL_FLOAT, im.z, (size_t) w * h - 1));
        assert_int_equal(fp_exr_write_file(f, NULL, NULL, out, 4), FP_OK);
        fp_frame_free(f);
        exr_context_t c = open_hdr(out);
        exr_storage_t st;
        const exr_attribute_t *a = NULL;
        assert_int_equal(exr_get_storage(c, 0, &st), 0);
        assert_int_equal(st, EXR_STORAGE_SCANLINE);
        assert_int_not_equal(exr_get_attribute_by_name(c, 0, "tiles", &a), 0);
        exr_finish(&c);
        assert_same_chan(in, 0, out, 0, "R");
        assert_same_chan(in, 0, out, 0, "A");
        assert_same_chan(in, 0, out, 0, "Z");
        assert_same_chan(in, 0, out, 0, "id");
    }
    std_img_free(&im);
}

/* Negative data window origin, data window != display window: kept;
 * decreasing line order: normalized to increasing (see
 * test_lineorder_decreasing). */
static void test_negative_window(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char in[4200], out[4200];
    path_in(in, sizeof in, "neg.exr");
    path_in(out, sizeof out, "neg.out.exr");
    tpart_t tp = std_part(&im, EXR_COMPRESSION_RLE, box(-10, -7, -10 + W0 - 1, -7 + H0 - 1),
                          box(0, 0, 99, 59), 1);
    tp.lineorder = EXR_LINEORDER_DECREASING_Y;
    write_exr(in, &tp, 1);
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_file(in, 5, NULL, &f), FP_OK);
    const fp_frame_info_t *info = fp_frame_info(f);
    assert_int_equal(info->data_x0, -10);
    assert_int_equal(info->data_y0, -7);
    assert_int_equal(info->disp_x0, 0);
    assert_int_equal(info->disp_w, 100);
    assert_int_equal(info->disp_h, 60);
    assert_true(fp_frame_rgba(f)[4 * 100] == pget(EXR_PIXEL_HALF, im.r, 100));
    assert_int_equal(fp_exr_write_file(f, NULL, NULL, out, 5), FP_OK);
    fp_frame_free(f);
    exr_context_t c = open_hdr(out);
    exr_attr_box2i_t dw, disp;
    exr_lineorder_t lo;
    assert_int_equal(exr_get_data_window(c, 0, &dw), 0);
    assert_int_equal(exr_get_display_window(c, 0, &disp), 0);
    assert_int_equal(exr_get_lineorder(c, 0, &lo), 0);
    assert_int_equal(dw.min.x, -10);
    assert_int_equal(dw.min.y, -7);
    assert_int_equal(dw.max.x, -10 + W0 - 1);
    assert_int_equal(disp.max.x, 99);
    assert_int_equal(lo, EXR_LINEORDER_INCREASING_Y);
    exr_finish(&c);
    assert_same_chan(in, 0, out, 0, "R");
    assert_same_chan(in, 0, out, 0, "N.X");
    std_img_free(&im);
}

static const float w2c[16] = { 1, 0, 0, 0, 0, 0.5f, 0.25f, 0, 0, -0.25f, 0.5f, 0,
                               10, 20, 30, 1 };
static const double w2n[16] = { 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, -1.0000001, -1,
                                0, 0, -0.2, 0 };

static void add_attrs(exr_context_t c, int p)
{
    exr_attr_m44f_t m;
    exr_attr_m44d_t md;
    memcpy(m.m, w2c, sizeof m.m);
    memcpy(md.m, w2n, sizeof md.m);
    exr_attr_chromaticities_t chr = { 0.64f, 0.33f, 0.3f, 0.6f, 0.15f, 0.06f,
                                      0.3127f, 0.329f };
    const char *sv[2] = { "left", "right" };
    const float fv[3] = { 1.5f, 2.5f, 3.5f };
    exr_attr_v2f_t v;
    v.x = 0.25f;
    v.y = -0.5f;
    assert_int_equal(exr_attr_set_string(c, p, "fp.note", "hello fog"), 0);
    assert_int_equal(exr_attr_set_string(c, p, "owner", "fogpipe tests"), 0);
    assert_int_equal(exr_attr_set_m44f(c, p, "worldToCamera", &m), 0);
    assert_int_equal(exr_attr_set_m44d(c, p, "worldToNDC", &md), 0);
    assert_int_equal(exr_attr_set_chromaticities(c, p, "chromaticities", &chr), 0);
    assert_int_equal(exr_attr_set_int(c, p, "fp.int", -42), 0);
    assert_int_equal(exr_attr_set_string_vector(c, p, "multiView", 2, sv), 0);
    assert_int_equal(exr_attr_set_float_vector(c, p, "fp.fv", 3, fv), 0);
    assert_int_equal(exr_attr_set_v2f(c, p, "fp.v2f", &v), 0);
    assert_int_equal(exr_attr_set_user(c, p, "fp.blob", "fpBlob", 5, "abcde"), 0);
}

static void test_attributes_kept(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char in[4200], out[4200];
    path_in(in, sizeof in, "attr.exr");
    path_in(out, sizeof out, "attr.out.exr");
    tpart_t tp = std_part(&im, EXR_COMPRESSION_ZIP, box(0, 0, W0 - 1, H0 - 1),
                          box(0, 0, W0 - 1, H0 - 1), 1);
    tp.attrs = add_attrs;
    write_exr(in, &tp, 1);
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_file(in, 6, NULL, &f), FP_OK);
    const fp_frame_info_t *info = fp_frame_info(f);
    assert_int_equal(info->has_world_to_camera, 1);
    assert_int_equal(info->has_world_to_ndc, 1);
    for (int i = 0; i < 16; ++i) {
        assert_true(info->world_to_camera[i] == (double) w2c[i]);
        assert_true(info->world_to_ndc[i] == w2n[i]);
    }
    assert_int_equal(fp_exr_write_file(f, NULL, NULL, out, 6), FP_OK);
    fp_frame_free(f);

    exr_context_t c = open_hdr(out);
    const char *s;
    int32_t len;
    assert_int_equal(exr_attr_get_string(c, 0, "fp.note", &len, &s), 0);
    assert_string_equal(s, "hello fog");
    assert_int_equal(exr_attr_get_string(c, 0, "owner", &len, &s), 0);
    assert_string_equal(s, "fogpipe tests");
    exr_attr_m44f_t m;
    exr_attr_m44d_t md;
    assert_int_equal(exr_attr_get_m44f(c, 0, "worldToCamera", &m), 0);
    assert_memory_equal(m.m, w2c, sizeof m.m);
    assert_int_equal(exr_attr_get_m44d(c, 0, "worldToNDC", &md), 0);
    assert_memory_equal(md.m, w2n, sizeof md.m);
    exr_attr_chromaticities_t chr;
    assert_int_equal(exr_attr_get_chromaticities(c, 0, "chromaticities", &chr), 0);
    assert_true(chr.white_x == 0.3127f && chr.red_y == 0.33f);
    int32_t iv;
    assert_int_equal(exr_attr_get_int(c, 0, "fp.int", &iv), 0);
    assert_int_equal(iv, -42);
    const char *sv[4];
    int32_t nsv = 4;
    assert_int_equal(exr_attr_get_string_vector(c, 0, "multiView", &nsv, sv), 0);
    assert_int_equal(nsv, 2);
    assert_string_equal(sv[1], "right");
    int32_t nfv;
    const float *fv;
    assert_int_equal(exr_attr_get_float_vector(c, 0, "fp.fv", &nfv, &fv), 0);
    assert_int_equal(nfv, 3);
    assert_true(fv[2] == 3.5f);
    exr_attr_v2f_t v;
    assert_int_equal(exr_attr_get_v2f(c, 0, "fp.v2f", &v), 0);
    assert_true(v.y == -0.5f);
    const char *ty;
    int32_t sz;
    const void *blob;
    assert_int_equal(exr_attr_get_user(c, 0, "fp.blob", &ty, &sz, &blob), 0);
    assert_string_equal(ty, "fpBlob");
    assert_int_equal(sz, 5);
    assert_memory_equal(blob, "abcde", 5);
    exr_finish(&c);
    std_img_free(&im);
}

/* Colour in part 0, an AOV part with another data window, depth in a
 * third part: depth found there, everything else passed through. */
static void test_multipart(void **state)
{
    (void) state;
    std_img_t im, aux;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    std_img_make(&aux, EXR_PIXEL_HALF, 20, 10);
    char in[4200], out[4200], out2[4200];
    path_in(in, sizeof in, "mp.exr");
    path_in(out, sizeof out, "mp.out.exr");
    path_in(out2, sizeof out2, "mp.aov.exr");
    tpart_t tp[3];
    memset(tp, 0, sizeof tp);
    tp[0].name = "beauty";
    tp[0].dw = tp[0].disp = box(0, 0, W0 - 1, H0 - 1);
    tp[0].compression = EXR_COMPRESSION_ZIP;
    tp[0].ch[0] = (tchan_t) { "R", EXR_PIXEL_HALF, 1, 1, im.r };
    tp[0].ch[1] = (tchan_t) { "G", EXR_PIXEL_HALF, 1, 1, im.g };
    tp[0].ch[2] = (tchan_t) { "B", EXR_PIXEL_HALF, 1, 1, im.b };
    tp[0].ch[3] = (tchan_t) { "A", EXR_PIXEL_HALF, 1, 1, im.a };
    tp[0].nch = 4;
    tp[0].attrs = add_attrs;
    tp[1].name = "aux";
    tp[1].dw = box(4, 5, 23, 14);
    tp[1].disp = box(0, 0, W0 - 1, H0 - 1);
    tp[1].compression = EXR_COMPRESSION_PIZ;
    tp[1].ch[0] = (tchan_t) { "N.X", EXR_PIXEL_FLOAT, 1, 1, aux.nx };
    tp[1].ch[1] = (tchan_t) { "id", EXR_PIXEL_UINT, 1, 1, aux.id };
    tp[1].nch = 2;
    tp[2].name = "depth";
    tp[2].dw = tp[2].disp = box(0, 0, W0 - 1, H0 - 1);
    tp[2].compression = EXR_COMPRESSION_ZIPS;
    tp[2].tiled = 1;
    tp[2].tw = tp[2].th = 32;
    tp[2].ch[0] = (tchan_t) { "Z", EXR_PIXEL_FLOAT, 1, 1, im.z };
    tp[2].nch = 1;
    write_exr(in, tp, 3);

    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_file(in, 7, NULL, &f), FP_OK);
    assert_int_equal(fp_frame_info(f)->num_parts, 3);
    assert_string_equal(fp_frame_info(f)->depth_name, "Z");
    assert_true(fp_frame_depth(f)[17] == pget(EXR_PIXEL_FLOAT, im.z, 17));
    assert_int_equal(fp_frame_info(f)->has_world_to_camera, 1);
    assert_int_equal(fp_exr_write_file(f, NULL, NULL, out, 7), FP_OK);

    /* --color-only with an AOV: only the colour part, colour + AOV */
    float *aov = malloc(sizeof(float) * W0 * H0);
    assert_non_null(aov);
    for (int i = 0; i < W0 * H0; ++i)
        aov[i] = (float) i * 0.5f;
    fp_exr_extra_t ex = { "fog.T", aov };
    fp_exr_write_opts_t o = FP_EXR_WRITE_OPTS_INITIALIZER;
    o.extra = &ex;
    o.num_extra = 1;
    o.color_only = 1;
    assert_int_equal(fp_exr_write_file(f, NULL, &o, out2, 7), FP_OK);
    fp_frame_free(f);

    exr_context_t c = open_hdr(out);
    int32_t np;
    const char *pn;
    assert_int_equal(exr_get_count(c, &np), 0);
    assert_int_equal(np, 3);
    assert_int_equal(exr_get_name(c, 1, &pn), 0);
    assert_string_equal(pn, "aux");
    exr_attr_box2i_t dw;
    assert_int_equal(exr_get_data_window(c, 1, &dw), 0);
    assert_int_equal(dw.min.x, 4);
    assert_int_equal(dw.max.y, 14);
    exr_storage_t st;
    assert_int_equal(exr_get_storage(c, 2, &st), 0);
    assert_int_equal(st, EXR_STORAGE_SCANLINE);
    exr_finish(&c);
    assert_same_chan(in, 0, out, 0, "R");
    assert_same_chan(in, 0, out, 0, "A");
    assert_same_chan(in, 1, out, 1, "N.X");
    assert_same_chan(in, 1, out, 1, "id");
    assert_same_chan(in, 2, out, 2, "Z");

    c = open_hdr(out2);
    assert_int_equal(exr_get_count(c, &np), 0);
    assert_int_equal(np, 1);
    const exr_attr_chlist_t *cl;
    assert_int_equal(exr_get_channels(c, 0, &cl), 0);
    assert_int_equal(cl->num_channels, 5); /* A B G R fog.T */
    assert_string_equal(cl->entries[4].name.str, "fog.T");
    assert_int_equal(cl->entries[4].pixel_type, EXR_PIXEL_FLOAT);
    exr_finish(&c);
    int t;
    size_t n;
    float *got = rd_chan(out2, 0, "fog.T", &t, &n);
    assert_non_null(got);
    assert_memory_equal(got, aov, sizeof(float) * W0 * H0);
    free(got);
    free(aov);
    std_img_free(&im);
    std_img_free(&aux);
}

/* Depth in another part with another data window: one clear error. */
static void test_depth_part_mismatch(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char in[4200];
    path_in(in, sizeof in, "mpbad.exr");
    tpart_t tp[2];
    memset(tp, 0, sizeof tp);
    tp[0].name = "rgb";
    tp[0].dw = tp[0].disp = box(0, 0, W0 - 1, H0 - 1);
    tp[0].ch[0] = (tchan_t) { "R", EXR_PIXEL_HALF, 1, 1, im.r };
    tp[0].ch[1] = (tchan_t) { "G", EXR_PIXEL_HALF, 1, 1, im.g };
    tp[0].ch[2] = (tchan_t) { "B", EXR_PIXEL_HALF, 1, 1, im.b };
    tp[0].nch = 3;
    tp[1].name = "z";
    tp[1].dw = box(0, 0, 31, 23);
    tp[1].disp = tp[0].disp;
    tp[1].ch[0] = (tchan_t) { "Z", EXR_PIXEL_FLOAT, 1, 1, im.z };
    tp[1].nch = 1;
    write_exr(in, tp, 2);
    fp_frame_t *f = NULL;
    cap_begin();
    int rc = fp_exr_read_file(in, 8, NULL, &f);
    const char *msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_null(f);
    assert_contains(msg, "mpbad.exr: frame 8:");
    assert_contains(msg, "64x48");
    assert_contains(msg, "32x24");
    std_img_free(&im);
}

static void blender_file(const char *path, std_img_t *im)
{
    tpart_t tp;
    memset(&tp, 0, sizeof tp);
    tp.dw = tp.disp = box(0, 0, W0 - 1, H0 - 1);
    tp.compression = EXR_COMPRESSION_ZIP;
    int n = 0;
    tp.ch[n++] = (tchan_t) { "ViewLayer.Combined.R", EXR_PIXEL_FLOAT, 1, 1, im->r };
    tp.ch[n++] = (tchan_t) { "ViewLayer.Combined.G", EXR_PIXEL_FLOAT, 1, 1, im->g };
    tp.ch[n++] = (tchan_t) { "ViewLayer.Combined.B", EXR_PIXEL_FLOAT, 1, 1, im->b };
    tp.ch[n++] = (tchan_t) { "ViewLayer.Combined.A", EXR_PIXEL_FLOAT, 1, 1, im->a };
    tp.ch[n++] = (tchan_t) { "ViewLayer.Depth.Z", EXR_PIXEL_FLOAT, 1, 1, im->z };
    tp.ch[n++] = (tchan_t) { "Alt.Combined.R", EXR_PIXEL_FLOAT, 1, 1, im->b };
    tp.ch[n++] = (tchan_t) { "Alt.Combined.G", EXR_PIXEL_FLOAT, 1, 1, im->r };
    tp.ch[n++] = (tchan_t) { "Alt.Combined.B", EXR_PIXEL_FLOAT, 1, 1, im->g };
    tp.ch[n++] = (tchan_t) { "Alt.Depth.Z", EXR_PIXEL_FLOAT, 1, 1, im->nx };
    tp.nch = n;
    write_exr(path, &tp, 1);
}

/* Blender multilayer names; the depth of the colour's view layer wins. */
static void test_blender_multilayer(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_FLOAT, W0, H0);
    char in[4200], out[4200];
    path_in(in, sizeof in, "blender.exr");
    path_in(out, sizeof out, "blender.out.exr");
    blender_file(in, &im);

    /* default: the first layer (sorted: Alt), and its depth */
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_file(in, 9, NULL, &f), FP_OK);
    assert_string_equal(fp_frame_info(f)->color_names[0], "Alt.Combined.R");
    assert_int_equal(fp_frame_info(f)->has_alpha, 0);
    assert_string_equal(fp_frame_info(f)->depth_name, "Alt.Depth.Z");
    fp_frame_free(f);

    /* --color-layer ViewLayer: its depth, though Alt.Depth.Z sorts first */
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    sel.color_layer = "ViewLayer";
    assert_int_equal(fp_exr_read_file(in, 9, &sel, &f), FP_OK);
    assert_string_equal(fp_frame_info(f)->color_names[0], "ViewLayer.Combined.R");
    assert_string_equal(fp_frame_info(f)->color_names[3], "ViewLayer.Combined.A");
    assert_string_equal(fp_frame_info(f)->depth_name, "ViewLayer.Depth.Z");
    assert_true(fp_frame_rgba(f)[4 * 10 + 3] == pget(EXR_PIXEL_FLOAT, im.a, 10));
    assert_true(fp_frame_depth(f)[10] == pget(EXR_PIXEL_FLOAT, im.z, 10));
    fp_exr_write_opts_t o = FP_EXR_WRITE_OPTS_INITIALIZER;
    o.use_float = 1;
    assert_int_equal(fp_exr_write_file(f, NULL, &o, out, 9), FP_OK);
    fp_frame_free(f);
    assert_same_chan(in, 0, out, 0, "ViewLayer.Combined.G");
    assert_same_chan(in, 0, out, 0, "ViewLayer.Depth.Z");
    assert_same_chan(in, 0, out, 0, "Alt.Combined.R");

    /* the full prefix works too, and --depth-channel overrides */
    sel.color_layer = "ViewLayer.Combined";
    sel.depth_channel = "Alt.Depth.Z";
    assert_int_equal(fp_exr_read_file(in, 9, &sel, &f), FP_OK);
    assert_string_equal(fp_frame_info(f)->color_names[1], "ViewLayer.Combined.G");
    assert_string_equal(fp_frame_info(f)->depth_name, "Alt.Depth.Z");
    assert_true(fp_frame_depth(f)[10] == pget(EXR_PIXEL_FLOAT, im.nx, 10));
    fp_frame_free(f);
    std_img_free(&im);
}

/* --color-layer / --depth-channel on generic names, and their errors. */
static void test_overrides(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char in[4200];
    path_in(in, sizeof in, "ovr_names.exr");
    tpart_t tp = std_part(&im, EXR_COMPRESSION_NONE, box(0, 0, W0 - 1, H0 - 1),
                          box(0, 0, W0 - 1, H0 - 1), 0);
    int n = tp.nch;
    tp.ch[n++] = (tchan_t) { "fog.R", EXR_PIXEL_HALF, 1, 1, im.g };
    tp.ch[n++] = (tchan_t) { "fog.G", EXR_PIXEL_HALF, 1, 1, im.b };
    tp.ch[n++] = (tchan_t) { "fog.B", EXR_PIXEL_HALF, 1, 1, im.r };
    tp.ch[n++] = (tchan_t) { "custom.depth", EXR_PIXEL_UINT, 1, 1, im.id };
    tp.nch = n;
    write_exr(in, &tp, 1);

    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_file(in, 10, &sel, &f), FP_OK);
    assert_string_equal(fp_frame_info(f)->color_names[0], "R");
    assert_string_equal(fp_frame_info(f)->depth_name, "Z");
    fp_frame_free(f);

    sel.color_layer = "fog";
    sel.depth_channel = "custom.depth";
    assert_int_equal(fp_exr_read_file(in, 10, &sel, &f), FP_OK);
    assert_string_equal(fp_frame_info(f)->color_names[0], "fog.R");
    assert_string_equal(fp_frame_info(f)->color_names[3], "");
    assert_string_equal(fp_frame_info(f)->depth_name, "custom.depth");
    assert_true(fp_frame_rgba(f)[0] == pget(EXR_PIXEL_HALF, im.g, 0));
    assert_true(fp_frame_depth(f)[77] == pget(EXR_PIXEL_UINT, im.id, 77));
    fp_frame_free(f);

    sel.color_layer = "nope";
    sel.depth_channel = NULL;
    cap_begin();
    int rc = fp_exr_read_file(in, 10, &sel, &f);
    const char *msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_contains(msg, "ovr_names.exr: frame 10: no color channels nope.R");

    sel.color_layer = NULL;
    sel.depth_channel = "nope.Z";
    cap_begin();
    rc = fp_exr_read_file(in, 10, &sel, &f);
    msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_contains(msg, "ovr_names.exr: frame 10: no depth channel 'nope.Z'");
    std_img_free(&im);
}

/* uint depth reads as float and passes through as uint. */
static void test_uint_depth(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char in[4200], out[4200];
    path_in(in, sizeof in, "uintz.exr");
    path_in(out, sizeof out, "uintz.out.exr");
    tpart_t tp;
    memset(&tp, 0, sizeof tp);
    tp.dw = tp.disp = box(0, 0, W0 - 1, H0 - 1);
    tp.compression = EXR_COMPRESSION_ZIP;
    tp.ch[0] = (tchan_t) { "R", EXR_PIXEL_HALF, 1, 1, im.r };
    tp.ch[1] = (tchan_t) { "G", EXR_PIXEL_HALF, 1, 1, im.g };
    tp.ch[2] = (tchan_t) { "B", EXR_PIXEL_HALF, 1, 1, im.b };
    tp.ch[3] = (tchan_t) { "depth.Z", EXR_PIXEL_UINT, 1, 1, im.id };
    tp.nch = 4;
    write_exr(in, &tp, 1);
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_file(in, 11, NULL, &f), FP_OK);
    assert_string_equal(fp_frame_info(f)->depth_name, "depth.Z");
    for (size_t i = 0; i < (size_t) W0 * H0; ++i)
        assert_true(fp_frame_depth(f)[i] == pget(EXR_PIXEL_UINT, im.id, i));
    assert_int_equal(fp_exr_write_file(f, NULL, NULL, out, 11), FP_OK);
    fp_frame_free(f);
    assert_same_chan(in, 0, out, 0, "depth.Z");
    std_img_free(&im);
}

/* x/y sub-sampled channels (chroma-style) pass through unchanged. */
static void test_subsampled_passthrough(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    void *sub = mkplane(EXR_PIXEL_HALF, W0 / 2, H0 / 2, 9);
    void *subx = mkplane(EXR_PIXEL_FLOAT, W0 / 4, H0, 10);
    char in[4200], out[4200];
    path_in(in, sizeof in, "sub.exr");
    path_in(out, sizeof out, "sub.out.exr");
    tpart_t tp = std_part(&im, EXR_COMPRESSION_ZIP, box(-8, 4, -8 + W0 - 1, 4 + H0 - 1),
                          box(0, 0, W0 - 1, H0 - 1), 1);
    tp.ch[tp.nch++] = (tchan_t) { "sub.C", EXR_PIXEL_HALF, 2, 2, sub };
    tp.ch[tp.nch++] = (tchan_t) { "sub.X", EXR_PIXEL_FLOAT, 4, 1, subx };
    write_exr(in, &tp, 1);
    /* the test reader agrees with what we wrote */
    int t;
    size_t n;
    void *chk = rd_chan(in, 0, "sub.C", &t, &n);
    assert_non_null(chk);
    assert_int_equal(n, (size_t) (W0 / 2) * (H0 / 2));
    assert_memory_equal(chk, sub, n * 2);
    free(chk);

    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_file(in, 12, NULL, &f), FP_OK);
    assert_int_equal(fp_exr_write_file(f, NULL, NULL, out, 12), FP_OK);
    fp_frame_free(f);
    assert_same_chan(in, 0, out, 0, "sub.C");
    assert_same_chan(in, 0, out, 0, "sub.X");
    assert_same_chan(in, 0, out, 0, "R");
    free(sub);
    free(subx);
    std_img_free(&im);
}

/* A depth-only file: colour optional; with rgba given, R,G,B,A written. */
static void test_no_color_input(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char in[4200], out[4200], out2[4200];
    path_in(in, sizeof in, "zonly.exr");
    path_in(out, sizeof out, "zonly.rgba.exr");
    path_in(out2, sizeof out2, "zonly.same.exr");
    tpart_t tp;
    memset(&tp, 0, sizeof tp);
    tp.dw = tp.disp = box(0, 0, W0 - 1, H0 - 1);
    tp.compression = EXR_COMPRESSION_ZIPS;
    tp.ch[0] = (tchan_t) { "Z", EXR_PIXEL_FLOAT, 1, 1, im.z };
    tp.nch = 1;
    write_exr(in, &tp, 1);

    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    fp_frame_t *f = NULL;
    cap_begin();
    int rc = fp_exr_read_file(in, 13, &sel, &f);
    const char *msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_contains(msg, "zonly.exr: frame 13: no color channels");

    sel.need_color = 0;
    assert_int_equal(fp_exr_read_file(in, 13, &sel, &f), FP_OK);
    assert_null(fp_frame_rgba(f));
    assert_non_null(fp_frame_depth(f));
    assert_int_equal(fp_exr_write_file(f, NULL, NULL, out2, 13), FP_OK);
    float *rgba = malloc(sizeof(float) * 4 * W0 * H0);
    assert_non_null(rgba);
    for (int i = 0; i < 4 * W0 * H0; ++i)
        rgba[i] = (float) (i % 7) * 0.25f;
    assert_int_equal(fp_exr_write_file(f, rgba, NULL, out, 13), FP_OK);
    fp_frame_free(f);
    assert_same_chan(in, 0, out2, 0, "Z");
    assert_same_chan(in, 0, out, 0, "Z");
    const char *cn[4] = { "R", "G", "B", "A" };
    for (int k = 0; k < 4; ++k) {
        int t;
        size_t n;
        void *d = rd_chan(out, 0, cn[k], &t, &n);
        assert_non_null(d);
        assert_int_equal(t, EXR_PIXEL_HALF);
        for (size_t i = 0; i < n; ++i)
            assert_true(pget(t, d, i) == rgba[i * 4 + (size_t) k]);
        free(d);
    }
    free(rgba);
    std_img_free(&im);
}

/* fp_frame_take_depth: same windows move the depth; others fail naming both. */
static void test_take_depth(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char cpath[4200], dpath[4200], bad[4200];
    path_in(cpath, sizeof cpath, "td_color.exr");
    path_in(dpath, sizeof dpath, "td_depth.exr");
    path_in(bad, sizeof bad, "td_small.exr");
    tpart_t tp;
    memset(&tp, 0, sizeof tp);
    tp.dw = tp.disp = box(0, 0, W0 - 1, H0 - 1);
    tp.ch[0] = (tchan_t) { "R", EXR_PIXEL_HALF, 1, 1, im.r };
    tp.ch[1] = (tchan_t) { "G", EXR_PIXEL_HALF, 1, 1, im.g };
    tp.ch[2] = (tchan_t) { "B", EXR_PIXEL_HALF, 1, 1, im.b };
    tp.nch = 3;
    write_exr(cpath, &tp, 1);
    tp.ch[0] = (tchan_t) { "Z", EXR_PIXEL_FLOAT, 1, 1, im.z };
    tp.nch = 1;
    write_exr(dpath, &tp, 1);
    tp.dw = box(0, 0, 31, 23);
    write_exr(bad, &tp, 1);

    fp_exr_select_t csel = FP_EXR_SELECT_INITIALIZER, dsel = FP_EXR_SELECT_INITIALIZER;
    csel.need_depth = 0;
    dsel.need_color = 0;
    fp_frame_t *c = NULL, *d = NULL, *s = NULL;
    assert_int_equal(fp_exr_read_file(cpath, 14, &csel, &c), FP_OK);
    assert_null(fp_frame_depth(c));
    assert_int_equal(fp_exr_read_file(dpath, 14, &dsel, &d), FP_OK);
    assert_int_equal(fp_exr_read_file(bad, 14, &dsel, &s), FP_OK);
    cap_begin();
    int rc = fp_frame_take_depth(c, cpath, s, bad, 14);
    const char *msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_contains(msg, "td_color.exr: frame 14:");
    assert_contains(msg, "td_small.exr");
    assert_contains(msg, "64x48");
    assert_contains(msg, "32x24");
    assert_null(fp_frame_depth(c));
    assert_int_equal(fp_frame_take_depth(c, cpath, d, dpath, 14), FP_OK);
    assert_null(fp_frame_depth(d));
    fp_frame_free(d);
    fp_frame_free(s);
    assert_true(fp_frame_depth(c)[5] == pget(EXR_PIXEL_FLOAT, im.z, 5));
    assert_string_equal(fp_frame_info(c)->depth_name, "Z");
    fp_frame_free(c);
    std_img_free(&im);
}

/* ------------------------------------------------------------ stream framing */

/* --- a byte builder for hand-made files */
typedef struct bytes_t {
    uint8_t *p;
    size_t n, cap;
} bytes_t;

static void put(bytes_t *b, const void *d, size_t n)
{
    if (b->n + n > b->cap) {
        b->cap = (b->n + n) * 2 + 256;
        b->p = realloc(b->p, b->cap);
        assert_non_null(b->p);
    }
    memcpy(b->p + b->n, d, n);
    b->n += n;
}

static void put_i32(bytes_t *b, int32_t v)
{
    uint8_t le[4] = { (uint8_t) v, (uint8_t) (v >> 8), (uint8_t) (v >> 16),
                      (uint8_t) ((uint32_t) v >> 24) };
    put(b, le, 4);
}

static void put_f32(bytes_t *b, float f)
{
    int32_t v;
    memcpy(&v, &f, 4);
    put_i32(b, v);
}

static void put_attr(bytes_t *b, const char *name, const char *type, int32_t size)
{
    put(b, name, strlen(name) + 1);
    put(b, type, strlen(type) + 1);
    put_i32(b, size);
}

static int lvl_count(int n, int up)
{
    int l = 0, odd = 0;
    while (n > 1) {
        odd |= n & 1;
        n >>= 1;
        l++;
    }
    return l + (up ? odd : 0) + 1;
}

static int lvl_size(int n, int l, int up)
{
    int s = n >> l;
    if (up && (s << l) < n)
        s++;
    return s < 1 ? 1 : s;
}

/* A RIPMAP-tiled file built byte by byte, uncompressed (OpenEXR 3.1's C
 * writer numbers ripmap chunks wrongly, so it cannot make one): float
 * channels B,G,R,Z, level 0 from `planes` (order R,G,B,Z), every other
 * level from the same planes, sub-sampled. */
static uint8_t *craft_ripmap(size_t *size, int w, int h, int tw, int th,
                             int up, float *const planes[4])
{
    bytes_t b = { NULL, 0, 0 };
    static const char *names[4] = { "B", "G", "R", "Z" };
    static const int src[4] = { 2, 1, 0, 3 };
    put_i32(&b, 20000630);
    put_i32(&b, 2 | 0x200);
    put_attr(&b, "channels", "chlist", 4 * (2 + 16) + 1);
    for (int c = 0; c < 4; ++c) {
        put(&b, names[c], 2);
        put_i32(&b, EXR_PIXEL_FLOAT);
        put_i32(&b, 0); /* pLinear + reserved */
        put_i32(&b, 1);
        put_i32(&b, 1);
    }
    put(&b, "", 1);
    put_attr(&b, "compression", "compression", 1);
    put(&b, "", 1);
    put_attr(&b, "dataWindow", "box2i", 16);
    put_i32(&b, 0);
    put_i32(&b, 0);
    put_i32(&b, w - 1);
    put_i32(&b, h - 1);
    put_attr(&b, "displayWindow", "box2i", 16);
    put_i32(&b, 0);
    put_i32(&b, 0);
    put_i32(&b, w - 1);
    put_i32(&b, h - 1);
    put_attr(&b, "lineOrder", "lineOrder", 1);
    put(&b, "", 1);
    put_attr(&b, "pixelAspectRatio", "float", 4);
    put_f32(&b, 1.0f);
    put_attr(&b, "screenWindowCenter", "v2f", 8);
    put_f32(&b, 0.0f);
    put_f32(&b, 0.0f);
    put_attr(&b, "screenWindowWidth", "float", 4);
    put_f32(&b, 1.0f);
    put_attr(&b, "tiles", "tiledesc", 9);
    put_i32(&b, tw);
    put_i32(&b, th);
    uint8_t mode = (uint8_t) (EXR_TILE_RIPMAP_LEVELS | (up ? 0x10 : 0));
    put(&b, &mode, 1);
    put(&b, "", 1);

    int nlx = lvl_count(w, up), nly = lvl_count(h, up);
    int nchunks = 0;
    for (int ly = 0; ly < nly; ++ly)
        for (int lx = 0; lx < nlx; ++lx)
            nchunks += ((lvl_size(w, lx, up) + tw - 1) / tw) *
                       ((lvl_size(h, ly, up) + th - 1) / th);
    size_t table = b.n;
    for (int i = 0; i < nchunks; ++i) {
        put_i32(&b, 0);
        put_i32(&b, 0);
    }
    int k = 0;
    for (int ly = 0; ly < nly; ++ly)
        for (int lx = 0; lx < nlx; ++lx) {
            int lw = lvl_size(w, lx, up), lh = lvl_size(h, ly, up);
            for (int ty = 0; ty < (lh + th - 1) / th; ++ty)
                for (int tx = 0; tx < (lw + tw - 1) / tw; ++tx) {
                    uint64_t off = b.n;
                    for (int i = 0; i < 8; ++i)
                        b.p[table + (size_t) k * 8 + (size_t) i] = (uint8_t) (off >> (8 * i));
                    k++;
                    int cw = lw - tx * tw < tw ? lw - tx * tw : tw;
                    int ch = lh - ty * th < th ? lh - ty * th : th;
                    put_i32(&b, tx);
                    put_i32(&b, ty);
                    put_i32(&b, lx);
                    put_i32(&b, ly);
                    put_i32(&b, cw * ch * 4 * 4);
                    for (int y = 0; y < ch; ++y)
                        for (int c = 0; c < 4; ++c)
                            for (int x = 0; x < cw; ++x) {
                                int sx = (tx * tw + x) << lx, sy = (ty * th + y) << ly;
                                if (sx >= w)
                                    sx = w - 1;
                                if (sy >= h)
                                    sy = h - 1;
                                put_f32(&b, planes[src[c]][(size_t) sy * w + sx]);
                            }
                }
        }
    *size = b.n;
    return b.p;
}

#define NSTREAM 5

/* Five frames: scanline, tiled, multipart (scanline + mipmapped tiles),
 * mipmapped single part (no chunkCount: counted from the header), and a
 * hand-made ripmap.  Returns them concatenated. */
static uint8_t *make_stream_files(size_t sizes[NSTREAM], std_img_t *im,
                                  float *rip_planes[4])
{
    char p[NSTREAM][4200];
    const char *names[NSTREAM] = { "s_scan.exr", "s_tiled.exr", "s_multi.exr",
                                   "s_mip.exr", "s_rip.exr" };
    for (int i = 0; i < NSTREAM; ++i)
        path_in(p[i], sizeof p[i], names[i]);
    tpart_t tp = std_part(im, EXR_COMPRESSION_PIZ, box(2, 1, 2 + W0 - 1, 1 + H0 - 1),
                          box(0, 0, W0 + 3, H0 + 3), 1);
    write_exr(p[0], &tp, 1);
    tp.compression = EXR_COMPRESSION_ZIP;
    tp.tiled = 1;
    tp.tw = 24;
    tp.th = 20;
    write_exr(p[1], &tp, 1);
    tpart_t mp[2];
    /* the parts share their display window, as OpenEXR requires: its C++
     * library, which decodes float B44, refuses parts that differ */
    mp[0] = std_part(im, EXR_COMPRESSION_B44A, box(0, 0, W0 - 1, H0 - 1),
                     box(0, 0, W0 + 3, H0 + 3), 1);
    mp[0].name = "a";
    mp[1] = tp;
    mp[1].name = "b";
    mp[1].level_mode = EXR_TILE_MIPMAP_LEVELS;
    mp[1].round_mode = EXR_TILE_ROUND_UP;
    write_exr(p[2], mp, 2);
    tp.level_mode = EXR_TILE_MIPMAP_LEVELS;
    tp.round_mode = EXR_TILE_ROUND_DOWN;
    tp.compression = EXR_COMPRESSION_PXR24;
    write_exr(p[3], &tp, 1);

    for (int c = 0; c < 4; ++c) {
        rip_planes[c] = malloc(sizeof(float) * W0 * H0);
        assert_non_null(rip_planes[c]);
        for (int i = 0; i < W0 * H0; ++i)
            rip_planes[c][i] = (float) (i % W0) * 0.01f + (float) (i / W0) * 0.1f + (float) c;
    }
    size_t rsize;
    uint8_t *rip = craft_ripmap(&rsize, W0, H0, 16, 16, 1, rip_planes);
    spit_file(p[4], rip, rsize);
    free(rip);

    size_t total = 0;
    uint8_t *bufs[NSTREAM];
    for (int i = 0; i < NSTREAM; ++i) {
        bufs[i] = slurp_file(p[i], &sizes[i]);
        total += sizes[i];
    }
    uint8_t *all = malloc(total);
    assert_non_null(all);
    size_t at = 0;
    for (int i = 0; i < NSTREAM; ++i) {
        memcpy(all + at, bufs[i], sizes[i]);
        at += sizes[i];
        free(bufs[i]);
    }
    return all;
}

static void free_planes(float *planes[4])
{
    for (int c = 0; c < 4; ++c)
        free(planes[c]);
}

typedef struct pipe_feed_t {
    int fd;
    const uint8_t *data;
    size_t n;
    int ok;
} pipe_feed_t;

/* Writes in small pieces, as a producer on the other end of stdin would. */
static void *pipe_feeder(void *arg)
{
    pipe_feed_t *pf = arg;
    size_t off = 0;
    while (off < pf->n) {
        ssize_t w = write(pf->fd, pf->data + off, pf->n - off > 1000 ? 1000 : pf->n - off);
        if (w <= 0)
            break;
        off += (size_t) w;
    }
    close(pf->fd);
    pf->ok = off == pf->n;
    return NULL;
}

static void test_stream_frames(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    size_t sizes[NSTREAM];
    float *rip[4];
    uint8_t *all = make_stream_files(sizes, &im, rip);
    size_t total = 0;
    for (int i = 0; i < NSTREAM; ++i)
        total += sizes[i];

    /* one frame */
    FILE *in = fmemopen(all, sizes[0], "rb");
    assert_non_null(in);
    void *buf;
    size_t size;
    assert_int_equal(fp_exr_stream_next(in, "<stdin>", 0, &buf, &size), FP_OK);
    assert_int_equal(size, sizes[0]);
    assert_memory_equal(buf, all, size);
    free(buf);
    assert_int_equal(fp_exr_stream_next(in, "<stdin>", 1, &buf, &size), FP_EOF);
    assert_null(buf);
    fclose(in);

    /* all back to back: scanline, tiled, multipart, mipmap, ripmap */
    in = fmemopen(all, total, "rb");
    assert_non_null(in);
    size_t at = 0;
    for (int i = 0; i < NSTREAM; ++i) {
        assert_int_equal(fp_exr_stream_next(in, "<stdin>", i, &buf, &size), FP_OK);
        assert_int_equal(size, sizes[i]);
        assert_memory_equal(buf, all + at, size);
        at += size;
        /* and the frame decodes from memory */
        fp_frame_t *f = NULL;
        assert_int_equal(fp_exr_read_memory(buf, size, "<stdin>", i, NULL, &f), FP_OK);
        assert_int_equal(fp_frame_info(f)->width, W0);
        assert_int_equal(fp_frame_info(f)->num_parts, i == 2 ? 2 : 1);
        if (i == NSTREAM - 1) {
            /* the ripmap's level 0 is what we read */
            const float *rgba = fp_frame_rgba(f), *z = fp_frame_depth(f);
            for (size_t j = 0; j < (size_t) W0 * H0; ++j) {
                assert_true(rgba[j * 4 + 0] == rip[0][j]);
                assert_true(rgba[j * 4 + 2] == rip[2][j]);
                assert_true(rgba[j * 4 + 3] == 1.0f);
                assert_true(z[j] == rip[3][j]);
            }
        }
        fp_frame_free(f);
    }
    assert_int_equal(fp_exr_stream_next(in, "<stdin>", NSTREAM, &buf, &size), FP_EOF);
    assert_int_equal(fp_exr_stream_next(in, "<stdin>", NSTREAM, &buf, &size), FP_EOF);
    fclose(in);

    /* through a pipe, which cannot seek: three frames then the end */
    int fds[2];
    assert_int_equal(pipe(fds), 0);
    pipe_feed_t feed = { fds[1], all, sizes[0] + sizes[1] + sizes[2], 0 };
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, pipe_feeder, &feed), 0);
    in = fdopen(fds[0], "rb");
    assert_non_null(in);
    at = 0;
    for (int i = 0; i < 3; ++i) {
        assert_int_equal(fp_exr_stream_next(in, "<stdin>", i, &buf, &size), FP_OK);
        assert_int_equal(size, sizes[i]);
        assert_memory_equal(buf, all + at, size);
        at += size;
        free(buf);
    }
    assert_int_equal(fp_exr_stream_next(in, "<stdin>", 3, &buf, &size), FP_EOF);
    fclose(in);
    assert_int_equal(pthread_join(th, NULL), 0);
    assert_int_equal(feed.ok, 1);

    /* empty stream */
    in = fmemopen(all, 0, "rb");
    if (in) { /* glibc's fmemopen accepts size 0 since 2.22 */
        assert_int_equal(fp_exr_stream_next(in, "<stdin>", 0, &buf, &size), FP_EOF);
        fclose(in);
    }
    free(all);
    free_planes(rip);
    std_img_free(&im);
}

/* Where the first chunk starts: the end of the offset table. */
static size_t first_chunk_offset(const char *path)
{
    exr_context_t c = open_hdr(path);
    exr_chunk_info_t ci;
    assert_int_equal(exr_read_scanline_chunk_info(c, 0, 1, &ci), 0);
    exr_finish(&c);
    return (size_t) ci.data_offset - 8; /* y and size precede the data */
}

static void expect_stream_error(const uint8_t *data, size_t n, const char *what,
                                long index)
{
    FILE *in = fmemopen((void *) data, n, "rb");
    assert_non_null(in);
    void *buf = (void *) 1;
    size_t size;
    cap_begin();
    int rc = fp_exr_stream_next(in, "<stdin>", index, &buf, &size);
    const char *msg = cap_end();
    fclose(in);
    if (rc != FP_ERR)
        fail_msg("cut at %zu: expected FP_ERR, got %d", n, rc);
    assert_null(buf);
    char label[64];
    snprintf(label, sizeof label, "<stdin>: frame %ld:", index);
    assert_contains(msg, label);
    assert_contains(msg, what);
}

static void test_stream_errors(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    size_t sizes[NSTREAM];
    float *rip[4];
    uint8_t *all = make_stream_files(sizes, &im, rip);
    free_planes(rip);
    char p0[4200];
    path_in(p0, sizeof p0, "s_scan.exr");
    size_t table_end = first_chunk_offset(p0);
    assert_true(table_end > 100 && table_end < sizes[0]);

    expect_stream_error(all, 2, "truncated EXR stream", 3);            /* magic */
    expect_stream_error(all, 40, "truncated EXR stream", 3);           /* header */
    expect_stream_error(all, 40, "in the header", 3);
    expect_stream_error(all, table_end - 3, "in the offset table", 3); /* table */
    expect_stream_error(all, table_end + 5, "in the chunk data", 3);   /* chunk */
    expect_stream_error(all, sizes[0] - 1, "expected 1 more bytes", 3); /* last */
    /* every cut of a multipart tiled frame fails cleanly */
    const uint8_t *mp = all + sizes[0] + sizes[1];
    for (size_t cut = 1; cut < sizes[2]; cut += 97)
        expect_stream_error(mp, cut, "truncated EXR stream", 4);

    const char garbage[] = "this is certainly not an OpenEXR file, just text\n";
    expect_stream_error((const uint8_t *) garbage, sizeof garbage - 1,
                        "not an EXR file (bad magic number)", 5);

    /* a good frame followed by garbage: the frame, then the error */
    size_t n = sizes[0] + sizeof garbage - 1;
    uint8_t *mix = malloc(n);
    assert_non_null(mix);
    memcpy(mix, all, sizes[0]);
    memcpy(mix + sizes[0], garbage, sizeof garbage - 1);
    FILE *in = fmemopen(mix, n, "rb");
    void *buf;
    size_t size;
    assert_int_equal(fp_exr_stream_next(in, "<stdin>", 0, &buf, &size), FP_OK);
    free(buf);
    cap_begin();
    int rc = fp_exr_stream_next(in, "<stdin>", 1, &buf, &size);
    const char *msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_contains(msg, "<stdin>: frame 1: not an EXR file");
    fclose(in);

    /* deep flag in the version field */
    memcpy(mix, all, sizes[0]);
    mix[5] |= 0x08;
    expect_stream_error(mix, sizes[0], "deep", 6);
    /* an absurd attribute size */
    memcpy(mix, all, sizes[0]);
    /* first attribute: name at 8, then its type, then its size */
    size_t q = 8 + strlen((char *) mix + 8) + 1;
    q += strlen((char *) mix + q) + 1;
    mix[q + 3] = 0x7f;
    expect_stream_error(mix, sizes[0], "corrupt EXR header", 7);
    free(mix);
    free(all);
    std_img_free(&im);
}

/* ------------------------------------------------------------ error paths */

static void test_read_errors(void **state)
{
    (void) state;
    char missing[4200], text[4200], trunc[4200], src[4200];
    path_in(missing, sizeof missing, "no_such_file.exr");
    path_in(text, sizeof text, "text.exr");
    path_in(trunc, sizeof trunc, "trunc.exr");
    path_in(src, sizeof src, "trunc_src.exr");
    fp_frame_t *f = (fp_frame_t *) 1;

    cap_begin();
    int rc = fp_exr_read_file(missing, 21, NULL, &f);
    const char *msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_null(f);
    assert_contains(msg, "no_such_file.exr: frame 21: cannot read (No such file");

    spit_file(text, "hello, world: not an image\n", 27);
    cap_begin();
    rc = fp_exr_read_file(text, 22, NULL, &f);
    msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_contains(msg, "text.exr: frame 22: not an EXR file (bad magic number)");

    spit_file(text, "", 0);
    cap_begin();
    rc = fp_exr_read_file(text, 22, NULL, &f);
    msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_contains(msg, "not an EXR file");

    /* truncated anywhere: a clean error naming file and frame */
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    tpart_t tp = std_part(&im, EXR_COMPRESSION_ZIP, box(0, 0, W0 - 1, H0 - 1),
                          box(0, 0, W0 - 1, H0 - 1), 1);
    write_exr(src, &tp, 1);
    tp.tiled = 1;
    tp.tw = tp.th = 16;
    char src2[4200];
    path_in(src2, sizeof src2, "trunc_src_tiled.exr");
    write_exr(src2, &tp, 1);
    const char *srcs[2] = { src, src2 };
    for (int s = 0; s < 2; ++s) {
        size_t size;
        uint8_t *all = slurp_file(srcs[s], &size);
        for (size_t cut = 8; cut < size; cut += 53) {
            spit_file(trunc, all, cut);
            f = NULL;
            cap_begin();
            rc = fp_exr_read_file(trunc, 23, NULL, &f);
            msg = cap_end();
            if (rc != FP_ERR)
                fail_msg("cut at %zu of %zu: read succeeded", cut, size);
            assert_null(f);
            assert_contains(msg, "trunc.exr: frame 23: ");
            /* one line: the library printed nothing of its own */
            assert_ptr_equal(strchr(msg, '\n'), msg + strlen(msg) - 1);
        }
        free(all);
    }

    /* no depth where it is needed */
    tpart_t rgb;
    memset(&rgb, 0, sizeof rgb);
    rgb.dw = rgb.disp = box(0, 0, W0 - 1, H0 - 1);
    rgb.ch[0] = (tchan_t) { "R", EXR_PIXEL_HALF, 1, 1, im.r };
    rgb.ch[1] = (tchan_t) { "G", EXR_PIXEL_HALF, 1, 1, im.g };
    rgb.ch[2] = (tchan_t) { "B", EXR_PIXEL_HALF, 1, 1, im.b };
    rgb.nch = 3;
    char nod[4200];
    path_in(nod, sizeof nod, "shot.0012.exr");
    write_exr(nod, &rgb, 1);
    cap_begin();
    rc = fp_exr_read_file(nod, 12, NULL, &f);
    msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_contains(msg, "shot.0012.exr: frame 12: no depth channel (looked for Z, "
                         "depth.Z, *.Depth.Z; use --depth-channel)");
    std_img_free(&im);
}

/* A deep scanline file, by hand: 4x2, one float channel Z, no samples. */
static uint8_t *craft_deep(size_t *size)
{
    bytes_t b = { NULL, 0, 0 };
    put_i32(&b, 20000630);
    put_i32(&b, 2 | 0x800);
    put_attr(&b, "channels", "chlist", 2 + 16 + 1);
    put(&b, "Z", 2);
    put_i32(&b, EXR_PIXEL_FLOAT);
    put_i32(&b, 0);
    put_i32(&b, 1);
    put_i32(&b, 1);
    put(&b, "", 1);
    put_attr(&b, "compression", "compression", 1);
    put(&b, "", 1);
    put_attr(&b, "dataWindow", "box2i", 16);
    put_i32(&b, 0);
    put_i32(&b, 0);
    put_i32(&b, 3);
    put_i32(&b, 1);
    put_attr(&b, "displayWindow", "box2i", 16);
    put_i32(&b, 0);
    put_i32(&b, 0);
    put_i32(&b, 3);
    put_i32(&b, 1);
    put_attr(&b, "lineOrder", "lineOrder", 1);
    put(&b, "", 1);
    put_attr(&b, "pixelAspectRatio", "float", 4);
    put_f32(&b, 1.0f);
    put_attr(&b, "screenWindowCenter", "v2f", 8);
    put_f32(&b, 0.0f);
    put_f32(&b, 0.0f);
    put_attr(&b, "screenWindowWidth", "float", 4);
    put_f32(&b, 1.0f);
    put_attr(&b, "type", "string", 12);
    put(&b, "deepscanline", 12);
    put_attr(&b, "version", "int", 4);
    put_i32(&b, 1);
    put_attr(&b, "chunkCount", "int", 4);
    put_i32(&b, 2);
    put(&b, "", 1);
    size_t table = b.n;
    for (int i = 0; i < 4; ++i)
        put_i32(&b, 0);
    for (int y = 0; y < 2; ++y) {
        uint64_t off = b.n;
        for (int i = 0; i < 8; ++i)
            b.p[table + (size_t) y * 8 + (size_t) i] = (uint8_t) (off >> (8 * i));
        put_i32(&b, y);
        put_i32(&b, 16); /* sample count table: 4 cumulative int32 */
        put_i32(&b, 0);
        put_i32(&b, 0); /* packed data */
        put_i32(&b, 0);
        put_i32(&b, 0); /* unpacked data */
        put_i32(&b, 0);
        for (int x = 0; x < 4; ++x)
            put_i32(&b, 0);
    }
    *size = b.n;
    return b.p;
}

static void test_deep_input(void **state)
{
    (void) state;
    size_t size;
    uint8_t *deep = craft_deep(&size);
    char path[4200];
    path_in(path, sizeof path, "deep.exr");
    spit_file(path, deep, size);

    fp_frame_t *f = NULL;
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    sel.need_color = 0;
    cap_begin();
    int rc = fp_exr_read_file(path, 41, &sel, &f);
    const char *msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_null(f);
    assert_contains(msg, "deep.exr: frame 41: ");
    assert_contains(msg, "deep");

    /* a stream frames deep scanline files whole (--deep reads them) */
    FILE *in = fmemopen(deep, size, "rb");
    assert_non_null(in);
    void *buf = NULL;
    size_t got = 0;
    assert_int_equal(fp_exr_stream_next(in, "<stdin>", 41, &buf, &got), FP_OK);
    assert_int_equal(got, size);
    assert_memory_equal(buf, deep, size);
    free(buf);
    fclose(in);
    free(deep);
}

static void test_write_errors(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char in[4200], bad[4200], dir[4200], good[4200];
    path_in(in, sizeof in, "w.exr");
    path_in(dir, sizeof dir, "no_such_dir");
    path_in(bad, sizeof bad, "no_such_dir/out.0001.exr");
    path_in(good, sizeof good, "w.out.exr");
    tpart_t tp = std_part(&im, EXR_COMPRESSION_ZIP, box(0, 0, W0 - 1, H0 - 1),
                          box(0, 0, W0 - 1, H0 - 1), 1);
    write_exr(in, &tp, 1);
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_file(in, 31, NULL, &f), FP_OK);

    cap_begin();
    int rc = fp_exr_write_file(f, NULL, NULL, bad, 31);
    const char *msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_contains(msg, "no_such_dir/out.0001.exr: frame 31: cannot write (No such file");
    struct stat st;
    assert_int_not_equal(stat(dir, &st), 0);
    assert_no_temporaries();

    /* a directory in the way of the rename: the temporary is removed */
    char blocker[4200];
    path_in(blocker, sizeof blocker, "blocker.exr");
    assert_int_equal(mkdir(blocker, 0755), 0);
    char inner[4300];
    snprintf(inner, sizeof inner, "%s/x", blocker);
    spit_file(inner, "x", 1);
    cap_begin();
    rc = fp_exr_write_file(f, NULL, NULL, blocker, 31);
    msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_contains(msg, "blocker.exr: frame 31: ");
    assert_no_temporaries();
    unlink(inner);
    rmdir(blocker);

    /* an existing file is replaced whole */
    spit_file(good, "old contents", 12);
    assert_int_equal(fp_exr_write_file(f, NULL, NULL, good, 31), FP_OK);
    assert_no_temporaries();
    assert_same_chan(in, 0, good, 0, "R");

    /* encode to memory = file contents */
    void *mem;
    size_t msize, fsize;
    assert_int_equal(fp_exr_encode(f, NULL, NULL, "<stdout>", 31, &mem, &msize), FP_OK);
    uint8_t *fb = slurp_file(good, &fsize);
    assert_int_equal(msize, fsize);
    assert_memory_equal(mem, fb, msize);
    free(mem);
    free(fb);

    /* plain atomic write */
    char plain[4200];
    path_in(plain, sizeof plain, "plain.bin");
    assert_int_equal(fp_write_file_atomic(plain, "abc", 3), FP_OK);
    size_t ps;
    uint8_t *pb = slurp_file(plain, &ps);
    assert_int_equal(ps, 3);
    assert_memory_equal(pb, "abc", 3);
    free(pb);
    cap_begin();
    rc = fp_write_file_atomic(bad, "abc", 3);
    msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_contains(msg, "out.0001.exr: cannot write (");
    assert_no_temporaries();

    fp_frame_free(f);
    std_img_free(&im);
}

typedef struct worker_t {
    const char *good, *bad;
    const uint8_t *ref;
    size_t ref_size;
    int failures;
} worker_t;

/* Read, encode and compare; read a broken file too, so that library
 * messages are produced on several threads at once. */
static void *worker(void *arg)
{
    worker_t *wk = arg;
    for (int i = 0; i < 6; ++i) {
        fp_frame_t *f = NULL;
        void *buf = NULL;
        size_t size = 0;
        if (fp_exr_read_file(wk->good, i, NULL, &f) != FP_OK ||
            fp_exr_encode(f, NULL, NULL, "<stdout>", i, &buf, &size) != FP_OK ||
            size != wk->ref_size || memcmp(buf, wk->ref, size) != 0)
            wk->failures++;
        free(buf);
        fp_frame_free(f);
        f = NULL;
        if (fp_exr_read_file(wk->bad, i, NULL, &f) != FP_ERR || f)
            wk->failures++;
    }
    return NULL;
}

/* Different frames on different threads at once give the same bytes as
 * one thread does: no shared per-frame state. */
static void test_threads(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char good[4200], bad[4200];
    path_in(good, sizeof good, "thr.exr");
    path_in(bad, sizeof bad, "thr_bad.exr");
    tpart_t tp = std_part(&im, EXR_COMPRESSION_PIZ, box(0, 0, W0 - 1, H0 - 1),
                          box(0, 0, W0 - 1, H0 - 1), 1);
    write_exr(good, &tp, 1);
    size_t gsize;
    uint8_t *g = slurp_file(good, &gsize);
    spit_file(bad, g, gsize - 100); /* cut inside the last chunks */
    free(g);

    fp_frame_t *f = NULL;
    void *ref = NULL;
    size_t ref_size = 0;
    assert_int_equal(fp_exr_read_file(good, 0, NULL, &f), FP_OK);
    assert_int_equal(fp_exr_encode(f, NULL, NULL, "<stdout>", 0, &ref, &ref_size), FP_OK);
    fp_frame_free(f);

    worker_t wk[4];
    pthread_t th[4];
    cap_begin();
    for (int i = 0; i < 4; ++i) {
        wk[i] = (worker_t) { good, bad, ref, ref_size, 0 };
        assert_int_equal(pthread_create(&th[i], NULL, worker, &wk[i]), 0);
    }
    for (int i = 0; i < 4; ++i)
        assert_int_equal(pthread_join(th[i], NULL), 0);
    const char *msg = cap_end();
    for (int i = 0; i < 4; ++i)
        assert_int_equal(wk[i].failures, 0);
    /* 24 failed reads, each one whole line naming the file */
    int lines = 0;
    for (const char *q = msg; (q = strstr(q, "thr_bad.exr: frame ")); ++q)
        lines++;
    assert_int_equal(lines, 24);
    free(ref);
    std_img_free(&im);
}

/* ------------------------------------------------------------ long names */

/* Names of 32 to 255 characters as Cycles writes them (through
 * OpenImageIO): cycles.<ViewLayer>.<stat> attributes, and the channels of a
 * view layer with a long name. */
#define LONG_LAYER_LEN 230
static char long_layer[LONG_LAYER_LEN + 1];
static char long_chan[5][LONG_LAYER_LEN + 16];
static char long_attr255[256];

static void long_names_init(void)
{
    static const char *const suffix[5] = { ".Combined.R", ".Combined.G",
                                           ".Combined.B", ".Combined.A",
                                           ".Depth.Z" };
    for (int i = 0; i < LONG_LAYER_LEN; ++i)
        long_layer[i] = (char) ('a' + i % 26);
    long_layer[LONG_LAYER_LEN] = '\0';
    for (int k = 0; k < 5; ++k)
        snprintf(long_chan[k], sizeof long_chan[k], "%s%s", long_layer, suffix[k]);
    memcpy(long_attr255, "cycles.", 7);
    for (int i = 7; i < 255; ++i)
        long_attr255[i] = (char) ('A' + i % 26);
    long_attr255[255] = '\0';
}

static void add_long_attrs(exr_context_t c, int p)
{
    assert_int_equal(exr_attr_set_string(c, p, "cycles.ViewLayer.synchronization_time",
                                         "00:00.02"), 0);
    assert_int_equal(exr_attr_set_string(c, p, "cycles.ViewLayer.total_time.x32",
                                         "32 characters"), 0);
    assert_int_equal(exr_attr_set_int(c, p, "cycles.ViewLayer.samples", 128), 0);
    assert_int_equal(exr_attr_set_string(c, p, long_attr255, "255 characters"), 0);
}

/* The long names, byte for byte, in a file's header. */
static void assert_long_names(const char *path, const char *what)
{
    exr_context_t c = open_hdr(path);
    const char *s;
    int32_t len;
    if (exr_attr_get_string(c, 0, "cycles.ViewLayer.synchronization_time", &len, &s))
        fail_msg("%s: no cycles.ViewLayer.synchronization_time", what);
    assert_string_equal(s, "00:00.02");
    assert_int_equal(exr_attr_get_string(c, 0, "cycles.ViewLayer.total_time.x32", &len, &s), 0);
    assert_int_equal(strlen("cycles.ViewLayer.total_time.x32"), 31);
    assert_string_equal(s, "32 characters");
    int32_t iv;
    assert_int_equal(exr_attr_get_int(c, 0, "cycles.ViewLayer.samples", &iv), 0);
    assert_int_equal(iv, 128);
    assert_int_equal(exr_attr_get_string(c, 0, long_attr255, &len, &s), 0);
    assert_string_equal(s, "255 characters");
    const exr_attr_chlist_t *cl;
    assert_int_equal(exr_get_channels(c, 0, &cl), 0);
    int found = 0;
    for (int i = 0; i < cl->num_channels; ++i)
        for (int k = 0; k < 5; ++k)
            if (strcmp(cl->entries[i].name.str, long_chan[k]) == 0 &&
                cl->entries[i].name.length == (int32_t) strlen(long_chan[k]))
                found++;
    if (found != 5)
        fail_msg("%s: %d of the 5 long channel names", what, found);
    exr_finish(&c);
    /* the long-names flag (bit 10 of the version field) is set */
    size_t n;
    uint8_t *b = slurp_file(path, &n);
    assert_true(n > 8);
    assert_true(b[5] & 0x04);
    free(b);
}

static void test_long_names(void **state)
{
    (void) state;
    long_names_init();
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char in[4200], out[4200], sout[4200];
    path_in(in, sizeof in, "long.exr");
    path_in(out, sizeof out, "long.out.exr");
    path_in(sout, sizeof sout, "long.stream.out.exr");
    tpart_t tp;
    memset(&tp, 0, sizeof tp);
    tp.dw = tp.disp = box(0, 0, W0 - 1, H0 - 1);
    tp.compression = EXR_COMPRESSION_ZIP;
    tp.lineorder = EXR_LINEORDER_INCREASING_Y;
    tp.ch[0] = (tchan_t) { long_chan[0], EXR_PIXEL_HALF, 1, 1, im.r };
    tp.ch[1] = (tchan_t) { long_chan[1], EXR_PIXEL_HALF, 1, 1, im.g };
    tp.ch[2] = (tchan_t) { long_chan[2], EXR_PIXEL_HALF, 1, 1, im.b };
    tp.ch[3] = (tchan_t) { long_chan[3], EXR_PIXEL_HALF, 1, 1, im.a };
    tp.ch[4] = (tchan_t) { long_chan[4], EXR_PIXEL_FLOAT, 1, 1, im.z };
    tp.nch = 5;
    tp.attrs = add_long_attrs;
    tw_long_names = 1;
    write_exr(in, &tp, 1);
    tw_long_names = 0;
    assert_long_names(in, "input");

    /* file in, file out: colour and depth found in the long-named layer */
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_file(in, 1, NULL, &f), FP_OK);
    assert_string_equal(fp_frame_info(f)->color_names[0], long_chan[0]);
    assert_string_equal(fp_frame_info(f)->depth_name, long_chan[4]);
    assert_int_equal(fp_exr_write_file(f, NULL, NULL, out, 1), FP_OK);
    fp_frame_free(f);
    assert_long_names(out, "file output");
    assert_same_chan(in, 0, out, 0, long_chan[4]);

    /* a stream of two such frames: framed, decoded and written the same */
    size_t n;
    uint8_t *one = slurp_file(in, &n);
    uint8_t *two = malloc(2 * n);
    assert_non_null(two);
    memcpy(two, one, n);
    memcpy(two + n, one, n);
    FILE *sin = fmemopen(two, 2 * n, "rb");
    assert_non_null(sin);
    for (int i = 0; i < 2; ++i) {
        void *buf;
        size_t size;
        assert_int_equal(fp_exr_stream_next(sin, "<stdin>", i + 1, &buf, &size), FP_OK);
        assert_int_equal(size, n);
        assert_memory_equal(buf, one, n);
        assert_int_equal(fp_exr_read_memory(buf, size, "<stdin>", i + 1, NULL, &f), FP_OK);
        void *enc;
        size_t enc_size;
        assert_int_equal(fp_exr_encode(f, NULL, NULL, "<stdout>", i + 1, &enc, &enc_size),
                         FP_OK);
        fp_frame_free(f);
        spit_file(sout, enc, enc_size);
        free(enc);
        assert_long_names(sout, "stream output");
        size_t fn, sn;
        uint8_t *fb = slurp_file(out, &fn);
        uint8_t *sb = slurp_file(sout, &sn);
        assert_int_equal(fn, sn);
        assert_memory_equal(fb, sb, sn); /* the same bytes as file mode */
        free(fb);
        free(sb);
    }
    fclose(sin);
    free(two);
    free(one);

    /* short names only: no long-names flag in the output */
    path_in(in, sizeof in, "short.exr");
    tpart_t sp = std_part(&im, EXR_COMPRESSION_ZIP, box(0, 0, W0 - 1, H0 - 1),
                          box(0, 0, W0 - 1, H0 - 1), 1);
    write_exr(in, &sp, 1);
    assert_int_equal(fp_exr_read_file(in, 1, NULL, &f), FP_OK);
    assert_int_equal(fp_exr_write_file(f, NULL, NULL, out, 1), FP_OK);
    fp_frame_free(f);
    uint8_t *b = slurp_file(out, &n);
    assert_false(b[5] & 0x04);
    free(b);
    std_img_free(&im);
}

/* ------------------------------------------------------------ line order, enums */

/* Decreasing line order in: the output declares increasing (the order its
 * chunks are in) and holds the same pixels. */
static void test_lineorder_decreasing(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char in[4200], out[4200];
    path_in(in, sizeof in, "dec.exr");
    path_in(out, sizeof out, "dec.out.exr");
    static const int comps[] = { EXR_COMPRESSION_NONE, EXR_COMPRESSION_ZIP,
                                 EXR_COMPRESSION_PIZ };
    for (size_t k = 0; k < sizeof comps / sizeof comps[0]; ++k) {
        tpart_t tp = std_part(&im, comps[k], box(0, 0, W0 - 1, H0 - 1),
                              box(0, 0, W0 - 1, H0 - 1), 1);
        tp.lineorder = EXR_LINEORDER_DECREASING_Y;
        write_exr(in, &tp, 1);
        fp_frame_t *f = NULL;
        assert_int_equal(fp_exr_read_file(in, 3, NULL, &f), FP_OK);
        assert_int_equal(fp_exr_write_file(f, NULL, NULL, out, 3), FP_OK);
        fp_frame_free(f);
        exr_context_t c = open_hdr(out);
        exr_lineorder_t lo;
        assert_int_equal(exr_get_lineorder(c, 0, &lo), 0);
        assert_int_equal(lo, EXR_LINEORDER_INCREASING_Y);
        /* the chunks lie in the file in the declared order */
        int32_t lpc;
        assert_int_equal(exr_get_scanlines_per_chunk(c, 0, &lpc), 0);
        uint64_t prev = 0;
        for (int y = 0; y < H0; y += lpc) {
            exr_chunk_info_t ci;
            assert_int_equal(exr_read_scanline_chunk_info(c, 0, y, &ci), 0);
            assert_true(ci.data_offset > prev);
            prev = ci.data_offset;
        }
        exr_finish(&c);
        assert_same_chan(in, 0, out, 0, "R");
        assert_same_chan(in, 0, out, 0, "Z");
        assert_same_chan(in, 0, out, 0, "id");
    }
    std_img_free(&im);
}

static void add_envmap(exr_context_t c, int p)
{
    assert_int_equal(exr_attr_set_envmap(c, p, "envmap", EXR_ENVMAP_LATLONG), 0);
}

/* The byte after "<name>\0<type>\0<size>" in a header. */
static size_t attr_value_at(const uint8_t *b, size_t n, const char *name,
                            const char *type)
{
    size_t nl = strlen(name) + 1, tl = strlen(type) + 1;
    for (size_t i = 8; i + nl + tl + 4 < n; ++i)
        if (memcmp(b + i, name, nl) == 0 && memcmp(b + i + nl, type, tl) == 0)
            return i + nl + tl + 4;
    fail_msg("attribute %s not found", name);
    return 0;
}

/* Invalid enum values are refused, from a file and from a stream, with
 * one message naming the file, the frame and the attribute. */
static void test_bad_enums(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char in[4200], bad[4200];
    path_in(in, sizeof in, "enum.exr");
    path_in(bad, sizeof bad, "enum.bad.exr");
    tpart_t tp = std_part(&im, EXR_COMPRESSION_NONE, box(0, 0, W0 - 1, H0 - 1),
                          box(0, 0, W0 - 1, H0 - 1), 1);
    tp.attrs = add_envmap;
    write_exr(in, &tp, 1);
    size_t n;
    uint8_t *good = slurp_file(in, &n);
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_memory(good, n, in, 1, NULL, &f), FP_OK);
    fp_frame_free(f);
    good = slurp_file(in, &n);

    struct {
        const char *name, *type;
        size_t skip;     /* bytes into the value */
        uint8_t value;
        const char *says;
    } cases[] = {
        { "lineOrder", "lineOrder", 0, 99, "lineOrder" },
        { "lineOrder", "lineOrder", 0, 3, "lineOrder" },
        { "compression", "compression", 0, 99, "compression" },
        { "compression", "compression", 0, EXR_COMPRESSION_LAST_TYPE, "compression" },
        { "envmap", "envmap", 0, 99, "envmap" },
        { "channels", "chlist", 2 + 4, 9, "perceptual linear" }, /* channel A's pLinear */
        { "channels", "chlist", 2, 7, "type" },           /* channel A's pixel type */
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        uint8_t *b = malloc(n);
        assert_non_null(b);
        memcpy(b, good, n);
        b[attr_value_at(b, n, cases[k].name, cases[k].type) + cases[k].skip] = cases[k].value;
        spit_file(bad, b, n);
        /* file */
        f = (fp_frame_t *) 1;
        cap_begin();
        int rc = fp_exr_read_file(bad, 7, NULL, &f);
        const char *msg = cap_end();
        if (rc != FP_ERR)
            fail_msg("%s = %d accepted", cases[k].name, cases[k].value);
        assert_null(f);
        assert_contains(msg, "enum.bad.exr: frame 7:");
        assert_contains(msg, cases[k].says);
        assert_non_null(strchr(msg, '\n'));
        assert_null(strchr(msg, '\n') + 1 < msg + strlen(msg) ? strchr(strchr(msg, '\n') + 1, '\n') : NULL);
        /* stream: the framing or the decoder refuses it */
        FILE *sin = fmemopen(b, n, "rb");
        assert_non_null(sin);
        void *buf = NULL;
        size_t size;
        cap_begin();
        rc = fp_exr_stream_next(sin, "<stdin>", 4, &buf, &size);
        if (rc == FP_OK)
            rc = fp_exr_read_memory(buf, size, "<stdin>", 4, NULL, &f);
        msg = cap_end();
        fclose(sin);
        if (rc != FP_ERR)
            fail_msg("stream: %s = %d accepted", cases[k].name, cases[k].value);
        assert_contains(msg, "<stdin>: frame 4:");
        assert_contains(msg, cases[k].says);
        free(b);
    }
    free(good);
    std_img_free(&im);
}

/* ------------------------------------------------------------ cut frames */

static int stream_read_n(const uint8_t *data, size_t n, int frames, const char **msg)
{
    FILE *in = fmemopen((void *) data, n, "rb");
    assert_non_null(in);
    int rc = FP_OK;
    cap_begin();
    for (int i = 1; i <= frames && rc == FP_OK; ++i) {
        void *buf = NULL;
        size_t size;
        rc = fp_exr_stream_next(in, "<stdin>", i, &buf, &size);
        if (rc == FP_OK) {
            fp_frame_t *f = NULL;
            rc = fp_exr_read_memory(buf, size, "<stdin>", i, NULL, &f);
            fp_frame_free(f);
        }
        if (rc != FP_OK)
            rc = i;
    }
    *msg = cap_end();
    fclose(in);
    return rc;
}

/* An uncompressed frame cut short inside a stream: the error names it,
 * not the frame after it, whose start it borrowed. */
static void test_stream_cut(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, W0, H0);
    char in[4200];
    path_in(in, sizeof in, "cut.exr");
    tpart_t tp = std_part(&im, EXR_COMPRESSION_NONE, box(0, 0, W0 - 1, H0 - 1),
                          box(0, 0, W0 - 1, H0 - 1), 1);
    write_exr(in, &tp, 1);
    size_t n;
    uint8_t *a = slurp_file(in, &n);
    uint8_t *st = malloc(3 * n);
    assert_non_null(st);
    const size_t line = (size_t) W0 * (4 * 2 + 4 + 4 + 4); /* one chunk */
    const size_t cuts[] = { 1, 2, 3, 4, 5, 6, 100, line - 8 - 1 };
    for (size_t k = 0; k < sizeof cuts / sizeof cuts[0]; ++k) {
        size_t len = 0;
        memcpy(st, a, n);
        len += n;
        memcpy(st + len, a, n - cuts[k]);
        len += n - cuts[k];
        memcpy(st + len, a, n);
        len += n;
        const char *msg;
        int bad = stream_read_n(st, len, 3, &msg);
        if (bad != 2)
            fail_msg("cut %zu: frame %d refused, expected 2: %s", cuts[k], bad, msg);
        assert_contains(msg, "<stdin>: frame 2: truncated");
    }
    /* the last chunk holding a magic number and version by chance (a uint
     * channel's last line): frames before a good frame, and at the end,
     * are read */
    uint32_t *id = im.id;
    id[(size_t) (H0 - 1) * W0 + 0] = 0x01312f76u;
    id[(size_t) (H0 - 1) * W0 + 1] = 2;
    for (int round = 0; round < 2; ++round) {
        if (round == 1) { /* ends with the first byte of one */
            id[(size_t) (H0 - 1) * W0 + 0] = 0;
            id[(size_t) (H0 - 1) * W0 + W0 - 1] = 0x76000000u;
        }
        write_exr(in, &tp, 1);
        free(a);
        a = slurp_file(in, &n);
        assert_true(round == 0 || a[n - 1] == 0x76);
        memcpy(st, a, n);
        memcpy(st + n, a, n);
        const char *msg;
        assert_int_equal(stream_read_n(st, 2 * n, 2, &msg), FP_OK);
        assert_string_equal(msg, "");
    }
    free(st);
    free(a);
    std_img_free(&im);
}

/* ------------------------------------------------------------ chunk threads */

#define WP 320
#define HP 243 /* not a multiple of any codec's lines per chunk */

/* Read `path` and encode it back (with `comp` as the output compression,
 * -1: the input's) on `threads` chunk threads. */
static void read_encode(const char *path, int threads, int comp, int use_float,
                        fp_frame_t **f, void **bytes, size_t *n)
{
    fp_exr_set_threads(threads);
    assert_int_equal(fp_exr_threads(), threads);
    assert_int_equal(fp_exr_read_file(path, 1, NULL, f), FP_OK);
    fp_exr_write_opts_t o = FP_EXR_WRITE_OPTS_INITIALIZER;
    o.compression = comp;
    o.use_float = use_float;
    assert_int_equal(fp_exr_encode(*f, NULL, &o, path, 1, bytes, n), FP_OK);
}

/* Chunks decoded and encoded on several threads give the frame and the
 * bytes of one thread, for every compression this library has, scanline
 * and tiled input, and an error in the same chunk with the same message. */
static void test_chunk_threads(void **state)
{
    (void) state;
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, WP, HP);
    char in[4200];
    path_in(in, sizeof in, "par.exr");
    static const int counts[] = { 2, 3, 4, 16 };
    int tested = 0;
    for (int comp = 0; comp < EXR_COMPRESSION_LAST_TYPE; ++comp)
        for (int tiled = 0; tiled < 2; ++tiled) {
            tpart_t tp = std_part(&im, comp, box(-5, 7, -5 + WP - 1, 7 + HP - 1),
                                  box(0, 0, WP - 1, HP - 1), 1);
            if (tiled) {
                tp.tiled = 1;
                tp.tw = 64;
                tp.th = 48;
                tp.level_mode = EXR_TILE_ONE_LEVEL;
            }
            exr_result_t wrv = try_write_exr(in, &tp, 1);
            if (wrv == EXR_ERR_FEATURE_NOT_IMPLEMENTED)
                continue; /* no DWA in OpenEXR 3.1's C library */
            assert_int_equal(wrv, EXR_ERR_SUCCESS);
            fp_frame_t *f1, *fn;
            void *b1, *bn;
            size_t n1, nn;
            read_encode(in, 1, -1, comp & 1, &f1, &b1, &n1);
            for (size_t k = 0; k < sizeof counts / sizeof counts[0]; ++k) {
                read_encode(in, counts[k], -1, comp & 1, &fn, &bn, &nn);
                assert_memory_equal(fp_frame_rgba(fn), fp_frame_rgba(f1),
                                    (size_t) WP * HP * 4 * sizeof(float));
                assert_memory_equal(fp_frame_depth(fn), fp_frame_depth(f1),
                                    (size_t) WP * HP * sizeof(float));
                if (nn != n1 || memcmp(bn, b1, n1) != 0)
                    fail_msg("%s%s, %d threads: %zu bytes, one thread: %zu, or "
                             "other bytes", fp_exr_compression_name(comp),
                             tiled ? " tiled" : "", counts[k], nn, n1);
                free(bn);
                fp_frame_free(fn);
                tested++;
            }
            fp_frame_free(f1);
            free(b1);
        }
    assert_true(tested >= 8 * 2 * 4);

    /* encode only, to each compression from one input */
    tpart_t tp = std_part(&im, EXR_COMPRESSION_ZIP, box(0, 0, WP - 1, HP - 1),
                          box(0, 0, WP - 1, HP - 1), 1);
    write_exr(in, &tp, 1);
    for (int comp = 0; comp < EXR_COMPRESSION_LAST_TYPE; ++comp) {
        if (comp == EXR_COMPRESSION_DWAA || comp == EXR_COMPRESSION_DWAB)
            continue;
        fp_frame_t *f1, *f4;
        void *b1, *b4;
        size_t n1, n4;
        read_encode(in, 1, comp, 0, &f1, &b1, &n1);
        read_encode(in, 4, comp, 0, &f4, &b4, &n4);
        assert_int_equal(n1, n4);
        assert_memory_equal(b1, b4, n1);
        free(b1);
        free(b4);
        fp_frame_free(f1);
        fp_frame_free(f4);
    }

    /* two chunks spoiled (ZIP, 16 lines each): the first in chunk order
     * is reported, whatever the threads */
    size_t n;
    uint8_t *b = slurp_file(in, &n);
    exr_context_t c = open_hdr(in);
    for (int y = 80; y <= 160; y += 80) {
        exr_chunk_info_t ci;
        assert_int_equal(exr_read_scanline_chunk_info(c, 0, y, &ci), 0);
        memset(b + ci.data_offset, 0xA5, (size_t) ci.packed_size < 64 ? (size_t) ci.packed_size : 64);
    }
    exr_finish(&c);
    char bad[4200];
    path_in(bad, sizeof bad, "par.bad.exr");
    spit_file(bad, b, n);
    free(b);
    char msg1[8192];
    for (int t = 1; t <= 4; t += 3) {
        fp_exr_set_threads(t);
        fp_frame_t *f = NULL;
        cap_begin();
        assert_int_equal(fp_exr_read_file(bad, 9, NULL, &f), FP_ERR);
        const char *msg = cap_end();
        assert_contains(msg, "par.bad.exr: frame 9: part 0: cannot decode pixels at 0,80");
        if (t == 1)
            snprintf(msg1, sizeof msg1, "%s", msg);
        else
            assert_string_equal(msg, msg1);
    }
    fp_exr_set_threads(0);
    std_img_free(&im);
}

/* Half colour specials (zeros, subnormals, the largest, infinities, a
 * quiet NaN) come out as the exact floats, whether the library converts
 * them (colour in a part with other channels) or exrio does (a part of
 * colour only), on one thread or several. */
static void test_half_specials(void **state)
{
    (void) state;
    static const uint16_t sp[] = { 0x0000, 0x8000, 0x0001, 0x03ff, 0x8001, 0x0400,
                                   0x7bff, 0xfbff, 0x7c00, 0xfc00, 0x7e00, 0x3c00,
                                   0x3555, 0xc000 };
    const size_t nsp = sizeof sp / sizeof sp[0];
    std_img_t im;
    std_img_make(&im, EXR_PIXEL_HALF, WP, HP);
    uint16_t *planes[4] = { im.r, im.g, im.b, im.a };
    for (int k = 0; k < 4; ++k)
        for (size_t i = 0; i < (size_t) WP * HP; ++i)
            planes[k][i] = sp[(i * 7 + (size_t) k * 3) % nsp];
    char in[4200];
    path_in(in, sizeof in, "specials.exr");
    for (int only_color = 0; only_color < 2; ++only_color)
        for (int threads = 1; threads <= 4; threads += 3) {
            tpart_t tp = std_part(&im, EXR_COMPRESSION_ZIP, box(0, 0, WP - 1, HP - 1),
                                  box(0, 0, WP - 1, HP - 1), 1);
            if (only_color)
                tp.nch = 4; /* R, G, B, A */
            write_exr(in, &tp, 1);
            fp_exr_set_threads(threads);
            fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
            sel.need_depth = !only_color;
            fp_frame_t *f = NULL;
            assert_int_equal(fp_exr_read_file(in, 1, &sel, &f), FP_OK);
            const float *rgba = fp_frame_rgba(f);
            for (size_t i = 0; i < (size_t) WP * HP; ++i)
                for (int k = 0; k < 4; ++k) {
                    float want = h2f(planes[k][i]), got = rgba[i * 4 + (size_t) k];
                    if (memcmp(&want, &got, 4) != 0)
                        fail_msg("half %04x: %a, expected %a (colour only %d, "
                                 "%d threads)", planes[k][i], (double) got,
                                 (double) want, only_color, threads);
                }
            fp_frame_free(f);
        }
    fp_exr_set_threads(0);
    std_img_free(&im);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_compression_names),
        cmocka_unit_test(test_roundtrip_compressions),
        cmocka_unit_test(test_compression_override),
        cmocka_unit_test(test_float_color),
        cmocka_unit_test(test_tiled_input),
        cmocka_unit_test(test_negative_window),
        cmocka_unit_test(test_attributes_kept),
        cmocka_unit_test(test_multipart),
        cmocka_unit_test(test_depth_part_mismatch),
        cmocka_unit_test(test_blender_multilayer),
        cmocka_unit_test(test_overrides),
        cmocka_unit_test(test_uint_depth),
        cmocka_unit_test(test_subsampled_passthrough),
        cmocka_unit_test(test_no_color_input),
        cmocka_unit_test(test_take_depth),
        cmocka_unit_test(test_stream_frames),
        cmocka_unit_test(test_stream_errors),
        cmocka_unit_test(test_read_errors),
        cmocka_unit_test(test_deep_input),
        cmocka_unit_test(test_write_errors),
        cmocka_unit_test(test_threads),
        cmocka_unit_test(test_long_names),
        cmocka_unit_test(test_lineorder_decreasing),
        cmocka_unit_test(test_bad_enums),
        cmocka_unit_test(test_stream_cut),
        cmocka_unit_test(test_chunk_threads),
        cmocka_unit_test(test_half_specials),
    };
    return cmocka_run_group_tests(tests, setup_group, teardown_group);
}

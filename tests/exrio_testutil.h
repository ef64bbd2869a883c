/* What the tests split from tests/test_exrio.c share by job: their helpers,
 * fixtures and the sample scene (header-only; each test program uses
 * some of them). */
#ifndef FP_EXRIO_TESTUTIL_H
#define FP_EXRIO_TESTUTIL_H

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

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-variable"

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
static int is_lossy(int comp)
{
    return comp == EXR_COMPRESSION_B44 || comp == EXR_COMPRESSION_B44A ||
           comp == EXR_COMPRESSION_DWAA || comp == EXR_COMPRESSION_DWAB;
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
/* ------------------------------------------------------------ error paths */
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
/* ------------------------------------------------------------ line order, enums */
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

#pragma GCC diagnostic pop

#endif

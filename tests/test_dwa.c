/* DWAA/DWAB in and out (src/exr/exr_dwa.cpp): frames made by OpenEXR's C
 * library uncompressed, turned into DWA by the bridge, read by the C path
 * (fp_exr_read_memory), written again (fp_exr_encode) and checked with the
 * C library on the bridge's uncompressed rewrite.  OpenImageIO's reading of
 * these files, and DWA files made by oiiotool, are in tests/dwa.sh.
 *
 * Tolerances: DWA is lossy only for half channels named R, G, B, Y, RY, BY
 * (OpenEXR's classifier); the content is smooth in [0.05, 0.95], where
 * level 45 stays within 0.01 + 2% per generation (the measured worst case
 * is printed).  Every other channel (float, uint, alpha, other half names,
 * sub-sampled ones) is stored losslessly and must come back bit-exact. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <openexr.h>

#include "exr_dwa.h"
#include "exrio.h"
#include "fp.h"

#include "exr_testutil.h"

static void *dup_bytes(const void *b, size_t n)
{
    void *d = malloc(n);
    assert_non_null(d);
    memcpy(d, b, n);
    return d;
}

/* ------------------------------------------------------------ fixtures */

typedef struct tchan_t {
    const char *name;
    int type, xs, ys;
    void *data;      /* planar samples over the (sub-sampled) data window */
} tchan_t;

typedef struct tpart_t {
    const char *name;
    exr_attr_box2i_t dw, disp;
    int compression; /* DWAA/DWAB: written NONE, then made DWA by the bridge */
    int lineorder;
    int nch;
    tchan_t ch[12];
} tpart_t;

/* Even origin and size: the C++ library wants sub-sampled windows aligned. */
#define X0 (-4)
#define Y0 6
#define W 62
#define H 46

static void add(tpart_t *tp, const char *name, int type, int s, int seed)
{
    tchan_t *c = &tp->ch[tp->nch++];
    c->name = name;
    c->type = type;
    c->xs = c->ys = s;
    c->data = mkplane(type, (int) scount(X0, X0 + W, s), (int) scount(Y0, Y0 + H, s), seed);
}

static tpart_t mkpart(const char *name, int comp, int lineorder)
{
    tpart_t tp;
    memset(&tp, 0, sizeof tp);
    tp.name = name;
    tp.dw = box(X0, Y0, X0 + W - 1, Y0 + H - 1);
    tp.disp = box(0, 0, 79, 59);
    tp.compression = comp;
    tp.lineorder = lineorder;
    return tp;
}

static void free_part(tpart_t *tp)
{
    for (int c = 0; c < tp->nch; ++c)
        free(tp->ch[c].data);
}

static const tchan_t *find_tchan(const tpart_t *tp, const char *name)
{
    for (int c = 0; c < tp->nch; ++c)
        if (strcmp(tp->ch[c].name, name) == 0)
            return &tp->ch[c];
    return NULL;
}

static int is_dwa(int c)
{
    return c == EXR_COMPRESSION_DWAA || c == EXR_COMPRESSION_DWAB;
}

/* The header attributes every test file carries (and must keep). */
static void set_attrs(exr_context_t ctx, int p)
{
    exr_attr_m44f_t m;
    for (int i = 0; i < 16; ++i)
        m.m[i] = (float) (i % 5) * 0.25f + (i == 15);
    assert_int_equal(exr_attr_set_m44f(ctx, p, "worldToCamera", &m), 0);
    assert_int_equal(exr_attr_set_string(ctx, p, "nuke/node", "Write1"), 0);
    assert_int_equal(exr_attr_set_int(ctx, p, "frameNumber", 1001), 0);
    assert_int_equal(exr_attr_set_double(ctx, p, "exposure", 0.125), 0);
    exr_attr_v3f_t v = { { { 1.0f, 2.0f, 3.0f } } };
    assert_int_equal(exr_attr_set_v3f(ctx, p, "lookAt", &v), 0);
    static const uint8_t blob[5] = { 1, 2, 3, 4, 5 };
    assert_int_equal(exr_attr_set_user(ctx, p, "studio.blob", "studioType", 5, blob), 0);
}

/* Write parts with the C library (DWA parts uncompressed), then make the
 * DWA parts DWA through the bridge.  Returns the file's bytes. */
static uint8_t *make_exr(const tpart_t *parts, int np, float level, size_t *size)
{
    char path[4200];
    path_in(path, sizeof path, "made.exr");
    exr_context_t ctx = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = quiet_handler;
    exr_attr_v2f_t swc = { { { 0.0f, 0.0f } } };
    int comps[8];
    int any_dwa = 0;
    assert_true(np <= 8);
    assert_int_equal(exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init), 0);
    for (int p = 0; p < np; ++p) {
        const tpart_t *tp = &parts[p];
        int idx;
        comps[p] = tp->compression;
        any_dwa |= is_dwa(tp->compression);
        assert_int_equal(exr_add_part(ctx, tp->name, EXR_STORAGE_SCANLINE, &idx), 0);
        assert_int_equal(exr_initialize_required_attr(
                             ctx, idx, &tp->disp, &tp->dw, 1.0f, &swc, 1.0f,
                             (exr_lineorder_t) tp->lineorder,
                             is_dwa(tp->compression) ? EXR_COMPRESSION_NONE
                                                     : (exr_compression_t) tp->compression),
                         0);
        for (int c = 0; c < tp->nch; ++c)
            assert_int_equal(exr_add_channel(ctx, idx, tp->ch[c].name,
                                             (exr_pixel_type_t) tp->ch[c].type,
                                             EXR_PERCEPTUALLY_LOGARITHMIC,
                                             tp->ch[c].xs, tp->ch[c].ys), 0);
        set_attrs(ctx, idx);
    }
    assert_int_equal(exr_write_header(ctx), 0);
    for (int p = 0; p < np; ++p) {
        const tpart_t *tp = &parts[p];
        exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
        int32_t lpc;
        int inited = 0;
        assert_int_equal(exr_get_scanlines_per_chunk(ctx, p, &lpc), 0);
        for (int k = 0; k < (H + lpc - 1) / lpc; ++k) {
            exr_chunk_info_t ci;
            assert_int_equal(exr_write_scanline_chunk_info(ctx, p, Y0 + k * lpc, &ci), 0);
            assert_int_equal(inited ? exr_encoding_update(ctx, p, &ci, &enc)
                                    : exr_encoding_initialize(ctx, p, &ci, &enc), 0);
            for (int c = 0; c < enc.channel_count; ++c) {
                exr_coding_channel_info_t *cc = &enc.channels[c];
                const tchan_t *t = find_tchan(tp, cc->channel_name);
                assert_non_null(t);
                size_t bpe = tsize(t->type);
                int64_t sw = scount(X0, X0 + W, t->xs);
                int64_t row = scount(Y0, ci.start_y, t->ys);
                cc->encode_from_ptr = (const uint8_t *) t->data + (size_t) (row * sw) * bpe;
                cc->user_pixel_stride = (int32_t) bpe;
                cc->user_line_stride = (int32_t) (sw * (int64_t) bpe);
                cc->user_bytes_per_element = (int16_t) bpe;
                cc->user_data_type = (uint16_t) t->type;
            }
            if (!inited)
                assert_int_equal(exr_encoding_choose_default_routines(ctx, p, &enc), 0);
            inited = 1;
            assert_int_equal(exr_encoding_run(ctx, p, &enc), 0);
        }
        exr_encoding_destroy(ctx, &enc);
    }
    assert_int_equal(exr_finish(&ctx), 0);
    uint8_t *plain = slurp_file(path, size);
    unlink(path);
    if (!any_dwa)
        return plain;
    void *dwa = NULL;
    size_t dsize = 0;
    assert_int_equal(fp_dwa_encode(plain, *size, comps, np, level, "made.exr", 1,
                                   &dwa, &dsize), FP_OK);
    free(plain);
    *size = dsize;
    return dwa;
}

/* A C-library context on the image (DWA parts rewritten uncompressed by
 * the bridge first), for headers and raw channels. */
typedef struct rd_t {
    exr_context_t ctx;
    char path[4200];
} rd_t;

static void rd_open(rd_t *r, const void *buf, size_t size, int *comps, int max_parts)
{
    void *plain = NULL;
    size_t psize = size;
    int *pc = NULL, np = 0;
    if (fp_dwa_probe(buf, size)) {
        assert_int_equal(fp_dwa_decode(buf, size, FP_DWA_REQUIRED, "check", 1, &plain, &psize, &pc, &np),
                         FP_OK);
        assert_false(fp_dwa_probe(plain, psize));
    } else {
        plain = dup_bytes(buf, size);
    }
    path_in(r->path, sizeof r->path, "check.exr");
    spit_file(r->path, plain, psize);
    free(plain);
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = quiet_handler;
    assert_int_equal(exr_start_read(&r->ctx, r->path, &init), 0);
    for (int p = 0; p < max_parts; ++p) {
        exr_compression_t c;
        comps[p] = -1;
        if (exr_get_compression(r->ctx, p, &c) == 0)
            comps[p] = pc && p < np ? pc[p] : (int) c;
    }
    free(pc);
}

static void rd_close(rd_t *r)
{
    exr_finish(&r->ctx);
    unlink(r->path);
}

/* One channel of a scanline part, raw. */
static void *rd_chan(rd_t *r, int part, const char *name, int *type, size_t *n)
{
    exr_attr_box2i_t dw;
    const exr_attr_chlist_t *cl;
    assert_int_equal(exr_get_data_window(r->ctx, part, &dw), 0);
    assert_int_equal(exr_get_channels(r->ctx, part, &cl), 0);
    const exr_attr_chlist_entry_t *e = NULL;
    for (int i = 0; i < cl->num_channels; ++i)
        if (strcmp(cl->entries[i].name.str, name) == 0)
            e = &cl->entries[i];
    if (!e)
        return NULL;
    size_t bpe = tsize(e->pixel_type);
    int64_t sw = scount(dw.min.x, (int64_t) dw.max.x + 1, e->x_sampling);
    int64_t sh = scount(dw.min.y, (int64_t) dw.max.y + 1, e->y_sampling);
    uint8_t *plane = calloc((size_t) (sw * sh) * bpe + 1, 1);
    assert_non_null(plane);
    int32_t lpc;
    assert_int_equal(exr_get_scanlines_per_chunk(r->ctx, part, &lpc), 0);
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    int inited = 0;
    for (int64_t y = dw.min.y; y <= dw.max.y; y += lpc) {
        exr_chunk_info_t ci;
        assert_int_equal(exr_read_scanline_chunk_info(r->ctx, part, (int) y, &ci), 0);
        assert_int_equal(inited ? exr_decoding_update(r->ctx, part, &ci, &dec)
                                : exr_decoding_initialize(r->ctx, part, &ci, &dec), 0);
        for (int k = 0; k < dec.channel_count; ++k) {
            exr_coding_channel_info_t *cc = &dec.channels[k];
            if (strcmp(cc->channel_name, name) != 0) {
                cc->decode_to_ptr = NULL;
                continue;
            }
            int64_t row = scount(dw.min.y, y, e->y_sampling);
            cc->decode_to_ptr = plane + (size_t) (row * sw) * bpe;
            cc->user_pixel_stride = (int32_t) bpe;
            cc->user_line_stride = (int32_t) (sw * (int64_t) bpe);
            cc->user_bytes_per_element = (int16_t) bpe;
            cc->user_data_type = cc->data_type;
        }
        if (!inited)
            assert_int_equal(exr_decoding_choose_default_routines(r->ctx, part, &dec), 0);
        inited = 1;
        assert_int_equal(exr_decoding_run(r->ctx, part, &dec), 0);
    }
    exr_decoding_destroy(r->ctx, &dec);
    *type = e->pixel_type;
    *n = (size_t) (sw * sh);
    return plane;
}

/* Worst error of lossy channels, over the whole run (printed at the end). */
static double worst_err;

/* A channel of the image against its source: bit-exact, or within
 * 0.01 + 2% per lossy generation. */
static void check_chan(rd_t *r, int part, const tchan_t *src, int generations)
{
    int type;
    size_t n;
    void *d = rd_chan(r, part, src->name, &type, &n);
    if (!d)
        fail_msg("channel %s missing in part %d", src->name, part);
    assert_int_equal(type, src->type);
    size_t want_n = (size_t) (scount(X0, X0 + W, src->xs) * scount(Y0, Y0 + H, src->ys));
    assert_int_equal(n, want_n);
    if (generations == 0) {
        if (memcmp(d, src->data, n * tsize(type)) != 0)
            fail_msg("part %d channel %s: not bit-exact", part, src->name);
    } else {
        for (size_t i = 0; i < n; ++i) {
            float want = pget(type, src->data, i), got = pget(type, d, i);
            double err = fabs((double) got - want);
            if (err > worst_err)
                worst_err = err;
            if (err > generations * (0.01 + 0.02 * fabs(want)))
                fail_msg("part %d channel %s sample %zu: %g vs %g", part, src->name,
                         i, got, want);
        }
    }
    free(d);
}

static void check_attrs(rd_t *r, int part)
{
    const exr_attribute_t *a;
    assert_int_equal(exr_get_attribute_by_name(r->ctx, part, "worldToCamera", &a), 0);
    assert_int_equal(a->type, EXR_ATTR_M44F);
    for (int i = 0; i < 16; ++i)
        assert_true(a->m44f->m[i] == (float) (i % 5) * 0.25f + (i == 15));
    assert_int_equal(exr_get_attribute_by_name(r->ctx, part, "nuke/node", &a), 0);
    assert_string_equal(a->string->str, "Write1");
    assert_int_equal(exr_get_attribute_by_name(r->ctx, part, "frameNumber", &a), 0);
    assert_int_equal(a->i, 1001);
    assert_int_equal(exr_get_attribute_by_name(r->ctx, part, "exposure", &a), 0);
    assert_true(a->d == 0.125);
    assert_int_equal(exr_get_attribute_by_name(r->ctx, part, "lookAt", &a), 0);
    assert_true(a->v3f->z == 3.0f);
    assert_int_equal(exr_get_attribute_by_name(r->ctx, part, "studio.blob", &a), 0);
    assert_string_equal(a->type_name, "studioType");
    assert_int_equal(a->opaque->size, 5);
    assert_memory_equal(a->opaque->packed_data, "\1\2\3\4\5", 5);
    exr_attr_box2i_t dw, disp;
    exr_lineorder_t lo;
    assert_int_equal(exr_get_data_window(r->ctx, part, &dw), 0);
    assert_int_equal(exr_get_display_window(r->ctx, part, &disp), 0);
    assert_int_equal(dw.min.x, X0);
    assert_int_equal(dw.min.y, Y0);
    assert_int_equal(dw.max.x, X0 + W - 1);
    assert_int_equal(dw.max.y, Y0 + H - 1);
    assert_int_equal(disp.max.x, 79);
    assert_int_equal(disp.max.y, 59);
    assert_int_equal(exr_get_lineorder(r->ctx, part, &lo), 0);
    (void) lo;
}

static float attr_float(rd_t *r, int part, const char *name)
{
    float v = -1.0f;
    assert_int_equal(exr_attr_get_float(r->ctx, part, name, &v), 0);
    return v;
}

/* the colour part: R,G,B half (lossy), A half, Z float, id uint, N.X half,
 * c.u half 2x2 sub-sampled */
static tpart_t color_part(int comp, int lineorder)
{
    tpart_t tp = mkpart("beauty", comp, lineorder);
    add(&tp, "A", EXR_PIXEL_HALF, 1, 4);
    add(&tp, "B", EXR_PIXEL_HALF, 1, 3);
    add(&tp, "G", EXR_PIXEL_HALF, 1, 2);
    add(&tp, "N.X", EXR_PIXEL_HALF, 1, 7);
    add(&tp, "R", EXR_PIXEL_HALF, 1, 1);
    add(&tp, "Z", EXR_PIXEL_FLOAT, 1, 5);
    add(&tp, "c.u", EXR_PIXEL_HALF, 2, 8);
    add(&tp, "id", EXR_PIXEL_UINT, 1, 6);
    return tp;
}

static int lossy_name(const char *n)
{
    return !strcmp(n, "R") || !strcmp(n, "G") || !strcmp(n, "B") ||
           !strcmp(n, "spec.R") || !strcmp(n, "spec.G") || !strcmp(n, "spec.B");
}

/* ------------------------------------------------------------ tests */

static void test_writable(void **state)
{
    (void) state;
    for (int c = 0; c < 10; ++c)
        assert_true(fp_exr_compression_writable(c));
    assert_false(fp_exr_compression_writable(-1));
    assert_false(fp_exr_compression_writable(10));
}

static void test_probe(void **state)
{
    (void) state;
    tpart_t tp = color_part(EXR_COMPRESSION_ZIP, EXR_LINEORDER_INCREASING_Y);
    size_t n;
    uint8_t *zip = make_exr(&tp, 1, -1.0f, &n);
    assert_false(fp_dwa_probe(zip, n));
    for (size_t cut = 0; cut < 64; ++cut)
        assert_false(fp_dwa_probe(zip, cut));
    free(zip);
    /* B44 with float channels: the C++ library is preferred; half only:
     * the C library reads it right */
    tp.compression = EXR_COMPRESSION_B44A;
    uint8_t *b44 = make_exr(&tp, 1, -1.0f, &n);
    assert_int_equal(fp_dwa_probe(b44, n), FP_DWA_PREFERRED);
    free(b44);
    tpart_t half = mkpart("half", EXR_COMPRESSION_B44, EXR_LINEORDER_INCREASING_Y);
    add(&half, "R", EXR_PIXEL_HALF, 1, 1);
    add(&half, "Y", EXR_PIXEL_HALF, 2, 2);
    b44 = make_exr(&half, 1, -1.0f, &n);
    assert_int_equal(fp_dwa_probe(b44, n), 0);
    free(b44);
    free_part(&half);
    tp.compression = EXR_COMPRESSION_DWAB;
    uint8_t *dwab = make_exr(&tp, 1, -1.0f, &n);
    assert_int_equal(fp_dwa_probe(dwab, n), FP_DWA_REQUIRED);
    assert_false(fp_dwa_probe(NULL, 0));
    assert_false(fp_dwa_probe("garbage!garbage!", 16));
    free(dwab);
    free_part(&tp);
}

/* DWAA and DWAB, both line orders: read by the C path (colour within
 * tolerance, depth exact), written back with the input's compression,
 * every channel, attribute and window kept. */
static void test_roundtrip(void **state)
{
    (void) state;
    static const int comps[2] = { EXR_COMPRESSION_DWAA, EXR_COMPRESSION_DWAB };
    static const int orders[2] = { EXR_LINEORDER_INCREASING_Y, EXR_LINEORDER_DECREASING_Y };
    for (int ci = 0; ci < 2; ++ci)
        for (int oi = 0; oi < 2; ++oi) {
            int comp = comps[ci];
            tpart_t tp = color_part(comp, orders[oi]);
            size_t n;
            uint8_t *in = make_exr(&tp, 1, -1.0f, &n);
            assert_true(fp_dwa_probe(in, n));

            /* what the bridge made: DWA with the level 45 attribute */
            rd_t r;
            int pc[1];
            rd_open(&r, in, n, pc, 1);
            assert_int_equal(pc[0], comp);
            assert_true(attr_float(&r, 0, "dwaCompressionLevel") == 45.0f);
            rd_close(&r);

            fp_frame_t *f = NULL;
            assert_int_equal(fp_exr_read_memory(dup_bytes(in, n), n, "in.exr", 1001, NULL, &f),
                             FP_OK);
            const fp_frame_info_t *info = fp_frame_info(f);
            assert_int_equal(info->compression, comp);
            assert_int_equal(info->width, W);
            assert_int_equal(info->height, H);
            assert_int_equal(info->data_x0, X0);
            assert_int_equal(info->data_y0, Y0);
            assert_int_equal(info->disp_w, 80);
            assert_int_equal(info->has_alpha, 1);
            assert_int_equal(info->has_world_to_camera, 1);
            const float *rgba = fp_frame_rgba(f);
            const float *z = fp_frame_depth(f);
            assert_non_null(rgba);
            assert_non_null(z);
            const char *cn[4] = { "R", "G", "B", "A" };
            for (int k = 0; k < 4; ++k) {
                const tchan_t *t = find_tchan(&tp, cn[k]);
                for (size_t i = 0; i < (size_t) W * H; ++i) {
                    float want = pget(t->type, t->data, i), got = rgba[i * 4 + k];
                    double err = fabs((double) got - want);
                    if (err > worst_err)
                        worst_err = err;
                    if (k == 3 ? got != want : err > 0.01 + 0.02 * fabs(want))
                        fail_msg("%s: pixel %zu.%s: %g vs %g",
                                 fp_exr_compression_name(comp), i, cn[k], got, want);
                }
            }
            const tchan_t *tz = find_tchan(&tp, "Z");
            for (size_t i = 0; i < (size_t) W * H; ++i)
                assert_true(z[i] == pget(EXR_PIXEL_FLOAT, tz->data, i));

            void *out = NULL;
            size_t on = 0;
            assert_int_equal(fp_exr_encode(f, NULL, NULL, "out.exr", 1001, &out, &on), FP_OK);
            fp_frame_free(f);
            assert_true(fp_dwa_probe(out, on));
            rd_open(&r, out, on, pc, 1);
            assert_int_equal(pc[0], comp);
            check_attrs(&r, 0);
            exr_lineorder_t lo;
            assert_int_equal(exr_get_lineorder(r.ctx, 0, &lo), 0);
            /* Line order is normalized to increasing on output (exr_write.c:
             * the C library stores chunks increasing), DWA included. */
            assert_int_equal((int) lo, EXR_LINEORDER_INCREASING_Y);
            assert_true(attr_float(&r, 0, "dwaCompressionLevel") == 45.0f);
            const exr_attr_chlist_t *cl;
            assert_int_equal(exr_get_channels(r.ctx, 0, &cl), 0);
            assert_int_equal(cl->num_channels, tp.nch);
            for (int c = 0; c < tp.nch; ++c)
                check_chan(&r, 0, &tp.ch[c], lossy_name(tp.ch[c].name) ? 2 : 0);
            rd_close(&r);
            free(out);
            free(in);
            free_part(&tp);
        }
    print_message("# DWA at level 45: worst colour error %.5f over two generations "
                  "(bound 0.02 + 4%%)\n", worst_err);
}

/* Any compression out of a DWA input, and DWA out of a ZIP input. */
static void test_convert(void **state)
{
    (void) state;
    for (int comp = 0; comp < 10; ++comp) {
        int src = is_dwa(comp) ? EXR_COMPRESSION_ZIP : EXR_COMPRESSION_DWAA;
        tpart_t tp = color_part(src, EXR_LINEORDER_INCREASING_Y);
        size_t n;
        uint8_t *in = make_exr(&tp, 1, -1.0f, &n);
        fp_frame_t *f = NULL;
        assert_int_equal(fp_exr_read_memory(in, n, "in.exr", 7, NULL, &f), FP_OK);
        assert_int_equal(fp_frame_info(f)->compression, src);
        fp_exr_write_opts_t o = FP_EXR_WRITE_OPTS_INITIALIZER;
        o.compression = comp;
        void *out = NULL;
        size_t on = 0;
        assert_int_equal(fp_exr_encode(f, NULL, &o, "out.exr", 7, &out, &on), FP_OK);
        fp_frame_free(f);
        rd_t r;
        int pc[1];
        rd_open(&r, out, on, pc, 1);
        assert_int_equal(pc[0], comp);
        check_attrs(&r, 0);
        for (int c = 0; c < tp.nch; ++c) {
            const tchan_t *t = &tp.ch[c];
            int lossy = lossy_name(t->name) && (is_dwa(comp) || src != EXR_COMPRESSION_ZIP ||
                                                comp == EXR_COMPRESSION_B44 ||
                                                comp == EXR_COMPRESSION_B44A);
            /* pxr24 rounds floats to 24 bits, b44 every half channel */
            if (comp == EXR_COMPRESSION_PXR24 && t->type == EXR_PIXEL_FLOAT) {
                int type;
                size_t k;
                float *d = rd_chan(&r, 0, t->name, &type, &k);
                for (size_t i = 0; i < k; ++i)
                    assert_true(fabsf(d[i] - pget(t->type, t->data, i)) <=
                                1e-4f * fabsf(pget(t->type, t->data, i)));
                free(d);
                continue;
            }
            int b44 = (comp == EXR_COMPRESSION_B44 || comp == EXR_COMPRESSION_B44A) &&
                      t->type == EXR_PIXEL_HALF;
            check_chan(&r, 0, t, lossy || b44 ? 2 : 0);
        }
        rd_close(&r);
        free(out);
        free_part(&tp);
    }
}

/* Multipart: a DWAA part, a ZIP part (copied chunk for chunk on the way
 * in) and a DWAB part; each keeps its compression. */
static void test_multipart(void **state)
{
    (void) state;
    tpart_t tp[3];
    tp[0] = color_part(EXR_COMPRESSION_DWAA, EXR_LINEORDER_INCREASING_Y);
    tp[1] = mkpart("aux", EXR_COMPRESSION_ZIP, EXR_LINEORDER_INCREASING_Y);
    add(&tp[1], "crypto.id", EXR_PIXEL_UINT, 1, 11);
    add(&tp[1], "motion.x", EXR_PIXEL_FLOAT, 1, 12);
    tp[2] = mkpart("spec", EXR_COMPRESSION_DWAB, EXR_LINEORDER_DECREASING_Y);
    add(&tp[2], "spec.B", EXR_PIXEL_HALF, 1, 13);
    add(&tp[2], "spec.G", EXR_PIXEL_HALF, 1, 14);
    add(&tp[2], "spec.R", EXR_PIXEL_HALF, 1, 15);
    size_t n;
    uint8_t *in = make_exr(tp, 3, 20.0f, &n);
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_memory(in, n, "mp.exr", 3, NULL, &f), FP_OK);
    assert_int_equal(fp_frame_info(f)->num_parts, 3);
    assert_int_equal(fp_frame_info(f)->compression, EXR_COMPRESSION_DWAA);
    void *out = NULL;
    size_t on = 0;
    assert_int_equal(fp_exr_encode(f, NULL, NULL, "mp.out.exr", 3, &out, &on), FP_OK);
    fp_frame_free(f);
    rd_t r;
    int pc[3];
    rd_open(&r, out, on, pc, 3);
    assert_int_equal(pc[0], EXR_COMPRESSION_DWAA);
    assert_int_equal(pc[1], EXR_COMPRESSION_ZIP);
    assert_int_equal(pc[2], EXR_COMPRESSION_DWAB);
    /* the input's level (20) is kept where no --dwa-level is given */
    assert_true(attr_float(&r, 0, "dwaCompressionLevel") == 20.0f);
    assert_true(attr_float(&r, 2, "dwaCompressionLevel") == 20.0f);
    for (int p = 0; p < 3; ++p) {
        const char *name = NULL;
        assert_int_equal(exr_get_name(r.ctx, p, &name), 0);
        assert_string_equal(name, tp[p].name);
        check_attrs(&r, p);
        for (int c = 0; c < tp[p].nch; ++c)
            check_chan(&r, p, &tp[p].ch[c], lossy_name(tp[p].ch[c].name) ? 2 : 0);
    }
    rd_close(&r);
    free(out);
    for (int p = 0; p < 3; ++p)
        free_part(&tp[p]);
}

/* --dwa-level: a higher level gives a smaller file; the level is written. */
static void test_level(void **state)
{
    (void) state;
    tpart_t tp = color_part(EXR_COMPRESSION_DWAA, EXR_LINEORDER_INCREASING_Y);
    size_t n;
    uint8_t *in = make_exr(&tp, 1, -1.0f, &n);
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_memory(in, n, "in.exr", 1, NULL, &f), FP_OK);
    size_t sizes[3];
    static const float levels[3] = { 1.0f, 45.0f, 500.0f };
    for (int i = 0; i < 3; ++i) {
        fp_exr_write_opts_t o = FP_EXR_WRITE_OPTS_INITIALIZER;
        o.dwa_level = levels[i];
        void *out = NULL;
        assert_int_equal(fp_exr_encode(f, NULL, &o, "out.exr", 1, &out, &sizes[i]), FP_OK);
        rd_t r;
        int pc[1];
        rd_open(&r, out, sizes[i], pc, 1);
        assert_true(attr_float(&r, 0, "dwaCompressionLevel") == levels[i]);
        rd_close(&r);
        free(out);
    }
    print_message("# DWAA sizes at levels 1, 45, 500: %zu %zu %zu bytes\n", sizes[0],
                  sizes[1], sizes[2]);
    assert_true(sizes[0] > sizes[1]);
    assert_true(sizes[1] > sizes[2]);
    fp_frame_free(f);
    free_part(&tp);
}

/* Streams: DWAA (32 lines a chunk), DWAB (256) and multipart DWA frames
 * back to back are split where they end; a cut frame is named. */
static void test_stream(void **state)
{
    (void) state;
    tpart_t a = color_part(EXR_COMPRESSION_DWAA, EXR_LINEORDER_INCREASING_Y);
    tpart_t b = color_part(EXR_COMPRESSION_DWAB, EXR_LINEORDER_DECREASING_Y);
    tpart_t mp[2];
    mp[0] = color_part(EXR_COMPRESSION_DWAB, EXR_LINEORDER_INCREASING_Y);
    mp[1] = mkpart("aux", EXR_COMPRESSION_DWAA, EXR_LINEORDER_INCREASING_Y);
    add(&mp[1], "Y", EXR_PIXEL_HALF, 1, 21);
    size_t n[4];
    uint8_t *fr[4];
    fr[0] = make_exr(&a, 1, -1.0f, &n[0]);
    fr[1] = make_exr(&b, 1, -1.0f, &n[1]);
    fr[2] = make_exr(mp, 2, -1.0f, &n[2]);
    fr[3] = make_exr(&a, 1, 100.0f, &n[3]);
    char path[4200];
    path_in(path, sizeof path, "dwa.stream");
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    for (int i = 0; i < 4; ++i)
        assert_int_equal(fwrite(fr[i], 1, n[i], fp), n[i]);
    assert_int_equal(fclose(fp), 0);

    fp = fopen(path, "rb");
    assert_non_null(fp);
    for (int i = 0; i < 4; ++i) {
        void *buf = NULL;
        size_t size = 0;
        assert_int_equal(fp_exr_stream_next(fp, "<stdin>", i + 1, &buf, &size), FP_OK);
        assert_int_equal(size, n[i]);
        assert_memory_equal(buf, fr[i], n[i]);
        fp_frame_t *f = NULL;
        assert_int_equal(fp_exr_read_memory(buf, size, "<stdin>", i + 1, NULL, &f), FP_OK);
        fp_frame_free(f);
    }
    void *buf = NULL;
    size_t size = 0;
    assert_int_equal(fp_exr_stream_next(fp, "<stdin>", 5, &buf, &size), FP_EOF);
    fclose(fp);

    /* the second frame cut 5 bytes before its end */
    fp = fopen(path, "wb");
    assert_non_null(fp);
    assert_int_equal(fwrite(fr[0], 1, n[0], fp), n[0]);
    assert_int_equal(fwrite(fr[1], 1, n[1] - 5, fp), n[1] - 5);
    assert_int_equal(fclose(fp), 0);
    fp = fopen(path, "rb");
    assert_non_null(fp);
    assert_int_equal(fp_exr_stream_next(fp, "<stdin>", 1, &buf, &size), FP_OK);
    free(buf);
    buf = NULL;
    cap_begin();
    int rc = fp_exr_stream_next(fp, "<stdin>", 2, &buf, &size);
    const char *msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_null(buf);
    assert_contains(msg, "<stdin>: frame 2: truncated");
    fclose(fp);
    unlink(path);
    for (int i = 0; i < 4; ++i)
        free(fr[i]);
    free_part(&a);
    free_part(&b);
    free_part(&mp[0]);
    free_part(&mp[1]);
}

/* Damaged DWA input: one line naming the file and frame, no crash. */
static void test_damaged(void **state)
{
    (void) state;
    tpart_t tp = color_part(EXR_COMPRESSION_DWAA, EXR_LINEORDER_INCREASING_Y);
    size_t n;
    uint8_t *in = make_exr(&tp, 1, -1.0f, &n);
    /* cut at several places past the header, and garbage in the chunks */
    for (int k = 0; k < 6; ++k) {
        size_t len = n;
        uint8_t *bad = dup_bytes(in, n);
        if (k < 3) {
            len = n - (n / 4) * (size_t) (k + 1) / 2;
        } else {
            for (size_t i = n / 2 + (size_t) k * 7; i < n; i += 3)
                bad[i] ^= 0x5a;
        }
        fp_frame_t *f = NULL;
        cap_begin();
        int rc = fp_exr_read_memory(bad, len, "bad.exr", 42, NULL, &f);
        const char *msg = cap_end();
        if (rc == FP_OK) {
            /* garbage that still decodes is garbage pixels, not a crash */
            assert_true(k >= 3);
            fp_frame_free(f);
            continue;
        }
        assert_null(f);
        assert_contains(msg, "bad.exr: frame 42: ");
        assert_non_null(strchr(msg, '\n'));
        assert_null(strchr(strchr(msg, '\n') + 1, '\n'));
    }
    /* the encoder's errors: a part count that does not match */
    int comps[2] = { EXR_COMPRESSION_DWAA, EXR_COMPRESSION_DWAA };
    void *out = NULL;
    size_t on = 0;
    tpart_t plain = color_part(EXR_COMPRESSION_NONE, EXR_LINEORDER_INCREASING_Y);
    size_t pn;
    uint8_t *p = make_exr(&plain, 1, -1.0f, &pn);
    cap_begin();
    int rc = fp_dwa_encode(p, pn, comps, 2, -1.0f, "x.exr", 9, &out, &on);
    const char *msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_null(out);
    assert_contains(msg, "x.exr: frame 9: cannot encode");
    cap_begin();
    rc = fp_dwa_encode(p, pn / 2, comps, 1, -1.0f, "x.exr", 9, &out, &on);
    msg = cap_end();
    assert_int_equal(rc, FP_ERR);
    assert_null(out);
    assert_contains(msg, "x.exr: frame 9: cannot encode DWA-compressed EXR (");
    free(p);
    free(in);
    free_part(&plain);
    free_part(&tp);
}

static int setup_group(void **state)
{
    (void) state;
    return tdir_make("test_dwa");
}

static int teardown_group(void **state)
{
    (void) state;
    return tdir_remove();
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_writable),
        cmocka_unit_test(test_probe),
        cmocka_unit_test(test_roundtrip),
        cmocka_unit_test(test_convert),
        cmocka_unit_test(test_multipart),
        cmocka_unit_test(test_level),
        cmocka_unit_test(test_stream),
        cmocka_unit_test(test_damaged),
    };
    return cmocka_run_group_tests(tests, setup_group, teardown_group);
}

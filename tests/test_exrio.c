/* Unit tests for exrio.h (src/exr/exr_read.c, exr_write.c): EXR
 * read/write round trips, compressions, tiled, multi-part and deep
 * input, channel selection, attributes, half specials.  Streams, error
 * paths and chunk threads are tests/test_exrstream.c,
 * tests/test_exrerrors.c and tests/test_exrthreads.c (helpers shared in
 * tests/exrio_testutil.h).
 *
 * Input files are made with OpenEXR's C API writer, in a temporary
 * directory under $FP_TMP (or /tmp) that is removed at the end.  Outputs
 * are checked with an independent reader built on the same C API, so a
 * bug in exrio's decoder cannot hide one in its encoder. */
#include "exrio_testutil.h"

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
        cmocka_unit_test(test_deep_input),
        cmocka_unit_test(test_half_specials),
    };
    return cmocka_run_group_tests(tests, setup_group, teardown_group);
}

/* EXR error paths (src/exr/exr_read.c, exr_check.c, exr_write.c): bad
 * files and writes, long names, decreasing line order, bad enums, one
 * clear line each (split from tests/test_exrio.c; helpers in
 * tests/exrio_testutil.h). */
#include "exrio_testutil.h"

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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_read_errors),
        cmocka_unit_test(test_write_errors),
        cmocka_unit_test(test_long_names),
        cmocka_unit_test(test_lineorder_decreasing),
        cmocka_unit_test(test_bad_enums),
    };
    return cmocka_run_group_tests(tests, setup_group, teardown_group);
}

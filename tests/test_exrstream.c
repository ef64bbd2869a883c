/* EXR frames as a stream (src/exr/exr_stream.c): frames framed on a
 * pipe, errors, a stream cut short (split from tests/test_exrio.c;
 * helpers in tests/exrio_testutil.h). */
#include "exrio_testutil.h"

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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_stream_frames),
        cmocka_unit_test(test_stream_errors),
        cmocka_unit_test(test_stream_cut),
    };
    return cmocka_run_group_tests(tests, setup_group, teardown_group);
}

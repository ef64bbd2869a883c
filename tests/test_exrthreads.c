/* EXR chunk threads (src/exr/exr_common.c): the same bytes and pixels
 * whatever the number of threads (split from tests/test_exrio.c; helpers
 * in tests/exrio_testutil.h). */
#include "exrio_testutil.h"

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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_threads),
        cmocka_unit_test(test_chunk_threads),
    };
    return cmocka_run_group_tests(tests, setup_group, teardown_group);
}

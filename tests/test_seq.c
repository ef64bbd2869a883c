/* Sequence patterns and frame lists. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fp.h"
#include "seq.h"

static void expect_name(const char *pat, long frame, const char *want)
{
    char buf[256];
    assert_int_equal(fp_seq_format(pat, frame, buf, sizeof buf), FP_OK);
    assert_string_equal(buf, want);
}

static void test_patterns(void **state)
{
    (void)state;
    expect_name("shot.####.exr", 12, "shot.0012.exr");
    expect_name("shot.#.exr", 12, "shot.12.exr");
    expect_name("shot.@@@@@@.exr", 1001, "shot.001001.exr");
    expect_name("shot.%04d.exr", 7, "shot.0007.exr");
    expect_name("shot.%d.exr", 7, "shot.7.exr");
    expect_name("dir/a_%05d_b.exr", 123456, "dir/a_123456_b.exr");
    expect_name("shot.####.exr", -5, "shot.-005.exr");
    expect_name("plain.exr", 3, "plain.exr");
    assert_int_equal(fp_seq_has_placeholder("plain.exr"), 0);
    assert_int_equal(fp_seq_has_placeholder("a.####.exr"), 1);
    assert_int_equal(fp_seq_has_placeholder("a.%04d.exr"), 1);
    assert_int_equal(fp_seq_has_placeholder("a.##.%04d.exr"), -1);
    assert_int_equal(fp_seq_has_placeholder("a.%04s.exr"), -1);
    char small[8];
    assert_int_equal(fp_seq_format("longname.####.exr", 1, small, sizeof small), FP_EUSAGE);
}

static void expect_frames(const char *spec, const long *want, size_t n)
{
    fp_frame_list_t l;
    assert_int_equal(fp_frames_parse(spec, &l), FP_OK);
    assert_int_equal(l.count, n);
    for (size_t i = 0; i < n; i++)
        assert_int_equal(l.frames[i], want[i]);
    fp_frames_free(&l);
}

static void test_frames(void **state)
{
    (void)state;
    expect_frames("5", (long[]){ 5 }, 1);
    expect_frames("1-4", (long[]){ 1, 2, 3, 4 }, 4);
    expect_frames("1-9x3", (long[]){ 1, 4, 7 }, 3);
    expect_frames("-3", (long[]){ -3 }, 1);
    expect_frames("-3--1", (long[]){ -3, -2, -1 }, 3);
    expect_frames("-2-1", (long[]){ -2, -1, 0, 1 }, 4);
    expect_frames("1,3,7-9", (long[]){ 1, 3, 7, 8, 9 }, 5);
    expect_frames("1001-1003, 1010", (long[]){ 1001, 1002, 1003, 1010 }, 4);
    fp_frame_list_t l;
    fp_frame_list_t big;
    assert_int_equal(fp_frames_parse("1001-1100", &big), FP_OK);
    assert_int_equal(big.count, 100);
    fp_frames_free(&big);
    const char *bad[] = { "", "a", "1-", "5-1", "1-9x0", "1,,2", "1-9x", "3 4", "1-2-3" };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++)
        assert_int_equal(fp_frames_parse(bad[i], &l), FP_EUSAGE);
    assert_int_equal(fp_frames_parse("1-999999999", &l), FP_EUSAGE);
}

static void test_scan(void **state)
{
    (void)state;
    char dir[] = "/tmp/fp-seq-XXXXXX";
    assert_non_null(mkdtemp(dir));
    const char *names[] = { "s.0003.exr", "s.0001.exr", "s.0010.exr", "s.01.exr", "s.0002.exr.tmp",
                            "t.0004.exr", "s.-001.exr" };
    char path[512];
    for (size_t i = 0; i < sizeof names / sizeof *names; i++) {
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        FILE *f = fopen(path, "w");
        assert_non_null(f);
        fclose(f);
    }
    char pat[512];
    snprintf(pat, sizeof pat, "%s/s.####.exr", dir);
    fp_frame_list_t l;
    assert_int_equal(fp_frames_scan(pat, &l), FP_OK);
    long want[] = { -1, 1, 3, 10 };
    assert_int_equal(l.count, 4);
    for (int i = 0; i < 4; i++)
        assert_int_equal(l.frames[i], want[i]);
    fp_frames_free(&l);
    snprintf(pat, sizeof pat, "%s/none.####.exr", dir);
    assert_int_not_equal(fp_frames_scan(pat, &l), FP_OK);
    for (size_t i = 0; i < sizeof names / sizeof *names; i++) {
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        unlink(path);
    }
    rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_patterns),
        cmocka_unit_test(test_frames),
        cmocka_unit_test(test_scan),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* libfogpipe's public API (lib/fogpipe.h) as a host uses it: misuse returns
 * errors with messages (NULL, wrong sizes, wrong order), never a crash or a
 * print; the fog layers agree with the composite; homogeneous fog against
 * its closed form; 1000 frames without growing the heap. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "fogpipe.h"

#include <fcntl.h>
#include <malloc.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

enum { W = 33, H = 17 };

static float rgba[W * H * 4], depth[W * H], out[W * H * 4], fog[W * H * 4], tau[W * H * 3];

static void fill(float z)
{
    for (int i = 0; i < W * H; i++) {
        rgba[4 * i] = 0.2f;
        rgba[4 * i + 1] = 0.4f;
        rgba[4 * i + 2] = 0.6f;
        rgba[4 * i + 3] = 1.0f;
        depth[i] = z;
    }
}

static fogpipe_frame_t frame(void)
{
    fogpipe_frame_t in = FOGPIPE_FRAME_INITIALIZER;
    in.width = W;
    in.height = H;
    in.rgba = rgba;
    in.depth = depth;
    in.name = "test-frame";
    return in;
}

/* A camera at the origin looking down -z, homogeneous fog. */
static fogpipe_t *make(double density)
{
    fogpipe_t *fp = NULL;
    char d[32];
    snprintf(d, sizeof d, "%g", density);
    assert_int_equal(fogpipe_new(&fp), FOGPIPE_OK);
    assert_int_equal(fogpipe_set(fp, "camera-pos", "0,0,0", NULL), FOGPIPE_OK);
    assert_int_equal(fogpipe_set(fp, "--camera-target", "0,0,-1", NULL), FOGPIPE_OK);
    assert_int_equal(fogpipe_set(fp, "vfov", "40", NULL), FOGPIPE_OK);
    assert_int_equal(fogpipe_set(fp, "density", d, NULL), FOGPIPE_OK);
    return fp;
}

static void test_null_and_sizes(void **state)
{
    (void)state;
    assert_int_equal(fogpipe_new(NULL), FOGPIPE_EUSAGE);
    fogpipe_free(NULL);
    assert_non_null(fogpipe_error(NULL));
    assert_int_equal(fogpipe_set(NULL, "density", "1", NULL), FOGPIPE_EUSAGE);
    assert_int_equal(fogpipe_parse_args(NULL, 0, NULL), FOGPIPE_EUSAGE);
    assert_int_equal(fogpipe_run(NULL, 0), FOGPIPE_EUSAGE);
    fogpipe_frame_t in = frame();
    assert_int_equal(fogpipe_apply(NULL, &in, out, NULL, NULL), FOGPIPE_EUSAGE);
    fogpipe_set_message_handler(NULL, NULL, NULL);

    fogpipe_t *fp = make(0.05);
    assert_string_equal(fogpipe_error(fp), "");
    assert_int_equal(fogpipe_apply(fp, NULL, out, NULL, NULL), FOGPIPE_EUSAGE);
    assert_non_null(strstr(fogpipe_error(fp), "the frame is NULL"));
    in.rgba = NULL;
    assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_EUSAGE);
    assert_non_null(strstr(fogpipe_error(fp), "rgba is NULL"));
    in = frame();
    in.depth = NULL;
    assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_EUSAGE);
    assert_non_null(strstr(fogpipe_error(fp), "depth is NULL"));
    in = frame();
    assert_int_equal(fogpipe_apply(fp, &in, NULL, NULL, NULL), FOGPIPE_EUSAGE);
    in.width = 0;
    assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_EUSAGE);
    assert_non_null(strstr(fogpipe_error(fp), "0x17 pixels"));
    in.width = -5;
    assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_EUSAGE);
    in.width = 1 << 30;
    in.height = 1 << 30;
    assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_EUSAGE);
    fogpipe_free(fp);
}

static void test_options(void **state)
{
    (void)state;
    fogpipe_t *fp;
    assert_int_equal(fogpipe_new(&fp), FOGPIPE_OK);
    assert_int_equal(fogpipe_set(fp, "bogus", "1", NULL), FOGPIPE_EUSAGE);
    assert_non_null(strstr(fogpipe_error(fp), "unknown option --bogus"));
    assert_int_equal(fogpipe_set(fp, "density", "-1", "host"), FOGPIPE_EUSAGE);
    assert_non_null(strstr(fogpipe_error(fp), "host: --density: -1 is out of range"));
    assert_int_equal(fogpipe_set(fp, "density", NULL, NULL), FOGPIPE_EUSAGE);
    assert_int_equal(fogpipe_set(fp, NULL, "1", NULL), FOGPIPE_EUSAGE);
    assert_int_equal(fogpipe_set(fp, "preset", "nosuch-look", NULL), FOGPIPE_EUSAGE);
    assert_non_null(strstr(fogpipe_error(fp), "no preset of that name"));
    /* A good call clears the message; a flag without a value is on. */
    assert_int_equal(fogpipe_set(fp, "float", NULL, NULL), FOGPIPE_OK);
    assert_string_equal(fogpipe_error(fp), "");
    assert_int_equal(fogpipe_set(fp, "preset", "night-street-lamps", NULL), FOGPIPE_OK);
    char *argv[] = { "host", "--density", "abc", NULL };
    assert_int_equal(fogpipe_parse_args(fp, 3, argv), FOGPIPE_EUSAGE);
    assert_non_null(strstr(fogpipe_error(fp), "density"));
    fogpipe_free(fp);
}

/* Wrong order: a frame before any camera is known. */
static void test_no_camera(void **state)
{
    (void)state;
    fogpipe_t *fp;
    assert_int_equal(fogpipe_new(&fp), FOGPIPE_OK);
    fill(10);
    fogpipe_frame_t in = frame();
    assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_ERROR);
    assert_non_null(strstr(fogpipe_error(fp), "test-frame"));
    assert_non_null(strstr(fogpipe_error(fp), "camera"));
    fogpipe_free(fp);
}

static void count_warning(void *user, int kind, const char *text)
{
    if (kind == FOGPIPE_MSG_WARNING && strstr(text, "negative depth"))
        ++*(int *)user;
}

static void test_fog(void **state)
{
    (void)state;
    const double sigma = 0.05, z = 10;
    fogpipe_t *fp = make(sigma);
    fill((float)z);
    fogpipe_frame_t in = frame();
    assert_int_equal(fogpipe_apply(fp, &in, out, fog, tau), FOGPIPE_OK);
    /* The center pixel's ray runs along the axis: tau = exp(-sigma z). */
    int c = (H / 2) * W + W / 2;
    printf("# center tau %.7f, closed form %.7f\n", tau[3 * c], exp(-sigma * z));
    assert_true(fabs(tau[3 * c] - exp(-sigma * z)) < 1e-5);
    for (int i = 0; i < W * H; i++) {
        assert_true(tau[3 * i] > 0 && tau[3 * i] < 1);
        assert_true(fabsf(fog[4 * i + 3] - (1 - tau[3 * i])) < 1e-6f);
        for (int k = 0; k < 3; k++)
            assert_true(fabsf(out[4 * i + k] - (rgba[4 * i + k] * tau[3 * i] + fog[4 * i + k])) <
                        1e-5f);
        /* Mirror pixels see the same fog; below the horizon (height 1 under
         * the fog's base) the rays are longer than the axis, with less
         * transmittance. */
        int x = i % W, y = i / W;
        assert_true(fabsf(tau[3 * i] - tau[3 * (y * W + W - 1 - x)]) < 1e-6f);
        if (y > H / 2)
            assert_true(tau[3 * i] < tau[3 * c]);
    }
    /* In place gives the same pixels. */
    float *copy = malloc(sizeof rgba);
    memcpy(copy, rgba, sizeof rgba);
    in.rgba = copy;
    assert_int_equal(fogpipe_apply(fp, &in, copy, NULL, NULL), FOGPIPE_OK);
    assert_memory_equal(copy, out, sizeof out);
    in.rgba = rgba;
    free(copy);

    /* Warnings go to the handler, nothing to stderr. */
    int warned = 0;
    fogpipe_set_message_handler(fp, count_warning, &warned);
    depth[5] = -1;
    fflush(stderr);
    int saved = dup(2);
    char path[] = "/tmp/fp-test-api-XXXXXX";
    int tmp = mkstemp(path);
    dup2(tmp, 2);
    assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_OK);
    fogpipe_set_message_handler(fp, NULL, NULL);
    assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_OK);
    fflush(stderr);
    dup2(saved, 2);
    close(saved);
    off_t size = lseek(tmp, 0, SEEK_END);
    close(tmp);
    unlink(path);
    assert_int_equal(warned, 1);
    assert_int_equal(size, 0);
    fogpipe_free(fp);
}

/* 1000 frames (and option changes that set the device up again) leave
 * the heap as it was after the first ones. */
static void test_no_leak(void **state)
{
    (void)state;
    fogpipe_t *fp = make(0.02);
    fill(20);
    fogpipe_frame_t in = frame();
    for (int i = 0; i < 10; i++)
        assert_int_equal(fogpipe_apply(fp, &in, out, fog, tau), FOGPIPE_OK);
    struct mallinfo2 before = mallinfo2();
    for (int i = 0; i < 1000; i++) {
        in.frame = i;
        if (i % 250 == 0)
            assert_int_equal(fogpipe_set(fp, "density", i % 500 ? "0.03" : "0.02", NULL),
                             FOGPIPE_OK);
        assert_int_equal(fogpipe_apply(fp, &in, out, fog, tau), FOGPIPE_OK);
        assert_int_equal(fogpipe_apply(fp, NULL, out, fog, tau), FOGPIPE_EUSAGE);
    }
    struct mallinfo2 after = mallinfo2();
    long grown = (long)after.uordblks - (long)before.uordblks;
    printf("# heap in use after 1000 frames: %+ld bytes\n", grown);
    assert_true(grown < 64 * 1024);
    fogpipe_free(fp);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_null_and_sizes),
        cmocka_unit_test(test_options),
        cmocka_unit_test(test_no_camera),
        cmocka_unit_test(test_fog),
        cmocka_unit_test(test_no_leak),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

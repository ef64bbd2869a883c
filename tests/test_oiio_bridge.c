/* The OpenImageIO bridge: fogmaps are read as data (no color conversion,
 * integers mapped linearly), channels by name, rows top to bottom;
 * previews are written atomically, dithered without banding. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fp.h"
#include "oiio_bridge.h"

static char dir[] = "/tmp/fp-oiio-XXXXXX";

static void path(char *out, size_t n, const char *name)
{
    snprintf(out, n, "%s/%s", dir, name);
}

static void test_png_roundtrip_is_data(void **state)
{
    (void)state;
    char p8[256], p16[256];
    path(p8, sizeof p8, "ramp8.png");
    path(p16, sizeof p16, "ramp16.png");
    const int w = 256, h = 4;
    float img[256 * 4];
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++)
            img[j * w + i] = i / 255.0f * (j == 0 ? 1.0f : 0.5f);   /* row 0 differs */
    assert_int_equal(fp_oiio_write_preview(p8, img, w, h, 1, 8, 0), FP_OK);
    assert_int_equal(fp_oiio_write_preview(p16, img, w, h, 1, 16, 0), FP_OK);
    float *got;
    int gw, gh;
    assert_int_equal(fp_oiio_read_channel(p8, NULL, &got, &gw, &gh), FP_OK);
    assert_int_equal(gw, w);
    assert_int_equal(gh, h);
    /* 8-bit 128 reads back as exactly 128/255: no linearization. */
    assert_true(got[128] == 128.0f / 255.0f);
    assert_true(got[255] == 1.0f);
    assert_true(fabsf(got[w + 128] - 64.0f / 255.0f) < 1e-6f);   /* row 0 is the top row */
    free(got);
    assert_int_equal(fp_oiio_read_channel(p16, NULL, &got, &gw, &gh), FP_OK);
    assert_true(fabsf(got[100] - 100 / 255.0f) < 1.0f / 65535);
    assert_true(got[255] == 1.0f);
    free(got);
    /* No temporary left behind. */
    char cmd[512];
    snprintf(cmd, sizeof cmd, "ls -a %s | grep -q tmp", dir);
    assert_int_not_equal(system(cmd), 0);
}

static void test_channel_by_name(void **state)
{
    (void)state;
    char p[256];
    path(p, sizeof p, "rgb.png");
    float img[2 * 2 * 3] = { 0, 1, 0.2f, 0, 1, 0.4f, 0, 1, 0.6f, 0, 1, 0.8f };
    assert_int_equal(fp_oiio_write_preview(p, img, 2, 2, 3, 16, 0), FP_OK);
    float *got;
    int w, h;
    assert_int_equal(fp_oiio_read_channel(p, "B", &got, &w, &h), FP_OK);
    assert_true(fabsf(got[3] - 0.8f) < 1e-4f);
    free(got);
    assert_int_equal(fp_oiio_read_channel(p, "G", &got, &w, &h), FP_OK);
    assert_true(got[0] == 1.0f);
    free(got);
    assert_int_not_equal(fp_oiio_read_channel(p, "density", &got, &w, &h), FP_OK);
}

static void test_errors(void **state)
{
    (void)state;
    char p[256];
    float *got;
    int w, h;
    path(p, sizeof p, "missing.png");
    assert_int_not_equal(fp_oiio_read_channel(p, NULL, &got, &w, &h), FP_OK);
    path(p, sizeof p, "text.png");
    FILE *f = fopen(p, "w");
    fputs("not an image\n", f);
    fclose(f);
    assert_int_not_equal(fp_oiio_read_channel(p, NULL, &got, &w, &h), FP_OK);
    float px = 0.5f;
    assert_int_not_equal(fp_oiio_write_preview("/nonexistent/dir/x.png", &px, 1, 1, 1, 8, 0), FP_OK);
}

/* A ramp too gentle for 8 bits: dithered, it uses both neighbouring codes
 * in mixed proportions (no bands), never more than one step off. */
static void test_dither(void **state)
{
    (void)state;
    char p[256];
    path(p, sizeof p, "dither.png");
    const int w = 256, h = 16;
    float *img = malloc(sizeof(float) * w * h);
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++)
            img[j * w + i] = 0.2f + 0.01f * i / (w - 1);
    assert_int_equal(fp_oiio_write_preview(p, img, w, h, 1, 8, 1), FP_OK);
    float *got;
    int gw, gh;
    assert_int_equal(fp_oiio_read_channel(p, NULL, &got, &gw, &gh), FP_OK);
    int mixed_columns = 0;
    for (int i = 0; i < w; i++) {
        int lo = 0, hi = 0;
        for (int j = 0; j < h; j++) {
            double code = got[j * w + i] * 255, want = img[j * w + i] * 255;
            assert_true(fabs(code - want) <= 1.0 + 1e-6);
            lo += code < want;
            hi += code >= want;
        }
        mixed_columns += lo > 0 && hi > 0;
    }
    assert_true(mixed_columns > w / 2);
    /* Deterministic: the same bytes twice. */
    char q[256], cmd[600];
    path(q, sizeof q, "dither2.png");
    assert_int_equal(fp_oiio_write_preview(q, img, w, h, 1, 8, 1), FP_OK);
    snprintf(cmd, sizeof cmd, "cmp -s %s %s", p, q);
    assert_int_equal(system(cmd), 0);
    free(got);
    free(img);
}

int main(void)
{
    if (!mkdtemp(dir))
        return 1;
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_png_roundtrip_is_data),
        cmocka_unit_test(test_channel_by_name),
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_dither),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd) != 0)
        rc = 1;
    return rc;
}

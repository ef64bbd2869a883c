/* The library's deep result (fogpipe_apply_deep), as a host links it:
 * the samples of every pixel tidy, ending with the surface, and composited
 * front to back the same frame as fogpipe_apply's composite; bad arguments
 * refused with a message. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fogpipe.h"

#define W 24
#define H 16

static void test_apply_deep(void **state)
{
    (void)state;
    static float rgba[W * H * 4], depth[W * H], flat[W * H * 4];
    for (int i = 0; i < W * H; i++) {
        rgba[4 * i] = 0.1f + 0.002f * i;
        rgba[4 * i + 1] = 0.3f;
        rgba[4 * i + 2] = 0.6f;
        rgba[4 * i + 3] = 1;
        depth[i] = i % 7 == 0 ? INFINITY : 2.0f + 0.5f * (float)(i % 31);
    }
    fogpipe_t *fp = NULL;
    assert_int_equal(fogpipe_new(&fp), FOGPIPE_OK);
    const char *opts[][2] = { { "camera-pos", "0,1.5,0" }, { "camera-target", "0,2,-1" },
                              { "vfov", "50" }, { "density", "0.04" }, { "height", "0,6" },
                              { "sun", "0.3,0.4,-0.6" }, { "cpu", "1" } };
    for (size_t k = 0; k < sizeof opts / sizeof opts[0]; k++)
        assert_int_equal(fogpipe_set(fp, opts[k][0], opts[k][1], NULL), FOGPIPE_OK);
    fogpipe_frame_t in = FOGPIPE_FRAME_INITIALIZER;
    in.width = W;
    in.height = H;
    in.rgba = rgba;
    in.depth = depth;
    assert_int_equal(fogpipe_apply(fp, &in, flat, NULL, NULL), FOGPIPE_OK);
    fogpipe_deep_t *d = NULL;
    assert_int_equal(fogpipe_apply_deep(fp, &in, &d), FOGPIPE_OK);
    assert_non_null(d);
    assert_int_equal(d->width, W);
    assert_int_equal(d->offsets[W * H], d->total);
    double worst = 0;
    for (int i = 0; i < W * H; i++) {
        unsigned long long a = d->offsets[i], b = d->offsets[i + 1];
        assert_int_equal(b - a, d->counts[i]);
        assert_true(b > a);
        double c[4] = { 0, 0, 0, 0 };
        for (unsigned long long k = a; k < b; k++) {
            if (k > a)
                assert_true(d->z[k] >= d->zback[k - 1]);
            assert_true(d->zback[k] >= d->z[k]);
            double t = 1 - c[3];
            for (int ch = 0; ch < 4; ch++)
                c[ch] += t * d->rgba[4 * k + ch];
        }
        if (isfinite(depth[i]))   /* the surface last, at its depth */
            assert_float_equal(d->z[b - 1], depth[i], 1e-4);
        for (int ch = 0; ch < 3; ch++)
            worst = fmax(worst, fabs(c[ch] - flat[4 * i + ch]));
    }
    print_message("# deep result flattened against fogpipe_apply: %.3g, %.2f samples a pixel\n",
                  worst, (double)d->total / (W * H));
    assert_true(worst < 1e-5);
    fogpipe_deep_free(d);
    fogpipe_deep_free(NULL);
    /* bad arguments: refused with a message, nothing handed out */
    d = (fogpipe_deep_t *)&in;
    in.depth = NULL;
    assert_int_equal(fogpipe_apply_deep(fp, &in, &d), FOGPIPE_EUSAGE);
    assert_null(d);
    assert_non_null(strstr(fogpipe_error(fp), "fogpipe_apply_deep: depth is NULL"));
    assert_int_equal(fogpipe_apply_deep(fp, &in, NULL), FOGPIPE_EUSAGE);
    fogpipe_free(fp);
}

int main(void)
{
    const struct CMUnitTest tests[] = { cmocka_unit_test(test_apply_deep) };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

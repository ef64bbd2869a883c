/* integrate_fogmap (kernels/fogmap_lanes.h): the exact walk of a linear
 * fogmap on 16 rays a work-item, against the exact C double reference
 * (|dtau| <= 1e-5, the tolerance of test_fogmap's OpenCL parity) and
 * against the one-ray kernel integrate_fog, over the cases its lanes
 * choose among: wrap zero and repeat, a finite or no top, a height
 * falloff or none (H infinite), haze, a moved and turned fog in a box the
 * camera is inside or outside of, rays from a clip plane (--clip-start),
 * sky pixels, level rays, a frame width
 * that is not a multiple of 16, one level and several; a pixel list
 * (integrate_fogmap_list) gets the whole frame's values. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "clrt.h"
#include "fogmap.h"
#include "fp.h"
#include "integrate.h"
#include "options.h"
#include "testutil.h"

#include "fog_core.h"   /* FP_F_* parameter slots */

typedef struct lanes_case_t {
    const char *name;
    int wrap, levels, boxed, haze, flat;
    double top, cam_y, pitch, clip;
} lanes_case_t;

static const lanes_case_t cases[] = {
    { "zero, 3 levels", 0, 3, 0, 0, 0, INFINITY, 2, -20, 0 },
    { "repeat, 3 levels, top 12", 2, 3, 0, 0, 0, 12, 2, -20, 0 },
    { "zero, 1 level, haze", 0, 1, 0, 1, 0, INFINITY, 6, -10, 0 },
    { "repeat, no falloff (H infinite)", 2, 2, 0, 0, 1, INFINITY, 3, -5, 0 },
    { "zero, box turned, camera outside", 0, 3, 1, 0, 0, INFINITY, 10, -30, 0 },
    { "repeat, box turned, camera inside, haze", 2, 3, 2, 1, 0, 9, 2, 0, 0 },
    { "zero, from a clip plane 1.5 out, haze", 0, 3, 0, 1, 0, INFINITY, 2, -20, 1.5 },
    { "repeat, box turned, from a clip plane 4 out", 2, 3, 2, 0, 0, 9, 2, -10, 4 },
};

static void make_case(const lanes_case_t *c, fp_params_t *p, fp_fogmap_stage_t *st,
                      fp_integrate_data_t *d, float **img)
{
    const int w = 40, h = 24;
    fp_options_defaults(p);
    p->fog.density = 0.05;
    p->fog.height[0] = 1;
    p->fog.height[1] = c->flat ? INFINITY : 6;
    p->fog.height[2] = c->top;
    p->fog.haze = c->haze ? 0.01 : 0;
    p->fogmap.basis = 1;
    p->fogmap.wrap = c->wrap;
    p->fogmap.levels = c->levels;
    p->fogmap.rect[0] = -10;
    p->fogmap.rect[1] = -5;
    p->fogmap.rect[2] = -10 + w * 2;
    p->fogmap.rect[3] = -5 + h * 1.5;
    *img = malloc((size_t)w * h * sizeof(float));
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++)
            (*img)[j * w + i] = (float)(urand() * 2 * ((i / 4 + j / 4) % 3 != 0));
    assert_int_equal(fp_integrate_commit(p, d), FP_OK);
    assert_int_equal(fp_fogmap_setup(p, NULL, *img, w, h, st, d), FP_OK);
    if (c->boxed) {
        /* A moved, turned fog in a box (1: the camera outside it, 2: in it). */
        const double out[6] = { -5, -1, -5, 20, 8, 15 }, in[6] = { -20, -3, -20, 30, 6, 40 };
        for (int i = 0; i < 6; i++)
            d->fp[FP_F_BOX + i] = c->boxed == 1 ? out[i] : in[i];
        d->fp[FP_F_OFF] = 1.5;
        d->fp[FP_F_COS] = cos(0.3);
        d->fp[FP_F_SIN] = sin(0.3);
    }
}

static void test_lanes_against_reference(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    if (fp_cl_open(NULL, &cl) != FP_OK)
        skip();
    fp_integrate_cl_t s;
    assert_int_equal(fp_integrate_cl_init(cl, &s), FP_OK);
    const int w = 155, h = 61;   /* rows of 9 full work-items and one of 11 pixels */
    size_t n = (size_t)w * h;
    float *depth = malloc(n * sizeof(float)), *ref = malloc(n * 4 * sizeof(float)),
          *got = malloc(n * 4 * sizeof(float)), *one = malloc(n * 4 * sizeof(float));
    int *pix = malloc((n / 3 + 1) * sizeof *pix);
    float *lst = malloc((n / 3 + 1) * 4 * sizeof *lst);
    for (size_t k = 0; k < FP_ARRAY_LEN(cases); k++) {
        const lanes_case_t *c = &cases[k];
        fp_params_t p;
        fp_fogmap_stage_t st;
        fp_integrate_data_t d;
        float *img;
        make_case(c, &p, &st, &d, &img);
        fp_view_t v;
        assert_int_equal(make_view(&v, w, h, c->cam_y, c->pitch), 0);
        v.clip = c->clip;
        for (size_t i = 0; i < n; i++) {
            double u = urand();
            depth[i] = u < 0.05 ? INFINITY : (float)pow(10, -1 + 2.5 * urand());
        }
        /* The lanes' kernel is the one this look takes. */
        assert_true(fp_integrate_lanes_ok(&d, &v));
        assert_int_equal(fp_integrate_process(&d, &v, depth, ref, NULL), FP_OK);
        s.no_lanes = 0;
        assert_int_equal(fp_integrate_process_cl(&s, &d, &v, depth, got), FP_OK);
        s.no_lanes = 1;
        assert_int_equal(fp_integrate_process_cl(&s, &d, &v, depth, one), FP_OK);
        double worst = 0, worst_one = 0, vs_one = 0;
        for (size_t i = 0; i < n; i++) {
            double e = fabs((double)got[4 * i + 3] - ref[4 * i + 3]);
            worst = fmax(worst, e);
            worst_one = fmax(worst_one, fabs((double)one[4 * i + 3] - ref[4 * i + 3]));
            vs_one = fmax(vs_one, fabs((double)got[4 * i + 3] - one[4 * i + 3]));
            if (!(e <= 1e-5))
                fail_msg("%s: pixel %zu (%zu, %zu) depth %g: lanes %.9g ref %.9g", c->name, i,
                         i % w, i / w, depth[i], got[4 * i + 3], ref[4 * i + 3]);
            for (int ch = 0; ch < 3; ch++)
                if (!(fabs((double)got[4 * i + ch] - one[4 * i + ch]) <= 1e-5))
                    fail_msg("%s: pixel %zu channel %d: lanes %.9g, one ray %.9g", c->name, i,
                             ch, got[4 * i + ch], one[4 * i + ch]);
        }
        print_message("%s: lanes vs C reference max |dtau| %.2e (one ray a work-item %.2e; "
                      "lanes vs one ray %.2e; tolerance 1e-5)\n",
                      c->name, worst, worst_one, vs_one);
        /* A pixel list (every 3rd pixel, out of order): the frame's values. */
        size_t m = test_pixel_list(n, pix);
        s.no_lanes = 0;
        assert_int_equal(fp_integrate_pixels_cl(&s, &d, &v, depth, pix, m, lst), FP_OK);
        double list_diff = test_list_diff(got, pix, m, lst);
        print_message("%s: pixel list of %zu vs the whole frame %.2e (bound 0)\n", c->name, m,
                      list_diff);
        assert_true(list_diff == 0);
        fp_fogmap_release(&st);
        fp_options_free(&p);
        free(img);
    }
    free(depth);
    free(ref);
    free(got);
    free(one);
    free(pix);
    free(lst);
    fp_integrate_cl_release(&s);
    fp_cl_close(cl);
}

/* The looks the lanes do not take go on through integrate_fog. */
static void test_lanes_not_taken(void **state)
{
    (void)state;
    fp_params_t p;
    fp_fogmap_stage_t st;
    fp_integrate_data_t d;
    float *img;
    fp_view_t v;
    assert_int_equal(make_view(&v, 32, 16, 2, -20), 0);
    make_case(&cases[0], &p, &st, &d, &img);
    assert_true(fp_integrate_lanes_ok(&d, &v));
    const struct {
        int slot;
        double value;
    } off[] = { { FP_F_DEGREE, 3 }, { FP_F_WRAP, 1 }, { FP_F_MODE, 1 }, { FP_F_LOD_BOUND, 1e-4 },
                { FP_F_FOOTPRINT, 1 }, { FP_F_LOD_MU, 0.5 }, { FP_F_OD_MAX, 5 } };
    for (size_t k = 0; k < FP_ARRAY_LEN(off); k++) {
        fp_integrate_data_t e = d;
        e.fp[off[k].slot] = off[k].value;
        assert_false(fp_integrate_lanes_ok(&e, &v));
    }
    v.ortho = 1;
    assert_false(fp_integrate_lanes_ok(&d, &v));
    fp_fogmap_release(&st);
    fp_options_free(&p);
    free(img);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lanes_against_reference),
        cmocka_unit_test(test_lanes_not_taken),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

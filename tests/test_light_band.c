/* The fast rule's node optical depths from the heights of a stretch's
 * ends (kernels/light_band_lanes.h, issue 26) compiled in double, against
 * fp_light_height_od (kernels/scatter_core.h), the closed form of the C
 * reference, on random stretches of height fog: rising, falling, level
 * (dy 0 and 1e-9), crossing the fog's base y0 and its top or not, from
 * below, inside and above the band, profiles with a top, without one,
 * and without falloff (H infinite); the camera's side (fp_ln_band_cam, a
 * view ray from its origin to t) and the light's (fp_ln_band_light, from a
 * node toward the light), and a node's extinction (fp_ln_band_node)
 * against fp_light_plain_sigma.  Both sides take the series of
 * (1 - e^-x) / x below x = 1/8 and the difference of the ends' h above:
 * every comparison within 1e-10 of the stretch's optical depth (and
 * 1e-15 absolute: fp_light_ratio's own series, three terms below x =
 * 1e-3, is off by up to x^3 / 24 = 4e-11 there), the largest difference
 * and the count of stretches on each side of the switch printed. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fp.h"
#include "integrate.h"
#include "options.h"
#include "scatter.h"
#include "testutil.h"

#include "fog_core.h"
#include "light_core.h"
#include "scatter_core.h"
#include "scatter_lanes.h"

#include "light_rig.h"

/* A random direction's dy: rising, falling, level or nearly so. */
static double rand_dy(void)
{
    double u = urand();
    return u < 0.08 ? 0 : u < 0.16 ? (urand() < 0.5 ? 1e-9 : -1e-9) : 2 * urand() - 1;
}

typedef struct profile_t {
    double sigma, y0, H, top;
} profile_t;

static const profile_t profiles[] = {
    { 0.05, 0, 8, INFINITY },   /* night-street-lamps */
    { 0.02, 1, 4, 12 },
    { 0.2, 0, INFINITY, INFINITY },
    { 0.08, -2, 3, 6 },
    { 0.03, 1, 10, 25 },
};

static int within(double got, double want, double *worst)
{
    double d = fabs(got - want);
    double rel = d / fmax(fabs(want), 1e-3);
    *worst = fmax(*worst, isnan(rel) ? INFINITY : rel);
    return d <= 1e-10 * fabs(want) + 1e-15;
}

static void test_band_od(void **state)
{
    (void)state;
    fp_test_rng = 0x2545f4914f6cdd1dull;
    double worst_cam = 0, worst_light = 0;
    long n = 0, bad = 0, series = 0, diff = 0;
    for (size_t pi = 0; pi < FP_ARRAY_LEN(profiles); pi++) {
        const profile_t *p = &profiles[pi];
        for (int k = 0; k < 4000; k++) {
            /* The view ray from oy along dy, the node at t, the light at
             * the end of the node's stretch toward it (its own dy, r). */
            double oy = -4 + 32 * urand(), dy = rand_dy();
            double t = urand() < 0.05 ? 0 : 90 * urand() * urand();
            double py = oy + t * dy;
            double dyl = rand_dy(), r = 60 * urand() * urand();
            double yl = py + r * dyl;
            fp_ln_band_t b;
            fp_ln_band_init(&b, p->sigma, p->y0, p->H, p->top, oy, dy, yl);
            double hp = fp_ln_band_clamp(&b, fp_ln_band_h(&b, py));
            double cam = fp_ln_band_cam(&b, t, hp);
            double cam_ref = fp_light_height_od(p->sigma, p->y0, p->H, p->top, oy, dy, t);
            double ddy = fabs(dyl) > 1e-30 ? dyl : 1e-30;
            double light = fp_ln_band_light(&b, py, ddy, 1 / ddy, r, hp);
            double light_ref = fp_light_height_od(p->sigma, p->y0, p->H, p->top, py, dyl, r);
            int ok = within(cam, cam_ref, &worst_cam) & within(light, light_ref, &worst_light);
            if (!ok && bad++ < 5)
                print_message("profile %zu, oy %.6g dy %.3g t %.6g: camera %.17g (ref %.17g); "
                              "py %.6g dy %.3g r %.6g: light %.17g (ref %.17g)\n", pi, oy, dy,
                              t, cam, cam_ref, py, dyl, r, light, light_ref);
            /* Which side of the switch the light's stretch took. */
            double u0 = (p->y0 - py) / ddy, u1 = (p->top - py) / ddy;
            double w = fmax(fmin(fmax(u0, u1), r) - fmax(fmin(u0, u1), 0), 0);
            double x = fabs(dyl) * w / p->H;
            series += w > 0 && x < 0.125;
            diff += w > 0 && x >= 0.125;
            n++;
        }
    }
    print_message("node optical depths from the ends' heights (light_band_lanes.h, double) vs "
                  "fp_light_height_od: camera side max %.3g, light side max %.3g of the "
                  "stretch's optical depth over %ld stretches (%ld by the series, %ld by the "
                  "difference; bound 1e-10)\n", worst_cam, worst_light, n, series, diff);
    assert_true(series > n / 20 && diff > n / 20);
    assert_int_equal(bad, 0);
}

/* A node's extinction and both optical depths (fp_ln_band_node, the main
 * fog with an offset and the haze) against fp_light_plain_sigma and two
 * fp_light_plain_od, as fp_ln_fast took them before. */
static void test_band_node(void **state)
{
    (void)state;
    rig_t r;
    const char *opts[] = { "density", "0.05", "height", "0,8,20", "haze", "0.01", "haze-height",
                           "1,10,30", "fog-offset", "0,0.7,0", "fog-color", "0,0,0", "light",
                           "point:-4,3.5,6:1,0.55,0.2:30", NULL };
    rig_open(&r, opts);
    fp_test_rng = 0x9e3779b97f4a7c15ull;
    const double *fp = r.fog.fp, *row = r.sd.lights;
    double yoff = fp[FP_F_OFF + 1], worst = 0;
    int bad = 0;
    for (int k = 0; k < 3000; k++) {
        double o[3] = { 8 * urand() - 4, -1 + 24 * urand(), 30 * urand() - 10 };
        double d[3] = { 2 * urand() - 1, rand_dy(), 2 * urand() - 1 };
        double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int c = 0; c < 3; c++)
            d[c] /= l;
        double t = 70 * urand() * urand();
        double p[3] = { o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2] };
        double v[3] = { row[FP_LL_POS] - p[0], row[FP_LL_POS + 1] - p[1], row[FP_LL_POS + 2] - p[2] };
        double rr = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        fp_ln_band_t bm, bh;
        fp_ln_band_init(&bm, fp[FP_F_SIGMA], fp[FP_F_Y0], fp[FP_F_H], fp[FP_F_TOP], o[1] - yoff,
                        d[1], row[FP_LL_POS + 1] - yoff);
        fp_ln_band_init(&bh, fp[FP_F_HAZE], fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2],
                        fp[FP_F_HAZE + 3], o[1], d[1], row[FP_LL_POS + 1]);
        double sig, od;
        fp_ln_band_node(&bm, 1, &bh, 1, t, p[1] - yoff, p[1], -v[1] / rr, rr, &sig, &od);
        double sig_ref = fp_light_plain_sigma(fp, p[0], p[1], p[2]);
        double od_ref = fp_light_plain_od(fp, o[0], o[1], o[2], d[0], d[1], d[2], t) +
                        fp_light_plain_od(fp, p[0], p[1], p[2], v[0] / rr, v[1] / rr, v[2] / rr, rr);
        int ok = within(sig, sig_ref, &worst) & within(od, od_ref, &worst);
        if (!ok && bad++ < 5)
            print_message("node at (%.4g, %.4g, %.4g): sigma %.17g (ref %.17g), od %.17g "
                          "(ref %.17g)\n", p[0], p[1], p[2], sig, sig_ref, od, od_ref);
    }
    print_message("a node's extinction and optical depths (fp_ln_band_node, main fog with an "
                  "offset and a top, haze) vs fp_light_plain_sigma and fp_light_plain_od: max "
                  "%.3g relative over 3000 nodes (bound 1e-10)\n", worst);
    rig_close(&r);
    assert_int_equal(bad, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_band_od),
        cmocka_unit_test(test_band_node),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* Culling's closer bound (issue 26, kernels/cull_core.h): what a local
 * light can add to a view ray, with the phase function and the fog's
 * extinction bounded over the ray's stretch alone instead of everywhere.
 *
 *  1. the phase function's largest value over [m0, m1] (fp_phase_max_over)
 *     against a fine sampling of the interval, every kind: never below it,
 *     and equal to it at the ends where the kind is monotone;
 *  2. the extinction over a stretch (fp_light_sigma_span) against the
 *     extinction sampled along it, height fog with a top, haze, offsets,
 *     a box: never below;
 *  3. a street of 64 lamps (points, spots, areas), 600 random rays: the
 *     in-scatter (fp_light_ray) never above the bound, the bound never
 *     above the former one (pmax, sigma_max) and at least 3x below it on
 *     a fifth of the point lights, the lanes' version (compiled in
 *     double) equal to the C one.
 * Every comparison prints its figures. */
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

static void unit(double v[3])
{
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++)
        v[i] /= n;
}

static void test_phase_max_over(void **state)
{
    (void)state;
    static const double gs[] = { -0.9, -0.5, -0.1, 0, 0.2, 0.6, 0.8, 0.95 };
    long checked = 0;
    double worst = 0;
    fp_test_rng = 11;
    for (int kind = FP_PHASE_ISO; kind <= FP_PHASE_MIXHG; kind++)
        for (size_t gi = 0; gi < sizeof gs / sizeof gs[0]; gi++)
            for (int iv = 0; iv < 40; iv++) {
                double a = 2 * urand() - 1, b = 2 * urand() - 1, w = urand();
                if (iv == 0) {
                    a = -1;
                    b = 1;
                }
                double m0 = fmin(a, b), m1 = fmax(a, b), g = gs[gi];
                double bound = fp_phase_max_over(kind, g, w, m0, m1), top = 0;
                for (int s = 0; s <= 2000; s++)
                    top = fmax(top, fp_phase(kind, g, w, m0 + (m1 - m0) * s / 2000.0));
                if (!(top <= bound * (1 + 1e-12)))
                    fail_msg("kind %d g %g w %g [%g, %g]: phase reaches %.9g above the bound %.9g",
                             kind, g, w, m0, m1, top, bound);
                /* Monotone kinds: the bound is the phase at an end. */
                if ((kind == FP_PHASE_ISO || kind == FP_PHASE_HG || kind == FP_PHASE_RAYLEIGH) &&
                    !(bound <= top * (1 + 1e-12)))
                    fail_msg("kind %d g %g [%g, %g]: bound %.9g above the phase's largest %.9g",
                             kind, g, m0, m1, bound, top);
                worst = fmax(worst, bound / top);
                checked++;
            }
    print_message("phase bound over an interval: %ld intervals, never below the phase; at most "
                  "%.3fx its largest value (the kinds that are products)\n", checked, worst);
}

static void test_sigma_span(void **state)
{
    (void)state;
    static const char *const looks[][12] = {
        { "density", "0.05", "height", "0,3,15", NULL },
        { "density", "0.1", "height", "1,2", "haze", "0.02", "haze-height", "-2,5,30", NULL },
        { "density", "0.08", "height", "0,inf,4", "fog-offset", "3,1.5,-2", NULL },
        { "density", "0.05", "height", "0,4", "fog-box", "-5,-1,0,5,6,40", "haze", "0.01", NULL },
    };
    long checked = 0;
    double tight = INFINITY;
    for (size_t li = 0; li < sizeof looks / sizeof looks[0]; li++) {
        rig_t r;
        rig_open(&r, looks[li]);
        const double *fp = r.fog.fp;
        fp_test_rng = 5 + li;
        for (int k = 0; k < 400; k++) {
            double o[3] = { -6 + 12 * urand(), -1 + 8 * urand(), -5 + 20 * urand() };
            double d[3] = { urand() - 0.5, 1.2 * (urand() - 0.5), urand() - 0.2 }, ta, tb;
            unit(d);
            double len = k % 4 ? 3 + 60 * urand() : INFINITY;
            fp_light_span(fp, o[0], o[1], o[2], d[0], d[1], d[2], len, &ta, &tb);
            if (!(tb > ta))
                continue;
            double span = fp_light_sigma_span(fp, o[1], d[1], ta, tb), top = 0;
            double te = isinf(tb) ? ta + 200 : tb;
            for (int s = 0; s <= 1000; s++) {
                double t = ta + (te - ta) * s / 1000.0;
                top = fmax(top, fp_light_plain_sigma(fp, o[0] + t * d[0], o[1] + t * d[1],
                                                     o[2] + t * d[2]));
            }
            if (!(top <= span * (1 + 1e-12)))
                fail_msg("look %zu ray %d: extinction %.9g on the stretch above its bound %.9g",
                         li, k, top, span);
            if (!(span <= fp_light_sigma_max(fp)))
                fail_msg("look %zu ray %d: bound %.9g above the fog's largest extinction", li, k,
                         span);
            if (top > 0)
                tight = fmin(tight, span / top);
            checked++;
        }
        rig_close(&r);
    }
    assert_true(checked > 500);
    print_message("extinction over a stretch: %ld rays in 4 fogs, never below the extinction "
                  "sampled along them\n", checked);
}

/* The former bound (before issue 26): pmax and the fog's largest
 * extinction anywhere. */
static double former_bound(const double *lt, const double *row, double smax, double omt,
                           const double o[3], const double d[3], double ta, double tb)
{
    double q[3], tc = 0, rr[3];
    for (int i = 0; i < 3; i++)
        q[i] = row[FP_LL_POS + i] - o[i];
    for (int i = 0; i < 3; i++)
        tc += q[i] * d[i];
    for (int i = 0; i < 3; i++)
        rr[i] = q[i] - tc * d[i];
    double D = sqrt(rr[0] * rr[0] + rr[1] * rr[1] + rr[2] * rr[2]), rho = row[FP_LL_REACH];
    double th0 = atan((ta - tc) / D), th1 = isinf(tb) ? M_PI / 2 : atan((tb - tc) / D);
    double f = D / (D - rho);
    f *= f;
    return lt[FP_LT_ALBEDO] * row[FP_LL_IMAX] * lt[FP_LT_PMAX] *
           fmin(omt * f / (D * D), smax * (th1 - th0) * f / D);
}

static void test_street_bound(void **state)
{
    (void)state;
    rig_t r;
    enum { N = 64 };
    static char spec[N][200];
    const char *opts[2 * N + 16];
    int m = 0;
    static const char *const base[] = { "density", "0.04", "height", "0,3,15", "phase", "hg:0.6",
                                        "light-cull", "0", NULL };
    for (int i = 0; base[i]; i++)
        opts[m++] = base[i];
    for (int k = 0; k < N; k++) {
        double x = (k % 2 ? -4 : 4) + 0.5 * sin(k), z = 2 + 1.5 * k;
        if (k % 4 == 0 || k % 4 == 2)
            snprintf(spec[k], 200, "point:%g,3.5,%g:1,0.6,0.3:8%s", x, z, k % 4 ? ":0.1" : "");
        else if (k % 4 == 1)
            snprintf(spec[k], 200, "spot:%g,4,%g:1,1,0.8:30:0,-1,0:20,35", x, z);
        else
            snprintf(spec[k], 200, "area:%g,3,%g:1,0.9,0.7:6:0,-1,0:1,0,0:0.6,0.3", x, z);
        opts[m++] = "light";
        opts[m++] = spec[k];
    }
    opts[m] = NULL;
    rig_open(&r, opts);
    const double *fp = r.fog.fp, *lt = r.sd.lt;
    long checked = 0, points = 0, closer3 = 0;
    double worst = 0;
    fp_test_rng = 17;
    for (int k = 0; k < 600; k++) {
        double o[3] = { -6 + 12 * urand(), 0.3 + 3 * urand(), -5 + 20 * urand() };
        double d[3] = { urand() - 0.5, 0.4 * (urand() - 0.5), 2 * urand() - 1 }, ta, tb;
        unit(d);
        double len = k % 5 ? 3 + 80 * urand() : INFINITY;
        fp_light_span(fp, o[0], o[1], o[2], d[0], d[1], d[2], len, &ta, &tb);
        if (!(tb > ta))
            continue;
        double od = fp_fog_od(fp, NULL, NULL, NULL, NULL, o[0], o[1], o[2], d[0], d[1], d[2],
                              len, 0);
        double omt = -expm1(-od), smax = fp_light_sigma_span(fp, o[1], d[1], ta, tb);
        for (int l = 0; l < N; l++) {
            const double *row = r.sd.lights + l * FP_LL_STRIDE;
            double S[3];
            fp_light_ray(fp, lt, r.sd.lights, l, o[0], o[1], o[2], d[0], d[1], d[2], len, S);
            double b = fp_light_bound(lt, row, smax, omt, o[0], o[1], o[2], d[0], d[1], d[2], ta,
                                      tb);
            double bl = fp_ln_bound(lt, row, smax, omt, o[0], o[1], o[2], d[0], d[1], d[2], ta,
                                    tb);
            double s = fmax(S[0], fmax(S[1], S[2]));
            if (!(s <= b * (1 + 1e-9) + 1e-15))
                fail_msg("ray %d light %d: in-scatter %.9g above its bound %.9g", k, l, s, b);
            if (!(fabs(bl - b) <= 1e-9 * b) && !(isinf(b) && isinf(bl)))
                fail_msg("ray %d light %d: lanes' bound %.9g, C's %.9g", k, l, bl, b);
            if (!isfinite(b) || b == 0)
                continue;
            double old = former_bound(lt, row, fp_light_sigma_max(fp), omt, o, d, ta, tb);
            if (!(b <= old * (1 + 1e-9)))
                fail_msg("ray %d light %d: bound %.9g above the former %.9g", k, l, b, old);
            if (s > 0)
                worst = fmax(worst, s / b);
            checked++;
            if ((int)row[FP_LL_TYPE] == FP_LIGHT_POINT) {
                points++;
                closer3 += b * 3 <= old;
            }
        }
    }
    print_message("street of %d lamps: %ld light-ray pairs, the in-scatter never above the bound "
                  "(at most %.3g of it); on %ld of %ld point-light pairs the bound is at least 3x "
                  "below the former one\n", N, checked, worst, closer3, points);
    assert_true(points > 1000);
    assert_true(closer3 * 5 >= points);
    rig_close(&r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_phase_max_over),
        cmocka_unit_test(test_sigma_span),
        cmocka_unit_test(test_street_bound),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* The fast multiple-scattering path (filters/ms.c, kernels/ms_core.h;
 * issue 28):
 *
 *  1. the plane-parallel solution J_ms(height) against an independent
 *     Monte Carlo photon simulation of the same slab (isotropic, albedo
 *     0.9, ground albedo 0.3, optical depth 1 and 4);
 *  2. the view ray's integral (fp_ms_ray, 12 segments) against brute-force
 *     quadrature of albedo int tau sigma_t E J_ms V dt (V: the grid's share);
 *  3. the box's sides take light away (J_ms smaller in a narrow box), and
 *     the grid's share is below 1 near a side;
 *  4. --fog-color auto and --multiple-scattering: what each gives;
 *     parsing.
 * The OpenCL kernel against the C path: tests/msfast.sh (whole frames).
 * Every comparison prints its measured error next to its tolerance. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "fp.h"
#include "integrate.h"
#include "ms.h"
#include "options.h"
#include "options_all.h"
#include "scatter.h"

#include "fog_core.h"
#include "light_core.h"
#include "ms_core.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* A homogeneous slab of extinction 1 between y = 0 and y = T, infinitely
 * wide (or in a box of half-width `half`). */
static void slab(double *fp, double T, double half)
{
    memset(fp, 0, FP_F_COUNT * sizeof *fp);
    fp[FP_F_SIGMA] = 1;
    fp[FP_F_Y0] = 0;
    fp[FP_F_H] = INFINITY;
    fp[FP_F_TOP] = INFINITY;
    fp[FP_F_COS] = 1;
    fp[FP_F_SIN] = 0;
    double box[6] = { -half, 0, -half, half, T, half };
    memcpy(fp + FP_F_BOX, box, sizeof box);
    fp[FP_F_HAZE + 2] = INFINITY;
    fp[FP_F_HAZE + 3] = INFINITY;
    fp[FP_F_CAP] = 1e6;
}

/* J from a table (fp_ms_solve's nodes). */
static double table_j(const double *J, double yb, double dy, double y)
{
    double u = fmin(fmax((y - yb) / dy, 0), FP_MS_NODES - 1);
    int i = (int)u < FP_MS_NODES - 1 ? (int)u : FP_MS_NODES - 2;
    return J[i] + (u - i) * (J[i + 1] - J[i]);
}

static double urand(unsigned long long *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return ((*s >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

/* Monte Carlo: photons of the sun (irradiance 1, cosine mu0) into the
 * slab [0, T] of optical depth (tau down from the top), isotropic
 * scattering with albedo w, a Lambertian ground of albedo A; the scalar
 * flux of the scattered light per bin (track-length estimator), over
 * 4 pi: J per bin. */
static void photons(double T, double w, double A, double mu0, long n, int nb, double *J)
{
    unsigned long long s = 12345;
    double *acc = calloc(nb, sizeof *acc);
    double bw = T / nb;
    for (long k = 0; k < n; k++) {
        double tau = 0, mu = mu0, wt = 1;
        int diffuse = 0;
        for (int ev = 0; ev < 10000; ev++) {
            double step = -log(urand(&s));
            double t1 = tau + mu * step;
            int ground = t1 >= T, top = t1 <= 0;
            double te = ground ? T : top ? 0 : t1;
            if (diffuse) {
                double lo = fmin(tau, te), hi = fmax(tau, te);
                for (int b = (int)(lo / bw); b < nb && b * bw < hi; b++) {
                    double ov = fmin(hi, (b + 1) * bw) - fmax(lo, b * bw);
                    if (ov > 0)
                        acc[b] += wt * ov / fabs(mu);
                }
            }
            if (top)
                break;
            tau = te;
            if (ground) {
                wt *= A;
                mu = -sqrt(urand(&s));
            } else {
                wt *= w;
                mu = 2 * urand(&s) - 1;
            }
            diffuse = 1;
            if (wt < 1e-3) {
                if (urand(&s) > 0.1)
                    break;
                wt *= 10;
            }
        }
    }
    for (int b = 0; b < nb; b++)
        J[b] = acc[b] * mu0 / n / bw / (4 * M_PI);
    free(acc);
}

static void test_slab_monte_carlo(void **state)
{
    (void)state;
    const double Ts[2] = { 1, 4 }, w = 0.9, A = 0.3;
    const double sun[3] = { 0, 0.5, sqrt(0.75) };
    for (int c = 0; c < 2; c++) {
        double T = Ts[c], fp[FP_F_COUNT], J[FP_MS_NODES], yb, dy, jm;
        slab(fp, T, INFINITY);
        assert_int_equal(fp_ms_solve(fp, w, 0, sun, A, J, &yb, &dy, &jm), 0);
        enum { NB = 10 };
        double mc[NB];
        photons(T, w, A, sun[1], 400000, NB, mc);
        double worst = 0;
        for (int b = 0; b < NB; b++) {
            /* bin b: tau in [b, b + 1] T / NB from the top; y = T - tau.
             * The table's mean over the bin (J is not linear in it). */
            double s = 0;
            for (int q = 0; q < 16; q++)
                s += table_j(J, yb, dy, T - (b + (q + 0.5) / 16) * T / NB);
            double e = s / 16 / mc[b] - 1;
            worst = fmax(worst, fabs(e));
            print_message("slab tau* %g, bin %d: J_ms %.5f, Monte Carlo %.5f (%+.3f)\n", T, b,
                          s / 16, mc[b], e);
        }
        print_message("slab tau* %g: largest relative difference %.4f; tolerance 0.02 (the "
                      "photons' noise is about 0.003)\n", T, worst);
        assert_true(worst < 0.02);
    }
}

#include "light_rig.h"

/* rig_open, then the frame's multiple-scattering tables. */
static int rig_open_ms(rig_t *r, const char *const *opts)
{
    rig_open(r, opts);
    return fp_ms_frame(&r->p, r->sd.lt, r->fog.fp, NULL);
}

static double ray(const rig_t *r, const double o[3], const double d[3], double len, double S[3])
{
    fp_view_t nov;
    memset(&nov, 0, sizeof nov);
    return fp_scatter_ray(&r->sd, &r->fog, &nov, NULL, NULL, o, d, len, S);
}

static void test_ray_integral(void **state)
{
    (void)state;
    static const char *const base[] = { "density", "0.1", "height", "0.5,2.5", "fog-box",
                                        "-20,-20,-0.05,20,20,8", "sun", "0,0.31,-1", "sun-intensity",
                                        "3", "albedo", "0.8", "phase", "hg:0.5", NULL, NULL,
                                        NULL };
    const char *on[20], *off[20];
    int n = 0;
    for (; base[n]; n++)
        on[n] = off[n] = base[n];
    on[n] = off[n] = "multiple-scattering";
    on[n + 1] = "on";
    off[n + 1] = "off";
    on[n + 2] = off[n + 2] = "fog-color";
    on[n + 3] = off[n + 3] = "0,0,0";
    on[n + 4] = off[n + 4] = NULL;
    rig_t a, b;
    assert_int_equal(rig_open_ms(&a, on), FP_OK);
    assert_int_equal(rig_open_ms(&b, off), FP_OK);
    assert_true(a.sd.lt[FP_LT_MS_ON] == 1 && b.sd.lt[FP_LT_MS_ON] == 0);
    const double *lt = a.sd.lt, *fp = a.fog.fp;
    /* Rays: level, down to the ground, up to the sky, grazing. */
    const double rays[4][7] = { { 0, 1.7, -7, 0, 0, 1, 30 },
                                { 0, 1.7, -7, 0, -0.12, 1, INFINITY },
                                { 0, 1.7, -7, 0.2, 0.3, 1, INFINITY },
                                { -3, 6, -15, 0.3, -0.25, 1, 60 } };
    double worst = 0;
    for (int k = 0; k < 4; k++) {
        double o[3] = { rays[k][0], rays[k][1], rays[k][2] }, d[3] = { rays[k][3], rays[k][4],
                                                                          rays[k][5] };
        double nn = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int i = 0; i < 3; i++)
            d[i] /= nn;
        double len = rays[k][6];
        /* Down: to the ground (y = 0). */
        if (d[1] < 0 && !isfinite(len))
            len = -o[1] / d[1];
        double Sa[3], Sb[3];
        ray(&a, o, d, len, Sa);
        ray(&b, o, d, len, Sb);
        double got = Sa[0] - Sb[0];
        /* Brute force: midpoints, 200000 steps over [0, min(len, 200)]. */
        double L = fmin(len, 200), h = L / 200000, od = 0, want = 0;
        for (int i = 0; i < 200000; i++) {
            double t = (i + 0.5) * h;
            double x = o[0] + t * d[0], y = o[1] + t * d[1], z = o[2] + t * d[2];
            double sg = fp_sigma_t(fp, NULL, NULL, NULL, x, y, z);
            double ds = sg * h;
            want += exp(-od - 0.5 * ds) * ds * fp_ms_j(lt, y) * fp_ms_vis(fp, lt, x, y, z);
            od += ds;
        }
        want *= lt[FP_LT_ALBEDO] * lt[FP_LT_SUN_E];
        double e = fabs(got / want - 1);
        worst = fmax(worst, e);
        print_message("ray %d: multiple scattering %.6g, brute force %.6g (%.2e)\n", k, got, want,
                      e);
        assert_true(want > 0);
    }
    print_message("fp_ms_ray against brute force: largest relative error %.2e; tolerance 5e-3\n",
                  worst);
    assert_true(worst < 5e-3);
    rig_close(&a);
    rig_close(&b);
}

static void test_box_sides(void **state)
{
    (void)state;
    const double sun[3] = { 0, 0.31, -0.95 };
    double fp[FP_F_COUNT], Jw[FP_MS_NODES], Jn[FP_MS_NODES], yb, dy, jm;
    slab(fp, 3, INFINITY);
    fp[FP_F_SIGMA] = 0.1;
    assert_int_equal(fp_ms_solve(fp, 1, 0, sun, 0, Jw, &yb, &dy, &jm), 0);
    slab(fp, 3, 10);
    fp[FP_F_SIGMA] = 0.1;
    assert_int_equal(fp_ms_solve(fp, 1, 0, sun, 0, Jn, &yb, &dy, &jm), 0);
    double rw = Jn[FP_MS_NODES / 2] / Jw[FP_MS_NODES / 2];
    print_message("J_ms at mid-height, a 20 m wide box over an infinite slab: %.3f (expected "
                  "below 0.95: the mean free path is 10 m)\n", rw);
    assert_true(rw < 0.95 && rw > 0.5);
    /* The grid: near a side less than at the center. */
    static const char *const opts[] = { "density", "0.1", "height", "0,inf", "fog-box",
                                        "-10,0,-10,10,3,10", "sun", "0,0.31,-1",
                                        "fog-color", "auto", NULL };
    rig_t r;
    assert_int_equal(rig_open_ms(&r, opts), FP_OK);
    const double *lt = r.sd.lt;
    assert_true(lt[FP_LT_MS_ON] == 1 && lt[FP_LT_MS_GON] == 1);
    double vc = fp_ms_vis(r.fog.fp, lt, 0, 1, 0), ve = fp_ms_vis(r.fog.fp, lt, 9.9, 1, 0);
    print_message("the grid's share at the center %.3f, at a side %.3f\n", vc, ve);
    assert_true(fabs(vc - 1) < 0.05 && ve < 0.85 * vc);
    rig_close(&r);
}

static void test_fog_color_auto(void **state)
{
    (void)state;
    /* No fog color given, a sun: the fast path on, no ambient. */
    static const char *const a[] = { "density", "0.05", "height", "0,3", "sun", "0,0.5,-1",
                                     NULL };
    rig_t r;
    assert_int_equal(rig_open_ms(&r, a), FP_OK);
    assert_true(r.sd.lt[FP_LT_MS_ON] == 1);
    assert_true(r.sd.lt[FP_LT_AMB] == 0 && r.sd.lt[FP_LT_AMB + 2] == 0);
    rig_close(&r);
    /* A typed fog color: the old model (off, the color as typed). */
    static const char *const b[] = { "density", "0.05", "height", "0,3", "sun", "0,0.5,-1",
                                     "fog-color", "0.1,0.2,0.3", NULL };
    assert_int_equal(rig_open_ms(&r, b), FP_OK);
    assert_true(r.sd.lt[FP_LT_MS_ON] == 0);
    assert_true(fabs(r.sd.lt[FP_LT_AMB + 1] - 0.2) < 1e-12);
    rig_close(&r);
    /* auto with the fast path off: the column's mean, per sun color. */
    static const char *const c[] = { "density", "0.05", "height", "0,3", "sun", "0,0.5,-1",
                                     "sun-color", "1,0.5,0.25", "fog-color", "auto",
                                     "multiple-scattering", "off", NULL };
    assert_int_equal(rig_open_ms(&r, c), FP_OK);
    double amb = r.sd.lt[FP_LT_AMB];
    print_message("--fog-color auto, --multiple-scattering off: ambient %.5f per unit sun\n", amb);
    assert_true(r.sd.lt[FP_LT_MS_ON] == 0 && amb > 1e-3 && amb < FP_INV_4PI);
    assert_true(fabs(r.sd.lt[FP_LT_AMB + 1] - 0.5 * amb) < 1e-12);
    rig_close(&r);
    /* No sun: the old constant. */
    static const char *const d[] = { "density", "0.05", NULL };
    assert_int_equal(rig_open_ms(&r, d), FP_OK);
    assert_true(fabs(r.sd.lt[FP_LT_AMB] - 0.7) < 1e-12 && r.fog.fog_color[2] == 0.8);
    rig_close(&r);
    /* Parsing. */
    fp_params_t p;
    fp_options_defaults(&p);
    assert_int_equal(p.ms.color_typed, 0);
    assert_int_equal(p.ms.mode, FP_MS_AUTO);
    assert_int_not_equal(fp_options_apply(&p, "fog-color", "0.1,0.2", "test"), FP_OK);
    assert_int_not_equal(fp_options_apply(&p, "fog-color", "0.1,0.2,x", "test"), FP_OK);
    assert_int_not_equal(fp_options_apply(&p, "fog-color", "-1,0,0", "test"), FP_OK);
    assert_int_not_equal(fp_options_apply(&p, "multiple-scattering", "maybe", "test"), FP_OK);
    assert_int_equal(fp_options_apply(&p, "fog-color", "1,2,3", "test"), FP_OK);
    assert_int_equal(p.ms.color_typed, 1);
    assert_int_equal(fp_options_apply(&p, "fog-color", "auto", "test"), FP_OK);
    assert_int_equal(p.ms.color_typed, 0);
    fp_options_free(&p);
}

int main(void)
{
    fp_quiet = 1;
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_slab_monte_carlo),
        cmocka_unit_test(test_ray_integral),
        cmocka_unit_test(test_box_sides),
        cmocka_unit_test(test_fog_color_auto),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

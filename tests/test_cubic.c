/* The cubic basis' segment in closed form (kernels/fogmap_cubic.h, issue
 * 26) against the generic path it replaces in the walk (the cell's power
 * basis, fp_cell_poly, and one series per moment, fp_poly_exp_integral),
 * both in double, over random cells and segments; and against a fine
 * quadrature of the segment's definition, F(x) exp(-u x) with F the sum of
 * the 16 coefficients times the B-spline weights (bspline.h). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>

#include "fog_core.h"

/* Uniform in [0, 1) (xorshift; the same numbers every run). */
static double urand(void)
{
    static uint64_t x = 88172645463325252ull;
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    return (double)(x >> 11) / 9007199254740992.0;
}

/* A random segment of a cell: coefficients, start, step (the end inside
 * the cell), exponent. */
static void random_seg(double *c, double *px, double *qx, double *py, double *qy, double *u,
                       int k)
{
    /* Signed coefficients every other time (a level's detail is signed). */
    for (int i = 0; i < 16; i++)
        c[i] = k & 1 ? 4 * urand() - 2 : 3 * urand();
    *px = urand();
    *py = urand();
    double ex = urand(), ey = urand();
    if (k % 5 == 0)
        ex = *px;                     /* along y only */
    if (k % 7 == 0)
        ey = *py + 1e-9 * (urand() - 0.5);   /* nearly along x */
    if (ey < 0)
        ey = 0;
    *qx = ex - *px;
    *qy = ey - *py;
    *u = k % 3 == 0 ? 0 : FP_SEG_U * (2 * urand() - 1);
}

/* The generic path of fp_grid_walk (d != 1). */
static double generic_seg(const double *c, double px, double qx, double py, double qy, double u)
{
    double P[7];
    fp_cell_poly(3, c, px, qx, py, qy, P);
    return fp_poly_exp_integral(P, 3, u);
}

/* Composite Simpson of the definition, n panels. */
static double simpson_seg(const double *c, double px, double qx, double py, double qy, double u,
                          int n)
{
    double sum = 0;
    for (int i = 0; i <= 2 * n; i++) {
        double x = (double)i / (2 * n), wx[4], wy[4], f = 0;
        fp_bspline_weights(3, px + qx * x, wx);
        fp_bspline_weights(3, py + qy * x, wy);
        for (int j = 0; j < 4; j++)
            for (int k = 0; k < 4; k++)
                f += c[j * 4 + k] * wx[k] * wy[j];
        double wgt = i == 0 || i == 2 * n ? 1 : i & 1 ? 4 : 2;
        sum += wgt * f * exp(-u * x);
    }
    return sum / (6.0 * n);
}

static void test_cubic_seg_matches_generic(void **state)
{
    (void)state;
    double worst = 0, worst_e = 0;
    for (int k = 0; k < 200000; k++) {
        double c[16], px, qx, py, qy, u, E = -1;
        random_seg(c, &px, &qx, &py, &qy, &u, k);
        double got = fp_cubic_seg(c, px, qx, py, qy, u, &E);
        double want = generic_seg(c, px, qx, py, qy, u);
        double scale = 0;
        for (int i = 0; i < 16; i++)
            scale += fabs(c[i]);
        double e = fabs(got - want) / scale;
        worst = fmax(worst, e);
        worst_e = fmax(worst_e, fabs(E - exp(-u)));
        if (!(e <= 1e-14))
            fail_msg("segment %d: closed form %.17g, generic %.17g (|d| / sum |c| %.3g, "
                     "tolerance 1e-14)", k, got, want, e);
        if (!(fabs(E - exp(-u)) <= 1e-15))
            fail_msg("segment %d: E %.17g, exp(-u) %.17g (tolerance 1e-15)", k, E, exp(-u));
    }
    print_message("cubic segment, closed form vs generic (double, 200000 segments): max |d| / "
                  "sum |c| %.2e (tolerance 1e-14), max |E - exp(-u)| %.1e (tolerance 1e-15)\n",
                  worst, worst_e);
}

static void test_cubic_seg_matches_quadrature(void **state)
{
    (void)state;
    double worst = 0;
    for (int k = 0; k < 2000; k++) {
        double c[16], px, qx, py, qy, u, E;
        random_seg(c, &px, &qx, &py, &qy, &u, k);
        double got = fp_cubic_seg(c, px, qx, py, qy, u, &E);
        /* Simpson with 400 panels: error below 1e-12 of sum |c| here (the
         * integrand's fourth derivative is a few sum |c|). */
        double want = simpson_seg(c, px, qx, py, qy, u, 400);
        double scale = 0;
        for (int i = 0; i < 16; i++)
            scale += fabs(c[i]);
        double e = fabs(got - want) / scale;
        worst = fmax(worst, e);
        if (!(e <= 1e-11))
            fail_msg("segment %d: closed form %.17g, Simpson %.17g (|d| / sum |c| %.3g, "
                     "tolerance 1e-11)", k, got, want, e);
    }
    print_message("cubic segment, closed form vs Simpson (400 panels, 2000 segments): max |d| / "
                  "sum |c| %.2e (tolerance 1e-11)\n", worst);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cubic_seg_matches_generic),
        cmocka_unit_test(test_cubic_seg_matches_quadrature),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

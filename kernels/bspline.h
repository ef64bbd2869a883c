/* fogpipe: centered uniform B-splines of degree 0..3, shared by the C
 * reference (double) and the OpenCL kernels (float).
 *
 * The fog function (DESIGN, Conventions; seed 000 sec. 3.2, 4.1) is
 *     F(u,v) = sum_ij c_ij b_d(u - i - 1/2) b_d(v - j - 1/2)
 * with b_d the centered B-spline of degree d:
 *     b_0 = box on [-1/2, 1/2)            b_1 = hat on [-1, 1]
 *     b_2 = quadratic on [-3/2, 3/2]      b_3 = cubic on [-2, 2]
 *
 * Per-cell pieces.  On a level grid whose basis function i is centered at
 * grid coordinate x = i (domain coordinate origin + cell * i, see
 * filters/wavelet.h), a sum  sum_i c_i b_d(x - i)  is one polynomial of
 * degree d between consecutive knots.  The knots are at integer x for odd
 * d and at half-integer x for even d, so with
 *     y = x + FP_BSPLINE_SHIFT(d)      (SHIFT = 1/2 for even d, 0 for odd d)
 *     k = floor(y),  s = y - k in [0, 1)
 * "cell k" is the knot interval x in [k - SHIFT, k + 1 - SHIFT), and there
 *     sum_i c_i b_d(x - i) = sum_{j=0..d} w_j(s) c_{k - FP_BSPLINE_FIRST(d) + j}
 * with FP_BSPLINE_FIRST(d) = d/2 (integer division) and w_j the uniform
 * B-spline blending polynomials of fp_bspline_weights():
 *     d = 0: coefficient k                    w = 1
 *     d = 1: coefficients k, k+1              w = (1-s, s)
 *     d = 2: coefficients k-1, k, k+1         w = ((1-s)^2, 1 + 2s - 2s^2, s^2) / 2
 *     d = 3: coefficients k-1, k, k+1, k+2    w = ((1-s)^3, 3s^3 - 6s^2 + 4,
 *                                                  -3s^3 + 3s^2 + 3s + 1, s^3) / 6
 * i.e. w_j(s) = b_d(s - SHIFT + FP_BSPLINE_FIRST(d) - j).  The same
 * polynomials in the power basis, w_j(s) = sum_p a_jp s^p, come from
 * fp_bspline_poly(), for exact integration along a ray crossing the cell.
 *
 * Usable from C (FP_REAL = double, functions static inline) and OpenCL C
 * (FP_REAL = float). */
#ifndef FP_BSPLINE_H
#define FP_BSPLINE_H

#ifdef __OPENCL_VERSION__
#ifndef FP_REAL
#define FP_REAL float
#endif
#define FP_BSPLINE_FN inline
#ifndef FP_LIT
#define FP_LIT(x) x##f          /* single-precision literal: no double on the device */
#endif
#else
#include <math.h>
#ifndef FP_REAL
#define FP_REAL double
#endif
#define FP_BSPLINE_FN static inline
#ifndef FP_LIT
#define FP_LIT(x) x
#endif
#endif

/* Highest supported degree; d + 1 <= 4 weights per cell. */
#define FP_BSPLINE_MAX_DEGREE 3
/* Knot shift: cell k covers x in [k - SHIFT, k + 1 - SHIFT) (see above). */
#define FP_BSPLINE_SHIFT(d) (((d) & 1) ? (FP_REAL)0 : FP_LIT(0.5))
/* Index of the first coefficient of cell k, relative to k. */
#define FP_BSPLINE_FIRST(d) ((d) / 2)

/* Value of the centered B-spline b_d at x (support [-(d+1)/2, (d+1)/2]).
 * b_0 is 1 on [-1/2, 1/2) so that the boxes tile the line; d outside
 * 0..3 gives 0. */
FP_BSPLINE_FN FP_REAL fp_bspline(int d, FP_REAL x)
{
    FP_REAL a = x < 0 ? -x : x;
    FP_REAL t;
    switch (d) {
    case 0:
        return (x >= -FP_LIT(0.5) && x < FP_LIT(0.5)) ? (FP_REAL)1 : (FP_REAL)0;
    case 1:
        return a < 1 ? 1 - a : (FP_REAL)0;
    case 2:
        if (a < FP_LIT(0.5))
            return FP_LIT(0.75) - a * a;
        t = FP_LIT(1.5) - a;
        return a < FP_LIT(1.5) ? FP_LIT(0.5) * t * t : (FP_REAL)0;
    case 3:
        if (a < 1)
            return (FP_REAL)2 / 3 - a * a + FP_LIT(0.5) * a * a * a;
        t = 2 - a;
        return a < 2 ? t * t * t / 6 : (FP_REAL)0;
    default:
        return 0;
    }
}

/* Weights w[0..d] of the d + 1 coefficients overlapping a cell, at local
 * position s in [0, 1) (see the header comment for which coefficients).
 * w[d+1..3] are set to 0.  They sum to 1 and are >= 0 on [0, 1]. */
FP_BSPLINE_FN void fp_bspline_weights(int d, FP_REAL s, FP_REAL w[4])
{
    FP_REAL r = 1 - s;
    w[0] = 1;
    w[1] = w[2] = w[3] = 0;
    switch (d) {
    case 1:
        w[0] = r;
        w[1] = s;
        break;
    case 2:
        w[0] = FP_LIT(0.5) * r * r;
        w[2] = FP_LIT(0.5) * s * s;
        w[1] = FP_LIT(0.5) + s * r;
        break;
    case 3:
        w[0] = r * r * r / 6;
        w[3] = s * s * s / 6;
        w[1] = ((3 * s - 6) * s * s + 4) / 6;
        w[2] = (((-3 * s + 3) * s + 3) * s + 1) / 6;
        break;
    default:
        break;
    }
}

/* Power-basis coefficients of w_j (0 <= j <= d): w_j(s) = sum_{p=0..3}
 * a[p] s^p (a[p] = 0 for p > d).  Rows of the uniform B-spline basis
 * matrix; equal to fp_bspline_weights() term by term. */
FP_BSPLINE_FN void fp_bspline_poly(int d, int j, FP_REAL a[4])
{
    a[0] = a[1] = a[2] = a[3] = 0;
    switch (d * 4 + j) {
    case 0:                         /* d = 0 */
        a[0] = 1;
        break;
    case 4:                         /* d = 1: 1 - s, s */
        a[0] = 1;
        a[1] = -1;
        break;
    case 5:
        a[1] = 1;
        break;
    case 8:                         /* d = 2: (1 - 2s + s^2)/2, (1 + 2s - 2s^2)/2, s^2/2 */
        a[0] = FP_LIT(0.5);
        a[1] = -1;
        a[2] = FP_LIT(0.5);
        break;
    case 9:
        a[0] = FP_LIT(0.5);
        a[1] = 1;
        a[2] = -1;
        break;
    case 10:
        a[2] = FP_LIT(0.5);
        break;
    case 12:                        /* d = 3: (1 - 3s + 3s^2 - s^3)/6, ... */
        a[0] = (FP_REAL)1 / 6;
        a[1] = -FP_LIT(0.5);
        a[2] = FP_LIT(0.5);
        a[3] = (FP_REAL)-1 / 6;
        break;
    case 13:                        /* (4 - 6s^2 + 3s^3)/6 */
        a[0] = (FP_REAL)2 / 3;
        a[2] = -1;
        a[3] = FP_LIT(0.5);
        break;
    case 14:                        /* (1 + 3s + 3s^2 - 3s^3)/6 */
        a[0] = (FP_REAL)1 / 6;
        a[1] = FP_LIT(0.5);
        a[2] = FP_LIT(0.5);
        a[3] = -FP_LIT(0.5);
        break;
    case 15:                        /* s^3/6 */
        a[3] = (FP_REAL)1 / 6;
        break;
    default:
        break;
    }
}

/* Cell of grid coordinate x (basis i centered at x = i): *k and the local
 * s in [0, 1), so that the overlapping coefficients are
 * k - FP_BSPLINE_FIRST(d) + j, j = 0..d. */
FP_BSPLINE_FN void fp_bspline_cell(int d, FP_REAL x, int *k, FP_REAL *s)
{
    FP_REAL y = x + FP_BSPLINE_SHIFT(d);
    FP_REAL f = floor(y);
    *k = (int)f;
    *s = y - f;
}

#endif

/* fogpipe: one segment of the walk over a cubic B-spline surface in closed
 * form, without the power basis of the cell (issue 26: the cubic basis'
 * exact self-shadowing cost 9x the linear one's).  Included by
 * fogmap_walk.h; compiled twice like it (OpenCL C in single precision, C in double).
 * It uses none of fogmap_walk.h's functions (its own series below), so the
 * two are not a circle (tools/layers.py).
 *
 * On a segment from local cell coordinates (px, py) to (px + qx, py + qy),
 * x in [0, 1], the surface is F(x) = sum_ji c_ji w_i(px + qx x) w_j(py + qy x)
 * (bspline.h: w the cubic blending polynomials), a polynomial of degree 6
 * in x, and h = h_a exp(-u x).  The generic path (fp_cell_poly) turns the
 * cell's 16 coefficients into the power basis, B^T C B, then into a
 * polynomial in x, and the moments m_k(u) = int_0^1 x^k exp(-u x) dx one
 * series each: some 560 operations a segment, against 60 for a bilinear
 * cell.  Here:
 *  - each row's cubic spline along x straight as its Taylor polynomial at
 *    px (a cubic B-spline's derivatives are the splines of its
 *    coefficients' differences, one degree lower):
 *        R(px + qx x) = R0 + R1 x + R2 x^2 + R3 x^3,
 *        R0 = sum_i c_i w_i(px)                         (the value)
 *        R1 = qx sum_i (c_{i+1} - c_i) v_i(px)          (v: the quadratic weights)
 *        R2 = qx^2 / 2 (D2_0 + px D3)                   (D2_i: second differences)
 *        R3 = qx^3 / 6 D3                               (D3: the third difference)
 *    then the same along y for each power of x of the four rows: the
 *    coefficient of x^(a+b) gathers S_ab;
 *  - the moments by the downward recurrence (integration by parts)
 *        m_{k-1} = (exp(-u) + u m_k) / k,
 *    stable for |u| <= FP_SEG_U (each step multiplies an error by u / k),
 *    from m_6 alone by its series, FP_CUBIC_TERMS terms (as many as
 *    fp_poly_exp_integral's: remainder below FP_SEG_U^J / J!).
 * Some 290 operations; the same integral up to rounding (tests/test_fogmap.c,
 * test_cubic_seg, against fp_cell_poly + fp_poly_exp_integral). */
#ifndef FP_FOGMAP_CUBIC_H
#define FP_FOGMAP_CUBIC_H

#include "fog_params.h"

#ifdef __OPENCL_VERSION__
#define FP_CUBIC_TERMS 7      /* 0.25^7 / 7! = 1.2e-8 */
#else
#define FP_CUBIC_TERMS 13     /* 0.25^13 / 13! = 2e-18 */
#endif

/* 1 / (j! (7 + j)), j = 0..15: the series of m_6(u) = sum_j (-u)^j / (j! (7 + j)). */
FP_TABLE fp_real fp_m6_series[16] = {
    1.0 / 7, 1.0 / 8, 1.0 / (2 * 9), 1.0 / (6 * 10), 1.0 / (24 * 11), 1.0 / (120 * 12),
    1.0 / (720 * 13), 1.0 / (5040 * 14), 1.0 / (40320.0 * 15), 1.0 / (362880.0 * 16),
    1.0 / (3628800.0 * 17), 1.0 / (39916800.0 * 18), 1.0 / (479001600.0 * 19),
    1.0 / (6227020800.0 * 20), 1.0 / (87178291200.0 * 21), 1.0 / (1307674368000.0 * 22) };

/* 1 / j!, j = 0..15. */
FP_TABLE fp_real fp_cubic_invfact[16] = {
    1.0, 1.0, 1.0 / 2, 1.0 / 6, 1.0 / 24, 1.0 / 120, 1.0 / 720, 1.0 / 5040, 1.0 / 40320,
    1.0 / 362880, 1.0 / 3628800, 1.0 / 39916800, 1.0 / 479001600, 1.0 / 6227020800.0,
    1.0 / 87178291200.0, 1.0 / 1307674368000.0 };

/* 1 / k, k = 1..6. */
FP_TABLE fp_real fp_cubic_recip[6] = { 1.0, 1.0 / 2, 1.0 / 3, 1.0 / 4, 1.0 / 5, 1.0 / 6 };

/* The weights of one axis at s (a cell's local coordinate) for a step q:
 * w[0..3] the cubic blending weights, v[0..2] the quadratic ones times q,
 * *q2 = q^2 / 2, *q3 = q^3 / 6. */
FP_HOT void fp_cubic_axis(fp_real s, fp_real q, fp_real *w, fp_real *v, fp_real *q2,
                          fp_real *q3)
{
    fp_real r = 1 - s;
    w[0] = r * r * r * ((fp_real)1 / 6);
    w[3] = s * s * s * ((fp_real)1 / 6);
    w[1] = ((3 * s - 6) * s * s + 4) * ((fp_real)1 / 6);
    w[2] = (((-3 * s + 3) * s + 3) * s + 1) * ((fp_real)1 / 6);
    v[0] = (fp_real)0.5 * r * r * q;
    v[2] = (fp_real)0.5 * s * s * q;
    v[1] = ((fp_real)0.5 + s * r) * q;
    *q2 = (fp_real)0.5 * q * q;
    *q3 = q * q * q * ((fp_real)1 / 6);
}

/* The Taylor coefficients T[0..3] in x of sum_i c_i w_i(s + q x),
 * c_i = c[i * cs], from fp_cubic_axis's weights at s. */
FP_HOT void fp_cubic_taylor(const fp_real *c, int cs, fp_real s, const fp_real *w,
                            const fp_real *v, fp_real q2, fp_real q3, fp_real *T)
{
    fp_real c0 = c[0], c1 = c[cs], c2 = c[2 * cs], c3 = c[3 * cs];
    fp_real d0 = c1 - c0, d1 = c2 - c1, d2 = c3 - c2;
    fp_real e0 = d1 - d0, D3 = (d2 - d1) - e0;
    T[0] = w[0] * c0 + w[1] * c1 + w[2] * c2 + w[3] * c3;
    T[1] = v[0] * d0 + v[1] * d1 + v[2] * d2;
    T[2] = q2 * (e0 + s * D3);
    T[3] = q3 * D3;
}

/* int_0^1 F(x) exp(-u x) dx over one segment of a cubic cell (coefficients
 * c[j * 4 + i], row j along y), the segment from local (px, py) by
 * (qx, qy); *E = exp(-u) (to the series' precision).  |u| <= FP_SEG_U. */
FP_HOT fp_real fp_cubic_seg(const fp_real *c, fp_real px, fp_real qx, fp_real py, fp_real qy,
                            fp_real u, fp_real *E)
{
    fp_real wx[4], vx[3], wy[4], vy[3], qx2, qx3, qy2, qy3;
    fp_cubic_axis(px, qx, wx, vx, &qx2, &qx3);
    fp_cubic_axis(py, qy, wy, vy, &qy2, &qy3);
    /* R[j * 4 + a]: row j's coefficient of x^a; S[a * 4 + b]: x^(a + b). */
    fp_real R[16], S[16];
    for (int j = 0; j < 4; j++)
        fp_cubic_taylor(c + j * 4, 1, px, wx, vx, qx2, qx3, R + j * 4);
    for (int a = 0; a < 4; a++)
        fp_cubic_taylor(R + a, 4, py, wy, vy, qy2, qy3, S + a * 4);
    fp_real P[7];
    for (int k = 0; k < 7; k++)
        P[k] = 0;
    for (int a = 0; a < 4; a++)
        for (int b = 0; b < 4; b++)
            P[a + b] += S[a * 4 + b];
    /* The moments: m_6 by its series, exp(-u) by its own (as many terms:
     * no call of exp), both by Horner, then down. */
    fp_real m = fp_m6_series[FP_CUBIC_TERMS - 1], e = fp_cubic_invfact[FP_CUBIC_TERMS - 1];
    for (int j = FP_CUBIC_TERMS - 2; j >= 0; j--) {
        m = fp_m6_series[j] - u * m;
        e = fp_cubic_invfact[j] - u * e;
    }
    fp_real sum = P[6] * m;
    for (int k = 6; k >= 1; k--) {
        m = (e + u * m) * fp_cubic_recip[k - 1];
        sum += P[k - 1] * m;
    }
    *E = e;
    return sum;
}

#endif

/* fogpipe: the homogeneous fog (no fogmap) on FP_SIMD rays at once.
 * Included by fog_core.h after fog_ray.h. */
#ifndef FP_FOG_SIMD_H
#define FP_FOG_SIMD_H

#include "fog_params.h"
#include "fog_ray.h"

/* The no-fogmap path without branches: fp_slab, fp_height_od, fp_clip and
 * the homogeneous branch of fp_fog_od on FP_SIMD rays at once (OpenCL:
 * float16 lanes, one work-item computing 16 pixels; C: one ray in double),
 * every quantity computed for every lane and the cases chosen among
 * computed values (?: on vectors selects per lane).  The CPU device runs
 * this as SIMD code: PoCL does not vectorise the scalar forms across
 * work-items (their branches, and the pairs its SLP pass forms inside one
 * work-item, keep its work-group loop scalar).  The values are those of
 * the branching forms, which stay the reference (tests/test_integrate.c
 * compares the two in double). */
#ifdef __OPENCL_VERSION__
#define FP_SIMD 16
typedef float16 fp_vreal;
typedef int16 fp_vint;
#define FP_FN_SIMD inline __attribute__((always_inline))
#else
#define FP_SIMD 1
typedef fp_real fp_vreal;
typedef int fp_vint;
#define FP_FN_SIMD static inline
#endif
#define FP_VR(x) ((fp_vreal)(x))

/* (1 - exp(-x)) / x by its Taylor series, for |x| < 1/8 (the first term
 * left out is x^7/8! < 2e-11 relative), where 1 - exp(-x) would cancel. */
FP_FN_SIMD fp_vreal fp_ratio_series(fp_vreal x)
{
    return 1 - x * ((fp_real)1 / 2 -
                    x * ((fp_real)1 / 6 -
                         x * ((fp_real)1 / 24 -
                              x * ((fp_real)1 / 120 -
                                   x * ((fp_real)1 / 720 - x * ((fp_real)1 / 5040))))));
}

FP_FN_SIMD void fp_slab_bf(fp_vreal oy, fp_vreal dy, fp_vreal inv_dy, fp_real lo, fp_real hi,
                           fp_vreal len, fp_vreal *a, fp_vreal *b)
{
    /* dy = 0 makes u, v infinite or NaN: the flat case is chosen below. */
    fp_vreal u = (lo - oy) * inv_dy, v = (hi - oy) * inv_dy;
    fp_vreal t0 = fmax(fmin(u, v), FP_VR(0)), t1 = fmin(fmax(u, v), len);
    fp_vint flat = dy == FP_VR(0), inside = (oy >= FP_VR(lo)) & (oy < FP_VR(hi));
    fp_vreal flat_b = inside ? len : FP_VR(0);
    *a = flat ? FP_VR(0) : t0;
    *b = flat ? flat_b : t1;
}

/* fp_height_od; inv_dy = 1 / dy (infinite for dy = 0). */
FP_FN_SIMD fp_vreal fp_height_od_bf(fp_real sigma, fp_real y0, fp_real H, fp_real top,
                                    fp_vreal oy, fp_vreal dy, fp_vreal inv_dy, fp_vreal len)
{
    fp_vreal a, b, c, e;
    fp_real inv_h = 1 / H;
    /* Below Y0 (h = 1). */
    fp_slab_bf(oy, dy, inv_dy, -FP_INF, fmin(y0, top), len, &a, &b);
    fp_vreal below = b > a ? b - a : FP_VR(0);
    /* Above it (as fp_height_od): exp(-m)(b - a)(1 - exp(-D))/D from the
     * lowest point m over a rise D, or exp(-ya) H / dy to infinity. */
    fp_slab_bf(oy, dy, inv_dy, y0, top, len, &c, &e);
    fp_vint unbounded = isinf(e);
    fp_vreal ef = unbounded ? c : e;
    fp_vreal ya = (oy + c * dy - y0) * inv_h;
    fp_vreal D = fabs(dy) * (ef - c) * inv_h;
    fp_vreal m = dy < FP_VR(0) ? ya - D : ya;
    /* Unbounded only with dy >= 0, where m = ya. */
    fp_vreal em = exp(-m);
    /* (1 - exp(-D)) / D: its Taylor series below 1/8, exp above, where
     * 1 - exp(-D) loses at most 8 ulp of single precision (expm1 is a call
     * PoCL does not inline). */
    fp_vreal series = fp_ratio_series(D);
    fp_vreal ratio_big = (1 - exp(-D)) / D;
    fp_vreal ratio = D < FP_VR(0.125) ? series : ratio_big;
    fp_vreal bounded = (ef - c) * em * ratio;
    fp_vreal rising = em * H * inv_dy;
    fp_vreal level = em > FP_VR(0) ? FP_VR(FP_INF) : FP_VR(0);
    fp_vreal to_inf = dy > FP_VR(0) ? rising : level;
    fp_vreal above_val = unbounded ? to_inf : bounded;
    fp_vreal above = e > c ? above_val : FP_VR(0);
    fp_vreal od = sigma * (below + above);
    return sigma > 0 ? od : FP_VR(0);
}

/* fp_height_od on rays that all start at the height oy (a perspective
 * camera's, the same in every lane) and run over t in [0, len], with one
 * exp a lane where fp_height_od_bf has two.  The layer's part is entered at
 * a height that is one of three numbers whichever the lane (oy inside the
 * layer, y0 rising into it from below, top falling into it from above), so
 * its exp(-(yc - y0) / H) is the same in every lane; only the exit's is
 * not.  Over a part of length s with x = dy s / H (negative falling):
 * exp(-(yc - y0)/H) s (1 - exp(-x)) / x = H / dy (E_in - E_out), the
 * difference of the two ends' densities, losing at most 8 ulp where |x| >=
 * 1/8 (one end at least e^(1/8) times the other); below that the Taylor
 * series of (1 - exp(-x)) / x (either sign; the first term left out is
 * x^7/8! < 2e-11); a part without an end (rising forever) E_in H / dy.
 * inv_dy = 1 / dy (infinite for dy = 0). */
FP_FN_SIMD fp_vreal fp_height_od_from_bf(fp_real sigma, fp_real y0, fp_real H, fp_real top,
                                         fp_real oy, fp_vreal dy, fp_vreal inv_dy, fp_vreal len)
{
    fp_real inv_h = 1 / H, base = fmin(y0, top);
    fp_vint up = dy > FP_VR(0), down = dy < FP_VR(0);
    /* Below the base (density 1): from the origin until a rising ray
     * crosses it, or from where a falling one does. */
    fp_vreal t_base = (base - oy) * inv_dy, below;
    if (oy < base)
        below = up ? fmin(len, t_base) : len;
    else
        below = down ? fmax(len - t_base, FP_VR(0)) : FP_VR(0);
    fp_vreal above = FP_VR(0);
    if (y0 < top) {
        /* The part in the layer: its length s, entered at yc. */
        fp_vreal t_y0 = (y0 - oy) * inv_dy, t_top = (top - oy) * inv_dy, s;
        fp_real yc;
        if (oy < y0) {
            s = up ? fmax(fmin(len, t_top) - t_y0, FP_VR(0)) : FP_VR(0);
            yc = y0;
        } else if (oy < top) {
            fp_vreal not_up = down ? fmin(len, t_y0) : len;
            s = up ? fmin(len, t_top) : not_up;
            yc = oy;
        } else {
            s = down ? fmax(fmin(len, t_y0) - t_top, FP_VR(0)) : FP_VR(0);
            yc = top;
        }
        fp_real ya = (yc - y0) * inv_h, e_in = exp(-ya);
        fp_vreal x = dy * s * inv_h;
        fp_vreal series = fp_ratio_series(x);
        fp_vreal ends = H * inv_dy * (e_in - exp(-(ya + x)));
        fp_vreal bounded = fabs(x) < FP_VR(0.125) ? e_in * s * series : ends;
        /* Without an end: rising forever, or level (density e_in all the way). */
        fp_vreal level = FP_VR(e_in > 0 ? FP_INF : 0);
        fp_vreal endless = up ? e_in * H * inv_dy : level;
        above = isinf(s) ? endless : bounded;
    }
    fp_vreal od = sigma * (below + above);
    return sigma > 0 ? od : FP_VR(0);
}

FP_FN_SIMD void fp_clip_bf(fp_vreal o, fp_vreal dd, fp_real lo, fp_real hi, fp_vreal *a,
                           fp_vreal *b)
{
    fp_vreal inv = 1 / dd;
    fp_vreal u = (lo - o) * inv, v = (hi - o) * inv;
    fp_vint flat = dd == FP_VR(0), out = (o < FP_VR(lo)) | (o > FP_VR(hi));
    fp_vreal na = fmax(*a, fmin(u, v)), nb = fmin(*b, fmax(u, v));
    fp_vreal flat_b = out ? *a : *b;
    *b = flat ? flat_b : nb;
    *a = flat ? *a : na;
}

/* fp_fog_od for fog without a fogmap (FP_F_HAS_MAP 0), branch-free within
 * the lanes, from the origin o along the unit directions d, t in [0, len].
 * The branches here are on parameters, the same for every lane: no haze,
 * no box (every bound infinite: the clip leaves [0, len] as it is). */
FP_FN_SIMD fp_vreal fp_fog_od_nomap_bf(FP_CONSTANT const fp_real *fp, fp_real ox, fp_real oy,
                                       fp_real oz, fp_vreal dx, fp_vreal dy, fp_vreal dz,
                                       fp_vreal len)
{
    fp_vreal inv_dy = 1 / dy;
    fp_vreal od = FP_VR(0);
    if (fp[FP_F_HAZE] > 0)
        od = fp_height_od_from_bf(fp[FP_F_HAZE], fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2],
                                  fp[FP_F_HAZE + 3], oy, dy, inv_dy, len);
    fp_real c = fp[FP_F_COS], s = fp[FP_F_SIN];
    fp_real px = ox - fp[FP_F_OFF], py = oy - fp[FP_F_OFF + 1], pz = oz - fp[FP_F_OFF + 2];
    int boxed = 0;
    for (int i = 0; i < 6; i++)
        boxed |= !isinf(fp[FP_F_BOX + i]);
    if (!boxed)
        return od + fp_height_od_from_bf(fp[FP_F_SIGMA], fp[FP_F_Y0], fp[FP_F_H], fp[FP_F_TOP],
                                         py, dy, inv_dy, len);
    /* In the box: [a, b] of every lane its own, from its own height. */
    fp_vreal a = FP_VR(0), b = len;
    fp_clip_bf(FP_VR(c * px - s * pz), c * dx - s * dz, fp[FP_F_BOX], fp[FP_F_BOX + 3], &a, &b);
    fp_clip_bf(FP_VR(py), dy, fp[FP_F_BOX + 1], fp[FP_F_BOX + 4], &a, &b);
    fp_clip_bf(FP_VR(s * px + c * pz), s * dx + c * dz, fp[FP_F_BOX + 2], fp[FP_F_BOX + 5], &a,
               &b);
    fp_vreal fog_main = fp_height_od_bf(fp[FP_F_SIGMA], fp[FP_F_Y0], fp[FP_F_H], fp[FP_F_TOP],
                                        py + a * dy, dy, inv_dy, b - a);
    return od + (b > a ? fog_main : FP_VR(0));
}


#endif

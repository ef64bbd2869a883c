/* fogpipe: what a local light can add to a view ray, bounded closer
 * (--light-cull, issue 26).  fp_light_bound (kernels/light_core.h) bounds
 * a light's in-scatter over the stretch [ta, tb] of a view ray by
 *   albedo Imax pmax min((1 - tau) f / D^2, sigma_max (th1 - th0) f / D),
 * pmax the phase function's largest value and sigma_max the fog's largest
 * extinction anywhere.  Both hold over the stretch alone:
 *
 * - the phase: at the point o + t d the light (a point, seen from it)
 *   arrives at mu = (tc - t) / r, r = sqrt(D^2 + (t - tc)^2), tc the
 *   ray's point nearest the light (fp_light_fast's -sin(theta)); mu
 *   falls as t grows, so over [ta, tb] it spans [mu(tb), mu(ta)] (mu(inf)
 *   = -1).  Henyey-Greenstein rises with mu when g >= 0 (falls when g <
 *   0), 1 + mu^2 is largest at the end farther from 0, and every kind of
 *   phase.h is a non-negative sum of products of those: each factor at
 *   its own largest bounds the phase over the stretch.  An area light's
 *   points are seen at other angles: pmax for it.
 * - the extinction: without a fogmap, sigma h(y - offset) + haze
 *   h_haze(y), each profile 1 below its base, exp(-(y - y0)/H) above, 0
 *   at or above its top: none increases with height, so their values at
 *   the stretch's lowest point bound the stretch (the main fog's box only
 *   removes fog).  With a fogmap: +inf (the fast rule does not run; the
 *   panels' bound keeps its 1 - tau term).
 *
 * fp_real (C: double, the judge; OpenCL: float); the lanes' versions are
 * in kernels/cull_lanes.h.  Included by light_core.h before
 * fp_light_bound. */
#ifndef FP_CULL_CORE_H
#define FP_CULL_CORE_H

/* The largest extinction fog without a fogmap can have (its height
 * profiles are at most 1); +inf with a fogmap (not bounded here). */
FP_FN fp_real fp_light_sigma_max(FP_CONSTANT const fp_real *fp)
{
    return fp[FP_F_HAS_MAP] != 0 ? (fp_real)FP_INF
                                 : fmax(fp[FP_F_SIGMA], (fp_real)0) + fmax(fp[FP_F_HAZE], (fp_real)0);
}

/* A height profile's value at y: non-increasing in y (1 at y = -inf). */
FP_FN fp_real fp_cull_height(fp_real y, fp_real y0, fp_real H, fp_real top)
{
    if (!(y < top))
        return 0;
    fp_real e = exp(-fmax(y - y0, (fp_real)0) / H);
    return isnan(e) ? (fp_real)1 : e;
}

/* The largest extinction of fog without a fogmap on the stretch [ta, tb]
 * of o + t d (tb may be +inf); +inf with a fogmap. */
FP_FN fp_real fp_light_sigma_span(FP_CONSTANT const fp_real *fp, fp_real oy, fp_real dy,
                                  fp_real ta, fp_real tb)
{
    if (fp[FP_F_HAS_MAP] != 0)
        return FP_INF;
    fp_real ylo = dy < 0 ? oy + tb * dy : oy + ta * dy, s = 0;
    if (fp[FP_F_SIGMA] > 0)
        s += fp[FP_F_SIGMA] * fp_cull_height(ylo - fp[FP_F_OFF + 1], fp[FP_F_Y0], fp[FP_F_H],
                                             fp[FP_F_TOP]);
    if (fp[FP_F_HAZE] > 0)
        s += fp[FP_F_HAZE] * fp_cull_height(ylo, fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2],
                                            fp[FP_F_HAZE + 3]);
    return fmin(s, fp_light_sigma_max(fp));
}

/* The phase function's largest value for mu in [m0, m1]. */
FP_FN fp_real fp_phase_max_over(int kind, fp_real g, fp_real w, fp_real m0, fp_real m1)
{
    if (kind < FP_PHASE_HG || kind > FP_PHASE_MIXHG)
        return FP_INV_4PI;
    fp_real q = (fp_real)1 + fmax(m0 * m0, m1 * m1);
    fp_real ray = (fp_real)0.75 * FP_INV_4PI * q;
    if (kind == FP_PHASE_RAYLEIGH)
        return ray;
    fp_real mu = g >= 0 ? m1 : m0, d = (fp_real)1 + g * g - (fp_real)2 * g * mu;
    fp_real hg = FP_INV_4PI * ((fp_real)1 - g * g) / (d * sqrt(d));
    fp_real cs = hg * (fp_real)1.5 * q / ((fp_real)2 + g * g);
    return kind == FP_PHASE_HG ? hg : kind == FP_PHASE_CS ? cs
         : kind == FP_PHASE_MIX ? w * ray + ((fp_real)1 - w) * cs : w * ray + ((fp_real)1 - w) * hg;
}

/* The phase function's largest value over the stretch [ta, tb] of a view
 * ray passing a point light at distance D (> 0), tc its nearest point;
 * at most lt's FP_LT_PMAX. */
FP_FN fp_real fp_light_phase_span(FP_CONSTANT const fp_real *lt, fp_real D, fp_real tc,
                                  fp_real ta, fp_real tb)
{
    fp_real m1 = (tc - ta) / sqrt(D * D + (ta - tc) * (ta - tc));
    fp_real m0 = isinf(tb) ? (fp_real)-1 : (tc - tb) / sqrt(D * D + (tb - tc) * (tb - tc));
    fp_real p = fp_phase_max_over((int)lt[FP_LT_PHASE], lt[FP_LT_PHASE + 1], lt[FP_LT_PHASE + 2],
                                  fmin(m0, m1), fmax(m0, m1));
    return fmin(p, lt[FP_LT_PMAX]);
}

#endif

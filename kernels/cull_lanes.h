/* fogpipe: kernels/cull_core.h on lanes (kernels/scatter_lanes.h's
 * fp_lnr: 16 view rays at once in OpenCL, one in C); the same formulas,
 * the phase function's kind the same for every lane.  Included by
 * scatter_lanes.h before fp_ln_bound. */
#ifndef FP_CULL_LANES_H
#define FP_CULL_LANES_H

FP_LN_FN fp_lnr fp_ln_cull_height(fp_lnr y, fp_real y0, fp_real H, fp_real top)
{
    fp_lnr e = exp(-fmax(y - y0, (fp_real)0) / H);
    e = isnan(e) ? FP_LN(1) : e;
    return y < top ? e : FP_LN(0);
}

/* fp_light_sigma_span on lanes. */
FP_LN_FN fp_lnr fp_ln_sigma_span(FP_CONSTANT const fp_real *fp, fp_lnr oy, fp_lnr dy, fp_lnr ta,
                                 fp_lnr tb)
{
    if (fp[FP_F_HAS_MAP] != 0)
        return FP_LN(FP_INF);
    fp_lnr ylo = dy < 0 ? oy + tb * dy : oy + ta * dy, s = FP_LN(0);
    if (fp[FP_F_SIGMA] > 0)
        s += fp[FP_F_SIGMA] * fp_ln_cull_height(ylo - fp[FP_F_OFF + 1], fp[FP_F_Y0], fp[FP_F_H],
                                                fp[FP_F_TOP]);
    if (fp[FP_F_HAZE] > 0)
        s += fp[FP_F_HAZE] * fp_ln_cull_height(ylo, fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2],
                                               fp[FP_F_HAZE + 3]);
    return fmin(s, fp_light_sigma_max(fp));
}

/* fp_light_phase_span on lanes. */
FP_LN_FN fp_lnr fp_ln_phase_span(FP_CONSTANT const fp_real *lt, fp_lnr D, fp_lnr tc, fp_lnr ta,
                                 fp_lnr tb)
{
    int kind = (int)lt[FP_LT_PHASE];
    fp_real g = lt[FP_LT_PHASE + 1], w = lt[FP_LT_PHASE + 2];
    if (kind < FP_PHASE_HG || kind > FP_PHASE_MIXHG)
        return FP_LN(fmin(FP_INV_4PI, lt[FP_LT_PMAX]));
    fp_lnr m1 = (tc - ta) / sqrt(D * D + (ta - tc) * (ta - tc));
    fp_lnr m0 = isinf(tb) ? FP_LN(-1) : (tc - tb) / sqrt(D * D + (tb - tc) * (tb - tc));
    fp_lnr lo = fmin(m0, m1), hi = fmax(m0, m1);
    fp_lnr q = 1 + fmax(lo * lo, hi * hi);
    fp_lnr ray = (fp_real)0.75 * FP_INV_4PI * q, p;
    if (kind == FP_PHASE_RAYLEIGH) {
        p = ray;
    } else {
        fp_lnr mu = g >= 0 ? hi : lo, d = 1 + g * g - 2 * g * mu;
        fp_lnr hg = FP_INV_4PI * (1 - g * g) / (d * sqrt(d));
        fp_lnr cs = hg * (fp_real)1.5 * q / (2 + g * g);
        p = kind == FP_PHASE_HG ? hg : kind == FP_PHASE_CS ? cs
          : kind == FP_PHASE_MIX ? w * ray + (1 - w) * cs : w * ray + (1 - w) * hg;
    }
    return fmin(p, lt[FP_LT_PMAX]);
}

#endif

/* fogpipe: phase functions, normalized over the sphere (integral of p over
 * all directions = 1), shared by the OpenCL kernels and the C reference.
 * Include after fog_core.h (fp_real, FP_FN).
 *
 * mu is the cosine of the scattering angle: between the direction the light
 * travels before and after scattering.  Along a view ray of direction d
 * (camera -> point) lit from direction l (point -> light), the light
 * travels along -l and leaves toward the camera along -d, so mu = dot(l, d):
 * looking toward the light, mu -> 1 (the forward peak of g > 0).
 *
 * Kinds (--phase, filters/scatter.c):
 *   iso        1 / (4 pi)
 *   hg:G       Henyey-Greenstein, mean cosine G
 *   cs:G       Cornette-Shanks 1992, mean cosine 3G(G^2+4) / (5(G^2+2))
 *   rayleigh   3 / (16 pi) (1 + mu^2)
 *   mix:W,G    W Rayleigh + (1 - W) Cornette-Shanks(G): seed 002's sum of a
 *              Rayleigh and a Mie term, its weights normalized
 *   mixhg:W,G  the same with Henyey-Greenstein for the Mie term */
#ifndef FP_PHASE_H
#define FP_PHASE_H

#define FP_PHASE_ISO 0
#define FP_PHASE_HG 1
#define FP_PHASE_CS 2
#define FP_PHASE_RAYLEIGH 3
#define FP_PHASE_MIX 4
#define FP_PHASE_MIXHG 5

#define FP_INV_4PI ((fp_real)0.079577471545947668)

FP_FN fp_real fp_phase_hg(fp_real g, fp_real mu)
{
    fp_real d = (fp_real)1 + g * g - (fp_real)2 * g * mu;
    return FP_INV_4PI * ((fp_real)1 - g * g) / (d * sqrt(d));
}

FP_FN fp_real fp_phase_cs(fp_real g, fp_real mu)
{
    return fp_phase_hg(g, mu) * (fp_real)1.5 * ((fp_real)1 + mu * mu) / ((fp_real)2 + g * g);
}

FP_FN fp_real fp_phase_rayleigh(fp_real mu)
{
    return (fp_real)0.75 * FP_INV_4PI * ((fp_real)1 + mu * mu);
}

FP_FN fp_real fp_phase(int kind, fp_real g, fp_real w, fp_real mu)
{
    switch (kind) {
    case FP_PHASE_HG:
        return fp_phase_hg(g, mu);
    case FP_PHASE_CS:
        return fp_phase_cs(g, mu);
    case FP_PHASE_RAYLEIGH:
        return fp_phase_rayleigh(mu);
    case FP_PHASE_MIX:
        return w * fp_phase_rayleigh(mu) + ((fp_real)1 - w) * fp_phase_cs(g, mu);
    case FP_PHASE_MIXHG:
        return w * fp_phase_rayleigh(mu) + ((fp_real)1 - w) * fp_phase_hg(g, mu);
    default:
        return FP_INV_4PI;
    }
}

/* The mean cosine of the scattering angle, by formula. */
FP_FN fp_real fp_phase_mean_cos(int kind, fp_real g, fp_real w)
{
    fp_real cs = (fp_real)3 * g * (g * g + 4) / ((fp_real)5 * (g * g + 2));
    switch (kind) {
    case FP_PHASE_HG:
        return g;
    case FP_PHASE_CS:
        return cs;
    case FP_PHASE_MIX:
        return ((fp_real)1 - w) * cs;
    case FP_PHASE_MIXHG:
        return ((fp_real)1 - w) * g;
    default:
        return 0;
    }
}

#endif

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
 *   mixhg:W,G  the same with Henyey-Greenstein for the Mie term
 *
 * Importance sampling (fp_phase_sample_mu, fp_phase_sample_dir) draws mu
 * with density 2 pi p(mu) on [-1, 1], and a direction o about a unit d with
 * dot(o, d) = mu and a uniform azimuth, so o has density p(dot(o, d)) per
 * steradian (fp_phase_pdf, derived from the samplers themselves).  With d
 * the view direction (camera -> point), o is a direction toward the light
 * (the role of l above); equally, with d the direction light travels
 * before scattering, o is the one it travels after.  Uniforms come from
 * kernels/rng.h, so a stream is the same in C and in OpenCL. */
#ifndef FP_PHASE_H
#define FP_PHASE_H

#include "rng.h"

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

#define FP_TWO_PI ((fp_real)6.283185307179586)

/* Henyey-Greenstein by inversion of its CDF: u in [0, 1) -> mu.  The usual
 * (1 + g^2 - ((1 - g^2) / (1 - g + 2 g u))^2) / (2 g) rewritten without the
 * division by g, so no isotropic special case is needed near g = 0 (where
 * the usual one cancels catastrophically) and the result is exact HG for
 * every g: with s = 1 - g + 2 g u,
 *   mu = 1 - 2 (1 - g)^2 (1 - u) (1 + g u) / s^2
 * for g >= 0, precise near the forward peak mu = 1; g < 0 by the symmetry
 * p_HG(-g, mu) = p_HG(g, -mu) with u -> 1 - u (so mu still increases with
 * u), precise near its peak mu = -1.
 * CDF: F(mu) = (1 - g^2) / (2 g) (1 / sqrt(1 + g^2 - 2 g mu) - 1 / (1 + g)).
 * For |g| < 1 (|g| = 1 is a delta; u = 0 would give 0 / 0). */
FP_FN fp_real fp_phase_hg_invert(fp_real g, fp_real u)
{
    fp_real a = fabs(g);
    u = g < 0 ? (fp_real)1 - u : u;
    fp_real s = (fp_real)1 - a + (fp_real)2 * a * u;
    fp_real b = (fp_real)1 - a;
    fp_real mu = (fp_real)1 - (fp_real)2 * b * b * ((fp_real)1 - u) * ((fp_real)1 + a * u) / (s * s);
    mu = fmin(fmax(mu, (fp_real)-1), (fp_real)1);
    return g < 0 ? -mu : mu;
}

/* Rayleigh by inversion of its CDF F(mu) = (mu^3 + 3 mu + 4) / 8: with
 * z = 2u - 1, mu^3 + 3 mu = 4 z, solved by mu = t - 1/t where
 * t^3 = 2z + sqrt(4 z^2 + 1) (Cardano; t in [0.618, 1.618]).  Odd in z,
 * so solved for |z| and signed, which keeps t^3 >= 1 (no cancellation). */
FP_FN fp_real fp_phase_rayleigh_invert(fp_real u)
{
    fp_real z = (fp_real)2 * u - (fp_real)1;
    fp_real a = fabs(z);
    fp_real t = cbrt((fp_real)2 * a + sqrt((fp_real)4 * a * a + (fp_real)1));
    fp_real mu = fmin(t - (fp_real)1 / t, (fp_real)1);
    return z < 0 ? -mu : mu;
}

/* Cornette-Shanks: p_CS = p_HG(g) 1.5 (1 + mu^2) / (2 + g^2), so HG
 * candidates accepted with probability (1 + mu^2) / 2 (at least 1/2: 64
 * tries fail with probability < 2^-64; then the last candidate). */
FP_FN fp_real fp_phase_cs_sample(fp_real g, fp_rng_t *rng)
{
    fp_real mu = 0;
    for (int i = 0; i < 64; i++) {
        mu = fp_phase_hg_invert(g, FP_RNG_NEXT(rng));
        if ((fp_real)2 * FP_RNG_NEXT(rng) < (fp_real)1 + mu * mu)
            break;
    }
    return mu;
}

/* mu with density 2 pi fp_phase(kind, g, w, mu) on [-1, 1]. */
FP_FN fp_real fp_phase_sample_mu(int kind, fp_real g, fp_real w, fp_rng_t *rng)
{
    if (kind == FP_PHASE_MIX || kind == FP_PHASE_MIXHG) {
        if (FP_RNG_NEXT(rng) < w)
            kind = FP_PHASE_RAYLEIGH;
        else
            kind = kind == FP_PHASE_MIX ? FP_PHASE_CS : FP_PHASE_HG;
    }
    switch (kind) {
    case FP_PHASE_HG:
        return fp_phase_hg_invert(g, FP_RNG_NEXT(rng));
    case FP_PHASE_CS:
        return fp_phase_cs_sample(g, rng);
    case FP_PHASE_RAYLEIGH:
        return fp_phase_rayleigh_invert(FP_RNG_NEXT(rng));
    default:
        return (fp_real)2 * FP_RNG_NEXT(rng) - (fp_real)1;
    }
}

/* A unit direction o with dot(o, d) = mu drawn by fp_phase_sample_mu and a
 * uniform azimuth about the unit d: density fp_phase(kind, g, w, dot(o, d))
 * per steradian.  The basis about d is Duff et al. 2017, "Building an
 * orthonormal basis, revisited" (continuous except across dz = 0's sign). */
FP_FN void fp_phase_sample_dir(int kind, fp_real g, fp_real w, fp_real dx, fp_real dy,
                               fp_real dz, fp_rng_t *rng, fp_real *ox, fp_real *oy,
                               fp_real *oz)
{
    fp_real mu = fp_phase_sample_mu(kind, g, w, rng);
    fp_real phi = FP_TWO_PI * FP_RNG_NEXT(rng);
    fp_real st = sqrt(fmax((fp_real)0, (fp_real)1 - mu * mu));
    fp_real c = st * cos(phi), s = st * sin(phi);
    fp_real sg = dz >= 0 ? (fp_real)1 : (fp_real)-1;
    fp_real a = (fp_real)-1 / (sg + dz);
    fp_real b = dx * dy * a;
    /* t1 = (1 + sg dx^2 a, sg b, -sg dx), t2 = (b, sg + dy^2 a, -dy) */
    *ox = c * ((fp_real)1 + sg * dx * dx * a) + s * b + mu * dx;
    *oy = c * sg * b + s * (sg + dy * dy * a) + mu * dy;
    *oz = -c * sg * dx - s * dy + mu * dz;
}

/* The density per steradian of fp_phase_sample_dir's directions at
 * dot(o, d) = mu, from the samplers rather than from fp_phase: the
 * derivative of the inverted CDFs over 2 pi for HG and Rayleigh, the
 * accepted HG candidates over the acceptance rate for Cornette-Shanks
 * (E_HG[(1 + mu^2) / 2] = (2 + g^2) / 3, from E_HG[mu^2] = (1 + 2 g^2) / 3),
 * the choice's weights for the mixes. */
FP_FN fp_real fp_phase_pdf(int kind, fp_real g, fp_real w, fp_real mu)
{
    fp_real t = sqrt((fp_real)1 + g * g - (fp_real)2 * g * mu);
    fp_real hg = (fp_real)0.5 * ((fp_real)1 - g) * ((fp_real)1 + g) / (t * t * t) / FP_TWO_PI;
    fp_real accept = (fp_real)0.5 * ((fp_real)1 + mu * mu);
    fp_real rate = (fp_real)0.5 * ((fp_real)1 + ((fp_real)1 + (fp_real)2 * g * g) / (fp_real)3);
    fp_real cs = hg * accept / rate;
    fp_real ray = (fp_real)0.375 * ((fp_real)1 + mu * mu) / FP_TWO_PI;
    switch (kind) {
    case FP_PHASE_HG:
        return hg;
    case FP_PHASE_CS:
        return cs;
    case FP_PHASE_RAYLEIGH:
        return ray;
    case FP_PHASE_MIX:
        return w * ray + ((fp_real)1 - w) * cs;
    case FP_PHASE_MIXHG:
        return w * ray + ((fp_real)1 - w) * hg;
    default:
        return (fp_real)0.5 / FP_TWO_PI;
    }
}

#endif

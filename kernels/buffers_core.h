/* fogpipe: the fog buffers' per-pixel operations, written once and compiled
 * twice: as OpenCL C in single precision (kernels/buffers.cl) and as C in
 * double precision (filters/buffers.c, the reference).  Layers hold 4
 * floats per pixel (S.r, S.g, S.b, tau), row-major; the guide `dist` one
 * per pixel, the distance along the pixel's view ray, +inf for sky.
 *
 * - Range weight of two guide distances d1, d2: exp(-r^2 / 2) with
 *   r = |d1 - d2| / min(d1, d2) / range; sky blends only with sky.
 * - The depth-aware bilateral blur of one pixel: over the (2 rx + 1) x
 *   (2 ry + 1) pixels around it (a separable pass: rx or ry 0), a Gaussian
 *   in pixels times the range weight against the pixel; pixels outside the
 *   frame are left out.
 * - Joint bilateral upsampling of one pixel (Kopf et al. 2007) from the
 *   samples of a 1/f layer (sample (i, j) at full-resolution pixel
 *   (f i, f j)): the 4 x 4 samples around it, Gaussian in full-resolution
 *   pixels (sigma f / 2) times the range weight; where that sums to less
 *   than FP_UPSAMPLE_EPS of the Gaussian alone, the sample of nearest
 *   distance.
 * - The depth-edge test of one pixel (--fog-edges exact). */
#ifndef FP_BUFFERS_CORE_H
#define FP_BUFFERS_CORE_H

#include "fp_real.h"

/* Below this share of the spatial weight, no low-resolution sample matches
 * the pixel's distance: the upsampling falls back to the nearest one. */
#define FP_UPSAMPLE_EPS 1e-3

/* Four channels of a layer: float4 on the device, four doubles in C.
 * FP_LOAD4(layer, j): pixel j; FP_ADD4(sum, w, v): sum += w v;
 * FP_DIV4(v, d): v / d. */
#ifdef __OPENCL_VERSION__
typedef float4 fp_real4;
#define FP_ZERO4 ((float4)(0.0f))
#define FP_LOAD4(layer, j) vload4((j), (layer))
#define FP_ADD4(sum, w, v) ((sum) += (w) * (v))
#define FP_DIV4(v, d) ((v) / (d))
#else
typedef struct fp_real4 {
    double c[4];
} fp_real4;
#define FP_ZERO4 ((fp_real4){ { 0, 0, 0, 0 } })
static inline fp_real4 fp_buf_load4(const float *layer, int j)
{
    const float *p = layer + 4 * (size_t)j;
    return (fp_real4){ { p[0], p[1], p[2], p[3] } };
}
static inline void fp_buf_add4(fp_real4 *sum, double w, fp_real4 v)
{
    for (int c = 0; c < 4; c++)
        sum->c[c] += w * v.c[c];
}
static inline fp_real4 fp_buf_div4(fp_real4 v, double d)
{
    for (int c = 0; c < 4; c++)
        v.c[c] /= d;
    return v;
}
#define FP_LOAD4(layer, j) fp_buf_load4((layer), (j))
#define FP_ADD4(sum, w, v) fp_buf_add4(&(sum), (w), (v))
#define FP_DIV4(v, d) fp_buf_div4((v), (d))
#endif

/* |d1 - d2| / min(d1, d2); 0 for two sky pixels, +inf for sky against
 * geometry (and for two different distances at or below 0). */
FP_FN fp_real fp_buf_rel_diff(fp_real d1, fp_real d2)
{
    int s1 = isinf(d1) != 0, s2 = isinf(d2) != 0;
    if (s1 || s2)
        return (s1 && s2) ? (fp_real)0 : (fp_real)FP_INF;
    fp_real m = fmin(d1, d2);
    if (!(m > 0))
        return d1 == d2 ? (fp_real)0 : (fp_real)FP_INF;
    return fabs(d1 - d2) / m;
}

/* exp(-r^2 / 2), r = fp_buf_rel_diff(d1, d2) * inv_range (written out:
 * the blur's inner loop). */
FP_FN fp_real fp_buf_range_weight(fp_real d1, fp_real d2, fp_real inv_range)
{
    int s1 = isinf(d1) != 0, s2 = isinf(d2) != 0;
    if (s1 || s2)
        return (s1 && s2) ? (fp_real)1 : (fp_real)0;
    fp_real m = fmin(d1, d2);
    if (!(m > 0))
        return d1 == d2 ? (fp_real)1 : (fp_real)0;
    fp_real r = fabs(d1 - d2) / m * inv_range;
    return exp((fp_real)-0.5 * r * r);
}

/* The blurred value of pixel (x, y) of `in` (w x h): Gaussian
 * exp(-(kx^2 + ky^2) inv2s2) over |kx| <= rx, |ky| <= ry times the range
 * weight against the pixel. */
FP_FN fp_real4 fp_buf_blur_pixel(FP_GLOBAL const float *in, FP_GLOBAL const float *dist, int w,
                                 int h, int x, int y, int rx, int ry, fp_real inv2s2,
                                 fp_real inv_range)
{
    fp_real dc = dist[y * w + x], ws = 0;
    fp_real4 sum = FP_ZERO4;
    for (int ky = -ry; ky <= ry; ky++) {
        int yy = y + ky;
        if (yy < 0 || yy >= h)
            continue;
        for (int kx = -rx; kx <= rx; kx++) {
            int xx = x + kx;
            if (xx < 0 || xx >= w)
                continue;
            int j = yy * w + xx;
            fp_real wt = exp(-(fp_real)(kx * kx + ky * ky) * inv2s2) *
                         fp_buf_range_weight(dc, dist[j], inv_range);
            if (wt == 0)
                continue;
            FP_ADD4(sum, wt, FP_LOAD4(in, j));
            ws += wt;
        }
    }
    return FP_DIV4(sum, ws);
}

/* Share of the blur at guide distance d (--blur-falloff D): 0 within D,
 * 1 from 2 D on, linear between; 1 everywhere when D is 0. */
FP_FN fp_real fp_buf_falloff(fp_real d, fp_real falloff)
{
    if (!(falloff > 0))
        return 1;
    fp_real a = (d - falloff) / falloff;
    return a < 0 ? (fp_real)0 : a > 1 ? (fp_real)1 : a;
}

/* Which sample to fall back on: the smallest relative difference of
 * distance; among equals (sky against geometry: all infinite), for a sky
 * pixel the farthest sample, else the spatially nearest. */
FP_FN int fp_buf_nearer(fp_real dp, fp_real rel, fp_real ds, fp_real sd2, fp_real best_rel,
                        fp_real best_ds, fp_real best_sd2)
{
    if (rel != best_rel)
        return rel < best_rel;
    if (isinf(dp))
        return ds > best_ds;
    return sd2 < best_sd2;
}

/* The upsampled value of full-resolution pixel (x, y) (frame w x h) from
 * the lw x lh samples lo of the 1/f layer. */
FP_FN fp_real4 fp_buf_upsample_pixel(FP_GLOBAL const float *lo, FP_GLOBAL const float *dist,
                                     int f, int w, int lw, int lh, int x, int y, fp_real inv2s2,
                                     fp_real inv_range)
{
    fp_real dp = dist[y * w + x], ws = 0, gs = 0;
    fp_real best_rel = FP_INF, best_ds = -FP_INF, best_sd2 = FP_INF;
    fp_real4 sum = FP_ZERO4;
    int best = -1;
    int ci = x / f, cj = y / f;
    for (int j = cj - 1; j <= cj + 2; j++) {
        if (j < 0 || j >= lh)
            continue;
        for (int i = ci - 1; i <= ci + 2; i++) {
            if (i < 0 || i >= lw)
                continue;
            int s = j * lw + i;
            fp_real ds = dist[(f * j) * w + f * i];
            fp_real sx = (fp_real)(x - f * i), sy = (fp_real)(y - f * j);
            fp_real sd2 = sx * sx + sy * sy;
            fp_real g = exp(-sd2 * inv2s2);
            fp_real wt = g * fp_buf_range_weight(dp, ds, inv_range);
            gs += g;
            if (wt > 0) {
                FP_ADD4(sum, wt, FP_LOAD4(lo, s));
                ws += wt;
            }
            fp_real rel = fp_buf_rel_diff(dp, ds);
            if (best < 0 || fp_buf_nearer(dp, rel, ds, sd2, best_rel, best_ds, best_sd2)) {
                best = s;
                best_rel = rel;
                best_ds = ds;
                best_sd2 = sd2;
            }
        }
    }
    return ws > (fp_real)FP_UPSAMPLE_EPS * gs ? FP_DIV4(sum, ws) : FP_LOAD4(lo, best);
}

/* 1 when full-resolution pixel (x, y) is a depth-edge pixel of upsampling
 * by f > 1 (fp_upsample_edges in filters/buffers.h): not a sample, and
 * past the last sample column or row or farther than `threshold` in
 * relative distance from a corner sample of its cell. */
FP_FN int fp_buf_edge_pixel(FP_GLOBAL const float *dist, int f, int w, int lw, int lh, int x,
                            int y, fp_real threshold)
{
    if (x % f == 0 && y % f == 0)
        return 0;   /* a sample: computed at its own ray already */
    int ci = x / f, cj = y / f;
    if ((x % f && ci + 1 >= lw) || (y % f && cj + 1 >= lh))
        return 1;   /* the upsampling would extrapolate */
    fp_real dp = dist[y * w + x];
    for (int j = cj; j <= cj + 1 && j < lh; j++)
        for (int i = ci; i <= ci + 1 && i < lw; i++)
            if (fp_buf_rel_diff(dp, dist[(f * j) * w + f * i]) > threshold)
                return 1;
    return 0;
}

#endif

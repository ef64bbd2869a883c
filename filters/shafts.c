#include "shafts.h"

#include <math.h>
#include <stdlib.h>

int fp_shafts_levels(int w, int h)
{
    int l = 0;
    while ((1 << l) < w || (1 << l) < h)
        l++;
    return l;
}

/* The smaller one-sided change of z at (i, j) along one axis (step di,
 * dj); 0 where no finite neighbour is on the same side. */
static double one_sided(const float *z, int w, int h, int i, int j, int di, int dj)
{
    double c = z[(size_t)j * w + i], best = INFINITY;
    for (int s = -1; s <= 1; s += 2) {
        int a = i + s * di, b = j + s * dj;
        if (a < 0 || b < 0 || a >= w || b >= h)
            continue;
        double v = z[(size_t)b * w + a];
        if (isfinite(v))
            best = fmin(best, fabs(v - c));
    }
    return isfinite(best) ? best : 0;
}

/* Levels 1..nl of p (after its w x h level 0): min and max per block. */
static void build_levels(float *p, int w, int h, int nl)
{
    size_t off = (size_t)w * h, prev = 0;
    int pw = w, ph = h;
    for (int l = 1; l <= nl; l++) {
        int lw = (w + (1 << l) - 1) >> l, lh = (h + (1 << l) - 1) >> l;
        for (int j = 0; j < lh; j++)
            for (int i = 0; i < lw; i++) {
                float mn = INFINITY, mx = -INFINITY;
                for (int q = 0; q < 4; q++) {
                    int a = 2 * i + (q & 1), b = 2 * j + (q >> 1);
                    if (a >= pw || b >= ph)
                        continue;
                    float lo, hi;
                    if (l == 1)
                        lo = hi = p[(size_t)b * w + a];
                    else {
                        lo = p[prev + 2 * ((size_t)b * pw + a)];
                        hi = p[prev + 2 * ((size_t)b * pw + a) + 1];
                    }
                    mn = fminf(mn, lo);
                    mx = fmaxf(mx, hi);
                }
                p[off + 2 * ((size_t)j * lw + i)] = mn;
                p[off + 2 * ((size_t)j * lw + i) + 1] = mx;
            }
        prev = off;
        off += 2 * (size_t)lw * lh;
        pw = lw;
        ph = lh;
    }
}

/* Floats of a w x h map with its nl levels. */
static size_t packed_size(int w, int h, int nl)
{
    size_t total = (size_t)w * h;
    for (int l = 1; l <= nl; l++)
        total += 2 * (size_t)((w + (1 << l) - 1) >> l) * (size_t)((h + (1 << l) - 1) >> l);
    return total;
}

int fp_shafts_pyramid(const float *z, int w, int h, float **out, size_t *n, int *levels)
{
    int nl = fp_shafts_levels(w, h);
    size_t total = packed_size(w, h, nl);
    float *p = malloc(total * sizeof *p);
    if (!p)
        return -1;
    for (size_t i = 0; i < (size_t)w * h; i++)
        p[i] = isnan(z[i]) ? INFINITY : z[i];
    build_levels(p, w, h, nl);
    *out = p;
    *n = total;
    *levels = nl;
    return 0;
}

int fp_shafts_build(const float *z, int w, int h, double max_slope_bias, double user_bias,
                    float **out, size_t *n, int *levels)
{
    int nl = fp_shafts_levels(w, h);
    size_t total = packed_size(w, h, nl);
    float *p = malloc(total * sizeof *p);
    if (!p)
        return -1;
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            double c = z[(size_t)j * w + i];
            if (!isfinite(c)) {
                p[(size_t)j * w + i] = INFINITY;
                continue;
            }
            double slope = 0.5 * (one_sided(z, w, h, i, j, 1, 0) + one_sided(z, w, h, i, j, 0, 1));
            double b = fmin(slope, max_slope_bias) + user_bias + 4e-7 * (fabs(c) + 1);
            /* Rounded up, so the bias never shrinks in float. */
            p[(size_t)j * w + i] = nextafterf((float)(c + b), INFINITY);
        }
    build_levels(p, w, h, nl);
    *out = p;
    *n = total;
    *levels = nl;
    return 0;
}

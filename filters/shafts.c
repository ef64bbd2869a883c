#include "shafts.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

int fp_shafts_levels(int w, int h)
{
    int l = 0;
    while ((1 << l) < w || (1 << l) < h)
        l++;
    return l;
}

/* The map is built for every frame of a sequence (the sun's map moves with
 * it), over about a million texels, so the per-texel work avoids calls:
 * fmin, fminf, fmaxf and nextafterf are library calls at -O2, and the
 * values compared are never NaN (undefined depths are +inf by then), where
 * a comparison gives their results (bit for bit; a min of +0 and -0 may
 * keep the other zero, which compares the same). */
static inline double min_d(double a, double b)
{
    return b < a ? b : a;
}

/* The smaller change of z from c to its finite neighbours a and b (either
 * may be absent: `has`), +inf when none. */
static inline double one_sided(double c, float a, int has_a, float b, int has_b)
{
    double best = INFINITY;
    if (has_a && isfinite(a))
        best = fabs(a - c);
    if (has_b && isfinite(b))
        best = min_d(best, fabs(b - c));
    return isfinite(best) ? best : 0;
}

/* nextafterf(x, +inf). */
static inline float next_up(float x)
{
    if (isnan(x) || x == INFINITY)
        return x;
    if (x == 0)
        return FLT_TRUE_MIN;
    union {
        float f;
        uint32_t u;
    } v = { x };
    v.u += x > 0 ? 1 : (uint32_t)-1;
    return v.f;
}

/* The largest float <= x and the least float >= x (x a double). */
static inline float float_down(double x)
{
    float f = (float)x;
    return (double)f > x ? -next_up(-f) : f;
}

static inline float float_up(double x)
{
    float f = (float)x;
    return (double)f < x ? next_up(f) : f;
}

/* Levels 1..nl of p (after its w x h level 0): min and max per block. */
/* finite_max: a block's largest finite value (+inf: none in it), for
 * the depth buffer's walk, where +inf (sky) is no cell at all: a block of
 * sky and geometry then bounds its cells' z, not [zmin, inf).  plane: the
 * bounds are of the residual zb - ga U - gb V over every point (U, V) of
 * the block's texels (texel (i, j) spans [i, i + 1) x [j, j + 1): its
 * center's residual less and plus half the plane's fall across it),
 * rounded outward to float. */
static void build_levels(float *p, int w, int h, int nl, int finite_max, int plane, double ga,
                         double gb)
{
    double half = 0.5 * (fabs(ga) + fabs(gb));
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
                    if (l == 1 && plane) {
                        double r = p[(size_t)b * w + a] - ga * (a + 0.5) - gb * (b + 0.5);
                        lo = float_down(r - half);
                        hi = float_up(r + half);
                    } else if (l == 1)
                        lo = hi = p[(size_t)b * w + a];
                    else {
                        lo = p[prev + 2 * ((size_t)b * pw + a)];
                        hi = p[prev + 2 * ((size_t)b * pw + a) + 1];
                    }
                    mn = lo < mn ? lo : mn;
                    mx = hi > mx && (!finite_max || hi < INFINITY) ? hi : mx;
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

size_t fp_shafts_size(int w, int h, int levels)
{
    return packed_size(w, h, levels);
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
    build_levels(p, w, h, nl, 1, 0, 0, 0);
    *out = p;
    *n = total;
    *levels = nl;
    return 0;
}

void fp_shafts_plane(const double *ndc, const double *cz, int w, int h, double *ga, double *gb)
{
    /* On y = c: (U, V) = A (x, z) + const, z_map = (cz0, cz2) (x, z) +
     * const, so z_map = (cz0, cz2) A^-1 (U, V) + const. */
    double a00 = ndc[0] * w, a01 = ndc[8] * w, a10 = ndc[1] * h, a11 = ndc[9] * h;
    double det = a00 * a11 - a01 * a10;
    double x = (cz[0] * a11 - cz[2] * a10) / det, y = (cz[2] * a00 - cz[0] * a01) / det;
    /* A sun at the horizon sees no ground: the plain min-max. */
    if (!(isfinite(x) && isfinite(y) && fabs(x) + fabs(y) < 1e6))
        x = y = 0;
    *ga = (float)x;
    *gb = (float)y;
}

int fp_shafts_build(const float *z, int w, int h, double max_slope_bias, double user_bias,
                    double ga, double gb, float **out, size_t *n, int *levels)
{
    int nl = fp_shafts_levels(w, h);
    size_t total = packed_size(w, h, nl);
    float *p = malloc(total * sizeof *p);
    if (!p)
        return -1;
    for (int j = 0; j < h; j++) {
        const float *row = z + (size_t)j * w;
        const float *up = j > 0 ? row - w : row, *down = j + 1 < h ? row + w : row;
        for (int i = 0; i < w; i++) {
            double c = row[i];
            if (!isfinite(c)) {
                p[(size_t)j * w + i] = INFINITY;
                continue;
            }
            /* The smaller one-sided change of z along each axis. */
            double sx = one_sided(c, row[i > 0 ? i - 1 : i], i > 0, row[i + 1 < w ? i + 1 : i],
                                  i + 1 < w);
            double sy = one_sided(c, up[i], j > 0, down[i], j + 1 < h);
            double slope = 0.5 * (sx + sy);
            double b = min_d(slope, max_slope_bias) + user_bias + 4e-7 * (fabs(c) + 1);
            /* Rounded up, so the bias never shrinks in float. */
            p[(size_t)j * w + i] = next_up((float)(c + b));
        }
    }
    build_levels(p, w, h, nl, 0, 1, ga, gb);
    *out = p;
    *n = total;
    *levels = nl;
    return 0;
}

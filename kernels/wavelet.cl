/* fogpipe: B-spline wavelet decomposition of the fogmap (seed 000 sec.
 * 3.2, 4.2, 4.4).  Host side and C reference: filters/wavelet.c, which
 * documents the lifting steps; these kernels compute the same steps out of
 * place, every work item recomputing the few intermediate lifting values
 * around its own coefficient, so one level is one kernel per direction.
 *
 * Along a line of n = 2 c samples (periodic), work item l of a forward
 * kernel writes s_l and d_l; of an inverse kernel, x_{2l} and x_{2l+1}. */
#include "bspline.h"

inline int wrap_index(int i, int n)
{
    i %= n;
    return i < 0 ? i + n : i;
}

/* Forward lifting at coarse index l from X(k) = x_{2l+k}, k = -3..3
 * (x[k + 3]).  Returns (s_l, d_l). */
inline float2 lift_forward(int d, const float *x)
{
#define X(k) x[(k) + 3]
    float s, dl;
    if (d == 0) {           /* Haar */
        dl = X(1) - X(0);
        s = X(0) + 0.5f * dl;
    } else if (d == 1) {    /* CDF (2,2) */
        float dm = X(-1) - 0.5f * (X(-2) + X(0));
        dl = X(1) - 0.5f * (X(0) + X(2));
        s = X(0) + 0.25f * (dm + dl);
    } else if (d == 2) {    /* CDF (3,1), Daubechies & Sweldens 1998 sec. 7 */
        float e0 = X(0) - X(-1) / 3.0f, e1 = X(2) - X(1) / 3.0f;
        dl = X(1) - (9.0f * e0 + 3.0f * e1) / 8.0f;
        s = 1.5f * (e0 + (4.0f / 9.0f) * dl);
    } else {                /* CDF (4,2) */
        float em = X(-2) - 0.25f * (X(-3) + X(-1));
        float e0 = X(0) - 0.25f * (X(-1) + X(1));
        float e1 = X(2) - 0.25f * (X(1) + X(3));
        float dm = X(-1) - (em + e0);
        dl = X(1) - (e0 + e1);
        s = 2.0f * (e0 + (3.0f / 16.0f) * (dm + dl));
    }
#undef X
    return (float2)(s, dl);
}

/* Inverse lifting at coarse index l from S(m) = s_{l+m}, D(m) = d_{l+m},
 * m = -2..2 (s[m + 2], dd[m + 2]).  Returns (x_{2l}, x_{2l+1}). */
inline float2 lift_inverse(int d, const float *s, const float *dd)
{
#define S(m) s[(m) + 2]
#define D(m) dd[(m) + 2]
    float x0, x1;
    if (d == 0) {
        x0 = S(0) - 0.5f * D(0);
        x1 = x0 + D(0);
    } else if (d == 1) {
        float e0 = S(0) - 0.25f * (D(-1) + D(0));
        float e1 = S(1) - 0.25f * (D(0) + D(1));
        x0 = e0;
        x1 = D(0) + 0.5f * (e0 + e1);
    } else if (d == 2) {
        float em = (2.0f / 3.0f) * S(-1) - (4.0f / 9.0f) * D(-1);
        float e0 = (2.0f / 3.0f) * S(0) - (4.0f / 9.0f) * D(0);
        float e1 = (2.0f / 3.0f) * S(1) - (4.0f / 9.0f) * D(1);
        float om = D(-1) + (9.0f * em + 3.0f * e0) / 8.0f;
        x1 = D(0) + (9.0f * e0 + 3.0f * e1) / 8.0f;
        x0 = e0 + om / 3.0f;
    } else {
        float em = 0.5f * S(-1) - (3.0f / 16.0f) * (D(-2) + D(-1));
        float e0 = 0.5f * S(0) - (3.0f / 16.0f) * (D(-1) + D(0));
        float e1 = 0.5f * S(1) - (3.0f / 16.0f) * (D(0) + D(1));
        float om = D(-1) + em + e0;
        x1 = D(0) + e0 + e1;
        x0 = e0 + 0.25f * (om + x1);
    }
#undef S
#undef D
    return (float2)(x0, x1);
}

/* The padded periodic domain (W x H) from the w x h fogmap placed at
 * (x0, y0): zeros around it (wrap 0), replicated edges (1), or the
 * fogmap itself (2, W = w, H = h, x0 = y0 = 0). */
__kernel void wavelet_pad(__global const float *img, const int w, const int h,
                          __global float *out, const int W, const int H, const int x0,
                          const int y0, const int wrap)
{
    int X = get_global_id(0), Y = get_global_id(1);
    if (X >= W || Y >= H)
        return;
    int i = X - x0, j = Y - y0;
    float v;
    if (wrap == 0 && (i < 0 || j < 0 || i >= w || j >= h)) {
        v = 0.0f;
    } else {
        i = clamp(i, 0, w - 1);
        j = clamp(j, 0, h - 1);
        v = img[j * w + i];
    }
    out[Y * W + X] = v;
}

/* Lifting along U of every row of src (nx x ny): lo, hi (nx/2 x ny). */
__kernel void wavelet_forward_rows(__global const float *src, const int nx, const int ny,
                                   __global float *lo, __global float *hi, const int degree)
{
    int l = get_global_id(0), y = get_global_id(1), c = nx / 2;
    if (l >= c || y >= ny)
        return;
    float x[7];
    __global const float *row = src + y * nx;
    for (int k = -3; k <= 3; k++)
        x[k + 3] = row[wrap_index(2 * l + k, nx)];
    float2 r = lift_forward(degree, x);
    lo[y * c + l] = r.x;
    hi[y * c + l] = r.y;
}

/* Lifting along V of every column of src (nx x ny): lo, hi (nx x ny/2). */
__kernel void wavelet_forward_cols(__global const float *src, const int nx, const int ny,
                                   __global float *lo, __global float *hi, const int degree)
{
    int x = get_global_id(0), l = get_global_id(1);
    if (x >= nx || l >= ny / 2)
        return;
    float v[7];
    for (int k = -3; k <= 3; k++)
        v[k + 3] = src[wrap_index(2 * l + k, ny) * nx + x];
    float2 r = lift_forward(degree, v);
    lo[l * nx + x] = r.x;
    hi[l * nx + x] = r.y;
}

/* Inverse lifting along V: lo, hi (nx x cy) -> dst (nx x 2 cy).  With
 * zero_lo set the low band is taken as 0 and not read (deconstruction). */
__kernel void wavelet_inverse_cols(__global const float *lo, __global const float *hi,
                                   const int nx, const int cy, const int zero_lo,
                                   __global float *dst, const int degree)
{
    int x = get_global_id(0), l = get_global_id(1);
    if (x >= nx || l >= cy)
        return;
    float s[5], dd[5];
    for (int m = -2; m <= 2; m++) {
        int at = wrap_index(l + m, cy) * nx + x;
        s[m + 2] = zero_lo ? 0.0f : lo[at];
        dd[m + 2] = hi[at];
    }
    float2 r = lift_inverse(degree, s, dd);
    dst[(2 * l) * nx + x] = r.x;
    dst[(2 * l + 1) * nx + x] = r.y;
}

/* Inverse lifting along U: lo, hi (cx x ny) -> dst (2 cx x ny). */
__kernel void wavelet_inverse_rows(__global const float *lo, __global const float *hi,
                                   const int cx, const int ny, __global float *dst,
                                   const int degree)
{
    int l = get_global_id(0), y = get_global_id(1);
    if (l >= cx || y >= ny)
        return;
    float s[5], dd[5];
    for (int m = -2; m <= 2; m++) {
        int at = y * cx + wrap_index(l + m, cx);
        s[m + 2] = lo[at];
        dd[m + 2] = hi[at];
    }
    float2 r = lift_inverse(degree, s, dd);
    dst[y * 2 * cx + 2 * l] = r.x;
    dst[y * 2 * cx + 2 * l + 1] = r.y;
}

/* For the tests: kernels/bspline.h evaluated in float on the device, to
 * compare with its double C version.  Per x: b_d(x), then the cell (k, s)
 * of x and the four weights at s. */
__kernel void wavelet_bspline_check(__global const float *x, const int n, const int degree,
                                    __global float *out)
{
    int i = get_global_id(0);
    if (i >= n)
        return;
    float w[4], s;
    int k;
    fp_bspline_cell(degree, x[i], &k, &s);
    fp_bspline_weights(degree, s, w);
    __global float *o = out + 7 * i;
    o[0] = fp_bspline(degree, x[i]);
    o[1] = (float)k;
    o[2] = s;
    for (int j = 0; j < 4; j++)
        o[3 + j] = w[j];
}

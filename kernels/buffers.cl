/* fogpipe: depth-aware bilateral blur of the fog layer and joint bilateral
 * upsampling of reduced-resolution fog.  Host side and C reference:
 * filters/buffers.c, which these kernels follow step for step. */

/* Must match FP_UPSAMPLE_EPS in filters/buffers.c. */
#define FP_UPSAMPLE_EPS 1e-3f

/* exp(-r^2 / (2 range^2)), r = |d1 - d2| / min(d1, d2); sky (+inf) blends
 * only with sky. */
inline float range_weight(float d1, float d2, float inv_range)
{
    int s1 = isinf(d1), s2 = isinf(d2);
    if (s1 || s2)
        return (s1 && s2) ? 1.0f : 0.0f;
    float m = fmin(d1, d2);
    if (!(m > 0.0f))
        return d1 == d2 ? 1.0f : 0.0f;
    float r = fabs(d1 - d2) / m * inv_range;
    return exp(-0.5f * r * r);
}

inline float rel_diff(float d1, float d2)
{
    int s1 = isinf(d1), s2 = isinf(d2);
    if (s1 || s2)
        return (s1 && s2) ? 0.0f : INFINITY;
    float m = fmin(d1, d2);
    if (!(m > 0.0f))
        return d1 == d2 ? 0.0f : INFINITY;
    return fabs(d1 - d2) / m;
}

/* One 1D pass along (dx, dy) of the separable blur: Gaussian times the
 * range weight against the center pixel; samples outside the frame left out. */
__kernel void blur_pass(__global const float4 *in, __global float4 *out,
                        __global const float *dist, const int width, const int height,
                        const int radius, const float inv2s2, const float inv_range,
                        const int dx, const int dy)
{
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height)
        return;
    int c = y * width + x;
    float dc = dist[c];
    float4 sum = (float4)(0.0f);
    float ws = 0.0f;
    for (int k = -radius; k <= radius; k++) {
        int xx = x + k * dx, yy = y + k * dy;
        if (xx < 0 || xx >= width || yy < 0 || yy >= height)
            continue;
        int j = yy * width + xx;
        float wt = exp(-(float)(k * k) * inv2s2) * range_weight(dc, dist[j], inv_range);
        if (wt == 0.0f)
            continue;
        sum += wt * in[j];
        ws += wt;
    }
    out[c] = sum / ws;
}

/* The full 2D kernel. */
__kernel void blur_full(__global const float4 *in, __global float4 *out,
                        __global const float *dist, const int width, const int height,
                        const int radius, const float inv2s2, const float inv_range)
{
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height)
        return;
    int c = y * width + x;
    float dc = dist[c];
    float4 sum = (float4)(0.0f);
    float ws = 0.0f;
    for (int ky = -radius; ky <= radius; ky++) {
        int yy = y + ky;
        if (yy < 0 || yy >= height)
            continue;
        float gy = exp(-(float)(ky * ky) * inv2s2);
        for (int kx = -radius; kx <= radius; kx++) {
            int xx = x + kx;
            if (xx < 0 || xx >= width)
                continue;
            int j = yy * width + xx;
            float wt = exp(-(float)(kx * kx) * inv2s2) * gy * range_weight(dc, dist[j], inv_range);
            if (wt == 0.0f)
                continue;
            sum += wt * in[j];
            ws += wt;
        }
    }
    out[c] = sum / ws;
}

/* Near-camera falloff: the unblurred fog within D, the blurred from 2 D on,
 * linear between. */
__kernel void blur_falloff(__global const float4 *orig, __global float4 *fog,
                           __global const float *dist, const int width, const int height,
                           const float falloff)
{
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height)
        return;
    int i = y * width + x;
    float a = clamp((dist[i] - falloff) / falloff, 0.0f, 1.0f);
    fog[i] = (1.0f - a) * orig[i] + a * fog[i];
}

/* Joint bilateral upsampling: the 4 x 4 low-resolution samples around the
 * pixel (sample (i, j) at full-resolution pixel (f i, f j)), Gaussian in
 * full-resolution pixels (sigma f / 2) times the range weight; where no
 * sample matches the pixel's distance, the nearest one in distance. */
__kernel void upsample_fog(__global const float4 *lo, __global float4 *fog,
                       __global const float *dist, const int f, const int width,
                       const int height, const int lw, const int lh, const float inv2s2,
                       const float inv_range)
{
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height)
        return;
    int p = y * width + x;
    float dp = dist[p];
    float4 sum = (float4)(0.0f);
    float ws = 0.0f, gs = 0.0f;
    float best_rel = INFINITY, best_ds = -INFINITY, best_sd2 = INFINITY;
    int best = -1;
    int ci = x / f, cj = y / f;
    for (int j = cj - 1; j <= cj + 2; j++) {
        if (j < 0 || j >= lh)
            continue;
        for (int i = ci - 1; i <= ci + 2; i++) {
            if (i < 0 || i >= lw)
                continue;
            int s = j * lw + i;
            float ds = dist[(f * j) * width + f * i];
            float sx = (float)(x - f * i), sy = (float)(y - f * j);
            float sd2 = sx * sx + sy * sy;
            float g = exp(-sd2 * inv2s2);
            float wt = g * range_weight(dp, ds, inv_range);
            gs += g;
            if (wt > 0.0f) {
                sum += wt * lo[s];
                ws += wt;
            }
            float rel = rel_diff(dp, ds);
            int take;
            if (best < 0)
                take = 1;
            else if (rel != best_rel)
                take = rel < best_rel;
            else if (isinf(dp))
                take = ds > best_ds;
            else
                take = sd2 < best_sd2;
            if (take) {
                best = s;
                best_rel = rel;
                best_ds = ds;
                best_sd2 = sd2;
            }
        }
    }
    fog[p] = ws > FP_UPSAMPLE_EPS * gs ? sum / ws : lo[best];
}

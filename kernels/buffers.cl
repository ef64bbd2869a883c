/* fogpipe: depth-aware bilateral blur of the fog layer and joint bilateral
 * upsampling of reduced-resolution fog, one work-item per pixel.  The
 * per-pixel code is buffers_core.h, shared with the C reference
 * (filters/buffers.c, which also holds the host side). */
#include "buffers_core.h"

/* One blur of the whole layer: a separable pass (rx or ry 0) or the full
 * 2D kernel (fp_buf_blur_pixel). */
__kernel void blur(__global const float *in, __global float *out, __global const float *dist,
                   const int width, const int height, const int rx, const int ry,
                   const float inv2s2, const float inv_range)
{
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height)
        return;
    vstore4(fp_buf_blur_pixel(in, dist, width, height, x, y, rx, ry, inv2s2, inv_range),
            y * width + x, out);
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
    float a = fp_buf_falloff(dist[i], falloff);
    fog[i] = (1.0f - a) * orig[i] + a * fog[i];
}

/* Joint bilateral upsampling of the lw x lh layer lo (fp_buf_upsample_pixel). */
__kernel void upsample_fog(__global const float *lo, __global float *fog,
                           __global const float *dist, const int f, const int width,
                           const int height, const int lw, const int lh, const float inv2s2,
                           const float inv_range)
{
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height)
        return;
    vstore4(fp_buf_upsample_pixel(lo, dist, f, width, lw, lh, x, y, inv2s2, inv_range),
            y * width + x, fog);
}

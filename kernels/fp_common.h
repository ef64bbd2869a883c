/* fogpipe kernels: shared helpers (view rays, layout of the view buffer).
 * The layout matches fp_view_pack() in src/scene/camera.c. */
#ifndef FP_COMMON_H
#define FP_COMMON_H

#include "view_layout.h"

#define FP_DEPTH_PLANAR 0
#define FP_DEPTH_RADIAL 1
#define FP_DEPTH_INVERSE 2

/* Sky: inf, NaN, negative, >= 1e10, 0 for inverse depth, beyond far
 * (fp_view_is_sky in src/scene/camera.c). */
inline int fp_is_sky(__constant const float *view, float depth)
{
    if (isnan(depth) || depth < 0.0f)
        return 1;
    float z = depth;
    if ((int)view[FP_VIEW_DEPTH_KIND] == FP_DEPTH_INVERSE) {
        if (depth == 0.0f)
            return 1;
        z = 1.0f / depth;
    }
    return isinf(z) || z >= 1e10f || z >= view[FP_VIEW_FAR];
}

/* Unit direction (fog space) and length of the view ray of data-window
 * pixel (x, y); len = INFINITY for sky.  As fp_view_ray() in C: an
 * orthographic ray runs along the view axis, its depth the distance from
 * the camera's plane. */
inline float3 fp_view_ray(__constant const float *view, int x, int y, float depth,
                          float *len)
{
    __constant const float *h = view + FP_VIEW_H;
    __constant const float *m = view + FP_VIEW_M;
    float cx = 0.0f, cy = 0.0f;
    if (view[FP_VIEW_ORTHO] == 0.0f) {
        float nx = ((float)x + view[FP_VIEW_NDC_OFFSET]) * view[FP_VIEW_NDC_SCALE];
        float ny = ((float)y + view[FP_VIEW_NDC_OFFSET + 1]) * view[FP_VIEW_NDC_SCALE + 1];
        float cw = h[6] * nx + h[7] * ny + h[8];
        cx = (h[0] * nx + h[1] * ny + h[2]) / cw;
        cy = (h[3] * nx + h[4] * ny + h[5]) / cw;
    }
    float3 d = (float3)(m[0] * cx + m[1] * cy + m[2],
                        m[3] * cx + m[4] * cy + m[5],
                        m[6] * cx + m[7] * cy + m[8]);
    float l = length(d);
    int sky = fp_is_sky(view, depth);
    float scale = 1.0f;
    int kind = (int)view[FP_VIEW_DEPTH_KIND];
    if (!sky) {
        if (kind == FP_DEPTH_PLANAR)
            scale = depth;
        else if (kind == FP_DEPTH_RADIAL)
            scale = depth / sqrt(cx * cx + cy * cy + 1.0f);
        else
            scale = 1.0f / depth;
    }
    *len = sky ? INFINITY : l * scale;
    /* From the clip plane (fp_view_origin_at): l * clip along the ray. */
    float clip = view[FP_VIEW_CLIP];
    if (clip > 0.0f && !sky)
        *len = fmax(*len - l * clip, 0.0f);
    return d / l;
}

/* Where the view ray of pixel (x, y) starts (fog space): the camera, or
 * for an orthographic camera the pixel's point on the camera's plane.  As
 * fp_view_origin_at() in C. */
inline float3 fp_view_origin_at(__constant const float *view, int x, int y)
{
    float3 o = (float3)(view[0], view[1], view[2]);
    int ortho = view[FP_VIEW_ORTHO] != 0.0f;
    float clip = view[FP_VIEW_CLIP];
    if (!ortho && !(clip > 0.0f))
        return o;
    __constant const float *h = view + FP_VIEW_H;
    __constant const float *m = view + FP_VIEW_M;
    float nx = ((float)x + view[FP_VIEW_NDC_OFFSET]) * view[FP_VIEW_NDC_SCALE];
    float ny = ((float)y + view[FP_VIEW_NDC_OFFSET + 1]) * view[FP_VIEW_NDC_SCALE + 1];
    float cw = h[6] * nx + h[7] * ny + h[8];
    float px = (h[0] * nx + h[1] * ny + h[2]) / cw;
    float py = (h[3] * nx + h[4] * ny + h[5]) / cw;
    if (ortho)
        o += (float3)(m[0] * px + m[1] * py, m[3] * px + m[4] * py, m[6] * px + m[7] * py);
    if (clip > 0.0f) {
        /* To the clip plane: the camera vector (x/z, y/z, 1) (orthographic:
         * (0, 0, 1)) times the planar depth. */
        float cx = ortho ? 0.0f : px, cy = ortho ? 0.0f : py;
        o += clip * (float3)(m[0] * cx + m[1] * cy + m[2], m[3] * cx + m[4] * cy + m[5],
                             m[6] * cx + m[7] * cy + m[8]);
    }
    return o;
}

/* The pixel (x, y) a work-item of a per-pixel fog kernel computes and the
 * index of its result: the whole frame (npix 0: 2D ids, result at
 * y * width + x) or the pixels pix[0 .. npix) of the frame (indices
 * y * width + x; 1D ids, results in list order).  0 for ids past the end. */
inline int fp_work_pixel(__global const int *pix, int npix, int width, int height, int *x,
                         int *y, int *out)
{
    if (npix > 0) {
        int g = get_global_id(0);
        if (g >= npix)
            return 0;
        int p = pix[g];
        *x = p % width;
        *y = p / width;
        *out = g;
        return 1;
    }
    *x = get_global_id(0);
    *y = get_global_id(1);
    if (*x >= width || *y >= height)
        return 0;
    *out = *y * width + *x;
    return 1;
}

#endif

/* fogpipe: exact integration of extinction along each view ray.
 * Host side and C reference: filters/integrate.c. */
#include "fp_common.h"

/* The t-interval [*a, *b] within [0, len] where lo <= oy + t dy < hi. */
inline int slab_interval(float oy, float dy, float lo, float hi, float len,
                         float *a, float *b)
{
    float t0, t1;
    if (dy == 0.0f) {
        if (oy < lo || oy >= hi)
            return 0;
        t0 = 0.0f;
        t1 = len;
    } else {
        float u = (lo - oy) / dy, v = (hi - oy) / dy;
        t0 = fmax(fmin(u, v), 0.0f);
        t1 = fmin(fmax(u, v), len);
    }
    *a = t0;
    *b = t1;
    return t1 > t0;
}

/* Optical depth of sigma * h(y), h = 1 below y0, exp(-(y - y0)/H) up to
 * top, 0 above (DESIGN, Conventions), along oy + t dy for t in [0, len]. */
inline float height_optical_depth(float4 fog, float oy, float dy, float len)
{
    float sigma = fog.x, y0 = fog.y, H = fog.z, top = fog.w;
    float od = 0.0f, a, b;
    if (sigma <= 0.0f)
        return 0.0f;
    if (slab_interval(oy, dy, -INFINITY, fmin(y0, top), len, &a, &b))
        od += b - a;
    if (slab_interval(oy, dy, y0, top, len, &a, &b)) {
        float ya = (oy + a * dy - y0) / H;
        if (isinf(b)) {
            /* Only a rising (or level) ray reaches infinity in this slab. */
            od += dy > 0.0f ? exp(-ya) * H / dy : (exp(-ya) > 0.0f ? INFINITY : 0.0f);
        } else {
            float D = fabs(dy) * (b - a) / H;
            float m = dy < 0.0f ? ya - D : ya;   /* the lowest point: largest density */
            od += (b - a) * exp(-m) * fp_expm1_ratio(D);
        }
    }
    return sigma * od;
}

/* Per pixel: fog layer (S.rgb, tau) with the ambient in-scatter of seed 000
 * eq. 4: S = (1 - tau) * fog_color. */
__kernel void integrate_height(__global const float *depth, __global float4 *fog_out,
                               __constant const float *view, const int width,
                               const int height, const float4 fog, const float4 fog_color)
{
    int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height)
        return;
    int i = y * width + x;
    float len;
    float3 dir = fp_view_ray(view, x, y, depth[i], &len);
    float3 o = fp_view_origin(view);
    float tau = exp(-height_optical_depth(fog, o.y, dir.y, len));
    float3 s = (1.0f - tau) * fog_color.xyz;
    fog_out[i] = (float4)(s, tau);
}

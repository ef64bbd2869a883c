/* fogpipe: exact integration of extinction along each view ray, and the fog
 * layer (S, tau).  Host side and C reference: filters/integrate.c; the ray
 * integrals themselves are in fog_core.h, shared with the reference. */
#include "fp_common.h"
#include "fog_core.h"

/* Deterministic per-pixel offset in [-0.5, 0.5) for --jitter: the same
 * pattern every frame, so a still camera gives still fog. */
inline float pixel_jitter(int x, int y)
{
    uint h = (uint)x * 73856093u ^ (uint)y * 19349663u;
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    return (float)(h & 0xffffffu) / 16777216.0f - 0.5f;
}

/* Per pixel (of the frame or of a list, fp_work_pixel): fog layer (S.rgb, tau) with the ambient in-scatter of seed 000
 * eq. 4: S = (1 - tau) * fog_color. */
__kernel void integrate_fog(__global const float *depth, __global float4 *fog_out,
                            __constant const float *view, const int width, const int height,
                            __constant const float *fp, __constant const int *lvi,
                            __constant const float *lvf, __global const float *coef,
                            __global const uchar *occ, __global const int *pix, const int npix,
                            const float4 fog_color)
{
    int x, y, out;
    if (!fp_work_pixel(pix, npix, width, height, &x, &y, &out))
        return;
    int i = y * width + x;
    float len;
    float3 dir = fp_view_ray(view, x, y, depth[i], &len);
    float3 o = fp_view_origin_at(view, x, y);
    float jitter = fp[FP_F_JITTER] != 0.0f ? pixel_jitter(x, y) : 0.0f;
    float od = fp_fog_od(fp, lvi, lvf, coef, occ, o.x, o.y, o.z, dir.x, dir.y, dir.z, len, jitter);
    float tau = exp(-od);
    float3 s = (1.0f - tau) * fog_color.xyz;
    fog_out[out] = (float4)(s, tau);
}

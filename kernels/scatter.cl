/* fogpipe: single scattering per pixel (ambient, sun with shadows and fog
 * self-shadowing, local lights).  Host side and C reference:
 * filters/scatter.c; the integral itself is in scatter_core.h. */
#include "fp_common.h"
#include "fog_core.h"
#include "light_core.h"
/* Local lights by the fast rule run apart, one launch of scatter_light
 * per light (filters/scatter.c): a kernel body without loops of varying
 * length, which the CPU device vectorises across work-items. */
#define FP_LIGHTS_APART
#include "scatter_core.h"

/* Per pixel (of the frame or of a list, fp_work_pixel): S.rgb and tau. */
__kernel void scatter_fog(__global const float *depth, __global float4 *fog_out,
                          __constant const float *view, const int width, const int height,
                          __constant const float *fp, __constant const int *lvi,
                          __constant const float *lvf, __global const float *coef,
                          __global const uchar *occ, __global const int *pix, const int npix,
                          __constant const float *lt, __global const float *smap,
                          __global const float *grid)
{
    int x, y, out;
    if (!fp_work_pixel(pix, npix, width, height, &x, &y, &out))
        return;
    int i = y * width + x;
    float len;
    float3 dir = fp_view_ray(view, x, y, depth[i], &len);
    float3 o = fp_view_origin_at(view, x, y);
    float S[3];
    float tau = fp_scatter_ray_core(fp, lvi, lvf, coef, occ, lt, smap, grid, view, depth, width,
                                    height, o.x, o.y, o.z, dir.x, dir.y, dir.z, len,
                                    fp_interleave_offset(lt, x, y), S);
    fog_out[out] = (float4)(S[0], S[1], S[2], tau);
}

/* The self-shadow grid (light_core.h): one column of nodes along the sun
 * per work-item, (i, j) across the sun in cascade c. */
__kernel void sun_od_grid(__global float *grid, __constant const float *fp,
                          __constant const int *lvi, __constant const float *lvf,
                          __global const float *coef, __global const uchar *occ,
                          __constant const float *lt)
{
    int i = get_global_id(0), j = get_global_id(1), c = get_global_id(2);
    if (i >= (int)lt[FP_LT_GRID_N] || j >= (int)lt[FP_LT_GRID_N + 1] || c >= (int)lt[FP_LT_GRID_K])
        return;
    fp_sun_od_column(fp, lvi, lvf, coef, occ, lt, grid, c, i, j);
}

/* One local light (fast rule, fog without a fogmap) added to the fog layer
 * that scatter_fog wrote: per pixel (of the frame or of a list).  The view
 * ray is fp_view_ray's, written out here so that nothing is called. */
__kernel void scatter_light(__global const float *depth, __global float4 *fog_out,
                            __constant const float *view, const int width, const int height,
                            __constant const float *fp, __global const int *pix, const int npix,
                            __constant const float *lt, const int light)
{
    int g = get_global_id(0);
    int list = npix > 0;
    int p = pix[list ? min(g, npix - 1) : 0];
    int x = list ? p % width : g, y = list ? p / width : (int)get_global_id(1);
    int out = list ? g : y * width + x;
    int in = !(list && g >= npix) && x < width && y < height;
    x = in ? x : 0;
    y = in ? y : 0;
    __constant const float *h = view + FP_VIEW_H;
    __constant const float *m = view + FP_VIEW_M;
    float nx = ((float)x + view[FP_VIEW_NDC_OFFSET]) * view[FP_VIEW_NDC_SCALE];
    float ny = ((float)y + view[FP_VIEW_NDC_OFFSET + 1]) * view[FP_VIEW_NDC_SCALE + 1];
    float cw = h[6] * nx + h[7] * ny + h[8];
    float px = (h[0] * nx + h[1] * ny + h[2]) / cw, py = (h[3] * nx + h[4] * ny + h[5]) / cw;
    /* Orthographic (fp_view_ray, fp_view_origin_at): rays along the view
     * axis from the pixel's point on the camera's plane. */
    float ortho = view[FP_VIEW_ORTHO] != 0.0f ? 1.0f : 0.0f;
    float cx = (1.0f - ortho) * px, cy = (1.0f - ortho) * py;
    float ox = view[0] + ortho * (m[0] * px + m[1] * py),
          oy = view[1] + ortho * (m[3] * px + m[4] * py),
          oz = view[2] + ortho * (m[6] * px + m[7] * py);
    float dx = m[0] * cx + m[1] * cy + m[2], dy = m[3] * cx + m[4] * cy + m[5],
          dz = m[6] * cx + m[7] * cy + m[8];
    float l = sqrt(dx * dx + dy * dy + dz * dz);
    float dv = depth[y * width + x];
    int kind = (int)view[FP_VIEW_DEPTH_KIND];
    float z = kind == FP_DEPTH_INVERSE ? 1.0f / dv : dv;
    int sky = isnan(dv) || dv < 0.0f || (kind == FP_DEPTH_INVERSE && dv == 0.0f) || isinf(z) ||
              z >= 1e10f || z >= view[FP_VIEW_FAR];
    float scale = kind == FP_DEPTH_PLANAR ? dv
                  : kind == FP_DEPTH_RADIAL ? dv / sqrt(cx * cx + cy * cy + 1.0f) : 1.0f / dv;
    float len = sky ? INFINITY : l * scale;
    float S[3];
    fp_light_ray(fp, lt, light, ox, oy, oz, dx / l, dy / l, dz / l, len, S);
    if (in)
        fog_out[out] += (float4)(S[0], S[1], S[2], 0.0f);
}

/* fogpipe: single scattering per pixel (ambient, sun with shadows and fog
 * self-shadowing, local lights).  Host side and C reference:
 * filters/scatter.c; the integral itself is in scatter_core.h. */
#include "fp_common.h"
#include "fog_core.h"
#include "light_core.h"
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

/* The self-shadow grid: optical depth from each node to the sun, exact. */
__kernel void sun_od_grid(__global float *grid, __constant const float *fp,
                          __constant const int *lvi, __constant const float *lvf,
                          __global const float *coef, __global const uchar *occ,
                          __constant const float *lt)
{
    int i = get_global_id(0), j = get_global_id(1), k = get_global_id(2);
    int nx = (int)lt[FP_LT_GRID_N], ny = (int)lt[FP_LT_GRID_N + 1], nz = (int)lt[FP_LT_GRID_N + 2];
    if (i >= nx || j >= ny || k >= nz)
        return;
    float x = lt[FP_LT_GRID] + i * lt[FP_LT_GRID_CELL];
    float y = lt[FP_LT_GRID + 1] + j * lt[FP_LT_GRID_CELL + 1];
    float z = lt[FP_LT_GRID + 2] + k * lt[FP_LT_GRID_CELL + 2];
    __constant const float *l = lt + FP_LT_SUN_DIR;
    grid[(k * ny + j) * nx + i] = fp_fog_od(fp, lvi, lvf, coef, occ, x, y, z, l[0], l[1], l[2],
                                            INFINITY, 0);
}

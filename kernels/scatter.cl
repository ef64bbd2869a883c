/* fogpipe: single scattering per pixel (ambient, sun with shadows and fog
 * self-shadowing, local lights).  Host side and C reference:
 * filters/scatter.c; the integral itself is in scatter_core.h. */
#include "fp_common.h"
#include "fog_core.h"
#include "light_core.h"
/* Local lights by the fast rule run apart, all in one launch of
 * scatter_lights (filters/scatter_cl.c), 16 pixels per work-item as vector
 * lanes (scatter_lanes.h), which the CPU device runs as SIMD code. */
#define FP_LIGHTS_APART
#include "scatter_core.h"
#include "scatter_lanes.h"
#include "lamp_shadow_fix.h"

/* Per pixel (of the frame or of a list, fp_work_pixel): S.rgb and tau. */
__kernel void scatter_fog(__global const float *depth, __global float4 *fog_out,
                          __constant const float *view, const int width, const int height,
                          __constant const float *fp, __constant const int *lvi,
                          __constant const float *lvf, __global const float *coef,
                          __global const uchar *occ, __global const int *pix, const int npix,
                          __constant const float *lt, __global const float *smap,
                          __global const float *grid, __global const float *lights)
{
    int x, y, out;
    if (!fp_work_pixel(pix, npix, width, height, &x, &y, &out))
        return;
    int i = y * width + x;
    float len;
    float3 dir = fp_view_ray(view, x, y, depth[i], &len);
    float3 o = fp_view_origin_at(view, x, y);
    float S[3];
    float tau = fp_scatter_ray_core(fp, lvi, lvf, coef, occ, lt, lights, smap, grid, view, depth,
                                    width, height, o.x, o.y, o.z, dir.x, dir.y, dir.z, len,
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

/* Every local light (fast rule, fog without a fogmap) added to the fog
 * layer that scatter_fog wrote, FP_LN_LANES (16) pixels per work-item as
 * the lanes of kernels/scatter_lanes.h, all lights in one launch: the
 * frame's pixels x0 .. x0 + 15 of row y (work-item (x0 / 16, y)), or when
 * npix > 0 the list's entries k0 .. k0 + 15 (pixels y * width + x, results
 * in list order, work-item k0 / 16).  Lanes past the end repeat the last
 * pixel and are not stored.  The view ray is fp_view_ray's and
 * fp_view_origin_at's on lanes. */
__kernel void scatter_lights(__global const float *restrict depth,
                             __global float *restrict fog_out,
                             __constant const float *restrict view, const int width,
                             const int height, __constant const float *restrict fp,
                             __global const int *restrict pix, const int npix,
                             __constant const float *restrict lt,
                             __global const float *restrict lights)
{
    int k0 = (int)get_global_id(0) * FP_LN_LANES, row = (int)get_global_id(1);
    int list = npix > 0, end = list ? npix : width;
    if (k0 >= end || (!list && row >= height))
        return;
    int n = min(FP_LN_LANES, end - k0), npx = width * height;
    size_t out0 = list ? (size_t)k0 : (size_t)row * width + k0;
    float lx[FP_LN_LANES], ly[FP_LN_LANES], ld[FP_LN_LANES];
    int valid[FP_LN_LANES];
    for (int j = 0; j < FP_LN_LANES; j++) {
        int p = list ? pix[k0 + min(j, n - 1)] : row * width + k0 + min(j, n - 1);
        valid[j] = p >= 0 && p < npx;
        p = valid[j] ? p : 0;
        int y = p / width;
        lx[j] = (float)(p - y * width);
        ly[j] = (float)y;
        ld[j] = depth[p];
    }
    fp_lnr x = FP_LN_CAT(vload, FP_LN_LANES)(0, lx), y = FP_LN_CAT(vload, FP_LN_LANES)(0, ly);
    fp_lnr dv = FP_LN_CAT(vload, FP_LN_LANES)(0, ld);
    __constant const float *h = view + FP_VIEW_H;
    __constant const float *m = view + FP_VIEW_M;
    fp_lnr nx = (x + view[FP_VIEW_NDC_OFFSET]) * view[FP_VIEW_NDC_SCALE];
    fp_lnr ny = (y + view[FP_VIEW_NDC_OFFSET + 1]) * view[FP_VIEW_NDC_SCALE + 1];
    fp_lnr cw = h[6] * nx + h[7] * ny + h[8];
    fp_lnr px = (h[0] * nx + h[1] * ny + h[2]) / cw, py = (h[3] * nx + h[4] * ny + h[5]) / cw;
    /* Orthographic: rays along the view axis from the pixel's point on the
     * camera's plane. */
    int ortho = view[FP_VIEW_ORTHO] != 0.0f;
    fp_lnr cx = ortho ? FP_LN(0.0f) : px, cy = ortho ? FP_LN(0.0f) : py;
    fp_lnr ox = FP_LN(view[0]), oy = FP_LN(view[1]), oz = FP_LN(view[2]);
    if (ortho) {
        ox += m[0] * px + m[1] * py;
        oy += m[3] * px + m[4] * py;
        oz += m[6] * px + m[7] * py;
    }
    fp_lnr dx = m[0] * cx + m[1] * cy + m[2], dy = m[3] * cx + m[4] * cy + m[5],
           dz = m[6] * cx + m[7] * cy + m[8];
    fp_lnr l = sqrt(dx * dx + dy * dy + dz * dz);
    /* fp_is_sky: inf, NaN, negative, 0 for inverse depth, >= 1e10, beyond
     * far. */
    int kind = (int)view[FP_VIEW_DEPTH_KIND];
    fp_lnr z = kind == FP_DEPTH_INVERSE ? 1.0f / dv : dv;
    fp_lni sky = isnan(dv) | (dv < 0.0f) | isinf(z) | (z >= 1e10f) | (z >= view[FP_VIEW_FAR]);
    if (kind == FP_DEPTH_INVERSE)
        sky |= dv == 0.0f;
    fp_lnr scale = kind == FP_DEPTH_PLANAR ? dv
                   : kind == FP_DEPTH_RADIAL ? dv / sqrt(cx * cx + cy * cy + 1.0f) : 1.0f / dv;
    fp_lnr len = sky ? FP_LN(INFINITY) : l * scale;
    float clip = view[FP_VIEW_CLIP];
    if (clip > 0.0f) {
        /* From the clip plane (fp_view_origin_at): l * clip along the ray. */
        len = sky ? len : fmax(len - l * clip, 0.0f);
        ox += clip * dx;
        oy += clip * dy;
        oz += clip * dz;
    }
    dx /= l;
    dy /= l;
    dz /= l;
    /* Each light added in turn to what scatter_fog wrote (the order of
     * one launch per light). */
    __global float *o = fog_out + 4 * out0;
    float sr[FP_LN_LANES], sg[FP_LN_LANES], sb[FP_LN_LANES], st[FP_LN_LANES];
    for (int j = 0; j < FP_LN_LANES; j++) {
        int jj = min(j, n - 1);
        sr[j] = o[4 * jj];
        sg[j] = o[4 * jj + 1];
        sb[j] = o[4 * jj + 2];
        st[j] = o[4 * jj + 3];
    }
    fp_lnr S[3] = { FP_LN_CAT(vload, FP_LN_LANES)(0, sr), FP_LN_CAT(vload, FP_LN_LANES)(0, sg),
                    FP_LN_CAT(vload, FP_LN_LANES)(0, sb) };
    /* Culling (fp_light_bound): a light is left out of these 16 pixels
     * when every one of them can spare its bound from what is left of its
     * budget (--light-cull); 1 - tau from scatter_fog's tau. */
    fp_lnr omt = 1.0f - FP_LN_CAT(vload, FP_LN_LANES)(0, st);
    fp_lnr budget = FP_LN(lt[FP_LT_CULL]), ta, tb;
    fp_ln_span(fp, ox, oy, oz, dx, dy, dz, len, &ta, &tb);
    fp_lnr smax = fp_ln_sigma_span(fp, oy, dy, ta, tb);
    int nl = (int)lt[FP_LT_NLIGHTS];
    for (int k = 0; k < nl; k++) {
        if (lt[FP_LT_CULL] > 0) {
            fp_lnr b = fp_ln_bound(lt, lights + k * FP_LL_STRIDE, smax, omt, ox, oy, oz, dx, dy,
                                   dz, ta, tb);
            b = tb > ta ? b : FP_LN(0);
            if (all(b <= budget)) {
                budget -= b;
                continue;
            }
        }
        fp_lnr Sk[3];
        fp_ln_light_ray(fp, lt, lights, k, ox, oy, oz, dx, dy, dz, len, Sk);
        S[0] += Sk[0];
        S[1] += Sk[1];
        S[2] += Sk[2];
    }
    FP_LN_CAT(vstore, FP_LN_LANES)(S[0], 0, sr);
    FP_LN_CAT(vstore, FP_LN_LANES)(S[1], 0, sg);
    FP_LN_CAT(vstore, FP_LN_LANES)(S[2], 0, sb);
    for (int j = 0; j < n; j++) {
        if (!valid[j])
            continue;
        o[4 * j] = sr[j];
        o[4 * j + 1] = sg[j];
        o[4 * j + 2] = sb[j];
    }
}

/* The local lights' screen-space shadows (--lamp-shadows screen,
 * kernels/lamp_shadow_core.h fp_ls_fix), per pixel after scatter_lights
 * added the lights unshadowed: each light that reaches the pixel and is
 * shadowed along its ray gives back what its shadowed stretches held. */
__kernel void lamp_shadows(__global const float *depth, __global float4 *fog_out,
                           __constant const float *view, const int width, const int height,
                           __constant const float *fp, __global const int *pix, const int npix,
                           __constant const float *lt, __global const float *smap,
                           __global const float *lights)
{
    int x, y, out;
    if (!fp_work_pixel(pix, npix, width, height, &x, &y, &out))
        return;
    int i = y * width + x;
    float len;
    float3 dir = fp_view_ray(view, x, y, depth[i], &len);
    float3 o = fp_view_origin_at(view, x, y);
    float4 f = fog_out[out];
    float S[3] = { f.x, f.y, f.z };
    fp_ls_fix(fp, lt, lights, view, smap, o.x, o.y, o.z, dir.x, dir.y, dir.z, len, f.w, S);
    fog_out[out] = (float4)(S[0], S[1], S[2], f.w);
}

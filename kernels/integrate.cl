/* fogpipe: exact integration of extinction along each view ray, and the fog
 * layer (S, tau).  Host side and C reference: filters/integrate.c; the ray
 * integrals themselves are in fog_core.h, shared with the reference. */
#include "fp_common.h"
#include "fog_core.h"
#include "fogmap_lanes.h"

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

/* Fog without a fogmap (the host's choice when FP_F_HAS_MAP is 0): the
 * transmittance tau of integrate_fog for FP_SIMD (16) pixels per
 * work-item, as float16 lanes (the layer follows from it: S = (1 - tau) *
 * fog color, height_fog_rgba4): the view ray of fp_view_ray with its sky
 * test and depth kinds as selects, then fp_fog_od_nomap_bf
 * (kernels/fog_core.h), all branch-free, so that the CPU device runs it as
 * SIMD code. */
inline __attribute__((always_inline)) float16
height_fog_lanes(__constant const float *restrict view, __constant const float *restrict fp,
                 float16 x, float16 y, float16 depth)
{
    float16 ox, oy, oz, dx, dy, dz, len;
    fp_view_ray_lanes(view, x, y, depth, &ox, &oy, &oz, &dx, &dy, &dz, &len);
    float16 od = fp_fog_od_nomap_bf(fp, view[0], view[1], view[2], dx, dy, dz, len);
    return exp(-od);
}

/* The alpha lanes of four RGBA pixels (a select's mask). */
#define FP_ALPHA_LANES (int16)(0, 0, 0, -1, 0, 0, 0, -1, 0, 0, 0, -1, 0, 0, 0, -1)

/* The fog color in the RGB lanes of four RGBA pixels. */
inline __attribute__((always_inline)) float16 height_fog_color4(float4 color)
{
    return (float16)(color.xyz, 0.0f, color.xyz, 0.0f, color.xyz, 0.0f, color.xyz, 0.0f);
}

/* The layer of four pixels from their tau spread over each pixel's four
 * lanes (t.s0000111122223333 and so on: one permute, where a transpose of
 * four float16 (r, g, b, tau) costs more than the fog): S = (1 - tau) *
 * color (seed 000 eq. 4) in the RGB lanes, tau in the alpha lanes. */
inline __attribute__((always_inline)) float16 height_fog_rgba4(float16 ts, float16 color4)
{
    return select((1.0f - ts) * color4, ts, FP_ALPHA_LANES);
}

/* Store the layer of n <= 16 pixels of lanes tau at out (RGBA each). */
inline __attribute__((always_inline)) void
height_fog_store(__global float *restrict out, int n, float16 t, float4 color)
{
    float16 color4 = height_fog_color4(color);
    if (n == 16) {
        vstore16(height_fog_rgba4(t.s0000111122223333, color4), 0, out);
        vstore16(height_fog_rgba4(t.s4444555566667777, color4), 1, out);
        vstore16(height_fog_rgba4(t.s88889999aaaabbbb, color4), 2, out);
        vstore16(height_fog_rgba4(t.sccccddddeeeeffff, color4), 3, out);
        return;
    }
    float lt[16];
    vstore16(t, 0, lt);
    for (int k = 0; k < n; k++) {
        out[4 * k] = (1.0f - lt[k]) * color.x;
        out[4 * k + 1] = (1.0f - lt[k]) * color.y;
        out[4 * k + 2] = (1.0f - lt[k]) * color.z;
        out[4 * k + 3] = lt[k];
    }
}

#define FP_LANES (float16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)

/* Work-item (i, y) of a whole frame: pixels 16 i .. 16 i + 15 of row y
 * (those past the row's end repeat its last pixel), their fog as lanes;
 * the number of them in the row (0: none, the work-item is past the
 * frame), *at the index of the first. */
inline __attribute__((always_inline)) int
height_fog_row(__global const float *restrict depth, __constant const float *restrict view,
               __constant const float *restrict fp, int width, int height, size_t *at,
               float16 *t)
{
    int x0 = (int)get_global_id(0) * FP_SIMD, y = get_global_id(1);
    if (x0 >= width || y >= height)
        return 0;
    size_t row = (size_t)y * width;
    int n = min(FP_SIMD, width - x0);
    float16 d;
    if (n == FP_SIMD) {
        d = vload16(0, depth + row + x0);
    } else {
        float ld[16];
        for (int k = 0; k < FP_SIMD; k++)
            ld[k] = depth[row + x0 + min(k, n - 1)];
        d = vload16(0, ld);
    }
    *t = height_fog_lanes(view, fp, min((float)x0 + FP_LANES, (float)(width - 1)),
                          (float16)((float)y), d);
    *at = row + x0;
    return n;
}

/* The whole frame: work-item (i, y) computes pixels 16 i .. 16 i + 15 of
 * row y (those past the row's end repeat its last pixel, not stored). */
__kernel void integrate_height(__global const float *restrict depth,
                               __global float *restrict fog_out,
                               __constant const float *restrict view, const int width,
                               const int height, __constant const float *restrict fp,
                               __constant const int *lvi, __constant const float *lvf,
                               __global const float *coef, __global const uchar *occ,
                               __global const int *pix, const int npix, const float4 fog_color)
{
    size_t at;
    float16 t;
    int n = height_fog_row(depth, view, fp, width, height, &at, &t);
    if (n == 0)
        return;
    height_fog_store(fog_out + 4 * at, n, t, fog_color);
}

/* integrate_height with the composite of filters/composite.c done here,
 * on a device in the host's memory: `rgba` (the plate in the working
 * space, argument 1 where integrate_height has its layer) becomes
 * tau * rgb + S, alpha kept, and no fog layer is written (16 bytes a
 * pixel less to write, and the host's composite pass gone: 32 bytes a
 * pixel it read).  No contraction into fma: the same roundings as
 * fp_composite_process, so the frame is the same to the bit. */
__kernel void integrate_height_over(__global const float *restrict depth,
                                    __global float *restrict rgba,
                                    __constant const float *restrict view, const int width,
                                    const int height, __constant const float *restrict fp,
                                    __constant const int *lvi, __constant const float *lvf,
                                    __global const float *coef, __global const uchar *occ,
                                    __global const int *pix, const int npix, const float4 fog_color)
{
#pragma OPENCL FP_CONTRACT OFF
    size_t at;
    float16 t;
    int n = height_fog_row(depth, view, fp, width, height, &at, &t);
    if (n == 0)
        return;
    __global float *out = rgba + 4 * at;
    if (n == FP_SIMD) {
        /* Four pixels per float16: tau * plate + S in the RGB lanes, the
         * alpha lanes passed through by the select (its bits kept, -0
         * and NaN too). */
        const int16 alpha = FP_ALPHA_LANES;
        float16 color4 = height_fog_color4(fog_color);
        float16 t0 = t.s0000111122223333, t1 = t.s4444555566667777, t2 = t.s88889999aaaabbbb,
                t3 = t.sccccddddeeeeffff;
        float16 c0 = vload16(0, out), c1 = vload16(1, out), c2 = vload16(2, out),
                c3 = vload16(3, out);
        float16 p0 = t0 * c0, p1 = t1 * c1, p2 = t2 * c2, p3 = t3 * c3;
        vstore16(select(p0 + height_fog_rgba4(t0, color4), c0, alpha), 0, out);
        vstore16(select(p1 + height_fog_rgba4(t1, color4), c1, alpha), 1, out);
        vstore16(select(p2 + height_fog_rgba4(t2, color4), c2, alpha), 2, out);
        vstore16(select(p3 + height_fog_rgba4(t3, color4), c3, alpha), 3, out);
        return;
    }
    float lt[16];
    vstore16(t, 0, lt);
    for (int k = 0; k < n; k++) {
        float pr = lt[k] * out[4 * k], pg = lt[k] * out[4 * k + 1], pb = lt[k] * out[4 * k + 2];
        out[4 * k] = pr + (1.0f - lt[k]) * fog_color.x;
        out[4 * k + 1] = pg + (1.0f - lt[k]) * fog_color.y;
        out[4 * k + 2] = pb + (1.0f - lt[k]) * fog_color.z;
    }
}

/* The listed pixels k0 .. k0 + n - 1 as lanes: their x, y and depth
 * (lanes past n repeat the last listed pixel, not stored). */
inline void list_lanes(__global const float *restrict depth, int width,
                       __global const int *restrict pix, int k0, int n, float *lx, float *ly,
                       float *ld)
{
    for (int k = 0; k < FP_SIMD; k++) {
        int p = pix[k0 + min(k, n - 1)];
        int y = p / width;
        lx[k] = (float)(p - y * width);
        ly[k] = (float)y;
        ld[k] = depth[p];
    }
}

/* The pixels pix[0 .. npix) (indices y * width + x), results in list
 * order, 16 per work-item. */
__kernel void integrate_height_list(__global const float *restrict depth,
                                    __global float *restrict fog_out,
                                    __constant const float *restrict view, const int width,
                                    const int height, __constant const float *restrict fp,
                                    __constant const int *lvi, __constant const float *lvf,
                                    __global const float *coef, __global const uchar *occ,
                                    __global const int *restrict pix, const int npix,
                                    const float4 fog_color)
{
    int k0 = (int)get_global_id(0) * FP_SIMD;
    if (k0 >= npix)
        return;
    int n = min(FP_SIMD, npix - k0);
    float lx[16], ly[16], ld[16];
    list_lanes(depth, width, pix, k0, n, lx, ly, ld);
    float16 t = height_fog_lanes(view, fp, vload16(0, lx), vload16(0, ly), vload16(0, ld));
    height_fog_store(fog_out + 4 * (size_t)k0, n, t, fog_color);
}

/* A fogmap of the linear basis walked exactly (the host's
 * fp_integrate_lanes_ok): integrate_fog's layer, work-item (i, y)
 * computing pixels 16 i .. 16 i + 15 of row y as float16 lanes (those
 * past the row's end repeat its last pixel, not stored), each lane
 * walking its own ray (kernels/fogmap_lanes.h). */
__kernel void integrate_fogmap(__global const float *restrict depth,
                               __global float *restrict fog_out,
                               __constant const float *restrict view, const int width,
                               const int height, __constant const float *restrict fp,
                               __constant const int *lvi, __constant const float *lvf,
                               __global const float *coef, __global const uchar *occ,
                               __global const int *pix, const int npix, const float4 fog_color)
{
    int x0 = (int)get_global_id(0) * FP_SIMD, y = get_global_id(1);
    if (x0 >= width || y >= height)
        return;
    size_t row = (size_t)y * width;
    int n = min(FP_SIMD, width - x0);
    float ld[16];
    for (int k = 0; k < FP_SIMD; k++)
        ld[k] = depth[row + x0 + min(k, n - 1)];
    float16 x = min((float)x0 + FP_LANES, (float)(width - 1));
    float16 od = fp_fog_od_lanes(view, fp, lvi, lvf, coef, x, (float16)((float)y),
                                 vload16(0, ld));
    height_fog_store(fog_out + 4 * (row + x0), n, exp(-od), fog_color);
}

/* integrate_fogmap on the pixels pix[0 .. npix) (indices y * width + x),
 * results in list order, 16 per work-item: each lane's ray is walked as
 * in the whole frame's kernel, whatever its neighbours, so a listed pixel
 * gets the frame's value. */
__kernel void integrate_fogmap_list(__global const float *restrict depth,
                                    __global float *restrict fog_out,
                                    __constant const float *restrict view, const int width,
                                    const int height, __constant const float *restrict fp,
                                    __constant const int *lvi, __constant const float *lvf,
                                    __global const float *coef, __global const uchar *occ,
                                    __global const int *restrict pix, const int npix,
                                    const float4 fog_color)
{
    int k0 = (int)get_global_id(0) * FP_SIMD;
    if (k0 >= npix)
        return;
    int n = min(FP_SIMD, npix - k0);
    float lx[16], ly[16], ld[16];
    list_lanes(depth, width, pix, k0, n, lx, ly, ld);
    float16 od = fp_fog_od_lanes(view, fp, lvi, lvf, coef, vload16(0, lx), vload16(0, ly),
                                 vload16(0, ld));
    height_fog_store(fog_out + 4 * (size_t)k0, n, exp(-od), fog_color);
}

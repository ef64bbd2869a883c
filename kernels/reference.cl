/* fogpipe: the Monte Carlo reference (--integrator reference), per pixel.
 * Host side and C version: filters/reference.c; the estimator itself is in
 * reference_core.h.  One launch covers a band of entries [e0, e0 + ne)
 * of the frame (entry e: pixel e) or of a pixel list (npix > 0; entry e:
 * pixel pix[e]) and a batch of samples [s0, s1), and writes each entry's
 * sums over the batch (S.rgb, tau, then their squares, for the standard
 * errors); the host adds the batches in double precision. */
#include "fp_common.h"
#include "fog_core.h"
#include "light_core.h"
#include "reference_core.h"

__kernel void reference_fog(__global const float *depth, __global float *acc,
                            __constant const float *view, const int width, const int height,
                            __global const int *pix, const int npix, const int e0,
                            const int ne, __constant const float *fp,
                            __constant const int *lvi, __constant const float *lvf,
                            __global const float *coef, __constant const float *lt,
                            __global const float *smap, __constant const float *rp,
                            __global const float *grid, const uint seed, const int s0,
                            const int s1, __global const float *lights)
{
    int g = get_global_id(0);
    if (g >= ne)
        return;
    int i = npix > 0 ? pix[e0 + g] : e0 + g;
    int x = i % width, y = i / width;
    float len;
    float3 dir = fp_view_ray(view, x, y, depth[i], &len);
    float3 o = fp_view_origin_at(view, x, y);
    float sum[4] = { 0.0f, 0.0f, 0.0f, 0.0f }, sq[4] = { 0.0f, 0.0f, 0.0f, 0.0f };
    for (int s = s0; s < s1; s++) {
        float S[3];
        float tau = fp_ref_sample(fp, lvi, lvf, coef, lt, lights, smap, view, depth, width, height, rp,
                                  grid, seed, (uint)i, (uint)s, o.x, o.y, o.z, dir.x, dir.y,
                                  dir.z, len, S);
        for (int c = 0; c < 3; c++) {
            sum[c] += S[c];
            sq[c] += S[c] * S[c];
        }
        sum[3] += tau;
        sq[3] += tau * tau;
    }
    for (int c = 0; c < 4; c++) {
        acc[8 * g + c] = sum[c];
        acc[8 * g + 4 + c] = sq[c];
    }
}

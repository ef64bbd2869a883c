/* fogpipe: the exact fogmap walk of the linear basis on FP_SIMD (16) view
 * rays at once, float16 lanes: one work-item walks 16 neighbouring pixels
 * of a row, each lane its own ray through the fine grid (A_{nl-1} = F),
 * every lane doing the same steps until the last lane's ray ends.  The
 * scalar walk (fp_fogmap_od -> fp_grid_walk, kernels/fogmap_walk.h) runs
 * one lane on the CPU device: PoCL does not vectorise its data-dependent
 * loop across work-items.  Here the loop's exits and the cell steps are
 * per-lane selects, a finished lane keeping its state, and the cell's four
 * coefficients are gathered per lane.  The segments and their math are
 * fp_grid_walk's (d = 1, no level of detail, no early termination): the
 * same cuts at the cells' edges, at Y0 and every FP_SEG_U of the
 * exponent, the same series (fp_bilinear_seg), h carried from segment to
 * segment and computed anew every 8th; the C double reference
 * (fp_fog_od) is the judge (tests/test_fogmap_lanes.c).
 *
 * Used by integrate_fogmap and integrate_fogmap_list (kernels/integrate.cl;
 * a lane's result does not depend on its neighbours, so a listed pixel
 * gets the frame's value to the bit) where the host's
 * fp_integrate_lanes_ok holds: a fogmap of the linear basis walked exactly
 * (no --lod-bound, --lod-mu 1 or one level, no --lod-footprint, no
 * --min-transmittance, exact mode, every level summed into A_l), wrap zero
 * or repeat (clamp's pieces bend the path), a perspective camera (with or
 * without --clip-start).  OpenCL only. */
#ifndef FP_FOGMAP_LANES_H
#define FP_FOGMAP_LANES_H

#ifdef __OPENCL_VERSION__

#include "fp_common.h"
#include "fog_params.h"
#include "fogmap_walk.h"
#include "fog_simd.h"

#define FP_LN_FN inline __attribute__((always_inline))

/* fp_clip on lanes: the same division and the same cases. */
FP_LN_FN void fp_clip_lanes(float16 o, float16 dd, float lo, float hi, float16 *a, float16 *b)
{
    float16 u = (lo - o) / dd, v = (hi - o) / dd;
    int16 flat = dd == (float16)0.0f, out = (o < (float16)lo) | (o > (float16)hi);
    float16 na = fmax(*a, fmin(u, v)), nb = fmin(*b, fmax(u, v));
    float16 flat_b = out ? *a : *b;
    *b = flat ? flat_b : nb;
    *a = flat ? *a : na;
}

/* fp_cell_of on lanes. */
FP_LN_FN int16 fp_cell_of_lanes(float16 x, float16 dxdt)
{
    float16 f = floor(x);
    f = (dxdt < (float16)0.0f) & (f == x) ? f - 1.0f : f;
    return convert_int16(f);
}

/* cf[idx] per lane. */
FP_LN_FN float16 fp_gather16(__global const float *cf, int16 i)
{
    return (float16)(cf[i.s0], cf[i.s1], cf[i.s2], cf[i.s3], cf[i.s4], cf[i.s5], cf[i.s6],
                     cf[i.s7], cf[i.s8], cf[i.s9], cf[i.sa], cf[i.sb], cf[i.sc], cf[i.sd],
                     cf[i.se], cf[i.sf]);
}

/* sum_j c_j z^j, j < 8, in fp_estrin's pairs, z2 = z^2, z4 = z^4. */
#define FP_LN_EST(c0, c1, c2, c3, c4, c5, c6, c7, z, z2, z4)                                     \
    (((c0) + (c1) * (z)) + ((c2) + (c3) * (z)) * (z2) +                                         \
     (((c4) + (c5) * (z)) + ((c6) + (c7) * (z)) * (z2)) * (z4))
/* 1 / (j! (k + j + 1)), zero from j = FP_SEG_TERMS (7) on. */
#define FP_LN_MC(j, k) (fp_invfact[j] * fp_recip[(j) + (k)])
/* M_k(z) = sum_j z^j / (j! (k + j + 1)), the series' first FP_SEG_TERMS terms. */
#define FP_LN_M(k, z, z2, z4)                                                                    \
    FP_LN_EST(FP_LN_MC(0, k), FP_LN_MC(1, k), FP_LN_MC(2, k), FP_LN_MC(3, k), FP_LN_MC(4, k),    \
              FP_LN_MC(5, k), FP_LN_MC(6, k), 0.0f, z, z2, z4)

/* The optical depth of the fogmap's fog (fp_fogmap_od's, sigma times the
 * walk) along the rays from the point o in the unit directions d, t in
 * [0, len] (len infinite for the sky), on lanes. */
FP_LN_FN float16 fp_fogmap_od_lanes(__constant const float *fp, __constant const int *lvi,
                                    __constant const float *lvf, __global const float *coef,
                                    float16 ox, float16 oy, float16 oz, float16 dx,
                                    float16 dy, float16 dz, float16 len)
{
    /* fp_fogmap_path: the fog-local frame, the box, the top, the clip
     * rectangle (wrap zero). */
    float c = fp[FP_F_COS], s = fp[FP_F_SIN];
    float16 px = ox - fp[FP_F_OFF], py = oy - fp[FP_F_OFF + 1], pz = oz - fp[FP_F_OFF + 2];
    float16 qx = c * px - s * pz, qz = s * px + c * pz;
    float16 ex = c * dx - s * dz, ez = s * dx + c * dz;
    float16 a = (float16)0.0f, b = len;
    fp_clip_lanes(qx, ex, fp[FP_F_BOX], fp[FP_F_BOX + 3], &a, &b);
    fp_clip_lanes(py, dy, fp[FP_F_BOX + 1], fp[FP_F_BOX + 4], &a, &b);
    fp_clip_lanes(qz, ez, fp[FP_F_BOX + 2], fp[FP_F_BOX + 5], &a, &b);
    fp_clip_lanes(py, dy, -INFINITY, fp[FP_F_TOP], &a, &b);
    float16 u0 = (qx - fp[FP_F_A0]) * fp[FP_F_USCALE] + fp[FP_F_PAD_X0];
    float16 du = ex * fp[FP_F_USCALE];
    float16 v0 = (qz - fp[FP_F_B0]) * fp[FP_F_VSCALE] + fp[FP_F_PAD_Y0];
    float16 dv = ez * fp[FP_F_VSCALE];
    if ((int)fp[FP_F_WRAP] == 0) {
        fp_clip_lanes(u0, du, fp[FP_F_CLIP], fp[FP_F_CLIP + 1], &a, &b);
        fp_clip_lanes(v0, dv, fp[FP_F_CLIP + 2], fp[FP_F_CLIP + 3], &a, &b);
    }
    float y0 = fp[FP_F_Y0], H = fp[FP_F_H];
    /* fp_fogmap_cap where b is infinite. */
    float16 cap = a + fp[FP_F_CAP];
    if (isfinite(H))
        cap = dy > (float16)0.0f ? fmax(a, (y0 + 40 * H - py) / dy) : cap;
    b = isinf(b) ? cap : b;
    int16 live = b > a;
    /* A lane without fog walks nothing from a harmless start. */
    a = live ? a : (float16)0.0f;
    b = live ? b : (float16)0.0f;

    /* fp_grid_walk on the finest level, d = 1 (kappa 0). */
    int L = (int)fp[FP_F_NLEVELS] - 1;
    int nx = lvi[L * FP_LI_STRIDE + FP_LI_NX], ny = lvi[L * FP_LI_STRIDE + FP_LI_NY];
    __global const float *cf = coef + lvi[L * FP_LI_STRIDE + FP_LI_APPROX];
    float cell = lvf[L * FP_LR_STRIDE + FP_LR_CELL];
    float16 xs = (u0 - lvf[L * FP_LR_STRIDE + FP_LR_ORIGIN_U]) / cell;
    float16 ys = (v0 - lvf[L * FP_LR_STRIDE + FP_LR_ORIGIN_V]) / cell;
    float16 dxdt = du / cell, dydt = dv / cell;
    dxdt = live ? dxdt : (float16)0.0f;
    dydt = live ? dydt : (float16)0.0f;
    float16 lam = dy / H;
    int flat_h = !isfinite(H);   /* H infinite: u = 0 in every lane, no series */
    float16 lmax = lam != (float16)0.0f ? FP_SEG_U / fabs(lam) : (float16)INFINITY;
    float16 tc = dy != (float16)0.0f ? (y0 - py) / dy : (float16)(-INFINITY);
    int16 sx = dxdt > (float16)0.0f ? (int16)1 : (int16)(-1);
    int16 sy = dydt > (float16)0.0f ? (int16)1 : (int16)(-1);
    float16 ix = dxdt != (float16)0.0f ? 1.0f / dxdt : (float16)0.0f;
    float16 iy = dydt != (float16)0.0f ? 1.0f / dydt : (float16)0.0f;
    int16 k = fp_cell_of_lanes(xs + a * dxdt, dxdt);
    int16 m = fp_cell_of_lanes(ys + a * dydt, dydt);
    /* fp_wrap_index */
    int16 kw = k % nx, mw = m % ny;
    kw = kw < (int16)0 ? kw + nx : kw;
    mw = mw < (int16)0 ? mw + ny : mw;
    float16 tx = dxdt != (float16)0.0f
                     ? (convert_float16(k + (dxdt > (float16)0.0f ? (int16)1 : (int16)0)) - xs) * ix
                     : (float16)INFINITY;
    float16 ty = dydt != (float16)0.0f
                     ? (convert_float16(m + (dydt > (float16)0.0f ? (int16)1 : (int16)0)) - ys) * iy
                     : (float16)INFINITY;
    float16 t = a, sum = (float16)0.0f, hc = (float16)1.0f;
    int16 run = t < b;
    for (int guard = 0; any(run) && guard < (1 << 24); guard++) {
        float16 tn = fmin(fmin(tx, ty), fmin(b, t + lmax));
        tn = (tc > t) & (tc < tn) ? tc : tn;
        tn = fmax(tn, t);
        tn = run ? tn : t;
        float16 len_s = tn - t;
        /* The cell's four coefficients (fp_grid_walk's d = 1 read). */
        int16 kw1 = kw + 1 >= nx ? kw + 1 - nx : kw + 1;
        int16 mw1 = mw + 1 >= ny ? mw + 1 - ny : mw + 1;
        int16 r0 = mw * nx, r1 = mw1 * nx;
        float16 c0 = fp_gather16(cf, r0 + kw), c1 = fp_gather16(cf, r0 + kw1);
        float16 c4 = fp_gather16(cf, r1 + kw), c5 = fp_gather16(cf, r1 + kw1);
        float16 pxl = xs + t * dxdt - convert_float16(k), qxl = dxdt * len_s;
        float16 pyl = ys + t * dydt - convert_float16(m), qyl = dydt * len_s;
        float16 ya = py + t * dy;
        int16 above = (py + (t + 0.5f * len_s) * dy) > (float16)y0;
        float16 u = above ? lam * len_s : (float16)0.0f;
        if ((guard & 7) == 0)
            hc = exp(-fmax(ya - y0, (float16)0.0f) / H);
        float16 ha = hc, E = (float16)1.0f;
        /* fp_bilinear_seg */
        float16 g1 = c1 - c0, g2 = c4 - c0, g3 = c5 - c4 - g1;
        float16 P0 = c0 + g1 * pxl + (g2 + g3 * pxl) * pyl;
        float16 P1 = g1 * qxl + g2 * qyl + g3 * (pxl * qyl + qxl * pyl);
        float16 P2 = g3 * qxl * qyl;
        float16 seg;
        if (flat_h) {
            seg = P0 * fp_recip[0] + P1 * fp_recip[1] + P2 * fp_recip[2];
        } else {
            /* fp_bilinear_seg's series sum_j (-u)^j / j! sum_k P_k / (k + j + 1)
             * regrouped as sum_k P_k M_k(-u), M_k(z) = sum_j z^j / (j! (k + j + 1)):
             * polynomials with constant coefficients (a loop over j building
             * the series' coefficients per lane went through memory, a sixth
             * of the kernel), and exp(-u) by the same series. */
            float16 z = -u, z2 = z * z, z4 = z2 * z2;
            seg = P0 * FP_LN_M(0, z, z2, z4) + P1 * FP_LN_M(1, z, z2, z4) +
                  P2 * FP_LN_M(2, z, z2, z4);
            E = FP_LN_EST(fp_invfact[0], fp_invfact[1], fp_invfact[2], fp_invfact[3],
                          fp_invfact[4], fp_invfact[5], fp_invfact[6], 0.0f, z, z2, z4);
        }
        sum += run ? ha * len_s * seg : (float16)0.0f;
        hc = ha * E;
        /* Into the next cell where the segment ended on its edge. */
        int16 stepx = run & (tx <= tn), stepy = run & (ty <= tn);
        k += stepx ? sx : (int16)0;
        kw += stepx ? sx : (int16)0;
        kw = kw >= nx ? kw - nx : kw < (int16)0 ? kw + nx : kw;
        tx = stepx ? (convert_float16(k + (dxdt > (float16)0.0f ? (int16)1 : (int16)0)) - xs) * ix
                   : tx;
        m += stepy ? sy : (int16)0;
        mw += stepy ? sy : (int16)0;
        mw = mw >= ny ? mw - ny : mw < (int16)0 ? mw + ny : mw;
        ty = stepy ? (convert_float16(m + (dydt > (float16)0.0f ? (int16)1 : (int16)0)) - ys) * iy
                   : ty;
        t = tn;
        run = t < b;
    }
    return fp[FP_F_SIGMA] * sum;
}

/* The view rays of pixels (x, y) (fp_view_ray's and fp_view_origin_at's,
 * a perspective camera): origins *ox, *oy, *oz (the camera, or the rays'
 * points on the clip plane), unit directions *dx, *dy, *dz and lengths
 * *len (infinite for the sky), on lanes; integrate_height's rays too
 * (kernels/integrate.cl: height_fog_lanes). */
FP_LN_FN void fp_view_ray_lanes(__constant const float *view, float16 x, float16 y,
                                float16 depth, float16 *ox, float16 *oy, float16 *oz,
                                float16 *dx, float16 *dy, float16 *dz, float16 *len)
{
    __constant const float *h = view + FP_VIEW_H;
    __constant const float *m = view + FP_VIEW_M;
    float16 nx = (x + view[FP_VIEW_NDC_OFFSET]) * view[FP_VIEW_NDC_SCALE];
    float16 ny = (y + view[FP_VIEW_NDC_OFFSET + 1]) * view[FP_VIEW_NDC_SCALE + 1];
    float16 inv_cw = 1.0f / (h[6] * nx + h[7] * ny + h[8]);
    float16 cx = (h[0] * nx + h[1] * ny + h[2]) * inv_cw;
    float16 cy = (h[3] * nx + h[4] * ny + h[5]) * inv_cw;
    float16 ddx = m[0] * cx + m[1] * cy + m[2];
    float16 ddy = m[3] * cx + m[4] * cy + m[5];
    float16 ddz = m[6] * cx + m[7] * cy + m[8];
    float16 l = sqrt(ddx * ddx + ddy * ddy + ddz * ddz);
    /* fp_is_sky and the depth kinds (the frame's, the same in every lane). */
    int kind = (int)view[FP_VIEW_DEPTH_KIND];
    float16 z = depth, scale = depth;
    int16 sky = isnan(depth) | (depth < 0.0f);
    if (kind == FP_DEPTH_INVERSE) {
        z = 1.0f / depth;
        scale = z;
        sky |= depth == 0.0f;
    } else if (kind == FP_DEPTH_RADIAL) {
        scale = depth / sqrt(cx * cx + cy * cy + 1.0f);
    }
    sky |= isinf(z) | (z >= 1e10f) | (z >= view[FP_VIEW_FAR]);
    *len = sky ? (float16)INFINITY : l * scale;
    *ox = (float16)view[0];
    *oy = (float16)view[1];
    *oz = (float16)view[2];
    /* From the clip plane: l * clip along the ray, starting there. */
    float clip = view[FP_VIEW_CLIP];
    if (clip > 0.0f) {
        *len = sky ? *len : fmax(*len - l * clip, (float16)0.0f);
        *ox += clip * ddx;
        *oy += clip * ddy;
        *oz += clip * ddz;
    }
    float16 inv_l = 1.0f / l;
    *dx = ddx * inv_l;
    *dy = ddy * inv_l;
    *dz = ddz * inv_l;
}

/* fp_fog_od with a fogmap on the lanes: the haze (closed form) and the
 * fogmap's walk, the view rays of pixels (x, y). */
FP_LN_FN float16 fp_fog_od_lanes(__constant const float *view, __constant const float *fp,
                                 __constant const int *lvi, __constant const float *lvf,
                                 __global const float *coef, float16 x, float16 y,
                                 float16 depth)
{
    float16 ox, oy, oz, dx, dy, dz, len;
    fp_view_ray_lanes(view, x, y, depth, &ox, &oy, &oz, &dx, &dy, &dz, &len);
    float16 od = (float16)0.0f;
    /* The haze from one height (the camera's), or each ray's own (from
     * the clip plane). */
    if (fp[FP_F_HAZE] > 0 && !(view[FP_VIEW_CLIP] > 0.0f))
        od = fp_height_od_from_bf(fp[FP_F_HAZE], fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2],
                                  fp[FP_F_HAZE + 3], view[1], dy, 1.0f / dy, len);
    else if (fp[FP_F_HAZE] > 0)
        od = fp_height_od_bf(fp[FP_F_HAZE], fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2],
                             fp[FP_F_HAZE + 3], oy, dy, 1.0f / dy, len);
    return od + fp_fogmap_od_lanes(fp, lvi, lvf, coef, ox, oy, oz, dx, dy, dz, len);
}

#endif
#endif

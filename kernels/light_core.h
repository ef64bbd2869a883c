/* fogpipe: light in the fog, the pieces shared by the deterministic
 * single-scattering integrator (scatter_core.h) and the Monte Carlo
 * reference (reference.cl / filters/reference.c), compiled as OpenCL C in
 * single precision and as C in double precision like fog_core.h.
 * Include after fog_core.h.
 *
 * Model (issue "Light in the fog"):
 *   L(O) = tau(O,P) L(P) + int tau(O,u) sigma_s(u) [ L_amb
 *          + sum_k E_k(u) p(theta_k) V_k(u) tau_k(u) ] du,
 *   sigma_s = albedo sigma_t.
 * Everything here is in fog space (+y up; src/scene/camera.h). */
#ifndef FP_LIGHT_CORE_H
#define FP_LIGHT_CORE_H

#include "phase.h"

#include "view_layout.h"

/* Layout of the light parameter array (filled by fp_scatter_commit and
 * fp_scatter_frame in filters/scatter.c). */
#define FP_LT_ALBEDO 0
#define FP_LT_AMB 1          /* 3: ambient in-scattered radiance (--fog-color) */
#define FP_LT_SUN_ON 4
#define FP_LT_SUN_DIR 5      /* 3: unit, toward the sun */
#define FP_LT_SUN_E 8        /* 3: sun irradiance, color * intensity */
#define FP_LT_PHASE 11       /* 3: kind (FP_PHASE_*), g, Rayleigh weight */
#define FP_LT_SHADOWS 14     /* FP_SHADOWS_* */
#define FP_LT_SELF 15        /* FP_SELF_*: fog self-shadowing of the sun */
#define FP_LT_STEPS 16       /* segments along the view ray (deterministic) */
#define FP_LT_PANELS 17      /* equiangular panels per local light (4 nodes each) */
#define FP_LT_NLIGHTS 18
#define FP_LT_SM_W 19        /* shadow map size, texels */
#define FP_LT_SM_H 20
#define FP_LT_SM_NDC 21      /* 16: fog point (row vector, w = 1) -> shadow map NDC */
#define FP_LT_SM_Z 37        /* 4: fog point -> the map camera's z: dot(p, c) + c[3] */
#define FP_LT_SM_BIAS 41     /* the user's depth bias, scene units (in the map's zb already) */
#define FP_LT_SM_RADIUS 42   /* --shadow-filter: ramps R texels each side of a shadow's edge */
/* The shadow map's ground plane (filters/shafts.c fp_shafts_plane): the
 * sun camera's z of a level (y = const) surface is ga U + gb V + c over the
 * map's texel coordinates; the pyramid's levels bound zb minus that. */
#define FP_LT_SM_GA 43
#define FP_LT_SS_DIST 44     /* how far toward the sun, scene units */
#define FP_LT_SS_THICK 45    /* assumed thickness of what the depth buffer shows */
#define FP_LT_SS_M 46        /* 9: fog vector -> camera vector (inverse of view m) */
#define FP_LT_SS_H 55        /* 9: camera (x/z, y/z, 1) -> NDC, homogeneous */
#define FP_LT_SUN_E1 64      /* 3: unit, horizontal, across the sun: the self-shadow grid's a */
#define FP_LT_SUN_E2 67      /* 3: unit, horizontal, toward the sun: its b axis (at y = 0) */
#define FP_LT_GRID_N 70      /* 3: nodes of each cascade of the grid along a, b and y */
#define FP_LT_OD_STOP 73     /* the view ray's in-scatter ends where its optical depth exceeds this */
#define FP_LT_SEG_OD 74     /* largest optical depth of one segment of the view ray */
#define FP_LT_SEG_JUMP 75   /* largest change of the light over one segment, weighted */
#define FP_LT_INTERLEAVE 76 /* 2: n x m pattern of per-pixel sample offsets (1, 1: off) */
#define FP_LT_LIGHT_QUAD 78 /* local lights: 0 equiangular panels, 1 the fast rule (no fogmap) */
#define FP_LT_GRID_K 79      /* cascades of the self-shadow grid (1..FP_LT_MAX_CASCADES) */
#define FP_LT_NDIR 80        /* directional lights (extra suns), after the local ones */
#define FP_LT_CULL 81        /* per pixel, the most the local lights left out may add */
#define FP_LT_PMAX 82        /* the phase function's largest value (culling's bound) */
#define FP_LT_SM_GB 83       /* the ground plane's gb (FP_LT_SM_GA) */
/* The self-shadow grid's cascades, finest first: per cascade its first
 * node (a, b, s in the sun's frame) and its cell (3 + 3). */
#define FP_LT_CASCADE 84
#define FP_LT_MAX_CASCADES 4
/* 2: the main fog's base Y0 (fog space) and scale height H of the grid's
 * weight (H 0: none): the nodes hold od w(y), w = e^(max(y - Y0, 0) / H). */
#define FP_LT_GRID_W (FP_LT_CASCADE + 6 * FP_LT_MAX_CASCADES)
#define FP_LT_SM_LEVELS (FP_LT_GRID_W + 2) /* levels of the shadow map's min-max pyramid */
#define FP_LT_SS_ZMAX (FP_LT_GRID_W + 3)   /* --shadows screen: the depth buffer's deepest z */
/* 4: --shadows screen: the depth buffer's own pixels -> NDC, scale x, y and
 * offset x, y (pixel i's center at (i + offset) scale), with its size in
 * FP_LT_SS_PW, FP_LT_SS_PH: the walk never takes them from the view traced,
 * which may be another (--fog-resolution's strided view, walking the
 * frame's full-resolution depth buffer). */
#define FP_LT_SS_NDC (FP_LT_GRID_W + 4)
/* 3: the depth buffer's min-max pyramid for the walk (--shadows screen,
 * map+screen): its size and levels.  Under map+screen it follows the
 * shadow map's packed floats in the same buffer (fp_ss_zpyr). */
#define FP_LT_SS_PW (FP_LT_GRID_W + 8)
#define FP_LT_SS_PH (FP_LT_GRID_W + 9)
#define FP_LT_SS_PLEVELS (FP_LT_GRID_W + 10)
/* --lamp-shadows screen (kernels/lamp_shadow_core.h): on for this frame,
 * and where its depth pyramid starts in the shadow-map buffer. */
#define FP_LT_LS_ON (FP_LT_GRID_W + 11)
#define FP_LT_LS_ZOFF (FP_LT_GRID_W + 12)
/* FP_LT_MS_COUNT: the fast multiple-scattering table (kernels/ms_core.h). */
#define FP_LT_MS (FP_LT_GRID_W + 13)
#define FP_LT_COUNT (FP_LT_MS + 674)

/* The lights: a table of their own (any number: a global buffer in
 * OpenCL), FP_LT_NLIGHTS local lights (point, spot, area) then
 * FP_LT_NDIR directional ones, FP_LL_STRIDE reals each, in fog space. */
#define FP_LL_STRIDE 28
#define FP_LL_TYPE 0         /* FP_LIGHT_* */
#define FP_LL_POS 1          /* 3; directional: unit, toward the light */
#define FP_LL_I 4            /* 3: radiant intensity, color * I (W/sr): E = I / d^2; area: along
                                its normal; directional: irradiance */
#define FP_LL_AXIS 7         /* 3: unit, the direction a spot shines; area: its normal */
#define FP_LL_COS_IN 10      /* spot: full intensity inside (profile 1: cos(half) + spread) */
#define FP_LL_COS_OUT 11     /* spot: none outside the outer cone; area: 0 (one-sided) */
#define FP_LL_PROFILE 12     /* spot: 0 smoothstep inner..outer, 1 Cycles 3.x (c smoothstep) */
#define FP_LL_SPREAD 13      /* spot, profile 1: (1 - cos(half)) * blend */
#define FP_LL_RADIUS 14      /* point, spot: soft size (Cycles: a disk facing the point) */
#define FP_LL_U 15           /* 3: area: half its extent along its local X */
#define FP_LL_V 18           /* 3: area: half its extent along N x U */
#define FP_LL_SHAPE 21       /* area: 0 rectangle, 1 ellipse */
#define FP_LL_AREA 22        /* area: its area */
#define FP_LL_IMAX 23        /* the largest of FP_LL_I's channels (culling) */
#define FP_LL_REACH 24       /* area: its half diagonal (culling's distance bound) */

#define FP_LIGHT_POINT 0
#define FP_LIGHT_SPOT 1
#define FP_LIGHT_AREA 2
#define FP_LIGHT_DIR 3

#define FP_SHADOWS_NONE 0
#define FP_SHADOWS_MAP 1
#define FP_SHADOWS_SCREEN 2
#define FP_SHADOWS_MAP_SCREEN 3   /* both: visibility = the map's x the walk's */

#define FP_SELF_OFF 0
#define FP_SELF_EXACT 1
#define FP_SELF_MAP 2

/* Extinction at a fog-space point: the fogmap surface (its fine grid, the
 * last level of the tables, whose B-spline surface is F itself) or the
 * homogeneous main fog, times the height profile, inside the fog box; plus
 * the haze.  The same model fp_fog_od integrates. */
FP_FN fp_real fp_sigma_t(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                         FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                         fp_real x, fp_real y, fp_real z)
{
    fp_real s = 0;
    fp_real hz = fp[FP_F_HAZE];
    if (hz > 0 && y < fp[FP_F_HAZE + 3])
        s = hz * (y < fp[FP_F_HAZE + 1] ? (fp_real)1
                                         : exp(-(y - fp[FP_F_HAZE + 1]) / fp[FP_F_HAZE + 2]));
    fp_real c = fp[FP_F_COS], sn = fp[FP_F_SIN];
    fp_real px = x - fp[FP_F_OFF], py = y - fp[FP_F_OFF + 1], pz = z - fp[FP_F_OFF + 2];
    fp_real qx = c * px - sn * pz, qz = sn * px + c * pz;
    if (qx < fp[FP_F_BOX] || qx > fp[FP_F_BOX + 3] || py < fp[FP_F_BOX + 1] ||
        py > fp[FP_F_BOX + 4] || qz < fp[FP_F_BOX + 2] || qz > fp[FP_F_BOX + 5])
        return s;
    fp_real h = fp_h(fp, py);
    if (h <= 0 || fp[FP_F_SIGMA] <= 0)
        return s;
    if (fp[FP_F_HAS_MAP] == 0)
        return s + fp[FP_F_SIGMA] * h;
    fp_real U = (qx - fp[FP_F_A0]) * fp[FP_F_USCALE] + fp[FP_F_PAD_X0];
    fp_real V = (qz - fp[FP_F_B0]) * fp[FP_F_VSCALE] + fp[FP_F_PAD_Y0];
    int wrap = (int)fp[FP_F_WRAP];
    if (wrap == 0 && (U < fp[FP_F_CLIP] || U > fp[FP_F_CLIP + 1] || V < fp[FP_F_CLIP + 2] ||
                      V > fp[FP_F_CLIP + 3]))
        return s;
    if (wrap == 1) {
        U = fmin(fmax(U, fp[FP_F_CLIP]), fp[FP_F_CLIP + 1]);
        V = fmin(fmax(V, fp[FP_F_CLIP + 2]), fp[FP_F_CLIP + 3]);
    }
    fp_real f = fp_level_eval(fp, lvi, lvf, coef, (int)fp[FP_F_NLEVELS], U, V);
    return s + fp[FP_F_SIGMA] * fmax(f, (fp_real)0) * h;
}

/* Shadow map: the sun's orthographic depth map, packed by fp_shafts_build
 * (filters/shafts.c): texel (i, j) covers map coordinates [i, i + 1) x
 * [j, j + 1) (NDC times the size) and holds zb, the sun camera's z of what
 * it sees plus the texel's bias (+inf where it sees nothing).  A point is
 * lit when its z is at most zb of the texel it falls in (point-sampled:
 * the visibility that kernels/shafts_core.h integrates exactly); points
 * outside the map are lit. */
FP_FN fp_real fp_shadow_map(FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *smap,
                            fp_real x, fp_real y, fp_real z)
{
    FP_CONSTANT const fp_real *m = lt + FP_LT_SM_NDC;
    FP_CONSTANT const fp_real *cz = lt + FP_LT_SM_Z;
    int W = (int)lt[FP_LT_SM_W], H = (int)lt[FP_LT_SM_H];
    fp_real u = (x * m[0] + y * m[4] + z * m[8] + m[12]) * W;
    fp_real v = (x * m[1] + y * m[5] + z * m[9] + m[13]) * H;
    if (!(u >= 0 && v >= 0 && u < W && v < H))
        return 1;
    fp_real pz = x * cz[0] + y * cz[1] + z * cz[2] + cz[3];
    int i = (int)floor(u), j = (int)floor(v);
    i = i > W - 1 ? W - 1 : i;
    j = j > H - 1 ? H - 1 : j;
    return pz <= smap[j * W + i] ? (fp_real)1 : (fp_real)0;
}

/* Camera-space z of the scene at depth-buffer pixel (i, j) (+inf: sky). */
FP_FN fp_real fp_scene_z(FP_CONSTANT const float *view, FP_GLOBAL const float *depth, int width,
                         int i, int j)
{
    fp_real dv = depth[j * width + i];
    int kind = (int)view[FP_VIEW_DEPTH_KIND];
    /* Depth kinds: 0 planar, 1 radial, 2 inverse (FP_DEPTH_*). */
    if (isnan(dv) || dv < 0 || (kind == 2 && dv == 0))
        return FP_INF;
    FP_CONSTANT const float *h = view + FP_VIEW_H;
    fp_real nx = ((fp_real)i + view[FP_VIEW_NDC_OFFSET]) * view[FP_VIEW_NDC_SCALE];
    fp_real ny = ((fp_real)j + view[FP_VIEW_NDC_OFFSET + 1]) * view[FP_VIEW_NDC_SCALE + 1];
    fp_real cw = h[6] * nx + h[7] * ny + h[8];
    fp_real cx = (h[0] * nx + h[1] * ny + h[2]) / cw, cy = (h[3] * nx + h[4] * ny + h[5]) / cw;
    /* Orthographic: the depth is the distance from the camera's plane. */
    if (view[FP_VIEW_ORTHO] != 0)
        cx = cy = 0;
    fp_real zc = kind == 0 ? dv : kind == 1 ? dv / sqrt(cx * cx + cy * cy + 1) : 1 / dv;
    if (isinf(zc) || zc >= (fp_real)1e10 || dv >= view[FP_VIEW_FAR])
        return FP_INF;
    return zc;
}

/* Screen-space shadows as intervals (--shadows screen).  A point P is in
 * shadow when its ray toward the sun, P + s l with 0 < s <= DIST, passes
 * through what a depth-buffer pixel shows, taken as a cell of the pixel's
 * footprint THICK deep behind its camera-space z: the march of before
 * with s continuous.  For the points of a view ray, X(t, s) = o + t d + s l
 * lies in one plane through the camera, and what projects into pixel q
 * with camera z in [z_q, z_q + THICK] is a convex polygon of (t, s) (each
 * condition is linear in t and s after the homogeneous divide is
 * multiplied out), whose shadow on the t axis is an interval: walking the
 * pixels that the plane's line crosses on screen, from the view ray's own
 * pixel toward the sun as far as DIST reaches, gives the view ray's
 * shadowed set exactly, as a union of intervals (merged, sorted). */
#define FP_SS_MAX_IV 48
#define FP_SM_MAX_LEVELS 15   /* levels of a min-max pyramid (shadow map, depth buffer) */

/* h (camera (ux, uy, uw) -> NDC homogeneous) of the screen vector of a
 * camera vector V: perspective (Vx, Vy, Vz); orthographic (Vx, Vy, w),
 * w = 1 for a point, 0 for a direction. */
FP_FN void fp_ss_ndc(FP_CONSTANT const fp_real *h, const fp_real *V, int ortho, fp_real w,
                     fp_real *n)
{
    fp_real z = ortho ? w : V[2];
    for (int k = 0; k < 3; k++)
        n[k] = h[3 * k] * V[0] + h[3 * k + 1] * V[1] + h[3 * k + 2] * z;
}

/* Clip the convex polygon (t, s) in p (n vertices) by A t + B s + C >= 0. */
FP_FN int fp_ss_clip(fp_real *pt, fp_real *ps, int n, fp_real A, fp_real B, fp_real C)
{
    fp_real qt[16], qs[16];
    int m = 0;
    for (int k = 0; k < n && m < 14; k++) {
        int k1 = k + 1 == n ? 0 : k + 1;
        fp_real va = A * pt[k] + B * ps[k] + C, vb = A * pt[k1] + B * ps[k1] + C;
        if (va >= 0) {
            qt[m] = pt[k];
            qs[m++] = ps[k];
        }
        if ((va >= 0) != (vb >= 0)) {
            fp_real f = va / (va - vb);
            qt[m] = pt[k] + f * (pt[k1] - pt[k]);
            qs[m++] = ps[k] + f * (ps[k1] - ps[k]);
        }
    }
    for (int k = 0; k < m; k++) {
        pt[k] = qt[k];
        ps[k] = qs[k];
    }
    return m;
}

/* The polygon (pt, ps) of n vertices in the plane X = C0 + t D + s L
 * (camera space; nt, ns, nc: the NDC rows of D, L, C0, fp_ss_ndc) clipped
 * to what pixels [i0, i1) x [j0, j1) of the depth buffer (its pixel
 * mapping ndc, FP_LT_SS_NDC) see with camera z in (zlo, zhi), in front of
 * the camera: its vertices left, in place.  The sun's walk clips a
 * rectangle of (t, s), a lamp's a triangle (lamp_shadow_core.h). */
FP_FN int fp_ss_clip_block(FP_CONSTANT const fp_real *ndc, const fp_real *nt, const fp_real *ns,
                           const fp_real *nc, const fp_real *D, const fp_real *L,
                           const fp_real *C0, int i0, int i1, int j0, int j1, fp_real zlo,
                           fp_real zhi, fp_real *pt, fp_real *ps, int n)
{
    for (int ax = 0; ax < 2 && n > 0; ax++) {
        fp_real sc = ndc[ax], off = ndc[2 + ax];
        fp_real a = ((ax ? j0 : i0) - (fp_real)0.5 + off) * sc;
        fp_real b = ((ax ? j1 : i1) - (fp_real)0.5 + off) * sc;
        fp_real lo = fmin(a, b), hi = fmax(a, b);
        /* lo <= N_ax / N_3 <= hi, N_3 > 0 */
        n = fp_ss_clip(pt, ps, n, nt[ax] - lo * nt[2], ns[ax] - lo * ns[2], nc[ax] - lo * nc[2]);
        n = fp_ss_clip(pt, ps, n, hi * nt[2] - nt[ax], hi * ns[2] - ns[ax], hi * nc[2] - nc[ax]);
    }
    n = fp_ss_clip(pt, ps, n, nt[2], ns[2], nc[2]);
    n = fp_ss_clip(pt, ps, n, D[2], L[2], C0[2] - zlo);
    return fp_ss_clip(pt, ps, n, -D[2], -L[2], zhi - C0[2]);
}

/* The t-interval of (t, s) in [t0, t1] x [0, smax] shadowed through the
 * pixels [i0, i1) x [j0, j1) with camera z in (zlo, zhi): X = C0 + t D +
 * s L in camera space, nt, ns, nc their NDC rows (fp_ss_ndc), ndc the
 * depth buffer's pixel mapping (FP_LT_SS_NDC); for a point
 * (t0 = t1), its s-interval.  Returns 0 when none.  One pixel of scene z
 * zs: (zs, zs + THICK); a block of them: its smallest zs to its largest
 * plus THICK, which holds every pixel's interval. */
FP_FN int fp_ss_cells(FP_CONSTANT const fp_real *ndc, const fp_real *nt, const fp_real *ns,
                      const fp_real *nc, const fp_real *D, const fp_real *L, const fp_real *C0,
                      int i0, int i1, int j0, int j1, fp_real zlo, fp_real zhi, fp_real t0,
                      fp_real t1, fp_real smax, int point, fp_real *ia, fp_real *ib)
{
    fp_real pt[16] = { t0, t1, t1, t0 }, ps[16] = { 0, 0, smax, smax };
    int n = 4;
    n = fp_ss_clip_block(ndc, nt, ns, nc, D, L, C0, i0, i1, j0, j1, zlo, zhi, pt, ps, n);
    if (n < 3)
        return 0;
    /* A point (t0 = t1): shadowed when some s is left. */
    fp_real lo = FP_INF, hi = -FP_INF;
    for (int k = 0; k < n; k++) {
        lo = fmin(lo, point ? ps[k] : pt[k]);
        hi = fmax(hi, point ? ps[k] : pt[k]);
    }
    *ia = lo;
    *ib = hi;
    return hi > lo;
}

/* Add [a, b] to the sorted disjoint intervals (n of them); when full, the
 * two nearest merge (more shadow, never less: documented). */
FP_FN int fp_ss_insert(fp_real *iv, int n, fp_real a, fp_real b)
{
    int k = 0;
    while (k < n && iv[2 * k + 1] < a)
        k++;
    int e = k;
    while (e < n && iv[2 * e] <= b) {
        a = fmin(a, iv[2 * e]);
        b = fmax(b, iv[2 * e + 1]);
        e++;
    }
    /* [k, e) merge into one at k */
    int shift = 1 - (e - k);
    if (shift > 0 && n == FP_SS_MAX_IV) {
        /* full: widen the nearest neighbour instead */
        if (k < n && (k == 0 || iv[2 * k] - b < a - iv[2 * k - 1]))
            iv[2 * k] = a;
        else
            iv[2 * k - 1] = b;
        return n;
    }
    if (shift > 0)
        for (int q = n - 1; q >= k; q--) {
            iv[2 * q + 2] = iv[2 * q];
            iv[2 * q + 3] = iv[2 * q + 1];
        }
    else if (shift < 0)
        for (int q = e; q < n; q++) {
            iv[2 * (q + shift)] = iv[2 * q];
            iv[2 * (q + shift) + 1] = iv[2 * q + 1];
        }
    iv[2 * k] = a;
    iv[2 * k + 1] = b;
    return n + shift;
}

/* Min-max pyramids (the shadow map's, the depth buffer's: filters/shafts.c):
 * where level k (1..nl) begins, after the W x H cells of level 0. */
FP_FN void fp_pyr_offsets(int W, int H, int nl, int *offs)
{
    offs[0] = 0;
    for (int k = 1; k <= nl; k++)
        offs[k] = k == 1 ? W * H
                         : offs[k - 1] + 2 * ((W + (1 << (k - 1)) - 1) >> (k - 1)) *
                                             ((H + (1 << (k - 1)) - 1) >> (k - 1));
}

/* Floats of a W x H pyramid with its nl levels (fp_shafts_size in
 * filters/shafts.c). */
FP_FN int fp_pyr_size(int W, int H, int nl)
{
    int n = W * H;
    for (int k = 1; k <= nl; k++)
        n += 2 * ((W + (1 << k) - 1) >> k) * ((H + (1 << k) - 1) >> k);
    return n;
}

/* The depth buffer's pyramid the walk reads: the buffer itself under
 * --shadows screen, after the shadow map's floats under map+screen. */
FP_FN FP_GLOBAL const float *fp_ss_zpyr(FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *smap)
{
    if ((int)lt[FP_LT_SHADOWS] != FP_SHADOWS_MAP_SCREEN)
        return smap;
    return smap + fp_pyr_size((int)lt[FP_LT_SM_W], (int)lt[FP_LT_SM_H], (int)lt[FP_LT_SM_LEVELS]);
}

/* A walk over a pyramid leaves the block (bi, bj) of sz cells along the
 * line a + u e (in cells) at ue, through its x face or its y face: the
 * axis crossed moves one block on, the other stays within the block's row
 * or column. */
FP_FN void fp_pyr_next(int *ix, int *iy, int bi, int bj, int sz, int xface, fp_real ax,
                       fp_real ay, fp_real ex, fp_real ey, fp_real ue)
{
    if (xface) {
        *ix = ex > 0 ? (bi + 1) * sz : bi * sz - 1;
        int jv = (int)floor(ay + ue * ey);
        *iy = jv < bj * sz ? bj * sz : jv > bj * sz + sz - 1 ? bj * sz + sz - 1 : jv;
    } else {
        *iy = ey > 0 ? (bj + 1) * sz : bj * sz - 1;
        int iu = (int)floor(ax + ue * ex);
        *ix = iu < bi * sz ? bi * sz : iu > bi * sz + sz - 1 ? bi * sz + sz - 1 : iu;
    }
}

/* A hierarchical 2D DDA over a min-max pyramid of W x H cells (nl levels)
 * along the line a + u e, u in [0, 1], in cells: the screen walks toward
 * the sun (fp_ss_walk_dir) and toward a lamp (fp_ls_walk, lamp_shadow_core.h)
 * differ only in their cell test.  Each step looks at one block
 * (fp_pyr_walk_block); a block the test hits is opened a level down, any
 * other is crossed whole, and the walk climbs back a level after each
 * block it leaves (fp_pyr_walk_next). */
typedef struct {
    int W, H, nl, lv, ix, iy, bi, bj, sz;
    fp_real ax, ay, ex, ey, u1, uX, uY;
    int offs[FP_SM_MAX_LEVELS + 1];
} fp_pyr_walk_t;

/* The walk's start where the line enters the cells; 0 when it misses. */
FP_FN int fp_pyr_walk_begin(fp_pyr_walk_t *w, int W, int H, int nl, fp_real ax, fp_real ay,
                            fp_real ex, fp_real ey)
{
    fp_real u0 = 0, u1 = 1;
    fp_clip(ax, ex, 0, (fp_real)W, &u0, &u1);
    fp_clip(ay, ey, 0, (fp_real)H, &u0, &u1);
    if (!(u1 >= u0))
        return 0;
    w->W = W;
    w->H = H;
    w->nl = nl;
    w->ax = ax;
    w->ay = ay;
    w->ex = ex;
    w->ey = ey;
    w->u1 = u1;
    fp_pyr_offsets(W, H, nl, w->offs);
    w->ix = (int)fmin(fmax(floor(ax + u0 * ex), (fp_real)0), (fp_real)(W - 1));
    w->iy = (int)fmin(fmax(floor(ay + u0 * ey), (fp_real)0), (fp_real)(H - 1));
    w->lv = nl;
    return 1;
}

/* The current block: its cells [x0, x1) x [y0, y1) and the range of its
 * values (a cell's value twice at level 0; +inf: sky). */
FP_FN void fp_pyr_walk_block(fp_pyr_walk_t *w, FP_GLOBAL const float *zpyr, int *x0, int *x1,
                             int *y0, int *y1, fp_real *zlo, fp_real *zhi)
{
    int lv = w->lv, sz = 1 << lv, bi = w->ix >> lv, bj = w->iy >> lv;
    w->sz = sz;
    w->bi = bi;
    w->bj = bj;
    w->uX = w->ex > 0 ? ((fp_real)((bi + 1) * sz) - w->ax) / w->ex
          : w->ex < 0 ? ((fp_real)(bi * sz) - w->ax) / w->ex : (fp_real)FP_INF;
    w->uY = w->ey > 0 ? ((fp_real)((bj + 1) * sz) - w->ay) / w->ey
          : w->ey < 0 ? ((fp_real)(bj * sz) - w->ay) / w->ey : (fp_real)FP_INF;
    if (lv == 0) {
        *zlo = *zhi = zpyr[w->iy * w->W + w->ix];
    } else {
        int o = w->offs[lv] + 2 * (bj * ((w->W + sz - 1) >> lv) + bi);
        *zlo = zpyr[o];
        *zhi = zpyr[o + 1];
    }
    *x0 = bi * sz;
    *x1 = (bi + 1) * sz < w->W ? (bi + 1) * sz : w->W;
    *y0 = bj * sz;
    *y1 = (bj + 1) * sz < w->H ? (bj + 1) * sz : w->H;
}

/* After a block: a hit above level 0 opens it; else on to the next block
 * along the line.  0 at the line's end or the cells' edge. */
FP_FN int fp_pyr_walk_next(fp_pyr_walk_t *w, int hit)
{
    if (hit && w->lv > 0) {
        w->lv--;
        return 1;
    }
    fp_real ue = fmin(w->uX, w->uY);
    if (ue >= w->u1)
        return 0;
    fp_pyr_next(&w->ix, &w->iy, w->bi, w->bj, w->sz, w->uX <= w->uY, w->ax, w->ay, w->ex, w->ey,
                ue);
    if (w->ix < 0 || w->iy < 0 || w->ix >= w->W || w->iy >= w->H)
        return 0;
    w->lv = w->lv < w->nl ? w->lv + 1 : w->nl;
    return 1;
}

/* A camera-space point's NDC (homogeneous, fp_ss_ndc) -> the depth
 * buffer's pixel units (pixel i spans [i, i + 1)), by its own mapping
 * (FP_LT_SS_NDC), not the traced view's. */
FP_FN fp_real fp_ss_pixel(FP_CONSTANT const fp_real *lt, const fp_real *n, int ax)
{
    return n[ax] / n[2] / lt[FP_LT_SS_NDC + ax] - lt[FP_LT_SS_NDC + 2 + ax] + (fp_real)0.5;
}

/* The shadowed t of X = o + t d + s l, t in [t0, t1] (t1 finite; d = 0 for
 * one point, t0 = t1 = 0), from pixel (ax, ay) (the projection of the ray,
 * in the depth buffer's pixel units: fp_ss_pixel) toward the sun: into iv,
 * returns their count.  A point stops at its first shadow.  zpyr: the
 * frame's scene z per pixel (+inf: sky) and its min-max pyramid, as the
 * shadow map's (fp_shafts_pyramid, filters/shafts.c), its size and pixel
 * mapping in lt (FP_LT_SS_PW, FP_LT_SS_PH, FP_LT_SS_NDC): a block whose
 * pixels cannot shadow the stretch is crossed in one step.  view: the
 * camera's origin and projection kind (the same for any resolution). */
/* fp_ss_walk toward the direction (lx, ly, lz) (unit): the sun's, or an
 * extra directional light's. */
FP_FN int fp_ss_walk_dir(FP_CONSTANT const fp_real *lt, fp_real lx, fp_real ly, fp_real lz,
                         FP_CONSTANT const float *view, FP_GLOBAL const float *zpyr, fp_real ox,
                         fp_real oy, fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real t0,
                         fp_real t1, fp_real ax, fp_real ay, int point, fp_real *iv)
{
    FP_CONSTANT const fp_real *m = lt + FP_LT_SS_M, *h = lt + FP_LT_SS_H;
    const fp_real l[3] = { lx, ly, lz };
    int ortho = view[FP_VIEW_ORTHO] != 0;
    fp_real dist = lt[FP_LT_SS_DIST], thick = lt[FP_LT_SS_THICK];
    fp_real q[3] = { ox - view[0], oy - view[1], oz - view[2] };
    fp_real D[3], L[3], C0[3], nt[3], ns[3], nc[3];
    for (int k = 0; k < 3; k++) {
        D[k] = m[3 * k] * dx + m[3 * k + 1] * dy + m[3 * k + 2] * dz;
        L[k] = m[3 * k] * l[0] + m[3 * k + 1] * l[1] + m[3 * k + 2] * l[2];
        C0[k] = m[3 * k] * q[0] + m[3 * k + 1] * q[1] + m[3 * k + 2] * q[2];
    }
    fp_ss_ndc(h, D, ortho, 0, nt);
    fp_ss_ndc(h, L, ortho, 0, ns);
    fp_ss_ndc(h, C0, ortho, 1, nc);
    /* How far the sun's rays reach on screen: from the nearest point of the
     * stretch (1 mm on, past a perspective camera's own center), to DIST
     * or to where they pass behind the camera. */
    fp_real tr = fmax(t0, fmin((fp_real)1e-3, t1));
    fp_real czr = C0[2] + tr * D[2];
    fp_real sr = dist;
    if (L[2] < 0)
        sr = fmin(dist, (czr - (fp_real)1e-6 * (1 + fabs(czr))) / -L[2]);
    if (!(sr > 0) || !(czr > 0))
        return 0;
    fp_real nb[3];
    for (int k = 0; k < 3; k++)
        nb[k] = nc[k] + tr * nt[k] + sr * ns[k];
    fp_real bx = fp_ss_pixel(lt, nb, 0), by = fp_ss_pixel(lt, nb, 1);
    /* A hierarchical 2D DDA over the pixels of [a, b] within the screen,
     * in the parameter u of a + u (b - a). */
    int W = (int)lt[FP_LT_SS_PW], H = (int)lt[FP_LT_SS_PH];
    fp_pyr_walk_t pw;
    if (!fp_pyr_walk_begin(&pw, W, H, (int)lt[FP_LT_SS_PLEVELS], ax, ay, bx - ax, by - ay))
        return 0;
    int n = 0;
    for (int guard = 0; guard < 8 * (W + H) + 64; guard++) {
        int x0, x1, y0, y1;
        fp_real zlo, zhi, a, b;
        fp_pyr_walk_block(&pw, zpyr, &x0, &x1, &y0, &y1, &zlo, &zhi);
        int hit = zlo < FP_INF && fp_ss_cells(lt + FP_LT_SS_NDC, nt, ns, nc, D, L, C0, x0, x1, y0,
                                              y1, zlo, zhi + thick, t0, t1, dist, point, &a, &b);
        if (hit && pw.lv == 0) {
            n = fp_ss_insert(iv, n, a, b);
            if (point)
                break;
        }
        if (!fp_pyr_walk_next(&pw, hit))
            break;
    }
    return n;
}

FP_FN int fp_ss_walk(FP_CONSTANT const fp_real *lt, FP_CONSTANT const float *view,
                     FP_GLOBAL const float *zpyr, fp_real ox, fp_real oy, fp_real oz,
                     fp_real dx, fp_real dy, fp_real dz, fp_real t0, fp_real t1, fp_real ax,
                     fp_real ay, int point, fp_real *iv)
{
    return fp_ss_walk_dir(lt, lt[FP_LT_SUN_DIR], lt[FP_LT_SUN_DIR + 1], lt[FP_LT_SUN_DIR + 2], view,
                          zpyr, ox, oy, oz, dx, dy, dz, t0, t1, ax, ay, point, iv);
}

/* A point's visibility of the direction (lx, ly, lz) under --shadows
 * screen, by the same rule (the brute force's and the Monte Carlo
 * reference's; the extra directional lights' in the integrator): the depth
 * buffer's size and pixels are in lt. */
FP_FN fp_real fp_shadow_screen_dir(FP_CONSTANT const fp_real *lt, fp_real lx, fp_real ly,
                                   fp_real lz, FP_CONSTANT const float *view,
                                   FP_GLOBAL const float *zpyr, fp_real x, fp_real y, fp_real z)
{
    FP_CONSTANT const fp_real *m = lt + FP_LT_SS_M, *h = lt + FP_LT_SS_H;
    fp_real q[3] = { x - view[0], y - view[1], z - view[2] }, c[3], n[3];
    for (int k = 0; k < 3; k++)
        c[k] = m[3 * k] * q[0] + m[3 * k + 1] * q[1] + m[3 * k + 2] * q[2];
    if (!(c[2] > 0))
        return 1;
    fp_ss_ndc(h, c, view[FP_VIEW_ORTHO] != 0, 1, n);
    fp_real px = fp_ss_pixel(lt, n, 0), py = fp_ss_pixel(lt, n, 1);
    if (!(px >= 0 && py >= 0 && px < lt[FP_LT_SS_PW] && py < lt[FP_LT_SS_PH]))
        return 1;
    fp_real iv[2 * FP_SS_MAX_IV];
    return fp_ss_walk_dir(lt, lx, ly, lz, view, zpyr, x, y, z, 0, 0, 0, 0, 0, px, py, 1, iv) > 0
               ? (fp_real)0
               : (fp_real)1;
}

/* The sun's visibility at a point under --shadows screen. */
FP_FN fp_real fp_shadow_screen(FP_CONSTANT const fp_real *lt, FP_CONSTANT const float *view,
                               FP_GLOBAL const float *zpyr, int width, int height, fp_real x,
                               fp_real y, fp_real z)
{
    (void)width;
    (void)height;
    return fp_shadow_screen_dir(lt, lt[FP_LT_SUN_DIR], lt[FP_LT_SUN_DIR + 1],
                                lt[FP_LT_SUN_DIR + 2], view, zpyr, x, y, z);
}

/* The sun's visibility at a point (geometry only). */
FP_FN fp_real fp_sun_visibility(FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *smap,
                                FP_CONSTANT const float *view, FP_GLOBAL const float *depth,
                                int width, int height, fp_real x, fp_real y, fp_real z)
{
    int mode = (int)lt[FP_LT_SHADOWS];
    if (mode == FP_SHADOWS_MAP)
        return fp_shadow_map(lt, smap, x, y, z);
    if (mode == FP_SHADOWS_SCREEN)
        return fp_shadow_screen(lt, view, smap, width, height, x, y, z);
    if (mode == FP_SHADOWS_MAP_SCREEN)
        return fp_shadow_map(lt, smap, x, y, z) > 0
                   ? fp_shadow_screen(lt, view, fp_ss_zpyr(lt, smap), width, height, x, y, z)
                   : (fp_real)0;
    return 1;
}

/* The self-shadow grid (--self-shadow map): optical depth to the sun on
 * columns along the sun's rays, in a frame that follows them: a point p
 * lies on the sun ray through (a e1 + b e2, 0), e1 and e2 horizontal (e1
 * across the sun, e2 toward it), at height y; so a = p.e1, b = p.e2 -
 * p.y |l_h| / l_y, and the optical depth varies slowly along y (the
 * integral of the extinction) and with the fog's detail across (a, b).
 * Nodes are regular in (a, b, y) on nested cascades of NA x NB x NY nodes
 * around the camera (the finest holds the view rays' fog nearest the
 * camera; filters/scatter.c grid_bounds, which also puts a plane of nodes
 * on the fog's top, where the extinction jumps).  Node (c, i, j, k) is
 * grid[((c NB + j) NA + i) NY + k]. */
FP_FN int fp_sun_od_index(FP_CONSTANT const fp_real *lt, int c, int i, int j, int k)
{
    int na = (int)lt[FP_LT_GRID_N], nb = (int)lt[FP_LT_GRID_N + 1], ns = (int)lt[FP_LT_GRID_N + 2];
    return ((c * nb + j) * na + i) * ns + k;
}

/* The grid's weight at height y: the optical depth toward the sun of
 * height fog falls as e^(-(y - Y0) / H) above Y0 (and linearly below), so
 * od w(y) is nearly constant along a column above Y0 and linear below,
 * which the interpolation between nodes follows exactly (a fogmap adds
 * only its own variation).  Capped where the optical depth is nil. */
FP_FN fp_real fp_sun_od_weight(FP_CONSTANT const fp_real *lt, fp_real y)
{
    fp_real H = lt[FP_LT_GRID_W + 1];
    fp_real e = fmin(fmax(y - lt[FP_LT_GRID_W], (fp_real)0) / fmax(H, (fp_real)1e-30),
                     (fp_real)80);
    /* e = 0 below Y0 and for fog without a falloff (H infinite): no exp. */
    return H > 0 && e > 0 ? exp(e) : (fp_real)1;
}

/* The fog-space point of node (c, i, j, k). */
FP_FN void fp_sun_od_node(FP_CONSTANT const fp_real *lt, int c, int i, int j, int k, fp_real *p)
{
    FP_CONSTANT const fp_real *box = lt + FP_LT_CASCADE + 6 * c;
    fp_real a = box[0] + i * box[3], b = box[1] + j * box[4], y = box[2] + k * box[5];
    fp_real t = y / lt[FP_LT_SUN_DIR + 1];
    for (int d = 0; d < 3; d++)
        p[d] = a * lt[FP_LT_SUN_E1 + d] + b * lt[FP_LT_SUN_E2 + d] + t * lt[FP_LT_SUN_DIR + d];
}

/* One column of the grid, the nodes (c, i, j, 0..NS-1) along the sun: the
 * exact optical depth from the last node to the sun, then each node's as
 * the next one's plus the exact optical depth of the stretch between
 * them (one walk down the column, away from the sun, resumed node after
 * node: fp_fog_cur_t). */
FP_FN void fp_sun_od_column(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                            FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                            FP_GLOBAL const unsigned char *occ, FP_CONSTANT const fp_real *lt,
                            FP_GLOBAL float *grid, int c, int i, int j)
{
    int ns = (int)lt[FP_LT_GRID_N + 2];
    FP_CONSTANT const fp_real *l = lt + FP_LT_SUN_DIR;
    fp_real hs = lt[FP_LT_CASCADE + 6 * c + 5] / l[1];
    int at = fp_sun_od_index(lt, c, i, j, 0);
    fp_real p[3];
    fp_sun_od_node(lt, c, i, j, ns - 1, p);
    fp_real od = fp_fog_od(fp, lvi, lvf, coef, occ, p[0], p[1], p[2], l[0], l[1], l[2], FP_INF, 0);
    grid[at + ns - 1] = (float)(od * fp_sun_od_weight(lt, p[1]));
    fp_fog_cur_t cur;
    fp_fog_cur_init(&cur, fp, lvi, p[0], p[1], p[2], -l[0], -l[1], -l[2], (ns - 1) * hs);
    for (int k = ns - 2; k >= 0; k--) {
        fp_sun_od_node(lt, c, i, j, k, p);
        od += fp_fog_cur_advance(&cur, fp, lvi, lvf, coef, occ, (ns - 1 - k) * hs);
        grid[at + k] = (float)(od * fp_sun_od_weight(lt, p[1]));
    }
}

/* The grid's coordinates of a fog-space point: (a, b, y) in cells of
 * the finest cascade that holds it, *c that cascade; 0 when none does. */
FP_FN int fp_sun_od_cell(FP_CONSTANT const fp_real *lt, fp_real x, fp_real y, fp_real z, int *c,
                         fp_real *g)
{
    int na = (int)lt[FP_LT_GRID_N], nb = (int)lt[FP_LT_GRID_N + 1], ns = (int)lt[FP_LT_GRID_N + 2];
    int K = (int)lt[FP_LT_GRID_K];
    FP_CONSTANT const fp_real *e1 = lt + FP_LT_SUN_E1, *e2 = lt + FP_LT_SUN_E2,
                              *l = lt + FP_LT_SUN_DIR;
    fp_real a = x * e1[0] + z * e1[2];
    fp_real b = x * e2[0] + z * e2[2] - y * (l[0] * e2[0] + l[2] * e2[2]) / l[1];
    for (int k = 0; k < K; k++) {
        FP_CONSTANT const fp_real *box = lt + FP_LT_CASCADE + 6 * k;
        g[0] = (a - box[0]) / box[3];
        g[1] = (b - box[1]) / box[4];
        g[2] = (y - box[2]) / box[5];
        if (g[0] >= 0 && g[1] >= 0 && g[2] >= 0 && g[0] <= na - 1 && g[1] <= nb - 1 &&
            g[2] <= ns - 1) {
            *c = k;
            return 1;
        }
    }
    return 0;
}

/* Optical depth from a point to the sun, from the grid (trilinear in the
 * finest cascade that holds the point; the nodes hold the exact optical
 * depth), or -1 when no cascade holds it. */
FP_FN fp_real fp_sun_od_grid(FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *grid,
                             fp_real x, fp_real y, fp_real z)
{
    int na = (int)lt[FP_LT_GRID_N], nb = (int)lt[FP_LT_GRID_N + 1], ns = (int)lt[FP_LT_GRID_N + 2];
    int c;
    fp_real g[3];
    if (!fp_sun_od_cell(lt, x, y, z, &c, g))
        return -1;
    int i = (int)fmin(floor(g[0]), (fp_real)(na - 2));
    int j = (int)fmin(floor(g[1]), (fp_real)(nb - 2));
    int k = (int)fmin(floor(g[2]), (fp_real)(ns - 2));
    fp_real ax = g[0] - i, ay = g[1] - j, az = g[2] - k, od = 0;
    int at = fp_sun_od_index(lt, c, i, j, k);
    for (int q = 0; q < 8; q++) {
        int di = q & 1, dj = (q >> 1) & 1, dk = q >> 2;
        fp_real w = (di ? ax : 1 - ax) * (dj ? ay : 1 - ay) * (dk ? az : 1 - az);
        if (w > 0) /* a node may hold +inf: no 0 * inf */
            od += w * grid[at + (dj * na + di) * ns + dk];
    }
    return od / fp_sun_od_weight(lt, y);
}

/* Optical depth from a point toward the sun through the fog (0 without
 * self-shadowing). */
FP_FN fp_real fp_sun_od(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                        FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                        FP_GLOBAL const unsigned char *occ, FP_CONSTANT const fp_real *lt,
                        FP_GLOBAL const float *grid, fp_real x, fp_real y, fp_real z)
{
    int self = (int)lt[FP_LT_SELF];
    if (self == FP_SELF_OFF)
        return 0;
    FP_CONSTANT const fp_real *l = lt + FP_LT_SUN_DIR;
    fp_real od = self == FP_SELF_MAP ? fp_sun_od_grid(lt, grid, x, y, z) : -1;
    if (od < (fp_real)-0.5)
        od = fp_fog_od(fp, lvi, lvf, coef, occ, x, y, z, l[0], l[1], l[2], FP_INF, 0);
    return od;
}

/* Transmittance from a point toward the sun through the fog (tau_k). */
FP_FN fp_real fp_sun_tau(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                         FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                         FP_GLOBAL const unsigned char *occ, FP_CONSTANT const fp_real *lt,
                         FP_GLOBAL const float *grid, fp_real x, fp_real y, fp_real z)
{
    return exp(-fp_sun_od(fp, lvi, lvf, coef, occ, lt, grid, x, y, z));
}

/* Interleaved sampling (Keller and Heidrich 2001): pixel (x, y)'s offset
 * of the samples along its ray, in [0, 1) of a segment, from an n x m
 * tile of evenly spread offsets; the same every frame.  0 when off. */
FP_FN fp_real fp_interleave_offset(FP_CONSTANT const fp_real *lt, int x, int y)
{
    int n = (int)lt[FP_LT_INTERLEAVE], m = (int)lt[FP_LT_INTERLEAVE + 1];
    if (n * m <= 1)
        return 0;
    /* Rows of the tile visit the offsets in a shuffled order (a stride
     * coprime to n m), so neighbours in both directions differ. */
    int k = (x % n) + n * (y % m), nm = n * m;
    int stride = 1;
    for (int s = nm / 2 + 1; s < nm; s++) {
        int a = s, b = nm;
        while (b) {
            int t = a % b;
            a = b;
            b = t;
        }
        if (a == 1) {
            stride = s;
            break;
        }
    }
    return ((fp_real)((k * stride) % nm) + (fp_real)0.5) / nm;
}

/* Solid angle of the triangle a, a + e, a + f seen from the origin (Van
 * Oosterom and Strackee 1983), unsigned.  The triple product is taken as
 * a.(e x f), from the triangle's own edges, so that it keeps its
 * precision far from the triangle (single precision included). */
FP_FN fp_real fp_tri_solid(fp_real ax, fp_real ay, fp_real az, fp_real ex, fp_real ey,
                           fp_real ez, fp_real fx, fp_real fy, fp_real fz)
{
    fp_real bx = ax + ex, by = ay + ey, bz = az + ez, cx = ax + fx, cy = ay + fy, cz = az + fz;
    fp_real num = ax * (ey * fz - ez * fy) + ay * (ez * fx - ex * fz) + az * (ex * fy - ey * fx);
    fp_real la = sqrt(ax * ax + ay * ay + az * az), lb = sqrt(bx * bx + by * by + bz * bz),
            lc = sqrt(cx * cx + cy * cy + cz * cz);
    fp_real den = la * lb * lc + (ax * bx + ay * by + az * bz) * lc +
                  (ax * cx + ay * cy + az * cz) * lb + (bx * cx + by * cy + bz * cz) * la;
    return 2 * fabs(atan2(num, den));
}

/* An ellipse is taken as the octagon of the same area inscribed in it
 * scaled by sqrt(pi / (4 sin(pi/4))) (its vertices at 45 degree steps). */
#define FP_AREA_OCT_SCALE 1.0539021936412585
#define FP_AREA_OCT_SIDES 8

/* Solid angle of area light `row` seen from the point at w = (its center
 * minus the point). */
FP_FN fp_real fp_area_solid(FP_GLOBAL const fp_real *row, fp_real wx, fp_real wy, fp_real wz)
{
    FP_GLOBAL const fp_real *U = row + FP_LL_U, *V = row + FP_LL_V;
    if ((int)row[FP_LL_SHAPE] == 0) {
        /* Corners -U-V, U-V, U+V, -U+V: two triangles from the first. */
        fp_real ax = wx - U[0] - V[0], ay = wy - U[1] - V[1], az = wz - U[2] - V[2];
        return fp_tri_solid(ax, ay, az, 2 * U[0], 2 * U[1], 2 * U[2], 2 * (U[0] + V[0]),
                            2 * (U[1] + V[1]), 2 * (U[2] + V[2])) +
               fp_tri_solid(ax, ay, az, 2 * (U[0] + V[0]), 2 * (U[1] + V[1]),
                            2 * (U[2] + V[2]), 2 * V[0], 2 * V[1], 2 * V[2]);
    }
    fp_real om = 0, s = (fp_real)FP_AREA_OCT_SCALE, h = (fp_real)0.70710678118654752;
    fp_real cs[FP_AREA_OCT_SIDES + 1] = { 1, h, 0, -h, -1, -h, 0, h, 1 };
    fp_real sn[FP_AREA_OCT_SIDES + 1] = { 0, h, 1, h, 0, -h, -1, -h, 0 };
    for (int k = 0; k < FP_AREA_OCT_SIDES; k++) {
        fp_real c0 = s * cs[k], s0 = s * sn[k], c1 = s * cs[k + 1], s1 = s * sn[k + 1];
        om += fp_tri_solid(wx, wy, wz, c0 * U[0] + s0 * V[0], c0 * U[1] + s0 * V[1],
                           c0 * U[2] + s0 * V[2], c1 * U[0] + s1 * V[0], c1 * U[1] + s1 * V[1],
                           c1 * U[2] + s1 * V[2]);
    }
    return om;
}

/* A local light's irradiance at a point as a factor of its intensity I
 * over the squared distance: E = I gain / r^2, (ux, uy, uz) unit from the
 * light's position to the point, r the distance.
 * - spot, profile 0 (fogpipe): 1 inside the inner cone, 0 outside the
 *   outer, smoothstep between;
 * - spot, profile 1 (Cycles 3.x spot_attenuation): c = cos to the axis,
 *   0 when c <= cos(half), else c smoothstep(0, spread, c - cos(half));
 * - point and spot with a soft radius R: Cycles 3.x samples a disk of
 *   radius R facing the point, radiance I / (pi R^2), with the cosine at
 *   the disk: E = I 2 / (s (s + r)), s = sqrt(r^2 + R^2) (the disk's
 *   integral of cos / d^2), I / r^2 far away, 2 I / R^2 at its center,
 *   never infinite;
 * - area (one-sided, Lambertian, intensity I cos along its normal): E =
 *   radiance x solid angle = I Omega / A exactly (Omega of the rectangle,
 *   or of the ellipse's equal-area octagon), I cos / r^2 far away.
 * The phase function is taken toward the light's center (the disk's and
 * the area's spread of directions is not). */
FP_FN fp_real fp_light_gain_cos(FP_GLOBAL const fp_real *row, fp_real c, fp_real ux, fp_real uy,
                                fp_real uz, fp_real r)
{
    int type = (int)row[FP_LL_TYPE];
    if (type == FP_LIGHT_AREA)
        return c > 0 ? r * r * fp_area_solid(row, -r * ux, -r * uy, -r * uz) / row[FP_LL_AREA]
                     : (fp_real)0;
    fp_real g = 1;
    if (type == FP_LIGHT_SPOT) {
        fp_real ci = row[FP_LL_COS_IN], co = row[FP_LL_COS_OUT];
        if (c <= co)
            return 0;
        if (row[FP_LL_PROFILE] == 0) {
            fp_real s = (c - co) / (ci - co);
            g = c >= ci ? (fp_real)1 : s * s * (3 - 2 * s);
        } else {
            fp_real sp = row[FP_LL_SPREAD], s = (c - co) / fmax(sp, (fp_real)1e-30);
            g = c * (sp > 0 && s < 1 ? s * s * (3 - 2 * s) : (fp_real)1);
        }
    }
    fp_real R = row[FP_LL_RADIUS];
    if (R > 0) {
        fp_real s = sqrt(r * r + R * R);
        g *= 2 * r * r / (s * (s + r));
    }
    return g;
}

/* The same, c the cosine of u to the light's axis computed here. */
FP_FN fp_real fp_light_gain(FP_GLOBAL const fp_real *row, fp_real ux, fp_real uy, fp_real uz,
                            fp_real r)
{
    fp_real c = ux * row[FP_LL_AXIS] + uy * row[FP_LL_AXIS + 1] + uz * row[FP_LL_AXIS + 2];
    return fp_light_gain_cos(row, c, ux, uy, uz, r);
}

#include "cull_core.h"

/* Culling (--light-cull): the most local light `row` can add to any
 * channel of the view ray o + t d's in-scatter over [ta, tb] (tb may be
 * +inf), one_minus_tau at least the ray's 1 - tau there.  0 when the
 * spot's cone or the area's front half-space misses the stretch (the
 * cone's support along the ray is |theta - theta_a| <= acos(cos_out / R)
 * in the angle seen from the light, as in fp_light_fast); else
 *   albedo Imax pmax min((1 - tau) f / D^2, sigma_max (th1 - th0) f / D)
 * with D the light's distance to the ray's line: the irradiance is at
 * most Imax / r^2 (the gain of fp_light_gain is at most 1) and r >= D,
 * so the in-scatter is at most that over the segment's own
 * int sigma tau dt <= 1 - tau, and at most sigma_max int dt / r^2 =
 * sigma_max (th1 - th0) / D; an area light's points are up to rho (its
 * half diagonal) nearer: r - rho >= r (D - rho) / D, f = (D / (D - rho))^2.
 * +inf (never culled) when the ray passes within rho of the light. */
FP_FN fp_real fp_light_bound(FP_CONSTANT const fp_real *lt, FP_GLOBAL const fp_real *row,
                             fp_real sigma_max, fp_real one_minus_tau, fp_real ox, fp_real oy,
                             fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real ta,
                             fp_real tb)
{
    fp_real qx = row[FP_LL_POS] - ox, qy = row[FP_LL_POS + 1] - oy, qz = row[FP_LL_POS + 2] - oz;
    fp_real tc = qx * dx + qy * dy + qz * dz;
    fp_real rx = qx - tc * dx, ry = qy - tc * dy, rz = qz - tc * dz;
    fp_real D = sqrt(rx * rx + ry * ry + rz * rz), rho = row[FP_LL_REACH];
    if (!(D > rho) || !(D > (fp_real)1e-6 * (1 + fabs(tc))))
        return FP_INF;
    const fp_real hp = (fp_real)1.5707963267948966, pi = (fp_real)3.14159265358979323846;
    fp_real th0 = atan((ta - tc) / D), th1 = isinf(tb) ? hp : atan((tb - tc) / D);
    int type = (int)row[FP_LL_TYPE];
    fp_real co = row[FP_LL_COS_OUT];
    if ((type == FP_LIGHT_SPOT || type == FP_LIGHT_AREA) && co >= 0) {
        /* n: from the light toward the ray's closest point. */
        fp_real na = -(rx * row[FP_LL_AXIS] + ry * row[FP_LL_AXIS + 1] + rz * row[FP_LL_AXIS + 2]) / D;
        fp_real da = dx * row[FP_LL_AXIS] + dy * row[FP_LL_AXIS + 1] + dz * row[FP_LL_AXIS + 2];
        fp_real R = sqrt(na * na + da * da);
        if (!(R > co))
            return 0;
        fp_real tha = atan2(da, na);
        tha += 2 * pi * floor(((fp_real)0.5 * (th0 + th1) - tha) / (2 * pi) + (fp_real)0.5);
        fp_real ao = acos(co / R);
        if (tha + ao < th0 || tha - ao > th1)
            return 0;
    }
    fp_real f = D / (D - rho);
    f *= f;
    fp_real b = fmin(one_minus_tau * f / (D * D), sigma_max * (th1 - th0) * f / D);
    /* pmax: the phase over the stretch alone for a point (cull_core.h). */
    fp_real pm = rho > 0 ? lt[FP_LT_PMAX] : fp_light_phase_span(lt, D, tc, ta, tb);
    return lt[FP_LT_ALBEDO] * row[FP_LL_IMAX] * pm * b;
}

#endif

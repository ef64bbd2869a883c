/* fogpipe: the one walk per ray over a fogmap's levels (the sum surfaces
 * A_l), its level of detail (--lod-bound, --lod-footprint, mu), the
 * tensor walk of the linear basis and the point evaluation of one level.
 * Included by fog_core.h after the parameter layout and the per-level
 * integral; compiled twice like it (OpenCL C in single precision, C in
 * double for the reference). */
#ifndef FP_FOGMAP_WALK_H
#define FP_FOGMAP_WALK_H

#include "fog_params.h"
#include "fogmap_cubic.h"

/* ------------------------------------------------------------------ */
/* One walk per ray.  The sum of levels 0..l of the deconstructed fogmap,
 * A_l, is itself one B-spline surface on level l's grid (each coarser
 * surface refined onto it, filters/fogmap.c), and every level's knots lie
 * on the finest grid's, so the ray crosses one grid once: A_{nl-1} = F
 * (the padded fogmap itself) where every level counts, coarser A_l where
 * levels are dropped.  A segment is the part of the ray inside one cell
 * and within one stretch of height over which the exponent of h changes
 * by at most FP_SEG_U; there F is a polynomial P of degree 2d in the
 * segment's parameter x in [0, 1] and h = h_a exp(-u x), so
 *     int P h = h_a len sum_k P_k m_k(u),  m_k(u) = int_0^1 x^k e^(-ux) dx
 *            = h_a len sum_j (-u)^j / j! sum_k P_k / (k + j + 1),
 * a series whose first FP_SEG_TERMS terms are exact to the precision:
 * the omitted rest is below FP_SEG_U^J / J!.  No quadrature, one exp per
 * segment, no branch around the math. */
#ifdef __OPENCL_VERSION__
#define FP_SEG_U 0.25f     /* remainder 0.25^7 / 7! = 1.2e-8 of the segment */
#define FP_SEG_TERMS 7
#define FP_SEG_POW2 8      /* FP_SEG_TERMS rounded up to a power of 2 */
#else
#define FP_SEG_U 0.25      /* remainder 0.25^13 / 13! = 2e-18 */
#define FP_SEG_TERMS 13
#define FP_SEG_POW2 16
#endif

/* Counts the walks' segments where a benchmark defines it before including
 * this header (tests/bench_lod.c, its C copies of the walks); nothing
 * otherwise. */
#ifndef FP_SEG_COUNT
#define FP_SEG_COUNT()
#endif

/* 1 / j!, j = 0..15. */
FP_TABLE fp_real fp_invfact[16] = {
    1.0, 1.0, 1.0 / 2, 1.0 / 6, 1.0 / 24, 1.0 / 120, 1.0 / 720, 1.0 / 5040, 1.0 / 40320,
    1.0 / 362880, 1.0 / 3628800, 1.0 / 39916800, 1.0 / 479001600, 1.0 / 6227020800.0,
    1.0 / 87178291200.0, 1.0 / 1307674368000.0 };

/* sum_j c[j] z^j, j < FP_SEG_POW2, pairwise (Estrin): a few dependent
 * steps instead of one per term.  Written out: as a loop over the halvings
 * neither PoCL nor gcc unrolled it, and its partial sums went through
 * memory, one store-to-load chain per step (half of the walk's time in
 * perf).  The same pairs in the same order as that loop. */
FP_HOT fp_real fp_estrin(const fp_real *c, fp_real z)
{
    fp_real z2 = z * z, z4 = z2 * z2;
    fp_real e0 = (c[0] + c[1] * z) + (c[2] + c[3] * z) * z2;
    fp_real e1 = (c[4] + c[5] * z) + (c[6] + c[7] * z) * z2;
#if FP_SEG_POW2 == 8
    return e0 + e1 * z4;
#elif FP_SEG_POW2 == 16
    fp_real e2 = (c[8] + c[9] * z) + (c[10] + c[11] * z) * z2;
    fp_real e3 = (c[12] + c[13] * z) + (c[14] + c[15] * z) * z2;
    return (e0 + e1 * z4) + (e2 + e3 * z4) * (z4 * z4);
#else
#error "fp_estrin: FP_SEG_POW2 must be 8 or 16"
#endif
}

/* 1 / n, n = 1..24. */
FP_TABLE fp_real fp_recip[24] = {
    1.0, 1.0 / 2, 1.0 / 3, 1.0 / 4, 1.0 / 5, 1.0 / 6, 1.0 / 7, 1.0 / 8, 1.0 / 9, 1.0 / 10,
    1.0 / 11, 1.0 / 12, 1.0 / 13, 1.0 / 14, 1.0 / 15, 1.0 / 16, 1.0 / 17, 1.0 / 18, 1.0 / 19,
    1.0 / 20, 1.0 / 21, 1.0 / 22, 1.0 / 23, 1.0 / 24 };

/* Uniform B-spline blending polynomials in the power basis (bspline.h,
 * fp_bspline_poly): weight j of degree d is sum_p fp_bsp_a[d][j * 4 + p] s^p. */
FP_TABLE fp_real fp_bsp_a[4][16] = {
    { 1, 0, 0, 0 },
    { 1, -1, 0, 0, 0, 1, 0, 0 },
    { 0.5, -1, 0.5, 0, 0.5, 1, -1, 0, 0, 0, 0.5, 0 },
    { 1.0 / 6, -0.5, 0.5, -1.0 / 6, 2.0 / 3, 0, -1, 0.5, 1.0 / 6, 0.5, 0.5, -0.5,
      0, 0, 0, 1.0 / 6 } };

/* int_0^1 P(x) exp(-u x) dx for P of degree 2d (coefficients P[0..2d]),
 * |u| <= FP_SEG_U. */
FP_HOT fp_real fp_poly_exp_integral(const fp_real *P, const int d, fp_real u)
{
    fp_real c[FP_SEG_POW2];
    for (int j = 0; j < FP_SEG_POW2; j++) {
        fp_real s = 0;
        for (int k = 0; k <= 2 * d; k++)
            s += P[k] * fp_recip[k + j];
        c[j] = j < FP_SEG_TERMS ? s * fp_invfact[j] : (fp_real)0;
    }
    return fp_estrin(c, -u);
}

/* The surface along one segment as a polynomial in x in [0, 1]: local
 * cell coordinates (px + qx x, py + qy x), coefficients c[j * 4 + i]. */
FP_HOT void fp_cell_poly(const int d, const fp_real *c, fp_real px, fp_real qx, fp_real py,
                        fp_real qy, fp_real *P)
{
    /* g[q][p]: the cell's surface as sum g_qp sx^p sy^q. */
    fp_real g[4][4];
    for (int q = 0; q <= d; q++)
        for (int p = 0; p <= d; p++) {
            fp_real acc = 0;
            for (int j = 0; j <= d; j++) {
                fp_real row = 0;
                for (int i = 0; i <= d; i++)
                    row += c[j * 4 + i] * fp_bsp_a[d][i * 4 + p];
                acc += fp_bsp_a[d][j * 4 + q] * row;
            }
            g[q][p] = acc;
        }
    /* Horner along sy of Horner along sx, each a polynomial in x. */
    for (int k = 0; k < 7; k++)
        P[k] = 0;
    for (int q = d; q >= 0; q--) {
        fp_real r[4];
        r[0] = g[q][d];
        for (int k = 1; k < 4; k++)
            r[k] = 0;
        for (int p = d - 1; p >= 0; p--) {
            for (int k = d; k >= 1; k--)
                r[k] = px * r[k] + qx * r[k - 1];
            r[0] = px * r[0] + g[q][p];
        }
        /* P = P * (py + qy x) + r */
        for (int k = 2 * d; k >= 1; k--)
            P[k] = py * P[k] + qy * P[k - 1];
        P[0] = py * P[0];
        for (int k = 0; k <= d; k++)
            P[k] += r[k];
    }
}

/* int_0^1 F(x) exp(-u x) dx over one segment of a bilinear cell, F =
 * g0 + g1 sx + g2 sy + g3 sx sy through the corner values c0 (0,0), c1
 * (1,0), c4 (0,1), c5 (1,1), the segment from local (px, py) by (qx, qy),
 * written out; *E = exp(-u) from the same series (lam = 0: fog without a
 * falloff, H infinite: u = 0, the series' first term alone, *E left as it
 * is; lam is the same for every ray of such fog, so lanes do not
 * diverge).  fp_grid_walk's linear cells and fp_tensor_walk's rectangles. */
FP_HOT fp_real fp_bilinear_seg(fp_real c0, fp_real c1, fp_real c4, fp_real c5, fp_real px,
                               fp_real qx, fp_real py, fp_real qy, fp_real lam, fp_real u,
                               fp_real *E)
{
    fp_real g1 = c1 - c0, g2 = c4 - c0, g3 = c5 - c4 - g1;
    fp_real P0 = c0 + g1 * px + (g2 + g3 * px) * py;
    fp_real P1 = g1 * qx + g2 * qy + g3 * (px * qy + qx * py);
    fp_real P2 = g3 * qx * qy;
    if (lam == 0)
        return P0 * fp_recip[0] + P1 * fp_recip[1] + P2 * fp_recip[2];
    fp_real cs[FP_SEG_POW2], ce[FP_SEG_POW2];
    for (int j = 0; j < FP_SEG_POW2; j++) {
        fp_real f = j < FP_SEG_TERMS ? fp_invfact[j] : (fp_real)0;
        cs[j] = f * (P0 * fp_recip[j] + P1 * fp_recip[j + 1] + P2 * fp_recip[j + 2]);
        ce[j] = f;
    }
    *E = fp_estrin(ce, -u);
    return fp_estrin(cs, -u);
}

/* Bounded level of detail (--lod-bound).  Each cell of level l's grid
 * carries a bound of |F - A_l| there (filters/fogmap.c: for the linear
 * basis its exact largest value, at the finest nodes of the cell, 0 where
 * A_l = F; for the other degrees the sum over the finer levels of their
 * largest |coefficient| reaching the cell, B-splines being >= 0 and
 * summing to 1), so a segment integrated on A_l instead of F changes the
 * optical depth by at most D = sigma bound w, w >= int h over the segment,
 * and tau by at most exp(-od) D exp(2 D), od the optical depth computed
 * before it (|tau - tau'| <= sum_i exp(-od'_<i) exp(|da_i|) |da_i|
 * telescoping, and od' falls at most by the D's).  A segment is kept on
 * the coarse grid only while these costs stay within the bound times the
 * share of the path's weight done (or what is left of the bound spread
 * over the weight left); otherwise the walk goes finer there, straight to
 * the coarsest level whose cell would let a segment of its length through
 * (fp_fogmap_od), and every FP_LOD_EVERY segments tries the ancestors of
 * its cell, as coarse as they cost at most half the fair share of what is
 * left (the period and the half: fewest segments on bench_lod's maps). */
#ifndef FP_LOD_EVERY
#define FP_LOD_EVERY 32    /* segments between tries of a coarser level (a power of 2, >= 2:
                              never the first segment after a restart) */
#endif
typedef struct fp_lod_t {
    fp_real bound;     /* largest |dtau| allowed in all (0: exact) */
    fp_real spent;     /* the costs of the segments done */
    fp_real sigma;
    fp_real wdone;     /* their weights (upper bounds of int h) */
    fp_real wtot;      /* an upper bound of int h over the whole ray */
    fp_real wfail;     /* the weight of the segment that asked for a finer level */
    fp_real efail;     /* sigma exp(-od) there */
} fp_lod_t;

/* Weight of the path over [t, end], int h: an upper bound (h is monotone
 * along a straight path). */
FP_FN fp_real fp_rest_weight(fp_real y0, fp_real H, const fp_path_t *p, fp_real t, fp_real end)
{
    fp_real ya = p->oy + t * p->dy, yb = p->oy + end * p->dy;
    fp_real low = fmin(ya, yb);
    fp_real hmax = exp(-fmax(low - y0, (fp_real)0) / H);
    fp_real len = end - t;
    /* Exact above Y0 on the rising or falling exponential: |h_a - h_b| H / |dy|. */
    fp_real ha = exp(-fmax(ya - y0, (fp_real)0) / H), hb = exp(-fmax(yb - y0, (fp_real)0) / H);
    fp_real below = p->dy == 0 ? (ya < y0 ? len : (fp_real)0)
                               : fmin(fmax((y0 - low) / fabs(p->dy), (fp_real)0), len);
    fp_real above = p->dy == 0 || !isfinite(H) ? (len - below) * fmax(ha, hb)
                                               : fabs(ha - hb) * H / fabs(p->dy);
    return fmin(len * hmax, below + above) * (1 + (fp_real)1e-5);
}

/* Whether a segment of weight w may cost `cost`: within the bound's share
 * of the weight done, or within what is left of the bound spread over the
 * weight left; either keeps the sum of the costs within the bound.  The
 * second division only when the first share does not do. */
FP_FN int fp_lod_fits(const fp_lod_t *lod, fp_real cost, fp_real w)
{
    if (cost <= lod->bound * fmin((fp_real)1, (lod->wdone + w) / lod->wtot) - lod->spent)
        return 1;
    return cost <= (lod->bound - lod->spent) * fmin((fp_real)1, w / (lod->wtot - lod->wdone));
}

/* An upper bound of exp(2 D), D >= 0: 1 + 4 D up to D = 1/4 (exp(x) <=
 * 1 + x exp(x) <= 1 + 1.65 x for x = 2 D <= 1/2), without an exp. */
FP_FN fp_real fp_lod_grow(fp_real D)
{
    return D <= (fp_real)0.25 ? 1 + 4 * D : exp(2 * D);
}

/* The cell bound of level L's grid at wrapped cell (k, m) (0 on the finest). */
FP_FN fp_real fp_lod_cell(FP_CONSTANT const int *lvi, FP_GLOBAL const float *coef, int L, int k,
                          int m)
{
    int off = lvi[L * FP_LI_STRIDE + FP_LI_TMAP];
    if (off < 0)
        return 0;
    return coef[off + (size_t)m * lvi[L * FP_LI_STRIDE + FP_LI_NX] + k];
}

/* The cell bound of level L at the point t of path p. */
FP_FN fp_real fp_lod_at(FP_CONSTANT const int *lvi, FP_CONSTANT const fp_real *lvf,
                        FP_GLOBAL const float *coef, int d, int L, const fp_path_t *p, fp_real t)
{
    fp_real kappa = (d & 1) ? (fp_real)0 : (fp_real)0.5, cell = lvf[L * FP_LR_STRIDE + FP_LR_CELL];
    fp_real x = (p->u0 + t * p->du - lvf[L * FP_LR_STRIDE + FP_LR_ORIGIN_U]) / cell + kappa;
    fp_real y = (p->v0 + t * p->dv - lvf[L * FP_LR_STRIDE + FP_LR_ORIGIN_V]) / cell + kappa;
    return fp_lod_cell(lvi, coef, L,
                       fp_wrap_index(fp_cell_of(x, p->du), lvi[L * FP_LI_STRIDE + FP_LI_NX]),
                       fp_wrap_index(fp_cell_of(y, p->dv), lvi[L * FP_LI_STRIDE + FP_LI_NY]));
}

/* The DDA's state between calls of fp_grid_walk on one path and level
 * (the resumable walk of fp_fog_cur_t): the cell (k, m) the walk stands in
 * at its *t_end.  live 0: the walk finds its cell from a. */
typedef struct fp_walk_t {
    int live, k, m;
} fp_walk_t;

/* Integral of A_L times h(y) along p over [a, b], segment by segment (2D
 * DDA over the cells plus cuts at Y0 and every FP_SEG_U of the exponent),
 * until b, until the optical depth passes od_stop, or (lod->bound > 0)
 * until a coarser level may take over: *t_end and *L_next say where and
 * which.  `od` is the optical depth before a (for the bound).  ws: where a
 * walk of the same path and level left off at a (ws->live), its state at
 * *t_end on return; so a walk resumed at its own *t_end goes on as one
 * walk over both stretches (its segments also end at that t). */
FP_HOT fp_real fp_grid_walk(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                           FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                           const int d, int L, int finer, const fp_path_t *p, fp_real a,
                           fp_real b, fp_real od, fp_real od_stop, fp_lod_t *lod, fp_walk_t *ws,
                           fp_real *t_end, int *L_next)
{
    int nx = lvi[L * FP_LI_STRIDE + FP_LI_NX], ny = lvi[L * FP_LI_STRIDE + FP_LI_NY];
    FP_GLOBAL const float *cf = coef + lvi[L * FP_LI_STRIDE + FP_LI_APPROX];
    fp_real cell = lvf[L * FP_LR_STRIDE + FP_LR_CELL];
    fp_real kappa = (d & 1) ? (fp_real)0 : (fp_real)0.5;
    fp_real xs = (p->u0 - lvf[L * FP_LR_STRIDE + FP_LR_ORIGIN_U]) / cell + kappa;
    fp_real ys = (p->v0 - lvf[L * FP_LR_STRIDE + FP_LR_ORIGIN_V]) / cell + kappa;
    fp_real dxdt = p->du / cell, dydt = p->dv / cell;
    fp_real y0 = fp[FP_F_Y0], H = fp[FP_F_H];
    fp_real lam = p->dy / H;
    /* Longest segment for which |u| <= FP_SEG_U. */
    fp_real lmax = lam != 0 ? FP_SEG_U / fabs(lam) : FP_INF;
    /* Where the path crosses Y0 (the kink of h). */
    fp_real tc = p->dy != 0 ? (y0 - p->oy) / p->dy : -FP_INF;
    int sx = dxdt > 0 ? 1 : -1, sy = dydt > 0 ? 1 : -1;
    fp_real ix = dxdt != 0 ? 1 / dxdt : 0, iy = dydt != 0 ? 1 / dydt : 0;
    int k = ws->live ? ws->k : fp_cell_of(xs + a * dxdt, dxdt);
    int m = ws->live ? ws->m : fp_cell_of(ys + a * dydt, dydt);
    int first = d / 2;
    /* Wrapped index of the cell's first coefficient column and row. */
    int kw = fp_wrap_index(k - first, nx), mw = fp_wrap_index(m - first, ny);
    fp_real tx = dxdt != 0 ? (k + (dxdt > 0) - xs) * ix : FP_INF;
    fp_real ty = dydt != 0 ? (m + (dydt > 0) - ys) * iy : FP_INF;
    fp_real t = a, sum = 0, od0 = od, hc = 1;
    int bounded = lod->bound > 0 && finer && lvi[L * FP_LI_STRIDE + FP_LI_TMAP] >= 0;
    int coarser = lod->bound > 0 && L > 0, lod_fresh = 1;
    fp_real se = 0;
    *L_next = L;
    for (int guard = 0; t < b && od0 + sum <= od_stop && guard < (1 << 24); guard++) {
        fp_real tn = fmin(fmin(tx, ty), fmin(b, t + lmax));
        tn = tc > t && tc < tn ? tc : tn;
        tn = fmax(tn, t);
        fp_real len = tn - t;
        FP_SEG_COUNT();
        /* The cell's coefficients (the linear basis' four read directly:
         * the loop below kept them in memory, a quarter of the walk). */
        fp_real c[16];
        if (d == 1) {
            int kw1 = kw + 1 >= nx ? kw + 1 - nx : kw + 1;
            int mw1 = mw + 1 >= ny ? mw + 1 - ny : mw + 1;
            FP_GLOBAL const float *r0 = cf + (size_t)mw * nx, *r1 = cf + (size_t)mw1 * nx;
            c[0] = r0[kw];
            c[1] = r0[kw1];
            c[4] = r1[kw];
            c[5] = r1[kw1];
        }
        for (int j = 0; d != 1 && j <= d; j++) {
            int mj = mw + j;
            mj = mj >= ny ? mj % ny : mj;   /* % only on grids narrower than d + 1 */
            FP_GLOBAL const float *row = cf + (size_t)mj * nx;
            for (int i = 0; i <= d; i++) {
                int ki = kw + i;
                ki = ki >= nx ? ki % nx : ki;
                c[j * 4 + i] = row[ki];
            }
        }
        fp_real px = xs + t * dxdt - k, qx = dxdt * len, py = ys + t * dydt - m, qy = dydt * len;
        fp_real ya = p->oy + t * p->dy;
        int above = (p->oy + (t + (fp_real)0.5 * len) * p->dy) > y0;
        fp_real u = above ? lam * len : (fp_real)0;
        /* h at the segment's start: carried from the last segment's end
         * (times exp(-u), from the same series), exact every 8th. */
        if ((guard & 7) == 0)
            hc = exp(-fmax(ya - y0, (fp_real)0) / H);
        fp_real ha = hc, E = 1;
        fp_real seg;
        if (d == 1) {
            seg = fp_bilinear_seg(c[0], c[1], c[4], c[5], px, qx, py, qy, lam, u, &E);
        } else if (d == 3) {
            seg = fp_cubic_seg(c, px, qx, py, qy, u, &E);
        } else {
            fp_real P[7];
            fp_cell_poly(d, c, px, qx, py, qy, P);
            seg = fp_poly_exp_integral(P, d, u);
            E = exp(-u);
        }
        /* sigma exp(-od) for the bound's costs, od at the segment's start:
         * anew every 8th segment and after a falling one (A_L may be
         * negative), so that od never fell since (the costs stay upper
         * bounds), one exp for 8 segments. */
        if ((bounded || coarser) && (lod_fresh || (guard & 7) == 0))
            se = lod->sigma * exp(-lod->sigma * (od0 + sum));
        if (bounded) {
            /* What integrating this segment on A_L instead of F may cost. */
            fp_real w = len * fmax(ha, ha * E);
            int kc = kw + first, mc = mw + first;
            kc = kc >= nx ? kc - nx : kc;
            mc = mc >= ny ? mc - ny : mc;
            fp_real tm = fp_lod_cell(lvi, coef, L, kc, mc);
            fp_real cost = se * tm * w * fp_lod_grow(lod->sigma * tm * w);
            if (!fp_lod_fits(lod, cost, w)) {
                /* Finer from t: fp_fogmap_od jumps to the coarsest level
                 * whose cell there would let a segment through, taken
                 * half as long per level as this one. */
                lod->wfail = w;
                lod->efail = se;
                *L_next = L + 1;
                break;
            }
            lod->spent += cost;
            lod->wdone += w;
        }
        sum += ha * len * seg;
        lod_fresh = seg < 0;
        hc = ha * E;
        /* Step to the next cell where the segment ended on its edge. */
        int stepx = tx <= tn, stepy = ty <= tn;
        k += stepx ? sx : 0;
        kw += stepx ? sx : 0;
        kw = kw >= nx ? kw - nx : kw < 0 ? kw + nx : kw;
        tx = stepx ? (k + (dxdt > 0) - xs) * ix : tx;
        m += stepy ? sy : 0;
        mw += stepy ? sy : 0;
        mw = mw >= ny ? mw - ny : mw < 0 ? mw + ny : mw;
        ty = stepy ? (m + (dydt > 0) - ys) * iy : ty;
        t = tn;
        if (coarser && (guard & (FP_LOD_EVERY - 1)) == FP_LOD_EVERY - 1 && t < b && len > 0) {
            /* Coarser where the ancestors of the cell the walk enters cost
             * at most half of what is left of the bound spread over the
             * weight left, per weight: the coarse walk then adds to the
             * slack rather than spending it (spent slack would force the
             * next refinement to the finest levels, hundreds of segments
             * on a map with kinks).  Never right after a restart, whose
             * first segment may be a sliver where rounding put the start
             * in the cell before.  The ancestors' indices are the cell's
             * halved: the grids nest (both wrapped). */
            int kc = kw + first, mc = mw + first;
            kc = kc >= nx ? kc - nx : kc;
            mc = mc >= ny ? mc - ny : mc;
            fp_real rest = lod->wtot - lod->wdone;
            fp_real thr = rest > 0 ? (lod->bound - lod->spent) / (2 * se * rest) : (fp_real)-1;
            int Lc = L;
            while (Lc > 0 &&
                   fp_lod_cell(lvi, coef, Lc - 1, kc >> (L - Lc + 1), mc >> (L - Lc + 1)) <= thr)
                Lc--;
            if (Lc < L) {
                *L_next = Lc;
                break;
            }
        }
    }
    *t_end = t;
    ws->live = 1;
    ws->k = k;
    ws->m = m;
    return sum;
}

/* fp_grid_walk with the degree a constant, so that its loops unroll. */
FP_FN fp_real fp_grid_walk_any(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                               FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                               int d, int L, int finer, const fp_path_t *p, fp_real a,
                               fp_real b, fp_real od, fp_real od_stop, fp_lod_t *lod,
                               fp_walk_t *ws, fp_real *t_end, int *L_next)
{
    switch (d) {
    case 0:
        return fp_grid_walk(fp, lvi, lvf, coef, 0, L, finer, p, a, b, od, od_stop, lod, ws,
                            t_end, L_next);
    case 1:
        return fp_grid_walk(fp, lvi, lvf, coef, 1, L, finer, p, a, b, od, od_stop, lod, ws,
                            t_end, L_next);
    case 2:
        return fp_grid_walk(fp, lvi, lvf, coef, 2, L, finer, p, a, b, od, od_stop, lod, ws,
                            t_end, L_next);
    default:
        return fp_grid_walk(fp, lvi, lvf, coef, 3, L, finer, p, a, b, od, od_stop, lod, ws,
                            t_end, L_next);
    }
}

/* ------------------------------------------------------------------ */
/* The tensor grid (--lod-bound, linear basis).  A fogmap made by resizing
 * a smaller one (oiiotool --resize:filter=triangle samples its bilinear
 * surface at the new pixel centres) is bilinear on far larger rectangles
 * than its cells, but their sides fall between the nodes of every coarser
 * dyadic level, so each of those levels has detail along every kink and
 * the bounded level of detail walks fine cells there.  filters/fogmap.c
 * finds, per axis, the break nodes: the nodes where F's second difference
 * across the other axis is not rounding; G, bilinear on the rectangles
 * between consecutive breaks (wrapping with the domain) through F's values
 * at their corners, is then F up to eps = max |F - G|, computed exactly at
 * every finest node (F - G is bilinear on each finest cell).  Its walk is
 * fp_grid_walk's (d = 1) with the cell sides read from the break arrays. */

/* The rectangle holding x on one axis of the tensor grid: index *r of its
 * lower break in br[0..nb-1] (sorted, in [0, n)), *o the multiple of the
 * period n it sits in.  On a break, a path moving down enters the
 * rectangle below (fp_cell_of). */
FP_FN void fp_tensor_find(FP_GLOBAL const float *br, int nb, int n, fp_real x, fp_real dxdt,
                          int *r, fp_real *o)
{
    fp_real per = floor(x / n);
    fp_real xr = x - per * n;
    int lo = 0, hi = nb;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        int below = dxdt < 0 ? br[mid] < xr : br[mid] <= xr;
        lo = below ? mid + 1 : lo;
        hi = below ? hi : mid;
    }
    *r = lo - 1;
    if (*r < 0) {
        *r = nb - 1;
        per -= 1;
    }
    *o = per * n;
}

/* One axis of fp_tensor_walk's DDA, into the next rectangle along the
 * path: rectangle *r between breaks *r and *r1 (wrapped indices), its sides
 * *lo, *hi in the path's unwrapped coordinates, *o the multiple of the
 * period n it sits in; s the path's start on this axis, dsdt its rate,
 * is = 1 / dsdt.  Returns the t of the next side's crossing. */
FP_FN fp_real fp_tensor_step(FP_GLOBAL const float *br, int nb, int n, fp_real s, fp_real dsdt,
                             fp_real is, int *r, int *r1, fp_real *o, fp_real *lo, fp_real *hi)
{
    if (dsdt > 0) {
        *r = *r1;
        *o += *r ? 0 : n;
        *r1 = *r + 1 == nb ? 0 : *r + 1;
        *lo = *hi;
        *hi = *r1 ? *o + br[*r1] : *o + n + br[0];
        return (*hi - s) * is;
    }
    *r1 = *r;
    *r = *r ? *r - 1 : nb - 1;
    *o -= *r1 ? 0 : n;
    *hi = *lo;
    *lo = *o + br[*r];
    return (*lo - s) * is;
}

/* Integral of G times h(y(t)) along p over [a, b], segment by segment (the
 * DDA over the rectangles plus the cuts at Y0 and every FP_SEG_U of the
 * exponent, as fp_grid_walk), until b or until the optical depth passes
 * od_stop (od: before a). */
FP_HOT fp_real fp_tensor_walk(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                              FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                              const fp_path_t *p, fp_real a, fp_real b, fp_real od,
                              fp_real od_stop)
{
    /* The finest level's coordinates: node i at x = i (linear: no knot shift). */
    int L = (int)fp[FP_F_NLEVELS] - 1;
    int nx = lvi[L * FP_LI_STRIDE + FP_LI_NX], ny = lvi[L * FP_LI_STRIDE + FP_LI_NY];
    FP_CONSTANT const int *ti = lvi + FP_TG_ROW * FP_LI_STRIDE;
    int nbx = ti[FP_TI_NX], nby = ti[FP_TI_NY];
    FP_GLOBAL const float *G = coef + ti[FP_TI_VAL];
    FP_GLOBAL const float *bx = coef + ti[FP_TI_BX], *iwx = bx + nbx;
    FP_GLOBAL const float *by = coef + ti[FP_TI_BY], *iwy = by + nby;
    fp_real cell = lvf[L * FP_LR_STRIDE + FP_LR_CELL];
    fp_real xs = (p->u0 - lvf[L * FP_LR_STRIDE + FP_LR_ORIGIN_U]) / cell;
    fp_real ys = (p->v0 - lvf[L * FP_LR_STRIDE + FP_LR_ORIGIN_V]) / cell;
    fp_real dxdt = p->du / cell, dydt = p->dv / cell;
    fp_real y0 = fp[FP_F_Y0], H = fp[FP_F_H];
    fp_real lam = p->dy / H;
    fp_real lmax = lam != 0 ? FP_SEG_U / fabs(lam) : FP_INF;
    fp_real tc = p->dy != 0 ? (y0 - p->oy) / p->dy : -FP_INF;
    fp_real ix = dxdt != 0 ? 1 / dxdt : 0, iy = dydt != 0 ? 1 / dydt : 0;
    int r, q;
    fp_real ox, oy;
    fp_tensor_find(bx, nbx, nx, xs + a * dxdt, dxdt, &r, &ox);
    fp_tensor_find(by, nby, ny, ys + a * dydt, dydt, &q, &oy);
    /* The rectangle's sides (xlo, xhi), (ylo, yhi) in the path's
     * unwrapped coordinates; r1, q1 the wrapped indices of the upper ones. */
    int r1 = r + 1 == nbx ? 0 : r + 1, q1 = q + 1 == nby ? 0 : q + 1;
    fp_real xlo = ox + bx[r], xhi = r1 ? ox + bx[r1] : ox + nx + bx[0];
    fp_real ylo = oy + by[q], yhi = q1 ? oy + by[q1] : oy + ny + by[0];
    fp_real tx = dxdt > 0 ? (xhi - xs) * ix : dxdt < 0 ? (xlo - xs) * ix : FP_INF;
    fp_real ty = dydt > 0 ? (yhi - ys) * iy : dydt < 0 ? (ylo - ys) * iy : FP_INF;
    fp_real t = a, sum = 0, hc = 1;
    for (int guard = 0; t < b && od + sum <= od_stop && guard < (1 << 24); guard++) {
        fp_real tn = fmin(fmin(tx, ty), fmin(b, t + lmax));
        tn = tc > t && tc < tn ? tc : tn;
        tn = fmax(tn, t);
        fp_real len = tn - t;
        FP_SEG_COUNT();
        fp_real c0 = G[q * nbx + r], c1 = G[q * nbx + r1];
        fp_real c4 = G[q1 * nbx + r], c5 = G[q1 * nbx + r1];
        fp_real wx = iwx[r], wy = iwy[q];
        fp_real px = (xs + t * dxdt - xlo) * wx, qx = dxdt * len * wx;
        fp_real py = (ys + t * dydt - ylo) * wy, qy = dydt * len * wy;
        fp_real ya = p->oy + t * p->dy;
        int above = (p->oy + (t + (fp_real)0.5 * len) * p->dy) > y0;
        fp_real u = above ? lam * len : (fp_real)0;
        if ((guard & 7) == 0)
            hc = exp(-fmax(ya - y0, (fp_real)0) / H);
        fp_real ha = hc, E = 1;
        fp_real seg = fp_bilinear_seg(c0, c1, c4, c5, px, qx, py, qy, lam, u, &E);
        sum += ha * len * seg;
        hc = ha * E;
        /* Into the next rectangle where the segment ended on its side. */
        if (tx <= tn)
            tx = fp_tensor_step(bx, nbx, nx, xs, dxdt, ix, &r, &r1, &ox, &xlo, &xhi);
        if (ty <= tn)
            ty = fp_tensor_step(by, nby, ny, ys, dydt, iy, &q, &q1, &oy, &ylo, &yhi);
        t = tn;
    }
    return sum;
}

/* F at a domain point from one level (the fine grid, for marching). */
FP_FN fp_real fp_level_eval(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                            FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef, int l,
                            fp_real U, fp_real V)
{
    int d = (int)fp[FP_F_DEGREE];
    int nx = lvi[l * FP_LI_STRIDE + FP_LI_NX], ny = lvi[l * FP_LI_STRIDE + FP_LI_NY];
    FP_GLOBAL const float *cf = coef + lvi[l * FP_LI_STRIDE + FP_LI_COEF];
    fp_real cell = lvf[l * FP_LR_STRIDE + FP_LR_CELL];
    fp_real kappa = (d & 1) ? (fp_real)0 : (fp_real)0.5;
    fp_real x = (U - lvf[l * FP_LR_STRIDE + FP_LR_ORIGIN_U]) / cell + kappa;
    fp_real y = (V - lvf[l * FP_LR_STRIDE + FP_LR_ORIGIN_V]) / cell + kappa;
    int k = (int)floor(x), m = (int)floor(y), first = d / 2;
    fp_real wu[4], wv[4], f = 0;
    fp_bspline_weights(d, x - k, wu);
    fp_bspline_weights(d, y - m, wv);
    for (int j = 0; j <= d; j++)
        for (int i = 0; i <= d; i++)
            f += cf[fp_wrap_index(m - first + j, ny) * nx + fp_wrap_index(k - first + i, nx)] *
                 wu[i] * wv[j];
    return f;
}

#endif

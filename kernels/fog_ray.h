/* fogpipe: the ray through the fog: the height profile at a point, the
 * ray clipped to the fog box and the haze's slab, the fogmap's path and
 * its clamp pieces, the optical depth of a whole ray (fp_fog_od) and the
 * cursor that integrates it stretch by stretch (fp_fog_cur_t).  Included
 * by fog_core.h after fogmap_walk.h. */
#ifndef FP_FOG_RAY_H
#define FP_FOG_RAY_H

#include "fog_params.h"
#include "fogmap_walk.h"

FP_FN fp_real fp_h(FP_CONSTANT const fp_real *fp, fp_real y)
{
    if (y >= fp[FP_F_TOP])
        return 0;
    return y < fp[FP_F_Y0] ? (fp_real)1 : exp(-(y - fp[FP_F_Y0]) / fp[FP_F_H]);
}

/* Clip [*a, *b] to lo <= o + t d <= hi. */
FP_FN void fp_clip(fp_real o, fp_real dd, fp_real lo, fp_real hi, fp_real *a, fp_real *b)
{
    if (dd == 0) {
        if (o < lo || o > hi)
            *b = *a;
        return;
    }
    fp_real u = (lo - o) / dd, v = (hi - o) / dd;
    *a = fmax(*a, fmin(u, v));
    *b = fmin(*b, fmax(u, v));
}

/* Where along o + t d, t in [0, len], the main fog can be non-zero: its
 * box, below its top, and within the fogmap's clip rectangle when it does
 * not wrap (the clipping of fp_fogmap_od).  0 when nowhere. */
FP_FN int fp_main_span(FP_CONSTANT const fp_real *fp, fp_real ox, fp_real oy, fp_real oz,
                       fp_real dx, fp_real dy, fp_real dz, fp_real len, fp_real *ta, fp_real *tb)
{
    fp_real a = 0, b = len;
    if (!(fp[FP_F_SIGMA] > 0))
        return 0;
    fp_real c = fp[FP_F_COS], s = fp[FP_F_SIN];
    fp_real px = ox - fp[FP_F_OFF], py = oy - fp[FP_F_OFF + 1], pz = oz - fp[FP_F_OFF + 2];
    fp_real qx = c * px - s * pz, qz = s * px + c * pz;
    fp_real ex = c * dx - s * dz, ez = s * dx + c * dz;
    fp_clip(qx, ex, fp[FP_F_BOX], fp[FP_F_BOX + 3], &a, &b);
    fp_clip(py, dy, fp[FP_F_BOX + 1], fp[FP_F_BOX + 4], &a, &b);
    fp_clip(qz, ez, fp[FP_F_BOX + 2], fp[FP_F_BOX + 5], &a, &b);
    fp_clip(py, dy, -FP_INF, fp[FP_F_TOP], &a, &b);
    if (fp[FP_F_HAS_MAP] != 0 && (int)fp[FP_F_WRAP] == 0) {
        fp_clip((qx - fp[FP_F_A0]) * fp[FP_F_USCALE] + fp[FP_F_PAD_X0], ex * fp[FP_F_USCALE],
                fp[FP_F_CLIP], fp[FP_F_CLIP + 1], &a, &b);
        fp_clip((qz - fp[FP_F_B0]) * fp[FP_F_VSCALE] + fp[FP_F_PAD_Y0], ez * fp[FP_F_VSCALE],
                fp[FP_F_CLIP + 2], fp[FP_F_CLIP + 3], &a, &b);
    }
    *ta = a;
    *tb = b;
    return b > a;
}

/* The same for the haze: below its top. */
FP_FN int fp_haze_span(FP_CONSTANT const fp_real *fp, fp_real oy, fp_real dy, fp_real len,
                       fp_real *ta, fp_real *tb)
{
    fp_real a = 0, b = len;
    if (!(fp[FP_F_HAZE] > 0))
        return 0;
    fp_clip(oy, dy, -FP_INF, fp[FP_F_HAZE + 3], &a, &b);
    *ta = a;
    *tb = b;
    return b > a;
}

/* Clamp: the straight path of the piece [pa, pb] between box crossings,
 * with a coordinate outside the box held at the box's edge. */
FP_FN void fp_clamp_piece(FP_CONSTANT const fp_real *fp, const fp_path_t *p, fp_real pa,
                          fp_real pb, fp_path_t *q)
{
    *q = *p;
    fp_real tm = (fp_real)0.5 * (pa + pb);
    fp_real um = p->u0 + tm * p->du, vm = p->v0 + tm * p->dv;
    if (um < fp[FP_F_CLIP] || um > fp[FP_F_CLIP + 1]) {
        q->u0 = um < fp[FP_F_CLIP] ? fp[FP_F_CLIP] : fp[FP_F_CLIP + 1];
        q->du = 0;
    }
    if (vm < fp[FP_F_CLIP + 2] || vm > fp[FP_F_CLIP + 3]) {
        q->v0 = vm < fp[FP_F_CLIP + 2] ? fp[FP_F_CLIP + 2] : fp[FP_F_CLIP + 3];
        q->dv = 0;
    }
}

/* The fog-space ray o + t dir as a path over the fogmap's domain (the
 * fog-local frame: the fog's offset and its turn about the vertical
 * undone; U = (x - A0) uscale + pad_x0, likewise V on z), and the stretch
 * [*a, *b] of t in [0, len] where the fogmap's fog can be: in the fog box,
 * below the fog's top, and in the fogmap's clip rectangle when it does not
 * wrap.  *b is infinite where len is. */
FP_FN void fp_fogmap_path(FP_CONSTANT const fp_real *fp, fp_real ox, fp_real oy, fp_real oz,
                          fp_real dx, fp_real dy, fp_real dz, fp_real len, fp_path_t *p,
                          fp_real *a, fp_real *b)
{
    fp_real c = fp[FP_F_COS], s = fp[FP_F_SIN];
    fp_real px = ox - fp[FP_F_OFF], py = oy - fp[FP_F_OFF + 1], pz = oz - fp[FP_F_OFF + 2];
    fp_real qx = c * px - s * pz, qz = s * px + c * pz;
    fp_real ex = c * dx - s * dz, ez = s * dx + c * dz;
    *a = 0;
    *b = len;
    fp_clip(qx, ex, fp[FP_F_BOX], fp[FP_F_BOX + 3], a, b);
    fp_clip(py, dy, fp[FP_F_BOX + 1], fp[FP_F_BOX + 4], a, b);
    fp_clip(qz, ez, fp[FP_F_BOX + 2], fp[FP_F_BOX + 5], a, b);
    fp_clip(py, dy, -FP_INF, fp[FP_F_TOP], a, b);
    p->u0 = (qx - fp[FP_F_A0]) * fp[FP_F_USCALE] + fp[FP_F_PAD_X0];
    p->du = ex * fp[FP_F_USCALE];
    p->v0 = (qz - fp[FP_F_B0]) * fp[FP_F_VSCALE] + fp[FP_F_PAD_Y0];
    p->dv = ez * fp[FP_F_VSCALE];
    p->oy = py;
    p->dy = dy;
    if ((int)fp[FP_F_WRAP] == 0) {
        fp_clip(p->u0, p->du, fp[FP_F_CLIP], fp[FP_F_CLIP + 1], a, b);
        fp_clip(p->v0, p->dv, fp[FP_F_CLIP + 2], fp[FP_F_CLIP + 3], a, b);
    }
}

/* Where an unbounded stretch from a ends: where the exponential has died
 * out, or CAP on. */
FP_FN fp_real fp_fogmap_cap(FP_CONSTANT const fp_real *fp, const fp_path_t *p, fp_real a)
{
    if (p->dy > 0 && isfinite(fp[FP_F_H]))
        return fmax(a, (fp[FP_F_Y0] + 40 * fp[FP_F_H] - p->oy) / p->dy);
    return a + fp[FP_F_CAP];
}

/* Clamp: outside the box the fog repeats its edge, so the clamped path is
 * straight within each of up to five pieces between box crossings: their
 * ends from a to b, sorted, into cuts (6); returns their count. */
FP_FN int fp_clamp_cuts(FP_CONSTANT const fp_real *fp, const fp_path_t *p, fp_real a, fp_real b,
                        fp_real *cuts)
{
    int ncut = 0;
    cuts[ncut++] = a;
    if ((int)fp[FP_F_WRAP] == 1) {
        for (int axis = 0; axis < 4; axis++) {
            fp_real o = axis < 2 ? p->u0 : p->v0, dd = axis < 2 ? p->du : p->dv;
            if (dd == 0)
                continue;
            fp_real tc = (fp[FP_F_CLIP + axis] - o) / dd;
            if (tc > a && tc < b) {
                int i = ncut++;
                while (i > 0 && cuts[i - 1] > tc) {
                    cuts[i] = cuts[i - 1];
                    i--;
                }
                cuts[i] = tc;
            }
        }
    }
    cuts[ncut++] = b;
    return ncut;
}

/* Optical depth of the fogmap part along the fog-space ray o + t dir,
 * t in [0, len].  `jitter` in [-0.5, 0.5) offsets the march samples. */
FP_FN fp_real fp_fogmap_od(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                           FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                           FP_GLOBAL const unsigned char *occ, fp_real ox, fp_real oy,
                           fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real len,
                           fp_real jitter)
{
    fp_path_t p;
    fp_real a, b;
    fp_fogmap_path(fp, ox, oy, oz, dx, dy, dz, len, &p, &a, &b);
    int wrap = (int)fp[FP_F_WRAP];
    if (isinf(b))
        b = fp_fogmap_cap(fp, &p, a);
    if (!(b > a))
        return 0;
    fp_real sigma = fp[FP_F_SIGMA];
    int nl = (int)fp[FP_F_NLEVELS];
    if ((int)fp[FP_F_MODE] == 1) {
        /* Baseline (seed 002 sec. 4.2): N uniform steps, midpoint samples. */
        int n = (int)fp[FP_F_STEPS];
        fp_real dt = (b - a) / n, od = 0;
        for (int i = 0; i < n; i++) {
            fp_real t = a + (i + (fp_real)0.5 + jitter) * dt;
            fp_real U = p.u0 + t * p.du, V = p.v0 + t * p.dv;
            if (wrap == 1) {
                U = fmin(fmax(U, fp[FP_F_CLIP]), fp[FP_F_CLIP + 1]);
                V = fmin(fmax(V, fp[FP_F_CLIP + 2]), fp[FP_F_CLIP + 3]);
            }
            od += fp_level_eval(fp, lvi, lvf, coef, nl, U, V) * fp_h(fp, p.oy + t * p.dy);
        }
        return sigma * od * dt;
    }
    /* Level of detail (seed 000 eq. 12): level l is integrated up to
     * d_max_l = |OP| mu^l, and not beyond its pixel-footprint distance. */
    fp_real dmax[FP_MAX_LEVELS_ALL];
    fp_real op = isinf(len) ? b : len, mu = fp[FP_F_LOD_MU], scale = 1;
    for (int l = 0; l < nl; l++) {
        fp_real foot = fp[FP_F_FOOTPRINT] > 0 ? lvf[l * FP_LR_STRIDE + FP_LR_LOD_DIST] /
                                                    fp[FP_F_FOOTPRINT] : FP_INF;
        dmax[l] = l == 0 ? FP_INF : fmin(op * scale, foot);
        scale *= mu;
    }
    fp_real od_max = fp[FP_F_OD_MAX] / fmax(sigma, (fp_real)1e-30);
    fp_real cuts[6];
    int ncut = fp_clamp_cuts(fp, &p, a, b, cuts);
    fp_real od = 0;
    /* One walk per ray when every level has its sum surface A_l (not with
     * raw bands): A_L over [dmax[L+1], dmax[L]), L falling with t. */
    int walk = lvi[FP_LI_APPROX] >= 0;
    fp_lod_t lod;
    lod.bound = fp[FP_F_LOD_BOUND];
    lod.spent = 0;
    lod.sigma = sigma;
    lod.wdone = 0;
    lod.wfail = 0;
    lod.efail = 0;
    lod.wtot = lod.bound > 0 ? fp_rest_weight(fp[FP_F_Y0], fp[FP_F_H], &p, a, b) : 1;
    /* Bounded, where the finest level reaches the whole ray (--lod-mu 1, no
     * --lod-footprint): the tensor grid when its error fits the whole ray,
     * |dtau| <= |d od| <= sigma eps wtot <= bound (both optical depths
     * >= 0: F >= 0 and G interpolates F's values). */
    if (walk && lod.bound > 0 && lvi[FP_TG_ROW * FP_LI_STRIDE + FP_TI_NX] > 0 &&
        !(dmax[nl - 1] < b) &&
        sigma * lvf[FP_TG_ROW * FP_LR_STRIDE + FP_TR_EPS] * lod.wtot <= lod.bound) {
        for (int piece = 0; piece + 1 < ncut && od <= od_max; piece++) {
            fp_path_t q = p;
            if (wrap == 1)
                fp_clamp_piece(fp, &p, cuts[piece], cuts[piece + 1], &q);
            od += fp_tensor_walk(fp, lvi, lvf, coef, &q, cuts[piece], cuts[piece + 1], od,
                                 od_max);
        }
        return sigma * od;
    }
    /* Bounded: from the coarsest grid, finer where the bound asks. */
    int L = lod.bound > 0 ? 0 : nl - 1, d = (int)fp[FP_F_DEGREE];
    for (int piece = 0; walk && piece + 1 < ncut && od <= od_max; piece++) {
        fp_real t = cuts[piece], pb = cuts[piece + 1];
        fp_path_t q = p;
        if (wrap == 1)
            fp_clamp_piece(fp, &p, t, pb, &q);
        for (int pass = 0; t < pb && od <= od_max && pass < (1 << 20); pass++) {
            /* The finest level --lod-mu and --lod-footprint keep at t. */
            int Lcap = nl - 1;
            while (Lcap > 0 && !(t < dmax[Lcap]))
                Lcap--;
            L = L < Lcap ? L : Lcap;
            fp_real te;
            int Ln;
            fp_walk_t ws;
            ws.live = 0;
            od += fp_grid_walk_any(fp, lvi, lvf, coef, d, L, L < Lcap, &q, t, fmin(pb, dmax[L]),
                                   od, od_max, &lod, &ws, &te, &Ln);
            /* Finer: as far as the cell bounds at te ask, not one level at a
             * time (the walk there checks its segments itself). */
            for (fp_real w = (fp_real)0.5 * lod.wfail; Ln > L && Ln < Lcap; w *= (fp_real)0.5) {
                fp_real tm = fp_lod_at(lvi, lvf, coef, d, Ln, &q, te);
                if (fp_lod_fits(&lod, lod.efail * tm * w * fp_lod_grow(sigma * tm * w), w))
                    break;
                Ln++;
            }
            L = Ln;
            t = te;
        }
    }
    for (int piece = 0; !walk && piece + 1 < ncut; piece++) {
        fp_real pa = cuts[piece], pb = cuts[piece + 1];
        if (!(pb > pa))
            continue;
        fp_path_t q = p;
        if (wrap == 1)
            fp_clamp_piece(fp, &p, pa, pb, &q);
        /* Early termination needs the sum of all levels, which alone is
         * non-negative: walk the path in chunks of one coarse cell, add
         * every level over each chunk, then test. */
        fp_real speed = fmax(fabs(q.du), fabs(q.dv));
        fp_real chunk = speed > 0 ? lvf[FP_LR_CELL] / speed : pb - pa;
        int stop = 0;
        for (fp_real ca = pa; ca < pb && !stop;) {
            fp_real cb = fmin(pb, ca + chunk);
            if (!(cb > ca))
                cb = pb;
            for (int l = 0; l < nl; l++) {
                fp_real lb = fmin(cb, dmax[l]);
                if (lb > ca)
                    od += fp_level_integral(fp, lvi, lvf, coef, occ, l, &q, ca, lb);
            }
            stop = od > od_max;
            ca = cb;
        }
        if (stop)
            break;
    }
    return sigma * od;
}

/* Optical depth of the whole fog along the fog-space ray o + t dir,
 * t in [0, len]: the main fog (the fogmap, or homogeneous height fog
 * without one) inside the fog box, plus the haze. */
FP_FN fp_real fp_fog_od(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                        FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                        FP_GLOBAL const unsigned char *occ, fp_real ox, fp_real oy, fp_real oz,
                        fp_real dx, fp_real dy, fp_real dz, fp_real len, fp_real jitter)
{
    fp_real od = fp_height_od(fp[FP_F_HAZE], fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2],
                              fp[FP_F_HAZE + 3], oy, dy, len);
    if (fp[FP_F_HAS_MAP] != 0)
        return od + fp_fogmap_od(fp, lvi, lvf, coef, occ, ox, oy, oz, dx, dy, dz, len, jitter);
    /* Homogeneous main fog: closed form over the part of the ray in the box
     * (the box is axis-aligned in the fog's turned frame). */
    fp_real c = fp[FP_F_COS], s = fp[FP_F_SIN];
    fp_real px = ox - fp[FP_F_OFF], py = oy - fp[FP_F_OFF + 1], pz = oz - fp[FP_F_OFF + 2];
    fp_real a = 0, b = len;
    fp_clip(c * px - s * pz, c * dx - s * dz, fp[FP_F_BOX], fp[FP_F_BOX + 3], &a, &b);
    fp_clip(py, dy, fp[FP_F_BOX + 1], fp[FP_F_BOX + 4], &a, &b);
    fp_clip(s * px + c * pz, s * dx + c * dz, fp[FP_F_BOX + 2], fp[FP_F_BOX + 5], &a, &b);
    if (b > a)
        od += fp_height_od(fp[FP_F_SIGMA], fp[FP_F_Y0], fp[FP_F_H], fp[FP_F_TOP],
                           py + a * dy, dy, b - a);
    return od;
}

/* A resumable walk: the optical depth of the whole fog (fp_fog_od's) over
 * [t, t1], [t1, t2], ... of one fog-space ray o + t dir, t in [0, len],
 * for increasing ends, at the cost of one walk over the ray.  The fogmap's
 * DDA keeps its cell from one stretch to the next (fp_walk_t), so a
 * stretch costs its own segments only, not the set-up of fp_fogmap_od
 * (rotation, clipping, the DDA's first cell) nor a walk from the camera;
 * each stretch is integrated by the same loop (fp_grid_walk) with the same
 * per-segment math, its segments also ending at the stretch's ends, so the
 * result is fp_fog_od's over [t, t1] up to rounding (tests/test_fogmap.c).
 * The haze and fog without a fogmap are closed forms per stretch.  The
 * rare paths go to fp_fog_od over each stretch from o + t dir (exactly
 * what the callers did before): march mode, levels kept as raw bands,
 * --lod-bound, --lod-mu < 1 and --lod-footprint (their levels' reach is
 * measured from each call's start), --min-transmittance (early
 * termination within each call).  A cursor is plain data: a copy of it
 * tries a stretch that may be refused (a step halved) and the original
 * goes on unchanged. */
typedef struct fp_fog_cur_t {
    fp_real ox, oy, oz, dx, dy, dz; /* the ray */
    fp_real t;                      /* where the next stretch starts */
    int walk;                       /* 1: the resumable walk; 0: fp_fog_od per stretch */
    fp_path_t p, q;                 /* the path; q: that of the current clamp piece */
    fp_real a, b;                   /* where the fogmap's fog can be (b may be infinite) */
    fp_real cuts[6];                /* the clamp pieces' ends (fp_clamp_cuts) */
    int ncut, piece;
    fp_walk_t w;                    /* the DDA, standing at wt */
    fp_real wt;
} fp_fog_cur_t;

/* A cursor at t = 0 along o + t dir, t in [0, len] (len may be infinite). */
FP_FN void fp_fog_cur_init(fp_fog_cur_t *cur, FP_CONSTANT const fp_real *fp,
                           FP_CONSTANT const int *lvi, fp_real ox, fp_real oy, fp_real oz,
                           fp_real dx, fp_real dy, fp_real dz, fp_real len)
{
    cur->ox = ox;
    cur->oy = oy;
    cur->oz = oz;
    cur->dx = dx;
    cur->dy = dy;
    cur->dz = dz;
    cur->t = 0;
    int nl = (int)fp[FP_F_NLEVELS];
    cur->walk = fp[FP_F_HAS_MAP] != 0 && (int)fp[FP_F_MODE] == 0 && lvi[FP_LI_APPROX] >= 0 &&
                !(fp[FP_F_LOD_BOUND] > 0) && !(fp[FP_F_FOOTPRINT] > 0) &&
                (nl < 2 || fp[FP_F_LOD_MU] >= 1) && isinf(fp[FP_F_OD_MAX]);
    cur->w.live = 0;
    cur->wt = 0;
    cur->piece = 0;
    cur->ncut = 0;
    if (!cur->walk)
        return;
    fp_fogmap_path(fp, ox, oy, oz, dx, dy, dz, len, &cur->p, &cur->a, &cur->b);
    cur->ncut = fp_clamp_cuts(fp, &cur->p, cur->a, cur->b, cur->cuts);
}

/* The optical depth over [cur->t, t1] (0 when t1 <= cur->t); the cursor
 * moves to t1.  t1 may be infinite: to where fp_fog_od of the whole ray
 * stops (its cap measured from the ray's start, so that the stretches of a
 * ray add up to fp_fog_od of the ray). */
FP_FN fp_real fp_fog_cur_advance(fp_fog_cur_t *cur, FP_CONSTANT const fp_real *fp,
                                 FP_CONSTANT const int *lvi, FP_CONSTANT const fp_real *lvf,
                                 FP_GLOBAL const float *coef, FP_GLOBAL const unsigned char *occ,
                                 fp_real t1)
{
    fp_real t = cur->t;
    if (!(t1 > t))
        return 0;
    cur->t = t1;
    fp_real px = cur->ox + t * cur->dx, py = cur->oy + t * cur->dy, pz = cur->oz + t * cur->dz;
    if (!cur->walk)
        return fp_fog_od(fp, lvi, lvf, coef, occ, px, py, pz, cur->dx, cur->dy, cur->dz, t1 - t,
                         0);
    fp_real od = fp_height_od(fp[FP_F_HAZE], fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2],
                              fp[FP_F_HAZE + 3], py, cur->dy, t1 - t);
    fp_real lo = fmax(t, cur->a), hi = fmin(t1, cur->b);
    if (isinf(hi))
        hi = fmax(lo, fp_fogmap_cap(fp, &cur->p, cur->a));
    int L = (int)fp[FP_F_NLEVELS] - 1, d = (int)fp[FP_F_DEGREE];
    fp_lod_t lod;
    lod.bound = 0;
    lod.spent = 0;
    lod.sigma = fp[FP_F_SIGMA];
    lod.wdone = 0;
    lod.wtot = 1;
    fp_real sum = 0;
    for (int guard = 0; lo < hi && guard < 16; guard++) {
        /* The clamp piece that holds lo (one piece without clamp). */
        int piece = cur->piece;
        while (piece + 2 < cur->ncut && cur->cuts[piece + 1] <= lo)
            piece++;
        fp_real pa = cur->cuts[piece], pb = fmin(hi, cur->cuts[piece + 1]);
        if (piece != cur->piece || !cur->w.live) {
            cur->q = cur->p;
            /* Any point of the piece tells which side of the box it is. */
            if ((int)fp[FP_F_WRAP] == 1)
                fp_clamp_piece(fp, &cur->p, pa, isinf(pb) ? pa + 1 : pb, &cur->q);
            cur->piece = piece;
            cur->w.live = 0;
        }
        /* Resumed where the last stretch left off, else from lo afresh. */
        cur->w.live = cur->w.live && cur->wt == lo;
        fp_real te;
        int Ln;
        sum += fp_grid_walk_any(fp, lvi, lvf, coef, d, L, 0, &cur->q, lo, pb, 0, FP_INF, &lod,
                                &cur->w, &te, &Ln);
        cur->wt = te;
        lo = te > lo ? te : pb;
    }
    return od + fp[FP_F_SIGMA] * sum;
}

#endif

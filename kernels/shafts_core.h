/* fogpipe: the sun's light in the fog along one view ray, exact for the
 * shadow map (issue 13), shared by the OpenCL kernel (scatter.cl, float)
 * and the C reference (filters/scatter.c, double).  Include after
 * fog_core.h and light_core.h, before scatter_core.h's ray function.
 *
 * The sun's part of the in-scatter is
 *   S_sun = albedo E p(mu) int_ta^tb sigma(t) tau(0,t) V(t) tau_sun(t) dt.
 * The sun's map is orthographic, so along the view ray the map's texel
 * coordinates and its depth z(t) are affine in t: the texels the ray's
 * projection crosses are walked in order (a DDA), and within each the
 * point is lit where z(t) <= zb (the texel's depth plus its bias), a
 * prefix or a suffix of the texel's stretch.  The visibility V(t) is thus
 * known exactly, as runs of lit and shadowed stretches; a min-max pyramid
 * of the map crosses long runs (blocks entirely in front of or behind the
 * ray) in one step.  Nothing is sampled: a shaft one texel wide is found.
 *
 * The integrand over a lit run is the derivative of
 *   C(t) = int_0^t sigma tau tau_sun,
 * so S_sun/(albedo E p) = sum over lit runs of C(b) - C(a).  Where the fog
 * depends on height alone (no fogmap, a box without sides), the sun's
 * optical depth s at a point of the ray is affine in the camera's optical
 * depth u there: s(t) = s0 + r u(t), r = -d_y / l_y, for any profile
 * sigma(y) (both are integrals of sigma(y) over the same heights, divided
 * by the rays' vertical speeds), so C is a closed form of u:
 *   C(t) = e^-s0 (1 - e^{-(1 + r) u}) / (1 + r),
 * exact with fog self-shadowing included.  Otherwise (a fogmap, a box with
 * sides) C is carried along the ray: each step's optical depth exact, the
 * sun's optical depth taken linear in u within it (so the sun's
 * transmittance exponential: exact where it is affine), steps of at most
 * 1/FP_SHAFT_STEPS of the ray halved where the transmittance changes;
 * exact without self-shadowing.
 *
 * Filtering (--shadow-filter R): the visibility ramps linearly over R
 * texels' worth of the ray around each end of a run, never more than half
 * of either neighbouring run, so a shadow keeps its dark core and no light
 * is moved behind a caster.  int ramp dC = C(e + h) - avg C over the ramp,
 * the average by Simpson's rule. */
#ifndef FP_SHAFTS_CORE_H
#define FP_SHAFTS_CORE_H

/* Pyramid level L (1..levels) of the packed map (fp_shafts_build in
 * filters/shafts.c): after the W x H biased depths, per level bounds of
 * the residual r = zb - (ga U + gb V) over 2^L x 2^L blocks (ga, gb: the
 * ground plane, FP_LT_SM_GA/GB; below the least and above the largest
 * over every point of the block's texels), (W + 2^L - 1) >> L blocks a
 * row, up to the level of one block.  Level ground is a constant residual
 * however the low sun tilts it in the map, so a ray above it crosses
 * large blocks where the plain min-max of zb would have the ramp's whole
 * fall across the block to clear. */
/* Where C is carried: the longest step, a share of the ray (steps are
 * halved where the sun's transmittance or the fog changes). */
#define FP_SHAFT_STEPS 8

/* The precision's unit roundoff (the residual test's margin). */
#ifdef __OPENCL_VERSION__
#define FP_SHAFT_EPS FLT_EPSILON
#else
#include <float.h>
#define FP_SHAFT_EPS DBL_EPSILON
#endif

/* C(t) along one ray: the closed form, or carried along the ray. */
typedef struct {
    int layered;
    fp_real e0, k;      /* layered: e^-s0, 1 + r */
    fp_real t, u, C, T; /* carried: where, camera optical depth, C, tau_sun there */
    fp_real s;          /* carried: the sun's optical depth there (T = e^-s) */
    fp_real h, hmax, hmin;
    fp_fog_cur_t cur;   /* carried: the view ray's walk, at t */
} fp_sun_acc_t;

/* e0 (1 - e^{-k u}) / k without cancellation or overflow. */
FP_FN fp_real fp_sun_layered_C(fp_real e0, fp_real k, fp_real u)
{
    if (!(u > 0))
        return 0;
    if (isinf(u))
        return k > 0 ? e0 / k : (fp_real)FP_INF;
    fp_real x = k * u;
    if (fabs(x) < (fp_real)1e-3)
        return e0 * u * (1 - x * ((fp_real)0.5 - x * ((fp_real)1 / 6)));
    /* e^-s0 - e^-(s0 + k u): the second is e^-(u + s(t)) <= 1. */
    return (e0 - e0 * exp(-x)) / k;
}

/* C at t (t never decreases between calls on one ray). */
FP_FN fp_real fp_sun_C(fp_sun_acc_t *a, FP_CONSTANT const fp_real *fp,
                       FP_CONSTANT const int *lvi, FP_CONSTANT const fp_real *lvf,
                       FP_GLOBAL const float *coef, FP_GLOBAL const unsigned char *occ,
                       FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *grid, fp_real ox,
                       fp_real oy, fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real t)
{
    /* Closed form of u(t); u(0) = 0 without a call. */
    if (a->layered)
        return t > 0 ? fp_sun_layered_C(a->e0, a->k, fp_fog_od(fp, lvi, lvf, coef, occ, ox, oy,
                                                               oz, dx, dy, dz, t, 0))
                     : (fp_real)0;
    int self = (int)lt[FP_LT_SELF] != FP_SELF_OFF;
    /* Exact self-shadowing is followed to 1/50 of the segments' light
     * jump (1e-5 of S in the tests); the grid's own error is larger than
     * the segments'. */
    fp_real xmax = lt[FP_LT_SEG_OD];
    fp_real jmax = ((int)lt[FP_LT_SELF] == FP_SELF_EXACT ? (fp_real)0.02 : (fp_real)1) *
                   lt[FP_LT_SEG_JUMP];
    for (int guard = 0; a->t < t && guard < 4096; guard++) {
        fp_real h = fmin(a->h, t - a->t);
        fp_real t1 = h >= t - a->t ? t : a->t + h;
        /* The step's optical depth from the ray's walk, tried on a copy
         * (a refused step is halved and tried again from a->t). */
        fp_fog_cur_t cur = a->cur;
        fp_real x = fp_fog_cur_advance(&cur, fp, lvi, lvf, coef, occ, t1);
        fp_real c0 = fp_one_minus_exp(x), ea = exp(-a->u);
        if (self && x > xmax && h > a->hmin) {
            a->h = h * fmax((fp_real)0.8 * xmax / x, (fp_real)0.1);
            continue;
        }
        fp_real s1 = self ? fp_sun_od(fp, lvi, lvf, coef, occ, lt, grid, ox + t1 * dx,
                                      oy + t1 * dy, oz + t1 * dz)
                          : (fp_real)0;
        fp_real T1 = exp(-s1);
        fp_real jump = fabs(T1 - a->T) * c0 * ea;
        if (jump > jmax * fmax((fp_real)0.5 * (T1 + a->T), (fp_real)1e-12) && h > a->hmin) {
            a->h = (fp_real)0.5 * h;
            continue;
        }
        /* The sun's optical depth taken linear in the camera's within the
         * step (exact in fog of height alone, where it is affine): T e^{-v}
         * decays as e^{-k v}, k = 1 + its slope (the optical depths
         * carried, not taken back from T by log). */
        fp_real tiny = (fp_real)1e-30;
        if (a->T > tiny && T1 > tiny && x > 0) {
            fp_real k = 1 + (s1 - a->s) / x;
            a->C += ea * a->T * fp_sun_layered_C(1, k, x);
        } else {
            fp_real c1 = x > 0 ? fp_expm1_ratio(x) - exp(-x) : (fp_real)0;
            a->C += ea * (a->T * c0 + (T1 - a->T) * c1);
        }
        a->u += x;
        a->T = T1;
        a->s = s1;
        a->t = t1;
        a->cur = cur;
        if (x < (fp_real)0.25 * xmax && jump < (fp_real)0.25 * jmax * a->T)
            a->h = fmin(2 * a->h, a->hmax);
    }
    return a->C;
}

/* Runs of lit and shadowed stretches become edges; an edge is settled
 * (its ramp known) when the run after it ends. */
typedef struct {
    int lit;           /* the run in progress */
    fp_real start;     /* where it began */
    int pending;       /* an edge at `start` waits for this run's end */
    fp_real prev_len;  /* the length of the run before that edge */
    fp_real hr;        /* the filter's half-width along the ray (0: hard) */
    fp_real S;         /* sum of the settled edges and runs */
} fp_runs_t;

#define FP_SUN_ARGS                                                                             \
    a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz

/* Settle the edge at r->start, the run after it ending at `end`. */
FP_FN void fp_runs_settle(fp_runs_t *r, fp_sun_acc_t *a, FP_CONSTANT const fp_real *fp,
                          FP_CONSTANT const int *lvi, FP_CONSTANT const fp_real *lvf,
                          FP_GLOBAL const float *coef, FP_GLOBAL const unsigned char *occ,
                          FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *grid,
                          fp_real ox, fp_real oy, fp_real oz, fp_real dx, fp_real dy,
                          fp_real dz, fp_real end)
{
    fp_real e = r->start;
    fp_real h = fmin(r->hr, (fp_real)0.5 * fmin(r->prev_len, end - e));
    fp_real c;
    if (h > 0)
        c = (fp_sun_C(FP_SUN_ARGS, e - h) + 4 * fp_sun_C(FP_SUN_ARGS, e) +
             fp_sun_C(FP_SUN_ARGS, e + h)) / 6;
    else
        c = fp_sun_C(FP_SUN_ARGS, e);
    /* Into the light: the run before was dark, C(start) is subtracted. */
    r->S += r->lit ? -c : c;
    r->pending = 0;
}

/* The stretch [t0, t1] is lit or not. */
FP_FN void fp_runs_emit(fp_runs_t *r, fp_sun_acc_t *a, FP_CONSTANT const fp_real *fp,
                        FP_CONSTANT const int *lvi, FP_CONSTANT const fp_real *lvf,
                        FP_GLOBAL const float *coef, FP_GLOBAL const unsigned char *occ,
                        FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *grid, fp_real ox,
                        fp_real oy, fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real t0,
                        fp_real t1, int lit)
{
    if (!(t1 > t0) || lit == r->lit)
        return;
    /* A new edge at t0: settle the one before it (its run ends here). */
    if (r->pending)
        fp_runs_settle(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, t0);
    r->prev_len = t0 - r->start;
    r->start = t0;
    r->lit = lit;
    r->pending = 1;
}

/* The stretch [t0, t1] is lit by the map or not, and shadowed where the
 * walk over the depth buffer says (--shadows map+screen: the sorted,
 * disjoint intervals iv[0..n), *k the first that may still matter; the
 * stretches come in order along the ray): the product of the two
 * visibilities. */
FP_FN void fp_runs_emit_vis(fp_runs_t *r, fp_sun_acc_t *a, FP_CONSTANT const fp_real *fp,
                            FP_CONSTANT const int *lvi, FP_CONSTANT const fp_real *lvf,
                            FP_GLOBAL const float *coef, FP_GLOBAL const unsigned char *occ,
                            FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *grid,
                            fp_real ox, fp_real oy, fp_real oz, fp_real dx, fp_real dy,
                            fp_real dz, fp_real t0, fp_real t1, int lit, const fp_real *iv,
                            int n, int *k)
{
    if (!lit || n == 0) {
        fp_runs_emit(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, t0, t1, lit);
        return;
    }
    while (*k < n && iv[2 * *k + 1] <= t0)
        (*k)++;
    fp_real t = t0;
    for (int j = *k; j < n && iv[2 * j] < t1; j++) {
        fp_real s0 = fmax(iv[2 * j], t), s1 = fmin(iv[2 * j + 1], t1);
        if (!(s1 > s0))
            continue;
        fp_runs_emit(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, t, s0, 1);
        fp_runs_emit(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, s0, s1, 0);
        t = s1;
    }
    fp_runs_emit(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, t, t1, 1);
}

/* The accumulator of C along one ray, from ta. */
FP_FN void fp_sun_acc_init(fp_sun_acc_t *a, FP_CONSTANT const fp_real *fp,
                           FP_CONSTANT const int *lvi, FP_CONSTANT const fp_real *lvf,
                           FP_GLOBAL const float *coef, FP_GLOBAL const unsigned char *occ,
                           FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *grid,
                           fp_real ox, fp_real oy, fp_real oz, fp_real dx, fp_real dy,
                           fp_real dz, fp_real ta, int layered, fp_real h0)
{
    FP_CONSTANT const fp_real *l = lt + FP_LT_SUN_DIR;
    a->layered = layered;
    a->e0 = 1;
    a->k = 1;
    if (layered && (int)lt[FP_LT_SELF] != FP_SELF_OFF) {
        a->e0 = exp(-fp_fog_od(fp, lvi, lvf, coef, occ, ox, oy, oz, l[0], l[1], l[2], FP_INF, 0));
        a->k = 1 - dy / l[1];
    }
    /* Carried: from ta, where the camera's optical depth is computed once,
     * by the walk that then goes on along the ray (fp_fog_cur_t). */
    a->t = ta;
    a->u = 0;
    if (!layered) {
        fp_fog_cur_init(&a->cur, fp, lvi, ox, oy, oz, dx, dy, dz, FP_INF);
        a->u = fp_fog_cur_advance(&a->cur, fp, lvi, lvf, coef, occ, ta);
    }
    a->C = 0;
    a->s = !layered && (int)lt[FP_LT_SELF] != FP_SELF_OFF
               ? fp_sun_od(fp, lvi, lvf, coef, occ, lt, grid, ox + ta * dx, oy + ta * dy,
                           oz + ta * dz)
               : 0;
    a->T = exp(-a->s);
    a->hmax = h0;
    a->h = h0;
    a->hmin = h0 * (fp_real)(1.0 / 256);
}

/* Start the runs at ta (lit). */
FP_FN void fp_runs_init(fp_runs_t *r, fp_sun_acc_t *a, FP_CONSTANT const fp_real *fp,
                        FP_CONSTANT const int *lvi, FP_CONSTANT const fp_real *lvf,
                        FP_GLOBAL const float *coef, FP_GLOBAL const unsigned char *occ,
                        FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *grid, fp_real ox,
                        fp_real oy, fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real ta,
                        fp_real hr)
{
    r->lit = 1;
    r->start = ta;
    r->pending = 0;
    r->prev_len = 0;
    r->hr = hr;
    r->S = -fp_sun_C(FP_SUN_ARGS, ta);
}

/* The last run, to tb; returns the sun's share. */
FP_FN fp_real fp_runs_finish(fp_runs_t *r, fp_sun_acc_t *a, FP_CONSTANT const fp_real *fp,
                             FP_CONSTANT const int *lvi, FP_CONSTANT const fp_real *lvf,
                             FP_GLOBAL const float *coef, FP_GLOBAL const unsigned char *occ,
                             FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *grid,
                             fp_real ox, fp_real oy, fp_real oz, fp_real dx, fp_real dy,
                             fp_real dz, fp_real tb, fp_real od_total)
{
    if (r->pending)
        fp_runs_settle(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, tb);
    if (r->lit) {
        /* Closed form: u(tb) is the ray's whole optical depth (no fog
         * beyond the span's end), known already. */
        r->S += a->layered ? fp_sun_layered_C(a->e0, a->k, od_total) : fp_sun_C(FP_SUN_ARGS, tb);
        /* Carried to where the fog stopped mattering (an unbounded ray):
         * the rest of the fog with the light of the last point. */
        if (!a->layered)
            r->S += a->T * fmax(exp(-a->u) - exp(-od_total), (fp_real)0);
    }
    return r->S;
}

/* The sun's share along the ray over [ta, tb] (tb may be infinite where
 * the closed form applies), without albedo, E and the phase function:
 * int sigma tau V tau_sun dt.  h0: the longest step where C is carried;
 * od_total the ray's whole optical depth (what lies beyond a carried tb);
 * iv[0..niv): the stretches the depth buffer's walk shadows besides the
 * map (--shadows map+screen; niv 0 otherwise). */
FP_FN fp_real fp_shafts_sun(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                            FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                            FP_GLOBAL const unsigned char *occ, FP_CONSTANT const fp_real *lt,
                            FP_GLOBAL const float *smap, FP_GLOBAL const float *grid,
                            fp_real ox, fp_real oy, fp_real oz, fp_real dx, fp_real dy,
                            fp_real dz, fp_real ta, fp_real tb, int layered, fp_real h0,
                            fp_real od_total, const fp_real *iv, int niv)
{
    fp_sun_acc_t acc, *a = &acc;
    fp_sun_acc_init(a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, ta, layered, h0);
    int kiv = 0;

    /* The map's texel coordinates and depth along the ray: affine. */
    FP_CONSTANT const fp_real *m = lt + FP_LT_SM_NDC;
    FP_CONSTANT const fp_real *cz = lt + FP_LT_SM_Z;
    int W = (int)lt[FP_LT_SM_W], H = (int)lt[FP_LT_SM_H], NL = (int)lt[FP_LT_SM_LEVELS];
    fp_real U0 = (ox * m[0] + oy * m[4] + oz * m[8] + m[12]) * W;
    fp_real dU = (dx * m[0] + dy * m[4] + dz * m[8]) * W;
    fp_real V0 = (ox * m[1] + oy * m[5] + oz * m[9] + m[13]) * H;
    fp_real dV = (dx * m[1] + dy * m[5] + dz * m[9]) * H;
    fp_real Z0 = ox * cz[0] + oy * cz[1] + oz * cz[2] + cz[3];
    fp_real dZ = dx * cz[0] + dy * cz[1] + dz * cz[2];
    /* The ray's residual R(t) = z(t) - ga U(t) - gb V(t), affine too,
     * tested against the pyramid's bounds with a margin for its rounding
     * (rm: a few units in the last place of the terms' sizes over the
     * map's stretch), so that a block taken as lit or shadowed is so for
     * every texel of it by the level-0 test itself. */
    fp_real ga = lt[FP_LT_SM_GA], gb = lt[FP_LT_SM_GB];
    fp_real R0 = Z0 - ga * U0 - gb * V0, dR = dZ - ga * dU - gb * dV;

    fp_runs_t runs, *r = &runs;
    fp_real tex = fmax(fabs(dU), fabs(dV));
    fp_runs_init(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, ta,
                 tex > 0 ? lt[FP_LT_SM_RADIUS] / tex : (fp_real)FP_INF);
#define FP_EMIT(t0, t1, lit)                                                                    \
    fp_runs_emit_vis(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, t0, t1, lit, \
                     iv, niv, &kiv)

    /* The map's rectangle: outside it everything is lit. */
    fp_real ma = ta, mb = tb;
    fp_clip(U0, dU, 0, (fp_real)W, &ma, &mb);
    fp_clip(V0, dV, 0, (fp_real)H, &ma, &mb);
    if (mb > ma) {
        fp_real t = ma;
        fp_real rm = (fp_real)(16 * FP_SHAFT_EPS) *
                     (fabs(Z0) + fabs(ga * U0) + fabs(gb * V0) +
                      fmax(fabs(ma), fabs(mb)) * (fabs(dZ) + fabs(ga * dU) + fabs(gb * dV)));
        rm = rm < FP_INF ? rm : (fp_real)FP_INF;
        int ix = (int)fmin(fmax(floor(U0 + t * dU), (fp_real)0), (fp_real)(W - 1));
        int iy = (int)fmin(fmax(floor(V0 + t * dV), (fp_real)0), (fp_real)(H - 1));
        /* Four levels below the top (blocks a sixteenth of the map's
         * side): the blocks about the ray's start hold what stands near
         * it (the camera's own surroundings), and a start at the top
         * fails down to there on most rays (the walk climbs back where it
         * may: 17 steps a ray instead of 20 on the sample scene). */
        int L = NL > 4 ? NL - 4 : 0;
        int offs[FP_SM_MAX_LEVELS + 1];
        fp_pyr_offsets(W, H, NL, offs);
        int guard = 16 * (W + H) + 64;
        while (t < mb && guard-- > 0) {
            int s = 1 << L;
            int bi = ix >> L, bj = iy >> L;
            fp_real tX = dU > 0 ? ((fp_real)((bi + 1) * s) - U0) / dU
                         : dU < 0 ? ((fp_real)(bi * s) - U0) / dU : (fp_real)FP_INF;
            fp_real tY = dV > 0 ? ((fp_real)((bj + 1) * s) - V0) / dV
                         : dV < 0 ? ((fp_real)(bj * s) - V0) / dV : (fp_real)FP_INF;
            /* Comparisons, not fmin/fmax: nothing here is NaN. */
            fp_real t1 = tX < tY ? tX : tY;
            t1 = t1 < mb ? t1 : mb;
            t1 = t1 > t ? t1 : t;
            if (L == 0) {
                fp_real za = Z0 + t * dZ;
                fp_real zb1 = dZ == 0 ? Z0 : Z0 + t1 * dZ;
                fp_real zlo = fmin(za, zb1), zhi = fmax(za, zb1);
                fp_real zm = smap[iy * W + ix];
                if (zhi <= zm) {
                    FP_EMIT(t, t1, 1);
                } else if (zlo > zm) {
                    FP_EMIT(t, t1, 0);
                } else {
                    /* z(tc) = zm within the stretch: lit before it when z rises. */
                    fp_real tc = fmin(fmax((zm - Z0) / dZ, t), t1);
                    FP_EMIT(t, tc, dZ > 0);
                    FP_EMIT(tc, t1, dZ < 0);
                }
            } else {
                int wl = (W + s - 1) >> L;
                int o = offs[L] + 2 * (bj * wl + bi);
                fp_real mn = smap[o], mx = smap[o + 1];
                fp_real ra = R0 + t * dR, rb = dR == 0 ? R0 : R0 + t1 * dR;
                if ((ra > rb ? ra : rb) + rm <= mn) {
                    FP_EMIT(t, t1, 1);
                } else if ((ra < rb ? ra : rb) - rm > mx) {
                    FP_EMIT(t, t1, 0);
                } else {
                    L--;
                    continue;
                }
            }
            if (t1 >= mb) {
                t = mb;
                break;
            }
            fp_pyr_next(&ix, &iy, bi, bj, s, tX <= tY, U0, V0, dU, dV, t1);
            iy = iy < 0 ? 0 : iy > H - 1 ? H - 1 : iy;
            ix = ix < 0 ? 0 : ix > W - 1 ? W - 1 : ix;
            t = t1;
            /* Up a level only into a parent block entered at its start
             * (the one face crossed is also the parent's): a parent
             * entered halfway holds the stretch behind, and its test
             * fails more often than the block beside. */
            int xf = tX <= tY, nb = xf ? ix >> L : iy >> L;
            if (L < NL && (nb & 1) == ((xf ? dU : dV) > 0 ? 0 : 1))
                L++;
        }
        /* Left the map (or the guard ran out): lit on from there. */
        if (t < mb)
            FP_EMIT(t, mb, 1);
    }
    FP_EMIT(mb > ma ? mb : ta, tb, 1);
#undef FP_EMIT
    return fp_runs_finish(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, tb,
                          od_total);
}
#undef FP_SUN_ARGS

/* The stretches of the view ray over [ta, tb] that the walk over the
 * depth buffer shadows (fp_ss_walk, kernels/light_core.h, over zpyr: the
 * depth buffer's scene z and its pyramid, its size and pixels in lt,
 * which the view traced need not share): sorted, disjoint, into iv;
 * returns their count. */
FP_FN int fp_shafts_screen_iv(FP_CONSTANT const fp_real *lt, FP_CONSTANT const float *view,
                              FP_GLOBAL const float *zpyr, fp_real ox, fp_real oy, fp_real oz,
                              fp_real dx, fp_real dy, fp_real dz, fp_real ta, fp_real tb,
                              fp_real *iv)
{
    /* Shadows reach only as far as the scene: beyond the deepest z it could
     * hold plus THICK and DIST, every sun ray is past it (the walk needs a
     * finite stretch). */
    FP_CONSTANT const fp_real *m = lt + FP_LT_SS_M;
    fp_real dzc = m[6] * dx + m[7] * dy + m[8] * dz;
    fp_real czo = m[6] * (ox - view[0]) + m[7] * (oy - view[1]) + m[8] * (oz - view[2]);
    fp_real reach = lt[FP_LT_SS_ZMAX] + lt[FP_LT_SS_THICK] + lt[FP_LT_SS_DIST];
    fp_real tw = dzc > 0 ? fmin(tb, fmax((reach - czo) / dzc, ta)) : tb;
    /* The ray's pixel in the depth buffer: where a point of it projects. */
    FP_CONSTANT const fp_real *h = lt + FP_LT_SS_H;
    fp_real c[3], nn[3], q1[3] = { ox + dx - view[0], oy + dy - view[1], oz + dz - view[2] };
    for (int k = 0; k < 3; k++)
        c[k] = m[3 * k] * q1[0] + m[3 * k + 1] * q1[1] + m[3 * k + 2] * q1[2];
    fp_ss_ndc(h, c, view[FP_VIEW_ORTHO] != 0, 1, nn);
    fp_real px = fp_ss_pixel(lt, nn, 0), py = fp_ss_pixel(lt, nn, 1);
    int n = isinf(tw) || !(c[2] > 0)
                ? 0
                : fp_ss_walk(lt, view, zpyr, ox, oy, oz, dx, dy, dz, ta, tw, px, py, 0, iv);
    /* Clipped to [ta, tb]. */
    int m2 = 0;
    for (int k = 0; k < n; k++) {
        fp_real s0 = fmax(iv[2 * k], ta), s1 = fmin(iv[2 * k + 1], tb);
        if (!(s1 > s0))
            continue;
        iv[2 * m2] = s0;
        iv[2 * m2 + 1] = s1;
        m2++;
    }
    return m2;
}

/* The sun's share along a view ray under --shadows screen: the runs from
 * the walk's intervals (fp_shafts_screen_iv), C as for the map. */
FP_FN fp_real fp_shafts_screen(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                               FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                               FP_GLOBAL const unsigned char *occ, FP_CONSTANT const fp_real *lt,
                               FP_GLOBAL const float *grid, FP_CONSTANT const float *view,
                               FP_GLOBAL const float *zpyr,
                               fp_real ox, fp_real oy, fp_real oz, fp_real dx,
                               fp_real dy, fp_real dz, fp_real ta, fp_real tb, int layered,
                               fp_real h0, fp_real od_total)
{
    fp_sun_acc_t acc, *a = &acc;
    fp_sun_acc_init(a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, ta, layered, h0);
    fp_runs_t runs, *r = &runs;
    fp_runs_init(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, ta, 0);
    fp_real iv[2 * FP_SS_MAX_IV];
    int n = fp_shafts_screen_iv(lt, view, zpyr, ox, oy, oz, dx, dy, dz, ta, tb, iv);
    fp_real t = ta;
    for (int k = 0; k < n; k++) {
        fp_runs_emit(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, t, iv[2 * k],
                     1);
        fp_runs_emit(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, iv[2 * k],
                     iv[2 * k + 1], 0);
        t = iv[2 * k + 1];
    }
    fp_runs_emit(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, t, tb, 1);
    return fp_runs_finish(r, a, fp, lvi, lvf, coef, occ, lt, grid, ox, oy, oz, dx, dy, dz, tb,
                          od_total);
}

/* S += w E_sun times the sun's share: the shadow map's walk, the depth
 * buffer's (--shadows screen), or both (map+screen: the map's walk with
 * the depth buffer's shadowed stretches taken out of its lit runs, so a
 * caster the map is too coarse for but the camera sees still shadows,
 * and one outside the frame still shadows through the map). */
FP_FN void fp_shafts_add(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                         FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                         FP_GLOBAL const unsigned char *occ, FP_CONSTANT const fp_real *lt,
                         FP_GLOBAL const float *smap, FP_GLOBAL const float *grid,
                         FP_CONSTANT const float *view, FP_GLOBAL const float *depth, int width,
                         int height, fp_real ox, fp_real oy, fp_real oz, fp_real dx, fp_real dy,
                         fp_real dz, fp_real ta, fp_real tb, int layered, fp_real h0,
                         fp_real od_total, fp_real w, fp_real *S)
{
    int mode = (int)lt[FP_LT_SHADOWS];
    fp_real sun;
    if (mode == FP_SHADOWS_SCREEN) {
        sun = fp_shafts_screen(fp, lvi, lvf, coef, occ, lt, grid, view, smap, ox, oy, oz, dx, dy,
                               dz, ta, tb, layered, h0, od_total);
    } else {
        fp_real iv[2 * FP_SS_MAX_IV];
        int niv = mode == FP_SHADOWS_MAP_SCREEN
                      ? fp_shafts_screen_iv(lt, view, fp_ss_zpyr(lt, smap), ox, oy, oz, dx, dy,
                                            dz, ta, tb, iv)
                      : 0;
        sun = fp_shafts_sun(fp, lvi, lvf, coef, occ, lt, smap, grid, ox, oy, oz, dx, dy, dz, ta,
                            tb, layered, h0, od_total, iv, niv);
    }
    for (int c = 0; c < 3; c++)
        S[c] += w * sun * lt[FP_LT_SUN_E + c];
}

#endif

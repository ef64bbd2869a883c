/* fogpipe: the Monte Carlo reference (seed 004), written once and compiled
 * twice like fog_core.h: as OpenCL C in single precision
 * (kernels/reference.cl) and as C in double precision (filters/reference.c,
 * the version the tests drive).
 *
 * It estimates the same fog layer as the deterministic integrator
 * (scatter_core.h), from the model's definition only:
 *   tau = exp(-int_0^len sigma_t),
 *   S   = int_0^len tau(O,u) sigma_s(u) [ L_amb
 *             + sum_k E_k(u) p(theta_k) V_k(u) tau_k(u) ] du,
 * with sigma_t the point extinction fp_sigma_t() (never fp_fog_od):
 *   - tau: ratio tracking along the view ray;
 *   - S: a free flight along the view ray by delta tracking (the point u
 *     with density tau(O,u) sigma_t(u)), and at a real collision
 *     albedo (L_amb + next-event estimates): the sun E_sun p V tau_sun (V
 *     the geometry visibility lookup, tau_sun by ratio tracking to where
 *     the fog ends), each local light I / r^2 cone p tau (ratio tracking
 *     over r).  With --bounces N, N more vertices: a direction drawn from
 *     the phase function (weight albedo, pdf = p), a free flight, and the
 *     same estimates there.
 *
 * The majorants.  sigma_t = sigma F(x,z) h(y) + haze hh(y) (fog_core.h):
 * the fogmap surface F varies across, the height profiles h, hh along y.
 * The majorant grid (filters/reference.c builds it) holds per axis-aligned
 * world cell the bounds Fmin <= F <= Fmax over the cell's footprint on the
 * fogmap (a convex combination of the fine coefficients whose support
 * reaches it); outside the grid the fogmap's global bounds hold, and
 * without a fogmap F = 1 and there is no grid.  A walk along a ray (3D DDA
 * through the grid) yields segments cut at cell faces, where the main fog
 * or the haze begin or end (box, top, clip rectangle), and where the
 * height has changed by a fraction of the smallest scale height; on each
 *   mu   = sigma Fmax h(y_low) + haze hh(y_low)      >= sigma_t,
 *   c(x) = sigma Fmin h(y) + haze hh(y)              <= sigma_t,
 *   r    = sigma (Fmax - Fmin) h(y_low)              >= sigma_t - c,
 * (h is non-increasing, y_low the segment's lowest point).
 *   - Free flights: decomposition tracking (Kutz et al. 2017), delta
 *     tracking split in two: the collisions with the control part c and
 *     with the residual sigma_t - c are independent processes; the first
 *     is sampled exactly by inverting c's closed-form integral, the second
 *     by delta tracking against r (tentative collisions at rate r,
 *     accepted with probability (sigma_t - c) / r); the flight ends at the
 *     earlier.  Without a fogmap r = 0: every flight is an exact
 *     inversion.  With FP_RP_CONTROL 0, plain delta tracking against mu.
 *   - Ratio tracking is residual ratio tracking (Novak et al. 2014) with
 *     the same control: T = exp(-int c) prod (1 - (sigma_t - c) / r) over
 *     tentative collisions at rate r.  Unbiased for any fog; where F is
 *     constant (no fogmap, or a constant patch) r = 0 and it is exact.
 *     With FP_RP_CONTROL 0, plain ratio tracking against mu.
 * The first free flight of sample s of a pixel takes its two uniforms
 * (the control's distance, the first residual acceptance) from the
 * (0,2)-sequence (van der Corput, Sobol' 2nd dimension) at index s,
 * Cranley-Patterson rotated per pixel and seed: each uniform alone is
 * exact, so the estimate stays unbiased, and over the pixel's samples the
 * scattering points along the view ray are stratified (without a fogmap,
 * perfectly: the sun's visibility and the lights are deterministic
 * lookups, so what remains is a stratified quadrature of a 1D integral).
 * Every other uniform comes from fp_rng_seed(seed, pixel, sample). */
#ifndef FP_REFERENCE_CORE_H
#define FP_REFERENCE_CORE_H

#include "fog_core.h"
#include "light_core.h"
#include "lamp_shadow_core.h"

/* Layout of the reference's parameter array (filters/reference.c). */
#define FP_RP_LO 0          /* 3: the grid's lower corner, fog space */
#define FP_RP_CELL 3        /* 3: cell size */
#define FP_RP_N 6           /* 3: cells along x, y, z (0: no grid) */
#define FP_RP_FMAX 9        /* bounds of F outside the grid (1 without a fogmap) */
#define FP_RP_FMIN 10
#define FP_RP_BOUNCES 11    /* scattering events after the first */
#define FP_RP_CONTROL 12    /* 1: decomposition and residual ratio tracking with the
                               control c; 0: plain delta and ratio tracking */
#define FP_RP_STRATIFY 13   /* 1: first free flight from the rotated (0,2)-sequence */
#define FP_RP_SOLID 14      /* step of the march for the geometry along scattered
                               paths, scene units (0: paths cross all geometry) */
#define FP_RP_CAM_INV 16    /* 9: camera vector = CAM_INV (fog point - camera) */
#define FP_RP_NDC_INV 25    /* 9: NDC (homogeneous) = NDC_INV (x/z, y/z, 1) */
#define FP_RP_COUNT 40

/* Relative margin of the majorants computed on the fly: float rounding of
 * sigma_t must not step over them. */
#define FP_REF_UP ((fp_real)1.000001)
/* Russian roulette on a transmittance weight below this (unbiased). */
#define FP_REF_RR ((fp_real)1e-3)
/* Guards against pathological inputs (a walk that never ends). */
#define FP_REF_MAX_SEGMENTS 65536
#define FP_REF_MAX_EVENTS (1 << 20)
/* Largest rise or fall of a segment where a height profile changes, in
 * smallest scale heights: for plain tracking against mu (the majorant's
 * slack), and with the control and a fogmap (the residual bound's); with
 * the control and no fogmap there is no residual and no limit. */
#define FP_REF_STEP_PLAIN ((fp_real)0.125)
#define FP_REF_STEP_RESIDUAL ((fp_real)0.5)

/* The haze's height profile (fp_h is the main fog's, in fog-local y). */
FP_FN fp_real fp_ref_hhaze(FP_CONSTANT const fp_real *fp, fp_real y)
{
    if (y >= fp[FP_F_HAZE + 3])
        return 0;
    return y < fp[FP_F_HAZE + 1] ? (fp_real)1 : exp(-(y - fp[FP_F_HAZE + 1]) / fp[FP_F_HAZE + 2]);
}

/* int_a^b h(y0 + t dy) dt for the profile h = 1 below Y0, exp(-(y - Y0)/H)
 * from Y0 up to TOP, 0 above (b may be INF), in closed form: the flat part
 * by its length, the exponential part as (b - a) e^-m (1 - e^-D) / D with
 * m its lowest point and D its rise, both in scale heights. */
FP_FN fp_real fp_ref_profile(fp_real Y0, fp_real H, fp_real TOP, fp_real y0, fp_real dy,
                             fp_real a, fp_real b)
{
    fp_real sum = 0, lo, hi;
    if (!(b > a))
        return 0;
    fp_real ya = y0 + a * dy, len = b - a;
    if (fp_slab(ya, dy, -FP_INF, fmin(Y0, TOP), len, &lo, &hi))
        sum += hi - lo;
    if (fp_slab(ya, dy, Y0, TOP, len, &lo, &hi)) {
        fp_real yl = (ya + lo * dy - Y0) / H;
        if (isinf(hi))
            sum += dy > 0 ? exp(-yl) * H / dy : FP_INF;
        else {
            fp_real D = fabs(dy) * (hi - lo) / H;
            fp_real m = dy < 0 ? yl - D : yl;
            sum += (hi - lo) * exp(-m) * fp_expm1_ratio(D);
        }
    }
    return sum;
}

/* Where the fog ends along o + t d within [0, len]: the end of the main
 * fog's and the haze's stretches; an unbounded stretch ends where its
 * height profile has died out (40 scale heights up, as fp_fogmap_od), or
 * after the fogmap's CAP; else it stays unbounded (homogeneous fog seen
 * level or downward: the trackers end it).  -INF: no fog at all. */
FP_FN fp_real fp_ref_fog_end(FP_CONSTANT const fp_real *fp, fp_real ox, fp_real oy, fp_real oz,
                             fp_real dx, fp_real dy, fp_real dz, fp_real len)
{
    fp_real end = -FP_INF, a, b;
    if (fp_main_span(fp, ox, oy, oz, dx, dy, dz, FP_INF, &a, &b)) {
        if (isinf(b)) {
            if (dy > 0 && isfinite(fp[FP_F_H]))
                b = fmax(a, (fp[FP_F_Y0] + 40 * fp[FP_F_H] - (oy - fp[FP_F_OFF + 1])) / dy);
            else if (fp[FP_F_HAS_MAP] != 0)
                b = a + fp[FP_F_CAP];
        }
        end = fmax(end, b);
    }
    if (fp_haze_span(fp, oy, dy, FP_INF, &a, &b)) {
        if (isinf(b) && dy > 0 && isfinite(fp[FP_F_HAZE + 2]))
            b = fmax(a, (fp[FP_F_HAZE + 1] + 40 * fp[FP_F_HAZE + 2] - oy) / dy);
        end = fmax(end, b);
    }
    return fmin(end, len);
}

/* ------------------------------------------------------------ the walk */

typedef struct fp_ref_walk_t {
    fp_real o[3], d[3];
    fp_real t, tend;          /* where the walk is, where it ends (may be INF) */
    fp_real g0, g1;           /* the ray's stretch in the grid */
    fp_real ma, mb, ha, hb;   /* the main fog's and the haze's stretches */
    int mon, hon;
    fp_real hstep;            /* largest rise or fall of a segment ... */
    fp_real ylo, yhi;         /* ... where a height profile still changes */
    int phase;                /* 0 before the grid, 1 in it, 2 after it */
    int c[3], step[3];
    fp_real next[3], delta[3];
    int guard;
    /* The current segment: [s0, s1], the majorant mu, the control's
     * factors (c = cm h(y - off_y) + ch hh(y)) and the residual's bound. */
    fp_real s0, s1, mu, cm, ch, r;
} fp_ref_walk_t;

/* `step`: the largest rise of a segment in smallest scale heights (INF:
 * none). */
FP_FN void fp_ref_walk_init(fp_ref_walk_t *w, FP_CONSTANT const fp_real *fp,
                            FP_CONSTANT const fp_real *rp, fp_real ox, fp_real oy, fp_real oz,
                            fp_real dx, fp_real dy, fp_real dz, fp_real t0, fp_real tend,
                            fp_real step)
{
    w->o[0] = ox;
    w->o[1] = oy;
    w->o[2] = oz;
    w->d[0] = dx;
    w->d[1] = dy;
    w->d[2] = dz;
    w->t = t0;
    w->tend = tend;
    w->mon = fp_main_span(fp, ox, oy, oz, dx, dy, dz, FP_INF, &w->ma, &w->mb);
    w->hon = fp_haze_span(fp, oy, dy, FP_INF, &w->ha, &w->hb);
    fp_real hs = FP_INF, lo = FP_INF, hi = -FP_INF;
    if (w->mon && isfinite(fp[FP_F_H])) {
        hs = fmin(hs, fp[FP_F_H]);
        lo = fmin(lo, fp[FP_F_Y0] + fp[FP_F_OFF + 1]);
        hi = fmax(hi, fp[FP_F_Y0] + fp[FP_F_OFF + 1] + 40 * fp[FP_F_H]);
    }
    if (w->hon && isfinite(fp[FP_F_HAZE + 2])) {
        hs = fmin(hs, fp[FP_F_HAZE + 2]);
        lo = fmin(lo, fp[FP_F_HAZE + 1]);
        hi = fmax(hi, fp[FP_F_HAZE + 1] + 40 * fp[FP_F_HAZE + 2]);
    }
    w->hstep = step * hs;
    w->ylo = lo;
    w->yhi = hi;
    fp_real a = t0, b = tend;
    int grid = rp[FP_RP_N] >= 1 && rp[FP_RP_N + 1] >= 1 && rp[FP_RP_N + 2] >= 1;
    for (int i = 0; i < 3 && grid; i++)
        fp_clip(w->o[i], w->d[i], rp[FP_RP_LO + i],
                rp[FP_RP_LO + i] + rp[FP_RP_N + i] * rp[FP_RP_CELL + i], &a, &b);
    if (grid && b > a) {
        w->g0 = a;
        w->g1 = b;
    } else {
        w->g0 = w->g1 = tend;
    }
    w->phase = 0;
    w->guard = 0;
    w->s0 = w->s1 = t0;
    w->mu = w->cm = w->ch = w->r = 0;
}

/* The next segment into w->s0, s1, mu, cm, ch, r; 0 at the end. */
FP_FN int fp_ref_walk_next(fp_ref_walk_t *w, FP_CONSTANT const fp_real *fp,
                           FP_CONSTANT const fp_real *rp, FP_GLOBAL const float *grid)
{
    while (w->t < w->tend) {
        if (++w->guard > FP_REF_MAX_SEGMENTS)
            return 0;
        fp_real tlim, fmx, fmn;
        int a = 0;
        if (w->phase == 0 && !(w->t < w->g0)) {
            if (!(w->g1 > w->g0)) {
                w->phase = 2;
                continue;
            }
            /* Enter the grid at g0, in the cell of the stretch's first point. */
            w->phase = 1;
            w->t = w->g0;
            for (int i = 0; i < 3; i++) {
                fp_real cell = rp[FP_RP_CELL + i], lo = rp[FP_RP_LO + i];
                int n = (int)rp[FP_RP_N + i];
                fp_real di = w->d[i];
                int k = (int)floor((w->o[i] + w->g0 * di - lo) / cell);
                k = k < 0 ? 0 : k >= n ? n - 1 : k;
                w->c[i] = k;
                w->step[i] = di > 0 ? 1 : di < 0 ? -1 : 0;
                w->next[i] = di > 0 ? (lo + (k + 1) * cell - w->o[i]) / di
                           : di < 0 ? (lo + k * cell - w->o[i]) / di : FP_INF;
                w->delta[i] = di != 0 ? cell / fabs(di) : FP_INF;
            }
        }
        if (w->phase == 1) {
            int nx = (int)rp[FP_RP_N], ny = (int)rp[FP_RP_N + 1], nz = (int)rp[FP_RP_N + 2];
            if (!(w->t < w->g1) || w->c[0] < 0 || w->c[1] < 0 || w->c[2] < 0 || w->c[0] >= nx ||
                w->c[1] >= ny || w->c[2] >= nz) {
                w->phase = 2;
                continue;
            }
            a = w->next[0] <= w->next[1] ? (w->next[0] <= w->next[2] ? 0 : 2)
                                         : (w->next[1] <= w->next[2] ? 1 : 2);
            tlim = fmax(fmin(w->next[a], w->g1), w->t);
            size_t at = 2 * (((size_t)w->c[2] * ny + w->c[1]) * nx + w->c[0]);
            fmx = grid[at];
            fmn = grid[at + 1];
        } else {
            tlim = w->phase == 0 ? w->g0 : w->tend;
            fmx = rp[FP_RP_FMAX];
            fmn = rp[FP_RP_FMIN];
        }
        /* Cut where the main fog or the haze begin or end, and where the
         * height has changed enough. */
        fp_real s0 = w->t, s1 = tlim, dy = w->d[1];
        if (w->mon) {
            if (w->ma > s0 && w->ma < s1)
                s1 = w->ma;
            if (w->mb > s0 && w->mb < s1)
                s1 = w->mb;
        }
        if (w->hon) {
            if (w->ha > s0 && w->ha < s1)
                s1 = w->ha;
            if (w->hb > s0 && w->hb < s1)
                s1 = w->hb;
        }
        fp_real ya = w->o[1] + s0 * dy;
        if (dy != 0 && isfinite(w->hstep) && !(dy > 0 && ya >= w->yhi) &&
            !(dy < 0 && ya <= w->ylo)) {
            fp_real lim = s0 + w->hstep / fabs(dy);
            if (lim > s0 && lim < s1)
                s1 = lim;
        }
        fp_real yb = isfinite(s1) ? w->o[1] + s1 * dy : dy > 0 ? FP_INF : dy < 0 ? -FP_INF : ya;
        fp_real ylo = fmin(ya, yb);
        fp_real tm = isfinite(s1) ? (fp_real)0.5 * (s0 + s1) : s0 + 1;
        w->mu = w->cm = w->ch = w->r = 0;
        if (w->mon && tm >= w->ma && tm <= w->mb) {
            fp_real sg = fp[FP_F_SIGMA], hl = fp_h(fp, ylo - fp[FP_F_OFF + 1]);
            w->mu = sg * fmx * hl;
            w->cm = sg * fmn;
            w->r = fmx > fmn ? sg * (fmx - fmn) * hl * FP_REF_UP : (fp_real)0;
        }
        if (w->hon && tm >= w->ha && tm <= w->hb) {
            w->mu += fp[FP_F_HAZE] * fp_ref_hhaze(fp, ylo);
            w->ch = fp[FP_F_HAZE];
        }
        w->mu *= FP_REF_UP;
        w->s0 = s0;
        w->s1 = s1;
        w->t = s1;
        if (w->phase == 1 && !(s1 < tlim)) {
            w->c[a] += w->step[a];
            w->next[a] += w->delta[a];
        }
        return 1;
    }
    return 0;
}

/* The control at a point of the current segment. */
FP_FN fp_real fp_ref_control(const fp_ref_walk_t *w, FP_CONSTANT const fp_real *fp, fp_real y)
{
    fp_real c = 0;
    if (w->cm > 0)
        c += w->cm * fp_h(fp, y - fp[FP_F_OFF + 1]);
    if (w->ch > 0)
        c += w->ch * fp_ref_hhaze(fp, y);
    return c;
}

/* The control's integral over the current segment, closed form. */
FP_FN fp_real fp_ref_control_od(const fp_ref_walk_t *w, FP_CONSTANT const fp_real *fp)
{
    fp_real od = 0;
    if (w->cm > 0)
        od += w->cm * fp_ref_profile(fp[FP_F_Y0], fp[FP_F_H], fp[FP_F_TOP],
                                     w->o[1] - fp[FP_F_OFF + 1], w->d[1], w->s0, w->s1);
    if (w->ch > 0)
        od += w->ch * fp_ref_profile(fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2], fp[FP_F_HAZE + 3],
                                     w->o[1], w->d[1], w->s0, w->s1);
    return od;
}

/* ------------------------------------------------------------ trackers */

FP_FN fp_real fp_ref_step(FP_CONSTANT const fp_real *fp, int control)
{
    return !control ? FP_REF_STEP_PLAIN : fp[FP_F_HAS_MAP] != 0 ? FP_REF_STEP_RESIDUAL : FP_INF;
}

#ifdef __OPENCL_VERSION__
#define FP_REF_TOL ((fp_real)1e-6)
#else
#define FP_REF_TOL ((fp_real)1e-12)
#endif

/* The point s of the current segment where the control's integral from s0
 * reaches `target` (below the segment's whole integral): safeguarded
 * Newton on the closed-form integral, whose derivative is c itself. */
FP_FN fp_real fp_ref_control_invert(fp_ref_walk_t *w, FP_CONSTANT const fp_real *fp,
                                    fp_real target)
{
    fp_real lo = w->s0, hi = w->s1, end = w->s1;
    fp_real c = fp_ref_control(w, fp, w->o[1] + lo * w->d[1]);
    fp_real s = c > 0 ? lo + target / c : isfinite(hi) ? (fp_real)0.5 * (lo + hi) : lo + 1;
    for (int it = 0; it < 100; it++) {
        if (!(s > lo && s < hi))
            s = isfinite(hi) ? (fp_real)0.5 * (lo + hi) : lo + 2 * (s - lo) + 1;
        w->s1 = s;
        fp_real e = fp_ref_control_od(w, fp) - target;
        if (e > 0)
            hi = s;
        else
            lo = s;
        if (fabs(e) <= FP_REF_TOL * target ||
            (isfinite(hi) && !(hi - lo > FP_REF_TOL * fabs(hi))))
            break;
        c = fp_ref_control(w, fp, w->o[1] + s * w->d[1]);
        s = c > 0 ? s - e / c : -FP_INF;
    }
    w->s1 = end;
    return s;
}

/* A free flight from o + t0 d: returns 1 with *tc at a real collision
 * before tend, 0 when the flight passes tend.
 * With FP_RP_CONTROL, decomposition tracking (Kutz et al. 2017): the
 * collisions of the control c and of the residual sigma_t - c are two
 * independent processes, the first by inverting c's closed-form integral
 * (exact, from u0: without a fogmap this is the whole flight), the second
 * by delta tracking against r (acceptance of its first tentative collision
 * from u1); the flight ends at the earlier.  Without, plain delta
 * tracking against mu (the first tentative collision from u0, u1).  The
 * other uniforms come from rng. */
FP_FN int fp_ref_free_flight(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                             FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                             FP_CONSTANT const fp_real *rp, FP_GLOBAL const float *grid,
                             fp_real ox, fp_real oy, fp_real oz, fp_real dx, fp_real dy,
                             fp_real dz, fp_real t0, fp_real tend, fp_rng_t *rng, fp_real u0,
                             fp_real u1, fp_real *tc)
{
    if (!(tend > t0))
        return 0;
    int control = rp[FP_RP_CONTROL] != 0;
    fp_ref_walk_t w;
    fp_ref_walk_init(&w, fp, rp, ox, oy, oz, dx, dy, dz, t0, tend,
                     fp_ref_step(fp, control));
    fp_real target = -log((fp_real)1 - u0), accept = u1;
    fp_real target_r = control ? -log((fp_real)1 - FP_RNG_NEXT(rng)) : (fp_real)0;
    int events = 0;
    while (fp_ref_walk_next(&w, fp, rp, grid)) {
        fp_real rate = control ? w.r : w.mu, lim = w.s1, pc = 0;
        int hit = 0;
        if (control && (w.cm > 0 || w.ch > 0)) {
            pc = fp_ref_control_od(&w, fp);
            if (target < pc) {
                lim = fp_ref_control_invert(&w, fp, target);
                hit = 1;
            }
        }
        fp_real *tr = control ? &target_r : &target;
        for (fp_real s = w.s0; rate > 0;) {
            fp_real room = rate * (lim - s);
            if (!(*tr < room)) {
                *tr -= room;
                break;
            }
            s += *tr / rate;
            fp_real y = oy + s * dy;
            fp_real e = fp_sigma_t(fp, lvi, lvf, coef, ox + s * dx, y, oz + s * dz);
            if (control)
                e -= fp_ref_control(&w, fp, y);
            if (accept * rate < e) {
                *tc = s;
                return 1;
            }
            if (++events > FP_REF_MAX_EVENTS)
                return 0;
            *tr = -log((fp_real)1 - FP_RNG_NEXT(rng));
            accept = FP_RNG_NEXT(rng);
        }
        if (hit) {
            *tc = lim;
            return 1;
        }
        target -= pc;
    }
    return 0;
}

/* Russian roulette on a small weight: kept at FP_REF_RR with probability
 * T / FP_REF_RR, else 0 (unbiased).  Played at tentative collisions only,
 * where it saves work: the control's attenuation is exact. */
FP_FN fp_real fp_ref_roulette(fp_real T, fp_rng_t *rng)
{
    if (T >= FP_REF_RR || T <= 0)
        return T;
    return FP_RNG_NEXT(rng) * FP_REF_RR < T ? FP_REF_RR : (fp_real)0;
}

/* Ratio tracking (residual, with the control c, when FP_RP_CONTROL): an
 * unbiased estimate of the transmittance over [t0, tend] of o + t d. */
FP_FN fp_real fp_ref_transmittance(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                                   FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                                   FP_CONSTANT const fp_real *rp, FP_GLOBAL const float *grid,
                                   fp_real ox, fp_real oy, fp_real oz, fp_real dx, fp_real dy,
                                   fp_real dz, fp_real t0, fp_real tend, fp_rng_t *rng)
{
    if (!(tend > t0))
        return 1;
    int control = rp[FP_RP_CONTROL] != 0;
    fp_ref_walk_t w;
    fp_ref_walk_init(&w, fp, rp, ox, oy, oz, dx, dy, dz, t0, tend,
                     fp_ref_step(fp, control));
    fp_real T = 1;
    int events = 0;
    while (fp_ref_walk_next(&w, fp, rp, grid)) {
        fp_real r = w.mu;
        if (control) {
            if (w.cm > 0 || w.ch > 0)
                T *= exp(-fp_ref_control_od(&w, fp));
            r = w.r;
        }
        if (r > 0) {
            for (fp_real s = w.s0;;) {
                s += -log((fp_real)1 - FP_RNG_NEXT(rng)) / r;
                if (!(s < w.s1))
                    break;
                fp_real y = oy + s * dy;
                fp_real e = fp_sigma_t(fp, lvi, lvf, coef, ox + s * dx, y, oz + s * dz);
                if (control)
                    e -= fp_ref_control(&w, fp, y);
                T *= fmin(fmax((fp_real)1 - e / r, (fp_real)0), (fp_real)1);
                T = fp_ref_roulette(T, rng);
                if (!(T > 0) || ++events > FP_REF_MAX_EVENTS)
                    return T > 0 ? T : (fp_real)0;
            }
        }
        if (!(T > 0))
            return 0;
    }
    return T;
}

/* ------------------------------------------------------------ sampling */

FP_FN fp_u32 fp_ref_reverse_bits(fp_u32 v)
{
    v = ((v >> 1) & 0x55555555U) | ((v & 0x55555555U) << 1);
    v = ((v >> 2) & 0x33333333U) | ((v & 0x33333333U) << 2);
    v = ((v >> 4) & 0x0F0F0F0FU) | ((v & 0x0F0F0F0FU) << 4);
    v = ((v >> 8) & 0x00FF00FFU) | ((v & 0x00FF00FFU) << 8);
    return (v >> 16) | (v << 16);
}

/* The second dimension of Sobol's sequence (with van der Corput's, a
 * (0,2)-sequence in base 2). */
FP_FN fp_u32 fp_ref_sobol2(fp_u32 i)
{
    fp_u32 r = 0, v = 0x80000000U;
    for (; i; i >>= 1, v ^= v >> 1)
        if (i & 1U)
            r ^= v;
    return r;
}

/* Bits to a uniform in [0, 1), 24 bits as FP_RNG_NEXT. */
FP_FN fp_real fp_ref_unit(fp_u32 bits)
{
    return (fp_real)(bits >> 8) * (fp_real)(1.0 / 16777216.0);
}

/* The control's transmittance over [t0, t1] of o + t d (deterministic:
 * exp of minus the control's integral, walked like the trackers). */
FP_FN fp_real fp_ref_control_tau(FP_CONSTANT const fp_real *fp, FP_CONSTANT const fp_real *rp,
                                 FP_GLOBAL const float *grid, fp_real ox, fp_real oy, fp_real oz,
                                 fp_real dx, fp_real dy, fp_real dz, fp_real t0, fp_real t1)
{
    if (!(t1 > t0))
        return 1;
    fp_ref_walk_t w;
    fp_ref_walk_init(&w, fp, rp, ox, oy, oz, dx, dy, dz, t0, t1, FP_INF);
    fp_real od = 0;
    while (fp_ref_walk_next(&w, fp, rp, grid))
        if (w.cm > 0 || w.ch > 0)
            od += fp_ref_control_od(&w, fp);
    return exp(-od);
}

/* Local light k seen from x along the path's direction d: the factor of
 * its intensity I (rgb), gain p(mu) tau / r^2 (fp_light_gain: cone, soft
 * radius, area), tau by ratio tracking. */
FP_FN fp_real fp_ref_light(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                           FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                           FP_CONSTANT const fp_real *lt, FP_GLOBAL const fp_real *lights,
                           FP_CONSTANT const fp_real *rp, FP_GLOBAL const float *grid, int k,
                           fp_real x, fp_real y, fp_real z, fp_real dx, fp_real dy, fp_real dz,
                           fp_rng_t *rng)
{
    FP_CONSTANT const fp_real *ph = lt + FP_LT_PHASE;
    FP_GLOBAL const fp_real *row = lights + k * FP_LL_STRIDE;
    fp_real vx = row[FP_LL_POS] - x, vy = row[FP_LL_POS + 1] - y, vz = row[FP_LL_POS + 2] - z;
    fp_real r2 = vx * vx + vy * vy + vz * vz;
    if (!(r2 > 0))
        return 0;
    fp_real r = sqrt(r2);
    vx /= r;
    vy /= r;
    vz /= r;
    fp_real e = fp_light_gain(row, -vx, -vy, -vz, r);
    if (e > 0)
        e *= fp_phase((int)ph[0], ph[1], ph[2], vx * dx + vy * dy + vz * dz) / r2;
    if (!(e > 0))
        return 0;
    fp_real te = fp_ref_fog_end(fp, x, y, z, vx, vy, vz, r);
    return e * fp_ref_transmittance(fp, lvi, lvf, coef, rp, grid, x, y, z, vx, vy, vz, 0, te, rng);
}

/* Equiangular sampling (Kulla and Fajardo 2012) of t in [0, tend] along
 * o + t d about light k: the density is proportional to 1 / r^2. */
typedef struct fp_ref_eq_t {
    fp_real tc, D, th0, th1;
} fp_ref_eq_t;

FP_FN fp_ref_eq_t fp_ref_eq_setup(FP_GLOBAL const fp_real *lights, int k, fp_real ox, fp_real oy,
                                  fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real tend)
{
    FP_GLOBAL const fp_real *row = lights + k * FP_LL_STRIDE;
    fp_real qx = row[FP_LL_POS] - ox, qy = row[FP_LL_POS + 1] - oy, qz = row[FP_LL_POS + 2] - oz;
    fp_ref_eq_t e;
    e.tc = qx * dx + qy * dy + qz * dz;
    fp_real rx = qx - e.tc * dx, ry = qy - e.tc * dy, rz = qz - e.tc * dz;
    e.D = fmax(sqrt(rx * rx + ry * ry + rz * rz), (fp_real)1e-6 * ((fp_real)1 + fabs(e.tc)));
    e.th0 = atan(-e.tc / e.D);
    e.th1 = isinf(tend) ? (fp_real)1.5707963267948966 : atan((tend - e.tc) / e.D);
    return e;
}

FP_FN fp_real fp_ref_eq_pdf(const fp_ref_eq_t *e, fp_real t)
{
    fp_real u = t - e->tc;
    return e->D / ((e->th1 - e->th0) * (e->D * e->D + u * u));
}

/* The view ray's collision on it for the MIS weights of the local
 * lights' next-event estimates (fp_ref_vertex): the ray, its end, the
 * collision's t and q there (fp_ref_sample). */
typedef struct fp_ref_mis_t {
    int on;
    fp_real ox, oy, oz, tend, tc, q;
} fp_ref_mis_t;

/* Next-event estimates and ambient at a real collision x, the path
 * arriving along d: L_amb + sun + extra directional lights + local lights
 * (without the albedo), light k weighted by q / (q + p_eq,k(tc)) when
 * mis->on (the collision on the view ray; else 1). */
FP_FN void fp_ref_vertex(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                         FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                         FP_CONSTANT const fp_real *lt, FP_GLOBAL const fp_real *lights,
                         FP_GLOBAL const float *smap, FP_CONSTANT const float *view,
                         FP_GLOBAL const float *depth, int width, int height,
                         FP_CONSTANT const fp_real *rp, FP_GLOBAL const float *grid, fp_real x,
                         fp_real y, fp_real z, fp_real dx, fp_real dy, fp_real dz,
                         const fp_ref_mis_t *mis, fp_rng_t *rng, fp_real *J)
{
    FP_CONSTANT const fp_real *ph = lt + FP_LT_PHASE;
    J[0] = lt[FP_LT_AMB];
    J[1] = lt[FP_LT_AMB + 1];
    J[2] = lt[FP_LT_AMB + 2];
    if (lt[FP_LT_SUN_ON] != 0) {
        FP_CONSTANT const fp_real *l = lt + FP_LT_SUN_DIR;
        fp_real p = fp_phase((int)ph[0], ph[1], ph[2], l[0] * dx + l[1] * dy + l[2] * dz);
        fp_real v = p > 0 ? fp_sun_visibility(lt, smap, view, depth, width, height, x, y, z) : 0;
        if (v > 0 && (int)lt[FP_LT_SELF] != FP_SELF_OFF) {
            fp_real te = fp_ref_fog_end(fp, x, y, z, l[0], l[1], l[2], FP_INF);
            v *= fp_ref_transmittance(fp, lvi, lvf, coef, rp, grid, x, y, z, l[0], l[1], l[2], 0,
                                      te, rng);
        }
        v *= p;
        J[0] += v * lt[FP_LT_SUN_E];
        J[1] += v * lt[FP_LT_SUN_E + 1];
        J[2] += v * lt[FP_LT_SUN_E + 2];
    }
    int nl = (int)lt[FP_LT_NLIGHTS], nd = (int)lt[FP_LT_NDIR];
    /* Extra directional lights: as the sun, screen shadows under
     * --shadows screen and map+screen, never a map. */
    for (int k = nl; k < nl + nd; k++) {
        FP_GLOBAL const fp_real *row = lights + k * FP_LL_STRIDE;
        fp_real lx = row[FP_LL_POS], ly = row[FP_LL_POS + 1], lz = row[FP_LL_POS + 2];
        fp_real v = fp_phase((int)ph[0], ph[1], ph[2], lx * dx + ly * dy + lz * dz);
        if (v > 0 && ((int)lt[FP_LT_SHADOWS] == FP_SHADOWS_SCREEN ||
                      (int)lt[FP_LT_SHADOWS] == FP_SHADOWS_MAP_SCREEN))
            v *= fp_shadow_screen_dir(lt, lx, ly, lz, view, fp_ss_zpyr(lt, smap), x, y, z);
        if (v > 0 && (int)lt[FP_LT_SELF] != FP_SELF_OFF) {
            fp_real te = fp_ref_fog_end(fp, x, y, z, lx, ly, lz, FP_INF);
            v *= fp_ref_transmittance(fp, lvi, lvf, coef, rp, grid, x, y, z, lx, ly, lz, 0, te, rng);
        }
        if (!(v > 0))
            continue;
        J[0] += v * row[FP_LL_I];
        J[1] += v * row[FP_LL_I + 1];
        J[2] += v * row[FP_LL_I + 2];
    }
    for (int k = 0; k < nl; k++) {
        fp_real w = 1;
        if (mis->on) {
            fp_ref_eq_t eq = fp_ref_eq_setup(lights, k, mis->ox, mis->oy, mis->oz, dx, dy, dz,
                                             mis->tend);
            fp_real pe = fp_ref_eq_pdf(&eq, mis->tc);
            w = mis->q > 0 ? mis->q / (mis->q + pe) : (fp_real)0;
        }
        if (!(w > 0))
            continue;
        FP_GLOBAL const fp_real *row = lights + k * FP_LL_STRIDE;
        if (lt[FP_LT_LS_ON] != 0 && fp_ls_visible(lt, row, view, smap, x, y, z) == 0)
            continue;
        fp_real e = w * fp_ref_light(fp, lvi, lvf, coef, lt, lights, rp, grid, k, x, y, z, dx, dy,
                                     dz, rng);
        J[0] += e * row[FP_LL_I];
        J[1] += e * row[FP_LL_I + 1];
        J[2] += e * row[FP_LL_I + 2];
    }
}

/* The geometry the reference assumes beyond what the camera sees: a point
 * is solid when both the sun's map and the depth buffer hide it (behind
 * what the map's texel holds, and behind the scene's z at the pixel it
 * projects to); where either does not see it (outside the map or the
 * frame, behind the camera) it is fog.  So the ground and what stands on
 * it are solid to the depth of what both views hide (the ground's
 * underside, a wall's inside), and the fog in a caster's shadow, seen by
 * the camera, stays fog.  Without a shadow map nothing is solid. */
FP_FN int fp_ref_solid(FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *smap,
                       FP_CONSTANT const float *view, FP_GLOBAL const float *depth, int width,
                       int height, FP_CONSTANT const fp_real *rp, fp_real x, fp_real y, fp_real z)
{
    int mode = (int)lt[FP_LT_SHADOWS];
    if (mode != FP_SHADOWS_MAP && mode != FP_SHADOWS_MAP_SCREEN)
        return 0;
    FP_CONSTANT const fp_real *m = lt + FP_LT_SM_NDC;
    FP_CONSTANT const fp_real *cz = lt + FP_LT_SM_Z;
    int W = (int)lt[FP_LT_SM_W], H = (int)lt[FP_LT_SM_H];
    fp_real u = (x * m[0] + y * m[4] + z * m[8] + m[12]) * W;
    fp_real v = (x * m[1] + y * m[5] + z * m[9] + m[13]) * H;
    if (!(u >= 0 && v >= 0 && u < W && v < H))
        return 0;
    fp_real pz = x * cz[0] + y * cz[1] + z * cz[2] + cz[3];
    int i = (int)floor(u), j = (int)floor(v);
    i = i > W - 1 ? W - 1 : i;
    j = j > H - 1 ? H - 1 : j;
    if (pz <= smap[j * W + i])
        return 0;
    /* Hidden from the sun: and from the camera? */
    FP_CONSTANT const fp_real *ci = rp + FP_RP_CAM_INV, *ni = rp + FP_RP_NDC_INV;
    fp_real px = x - view[0], py = y - view[1], pzz = z - view[2];
    fp_real c0 = ci[0] * px + ci[1] * py + ci[2] * pzz;
    fp_real c1 = ci[3] * px + ci[4] * py + ci[5] * pzz;
    fp_real c2 = ci[6] * px + ci[7] * py + ci[8] * pzz;
    if (!(c2 > 0))
        return 0;
    if (view[FP_VIEW_ORTHO] == 0) {
        c0 /= c2;
        c1 /= c2;
    }
    fp_real nw = ni[6] * c0 + ni[7] * c1 + ni[8];
    if (!(nw != 0))
        return 0;
    fp_real nx = (ni[0] * c0 + ni[1] * c1 + ni[2]) / nw;
    fp_real ny = (ni[3] * c0 + ni[4] * c1 + ni[5]) / nw;
    fp_real fx = floor(nx / view[FP_VIEW_NDC_SCALE] - view[FP_VIEW_NDC_OFFSET] + (fp_real)0.5);
    fp_real fy = floor(ny / view[FP_VIEW_NDC_SCALE + 1] - view[FP_VIEW_NDC_OFFSET + 1] +
                       (fp_real)0.5);
    if (!(fx >= 0 && fy >= 0 && fx < width && fy < height))
        return 0;
    return c2 > fp_scene_z(view, depth, width, (int)fx, (int)fy);
}

/* Whether o + s d meets the solid for s in (0, t1]: marched in steps of
 * FP_RP_SOLID from a random offset, and at t1 itself. */
FP_FN int fp_ref_blocked(FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *smap,
                         FP_CONSTANT const float *view, FP_GLOBAL const float *depth, int width,
                         int height, FP_CONSTANT const fp_real *rp, fp_real ox, fp_real oy,
                         fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real t1,
                         fp_rng_t *rng)
{
    fp_real step = rp[FP_RP_SOLID];
    if (!(step > 0))
        return 0;
    for (fp_real s = step * FP_RNG_NEXT(rng); s < t1; s += step)
        if (fp_ref_solid(lt, smap, view, depth, width, height, rp, ox + s * dx, oy + s * dy,
                         oz + s * dz))
            return 1;
    return fp_ref_solid(lt, smap, view, depth, width, height, rp, ox + t1 * dx, oy + t1 * dy,
                        oz + t1 * dz);
}

/* One sample of a view ray o + t d, t in [0, len] (len INF: sky): adds
 * the in-scattered S (3) and returns the transmittance estimate.
 * Local lights along the view ray by two strategies, combined by multiple
 * importance sampling (balance heuristic): the free flight's collision
 * (density tau sigma_t) and an equiangular sample per light (density
 * p_eq ~ 1 / r^2, which resolves the peak of a ray passing close to a
 * light).  The weights use q = tau_c sigma_t with tau_c the control's
 * transmittance (deterministic, so the weights of the two strategies sum
 * to 1 at every point and the estimate stays unbiased; without a fogmap
 * q is the free flight's density itself). */
FP_FN fp_real fp_ref_sample(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                            FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                            FP_CONSTANT const fp_real *lt, FP_GLOBAL const fp_real *lights,
                            FP_GLOBAL const float *smap, FP_CONSTANT const float *view,
                            FP_GLOBAL const float *depth, int width, int height,
                            FP_CONSTANT const fp_real *rp, FP_GLOBAL const float *grid,
                            fp_u32 seed, fp_u32 pixel,
                            fp_u32 sample, fp_real ox, fp_real oy, fp_real oz, fp_real dx,
                            fp_real dy, fp_real dz, fp_real len, fp_real *S)
{
    S[0] = S[1] = S[2] = 0;
    fp_real tend = fp_ref_fog_end(fp, ox, oy, oz, dx, dy, dz, len);
    if (!(tend > 0))
        return 1;
    fp_rng_t rng = fp_rng_seed(seed, pixel, sample);
    fp_real tau = fp_ref_transmittance(fp, lvi, lvf, coef, rp, grid, ox, oy, oz, dx, dy, dz, 0,
                                       tend, &rng);
    int stratify = rp[FP_RP_STRATIFY] != 0;
    fp_u32 h = fp_hash32(seed ^ fp_hash32(pixel ^ 0x2545f491U));
    fp_u32 vdc = fp_ref_reverse_bits(sample);
    fp_real albedo = lt[FP_LT_ALBEDO];
    /* The lights' equiangular samples. */
    int nl = (int)lt[FP_LT_NLIGHTS];
    fp_real tend0 = tend;
    for (int k = 0; k < nl; k++) {
        fp_ref_eq_t eq = fp_ref_eq_setup(lights, k, ox, oy, oz, dx, dy, dz, tend);
        fp_real u = stratify ? fp_ref_unit(vdc + fp_hash32(h ^ (0x3c6ef372U + (fp_u32)k)))
                             : FP_RNG_NEXT(&rng);
        fp_real t = eq.tc + eq.D * tan(eq.th0 + u * (eq.th1 - eq.th0));
        t = fmin(fmax(t, (fp_real)0), tend);
        fp_real x = ox + t * dx, y = oy + t * dy, z = oz + t * dz;
        fp_real sig = fp_sigma_t(fp, lvi, lvf, coef, x, y, z);
        fp_real pe = fp_ref_eq_pdf(&eq, t);
        if (!(sig > 0) || !(pe > 0) || !isfinite(t) ||
            (lt[FP_LT_LS_ON] != 0 &&
             fp_ls_visible(lt, lights + k * FP_LL_STRIDE, view, smap, x, y, z) == 0))
            continue;
        fp_real q = fp_ref_control_tau(fp, rp, grid, ox, oy, oz, dx, dy, dz, 0, t) * sig;
        fp_real e = fp_ref_light(fp, lvi, lvf, coef, lt, lights, rp, grid, k, x, y, z, dx, dy, dz,
                                 &rng);
        if (!(e > 0))
            continue;
        e *= fp_ref_transmittance(fp, lvi, lvf, coef, rp, grid, ox, oy, oz, dx, dy, dz, 0, t,
                                  &rng);
        e *= albedo * sig / (q + pe);
        FP_GLOBAL const fp_real *row = lights + k * FP_LL_STRIDE;
        S[0] += e * row[FP_LL_I];
        S[1] += e * row[FP_LL_I + 1];
        S[2] += e * row[FP_LL_I + 2];
    }
    /* The path: free flights from the view ray on. */
    fp_real u0, u1;
    if (stratify) {
        u0 = fp_ref_unit(vdc + h);
        u1 = fp_ref_unit(fp_ref_sobol2(sample) + fp_hash32(h ^ 0x68e31da4U));
    } else {
        u0 = FP_RNG_NEXT(&rng);
        u1 = FP_RNG_NEXT(&rng);
    }
    FP_CONSTANT const fp_real *ph = lt + FP_LT_PHASE;
    int bounces = (int)rp[FP_RP_BOUNCES];
    fp_real beta = albedo;
    fp_real px = ox, py = oy, pz = oz;
    for (int j = 0;; j++) {
        fp_real tc;
        if (!fp_ref_free_flight(fp, lvi, lvf, coef, rp, grid, px, py, pz, dx, dy, dz, 0, tend, &rng,
                                u0, u1, &tc))
            break;
        /* A scattered path ends on the geometry it meets (black). */
        if (j > 0 && fp_ref_blocked(lt, smap, view, depth, width, height, rp, px, py, pz, dx, dy,
                                    dz, tc, &rng))
            break;
        px += tc * dx;
        py += tc * dy;
        pz += tc * dz;
        /* On the view ray the lights take the free flight's MIS weight. */
        fp_ref_mis_t mis;
        mis.on = j == 0 && nl > 0;
        mis.ox = ox;
        mis.oy = oy;
        mis.oz = oz;
        mis.tend = tend0;
        mis.tc = tc;
        mis.q = mis.on ? fp_ref_control_tau(fp, rp, grid, ox, oy, oz, dx, dy, dz, 0, tc) *
                             fp_sigma_t(fp, lvi, lvf, coef, px, py, pz)
                       : (fp_real)0;
        fp_real J[3];
        fp_ref_vertex(fp, lvi, lvf, coef, lt, lights, smap, view, depth, width, height, rp, grid,
                      px, py, pz, dx, dy, dz, &mis, &rng, J);
        S[0] += beta * J[0];
        S[1] += beta * J[1];
        S[2] += beta * J[2];
        if (j >= bounces || !(beta > 0))
            break;
        /* Scatter: a direction from the phase function (pdf = p, so the
         * weight is the albedo alone). */
        fp_real nx, ny, nz;
        fp_phase_sample_dir((int)ph[0], ph[1], ph[2], dx, dy, dz, &rng, &nx, &ny, &nz);
        fp_real nn = sqrt(nx * nx + ny * ny + nz * nz);
        dx = nx / nn;
        dy = ny / nn;
        dz = nz / nn;
        beta *= albedo;
        tend = fp_ref_fog_end(fp, px, py, pz, dx, dy, dz, FP_INF);
        u0 = FP_RNG_NEXT(&rng);
        u1 = FP_RNG_NEXT(&rng);
    }
    return tau;
}

#endif

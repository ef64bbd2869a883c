/* fogpipe: the fog integrals along one view ray, written once and compiled
 * twice: as OpenCL C in single precision (kernels/integrate.cl) and as C in
 * double precision (filters/integrate.c, the reference).  The two differ in
 * precision and in quadrature order only (FP_GL_EXTRA, FP_EXP_STEP, and for
 * the one walk per ray FP_SEG_U, FP_SEG_TERMS); the logic is judged by
 * brute-force quadrature of the fog's definition in the tests
 * (tests/test_integrate.c, tests/test_fogmap.c).
 *
 * Fog model (DESIGN.md, Conventions):
 *   sigma_t(p) = sigma F(u,v) h(y) + sigma_haze h_haze(y)
 * F: B-spline surface of degree d over the fogmap (a sum of one surface per
 * wavelet level, seed 000 sec. 4.4), h: 1 below Y0, exp(-(y-Y0)/H) above,
 * 0 above TOP.  Along a ray, within one cell of one level, F is a
 * polynomial of degree 2d in t and h an exponential, so each cell's
 * integral has a closed form (fp_grid_walk: moments of the exponential,
 * the sum of all levels walked once) or is Gauss-Legendre exact for the
 * polynomial part (fp_level_integral, level by level for raw bands; the
 * exponential kept smooth by splitting where it varies) (DESIGN,
 * Exactness). */
#ifndef FP_FOG_CORE_H
#define FP_FOG_CORE_H

#include "fp_real.h"

#ifdef __OPENCL_VERSION__
#ifndef FP_GL_EXTRA
#define FP_GL_EXTRA 0
#endif
#ifndef FP_EXP_STEP
#define FP_EXP_STEP 0.5f
#endif
#else
#ifndef FP_GL_EXTRA
#define FP_GL_EXTRA 2
#endif
#ifndef FP_EXP_STEP
#define FP_EXP_STEP 0.25
#endif
#endif

#define FP_REAL fp_real
#include "bspline.h"

/* Always inlined: the walk's helpers, so that the degree becomes a
 * constant in each copy and their small loops unroll (PoCL and gcc leave
 * them as calls otherwise). */
#ifdef __OPENCL_VERSION__
#define FP_HOT inline __attribute__((always_inline))
#else
#define FP_HOT static inline __attribute__((always_inline))
#endif

/* Layout of the fog parameter array (filled by fp_fog_pack in
 * filters/integrate.c). */
#define FP_F_SIGMA 0
#define FP_F_Y0 1
#define FP_F_H 2
#define FP_F_TOP 3
#define FP_F_OFF 4        /* 3: fog offset */
#define FP_F_COS 7        /* rotation about the vertical axis */
#define FP_F_SIN 8
#define FP_F_USCALE 9     /* fogmap pixels per fog unit, along x and z */
#define FP_F_VSCALE 10
#define FP_F_A0 11        /* fog rectangle origin (fog-local x, z) */
#define FP_F_B0 12
#define FP_F_PAD_X0 13    /* fogmap pixel (0,0) in the padded domain */
#define FP_F_PAD_Y0 14
#define FP_F_CLIP 15      /* 4: U0, U1, V0, V1: clip (zero) or clamp box, domain pixels */
#define FP_F_BOX 19       /* 6: fog box, fog-local */
#define FP_F_DEGREE 25
#define FP_F_WRAP 26      /* 0 zero, 1 clamp, 2 repeat */
#define FP_F_NLEVELS 27
#define FP_F_LOD_MU 28
#define FP_F_OD_MAX 29    /* early termination: -ln(min transmittance) */
#define FP_F_CAP 30       /* longest integration for unbounded rays */
#define FP_F_HAZE 31      /* 4: sigma, Y0, H, TOP of the homogeneous haze */
#define FP_F_MODE 35      /* 0 exact, 1 march */
#define FP_F_STEPS 36
#define FP_F_JITTER 37
#define FP_F_SPARSE 38
#define FP_F_HAS_MAP 39
#define FP_F_FOOTPRINT 40 /* --lod-footprint pixels times the angle of one pixel */
#define FP_F_LOD_BOUND 41 /* --lod-bound: largest change of tau the dropped levels may make
                             (0 = exact) */
#define FP_F_TAPS 44     /* synthesis filters for levels kept as raw bands:
                            phi lo, hi, 16 taps; psi lo, hi, 16 taps */
#define FP_F_COUNT 80

/* Per level: ints and reals. */
#define FP_LI_NX 0
#define FP_LI_NY 1
#define FP_LI_COEF 2      /* offset into the coefficient buffer */
#define FP_LI_OCC 3       /* offset into the occupancy buffer */
#define FP_LI_BLOCK 4     /* cells per occupancy block (divides nx and ny) */
#define FP_LI_BANDS 5     /* 1: raw LH, HL, HH bands at half resolution, expanded on the fly */
#define FP_LI_APPROX 6    /* offset of A_l = S_0 + .. + S_l on this level's grid (-1: none) */
#define FP_LI_TMAP 7      /* offset of the cells' bounds of |F - A_l| (-1: none, 0 there) */
#define FP_LI_STRIDE 8
#define FP_LR_CELL 0      /* cell size in domain pixels */
#define FP_LR_ORIGIN_U 1  /* basis (i,j) centered at origin + cell*(i,j) */
#define FP_LR_ORIGIN_V 2
#define FP_LR_LOD_DIST 3  /* cell size in fog units: dropped beyond cell / FP_F_FOOTPRINT */
#define FP_LR_TAIL 4      /* sum of max |coef| of the levels finer than this one: bounds
                             |F - A_l| (B-splines >= 0 and sum to 1) */
#define FP_LR_STRIDE 8
#define FP_MAX_LEVELS_ALL 16   /* levels + coarse + the fine grid for marching */
/* The tensor grid of the linear basis (fp_tensor_walk): the last row of
 * the level tables, after the levels' and the fine grid's (at most
 * FP_MAX_LEVELS + 2 = 14 rows, filters/wavelet.h). */
#define FP_TG_ROW 15
#define FP_TI_NX 0        /* rectangles along U, as many as break nodes (0: no tensor grid) */
#define FP_TI_NY 1
#define FP_TI_VAL 2       /* offset of G at the break nodes: NY rows of NX */
#define FP_TI_BX 3        /* offset of the break nodes along U (NX), then 1 / widths (NX) */
#define FP_TI_BY 4        /* the same along V */
#define FP_TR_EPS 0       /* max |F - G| over the plane */

/* Gauss-Legendre nodes and weights on [0,1], n = 1..8. */
FP_TABLE fp_real fp_gl_x[36] = {
    0.5,
    0.21132486540518713, 0.78867513459481287,
    0.11270166537925831, 0.5, 0.88729833462074169,
    0.069431844202973713, 0.33000947820757187, 0.66999052179242813, 0.93056815579702629,
    0.046910077030668004, 0.23076534494715845, 0.5, 0.76923465505284155, 0.95308992296933200,
    0.033765242898423987, 0.16939530676686775, 0.38069040695840155, 0.61930959304159845,
    0.83060469323313225, 0.96623475710157601,
    0.025446043828620738, 0.12923440720030277, 0.29707742431130142, 0.5, 0.70292257568869858,
    0.87076559279969723, 0.97455395617137926,
    0.019855071751231856, 0.10166676129318664, 0.23723379504183550, 0.40828267875217510,
    0.59171732124782490, 0.76276620495816450, 0.89833323870681336, 0.98014492824876814 };
FP_TABLE fp_real fp_gl_w[36] = {
    1.0,
    0.5, 0.5,
    0.27777777777777778, 0.44444444444444444, 0.27777777777777778,
    0.17392742256872693, 0.32607257743127307, 0.32607257743127307, 0.17392742256872693,
    0.11846344252809454, 0.23931433524968324, 0.28444444444444444, 0.23931433524968324,
    0.11846344252809454,
    0.085662246189585173, 0.18038078652406930, 0.23395696728634553, 0.23395696728634553,
    0.18038078652406930, 0.085662246189585173,
    0.064742483084434847, 0.13985269574463833, 0.19091502525255947, 0.20897959183673469,
    0.19091502525255947, 0.13985269574463833, 0.064742483084434847,
    0.050614268145188130, 0.11119051722668724, 0.15685332293894364, 0.18134189168918099,
    0.18134189168918099, 0.15685332293894364, 0.11119051722668724, 0.050614268145188130 };
#define FP_GL_FIRST(n) (((n) - 1) * (n) / 2)

/* (1 - exp(-x)) / x for x >= 0, without cancellation near 0. */
FP_FN fp_real fp_expm1_ratio(fp_real x)
{
    return x < (fp_real)1e-3 ? (fp_real)1 - x * ((fp_real)0.5 - x * ((fp_real)1 / 6))
                             : -expm1(-x) / x;
}

/* 1 - exp(-x), x >= 0: -expm1(-x).  In OpenCL expm1 is a call the CPU
 * device does not inline: there the series below 0.05 (the first term
 * left out, x^5/120, is below 3e-9 of it) and 1 - exp(-x) above (within
 * 1e-6 of it in single precision). */
#ifdef __OPENCL_VERSION__
FP_FN float fp_one_minus_exp(float x)
{
    float series = x * (1.0f - x * (0.5f - x * (1.0f / 6 - x * (1.0f / 24))));
    return x < 0.05f ? series : 1.0f - exp(-x);
}
#else
FP_FN double fp_one_minus_exp(double x)
{
    return -expm1(-x);
}
#endif

/* The t-interval [*a, *b] within [0, len] where lo <= oy + t dy < hi. */
FP_FN int fp_slab(fp_real oy, fp_real dy, fp_real lo, fp_real hi, fp_real len,
                  fp_real *a, fp_real *b)
{
    fp_real t0, t1;
    if (dy == 0) {
        if (oy < lo || oy >= hi)
            return 0;
        t0 = 0;
        t1 = len;
    } else {
        fp_real u = (lo - oy) / dy, v = (hi - oy) / dy;
        t0 = fmax(fmin(u, v), (fp_real)0);
        t1 = fmin(fmax(u, v), len);
    }
    *a = t0;
    *b = t1;
    return t1 > t0;
}

/* Optical depth of sigma h(y) along oy + t dy, t in [0, len] (len may be
 * infinite), in closed form. */
FP_FN fp_real fp_height_od(fp_real sigma, fp_real y0, fp_real H, fp_real top,
                           fp_real oy, fp_real dy, fp_real len)
{
    fp_real od = 0, a, b;
    if (sigma <= 0)
        return 0;
    if (fp_slab(oy, dy, -FP_INF, fmin(y0, top), len, &a, &b))
        od += b - a;
    if (fp_slab(oy, dy, y0, top, len, &a, &b)) {
        /* Heights in units of H above the base: the integral of exp(-y)
         * from the lowest point m over a rise D is exp(-m)(1 - exp(-D)). */
        fp_real ya = (oy + a * dy - y0) / H;
        if (isinf(b)) {
            if (dy > 0)
                od += exp(-ya) * H / dy;
            else if (exp(-ya) > 0)
                od = FP_INF;
        } else {
            fp_real D = fabs(dy) * (b - a) / H;
            fp_real m = dy < 0 ? ya - D : ya;
            od += (b - a) * exp(-m) * fp_expm1_ratio(D);
        }
    }
    return sigma * od;
}

/* Knot interval of level coordinate x (basis i centered at x = i): knots at
 * integers for odd degree, at half-integers for even degree (kappa = 1/2).
 * On a knot, a ray moving down enters the interval below.  Coefficients of
 * interval k: k - d/2 ... k - d/2 + d (kernels/bspline.h). */
FP_FN int fp_cell_of(fp_real x, fp_real dxdt)
{
    fp_real f = floor(x);
    if (dxdt < 0 && f == x)
        f -= 1;
    return (int)f;
}

FP_FN int fp_wrap_index(int i, int n)
{
    int r = i % n;
    return r < 0 ? r + n : r;
}

/* A straight piece of the path in domain coordinates: U(t) = u0 + t du,
 * V(t) = v0 + t dv, height y(t) = y0 + t dy (fog-local). */
typedef struct fp_path_t {
    fp_real u0, du, v0, dv, oy, dy;
} fp_path_t;

/* Integral over [a, b] of the level's surface times h(y(t)), inside one
 * knot interval (k, m), by Gauss-Legendre: n = d+1 nodes are exact below
 * Y0 (degree 2d), d+2 (+FP_GL_EXTRA) above it, where the exponential is
 * split so that it changes by at most exp(FP_EXP_STEP) per piece. */
FP_FN fp_real fp_cell_integral(FP_CONSTANT const fp_real *fp, int d, const fp_real *c,
                               fp_real xs, fp_real dxdt, fp_real ys, fp_real dydt,
                               int k, int m, const fp_path_t *p, fp_real a, fp_real b)
{
    fp_real y0 = fp[FP_F_Y0], H = fp[FP_F_H];
    fp_real sum = 0;
    /* Below Y0 (h = 1) and above it (exponential). */
    fp_real ta = a, tb = b, tc;
    if (p->dy == 0)
        tc = p->oy < y0 ? b : a;
    else
        tc = fmin(fmax((y0 - p->oy) / p->dy, a), b);
    for (int part = 0; part < 2; part++) {
        fp_real s0 = part == 0 ? ta : tc, s1 = part == 0 ? tc : tb;
        if (!(s1 > s0))
            continue;
        fp_real ymid = p->oy + (fp_real)0.5 * (s0 + s1) * p->dy;
        int below = ymid < y0;
        int n = d + 1 + (below ? 0 : 1) + FP_GL_EXTRA;
        int pieces = 1;
        if (!below && isfinite(H)) {
            fp_real change = fabs(p->dy) * (s1 - s0) / H;
            pieces = (int)ceil(change / FP_EXP_STEP);
            pieces = pieces < 1 ? 1 : pieces > 256 ? 256 : pieces;
        }
        fp_real step = (s1 - s0) / pieces;
        for (int q = 0; q < pieces; q++) {
            fp_real q0 = s0 + q * step;
            fp_real acc = 0;
            for (int g = 0; g < n; g++) {
                fp_real t = q0 + step * fp_gl_x[FP_GL_FIRST(n) + g];
                fp_real wu[4], wv[4];
                fp_bspline_weights(d, xs + t * dxdt - k, wu);
                fp_bspline_weights(d, ys + t * dydt - m, wv);
                fp_real f = 0;
                for (int j = 0; j <= d; j++) {
                    fp_real row = 0;
                    for (int i = 0; i <= d; i++)
                        row += c[j * 4 + i] * wu[i];
                    f += row * wv[j];
                }
                fp_real h = below ? (fp_real)1 : exp(-(p->oy + t * p->dy - y0) / H);
                acc += fp_gl_w[FP_GL_FIRST(n) + g] * f * h;
            }
            sum += acc * step;
        }
    }
    return sum;
}

FP_FN int fp_floor_div2(int a)
{
    return a >= 0 ? a / 2 : -((1 - a) / 2);
}

/* Without deconstruction (seed 000 sec. 4.4, its Table 3 compares): the
 * scaling coefficient n, m of a level, computed on the fly from the three
 * raw detail bands at half resolution through the synthesis filters:
 * e(n,m) = sum_ij LH_ij phi(n-2i) psi(m-2j) + HL_ij psi(n-2i) phi(m-2j)
 *        + HH_ij psi(n-2i) psi(m-2j). */
FP_FN fp_real fp_band_coef(FP_CONSTANT const fp_real *fp, FP_GLOBAL const float *bands, int nbx,
                           int nby, int n, int m)
{
    FP_CONSTANT const fp_real *t = fp + FP_F_TAPS;
    int lo0 = (int)t[0], hi0 = (int)t[1], lo1 = (int)t[18], hi1 = (int)t[19];
    int lo = lo0 < lo1 ? lo0 : lo1, hi = hi0 > hi1 ? hi0 : hi1;
    size_t nb = (size_t)nbx * nby;
    fp_real sum = 0;
    for (int j = fp_floor_div2(m - hi + 1); j <= fp_floor_div2(m - lo); j++) {
        int kv = m - 2 * j;
        fp_real phv = kv >= lo0 && kv <= hi0 ? t[2 + kv - lo0] : 0;
        fp_real psv = kv >= lo1 && kv <= hi1 ? t[20 + kv - lo1] : 0;
        size_t row = (size_t)fp_wrap_index(j, nby) * nbx;
        for (int i = fp_floor_div2(n - hi + 1); i <= fp_floor_div2(n - lo); i++) {
            int ku = n - 2 * i;
            fp_real phu = ku >= lo0 && ku <= hi0 ? t[2 + ku - lo0] : 0;
            fp_real psu = ku >= lo1 && ku <= hi1 ? t[20 + ku - lo1] : 0;
            size_t at = row + fp_wrap_index(i, nbx);
            sum += bands[at] * phu * psv + bands[nb + at] * psu * phv +
                   bands[2 * nb + at] * psu * psv;
        }
    }
    return sum;
}

/* One level's contribution over [a, b]: walk the knot intervals the path
 * crosses (2D DDA), each with the (d+1)^2 coefficients whose support
 * reaches it, skipping occupancy blocks that hold only zeros. */
FP_FN fp_real fp_level_integral(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                                FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                                FP_GLOBAL const unsigned char *occ, int l,
                                const fp_path_t *p, fp_real a, fp_real b)
{
    int d = (int)fp[FP_F_DEGREE];
    int nx = lvi[l * FP_LI_STRIDE + FP_LI_NX], ny = lvi[l * FP_LI_STRIDE + FP_LI_NY];
    int block = lvi[l * FP_LI_STRIDE + FP_LI_BLOCK];
    int bands = lvi[l * FP_LI_STRIDE + FP_LI_BANDS];
    FP_GLOBAL const float *cf = coef + lvi[l * FP_LI_STRIDE + FP_LI_COEF];
    FP_GLOBAL const unsigned char *oc = occ + lvi[l * FP_LI_STRIDE + FP_LI_OCC];
    fp_real cell = lvf[l * FP_LR_STRIDE + FP_LR_CELL];
    fp_real kappa = (d & 1) ? (fp_real)0 : (fp_real)0.5;
    /* Level coordinates: basis i centered at x = i, knots shifted by kappa. */
    fp_real xs = (p->u0 - lvf[l * FP_LR_STRIDE + FP_LR_ORIGIN_U]) / cell + kappa;
    fp_real ys = (p->v0 - lvf[l * FP_LR_STRIDE + FP_LR_ORIGIN_V]) / cell + kappa;
    fp_real dxdt = p->du / cell, dydt = p->dv / cell;
    int sx = dxdt > 0 ? 1 : -1, sy = dydt > 0 ? 1 : -1;
    int bx = nx / block;
    int sparse = fp[FP_F_SPARSE] != 0 && !bands;
    fp_real t = a, sum = 0;
    int k = fp_cell_of(xs + t * dxdt, dxdt), m = fp_cell_of(ys + t * dydt, dydt);
    int first = d / 2;
    for (int guard = 0; t < b && guard < (1 << 22); guard++) {
        fp_real tx = dxdt > 0 ? (k + 1 - xs) / dxdt : dxdt < 0 ? (k - xs) / dxdt : FP_INF;
        fp_real ty = dydt > 0 ? (m + 1 - ys) / dydt : dydt < 0 ? (m - ys) / dydt : FP_INF;
        fp_real tn = fmin(fmin(tx, ty), b);
        if (tn < t)
            tn = t;
        int kw = fp_wrap_index(k, nx), mw = fp_wrap_index(m, ny);
        if (sparse && !oc[(mw / block) * bx + kw / block]) {
            /* Jump to where the path leaves this empty block. */
            int kb = k - (kw % block), mb = m - (mw % block);
            fp_real ex = dxdt > 0 ? (kb + block - xs) / dxdt : dxdt < 0 ? (kb - xs) / dxdt : FP_INF;
            fp_real ey = dydt > 0 ? (mb + block - ys) / dydt : dydt < 0 ? (mb - ys) / dydt : FP_INF;
            fp_real te = fmin(fmin(ex, ey), b);
            if (te <= t)
                te = tn;
            t = te;
            if (t >= b)
                break;
            k = fp_cell_of(xs + t * dxdt, dxdt);
            m = fp_cell_of(ys + t * dydt, dydt);
            /* The crossing lands exactly on the block edge: step over it. */
            if (ex <= ey && dxdt != 0)
                k = dxdt > 0 ? kb + block : kb - 1;
            if (ey <= ex && dydt != 0)
                m = dydt > 0 ? mb + block : mb - 1;
            continue;
        }
        if (tn > t) {
            fp_real c[16];
            int nz = 0;
            for (int j = 0; j <= d; j++)
                for (int i = 0; i <= d; i++) {
                    fp_real v = bands ? fp_band_coef(fp, cf, nx / 2, ny / 2, k - first + i,
                                                     m - first + j)
                                      : cf[fp_wrap_index(m - first + j, ny) * nx +
                                           fp_wrap_index(k - first + i, nx)];
                    c[j * 4 + i] = v;
                    nz |= v != 0;
                }
            if (nz)
                sum += fp_cell_integral(fp, d, c, xs, dxdt, ys, dydt, k, m, p, t, tn);
        }
        if (tx <= tn)
            k += sx;
        if (ty <= tn)
            m += sy;
        t = tn;
    }
    return sum;
}

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
        /* The cell's coefficients. */
        fp_real c[16];
        for (int j = 0; j <= d; j++) {
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

/* The no-fogmap path without branches: fp_slab, fp_height_od, fp_clip and
 * the homogeneous branch of fp_fog_od on FP_SIMD rays at once (OpenCL:
 * float16 lanes, one work-item computing 16 pixels; C: one ray in double),
 * every quantity computed for every lane and the cases chosen among
 * computed values (?: on vectors selects per lane).  The CPU device runs
 * this as SIMD code: PoCL does not vectorise the scalar forms across
 * work-items (their branches, and the pairs its SLP pass forms inside one
 * work-item, keep its work-group loop scalar).  The values are those of
 * the branching forms, which stay the reference (tests/test_integrate.c
 * compares the two in double). */
#ifdef __OPENCL_VERSION__
#define FP_SIMD 16
typedef float16 fp_vreal;
typedef int16 fp_vint;
#define FP_FN_SIMD inline __attribute__((always_inline))
#else
#define FP_SIMD 1
typedef fp_real fp_vreal;
typedef int fp_vint;
#define FP_FN_SIMD static inline
#endif
#define FP_VR(x) ((fp_vreal)(x))

/* (1 - exp(-x)) / x by its Taylor series, for |x| < 1/8 (the first term
 * left out is x^7/8! < 2e-11 relative), where 1 - exp(-x) would cancel. */
FP_FN_SIMD fp_vreal fp_ratio_series(fp_vreal x)
{
    return 1 - x * ((fp_real)1 / 2 -
                    x * ((fp_real)1 / 6 -
                         x * ((fp_real)1 / 24 -
                              x * ((fp_real)1 / 120 -
                                   x * ((fp_real)1 / 720 - x * ((fp_real)1 / 5040))))));
}

FP_FN_SIMD void fp_slab_bf(fp_vreal oy, fp_vreal dy, fp_vreal inv_dy, fp_real lo, fp_real hi,
                           fp_vreal len, fp_vreal *a, fp_vreal *b)
{
    /* dy = 0 makes u, v infinite or NaN: the flat case is chosen below. */
    fp_vreal u = (lo - oy) * inv_dy, v = (hi - oy) * inv_dy;
    fp_vreal t0 = fmax(fmin(u, v), FP_VR(0)), t1 = fmin(fmax(u, v), len);
    fp_vint flat = dy == FP_VR(0), inside = (oy >= FP_VR(lo)) & (oy < FP_VR(hi));
    fp_vreal flat_b = inside ? len : FP_VR(0);
    *a = flat ? FP_VR(0) : t0;
    *b = flat ? flat_b : t1;
}

/* fp_height_od; inv_dy = 1 / dy (infinite for dy = 0). */
FP_FN_SIMD fp_vreal fp_height_od_bf(fp_real sigma, fp_real y0, fp_real H, fp_real top,
                                    fp_vreal oy, fp_vreal dy, fp_vreal inv_dy, fp_vreal len)
{
    fp_vreal a, b, c, e;
    fp_real inv_h = 1 / H;
    /* Below Y0 (h = 1). */
    fp_slab_bf(oy, dy, inv_dy, -FP_INF, fmin(y0, top), len, &a, &b);
    fp_vreal below = b > a ? b - a : FP_VR(0);
    /* Above it (as fp_height_od): exp(-m)(b - a)(1 - exp(-D))/D from the
     * lowest point m over a rise D, or exp(-ya) H / dy to infinity. */
    fp_slab_bf(oy, dy, inv_dy, y0, top, len, &c, &e);
    fp_vint unbounded = isinf(e);
    fp_vreal ef = unbounded ? c : e;
    fp_vreal ya = (oy + c * dy - y0) * inv_h;
    fp_vreal D = fabs(dy) * (ef - c) * inv_h;
    fp_vreal m = dy < FP_VR(0) ? ya - D : ya;
    /* Unbounded only with dy >= 0, where m = ya. */
    fp_vreal em = exp(-m);
    /* (1 - exp(-D)) / D: its Taylor series below 1/8, exp above, where
     * 1 - exp(-D) loses at most 8 ulp of single precision (expm1 is a call
     * PoCL does not inline). */
    fp_vreal series = fp_ratio_series(D);
    fp_vreal ratio_big = (1 - exp(-D)) / D;
    fp_vreal ratio = D < FP_VR(0.125) ? series : ratio_big;
    fp_vreal bounded = (ef - c) * em * ratio;
    fp_vreal rising = em * H * inv_dy;
    fp_vreal level = em > FP_VR(0) ? FP_VR(FP_INF) : FP_VR(0);
    fp_vreal to_inf = dy > FP_VR(0) ? rising : level;
    fp_vreal above_val = unbounded ? to_inf : bounded;
    fp_vreal above = e > c ? above_val : FP_VR(0);
    fp_vreal od = sigma * (below + above);
    return sigma > 0 ? od : FP_VR(0);
}

/* fp_height_od on rays that all start at the height oy (a perspective
 * camera's, the same in every lane) and run over t in [0, len], with one
 * exp a lane where fp_height_od_bf has two.  The layer's part is entered at
 * a height that is one of three numbers whichever the lane (oy inside the
 * layer, y0 rising into it from below, top falling into it from above), so
 * its exp(-(yc - y0) / H) is the same in every lane; only the exit's is
 * not.  Over a part of length s with x = dy s / H (negative falling):
 * exp(-(yc - y0)/H) s (1 - exp(-x)) / x = H / dy (E_in - E_out), the
 * difference of the two ends' densities, losing at most 8 ulp where |x| >=
 * 1/8 (one end at least e^(1/8) times the other); below that the Taylor
 * series of (1 - exp(-x)) / x (either sign; the first term left out is
 * x^7/8! < 2e-11); a part without an end (rising forever) E_in H / dy.
 * inv_dy = 1 / dy (infinite for dy = 0). */
FP_FN_SIMD fp_vreal fp_height_od_from_bf(fp_real sigma, fp_real y0, fp_real H, fp_real top,
                                         fp_real oy, fp_vreal dy, fp_vreal inv_dy, fp_vreal len)
{
    fp_real inv_h = 1 / H, base = fmin(y0, top);
    fp_vint up = dy > FP_VR(0), down = dy < FP_VR(0);
    /* Below the base (density 1): from the origin until a rising ray
     * crosses it, or from where a falling one does. */
    fp_vreal t_base = (base - oy) * inv_dy, below;
    if (oy < base)
        below = up ? fmin(len, t_base) : len;
    else
        below = down ? fmax(len - t_base, FP_VR(0)) : FP_VR(0);
    fp_vreal above = FP_VR(0);
    if (y0 < top) {
        /* The part in the layer: its length s, entered at yc. */
        fp_vreal t_y0 = (y0 - oy) * inv_dy, t_top = (top - oy) * inv_dy, s;
        fp_real yc;
        if (oy < y0) {
            s = up ? fmax(fmin(len, t_top) - t_y0, FP_VR(0)) : FP_VR(0);
            yc = y0;
        } else if (oy < top) {
            fp_vreal not_up = down ? fmin(len, t_y0) : len;
            s = up ? fmin(len, t_top) : not_up;
            yc = oy;
        } else {
            s = down ? fmax(fmin(len, t_y0) - t_top, FP_VR(0)) : FP_VR(0);
            yc = top;
        }
        fp_real ya = (yc - y0) * inv_h, e_in = exp(-ya);
        fp_vreal x = dy * s * inv_h;
        fp_vreal series = fp_ratio_series(x);
        fp_vreal ends = H * inv_dy * (e_in - exp(-(ya + x)));
        fp_vreal bounded = fabs(x) < FP_VR(0.125) ? e_in * s * series : ends;
        /* Without an end: rising forever, or level (density e_in all the way). */
        fp_vreal level = FP_VR(e_in > 0 ? FP_INF : 0);
        fp_vreal endless = up ? e_in * H * inv_dy : level;
        above = isinf(s) ? endless : bounded;
    }
    fp_vreal od = sigma * (below + above);
    return sigma > 0 ? od : FP_VR(0);
}

FP_FN_SIMD void fp_clip_bf(fp_vreal o, fp_vreal dd, fp_real lo, fp_real hi, fp_vreal *a,
                           fp_vreal *b)
{
    fp_vreal inv = 1 / dd;
    fp_vreal u = (lo - o) * inv, v = (hi - o) * inv;
    fp_vint flat = dd == FP_VR(0), out = (o < FP_VR(lo)) | (o > FP_VR(hi));
    fp_vreal na = fmax(*a, fmin(u, v)), nb = fmin(*b, fmax(u, v));
    fp_vreal flat_b = out ? *a : *b;
    *b = flat ? flat_b : nb;
    *a = flat ? *a : na;
}

/* fp_fog_od for fog without a fogmap (FP_F_HAS_MAP 0), branch-free within
 * the lanes, from the origin o along the unit directions d, t in [0, len].
 * The branches here are on parameters, the same for every lane: no haze,
 * no box (every bound infinite: the clip leaves [0, len] as it is). */
FP_FN_SIMD fp_vreal fp_fog_od_nomap_bf(FP_CONSTANT const fp_real *fp, fp_real ox, fp_real oy,
                                       fp_real oz, fp_vreal dx, fp_vreal dy, fp_vreal dz,
                                       fp_vreal len)
{
    fp_vreal inv_dy = 1 / dy;
    fp_vreal od = FP_VR(0);
    if (fp[FP_F_HAZE] > 0)
        od = fp_height_od_from_bf(fp[FP_F_HAZE], fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2],
                                  fp[FP_F_HAZE + 3], oy, dy, inv_dy, len);
    fp_real c = fp[FP_F_COS], s = fp[FP_F_SIN];
    fp_real px = ox - fp[FP_F_OFF], py = oy - fp[FP_F_OFF + 1], pz = oz - fp[FP_F_OFF + 2];
    int boxed = 0;
    for (int i = 0; i < 6; i++)
        boxed |= !isinf(fp[FP_F_BOX + i]);
    if (!boxed)
        return od + fp_height_od_from_bf(fp[FP_F_SIGMA], fp[FP_F_Y0], fp[FP_F_H], fp[FP_F_TOP],
                                         py, dy, inv_dy, len);
    /* In the box: [a, b] of every lane its own, from its own height. */
    fp_vreal a = FP_VR(0), b = len;
    fp_clip_bf(FP_VR(c * px - s * pz), c * dx - s * dz, fp[FP_F_BOX], fp[FP_F_BOX + 3], &a, &b);
    fp_clip_bf(FP_VR(py), dy, fp[FP_F_BOX + 1], fp[FP_F_BOX + 4], &a, &b);
    fp_clip_bf(FP_VR(s * px + c * pz), s * dx + c * dz, fp[FP_F_BOX + 2], fp[FP_F_BOX + 5], &a,
               &b);
    fp_vreal fog_main = fp_height_od_bf(fp[FP_F_SIGMA], fp[FP_F_Y0], fp[FP_F_H], fp[FP_F_TOP],
                                        py + a * dy, dy, inv_dy, b - a);
    return od + (b > a ? fog_main : FP_VR(0));
}

#endif

/* fogpipe: the fog's parameter layout, its quadrature and the per-level
 * integral (kernels/fog_core.h gathers the fog's headers).
 *
 * The fog integrals along one view ray are written once and compiled
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
#ifndef FP_FOG_PARAMS_H
#define FP_FOG_PARAMS_H

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

#endif

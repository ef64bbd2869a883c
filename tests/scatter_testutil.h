/* What the tests split from tests/test_scatter.c share by job: their helpers,
 * fixtures and the sample scene (header-only; each test program uses
 * some of them). */
#ifndef FP_SCATTER_TESTUTIL_H
#define FP_SCATTER_TESTUTIL_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "camera.h"
#include "clrt.h"
#include "exrio.h"
#include "fogmap.h"
#include "fp.h"
#include "integrate.h"
#include "options.h"
#include "scatter.h"
#include "testutil.h"

/* The shared ray code in double precision (FP_F_*, FP_LT_*, fp_sigma_t,
 * fp_sun_tau, fp_shadow_map, fp_sun_visibility). */

#include "fog_core.h"
#include "light_core.h"
#include "scatter_core.h"
#include "shafts.h"
#include "scatter_lanes.h"

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-variable"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* ------------------------------------------------------------ helpers */

/* Parameters, fog and light data from option pairs (name, value, ...,
 * NULL), as the CLI would set them. */
typedef struct rig_t {
    fp_params_t p;
    fp_integrate_data_t fog;
    fp_scatter_data_t sd;
    fp_fogmap_stage_t fm;
    int has_fm;
} rig_t;

static int rig_apply(rig_t *r, const char *const *opts)
{
    for (int i = 0; opts && opts[i]; i += 2) {
        int rc = fp_options_apply(&r->p, opts[i], opts[i + 1], "test");
        if (rc)
            return rc;
    }
    return FP_OK;
}

/* Commit the integrate and scatter stages; fails the test on error. */
static void rig_open(rig_t *r, const char *const *opts)
{
    memset(r, 0, sizeof *r);
    fp_options_defaults(&r->p);
    assert_int_equal(rig_apply(r, opts), FP_OK);
    assert_int_equal(fp_integrate_commit(&r->p, &r->fog), FP_OK);
    assert_int_equal(fp_scatter_commit(&r->p, &r->sd), FP_OK);
}

/* The same with a fogmap from memory (w x h pixels). */
static void rig_open_map(rig_t *r, const char *const *opts, const float *img, int w, int h)
{
    rig_open(r, opts);
    assert_int_equal(fp_fogmap_setup(&r->p, NULL, img, w, h, &r->fm, &r->fog), FP_OK);
    r->has_fm = 1;
}

static void rig_close(rig_t *r)
{
    fp_scatter_release(&r->sd);
    if (r->has_fm)
        fp_fogmap_release(&r->fm);
    fp_options_free(&r->p);
}

/* One ray through fp_scatter_ray without a frame (no screen-space shadows). */
static double ray(const rig_t *r, const double o[3], const double d[3], double len, double S[3])
{
    fp_view_t nov;
    memset(&nov, 0, sizeof nov);
    return fp_scatter_ray(&r->sd, &r->fog, &nov, NULL, NULL, o, d, len, S);
}

static void unit(double v[3])
{
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++)
        v[i] /= n;
}

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* The fogmap tables as the kernels' C versions take them. */
static const float no_map[1] = { INFINITY };
#define TABLES(t) FP_TABLES(fp_fog_tables_or_empty(t))

/* Phase functions written out here (not phase.h's), normalized over the
 * sphere; mu = dot(view direction, direction toward the light). */
static double ph_hg(double g, double mu)
{
    return (1 - g * g) / (4 * M_PI * pow(1 + g * g - 2 * g * mu, 1.5));
}
static double ph_cs(double g, double mu)
{
    return 3 / (8 * M_PI) * (1 - g * g) * (1 + mu * mu) /
           ((2 + g * g) * pow(1 + g * g - 2 * g * mu, 1.5));
}
static double ph_ray(double mu) { return 3 / (16 * M_PI) * (1 + mu * mu); }

typedef struct phase_case_t {
    const char *spec;
    double (*fn)(const struct phase_case_t *, double);
    double g, w;
} phase_case_t;
static double pc_iso(const phase_case_t *c, double mu) { (void)c; (void)mu; return 1 / (4 * M_PI); }
static double pc_hg(const phase_case_t *c, double mu) { return ph_hg(c->g, mu); }
static double pc_cs(const phase_case_t *c, double mu) { return ph_cs(c->g, mu); }
static double pc_ray(const phase_case_t *c, double mu) { (void)c; return ph_ray(mu); }
static double pc_mix(const phase_case_t *c, double mu)
{
    return c->w * ph_ray(mu) + (1 - c->w) * ph_cs(c->g, mu);
}

/* Gauss-Legendre, 8 nodes on [-1, 1]. */
static const double gx8[8] = { -0.9602898564975363, -0.7966664774136267, -0.5255324099163290,
                               -0.1834346424956498, 0.1834346424956498, 0.5255324099163290,
                               0.7966664774136267, 0.9602898564975363 };
static const double gw8[8] = { 0.1012285362903763, 0.2223810344533745, 0.3137066458778873,
                               0.3626837833783620, 0.3626837833783620, 0.3137066458778873,
                               0.2223810344533745, 0.1012285362903763 };

typedef double (*fn1_t)(double t, void *ctx);

static double gl8(fn1_t f, void *c, double a, double b)
{
    double m = 0.5 * (a + b), h = 0.5 * (b - a), s = 0;
    for (int i = 0; i < 8; i++)
        s += gw8[i] * f(m + h * gx8[i], c);
    return s * h;
}

/* Adaptive Gauss-Legendre: split until the halves agree with the whole
 * to `tol` (absolute, per unit of length). */
static double adapt_rec(fn1_t f, void *c, double a, double b, double whole, double tol, int depth)
{
    double m = 0.5 * (a + b);
    double l = gl8(f, c, a, m), r = gl8(f, c, m, b);
    if (depth <= 0 || fabs(l + r - whole) <= fmax(tol * (b - a), 1e-14 * fabs(l + r)))
        return l + r;
    return adapt_rec(f, c, a, m, l, tol, depth - 1) + adapt_rec(f, c, m, b, r, tol, depth - 1);
}

/* Over the sorted breakpoints cut[0..n-1], each piece adaptively (and
 * first split into `pre` panels so nothing is missed). */
static double adapt(fn1_t f, void *c, const double *cut, int n, int pre, double tol)
{
    double s = 0;
    for (int i = 0; i + 1 < n; i++) {
        double a = cut[i], b = cut[i + 1];
        if (!(b > a))
            continue;
        for (int k = 0; k < pre; k++) {
            double x0 = a + (b - a) * k / pre, x1 = a + (b - a) * (k + 1) / pre;
            s += adapt_rec(f, c, x0, x1, gl8(f, c, x0, x1), tol, 30);
        }
    }
    return s;
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* ------------------------------------------------------------ 1. ambient */
/* ------------------------------------------------------------ 2. sun, closed form */

/* (1 - e^-x) / x, 1 at 0. */
static double g_ratio(double x) { return fabs(x) < 1e-12 ? 1 - 0.5 * x : -expm1(-x) / x; }

/* Sun single scattering in sigma0 e^{-(y - Y0)/H} (Y0 = 0, the whole ray
 * above it), from o along unit d for len, sun toward unit l, with (b > 0)
 * or without (b = 0) self-shadowing; per unit of albedo E p(mu).
 * u(y) = e^{-y/H}; od(0,t) = a (u0 - u(t)), a = sigma0 H / d_y;
 * od to the sun = b u, b = sigma0 H / l_y;
 *   S = int sigma0 u e^{-a (u0 - u)} e^{-b u} dt,  sigma0 u dt = -a du
 *     = a e^{-a u0} [e^{(a-b) u}]_{u1}^{u0} / (a - b)
 *     = e^{-b u0} od g(od - b w),  w = u0 - u1, od = a w (the ray's
 * optical depth), g(x) = (1 - e^-x) / x: the same expression for d_y < 0
 * (a < 0, w < 0), a = b (g(0) = 1), d_y = 0 (od = sigma0 u0 len, w = 0)
 * and sky rays (u1 = 0; level: od = inf, S = e^{-b u0}). */
static double sun_closed(double sigma0, double H, double oy, double dy, double ly, double len,
                         int self)
{
    double u0 = exp(-oy / H), b = self ? sigma0 * H / ly : 0;
    double od, w;
    if (dy == 0) {
        if (isinf(len))
            return exp(-b * u0);
        od = sigma0 * u0 * len;
        w = 0;
    } else {
        w = isinf(len) ? u0 : -u0 * expm1(-dy * len / H);
        od = sigma0 * H / dy * w;
    }
    return exp(-b * u0) * od * g_ratio(od - b * w);
}

/* The same integral by quadrature, to check the closed form itself. */
typedef struct { double sigma0, H, oy, dy, ly; int self; } sun_q_t;
static double sun_q_f(double t, void *cv)
{
    const sun_q_t *c = cv;
    double u0 = exp(-c->oy / c->H), u = exp(-(c->oy + t * c->dy) / c->H);
    double od = c->dy == 0 ? c->sigma0 * u0 * t : c->sigma0 * c->H / c->dy * (u0 - u);
    double b = c->self ? c->sigma0 * c->H / c->ly : 0;
    return c->sigma0 * u * exp(-od - b * u);
}
/* ------------------------------------------------------------ 3. local lights */

/* Sun, Ramamoorthi, Narasimhan, Nayar 2005: a point light of intensity I
 * in homogeneous fog (beta), isotropic phase, viewer at distance D_sv from
 * the light, gamma between the view ray and the direction to the light,
 * ray length D_vp.  With x = D cos g + D sin g tan phi along the ray
 * (d = D sin g sec phi, dx = D sin g sec^2 phi dphi):
 *   L = beta I / (4 pi) int e^{-beta x} e^{-beta d} / d^2 dx
 *     = beta I e^{-T cos g} / (4 pi D sin g) int e^{-T sin g (sec phi + tan phi)} dphi
 * over phi in [g - pi/2, atan((D_vp - D cos g) / (D sin g))]; sec + tan =
 * tan(pi/4 + phi/2), xi = pi/4 + phi/2:
 *   L = A0 [F(A1, pi/4 + atan((T_vp - T cos g) / (T sin g)) / 2) - F(A1, g/2)],
 * A0 = beta^2 I e^{-T cos g} / (2 pi T sin g), A1 = T sin g, T = beta D. */
typedef struct { double a1; } sun05_t;
static double sun05_f(double xi, void *c)
{
    double t = tan(xi);
    return isfinite(t) ? exp(-((sun05_t *)c)->a1 * t) : 0;
}

static double sun05(double beta, double I, double Dsv, double g, double Dvp)
{
    double T = beta * Dsv, Tvp = beta * Dvp;
    double A0 = beta * beta * I * exp(-T * cos(g)) / (2 * M_PI * T * sin(g));
    sun05_t c = { T * sin(g) };
    double x1 = isinf(Dvp) ? M_PI / 2
                           : M_PI / 4 + 0.5 * atan((Tvp - T * cos(g)) / (T * sin(g)));
    /* x1 >= g/2 for D_vp >= 0 (equal at D_vp = 0). */
    double cut[2] = { g / 2, x1 };
    return A0 * adapt(sun05_f, &c, cut, 2, 16, 1e-15);
}

/* Breakpoints for quadrature along a ray near a light: distances from
 * the closest point tc growing geometrically from h 2^-8 (h the light's
 * distance from the ray), within (0, end), appended to cut[n..]; the new
 * count (76 at most added). */
static int light_cuts(double tc, double h, double end, double *cut, int n)
{
    for (int k = -8; k < 30; k++) {
        double s = h * ldexp(1, k);
        if (tc - s > 0 && tc - s < end)
            cut[n++] = tc - s;
        if (tc + s > 0 && tc + s < end)
            cut[n++] = tc + s;
    }
    return n;
}

/* Brute force of the single-scattering integral of one point light in
 * homogeneous fog (sigma), any phase: adaptive quadrature in t with
 * breakpoints geometrically spaced about the closest point. */
typedef struct {
    double o[3], d[3], L[3], sigma, I;
    const phase_case_t *ph;
} light_bf_t;
static double light_bf_f(double t, void *cv)
{
    const light_bf_t *c = cv;
    double v[3];
    for (int i = 0; i < 3; i++)
        v[i] = c->L[i] - (c->o[i] + t * c->d[i]);
    double r = sqrt(dot3(v, v));
    double mu = dot3(v, c->d) / r;
    return c->sigma * exp(-c->sigma * (t + r)) * c->I / (r * r) * c->ph->fn(c->ph, mu);
}
static double light_bf(light_bf_t *c, double len)
{
    double q[3] = { c->L[0] - c->o[0], c->L[1] - c->o[1], c->L[2] - c->o[2] };
    double tc = dot3(q, c->d), h2 = dot3(q, q) - tc * tc, h = sqrt(fmax(h2, 0));
    double end = isinf(len) ? 40 / c->sigma : len;
    double cut[80];
    int n = 0;
    cut[n++] = 0;
    cut[n++] = end;
    n = light_cuts(tc, h, end, cut, n);
    if (tc > 0 && tc < end)
        cut[n++] = tc;
    qsort(cut, n, sizeof *cut, cmp_d);
    /* Tolerance: relative to a first estimate. */
    double est = adapt(light_bf_f, c, cut, n, 1, 1e-6);
    return adapt(light_bf_f, c, cut, n, 1, 1e-10 * est / end);
}

/* The ray o + t d and a light at distance D from o, at angle g from d. */
static void place_light(const double o[3], const double d[3], double D, double g, double L[3])
{
    double n[3] = { -d[2], 0, d[0] };
    unit(n);
    for (int i = 0; i < 3; i++)
        L[i] = o[i] + D * (cos(g) * d[i] + sin(g) * n[i]);
}
/* ------------------------------------------------------------ 4. self-shadowing */

/* The fogmap rectangle of test 4: w x h pixels of 2 x 1.5 units. */
#define MA0 (-10.0)
#define MB0 (-5.0)

/* A fog for self-shadowing: a random fogmap (pixels urand() * 2, the
 * B-spline makes it smooth), a sun. */
static void self_rig(rig_t *r, float **img, int w, int h, const char *density, const char *basis,
                     const char *wrap, const char *height, const char *box, const char *self,
                     const char *grid)
{
    char rect[128];
    snprintf(rect, sizeof rect, "%g,%g,%g,%g", MA0, MB0, MA0 + 2.0 * w, MB0 + 1.5 * h);
    *img = malloc((size_t)w * h * sizeof **img);
    for (int i = 0; i < w * h; i++)
        (*img)[i] = (float)(2 * urand());
    const char *opts[32] = { "density", density, "height", height, "fog-rect", rect, "basis", basis,
                             "fog-wrap", wrap, "levels", "2", "sun", "0.3,0.5,-0.4",
                             "self-shadow", self, "fog-color", "0,0,0" };
    int n = 18;
    if (box) {
        opts[n++] = "fog-box";
        opts[n++] = box;
    }
    if (grid) {
        opts[n++] = "self-shadow-grid";
        opts[n++] = grid;
    }
    opts[n] = NULL;
    rig_open_map(r, opts, *img, w, h);
}

/* Brute force: the midpoint rule for sigma_t (fp_sigma_t) along the sun
 * ray from p, with the pieces cut where sigma_t may jump or kink (the
 * box's faces, the fogmap rectangle's edges, Y0, TOP), steps of at most
 * `h`, up to TOP or to where exp(-(y - Y0)/H) < e^-40. */
static double sun_od_brute(const rig_t *r, const double p[3], const double l[3], double h)
{
    const double *fp = r->fog.fp;
    const fp_fog_tables_t *t = r->fog.tables;
    double yend = isfinite(fp[FP_F_TOP]) ? fp[FP_F_TOP] : fp[FP_F_Y0] + 40 * fp[FP_F_H];
    double end = (yend - p[1]) / l[1];
    if (!(end > 0))
        return 0;
    double cut[32];
    int n = 0;
    cut[n++] = 0;
    cut[n++] = end;
    double planes[3][6];
    int np[3] = { 0, 0, 0 };
    for (int a = 0; a < 3; a++) {
        planes[a][np[a]++] = fp[FP_F_BOX + a];
        planes[a][np[a]++] = fp[FP_F_BOX + 3 + a];
    }
    planes[1][np[1]++] = fp[FP_F_Y0];
    for (int k = 0; k < 2; k++) {
        planes[0][np[0]++] = (fp[FP_F_CLIP + k] - fp[FP_F_PAD_X0]) / fp[FP_F_USCALE] + fp[FP_F_A0];
        planes[2][np[2]++] =
            (fp[FP_F_CLIP + 2 + k] - fp[FP_F_PAD_Y0]) / fp[FP_F_VSCALE] + fp[FP_F_B0];
    }
    for (int a = 0; a < 3; a++)
        for (int k = 0; k < np[a]; k++) {
            double s = (planes[a][k] - p[a]) / l[a];
            if (isfinite(s) && s > 0 && s < end)
                cut[n++] = s;
        }
    qsort(cut, n, sizeof *cut, cmp_d);
    double od = 0;
    for (int i = 0; i + 1 < n; i++) {
        double a = cut[i], b = cut[i + 1];
        if (!(b > a))
            continue;
        long m = (long)ceil((b - a) / h);
        double step = (b - a) / m;
        for (long k = 0; k < m; k++) {
            double s = a + (k + 0.5) * step;
            od += step * fp_sigma_t(fp, t->lvi, t->lvf, t->coef, p[0] + s * l[0], p[1] + s * l[1],
                                    p[2] + s * l[2]);
        }
    }
    return od;
}

static double tau_of(const rig_t *r, const double p[3])
{
    const fp_fog_tables_t *t = r->fog.tables;
    return fp_sun_tau(r->fog.fp, TABLES(t), r->sd.lt, r->sd.grid ? r->sd.grid : no_map, p[0],
                      p[1], p[2]);
}
/* --self-shadow map at points along the view rays of a frame (view v,
 * depth): the grid's tau_sun against the exact optical depth toward the
 * sun (fp_fog_od, checked against brute force above), relative error, at
 * npts points uniform in distance over each ray's fog up to `reach` from
 * the camera.  *outside: the share of those points that no cascade holds
 * (integrated exactly). */
static double grid_view_error(const rig_t *r, const fp_view_t *v, const float *depth, double reach,
                              int npts, double *outside)
{
    const double *lt = r->sd.lt, *l = lt + FP_LT_SUN_DIR;
    const fp_fog_tables_t *t = r->fog.tables;
    double worst = 0;
    int out = 0, n = 0;
    for (int tries = 0; n < npts && tries < 100 * npts; tries++) {
        int x = (int)(urand() * v->width), y = (int)(urand() * v->height);
        double dir[3], len, o[3], ta, tb;
        fp_view_ray(v, x, y, depth[y * v->width + x], dir, &len);
        fp_view_origin_at(v, x, y, o);
        if (!fp_fog_span(r->fog.fp, o[0], o[1], o[2], dir[0], dir[1], dir[2], len, &ta, &tb) ||
            !(ta < reach))
            continue;
        double tt = ta + urand() * (fmin(tb, reach) - ta), p[3];
        for (int i = 0; i < 3; i++)
            p[i] = o[i] + tt * dir[i];
        double og = fp_sun_od_grid(lt, r->sd.grid, p[0], p[1], p[2]);
        n++;
        if (og < -0.5) {
            out++;
            continue;
        }
        double oe =
            fp_fog_od(r->fog.fp, TABLES(t), p[0], p[1], p[2], l[0], l[1], l[2], INFINITY, 0);
        if (isinf(oe) && isinf(og))
            continue;
        worst = fmax(worst, fabs(expm1(oe - og)));
    }
    *outside = n ? (double)out / n : 0;
    return worst;
}

/* --self-shadow map: the cascades of exact values at their nodes,
 * trilinear between them, over the boxes fp_scatter_frame gives them,
 * filled by fp_scatter_process, against the same brute force: at points
 * spread over the cascades' boxes (err[0]) and at points along the
 * frame's view rays, up to 60 units from the camera, where the integrator
 * looks it up (err[1]). */
static void grid_error(const char *density, const char *height, const char *wrap, const char *grid,
                       int npts, double cell[3], double err[2])
{
    rig_t r;
    float *img = NULL;
    if (wrap) {
        self_rig(&r, &img, 13, 9, density, "cubic", wrap, height, NULL, "map", grid);
    } else {
        const char *opts[] = { "density", density, "height", height, "sun", "0.3,0.5,-0.4",
                               "self-shadow", "map", "fog-color", "0,0,0", NULL };
        rig_open(&r, opts);
    }
    const int w = 16, h = 12;
    fp_view_t v;
    assert_int_equal(make_view(&v, w, h, 3, -20), 0);
    float depth[16 * 12], *out = malloc((size_t)w * h * 4 * sizeof *out);
    for (int i = 0; i < w * h; i++)
        depth[i] = urand() < 0.2 ? INFINITY : (float)(1 + 40 * urand());
    assert_int_equal(fp_scatter_frame(&r.p, &r.sd, &r.fog, &v, depth, 1), FP_OK);
    assert_int_equal(fp_scatter_process(&r.sd, &r.fog, &v, depth, out), FP_OK);
    assert_non_null(r.sd.grid);
    const double *lt = r.sd.lt, *l = lt + FP_LT_SUN_DIR;
    /* The finest cascade's cell (a, b across the sun, s along it). */
    for (int i = 0; i < 3; i++)
        cell[i] = lt[FP_LT_CASCADE + 3 + i];
    err[0] = err[1] = 0;
    int K = (int)lt[FP_LT_GRID_K];
    for (int k = 0; k < 2 * npts; k++) {
        double p[3];
        if (k < npts) {
            const double *box = lt + FP_LT_CASCADE + 6 * (int)(urand() * K);
            double q[3];
            for (int i = 0; i < 3; i++)
                q[i] = box[i] + urand() * box[3 + i] * (lt[FP_LT_GRID_N + i] - 1);
            for (int i = 0; i < 3; i++)
                p[i] = q[0] * lt[FP_LT_SUN_E1 + i] + q[1] * lt[FP_LT_SUN_E2 + i] + q[2] * l[i];
        } else {
            int x = (int)(urand() * w), y = (int)(urand() * h);
            double dir[3], len;
            fp_view_ray(&v, x, y, depth[y * w + x], dir, &len);
            double t = urand() * fmin(len, 60);
            for (int i = 0; i < 3; i++)
                p[i] = v.origin[i] + t * dir[i];
        }
        /* Inside the grid: its value, not the -1 of "outside" (tiny
         * negative optical depths from rounding do occur at its nodes).
         * A view ray's point outside it (beyond the fog's span) is
         * integrated exactly: not the grid's, skipped. */
        double og = fp_sun_od_grid(lt, r.sd.grid, p[0], p[1], p[2]);
        if (k >= npts && og < -0.5) {
            k--;
            continue;
        }
        assert_true(og > -1e-6);
        /* Brute force with a fogmap; without one the exact path (its
         * closed form, checked against brute force above) is the judge. */
        double tb;
        if (wrap) {
            tb = exp(-sun_od_brute(&r, p, l, 0.01));
        } else {
            double o[3] = { p[0], p[1], p[2] }, dl[3] = { l[0], l[1], l[2] };
            tb = exp(-fp_integrate_optical_depth(&r.fog, o, dl, INFINITY, 0));
        }
        double tg = tau_of(&r, p);
        err[k >= npts] = fmax(err[k >= npts], fabs(tg - tb) / tb);
    }
    free(out);
    rig_close(&r);
    free(img);
}
/* ------------------------------------------------------------ the sample scene */

/* samples/fogpipe-scene, run once into a temporary directory: a 64x48 frame 1
 * (scene.0001.exr), its sun map (shadow.0001.exr, 512 texels) and the
 * fogmap.  $FP_SCENE (make check) or next to the test binary. */
static const char *test_argv0 = "tests/test_scatter";
static char scene_dir[4096];
static int scene_made;   /* 1 made, -1 no generator */

static const char *sample_scene(void)
{
    if (scene_made)
        return scene_made > 0 ? scene_dir : NULL;
    char gen[4096];
    const char *env = getenv("FP_SCENE");
    if (env && *env) {
        snprintf(gen, sizeof gen, "%s", env);
    } else {
        /* tests/test_scatter -> samples/fogpipe-scene (an in-tree or VPATH build). */
        snprintf(gen, sizeof gen, "%s", test_argv0);
        char *slash = strrchr(gen, '/');
        if (slash)
            snprintf(slash, gen + sizeof gen - slash, "/../samples/fogpipe-scene");
        else
            snprintf(gen, sizeof gen, "../samples/fogpipe-scene");
    }
    if (access(gen, X_OK) != 0) {
        print_message("no sample scene generator at %s (set FP_SCENE)\n", gen);
        scene_made = -1;
        return NULL;
    }
    const char *tmp = getenv("FP_TMP");
    char templ[4096];
    if (tmp && *tmp) {
        mkdir(tmp, 0777);
        snprintf(templ, sizeof templ, "%s/test_scatter.XXXXXX", tmp);
    } else {
        snprintf(templ, sizeof templ, "/tmp/fp-test-scatter.XXXXXX");
    }
    assert_non_null(mkdtemp(templ));
    snprintf(scene_dir, sizeof scene_dir, "%s", templ);
    char cmd[8400];
    snprintf(cmd, sizeof cmd, "'%s' -o '%s' --width 64 --height 48 --frames 1-1 --shadow-size 512",
             gen, scene_dir);
    if (system(cmd) != 0)
        fail_msg("%s failed", cmd);
    scene_made = 1;
    return scene_dir;
}

static void remove_scene(void)
{
    if (scene_made <= 0)
        return;
    static const char *const files[] = { "scene.0001.exr", "shadow.0001.exr", "fogmap.exr" };
    char path[4400];
    for (size_t i = 0; i < FP_ARRAY_LEN(files); i++) {
        snprintf(path, sizeof path, "%s/%s", scene_dir, files[i]);
        unlink(path);
    }
    rmdir(scene_dir);
}

/* Frame 1 of the sample scene: the frame, its view, the fog (with the
 * sample fogmap when asked) and this frame's light data. */
typedef struct scene_t {
    rig_t r;
    fp_frame_t *f;
    fp_view_t v;
    const float *depth;
    int w, h;
} scene_t;

static int scene_open(scene_t *sc, const char *const *opts, int fogmap)
{
    const char *dir = sample_scene();
    if (!dir)
        return -1;
    memset(sc, 0, sizeof *sc);
    rig_t *r = &sc->r;
    fp_options_defaults(&r->p);
    char fm[4400], sm[4400], scene[4400];
    snprintf(fm, sizeof fm, "%s/fogmap.exr", dir);
    snprintf(sm, sizeof sm, "%s/shadow.%%04d.exr", dir);
    snprintf(scene, sizeof scene, "%s/scene.0001.exr", dir);
    /* The fogmap's placement first: opts may change its basis. */
    if (fogmap) {
        static const char *const fo[] = { "fog-rect", "-60,-20,60,160", "basis", "quadratic",
                                          "levels", "3", NULL };
        assert_int_equal(rig_apply(r, fo), FP_OK);
        assert_int_equal(fp_options_apply(&r->p, "fogmap", fm, "test"), FP_OK);
    }
    assert_int_equal(rig_apply(r, opts), FP_OK);
    for (int i = 0; opts[i]; i += 2)
        if (strcmp(opts[i], "shadow-map") == 0)
            assert_int_equal(fp_options_apply(&r->p, "shadow-map", sm, "test"), FP_OK);
    assert_int_equal(fp_integrate_commit(&r->p, &r->fog), FP_OK);
    assert_int_equal(fp_scatter_commit(&r->p, &r->sd), FP_OK);
    int active = 0;
    assert_int_equal(fp_fogmap_commit(&r->p, NULL, &r->fm, &r->fog, &active), FP_OK);
    r->has_fm = 1;
    assert_int_equal(active, fogmap);
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    assert_int_equal(fp_exr_read_file(scene, 1, &sel, &sc->f), FP_OK);
    const fp_frame_info_t *info = fp_frame_info(sc->f);
    fp_camera_t cam;
    assert_int_equal(fp_camera_resolve(&r->p, info, scene, 1, &cam), FP_OK);
    assert_int_equal(fp_view_setup(&cam, &r->p, info, &sc->v), FP_OK);
    assert_int_equal(fp_fogmap_frame(&r->p, NULL, &r->fm, 1, &sc->v, &r->fog), FP_OK);
    sc->depth = fp_frame_depth(sc->f);
    sc->w = info->width;
    sc->h = info->height;
    assert_int_equal(fp_scatter_frame(&r->p, &r->sd, &r->fog, &sc->v, sc->depth, 1), FP_OK);
    return 0;
}

static void scene_close(scene_t *sc)
{
    fp_frame_free(sc->f);
    rig_close(&sc->r);
}
/* ------------------------------------------------------------ 5. OpenCL parity */

/* The OpenCL device with the integrate and scatter stages on it; skips
 * the test where there is no device. */
typedef struct cl_rig_t {
    fp_cl_t *cl;
    fp_integrate_cl_t icl;
    fp_scatter_cl_t scl;
} cl_rig_t;

static void cl_rig_open(cl_rig_t *c)
{
    c->cl = NULL;
    if (fp_cl_open(NULL, &c->cl) != FP_OK) {
        print_message("no OpenCL device: skipped\n");
        skip();
    }
    assert_int_equal(fp_integrate_cl_init(c->cl, &c->icl), FP_OK);
    assert_int_equal(fp_scatter_cl_init(c->cl, &c->scl), FP_OK);
}

static void cl_rig_close(cl_rig_t *c)
{
    fp_scatter_cl_release(&c->scl);
    fp_integrate_cl_release(&c->icl);
    fp_cl_close(c->cl);
}
/* ------------------------------------------------------------ 5b. fast local lights */

/* Brute force of one local light's in-scatter (S.r without the color) in
 * any fog without a fogmap: adaptive quadrature in t of
 * albedo sigma(t) e^{-od(o,t) - od(t,light)} I cone p(mu) / r^2, with
 * fp_sigma_t and the exact optical depths (fp_fog_od, closed forms checked
 * above), cut geometrically about the closest point and where the ray
 * crosses Y0 and TOP. */
typedef struct {
    const rig_t *r;
    double o[3], d[3];
    const double *row;
} light_gen_t;
static double light_gen_f(double t, void *cv)
{
    const light_gen_t *c = cv;
    const double *fp = c->r->fog.fp, *lt = c->r->sd.lt, *row = c->row;
    double p[3], v[3];
    for (int i = 0; i < 3; i++) {
        p[i] = c->o[i] + t * c->d[i];
        v[i] = row[FP_LL_POS + i] - p[i];
    }
    double r = sqrt(dot3(v, v));
    for (int i = 0; i < 3; i++)
        v[i] /= r;
    double sig = fp_sigma_t(fp, NULL, NULL, NULL, p[0], p[1], p[2]);
    if (!(sig > 0))
        return 0;
    double od = fp_fog_od(fp, NULL, NULL, NULL, NULL, c->o[0], c->o[1], c->o[2], c->d[0],
                          c->d[1], c->d[2], t, 0) +
                fp_fog_od(fp, NULL, NULL, NULL, NULL, p[0], p[1], p[2], v[0], v[1], v[2], r, 0);
    double cone = fp_light_gain(row, -v[0], -v[1], -v[2], r);
    return lt[FP_LT_ALBEDO] * sig * exp(-od) * row[FP_LL_I] * cone *
           fp_phase((int)lt[FP_LT_PHASE], lt[FP_LT_PHASE + 1], lt[FP_LT_PHASE + 2],
                    dot3(v, c->d)) / (r * r);
}
static double light_gen(const rig_t *r, const double o[3], const double d[3], double len)
{
    light_gen_t c = { r, { o[0], o[1], o[2] }, { d[0], d[1], d[2] }, r->sd.lights };
    const double *row = c.row, *fp = r->fog.fp;
    double q[3] = { row[FP_LL_POS] - o[0], row[FP_LL_POS + 1] - o[1], row[FP_LL_POS + 2] - o[2] };
    double tc = dot3(q, d), h = sqrt(fmax(dot3(q, q) - tc * tc, 0));
    double end = isinf(len) ? 4000 : len;
    double cut[100];
    int n = 0;
    cut[n++] = 0;
    cut[n++] = end;
    n = light_cuts(tc, h, end, cut, n);
    double ys[2] = { fp[FP_F_Y0], fp[FP_F_TOP] };
    for (int i = 0; i < 2; i++) {
        double t = (ys[i] - o[1]) / d[1];
        if (t > 0 && t < end)
            cut[n++] = t;
    }
    if (tc > 0 && tc < end)
        cut[n++] = tc;
    qsort(cut, n, sizeof *cut, cmp_d);
    double est = adapt(light_gen_f, &c, cut, n, 2, 1e-6);
    return adapt(light_gen_f, &c, cut, n, 2, 1e-9 * fmax(est, 1e-30) / end);
}
/* ------------------------------------------------------------ 6. shadows */

/* The sample scene's casters (samples/scene.c), for the chosen points'
 * ground truth: boxes and spheres, the sun toward (-0.4, 0.35, 0.6). */
static const double scene_boxes[][6] = {
    { -40, 0, 40, -17, 6, 41 }, { -15, 0, 40, -7, 6, 41 }, { -5, 0, 40, -3.5, 6, 41 },
    { -3, 0, 40, -1.5, 6, 41 }, { -1, 0, 40, 0.5, 6, 41 }, { 1, 0, 40, 3, 6, 41 },
    { 5, 0, 40, 13, 6, 41 },    { 15, 0, 40, 40, 6, 41 },  { -11.3, 0, 34, -10.7, 5, 34.6 },
    { -6.3, 0, 34, -5.7, 5, 34.6 }, { 2.7, 0, 34, 3.3, 5, 34.6 }, { 11.7, 0, 34, 12.3, 5, 34.6 },
    { -8, 0, 20, -5, 3, 23 },
    { 6, 0, 15, 9, 5, 18 },     { -20, 0, 80, -12, 25, 88 }, { 10, 0, 110, 20, 40, 120 },
    { -45, 0, 140, -28, 18, 150 }, { 30, 0, 60, 36, 12, 66 },
};
static const double scene_spheres[][4] = { { 0, 1, 12, 1 }, { -3, 0.7, 8, 0.7 }, { 4, 2, 30, 2 } };

static int scene_occluded(const double p[3], const double l[3])
{
    for (size_t i = 0; i < FP_ARRAY_LEN(scene_boxes); i++) {
        double a = 0, b = INFINITY;
        for (int k = 0; k < 3; k++)
            fp_clip(p[k], l[k], scene_boxes[i][k], scene_boxes[i][k + 3], &a, &b);
        if (b > a)
            return 1;
    }
    for (size_t i = 0; i < FP_ARRAY_LEN(scene_spheres); i++) {
        const double *c = scene_spheres[i];
        double q[3] = { p[0] - c[0], p[1] - c[1], p[2] - c[2] };
        double bb = dot3(q, l), cc = dot3(q, q) - c[3] * c[3], disc = bb * bb - cc;
        if (disc >= 0 && -bb + sqrt(disc) > 0)
            return 1;
    }
    return 0;
}
/* A view from options: camera at pos looking at target (OpenEXR camera,
 * square pixels). */
static void make_view_at(fp_view_t *v, int w, int h, const char *pos, const char *target,
                         const char *vfov)
{
    fp_params_t p;
    fp_options_defaults(&p);
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.width = info.disp_w = w;
    info.height = info.disp_h = h;
    info.pixel_aspect = 1;
    assert_int_equal(fp_options_apply(&p, "camera-pos", pos, "test"), FP_OK);
    assert_int_equal(fp_options_apply(&p, "camera-target", target, "test"), FP_OK);
    assert_int_equal(fp_options_apply(&p, "vfov", vfov, "test"), FP_OK);
    fp_camera_t c;
    assert_int_equal(fp_camera_resolve(&p, &info, "synthetic", 1, &c), FP_OK);
    assert_int_equal(fp_view_setup(&c, &p, &info, v), FP_OK);
    fp_options_free(&p);
}

/* Screen-space shadows on a synthetic depth buffer: a wall at z = 10
 * (planar depth 10) over the pixels that look toward -x, sky elsewhere;
 * the sun beyond it, toward +z and up (light shafts toward the camera).
 * A point in front of the wall whose sun ray meets it is in shadow; one
 * beside it (its ray misses the wall) or behind it (beyond the assumed
 * thickness: nothing the camera sees is between it and the sun) is lit. */
/* The biased map (fp_shafts_build, written without library calls per
 * texel) against its definition with fmin and nextafterf, bit for bit, on
 * maps with undefined (NaN), infinite and zero depths, and edges. */
static double shafts_one_sided(const float *z, int w, int h, int i, int j, int di, int dj)
{
    double c = z[(size_t)j * w + i], best = INFINITY;
    for (int s = -1; s <= 1; s += 2) {
        int a = i + s * di, b = j + s * dj;
        if (a < 0 || b < 0 || a >= w || b >= h)
            continue;
        double v = z[(size_t)b * w + a];
        if (isfinite(v))
            best = fmin(best, fabs(v - c));
    }
    return isfinite(best) ? best : 0;
}
/* ------------------------------------------------------------ 7. options */

/* Apply one option to fresh parameters, capturing the messages. */
static int try_option(const char *name, const char *value, char *msg, size_t cap)
{
    fp_params_t p;
    fp_options_defaults(&p);
    fp_msgbuf_t buf;
    memset(&buf, 0, sizeof buf);
    fp_msgbuf_t *prev = fp_msg_capture(&buf);
    int rc = fp_options_apply(&p, name, value, "test");
    fp_msg_capture(prev);
    size_t n = buf.len < cap - 1 ? buf.len : cap - 1;
    memcpy(msg, buf.text ? buf.text : "", n);
    msg[n] = 0;
    fp_msg_free(&buf);
    fp_options_free(&p);
    return rc;
}

static void expect_usage(const char *name, const char *value, const char *in_msg)
{
    char msg[2048];
    int rc = try_option(name, value, msg, sizeof msg);
    if (rc != FP_EUSAGE)
        fail_msg("--%s %s: status %d, expected FP_EUSAGE", name, value, rc);
    if (!strstr(msg, in_msg) || !strstr(msg, value) || strchr(msg, '\n') != msg + strlen(msg) - 1)
        fail_msg("--%s %s: message '%s' should be one line naming the value and '%s'", name,
                 value, msg, in_msg);
}

static void expect_ok(const char *name, const char *value)
{
    char msg[2048];
    int rc = try_option(name, value, msg, sizeof msg);
    if (rc != FP_OK || msg[0])
        fail_msg("--%s %s: status %d, message '%s'; expected it accepted", name, value, rc, msg);
}

#pragma GCC diagnostic pop

#endif

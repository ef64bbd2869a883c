/* What the tests split from tests/test_reference.c share by job: their helpers,
 * fixtures and the sample scene (header-only; each test program uses
 * some of them). */
#ifndef FP_REFERENCE_TESTUTIL_H
#define FP_REFERENCE_TESTUTIL_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "camera.h"
#include "clrt.h"
#include "exrio.h"
#include "fogmap.h"
#include "fp.h"
#include "integrate.h"
#include "options.h"
#include "reference.h"
#include "scatter.h"
#include "testutil.h"

#include "fog_core.h"   /* FP_F_* slots */
#include "light_core.h" /* FP_LT_* slots */
#include "reference_core.h" /* FP_RP_* slots */

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-variable"

#define PI 3.14159265358979323846

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* ------------------------------------------------------------ scenes */

typedef struct scene_t {
    fp_params_t p;
    fp_integrate_data_t fog;
    fp_fogmap_stage_t fm;
    int has_map;
    float *img;
    fp_scatter_data_t sd;
    fp_view_t v;
    float *depth;
    int w, h;
} scene_t;

/* Options as name, value pairs ending with NULL. */
static void apply(fp_params_t *p, const char *const *opts)
{
    for (int k = 0; opts && opts[k]; k += 2)
        if (fp_options_apply(p, opts[k], opts[k + 1], "test") != FP_OK)
            fail_msg("option --%s %s refused", opts[k], opts[k + 1]);
}

/* A w x h frame of the wide test camera (tests/testutil.h) at height
 * cam_y: pixels whose ray rises more than `sky_dy` see the sky, the others
 * a surface at a planar depth between 4 and 40.  With `map`, a random
 * 24 x 20 fogmap over the rectangle -30,-10,30,40. */
static void scene_make(scene_t *sc, int w, int h, double cam_y, double pitch, double sky_dy,
                       int map, const char *const *opts)
{
    memset(sc, 0, sizeof *sc);
    assert_int_equal(fp_options_defaults(&sc->p), FP_OK);
    apply(&sc->p, opts);
    sc->p.reference.spp = 64;
    assert_int_equal(fp_integrate_commit(&sc->p, &sc->fog), FP_OK);
    if (map) {
        const int mw = 24, mh = 20;
        sc->img = malloc((size_t)mw * mh * sizeof(float));
        for (int i = 0; i < mw * mh; i++)
            sc->img[i] = (float)(urand() < 0.2 ? 0 : 2 * urand());
        const char *const mo[] = { "fog-rect", "-30,-10,30,40", "basis", "quadratic", "levels",
                                   "2", NULL };
        apply(&sc->p, mo);
        assert_int_equal(fp_fogmap_setup(&sc->p, NULL, sc->img, mw, mh, &sc->fm, &sc->fog), FP_OK);
        sc->has_map = 1;
    }
    sc->w = w;
    sc->h = h;
    assert_int_equal(make_view(&sc->v, w, h, cam_y, pitch), 0);
    sc->depth = malloc((size_t)w * h * sizeof(float));
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double dir[3], len;
            fp_view_ray(&sc->v, x, y, 1.0f, dir, &len);
            unsigned hsh = (unsigned)(x * 7919 + y * 104729) % 1000;
            sc->depth[y * w + x] = dir[1] > sky_dy ? INFINITY : (float)(4 + 36 * hsh / 1000.0);
        }
    assert_int_equal(fp_scatter_commit(&sc->p, &sc->sd), FP_OK);
    assert_int_equal(fp_scatter_frame(&sc->p, &sc->sd, &sc->fog, &sc->v, sc->depth, 1), FP_OK);
}

static void scene_free(scene_t *sc)
{
    fp_scatter_release(&sc->sd);
    if (sc->has_map)
        fp_fogmap_release(&sc->fm);
    fp_options_free(&sc->p);
    free(sc->img);
    free(sc->depth);
}

/* Normalized errors of a against b, with standard errors sa (and sb, may
 * be NULL), over n pixels x 4 channels: the largest |z| and the rms.  The
 * standard errors get a floor: floor_abs, float rounding, and rel_floor
 * times the value.  The last is the resolution of stratified runs: R runs
 * of N samples each resolve a step in the integrand (whether the flight
 * collides before the ray's end, a shadow's edge) to about 1 / (N sqrt R)
 * of the value, an error the spread of the runs can miss (with few runs,
 * all of them may count the same number of samples on one side). */
static void zstats(const float *a, const float *sa, const float *b, const float *sb, size_t n,
                   double floor_abs, double rel_floor, double *zmax, double *zrms, size_t *at)
{
    double m = 0, s2 = 0;
    size_t cnt = 0;
    *at = 0;
    for (size_t i = 0; i < 4 * n; i++) {
        double se2 = (double)sa[i] * sa[i] + (sb ? (double)sb[i] * sb[i] : 0);
        double se = sqrt(se2) + floor_abs + (1e-6 + rel_floor) * fabs(b[i]);
        double z = ((double)a[i] - b[i]) / se;
        if (!isfinite(z))
            z = a[i] == b[i] ? 0 : INFINITY;
        if (fabs(z) > m) {
            m = fabs(z);
            *at = i;
        }
        s2 += z * z;
        cnt++;
    }
    *zmax = m;
    *zrms = sqrt(s2 / cnt);
}

/* R independent runs (seeds seed0 + k) of spp samples each, by the C
 * version or OpenCL (rc): their mean and its standard error from the
 * spread of the runs, which is honest for the stratified estimator (the
 * samples of one run are not independent draws). */
static void replicas(scene_t *sc, fp_reference_cl_t *rc, const fp_reference_opts_t *o, int R,
                     int spp, int seed0, float *mean, float *se)
{
    size_t n = (size_t)sc->w * sc->h;
    double *s1 = calloc(4 * n, sizeof *s1), *s2 = calloc(4 * n, sizeof *s2);
    float *one = malloc(4 * n * sizeof *one);
    assert_non_null(s1);
    assert_non_null(s2);
    assert_non_null(one);
    sc->p.reference.spp = spp;
    for (int k = 0; k < R; k++) {
        sc->p.anim.seed = seed0 + k;
        if (rc)
            assert_int_equal(fp_reference_process_cl_se(rc, &sc->p, &sc->sd, &sc->fog, &sc->v,
                                                        sc->depth, o, one, NULL), FP_OK);
        else
            assert_int_equal(fp_reference_process_se(&sc->p, &sc->sd, &sc->fog, &sc->v,
                                                     sc->depth, o, one, NULL), FP_OK);
        for (size_t i = 0; i < 4 * n; i++) {
            s1[i] += one[i];
            s2[i] += (double)one[i] * one[i];
        }
    }
    for (size_t i = 0; i < 4 * n; i++) {
        double m = s1[i] / R;
        mean[i] = (float)m;
        se[i] = (float)sqrt(fmax(s2[i] - R * m * m, 0) / (R - 1) / R);
    }
    free(s1);
    free(s2);
    free(one);
}

/* ------------------------------------------------------------ slab */

static fp_integrate_data_t fog_of(const char *const *opts)
{
    fp_params_t p;
    fp_integrate_data_t d;
    assert_int_equal(fp_options_defaults(&p), FP_OK);
    apply(&p, opts);
    assert_int_equal(fp_integrate_commit(&p, &d), FP_OK);
    fp_options_free(&p);
    return d;
}
/* A random fogmap (every wrap mode, turned fog, exponential height,
 * haze): delta tracking's pass fraction and ratio tracking (residual, with
 * the majorant grid) against exp(-optical depth) from the exact
 * integrator, within 3.5 standard errors, over random rays. */
typedef struct mapfog_t {
    fp_params_t p;
    fp_integrate_data_t fog;
    fp_fogmap_stage_t fm;
    float *img;
} mapfog_t;

static void mapfog_make(mapfog_t *m, int trial, int mw, int mh)
{
    int degree = trial % 4, wrap = (trial / 4) % 3;
    assert_int_equal(fp_options_defaults(&m->p), FP_OK);
    char rot[32], off[64];
    snprintf(rot, sizeof rot, "%g", 360 * urand());
    snprintf(off, sizeof off, "%g,%g,%g", 10 * urand() - 5, 2 * urand() - 1, 10 * urand() - 5);
    const char *const opts[] = {
        "density", "0.07", "height", trial % 2 ? "1,6,30" : "0,4", "haze",
        trial % 3 ? "0.01" : "0", "haze-height", "2,9", "fog-box",
        trial % 5 == 0 ? "-inf,-inf,-inf,inf,inf,inf" : "-25,-3,-12,20,25,30", "fog-rotate", rot,
        "fog-offset", off, "fog-rect", "-20,-15,25,30", "basis",
        (const char *[]){ "haar", "linear", "quadratic", "cubic" }[degree], "fog-wrap",
        (const char *[]){ "zero", "clamp", "repeat" }[wrap], "levels", "2", NULL };
    apply(&m->p, opts);
    assert_int_equal(fp_integrate_commit(&m->p, &m->fog), FP_OK);
    m->img = malloc((size_t)mw * mh * sizeof *m->img);
    for (int i = 0; i < mw * mh; i++)
        m->img[i] = (float)(urand() < 0.3 ? 0 : 3 * urand() * urand());
    assert_int_equal(fp_fogmap_setup(&m->p, NULL, m->img, mw, mh, &m->fm, &m->fog), FP_OK);
}

static void mapfog_free(mapfog_t *m)
{
    fp_fogmap_release(&m->fm);
    fp_options_free(&m->p);
    free(m->img);
}

static void random_ray(const double lo[3], const double hi[3], int level, double o[3], double d[3])
{
    for (int i = 0; i < 3; i++)
        o[i] = lo[i] - 10 + (hi[i] - lo[i] + 20) * urand();
    double nn;
    do {
        for (int i = 0; i < 3; i++)
            d[i] = 2 * urand() - 1;
        if (level)
            d[1] = 0;
        nn = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    } while (nn < 0.1 || nn > 1);
    for (int i = 0; i < 3; i++)
        d[i] /= nn;
}
/* ------------------------------------------------------------ majorant */

/* Gauss-Legendre (8 nodes, 16 panels) of the control over a segment,
 * between the heights where a profile has a kink or a step. */
static double control_quadrature(const fp_integrate_data_t *fog, const double o[3],
                                 const double d[3], const double *q)
{
    static const double gx[8] = { -0.9602898564975363, -0.7966664774136267, -0.5255324099163290,
                                  -0.1834346424956498, 0.1834346424956498, 0.5255324099163290,
                                  0.7966664774136267, 0.9602898564975363 };
    static const double gw[8] = { 0.1012285362903763, 0.2223810344533745, 0.3137066458778873,
                                  0.3626837833783620, 0.3626837833783620, 0.3137066458778873,
                                  0.2223810344533745, 0.1012285362903763 };
    const double *fp = fog->fp;
    double ys[4] = { fp[FP_F_Y0] + fp[FP_F_OFF + 1], fp[FP_F_TOP] + fp[FP_F_OFF + 1],
                     fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 3] };
    double cut[6] = { q[0], q[1] };
    int nc = 2;
    for (int i = 0; i < 4 && d[1] != 0; i++) {
        double t = (ys[i] - o[1]) / d[1];
        if (t > q[0] && t < q[1])
            cut[nc++] = t;
    }
    for (int i = 0; i < nc; i++)
        for (int j = i + 1; j < nc; j++)
            if (cut[j] < cut[i]) {
                double t = cut[i];
                cut[i] = cut[j];
                cut[j] = t;
            }
    double sum = 0;
    for (int c = 0; c + 1 < nc; c++) {
        double hw = (cut[c + 1] - cut[c]) / 16;
        for (int pa = 0; pa < 16; pa++)
            for (int g = 0; g < 8; g++) {
                double t = cut[c] + (pa + 0.5 + 0.5 * gx[g]) * hw;
                sum += 0.5 * hw * gw[g] * fp_reference_control(fog, q, o[1] + t * d[1]);
            }
    }
    return sum;
}
/* ------------------------------------------------------------ sun */

/* Exponential height fog: h = 1 below Y0, exp(-(y - Y0)/H) above; G its
 * antiderivative in y, so that the optical depth from y to y + dy t is
 * sigma (G(y + dy t) - G(y)) / dy. */
#define SY0 1.0
#define SH 8.0
#define SSIG 0.04
static double hprof(double y) { return y < SY0 ? 1 : exp(-(y - SY0) / SH); }
static double G(double y) { return y < SY0 ? y : SY0 + SH * -expm1(-(y - SY0) / SH); }
static double od_ray(double oy, double dy, double t)
{
    return fabs(dy) < 1e-9 ? SSIG * t * hprof(oy) : SSIG * (G(oy + dy * t) - G(oy)) / dy;
}

static double hg(double g, double mu)
{
    double d = 1 + g * g - 2 * g * mu;
    return (1 - g * g) / (4 * PI * d * sqrt(d));
}

/* Gauss-Legendre, 8 nodes on [-1, 1]. */
static const double GX[8] = { -0.9602898564975363, -0.7966664774136267, -0.5255324099163290,
                              -0.1834346424956498, 0.1834346424956498, 0.5255324099163290,
                              0.7966664774136267, 0.9602898564975363 };
static const double GW[8] = { 0.1012285362903763, 0.2223810344533745, 0.3137066458778873,
                              0.3626837833783620, 0.3626837833783620, 0.3137066458778873,
                              0.2223810344533745, 0.1012285362903763 };

/* The test's own integral of the model along one view ray: S (3), tau. */
static double sun_quadrature(const double o[3], const double d[3], double len, const double l[3],
                             double albedo, const double amb[3], const double E[3], double g,
                             double S[3])
{
    double T = isfinite(len) ? len : (SY0 + 60 * SH - o[1]) / d[1];
    double mu = d[0] * l[0] + d[1] * l[1] + d[2] * l[2], ph = hg(g, mu);
    double cuts[3] = { 0, T, T };
    int nc = 2;
    double tc = (SY0 - o[1]) / d[1];
    if (tc > 0 && tc < T) {
        cuts[1] = tc;
        cuts[2] = T;
        nc = 3;
    }
    S[0] = S[1] = S[2] = 0;
    for (int c = 0; c + 1 < nc; c++) {
        const int panels = 4000;
        double a = cuts[c], hw = (cuts[c + 1] - a) / panels;
        for (int k = 0; k < panels; k++)
            for (int q = 0; q < 8; q++) {
                double t = a + (k + 0.5 + 0.5 * GX[q]) * hw;
                double y = o[1] + t * d[1];
                double sun_od = SSIG * (SY0 + SH - G(y)) / l[1];
                double base = 0.5 * hw * GW[q] * exp(-od_ray(o[1], d[1], t)) * SSIG * hprof(y) *
                              albedo;
                for (int ch = 0; ch < 3; ch++)
                    S[ch] += base * (amb[ch] + E[ch] * ph * exp(-sun_od));
            }
    }
    return exp(-od_ray(o[1], d[1], T));
}
/* ------------------------------------------------------------ lights */

#define LSIG 0.05

/* A point light and a spot light in homogeneous fog: in-scattering by
 * composite Gauss-Legendre, with the spot's smoothstep cone. */
static double cone_of(double c, double ci, double co)
{
    if (c >= ci)
        return 1;
    if (c <= co)
        return 0;
    double s = (c - co) / (ci - co);
    return s * s * (3 - 2 * s);
}

/* Point light at P (intensity I), spot at Q shining along A with cones
 * (ci, co) and intensity J; isotropic phase, albedo 1. */
static void light_quadrature(const double o[3], const double d[3], double len, const double P[3],
                             double I, const double Q[3], const double A[3], double ci,
                             double co, double J, double *S)
{
    const int panels = 20000;
    double hw = len / panels;
    *S = 0;
    for (int k = 0; k < panels; k++)
        for (int q = 0; q < 8; q++) {
            double t = (k + 0.5 + 0.5 * GX[q]) * hw, x[3];
            for (int i = 0; i < 3; i++)
                x[i] = o[i] + t * d[i];
            double v[3], r2 = 0, w[3], s2 = 0, ca = 0;
            for (int i = 0; i < 3; i++) {
                v[i] = P[i] - x[i];
                r2 += v[i] * v[i];
                w[i] = x[i] - Q[i];
                s2 += w[i] * w[i];
            }
            for (int i = 0; i < 3; i++)
                ca += w[i] * A[i];
            double f = I * exp(-LSIG * sqrt(r2)) / r2 +
                       J * cone_of(ca / sqrt(s2), ci, co) * exp(-LSIG * sqrt(s2)) / s2;
            *S += 0.5 * hw * GW[q] * exp(-LSIG * t) * LSIG * f / (4 * PI);
        }
}
/* ------------------------------------------------------------ OpenCL */

/* Everything at once: a fogmap in exponential fog with haze, the sun with
 * self-shadowing, a point light, Cornette-Shanks, one bounce. */
static const char *const full_opts[] = {
    "density", "0.05", "height", "0,6", "haze", "0.004", "haze-height", "0,30", "fog-color",
    "0.1,0.12,0.15", "sun",
    "-0.4,0.5,0.6", "sun-intensity", "4", "light", "point:1,2,8:1,0.7,0.4:30", "phase",
    "cs:0.5", "albedo", "0.9", "fog-rotate", "20", NULL };
/* ------------------------------------------------------------ seeds */
/* ------------------------------------------------------------ bounces */
/* ------------------------------------------------------------ joint */

/* The deterministic integrator against the reference on the sample scene
 * (64 x 48, frame 1 of fogpipe-scene): its sun with the shadow map, a point
 * light, ambient, exponential fog, HG phase: relative error <= 1% or
 * absolute <= 1e-3 in all four channels on >= 99% of the pixels.  The
 * reference is the mean of two independent runs of 2048 spp (OpenCL when
 * there is a device, else C); half their difference estimates its own
 * error, which must stay below a third of the tolerance on all but 1% of
 * the channels, so that the judge is sharper than the judgement. */
static int scene_dir(char *dir, size_t size)
{
    const char *tmp = getenv("FP_TMP");
    snprintf(dir, size, "%s/test_reference", tmp ? tmp : "tests/tmp");
    const char *gen = getenv("FP_SCENE");
    const char *fmt = "mkdir -p '%s' && '%s' -o '%s' --width 64 --height 48 --frames 1-1 "
                      ">/dev/null";
    gen = gen ? gen : "samples/fogpipe-scene";
    int len = snprintf(NULL, 0, fmt, dir, gen, dir);
    char *cmd = malloc((size_t)len + 1);
    if (!cmd)
        return -1;
    snprintf(cmd, (size_t)len + 1, fmt, dir, gen, dir);
    int rc = system(cmd);
    free(cmd);
    return rc;
}

#pragma GCC diagnostic pop

#endif

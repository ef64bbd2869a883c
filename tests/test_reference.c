/* The Monte Carlo reference (filters/reference.c, kernels/reference_core.h):
 * - delta and ratio tracking (plain and residual) against the closed-form
 *   transmittance of a homogeneous slab, within 3 standard errors;
 * - delta and residual ratio tracking through a random fogmap with the
 *   majorant grid against the exact integrator's optical depth;
 * - the majorant grid and the walk: c <= sigma_t <= mu and
 *   sigma_t - c <= r at random points of a random fogmap (every basis and
 *   wrap mode), the control's closed-form integral against quadrature;
 * - single scattering of the sun in exponential height fog, and of a
 *   point and a spot light in homogeneous fog, against the test's own
 *   quadrature of the model;
 * - OpenCL against C within their combined standard errors;
 * - determinism for a seed, C and OpenCL;
 * - bounces: the closed form of an infinite medium lit by ambient light,
 *   and monotone growth with albedo 1;
 * - the deterministic integrator (filters/scatter.c) against the reference
 *   on the sample scene: <= 1% or <= 1e-3 on >= 99% of the pixels. */
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

/* Transmittance of a homogeneous slab (density 0.8, 2 thick, in a fog box)
 * by delta tracking (the fraction of free flights that pass) and by ratio
 * tracking, plain and residual (whose control is exact here), within 3
 * standard errors of exp(-sigma L); the second ray runs 7 units through
 * the slab. */
static void test_slab(void **state)
{
    (void)state;
    const char *const opts[] = { "density", "0.8", "height", "0,inf", "fog-box",
                                 "-1000,0,-1000,1000,2,1000", NULL };
    fp_integrate_data_t fog = fog_of(opts);
    fp_reference_grid_t g;
    const double lo[3] = { -3, -2, -3 }, hi[3] = { 3, 6, 3 };
    const int n[3] = { 4, 1, 3 };
    assert_int_equal(fp_reference_grid_fill(&fog, lo, hi, n, &g), FP_OK);
    struct { double o[3], d[3], len; } rays[2] = {
        { { 0.3, -1, 0.2 }, { 0, 1, 0 }, 6 },
        { { 0.5, -0.5, 0.1 }, { 0.96, 0.28, 0 }, 40 },
    };
    const int N = 200000;
    for (int r = 0; r < 2; r++) {
        double *o = rays[r].o, *d = rays[r].d;
        double nn = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int i = 0; i < 3; i++)
            d[i] /= nn;
        double L = 2 / d[1], T = exp(-0.8 * L);
        uint32_t rng = 0x9e3779b9u * (r + 1);
        /* Delta tracking. */
        long pass = 0;
        for (int k = 0; k < N; k++)
            pass += isinf(fp_reference_free_flight(&fog, &g, o, d, rays[r].len, &rng));
        double ph = (double)pass / N, se = sqrt(ph * (1 - ph) / N);
        print_message("ray %d: T = %.6f; delta tracking %.6f (se %.2g, %.2f se)\n", r, T, ph, se,
                      fabs(ph - T) / se);
        if (!(fabs(ph - T) <= 3 * se))
            fail_msg("ray %d: delta tracking passes %.6f, expected %.6f (se %.3g)", r, ph, T, se);
        /* Ratio tracking, plain and residual. */
        for (int control = 0; control < 2; control++) {
            g.rp[FP_RP_CONTROL] = control;
            double s = 0, s2 = 0;
            for (int k = 0; k < N; k++) {
                double t = fp_reference_ratio(&fog, &g, o, d, rays[r].len, &rng);
                s += t;
                s2 += t * t;
            }
            double m = s / N, sd = sqrt(fmax(s2 / N - m * m, 0) * N / (N - 1)), sem = sd / sqrt(N);
            print_message("ray %d: ratio tracking (%s) %.6f (se %.2g, error %.2g)\n", r,
                          control ? "residual" : "plain", m, sem, fabs(m - T));
            if (!(fabs(m - T) <= 3 * sem + 1e-10 * T))
                fail_msg("ray %d: ratio tracking (control %d) %.9g, expected %.9g (se %.3g)", r,
                         control, m, T, sem);
            /* Plain ratio tracking has variance. */
            if (control == 0 && !(sem > 0))
                fail_msg("ray %d: plain ratio tracking without variance", r);
        }
        g.rp[FP_RP_CONTROL] = 1;
    }
    fp_reference_grid_release(&g);
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

static void test_fogmap_transmittance(void **state)
{
    (void)state;
    const int N = 20000;
    double zmax = 0, z2 = 0;
    int nz = 0;
    for (int trial = 0; trial < 12; trial++) {
        mapfog_t m;
        mapfog_make(&m, trial, 16 + 4 * (trial % 3), 12 + 4 * (trial % 2));
        fp_reference_grid_t g;
        const double lo[3] = { -30, -4, -20 }, hi[3] = { 35, 24, 40 };
        const int n[3] = { 12, 1, 14 };
        assert_int_equal(fp_reference_grid_fill(&m.fog, lo, hi, n, &g), FP_OK);
        for (int r = 0; r < 4; r++) {
            double o[3], d[3];
            random_ray(lo, hi, r == 3, o, d);
            double len = 10 + 60 * urand();
            double tend = fp_reference_fog_end(&m.fog, o, d, len);
            double T = exp(-fp_integrate_optical_depth(&m.fog, o, d, len, 0));
            uint32_t rng = 12345u + 977u * (trial * 4 + r);
            long pass = 0;
            double s = 0, s2 = 0;
            for (int k = 0; k < N; k++) {
                pass += isinf(fp_reference_free_flight(&m.fog, &g, o, d, tend, &rng));
                double t = fp_reference_ratio(&m.fog, &g, o, d, tend, &rng);
                s += t;
                s2 += t * t;
            }
            double ph = (double)pass / N, seh = sqrt(fmax(ph * (1 - ph), 1.0 / N) / N);
            double mr = s / N, ser = sqrt(fmax(s2 / N - mr * mr, 0) / (N - 1));
            double za = fabs(ph - T) / seh, zb = fabs(mr - T) / fmax(ser, 1e-9);
            zmax = fmax(zmax, fmax(za, zb));
            z2 += za * za + zb * zb;
            nz += 2;
            if (!(za <= 3.5) || !(zb <= 3.5))
                fail_msg("trial %d ray %d: T %.6f; delta tracking %.6f (se %.2g), ratio "
                         "tracking %.6f (se %.2g)", trial, r, T, ph, seh, mr, ser);
        }
        fp_reference_grid_release(&g);
        mapfog_free(&m);
    }
    print_message("48 rays x %d samples: max |error| %.2f se, rms %.2f se\n", N, zmax,
                  sqrt(z2 / nz));
    assert_true(sqrt(z2 / nz) <= 1.5);
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

/* The walk's segments cover [0, tend] in order, and on each
 * c <= sigma_t <= mu and sigma_t - c <= r, at random points of random
 * rays through a random fogmap (every basis and wrap mode, turned and
 * moved fog, a fog box, haze, a top), in the grid and beyond; the
 * control's closed-form integral matches quadrature. */
static void test_majorant_bounds(void **state)
{
    (void)state;
    long checked = 0, inside = 0;
    double sum_sigma = 0, sum_mu = 0, worst_od = 0;
    static double seg[FP_REFERENCE_SEG * 65536];
    for (int trial = 0; trial < 24; trial++) {
        mapfog_t m;
        mapfog_make(&m, trial, 16 + 4 * (trial % 3), 12 + 4 * (trial % 2));
        fp_reference_grid_t g;
        const double lo[3] = { -30, -4, -20 }, hi[3] = { 35, 24, 40 };
        const int n[3] = { 9 + trial % 4, 1 + trial % 3, 11 };
        assert_int_equal(fp_reference_grid_fill(&m.fog, lo, hi, n, &g), FP_OK);
        for (int r = 0; r < 200; r++) {
            double o[3], d[3];
            random_ray(lo, hi, r % 7 == 0, o, d);
            double len = r % 3 ? 200 * urand() : INFINITY;
            double tend = fp_reference_fog_end(&m.fog, o, d, len);
            if (!(tend > 0))
                continue;
            g.rp[FP_RP_CONTROL] = r % 2;   /* plain and residual segments */
            int ns = fp_reference_segments(&m.fog, &g, o, d, tend, seg, 65536);
            assert_true(ns > 0);
            if (seg[0] != 0)
                fail_msg("trial %d ray %d: the walk starts at %g", trial, r, seg[0]);
            for (int k = 0; k < ns; k++) {
                const double *q = seg + FP_REFERENCE_SEG * k;
                double s0 = q[0], s1 = q[1], mu = q[2], res = q[3];
                if (k > 0 && s0 != q[1 - FP_REFERENCE_SEG])
                    fail_msg("trial %d ray %d: segment %d starts at %.17g, the last ended at "
                             "%.17g", trial, r, k, s0, q[1 - FP_REFERENCE_SEG]);
                if (!(s1 >= s0) || !(mu >= 0) || !(res >= 0))
                    fail_msg("trial %d ray %d: segment %d [%g, %g] mu %g r %g", trial, r, k, s0,
                             s1, mu, res);
                int pts = isfinite(s1) ? 6 : 20;
                for (int p = 0; p < pts; p++) {
                    double t = isfinite(s1) ? s0 + (s1 - s0) * urand()
                                            : s0 - 30 * log(1 - urand()) * (p + 1);
                    double x[3] = { o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2] };
                    double sig = fp_reference_sigma_t(&m.fog, x);
                    double c = fp_reference_control(&m.fog, q, x[1]);
                    if (!(sig <= mu) || !(c <= sig) || !(sig - c <= res + 1e-12 * sig))
                        fail_msg("trial %d ray %d segment %d [%g, %g]: sigma_t(%g,%g,%g) = %.9g, "
                                 "control %.9g, majorant %.9g, residual bound %.9g",
                                 trial, r, k, s0, s1, x[0], x[1], x[2], sig, c, mu, res);
                    checked++;
                    int in = 1;
                    for (int i = 0; i < 3; i++)
                        in &= x[i] > lo[i] && x[i] < hi[i];
                    if (in && sig > 0) {
                        inside++;
                        sum_sigma += sig;
                        sum_mu += mu;
                    }
                }
                /* The control's integral, closed form against quadrature. */
                if (isfinite(s1) && s1 > s0 && (q[4] > 0 || q[5] > 0)) {
                    double qd = control_quadrature(&m.fog, o, d, q);
                    double cf = fp_reference_control_od(&m.fog, o, d, q);
                    double e = fabs(cf - qd) / fmax(qd, 1e-300);
                    worst_od = fmax(worst_od, qd > 1e-12 ? e : 0);
                    if (qd > 1e-12 && !(e <= 1e-9))
                        fail_msg("trial %d ray %d segment %d [%g, %g]: control optical depth "
                                 "%.12g, quadrature %.12g", trial, r, k, s0, s1, cf, qd);
                }
            }
            if (ns < 65536 && seg[FP_REFERENCE_SEG * (ns - 1) + 1] != tend)
                fail_msg("trial %d ray %d: the walk ends at %g, not %g", trial, r,
                         seg[FP_REFERENCE_SEG * (ns - 1) + 1], tend);
        }
        fp_reference_grid_release(&g);
        mapfog_free(&m);
    }
    print_message("%ld points checked; in the grid where there is fog, mean sigma_t / mean "
                  "majorant = %.3f; control integrals within %.2g of quadrature\n", checked,
                  sum_sigma / sum_mu, worst_od);
    assert_true(checked > 100000);
    /* A useful majorant, not merely a valid one. */
    assert_true(sum_sigma / sum_mu > 0.2);
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

/* Single scattering (bounces 0) of the sun in exponential height fog
 * without shadows (self-shadowing exact), HG phase, colored ambient and
 * sun, albedo 0.8, sky and surface pixels: the C reference (16 independent
 * runs of 256 spp) against quadrature, within 5.5 standard errors per pixel
 * and channel, 1.5 in the rms over all (standard errors from the runs'
 * spread with zstats' floor); and the same for the plain estimator (delta
 * and ratio tracking against the majorant, no control, no stratification;
 * 32 runs of 128 spp). */
static void test_sun_single(void **state)
{
    (void)state;
    const char *const opts[] = { "density", "0.04", "height", "1,8", "fog-color",
                                 "0.2,0.25,0.3", "sun", "-0.5,0.6,0.62", "sun-color",
                                 "1,0.9,0.7", "sun-intensity", "3", "phase", "hg:0.6",
                                 "albedo", "0.8", NULL };
    scene_t sc;
    scene_make(&sc, 8, 6, 3, -10, 0.03, 0, opts);
    size_t n = (size_t)sc.w * sc.h;
    float *out = malloc(n * 4 * sizeof(float)), *se = malloc(n * 4 * sizeof(float));
    float *want = malloc(n * 4 * sizeof(float));
    const double *l = sc.sd.lt + FP_LT_SUN_DIR, amb[3] = { 0.2, 0.25, 0.3 };
    const double E[3] = { 3, 2.7, 2.1 };
    int sky = 0;
    for (int y = 0; y < sc.h; y++)
        for (int x = 0; x < sc.w; x++) {
            size_t i = (size_t)y * sc.w + x;
            double dir[3], len, S[3];
            fp_view_ray(&sc.v, x, y, sc.depth[i], dir, &len);
            sky += isinf(len);
            double tau = sun_quadrature(sc.v.origin, dir, len, l, 0.8, amb, E, 0.6, S);
            for (int c = 0; c < 3; c++)
                want[4 * i + c] = (float)S[c];
            want[4 * i + 3] = (float)tau;
        }
    assert_true(sky > 0 && sky < (int)n);
    /* The estimator as it runs, and plain: delta and ratio tracking
     * against the majorant, no stratification. */
    for (int plain = 0; plain < 2; plain++) {
        const fp_reference_opts_t po = { 0, 0, 0 };
        double t0 = now_s();
        int R = plain ? 32 : 16, spp = 4096 / R;
        replicas(&sc, NULL, plain ? &po : NULL, R, spp, 100, out, se);
        double dt = now_s() - t0;
        double zmax, zrms, rel = 0;
        size_t at;
        zstats(out, se, want, NULL, n, 1e-7, plain ? 0 : 1 / (spp * sqrt(R)), &zmax, &zrms, &at);
        for (size_t i = 0; i < 4 * n; i++)
            rel = fmax(rel, fabs(out[i] - want[i]) / fmax(want[i], 1e-3));
        print_message("%s: %zu pixels (%d sky), %d runs of %d spp, %.1f s: max |error| %.2f se "
                      "(pixel %zu channel %zu: %.7g, quadrature %.7g), rms %.2f se; max relative "
                      "error %.2g\n", plain ? "plain" : "default", n, sky, R, spp, dt, zmax,
                      at / 4, at % 4, out[at], want[at], zrms, rel);
        if (!(zmax <= 5.5))
            fail_msg("%s: pixel %zu channel %zu: reference %.7g (se %.2g), quadrature %.7g",
                     plain ? "plain" : "default", at / 4, at % 4, out[at], se[at], want[at]);
        assert_true(zrms <= 1.5);
    }
    free(out);
    free(se);
    free(want);
    scene_free(&sc);
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

/* Single scattering of a point light and a spot light (cone edge
 * included) in homogeneous fog, isotropic phase, albedo 1: as
 * test_sun_single. */
static void test_lights_single(void **state)
{
    (void)state;
    const double P[3] = { 2, 1.5, 6 }, Q[3] = { -3, 6, 12 }, A0[3] = { 0.3, -1, 0.2 };
    double A[3], an = sqrt(A0[0] * A0[0] + A0[1] * A0[1] + A0[2] * A0[2]);
    for (int i = 0; i < 3; i++)
        A[i] = A0[i] / an;
    char pl[128], sl[160];
    snprintf(pl, sizeof pl, "point:%g,%g,%g:1,1,1:20", P[0], P[1], P[2]);
    snprintf(sl, sizeof sl, "spot:%g,%g,%g:1,1,1:60:%g,%g,%g:20,35", Q[0], Q[1], Q[2], A0[0],
             A0[1], A0[2]);
    const char *const opts[] = { "density", "0.05", "height", "0,inf", "fog-color", "0,0,0",
                                 "light", pl, "light", sl, "lamp-shadows", "none", NULL };
    scene_t sc;
    scene_make(&sc, 8, 6, 1.5, 5, 10, 0, opts);   /* no sky */
    size_t n = (size_t)sc.w * sc.h;
    float *out = malloc(n * 4 * sizeof(float)), *se = malloc(n * 4 * sizeof(float));
    float *want = calloc(n * 4, sizeof(float));
    double t0 = now_s();
    replicas(&sc, NULL, NULL, 16, 256, 200, out, se);
    double dt = now_s() - t0;
    double ci = cos(20 * PI / 180), co = cos(35 * PI / 180);
    for (size_t i = 0; i < n; i++) {
        double dir[3], len, S;
        fp_view_ray(&sc.v, (int)(i % sc.w), (int)(i / sc.w), sc.depth[i], dir, &len);
        light_quadrature(sc.v.origin, dir, len, P, 20, Q, A, ci, co, 60, &S);
        for (int c = 0; c < 3; c++)
            want[4 * i + c] = (float)S;
        want[4 * i + 3] = (float)exp(-LSIG * len);
    }
    double zmax, zrms, rel = 0;
    size_t at;
    zstats(out, se, want, NULL, n, 1e-7, 1 / (256 * sqrt(16)), &zmax, &zrms, &at);
    for (size_t i = 0; i < 4 * n; i++)
        rel = fmax(rel, fabs(out[i] - want[i]) / fmax(want[i], 1e-3));
    print_message("%zu pixels, 16 runs of 256 spp, %.1f s: max |error| %.2f se (pixel %zu "
                  "channel %zu: %.7g, quadrature %.7g), rms %.2f se; max relative error %.2g\n",
                  n, dt, zmax, at / 4, at % 4, out[at], want[at], zrms, rel);
    if (!(zmax <= 5.5))
        fail_msg("pixel %zu channel %zu: reference %.7g (se %.2g), quadrature %.7g", at / 4,
                 at % 4, out[at], se[at], want[at]);
    assert_true(zrms <= 1.5);
    free(out);
    free(se);
    free(want);
    scene_free(&sc);
}

/* Issue 23's kinds: a Cycles spot with a blend and a soft radius, an area
 * light (rectangle) and an extra directional light, in height fog with a
 * forward phase function: the Monte Carlo reference (its own estimator:
 * free flights, equiangular sampling, ratio tracking, the same light
 * models, fp_light_gain) against the deterministic integrator's fast rule
 * (kernels/scatter_core.h), statistically, as test_lights_single. */
static void test_new_kinds_single(void **state)
{
    (void)state;
    const char *const opts[] = {
        "density", "0.06", "height", "0,6", "fog-color", "0,0,0", "phase", "hg:0.4",
        "light", "spot:-2,4,10:1,0.8,0.6:40:0.2,-1,0.1:cycles:60,0.3:0.3",
        "light", "area:2,3,8:0.6,0.8,1:25:0,-1,0.3:1,0,0:2,1",
        "light", "dir:0.3,0.8,-0.4:1,1,1:0.5", "light-cull", "0", NULL };
    scene_t sc;
    scene_make(&sc, 8, 6, 1.5, 5, 0.3, 0, opts);
    size_t n = (size_t)sc.w * sc.h;
    float *out = malloc(n * 4 * sizeof(float)), *se = malloc(n * 4 * sizeof(float));
    float *want = malloc(n * 4 * sizeof(float));
    double t0 = now_s();
    replicas(&sc, NULL, NULL, 16, 128, 300, out, se);
    double dt = now_s() - t0;
    assert_int_equal(fp_scatter_process(&sc.sd, &sc.fog, &sc.v, sc.depth, want), FP_OK);
    double zmax, zrms, rel = 0, smax = 0;
    size_t at;
    zstats(out, se, want, NULL, n, 1e-7, 1 / (128 * sqrt(16)), &zmax, &zrms, &at);
    for (size_t i = 0; i < 4 * n; i++) {
        rel = fmax(rel, fabs(out[i] - want[i]) / fmax(want[i], 1e-3));
        smax = fmax(smax, i % 4 < 3 ? want[i] : 0);
    }
    print_message("Cycles spot + area + dir light, %zu pixels, 16 runs of 128 spp, %.1f s: "
                  "reference vs deterministic max |error| %.2f se (pixel %zu channel %zu: %.7g, "
                  "deterministic %.7g), rms %.2f se; max relative error %.2g (S up to %.3g)\n",
                  n, dt, zmax, at / 4, at % 4, out[at], want[at], zrms, rel, smax);
    if (!(zmax <= 5.5))
        fail_msg("pixel %zu channel %zu: reference %.7g (se %.2g), deterministic %.7g", at / 4,
                 at % 4, out[at], se[at], want[at]);
    assert_true(zrms <= 1.5);
    assert_true(smax > 0.01);
    free(out);
    free(se);
    free(want);
    scene_free(&sc);
}

/* A view ray passing 2 cm from a point light: the in-scattering peaks
 * like 1 / (D^2 + s^2) over a few centimetres of a 30 m ray, which free
 * flights alone would resolve only at enormous sample counts; with the
 * equiangular strategy (MIS) 16 runs of 256 spp match quadrature. */
static void test_light_close(void **state)
{
    (void)state;
    scene_t sc;
    memset(&sc, 0, sizeof sc);
    sc.w = sc.h = 1;
    assert_int_equal(make_view(&sc.v, 1, 1, 1.5, 3), 0);
    double dir[3], len;
    fp_view_ray(&sc.v, 0, 0, 1.0f, dir, &len);
    /* A unit vector across the ray. */
    double side[3] = { dir[2], 0, -dir[0] }, sn = sqrt(side[0] * side[0] + side[2] * side[2]);
    double P[3];
    for (int i = 0; i < 3; i++)
        P[i] = sc.v.origin[i] + 10 * dir[i] + 0.02 * side[i] / sn;
    char pl[160];
    snprintf(pl, sizeof pl, "point:%.17g,%.17g,%.17g:1,1,1:5", P[0], P[1], P[2]);
    const char *const opts[] = { "density", "0.05", "height", "0,inf", "fog-color", "0,0,0",
                                 "light", pl, NULL };
    assert_int_equal(fp_options_defaults(&sc.p), FP_OK);
    apply(&sc.p, opts);
    assert_int_equal(fp_integrate_commit(&sc.p, &sc.fog), FP_OK);
    sc.depth = malloc(sizeof(float));
    fp_view_ray(&sc.v, 0, 0, 1.0f, dir, &len);
    sc.depth[0] = (float)(30 / len);   /* planar depth of a point 30 along the ray */
    assert_int_equal(fp_scatter_commit(&sc.p, &sc.sd), FP_OK);
    assert_int_equal(fp_scatter_frame(&sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth, 1), FP_OK);
    float out[4], se[4], want[4];
    replicas(&sc, NULL, NULL, 16, 256, 300, out, se);
    fp_view_ray(&sc.v, 0, 0, sc.depth[0], dir, &len);
    const double Q[3] = { 0, -1000, 0 }, A[3] = { 0, 1, 0 };
    double S;
    light_quadrature(sc.v.origin, dir, len, P, 5, Q, A, 1, 0.5, 0, &S);
    for (int c = 0; c < 3; c++)
        want[c] = (float)S;
    want[3] = (float)exp(-LSIG * len);
    double zmax, zrms;
    size_t at;
    zstats(out, se, want, NULL, 1, 1e-7, 1 / (256 * sqrt(16)), &zmax, &zrms, &at);
    print_message("S %.6f (se %.2g), quadrature %.6f: %.2f se\n", out[0], se[0], want[0], zmax);
    if (!(zmax <= 5.5))
        fail_msg("channel %zu: reference %.7g (se %.2g), quadrature %.7g", at, out[at], se[at],
                 want[at]);
    scene_free(&sc);
}

/* ------------------------------------------------------------ OpenCL */

/* Everything at once: a fogmap in exponential fog with haze, the sun with
 * self-shadowing, a point light, Cornette-Shanks, one bounce. */
static const char *const full_opts[] = {
    "density", "0.05", "height", "0,6", "haze", "0.004", "haze-height", "0,30", "fog-color",
    "0.1,0.12,0.15", "sun",
    "-0.4,0.5,0.6", "sun-intensity", "4", "light", "point:1,2,8:1,0.7,0.4:30", "phase",
    "cs:0.5", "albedo", "0.9", "fog-rotate", "20", NULL };

static void test_opencl_agrees(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    if (fp_cl_open(NULL, &cl) != FP_OK)
        skip();
    fp_reference_cl_t rc;
    assert_int_equal(fp_reference_cl_init(cl, &rc), FP_OK);
    scene_t sc;
    scene_make(&sc, 12, 8, 2.5, -5, 0.05, 1, full_opts);
    size_t n = (size_t)sc.w * sc.h;
    float *a = malloc(n * 4 * sizeof(float)), *sa = malloc(n * 4 * sizeof(float));
    float *b = malloc(n * 4 * sizeof(float)), *sb = malloc(n * 4 * sizeof(float));
    /* Single scattering: 8 independent runs each. */
    double t0 = now_s();
    replicas(&sc, NULL, NULL, 8, 64, 1, a, sa);
    double t1 = now_s();
    replicas(&sc, &rc, NULL, 8, 64, 101, b, sb);
    double t2 = now_s();
    double zmax, zrms;
    size_t at;
    zstats(a, sa, b, sb, n, 1e-6, sqrt(2.0) / (64 * sqrt(8)), &zmax, &zrms, &at);
    print_message("%zu pixels, 8 x 64 spp: C %.2f s, OpenCL %.2f s; max |difference| %.2f "
                  "combined se (pixel %zu channel %zu: C %.6g, OpenCL %.6g), rms %.2f\n", n,
                  t1 - t0, t2 - t1, zmax, at / 4, at % 4, a[at], b[at], zrms);
    if (!(zmax <= 5.5))
        fail_msg("pixel %zu channel %zu: C %.7g (se %.2g), OpenCL %.7g (se %.2g)", at / 4, at % 4,
                 a[at], sa[at], b[at], sb[at]);
    assert_true(zrms <= 1.5);
    /* One bounce: 128 spp each, standard errors from the samples. */
    sc.p.reference.spp = 128;
    sc.p.reference.bounces = 1;
    sc.p.anim.seed = 3;
    t0 = now_s();
    assert_int_equal(fp_reference_process_se(&sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth, NULL, a, sa),
                     FP_OK);
    t1 = now_s();
    sc.p.anim.seed = 4;
    assert_int_equal(fp_reference_process_cl_se(&rc, &sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth, NULL,
                                                b, sb), FP_OK);
    t2 = now_s();
    zstats(a, sa, b, sb, n, 1e-6, 0, &zmax, &zrms, &at);
    double mean_s = 0;
    for (size_t i = 0; i < n; i++)
        mean_s += a[4 * i] / n;
    print_message("%zu pixels, 128 spp, 1 bounce: C %.2f s, OpenCL %.2f s; mean S.r %.4f; "
                  "max |difference| %.2f combined se, rms %.2f\n", n, t1 - t0, t2 - t1, mean_s,
                  zmax, zrms);
    if (!(zmax <= 5.5))
        fail_msg("pixel %zu channel %zu: C %.7g (se %.2g), OpenCL %.7g (se %.2g)", at / 4, at % 4,
                 a[at], sa[at], b[at], sb[at]);
    assert_true(zrms <= 1.5);
    assert_true(mean_s > 0.01);
    free(a);
    free(sa);
    free(b);
    free(sb);
    scene_free(&sc);
    fp_reference_cl_release(&rc);
    fp_cl_close(cl);
}

/* ------------------------------------------------------------ seeds */

static void test_determinism(void **state)
{
    (void)state;
    scene_t sc;
    scene_make(&sc, 12, 8, 2.5, -5, 0.05, 1, full_opts);
    sc.p.reference.spp = 16;
    sc.p.reference.bounces = 2;
    size_t n = (size_t)sc.w * sc.h, bytes = n * 4 * sizeof(float);
    float *a = malloc(bytes), *b = malloc(bytes), *c = malloc(bytes);
    sc.p.anim.seed = 11;
    assert_int_equal(fp_reference_process(&sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth, a), FP_OK);
    assert_int_equal(fp_reference_process(&sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth, b), FP_OK);
    assert_memory_equal(a, b, bytes);
    /* A pixel list (every 3rd pixel, out of order; --fog-edges exact):
     * each pixel's own random stream, so the frame's values. */
    int *pix = malloc((n / 3 + 1) * sizeof *pix);
    float *lst = malloc((n / 3 + 1) * 4 * sizeof *lst);
    size_t m = test_pixel_list(n, pix);
    assert_int_equal(fp_reference_pixels(&sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth, pix, m, lst),
                     FP_OK);
    double c_list = test_list_diff(a, pix, m, lst);
    sc.p.anim.seed = 12;
    assert_int_equal(fp_reference_process(&sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth, c), FP_OK);
    assert_memory_not_equal(a, c, bytes);
    fp_cl_t *cl = NULL;
    if (fp_cl_open(NULL, &cl) == FP_OK) {
        fp_reference_cl_t rc;
        assert_int_equal(fp_reference_cl_init(cl, &rc), FP_OK);
        sc.p.anim.seed = 11;
        assert_int_equal(fp_reference_process_cl(&rc, &sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth, a),
                         FP_OK);
        /* A second state, so nothing is reused from the first run. */
        fp_reference_cl_t rc2;
        assert_int_equal(fp_reference_cl_init(cl, &rc2), FP_OK);
        assert_int_equal(fp_reference_process_cl(&rc2, &sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth,
                                                 b), FP_OK);
        assert_memory_equal(a, b, bytes);
        assert_int_equal(fp_reference_pixels_cl(&rc, &sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth, pix,
                                                m, lst), FP_OK);
        double cl_list = test_list_diff(a, pix, m, lst);
        print_message("pixel list of %zu vs the whole frame: C %.3g, OpenCL %.3g (bounds 0, "
                      "1e-6)\n", m, c_list, cl_list);
        assert_true(cl_list <= 1e-6);
        sc.p.anim.seed = 12;
        assert_int_equal(fp_reference_process_cl(&rc, &sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth, c),
                         FP_OK);
        assert_memory_not_equal(a, c, bytes);
        fp_reference_cl_release(&rc);
        fp_reference_cl_release(&rc2);
        fp_cl_close(cl);
    } else {
        print_message("no OpenCL device: C determinism only\n");
    }
    assert_true(c_list == 0);
    free(pix);
    free(lst);
    free(a);
    free(b);
    free(c);
    scene_free(&sc);
}

/* ------------------------------------------------------------ bounces */

/* An infinite homogeneous medium lit by ambient light alone: every path
 * scatters N + 1 times, each vertex adding albedo^(j+1) L_amb, so
 * S = L_amb a (1 - a^(N+1)) / (1 - a) exactly, and tau = 0 for the sky. */
static void test_bounces_closed_form(void **state)
{
    (void)state;
    const char *const opts[] = { "density", "0.3", "height", "0,inf", "fog-color",
                                 "0.5,0.3,0.2", "albedo", "0.7", "phase", "hg:0.3", NULL };
    scene_t sc;
    scene_make(&sc, 6, 4, 2, 0, -2, 0, opts);   /* all sky */
    sc.p.reference.spp = 8;
    size_t n = (size_t)sc.w * sc.h;
    float *out = malloc(n * 4 * sizeof(float));
    const double L[3] = { 0.5, 0.3, 0.2 }, a = 0.7;
    for (int N = 0; N <= 4; N++) {
        sc.p.reference.bounces = N;
        assert_int_equal(fp_reference_process(&sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth, out), FP_OK);
        double f = a * (1 - pow(a, N + 1)) / (1 - a);
        for (size_t i = 0; i < n; i++) {
            for (int c = 0; c < 3; c++)
                if (!(fabs(out[4 * i + c] - L[c] * f) <= 1e-6 * L[c] * f))
                    fail_msg("bounces %d pixel %zu channel %d: S %.9g, expected %.9g", N, i, c,
                             out[4 * i + c], L[c] * f);
            assert_true(out[4 * i + 3] == 0);
        }
    }
    free(out);
    scene_free(&sc);
}

/* With albedo 1, the sun, a light and ambient, in finite height fog: S
 * never shrinks with more bounces (same seed: the paths of N bounces are
 * the beginnings of those of N + 1), grows on average, and tau does not
 * change.  (Bounces 0 is the single scattering the tests above check.) */
static void test_bounces_monotone(void **state)
{
    (void)state;
    const char *const opts[] = { "density", "0.08", "height", "0,5", "fog-color",
                                 "0.05,0.05,0.06", "sun", "0.3,0.7,0.5", "sun-intensity", "3",
                                 "light", "point:0,2,6:1,1,1:20", "albedo", "1", NULL };
    scene_t sc;
    scene_make(&sc, 8, 6, 2, -5, 0.1, 0, opts);
    sc.p.reference.spp = 64;
    size_t n = (size_t)sc.w * sc.h;
    float *prev = malloc(n * 4 * sizeof(float)), *cur = malloc(n * 4 * sizeof(float));
    double mean_prev = 0;
    for (int N = 0; N <= 4; N++) {
        sc.p.reference.bounces = N;
        assert_int_equal(fp_reference_process(&sc.p, &sc.sd, &sc.fog, &sc.v, sc.depth, cur), FP_OK);
        double mean = 0;
        for (size_t i = 0; i < n; i++) {
            for (int c = 0; c < 3; c++) {
                mean += cur[4 * i + c];
                if (N > 0 && !(cur[4 * i + c] >= prev[4 * i + c] * (1 - 1e-6)))
                    fail_msg("bounces %d pixel %zu channel %d: S %.9g < %.9g with one bounce "
                             "less", N, i, c, cur[4 * i + c], prev[4 * i + c]);
            }
            /* tau does not depend on the bounces. */
            if (N > 0)
                assert_true(cur[4 * i + 3] == prev[4 * i + 3]);
        }
        mean /= 3 * n;
        print_message("bounces %d: mean S %.5f\n", N, mean);
        if (N > 0)
            assert_true(mean > mean_prev * 1.001);
        mean_prev = mean;
        memcpy(prev, cur, n * 4 * sizeof(float));
    }
    free(prev);
    free(cur);
    scene_free(&sc);
}

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

static void test_deterministic_vs_reference(void **state)
{
    (void)state;
    char dir[4096];
    if (scene_dir(dir, sizeof dir) != 0) {
        print_message("fogpipe-scene did not run (set FP_SCENE)\n");
        fail();
    }
    fp_cl_t *cl = NULL;
    int have_cl = fp_cl_open(NULL, &cl) == FP_OK;
    char smap[4200], frame_path[4200];
    snprintf(smap, sizeof smap, "%s/shadow.%%04d.exr", dir);
    snprintf(frame_path, sizeof frame_path, "%s/scene.0001.exr", dir);
    fp_params_t p;
    assert_int_equal(fp_options_defaults(&p), FP_OK);
    const char *const opts[] = { "density", "0.03", "height", "0,10", "fog-color",
                                 "0.08,0.09,0.11", "sun", "-0.4,0.35,0.6", "sun-color",
                                 "1,0.9,0.75", "sun-intensity", "3", "shadow-map", smap,
                                 "phase", "hg:0.4", "light", "point:-2,2.5,14:1,0.8,0.6:30",
                                 "albedo", "0.9", NULL };
    apply(&p, opts);
    p.reference.spp = 2048;
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    fp_frame_t *f = NULL;
    assert_int_equal(fp_exr_read_file(frame_path, 1, &sel, &f), FP_OK);
    const fp_frame_info_t *info = fp_frame_info(f);
    fp_camera_t cam;
    fp_view_t v;
    assert_int_equal(fp_camera_resolve(&p, info, frame_path, 1, &cam), FP_OK);
    assert_int_equal(fp_view_setup(&cam, &p, info, &v), FP_OK);
    const float *depth = fp_frame_depth(f);
    fp_integrate_data_t fog;
    fp_scatter_data_t sd;
    assert_int_equal(fp_integrate_commit(&p, &fog), FP_OK);
    assert_int_equal(fp_scatter_commit(&p, &sd), FP_OK);
    assert_int_equal(fp_scatter_frame(&p, &sd, &fog, &v, depth, 1), FP_OK);
    size_t n = (size_t)v.width * v.height;
    float *det = malloc(n * 4 * sizeof(float)), *ref = malloc(n * 4 * sizeof(float));
    float *se = malloc(n * 4 * sizeof(float));
    double t0 = now_s();
    assert_int_equal(fp_scatter_process(&sd, &fog, &v, depth, det), FP_OK);
    double t1 = now_s();
    /* Two independent halves (seeds 1 and 2): their mean is the
     * reference, half their difference an estimate of its error. */
    float *half = malloc(n * 4 * sizeof(float));
    fp_reference_cl_t rc;
    if (have_cl)
        assert_int_equal(fp_reference_cl_init(cl, &rc), FP_OK);
    for (int k = 0; k < 2; k++) {
        p.anim.seed = 1 + k;
        if (have_cl)
            assert_int_equal(fp_reference_process_cl(&rc, &p, &sd, &fog, &v, depth, k ? half : ref),
                             FP_OK);
        else
            assert_int_equal(fp_reference_process(&p, &sd, &fog, &v, depth, k ? half : ref), FP_OK);
    }
    if (have_cl) {
        fp_reference_cl_release(&rc);
        fp_cl_close(cl);
    }
    double t2 = now_s();
    size_t good = 0, good_px = 0, worst_at = 0, noisy = 0;
    double worst = 0;
    for (size_t i = 0; i < n; i++) {
        int all = 1;
        for (int c = 0; c < 4; c++) {
            size_t j = 4 * i + c;
            double r = 0.5 * ((double)ref[j] + half[j]);
            double noise = 0.5 * fabs((double)ref[j] - half[j]);
            double tol = fmax(1e-3, 0.01 * fabs(r)), e = fabs(det[j] - r);
            se[j] = (float)noise;
            ref[j] = (float)r;
            good += e <= tol;
            all &= e <= tol;
            if (e / tol > worst) {
                worst = e / tol;
                worst_at = j;
            }
            noisy += noise > tol / 3;
        }
        good_px += all;
    }
    double frac = (double)good / (4 * n), frac_px = (double)good_px / n;
    print_message("%dx%d, reference 2 x %d spp (%s, %.1f s), deterministic %.2f s: %.2f%% of "
                  "pixels (%.2f%% of channels) within 1%% or 1e-3; worst %.2f x the tolerance "
                  "at pixel %zu channel %zu (deterministic %.6g, reference %.6g, its error "
                  "about %.2g); %zu channels where the reference's error may exceed a third of "
                  "the tolerance\n",
                  v.width, v.height, p.reference.spp, have_cl ? "OpenCL" : "C", t2 - t1, t1 - t0,
                  100 * frac_px, 100 * frac, worst, worst_at / 4, worst_at % 4, det[worst_at],
                  ref[worst_at], se[worst_at], noisy);
    /* The reference must be good enough to judge. */
    assert_true(noisy <= 4 * n / 100);
    assert_true(frac_px >= 0.99);
    free(det);
    free(ref);
    free(se);
    free(half);
    fp_scatter_release(&sd);
    fp_frame_free(f);
    fp_options_free(&p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_slab),
        cmocka_unit_test(test_fogmap_transmittance),
        cmocka_unit_test(test_majorant_bounds),
        cmocka_unit_test(test_sun_single),
        cmocka_unit_test(test_lights_single),
        cmocka_unit_test(test_new_kinds_single),
        cmocka_unit_test(test_light_close),
        cmocka_unit_test(test_opencl_agrees),
        cmocka_unit_test(test_determinism),
        cmocka_unit_test(test_bounces_closed_form),
        cmocka_unit_test(test_bounces_monotone),
        cmocka_unit_test(test_deterministic_vs_reference),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

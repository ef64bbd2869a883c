/* The light engine of issue 23: any number of lights, Cycles 3.x's light
 * models, per-pixel culling with a stated bound.
 *
 *  1. fp_light_append and --light's syntax for every kind (1024 lights
 *     and more; bad input named);
 *  2. the models (fp_light_gain) against independent quadrature: Cycles'
 *     spot profile (cos x smoothstep), the soft radius (Cycles' disk
 *     facing the point, integrated over the disk), area lights (radiance
 *     over the rectangle or ellipse, integrated over it);
 *  3. the in-scatter of each kind along view rays, fast rule and panels,
 *     against brute-force quadrature along the ray;
 *  4. an extra directional light is the sun without a shadow map;
 *  5. culling: the bound holds for every light and ray; with 256 lamps
 *     the frame differs from computing every light by at most the
 *     budget, C and OpenCL; OpenCL against the C reference.
 * Every comparison prints its measured error next to its tolerance. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "clrt.h"
#include "fp.h"
#include "integrate.h"
#include "options.h"
#include "scatter.h"
#include "testutil.h"

#include "fog_core.h"
#include "light_core.h"
#include "scatter_core.h"
#include "scatter_lanes.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#include "light_rig.h"

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

static int apply_msg(fp_params_t *p, const char *name, const char *value, char *msg, size_t n)
{
    fp_msgbuf_t buf;
    memset(&buf, 0, sizeof buf);
    fp_msgbuf_t *prev = fp_msg_capture(&buf);
    int rc = fp_options_apply(p, name, value, "t");
    fp_msg_capture(prev);
    size_t m = buf.len < n - 1 ? buf.len : n - 1;
    memcpy(msg, buf.text ? buf.text : "", m);
    msg[m] = 0;
    fp_msg_free(&buf);
    return rc;
}

/* ------------------------------------------------------------ 1. storage, syntax */

static void test_append_and_syntax(void **state)
{
    (void)state;
    fp_params_t p;
    fp_options_defaults(&p);
    char msg[2048];
    static const char *const good[] = {
        "point:1,2,3:1,0.5,0.25:10", "point:1,2,3:1,1,1:10:0.25",
        "spot:1,2,3:1,1,1:10:0,-1,0:20,30", "spot:1,2,3:1,1,1:10:0,-1,0:20,30:0.1",
        "spot:1,2,3:1,1,1:10:0,-1,0:cycles:45,0.15", "spot:1,2,3:1,1,1:10:0,-1,0:cycles:45,0:0.2",
        "area:1,2,3:1,1,1:10:0,-1,0:1,0,0:2,1", "area:1,2,3:1,1,1:10:0,-1,0:1,0,0:2,1:ellipse",
        "area:1,2,3:1,1,1:10:0,-1,0:1,0,0:2,1:rectangle", "dir:0.3,1,0.2:1,0.9,0.8:2.5",
    };
    for (size_t i = 0; i < FP_ARRAY_LEN(good); i++)
        if (apply_msg(&p, "light", good[i], msg, sizeof msg) != FP_OK)
            fail_msg("--light %s refused: %s", good[i], msg);
    assert_int_equal(p.light.num_lights, (int)FP_ARRAY_LEN(good));
    const fp_light_t *L = p.light.lights;
    assert_double_equal(L[1].radius, 0.25, 0);
    assert_int_equal(L[4].spot_profile, 1);
    assert_double_equal(L[4].outer, 22.5, 0);
    assert_double_equal(L[4].blend, 0.15, 0);
    assert_double_equal(L[5].radius, 0.2, 0);
    assert_int_equal(L[6].kind, 2);
    assert_int_equal(L[6].shape, 0);
    assert_int_equal(L[7].shape, 1);
    assert_double_equal(L[6].size[0], 2, 0);
    assert_double_equal(L[6].u[0], 1, 0);
    assert_int_equal(L[9].kind, 3);
    assert_double_equal(L[9].axis[1], 1, 0);
    assert_double_equal(L[9].intensity, 2.5, 0);
    static const char *const bad[][2] = {
        { "spot:1,2,3:1,1,1:10:0,-1,0:cycles:45", "expected point" },
        { "spot:1,2,3:1,1,1:10:0,-1,0:cycles:200,0.1", "spot size" },
        { "spot:1,2,3:1,1,1:10:0,-1,0:cycles:45,1.5", "blend" },
        { "point:1,2,3:1,1,1:10:-1", "radius" },
        { "area:1,2,3:1,1,1:10:0,-1,0:0,1,0:2,1", "not along the normal" },
        { "area:1,2,3:1,1,1:10:0,-1,0:1,0,0:0,1", "SU, SV > 0" },
        { "area:1,2,3:1,1,1:10:0,-1,0:1,0,0:2,1:disk", "expected point" },
        { "dir:0,0,0:1,1,1:2", "non-zero direction" },
        { "dir:0,1,0:1,1,1", "expected point" },
        { "dir:0,1,0:1,1,1:2:5", "expected point" },
    };
    for (size_t i = 0; i < FP_ARRAY_LEN(bad); i++) {
        int rc = apply_msg(&p, "light", bad[i][0], msg, sizeof msg);
        if (rc != FP_EUSAGE || !strstr(msg, bad[i][1]) || !strstr(msg, bad[i][0]))
            fail_msg("--light %s: status %d, message '%s' (expected '%s')", bad[i][0], rc, msg,
                     bad[i][1]);
    }
    assert_int_equal(p.light.num_lights, (int)FP_ARRAY_LEN(good));
    /* fp_light_append: thousands of lights; a bad one refused and named. */
    fp_light_t li;
    memset(&li, 0, sizeof li);
    li.color[0] = li.color[1] = li.color[2] = 1;
    li.intensity = 1;
    for (int k = 0; k < 3000; k++) {
        li.pos[0] = k;
        assert_int_equal(fp_light_append(&p.light, &li), FP_OK);
    }
    assert_int_equal(p.light.num_lights, (int)FP_ARRAY_LEN(good) + 3000);
    assert_double_equal(p.light.lights[FP_ARRAY_LEN(good) + 2999].pos[0], 2999, 0);
    li.intensity = NAN;
    fp_msgbuf_t buf;
    memset(&buf, 0, sizeof buf);
    fp_msgbuf_t *prev = fp_msg_capture(&buf);
    assert_int_not_equal(fp_light_append(&p.light, &li), FP_OK);
    fp_msg_capture(prev);
    assert_non_null(buf.text);
    assert_non_null(strstr(buf.text, "finite"));
    fp_msg_free(&buf);
    /* The run packs them all (3010 rows), local lights then the directional. */
    fp_scatter_data_t sd;
    assert_int_equal(fp_scatter_commit(&p, &sd), FP_OK);
    assert_int_equal(sd.nlights, 3010);
    assert_int_equal((int)sd.lt[FP_LT_NLIGHTS], 3009);
    assert_int_equal((int)sd.lt[FP_LT_NDIR], 1);
    assert_int_equal((int)sd.lights[3009 * FP_LL_STRIDE + FP_LL_TYPE], FP_LIGHT_DIR);
    fp_scatter_release(&sd);
    fp_options_free(&p);
    assert_null(p.light.lights);
}

/* ------------------------------------------------------------ 2. models */

static double smooth01(double s)
{
    s = fmin(fmax(s, 0), 1);
    return s * s * (3 - 2 * s);
}

static void test_gain_models(void **state)
{
    (void)state;
    rig_t r;
    static const char *const opts[] = {
        "light", "spot:0,0,0:1,1,1:1:0,-1,0:cycles:60,0.3",
        "light", "point:0,0,0:1,1,1:1:0.5",
        "light", "area:0,0,0:1,1,1:1:0,-1,0:1,0,0:2,1",
        "light", "area:0,0,0:1,1,1:1:0,-1,0:1,0,0:2,1:ellipse",
        "light", "spot:0,0,0:1,1,1:1:0,-1,0:cycles:60,0", NULL };
    rig_open(&r, opts);
    const double *spot = r.sd.lights, *pt = spot + FP_LL_STRIDE, *rect = pt + FP_LL_STRIDE,
                 *ell = rect + FP_LL_STRIDE, *hard = ell + FP_LL_STRIDE;
    /* Cycles 3.x spot_attenuation, written out. */
    double co = cos(30 * M_PI / 180), spread = (1 - co) * 0.3, emax = 0;
    for (double a = 0; a <= 40; a += 0.25) {
        double c = cos(a * M_PI / 180), u[3] = { sin(a * M_PI / 180), -c, 0 };
        double want = c <= co ? 0 : c * (c - co < spread ? smooth01((c - co) / spread) : 1);
        double want_hard = c <= co ? 0 : c;
        emax = fmax(emax, fabs(fp_light_gain(spot, u[0], u[1], u[2], 3) - want));
        emax = fmax(emax, fabs(fp_light_gain(hard, u[0], u[1], u[2], 3) - want_hard));
    }
    print_message("Cycles spot profile (size 60, blend 0.3 and 0): max |error| %.3g "
                  "(tolerance 1e-12)\n", emax);
    assert_true(emax <= 1e-12);
    /* Soft radius R = 0.5: E / I = (1 / (pi R^2)) int_disk cos / t^2 dA over
     * the disk facing the point (Cycles 3.x point_light_sample, the pdf's
     * cosine), by the midpoint rule in the disk's radius. */
    double R = 0.5, erad = 0;
    static const double dist[] = { 0, 0.01, 0.2, 0.5, 1, 3, 20 };
    for (size_t i = 0; i < FP_ARRAY_LEN(dist); i++) {
        double d = dist[i], e = 0;
        int n = 200000;
        for (int k = 0; k < n; k++) {
            double rho = (k + 0.5) * R / n, t2 = d * d + rho * rho;
            e += (d > 0 ? d / (t2 * sqrt(t2)) : 0) * 2 * M_PI * rho * R / n;
        }
        if (d == 0)
            e = 2 * M_PI;   /* the limit: int 2 pi rho d / t^3 = 2 pi (1 - d / sqrt(d^2 + R^2)) */
        e /= M_PI * R * R;
        double got = d > 0 ? fp_light_gain(pt, 0, 1, 0, d) / (d * d)
                           : 2 / (R * R);   /* gain / d^2 at d -> 0: 2 / (s (s + d)) */
        if (d > 0)
            erad = fmax(erad, fabs(got - e) / e);
        print_message("soft radius 0.5 at %g: E/I %.9g, disk quadrature %.9g%s\n", d, got, e,
                      d == 0 ? " (the limit 2/R^2)" : "");
    }
    print_message("soft radius: max relative error %.3g (tolerance 1e-6); no peak: E/I at most "
                  "2/R^2 = %g\n", erad, 2 / (R * R));
    assert_true(erad <= 1e-6);
    /* Area lights, 2 x 1, facing -y: E / I = (1 / A) int cos_l / rho^2 dA
     * (radiance I / A), midpoint rule over the shape. */
    static const double pts[][3] = { { 0, -0.1, 0 }, { 0.9, -0.05, 0.4 }, { 1.5, -0.3, 0.2 },
                                     { 0.2, -1, -0.3 }, { -3, -2, 1 }, { 0.5, -20, 3 },
                                     { 1, -0.01, 0.45 } };
    double erect = 0, eell_near = 0, eell_far = 0;
    for (int shape = 0; shape < 2; shape++) {
        const double *row = shape ? ell : rect;
        double A = shape ? M_PI / 2 : 2;
        for (size_t i = 0; i < FP_ARRAY_LEN(pts); i++) {
            const double *x = pts[i];
            int nu = 2000, nv = 1000;
            double e = 0, du = 2.0 / nu, dv = 1.0 / nv;
            for (int a = 0; a < nu; a++)
                for (int b = 0; b < nv; b++) {
                    double qx = -1 + (a + 0.5) * du, qz = -0.5 + (b + 0.5) * dv;
                    if (shape && qx * qx + 4 * qz * qz > 1)
                        continue;
                    double vx = x[0] - qx, vy = x[1], vz = x[2] - qz;
                    double r2 = vx * vx + vy * vy + vz * vz;
                    e += (-vy / sqrt(r2)) / r2 * du * dv;
                }
            e /= A;
            double rr = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
            double u[3] = { x[0] / rr, x[1] / rr, x[2] / rr };
            double got = fp_light_gain(row, u[0], u[1], u[2], rr) / (rr * rr);
            double rel = fabs(got - e) / e;
            if (!shape)
                erect = fmax(erect, rel);
            else if (rr > 3)
                eell_far = fmax(eell_far, rel);
            else
                eell_near = fmax(eell_near, rel);
            print_message("area %s at (%g, %g, %g): E/I %.7g, quadrature %.7g, far field "
                          "cos/r^2 %.7g\n", shape ? "ellipse" : "rectangle", x[0], x[1], x[2], got,
                          e, -u[1] / (rr * rr));
        }
        double back = fp_light_gain(row, 0, 1, 0, 0.5);
        assert_true(back == 0);
    }
    print_message("area lights: rectangle max relative error %.3g (tolerance 1e-3: the "
                  "quadrature's); ellipse as its equal-area octagon %.3g within 3 sizes, %.3g "
                  "beyond (tolerances 0.05, 2e-3)\n", erect, eell_near, eell_far);
    assert_true(erect <= 1e-3);
    assert_true(eell_near <= 0.05);
    assert_true(eell_far <= 2e-3);
    rig_close(&r);
}

/* ------------------------------------------------------------ 3. along the ray */

/* Brute force of one light's in-scatter along o + t d, t in [0, len]:
 * albedo int sigma e^(-od_cam - od_light) I gain / r^2 p dt by the
 * midpoint rule with n steps (optical depths exact), channel 0. */
static double brute_light(const rig_t *r, const double *row, const double o[3], const double d[3],
                          double len, long n)
{
    const double *fp = r->fog.fp, *lt = r->sd.lt;
    double dt = len / n, s = 0;
    for (long i = 0; i < n; i++) {
        double t = (i + 0.5) * dt, p[3], v[3];
        for (int k = 0; k < 3; k++) {
            p[k] = o[k] + t * d[k];
            v[k] = row[FP_LL_POS + k] - p[k];
        }
        double rr = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        for (int k = 0; k < 3; k++)
            v[k] /= rr;
        double sig = fp_sigma_t(fp, NULL, NULL, NULL, p[0], p[1], p[2]);
        if (!(sig > 0))
            continue;
        double g = fp_light_gain(row, -v[0], -v[1], -v[2], rr);
        if (!(g > 0))
            continue;
        double od = fp_fog_od(fp, NULL, NULL, NULL, NULL, o[0], o[1], o[2], d[0], d[1], d[2], t, 0) +
                    fp_fog_od(fp, NULL, NULL, NULL, NULL, p[0], p[1], p[2], v[0], v[1], v[2], rr, 0);
        s += sig * exp(-od) * g / (rr * rr) *
             fp_phase((int)lt[FP_LT_PHASE], lt[FP_LT_PHASE + 1], lt[FP_LT_PHASE + 2],
                      v[0] * d[0] + v[1] * d[1] + v[2] * d[2]) * dt;
    }
    return s * lt[FP_LT_ALBEDO] * row[FP_LL_I];
}

static void test_kinds_along_rays(void **state)
{
    (void)state;
    static const char *const kinds[] = {
        "spot:1,4,10:1,1,1:50:0.2,-1,0.1:cycles:70,0.25",
        "spot:1,4,10:1,1,1:50:0.2,-1,0.1:cycles:50,0:0.3",
        "point:0.5,1.2,8:1,1,1:20:0.6",
        "area:0,3,9:1,1,1:20:0.1,-1,0.2:1,0,0:3,1.5",
        "area:0,3,9:1,1,1:20:0.1,-1,0.2:1,0,0:3,1.5:ellipse",
        "area:0,1,8:1,1,1:20:0,0,-1:1,0,0:2,2",
    };
    static const char *const quads[][2] = { { "fast", "8" }, { "panels", "32" } };
    double worst[2] = { 0, 0 };
    for (size_t qi = 0; qi < 2; qi++)
        for (size_t ki = 0; ki < FP_ARRAY_LEN(kinds); ki++) {
            const char *opts[] = { "density", "0.08", "height", "0,6", "fog-color", "0,0,0",
                                   "phase", "hg:0.5", "light", kinds[ki], "light-quad",
                                   quads[qi][0], "light-panels", quads[qi][1], "light-cull", "0",
                                   NULL };
            rig_t r;
            rig_open(&r, opts);
            fp_test_rng = 12345;
            for (int k = 0; k < 12; k++) {
                double o[3] = { -2 + 4 * urand(), 0.5 + 2 * urand(), 0 };
                double d[3] = { -0.4 + 0.8 * urand(), -0.15 + 0.3 * urand(), 1 };
                unit(d);
                double len = 30, S[3];
                ray(&r, o, d, len, S);
                double want = brute_light(&r, r.sd.lights, o, d, len, 150000);
                double e = fabs(S[0] - want) / fmax(want, 1e-4);
                worst[qi] = fmax(worst[qi], e);
                if (!(e <= 2e-3))
                    fail_msg("%s, %s rule, ray %d: S %.9g, brute force %.9g (relative %.3g)",
                             kinds[ki], quads[qi][0], k, S[0], want, e);
            }
            rig_close(&r);
        }
    print_message("Cycles spot, soft radius, area lights along view rays vs brute force: max "
                  "relative error %.3g (fast rule), %.3g (32 panels); tolerance 2e-3\n", worst[0],
                  worst[1]);
}

/* ------------------------------------------------------------ 4. extra suns */

static void test_dir_is_sun(void **state)
{
    (void)state;
    static const char *const sun[] = { "density", "0.05", "height", "0,8", "phase", "hg:0.6",
                                       "sun", "0.3,0.8,0.2", "sun-intensity", "2", "sun-color",
                                       "1,0.5,0.25", NULL };
    static const char *const dir[] = { "density", "0.05", "height", "0,8", "phase", "hg:0.6",
                                       "light", "dir:0.3,0.8,0.2:1,0.5,0.25:2", NULL };
    rig_t a, b;
    rig_open(&a, sun);
    rig_open(&b, dir);
    double emax = 0, smax = 0;
    fp_test_rng = 99;
    for (int k = 0; k < 40; k++) {
        double o[3] = { 0, 1 + 3 * urand(), 0 }, d[3] = { urand() - 0.5, urand() - 0.6, 1 };
        unit(d);
        double len = k % 4 ? 10 + 50 * urand() : INFINITY, Sa[3], Sb[3];
        double ta = ray(&a, o, d, len, Sa), tb = ray(&b, o, d, len, Sb);
        assert_double_equal(ta, tb, 1e-12);
        for (int c = 0; c < 3; c++) {
            emax = fmax(emax, fabs(Sa[c] - Sb[c]) / fmax(Sa[c], 1e-9));
            smax = fmax(smax, Sa[c]);
        }
    }
    print_message("dir light vs --sun (no shadow map): max relative difference %.3g (S up to "
                  "%.3g; tolerance 1e-9)\n", emax, smax);
    assert_true(emax <= 1e-9);
    assert_true(smax > 0.01);
    rig_close(&a);
    rig_close(&b);
}

/* ------------------------------------------------------------ 5. culling */

/* A street of n lamps of every local kind along z, in ground fog. */
static void street(char (*spec)[200], int n)
{
    for (int k = 0; k < n; k++) {
        double x = (k % 2 ? -4 : 4) + 0.5 * sin(k), z = 2 + 1.5 * k;
        switch (k % 4) {
        case 0:
            snprintf(spec[k], 200, "point:%g,3.5,%g:1,0.6,0.3:8:0.1", x, z);
            break;
        case 1:
            snprintf(spec[k], 200, "spot:%g,4,%g:0.8,0.9,1:30:%g,-1,0.1:cycles:60,0.2:0.05", x, z,
                     -x * 0.1);
            break;
        case 2:
            snprintf(spec[k], 200, "spot:%g,4,%g:1,1,0.8:30:0,-1,0:20,35", x, z);
            break;
        default:
            snprintf(spec[k], 200, "area:%g,3,%g:1,0.9,0.7:6:0,-1,0:1,0,0:0.6,0.3%s", x, z,
                     k % 8 == 3 ? ":ellipse" : "");
        }
    }
}

typedef struct frame_t {
    fp_view_t v;
    float *depth;
    int w, h;
} frame_t;

static void frame_make(frame_t *f, int w, int h)
{
    f->w = w;
    f->h = h;
    assert_int_equal(make_view(&f->v, w, h, 1.7, -5), 0);
    f->depth = malloc((size_t)w * h * sizeof *f->depth);
    fp_test_rng = 4242;
    for (int i = 0; i < w * h; i++)
        f->depth[i] = i % 7 == 0 ? INFINITY : (float)(5 + 80 * urand());
}

static void commit_frame(rig_t *r, frame_t *f)
{
    assert_int_equal(fp_scatter_frame(&r->p, &r->sd, &r->fog, &f->v, f->depth, 1), FP_OK);
}

static void open_street(rig_t *r, int n, const char *cull, const char *quad)
{
    char (*spec)[200] = malloc((size_t)n * sizeof *spec);
    street(spec, n);
    memset(r, 0, sizeof *r);
    fp_options_defaults(&r->p);
    static const char *const base[] = { "density", "0.04", "height", "0,6", "fog-color",
                                        "0.002,0.003,0.006", "phase", "hg:0.6", NULL };
    for (int i = 0; base[i]; i += 2)
        assert_int_equal(fp_options_apply(&r->p, base[i], base[i + 1], "t"), FP_OK);
    for (int k = 0; k < n; k++)
        assert_int_equal(fp_options_apply(&r->p, "light", spec[k], "t"), FP_OK);
    assert_int_equal(fp_options_apply(&r->p, "light-cull", cull, "t"), FP_OK);
    assert_int_equal(fp_options_apply(&r->p, "light-quad", quad, "t"), FP_OK);
    free(spec);
    assert_int_equal(fp_integrate_commit(&r->p, &r->fog), FP_OK);
    assert_int_equal(fp_scatter_commit(&r->p, &r->sd), FP_OK);
}

static void test_cull_bound_holds(void **state)
{
    (void)state;
    rig_t r;
    open_street(&r, 64, "0", "fast");
    long checked = 0, zero = 0;
    double tight = INFINITY;
    fp_test_rng = 7;
    for (int k = 0; k < 300; k++) {
        double o[3] = { -6 + 12 * urand(), 0.3 + 3 * urand(), -5 + 20 * urand() };
        double d[3] = { urand() - 0.5, 0.3 * (urand() - 0.5), urand() - 0.2 };
        unit(d);
        double len = k % 5 ? 3 + 80 * urand() : INFINITY, ta, tb;
        fp_light_span(r.fog.fp, o[0], o[1], o[2], d[0], d[1], d[2], len, &ta, &tb);
        if (!(tb > ta))
            continue;
        double od = fp_fog_od(r.fog.fp, NULL, NULL, NULL, NULL, o[0], o[1], o[2], d[0], d[1], d[2],
                              len, 0);
        for (int l = 0; l < 64; l++) {
            const double *row = r.sd.lights + l * FP_LL_STRIDE;
            double S[3];
            fp_light_ray(r.fog.fp, r.sd.lt, r.sd.lights, l, o[0], o[1], o[2], d[0], d[1], d[2], len,
                         S);
            double b = fp_light_bound(r.sd.lt, row, fp_light_sigma_span(r.fog.fp, o[1], d[1], ta, tb),
                                      -expm1(-od),
                                      o[0], o[1], o[2], d[0], d[1], d[2], ta, tb);
            double s = fmax(S[0], fmax(S[1], S[2]));
            if (!(s <= b * (1 + 1e-9) + 1e-15))
                fail_msg("ray %d light %d (%s): in-scatter %.9g above its bound %.9g", k, l,
                         row[FP_LL_TYPE] == FP_LIGHT_AREA ? "area" : "point/spot", s, b);
            checked++;
            zero += b == 0;
            if (s > 1e-6 && isfinite(b))
                tight = fmin(tight, b / s);
        }
    }
    print_message("culling bound: %ld light-ray pairs, the in-scatter never above its bound "
                  "(%ld bounds 0: a spot's cone or an area's back missed)\n", checked, zero);
    assert_true(zero > 0);
    rig_close(&r);
}

static double max_channel_diff(const float *a, const float *b, size_t n, double *amax)
{
    double e = 0;
    *amax = 0;
    for (size_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) {
            e = fmax(e, fabs((double)a[4 * i + c] - b[4 * i + c]));
            *amax = fmax(*amax, a[4 * i + c]);
        }
    return e;
}

static void test_cull_frame(void **state)
{
    (void)state;
    frame_t f;
    frame_make(&f, 40, 30);
    size_t n = (size_t)f.w * f.h;
    float *all = malloc(n * 4 * sizeof *all), *cut = malloc(n * 4 * sizeof *cut);
    float *cl_all = malloc(n * 4 * sizeof *cl_all), *cl_cut = malloc(n * 4 * sizeof *cl_cut);
    fp_cl_t *cl = NULL;
    int have_cl = fp_cl_open(NULL, &cl) == FP_OK;
    fp_integrate_cl_t icl;
    fp_scatter_cl_t scl;
    if (have_cl) {
        assert_int_equal(fp_integrate_cl_init(cl, &icl), FP_OK);
        assert_int_equal(fp_scatter_cl_init(cl, &scl), FP_OK);
    } else {
        print_message("no OpenCL device: the OpenCL half skipped\n");
    }
    static const char *const quads[] = { "fast", "panels" };
    for (int qi = 0; qi < 2; qi++) {
        const char *E = "1e-4";
        rig_t a, b;
        int nl = qi ? 64 : 256;   /* the panels' C path is the slow one */
        open_street(&a, nl, "0", quads[qi]);
        open_street(&b, nl, E, quads[qi]);
        commit_frame(&a, &f);
        commit_frame(&b, &f);
        assert_int_equal(fp_scatter_process(&a.sd, &a.fog, &f.v, f.depth, all), FP_OK);
        assert_int_equal(fp_scatter_process(&b.sd, &b.fog, &f.v, f.depth, cut), FP_OK);
        double smax, e = max_channel_diff(all, cut, n, &smax);
        print_message("%d lamps, %s rule, C: --light-cull %s changes the fog layer by at most "
                      "%.3g (S up to %.3g; bound %s)\n", nl, quads[qi], E, e, smax, E);
        assert_true(e <= 1e-4 * (1 + 1e-6));
        assert_true(smax > 1e-3);
        if (have_cl) {
            assert_int_equal(fp_scatter_process_cl(&scl, &icl, &a.sd, &a.fog, &f.v, f.depth,
                                                   cl_all), FP_OK);
            assert_int_equal(fp_scatter_process_cl(&scl, &icl, &b.sd, &b.fog, &f.v, f.depth,
                                                   cl_cut), FP_OK);
            double cmax, ec = max_channel_diff(cl_all, cl_cut, n, &cmax);
            /* OpenCL against the C reference, every light computed. */
            long fail = 0;
            double dmax = 0;
            for (size_t i = 0; i < 4 * n; i++) {
                double d = fabs((double)cl_all[i] - all[i]);
                dmax = fmax(dmax, d);
                fail += !(d <= fmax(2e-3 * fabs(all[i]), 1e-4));
            }
            print_message("%d lamps, %s rule, OpenCL: culling changes it by at most %.3g "
                          "(bound %s, plus float rounding 1e-6); vs the C reference max |d| %.3g "
                          "(tolerance 2e-3 relative or 1e-4)\n", nl, quads[qi], ec, E, dmax);
            assert_true(ec <= 1e-4 + 1e-6);
            assert_int_equal(fail, 0);
        }
        rig_close(&a);
        rig_close(&b);
    }
    if (have_cl) {
        fp_scatter_cl_release(&scl);
        fp_integrate_cl_release(&icl);
        fp_cl_close(cl);
    }
    free(all);
    free(cut);
    free(cl_all);
    free(cl_cut);
    free(f.depth);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_append_and_syntax),
        cmocka_unit_test(test_gain_models),
        cmocka_unit_test(test_kinds_along_rays),
        cmocka_unit_test(test_dir_is_sun),
        cmocka_unit_test(test_cull_bound_holds),
        cmocka_unit_test(test_cull_frame),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* The integrate stage: the closed-form optical depth against independent
 * quadrature and known closed forms (double), and the OpenCL kernel against
 * the C reference on whole frames of random rays (|dtau| <= 1e-5). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "clrt.h"
#include "composite.h"
#include "fp.h"
#include "integrate.h"
#include "options.h"
#include "testutil.h"

/* The ray integrals themselves (static functions, double precision), for
 * the branch-free forms against the branching ones. */
#include "fog_core.h"

/* Fog parameters by name, for readability below. */
#define SIGMA(d) ((d)->fp[0])
#define Y0(d) ((d)->fp[1])
#define HS(d) ((d)->fp[2])
#define TOP(d) ((d)->fp[3])

static double density(const fp_integrate_data_t *d, double y)
{
    if (y >= TOP(d))
        return 0;
    if (y < Y0(d))
        return SIGMA(d);
    return SIGMA(d) * exp(-(y - Y0(d)) / HS(d));
}

/* Optical depth of a ray that starts at height oy with vertical component dy. */
static double od(const fp_integrate_data_t *d, double oy, double dy, double len)
{
    double o[3] = { 1, oy, 2 }, dir[3] = { sqrt(1 - dy * dy), dy, 0 };
    return fp_integrate_optical_depth(d, o, dir, len, 0);
}

/* Independent check: composite Gauss-Legendre (5 nodes) over many panels,
 * with panel edges at the slab crossings so the kink is not smeared. */
static double quadrature(const fp_integrate_data_t *d, double oy, double dy, double len)
{
    static const double x[5] = { -0.9061798459386640, -0.5384693101056831, 0,
                                 0.5384693101056831, 0.9061798459386640 };
    static const double w[5] = { 0.2369268850561891, 0.4786286704993665, 0.5688888888888889,
                                 0.4786286704993665, 0.2369268850561891 };
    double cuts[4] = { 0, len, len, len };
    int nc = 2;
    if (dy != 0) {
        double t0 = (Y0(d) - oy) / dy, t1 = (TOP(d) - oy) / dy;
        if (t0 > 0 && t0 < len)
            cuts[nc++] = t0;
        if (isfinite(t1) && t1 > 0 && t1 < len)
            cuts[nc++] = t1;
    }
    /* sort */
    for (int i = 0; i < nc; i++)
        for (int j = i + 1; j < nc; j++)
            if (cuts[j] < cuts[i]) {
                double t = cuts[i];
                cuts[i] = cuts[j];
                cuts[j] = t;
            }
    double sum = 0;
    for (int s = 0; s + 1 < nc; s++) {
        double a = cuts[s], b = cuts[s + 1];
        const int panels = 2000;
        double hw = (b - a) / panels;
        for (int k = 0; k < panels; k++) {
            double c = a + (k + 0.5) * hw;
            for (int q = 0; q < 5; q++)
                sum += w[q] * 0.5 * hw * density(d, oy + (c + 0.5 * hw * x[q]) * dy);
        }
    }
    return sum;
}

static fp_integrate_data_t fog(double sigma, double y0, double H, double top)
{
    fp_params_t p;
    fp_integrate_data_t d;
    fp_options_defaults(&p);
    p.fog.density = sigma;
    p.fog.height[0] = y0;
    p.fog.height[1] = H;
    p.fog.height[2] = top;
    p.fog.color[0] = p.fog.color[1] = p.fog.color[2] = 0.5;
    assert_int_equal(fp_integrate_commit(&p, &d), FP_OK);
    fp_options_free(&p);
    return d;
}

static void test_closed_forms(void **state)
{
    (void)state;
    /* Homogeneous: sigma * L. */
    fp_integrate_data_t h = fog(0.3, 0, INFINITY, INFINITY);
    assert_double_equal(od(&h, 5, 0.3, 10), 3.0, 1e-12);
    /* Horizontal ray in the exponential part. */
    fp_integrate_data_t e = fog(0.1, 2, 5, INFINITY);
    assert_double_equal(od(&e, 7, 0, 20), 0.1 * exp(-1.0) * 20, 1e-12);
    /* Straight up from the base to infinity: sigma * H. */
    assert_double_equal(od(&e, 2, 1, INFINITY), 0.1 * 5, 1e-12);
    /* Above the top nothing; below the base a sky ray going down is opaque. */
    fp_integrate_data_t t = fog(0.1, 0, 10, 30);
    assert_double_equal(od(&t, 40, 0, 1e6), 0, 0);
    assert_true(isinf(od(&t, 5, -0.1, INFINITY)));
    /* A level sky ray inside the exponential part sees infinite fog. */
    assert_true(isinf(od(&e, 3, 0, INFINITY)));
    /* Zero length, zero density. */
    assert_double_equal(od(&e, 3, 0.5, 0), 0, 0);
    fp_integrate_data_t z = fog(0, 0, 10, INFINITY);
    assert_double_equal(od(&z, 3, -1, INFINITY), 0, 0);
}

/* Random rays, grazing and level ones included, cameras below, inside and
 * above the fog, against quadrature. */
static void test_against_quadrature(void **state)
{
    (void)state;
    double worst = 0;
    for (int k = 0; k < 3000; k++) {
        double H = 0.5 + 30 * urand();
        double y0 = -5 + 10 * urand();
        double top = urand() < 0.5 ? INFINITY : y0 + 1 + 40 * urand();
        fp_integrate_data_t d = fog(0.01 + 0.2 * urand(), y0, H, top);
        double oy = -20 + 80 * urand();
        double dy;
        switch (k % 4) {
        case 0: dy = 0; break;                              /* level */
        case 1: dy = (urand() - 0.5) * 1e-4; break;         /* grazing */
        case 2: dy = (urand() - 0.5) * 2e-2; break;
        default: dy = 2 * urand() - 1; break;
        }
        double len = pow(10, -2 + 5 * urand());
        double a = od(&d, oy, dy, len);
        double b = quadrature(&d, oy, dy, len);
        double err = fabs(a - b) / fmax(1e-300, fmax(fabs(b), 1e-12));
        if (err > worst)
            worst = err;
        if (err > 1e-9)
            fail_msg("ray %d: oy %g dy %g len %g fog (%g,%g,%g,%g): exact %.17g quadrature %.17g",
                     k, oy, dy, len, SIGMA(&d), Y0(&d), HS(&d), TOP(&d), a, b);
    }
    print_message("max relative error against quadrature: %.3g\n", worst);
}

static void test_opencl_parity(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    if (fp_cl_open(NULL, &cl) != FP_OK)
        skip();
    fp_integrate_cl_t s;
    assert_int_equal(fp_integrate_cl_init(cl, &s), FP_OK);
    const int w = 192, h = 128;
    size_t n = (size_t)w * h;
    float *depth = malloc(n * sizeof(float));
    float *ref = malloc(n * 4 * sizeof(float));
    float *got = malloc(n * 4 * sizeof(float));
    const double cams[4][2] = { { 1.5, -3 }, { 12, -30 }, { 60, -80 }, { -4, 20 } };
    const double fogs[3][4] = { { 0.05, 0, 8, INFINITY }, { 0.02, 2, 20, 40 },
                                { 0.01, -1, INFINITY, 15 } };
    double worst = 0, list_worst[2] = { 0, 0 };
    int *pix = malloc((n / 3 + 1) * sizeof *pix);
    float *lst = malloc((n / 3 + 1) * 4 * sizeof *lst);
    assert_non_null(lst);
    for (int ci = 0; ci < 4; ci++)
        for (int fi = 0; fi < 3; fi++) {
            fp_view_t v;
            assert_int_equal(make_view(&v, w, h, cams[ci][0], cams[ci][1]), 0);
            fp_integrate_data_t d = fog(fogs[fi][0], fogs[fi][1], fogs[fi][2], fogs[fi][3]);
            for (size_t i = 0; i < n; i++) {
                double u = urand();
                depth[i] = u < 0.05 ? INFINITY : u < 0.07 ? NAN : u < 0.09 ? 1e10f
                                                 : (float)pow(10, -1 + 4 * urand());
            }
            long bad = 0;
            assert_int_equal(fp_integrate_process(&d, &v, depth, ref, &bad), FP_OK);
            assert_true(bad > 0);
            assert_int_equal(fp_integrate_process_cl(&s, &d, &v, depth, got), FP_OK);
            for (size_t i = 0; i < n; i++)
                for (int c = 0; c < 4; c++) {
                    double e = fabs((double)got[4 * i + c] - ref[4 * i + c]);
                    if (e > worst)
                        worst = e;
                    if (!(e <= 1e-5))
                        fail_msg("camera %d fog %d pixel %zu ch %d depth %g: cl %.9g ref %.9g",
                                 ci, fi, i, c, depth[i], got[4 * i + c], ref[4 * i + c]);
                }
            /* A pixel list (every 3rd pixel, out of order): the frame's
             * values, C and OpenCL. */
            size_t m = test_pixel_list(n, pix);
            assert_int_equal(fp_integrate_pixels(&d, &v, depth, pix, m, lst), FP_OK);
            list_worst[0] = fmax(list_worst[0], test_list_diff(ref, pix, m, lst));
            assert_int_equal(fp_integrate_pixels_cl(&s, &d, &v, depth, pix, m, lst), FP_OK);
            list_worst[1] = fmax(list_worst[1], test_list_diff(got, pix, m, lst));
        }
    print_message("OpenCL vs C reference: max |difference| %.3g (tolerance 1e-5)\n", worst);
    print_message("pixel lists vs the whole frame: C %.3g, OpenCL %.3g (bounds 0, 1e-6)\n",
                  list_worst[0], list_worst[1]);
    assert_true(list_worst[0] == 0);
    assert_true(list_worst[1] <= 1e-6);
    free(pix);
    free(lst);
    free(depth);
    free(ref);
    free(got);
    fp_integrate_cl_release(&s);
    fp_cl_close(cl);
}

/* Fog without a fogmap with everything it has: haze, a box, a turn and an
 * offset (fog space parameters set directly).  bounded: no exponential
 * profile without a top (single precision: the optical depth of a rising
 * sky ray, exp(-ya) H / dy, is as uncertain as dy, and a grazing ray's dy
 * is a difference of terms near 1, good to some 1e-7 absolute). */
static fp_integrate_data_t full_fog(int bounded)
{
    double H = urand() < 0.2 ? INFINITY : 0.5 + 30 * urand();
    double top = urand() < 0.5 && !(bounded && isfinite(H)) ? INFINITY : 6 + 40 * urand();
    fp_integrate_data_t d = fog(0.01 + 0.2 * urand(), -5 + 10 * urand(), H, top);
    if (urand() < 0.7) {
        d.fp[FP_F_HAZE] = 0.002 + 0.05 * urand();
        d.fp[FP_F_HAZE + 1] = -3 + 6 * urand();
        d.fp[FP_F_HAZE + 2] = urand() < 0.5 ? INFINITY : 1 + 50 * urand();
        d.fp[FP_F_HAZE + 3] = urand() < 0.5 && !(bounded && isfinite(d.fp[FP_F_HAZE + 2]))
                                  ? INFINITY : 5 + 60 * urand();
    }
    if (urand() < 0.6) {
        double ang = 2 * M_PI * urand();
        d.fp[FP_F_COS] = cos(ang);
        d.fp[FP_F_SIN] = sin(ang);
        for (int i = 0; i < 3; i++)
            d.fp[FP_F_OFF + i] = -5 + 10 * urand();
        for (int i = 0; i < 3; i++) {
            double lo = -40 + 30 * urand();
            d.fp[FP_F_BOX + i] = urand() < 0.2 ? -INFINITY : lo;
            d.fp[FP_F_BOX + 3 + i] = urand() < 0.2 ? INFINITY : lo + 5 + 60 * urand();
        }
    }
    return d;
}

/* The branch-free no-fogmap path (fp_fog_od_nomap_bf, what the fast kernel
 * runs) against fp_fog_od in double: the same values (relative 1e-10, or
 * both infinite) on random rays, level, grazing, axis-aligned and
 * unbounded ones included. */
static void test_branch_free(void **state)
{
    (void)state;
    double worst = 0;
    for (int k = 0; k < 20000; k++) {
        fp_integrate_data_t d = full_fog(0);
        double o[3] = { -30 + 60 * urand(), -20 + 80 * urand(), -30 + 60 * urand() };
        double dir[3] = { 2 * urand() - 1, 0, 2 * urand() - 1 };
        switch (k % 5) {
        case 0: dir[1] = 0; break;
        case 1: dir[1] = (urand() - 0.5) * 1e-4; break;
        case 2: dir[0] = 0; dir[1] = 2 * urand() - 1; break;
        default: dir[1] = 2 * urand() - 1; break;
        }
        if (k % 7 == 0)
            o[1] = d.fp[FP_F_Y0];   /* on the base */
        double l = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
        if (!(l > 0))
            continue;
        for (int i = 0; i < 3; i++)
            dir[i] /= l;
        double len = k % 3 == 0 ? INFINITY : pow(10, -2 + 5 * urand());
        double a = fp_fog_od(d.fp, NULL, NULL, NULL, NULL, o[0], o[1], o[2], dir[0], dir[1],
                             dir[2], len, 0);
        double b = fp_fog_od_nomap_bf(d.fp, o[0], o[1], o[2], dir[0], dir[1], dir[2], len);
        if (isinf(a) || isinf(b)) {
            if (a != b)
                fail_msg("ray %d: branching %.17g, branch-free %.17g", k, a, b);
            continue;
        }
        double err = fabs(a - b) / fmax(fabs(a), 1e-300);
        worst = fmax(worst, a == b ? 0 : err);
        if (!(err <= 1e-10))
            fail_msg("ray %d: o (%g,%g,%g) dir (%g,%g,%g) len %g: branching %.17g, branch-free "
                     "%.17g", k, o[0], o[1], o[2], dir[0], dir[1], dir[2], len, a, b);
    }
    print_message("branch-free vs branching optical depth (double): max relative difference "
                  "%.3g (tolerance 1e-10)\n", worst);
}

/* The fast kernel (fog without a fogmap) on frames whose width is not a
 * multiple of its 16 lanes, with haze, a turned box, and every depth kind,
 * against the C reference (|d| <= 1e-5, as above), whole and as lists. */
static void test_opencl_height_shapes(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    if (fp_cl_open(NULL, &cl) != FP_OK)
        skip();
    fp_integrate_cl_t s;
    assert_int_equal(fp_integrate_cl_init(cl, &s), FP_OK);
    const int sizes[3][2] = { { 189, 67 }, { 7, 5 }, { 33, 40 } };
    double worst = 0, list_worst = 0;
    int over_frames = 0;
    for (int si = 0; si < 3; si++)
        for (int kind = 0; kind < 3; kind++)
            for (int rep = 0; rep < 4; rep++) {
                int w = sizes[si][0], h = sizes[si][1];
                size_t n = (size_t)w * h;
                float *depth = malloc(n * sizeof(float)), *ref = malloc(n * 4 * sizeof(float));
                /* Page-aligned (a device in the host's memory writes the
                 * layer in place) and 16 bytes off (read back). */
                float *got_mem = NULL;
                assert_int_equal(posix_memalign((void **)&got_mem, 4096,
                                                (n * 4 + 4) * sizeof(float)),
                                 0);
                float *got = got_mem + (rep & 1 ? 4 : 0);
                int *pix = malloc((n / 3 + 1) * sizeof *pix);
                float *lst = malloc((n / 3 + 1) * 4 * sizeof *lst);
                assert_non_null(lst);
                fp_view_t v;
                /* rep 2: the camera high, above most tops (rays fall into
                 * the layer from above). */
                double cam_y = rep == 2 ? 15 + 45 * urand() : -4 + 20 * urand();
                assert_int_equal(make_view(&v, w, h, cam_y, -30 + 40 * urand()), 0);
                v.depth_kind = kind;
                v.far = rep == 1 ? 50 : INFINITY;
                /* An orthographic view (the same ndc_to_cam read as the
                 * camera plane's x, y): rays start on the plane, not at
                 * the camera (fp_view_origin_at). */
                v.ortho = rep == 3;
                fp_integrate_data_t d = full_fog(1);
                for (size_t i = 0; i < n; i++) {
                    double u = urand();
                    float z = (float)pow(10, -1 + 3 * urand());
                    depth[i] = u < 0.05 ? INFINITY : u < 0.07 ? NAN : u < 0.08 ? 0
                             : u < 0.09 ? -1 : kind == 2 ? 1 / z : z;
                }
                assert_int_equal(fp_integrate_pixels(&d, &v, depth, NULL, n, ref), FP_OK);
                assert_int_equal(fp_integrate_process_cl(&s, &d, &v, depth, got), FP_OK);
                for (size_t i = 0; i < 4 * n; i++) {
                    double e = fabs((double)got[i] - ref[i]);
                    worst = fmax(worst, e);
                    if (!(e <= 1e-5))
                        fail_msg("%dx%d depth kind %d pixel %zu ch %zu depth %g: cl %.9g ref %.9g",
                                 w, h, kind, i / 4, i % 4, depth[i / 4], got[i], ref[i]);
                }
                size_t m = test_pixel_list(n, pix);
                assert_int_equal(fp_integrate_pixels_cl(&s, &d, &v, depth, pix, m, lst), FP_OK);
                list_worst = fmax(list_worst, test_list_diff(got, pix, m, lst));
                /* Composited over the plate in the kernel: bit for bit the
                 * layer just read composited on the host, alpha's bits
                 * kept (-0, NaN); only in page-aligned memory. */
                if (s.host_align && !v.ortho) {
                    float *over = NULL, *want = malloc(n * 4 * sizeof(float));
                    assert_int_equal(posix_memalign((void **)&over, 4096, (n * 4 + 4) * sizeof(float)),
                                     0);
                    assert_non_null(want);
                    for (size_t i = 0; i < 4 * n; i++) {
                        double u = urand();
                        want[i] = i % 4 == 3 && u < 0.1 ? (u < 0.05 ? -0.0f : NAN)
                                                        : (float)(-1 + 9 * urand());
                    }
                    assert_false(fp_integrate_over_ok(&s, &d, &v, over + 4));
                    assert_true(fp_integrate_over_ok(&s, &d, &v, over));
                    memcpy(over, want, n * 4 * sizeof(float));
                    /* The depth read in place (page-aligned) or uploaded. */
                    float *dal = NULL;
                    assert_int_equal(posix_memalign((void **)&dal, 4096, n * sizeof(float)), 0);
                    memcpy(dal, depth, n * sizeof(float));
                    assert_int_equal(fp_integrate_over_cl(&s, &d, &v, rep == 2 ? dal : depth, over),
                                     FP_OK);
                    free(dal);
                    fp_composite_process(want, got, n, want);
                    for (size_t i = 0; i < 4 * n; i++)
                        if (memcmp(&over[i], &want[i], sizeof(float)))
                            fail_msg("%dx%d depth kind %d pixel %zu ch %zu: over %.9g, layer "
                                     "composited %.9g",
                                     w, h, kind, i / 4, i % 4, over[i], want[i]);
                    over_frames++;
                    free(over);
                    free(want);
                }
                free(depth);
                free(ref);
                free(got_mem);
                free(pix);
                free(lst);
            }
    print_message("fog without a fogmap, odd sizes, haze, box, depth kinds, orthographic: "
                  "OpenCL vs C max "
                  "|difference| %.3g (tolerance 1e-5); lists vs frame %.3g (bound 1e-6); the "
                  "layer written in place on the host: %s; composited over the plate in the "
                  "kernel: %d frames, bit for bit\n",
                  worst, list_worst, s.host_align ? "yes (half of the frames)" : "no (device)",
                  over_frames);
    assert_true(list_worst <= 1e-6);
    fp_integrate_cl_release(&s);
    fp_cl_close(cl);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_closed_forms),
        cmocka_unit_test(test_against_quadrature),
        cmocka_unit_test(test_opencl_parity),
        cmocka_unit_test(test_branch_free),
        cmocka_unit_test(test_opencl_height_shapes),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

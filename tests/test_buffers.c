/* The buffers stage (filters/buffers.c, kernels/buffers.cl): depth-aware
 * bilateral blur of the fog layer and joint bilateral upsampling of
 * reduced-resolution fog.
 *
 *  1. flat depth: the bilateral blur is a plain Gaussian (separable and
 *     full kernel, 1 and 2 iterations) to 1e-6;
 *  2. a step in depth (an L-shaped near plane in front of a far one, fog
 *     very different on each): no fog bleeds across it, after the blur
 *     (both kernels) and after upsampling from 1/2 and 1/4 (bound 1e-3 of
 *     the difference; a plain Gaussian's bleeding printed alongside);
 *  3. separable against the full 2D kernel on noisy fog over depth with
 *     edges: the measured difference, asserted;
 *  4. upsampling smooth fog (the integrate stage's, computed on the
 *     strided view) against the full-resolution fog: max error and PSNR;
 *  5. the strided view's rays are the full view's at (f x', f y') (1e-12),
 *     and fog integrated on it is the full fog at those pixels;
 *  6. near-camera falloff: unchanged within D, the plain blur from 2 D on;
 *  7. OpenCL against the C reference (both kernels, 2 iterations,
 *     falloff; upsampling at 1/2 and 1/4) within 1e-5;
 *  8. sky blends only with sky, geometry only with geometry;
 *  9. option parsing;
 * 10. the depth-edge pixels of the upsampling (fp_upsample_edges): none on
 *     smooth depth but past the last sample row and column; on depth with
 *     edges exactly the pixels its definition names (never a sample,
 *     ascending), the one-pixel pole and the horizon among them;
 * 11. --fog-edges exact: upsampled fog with the edge pixels computed again
 *     at full resolution against full-resolution fog, over depth edges
 *     and sky (bounds), and better than the upsampling alone.
 * Every comparison prints its measured figure next to its bound. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "buffers.h"
#include "camera.h"
#include "clrt.h"
#include "fp.h"
#include "integrate.h"
#include "options.h"
#include "testutil.h"

/* A camera at (0, 1.5, 0) looking down -Z with the given vertical field of
 * view, planar depth. */
static void view_fov(fp_view_t *v, int w, int h, const char *vfov)
{
    fp_params_t p;
    assert_int_equal(fp_options_defaults(&p), FP_OK);
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.width = info.disp_w = w;
    info.height = info.disp_h = h;
    info.pixel_aspect = 1;
    assert_int_equal(fp_options_apply(&p, "camera-pos", "0,1.5,0", "test"), FP_OK);
    assert_int_equal(fp_options_apply(&p, "camera-rot", "0,0,0", "test"), FP_OK);
    assert_int_equal(fp_options_apply(&p, "vfov", vfov, "test"), FP_OK);
    fp_camera_t c;
    assert_int_equal(fp_camera_resolve(&p, &info, "synthetic", 1, &c), FP_OK);
    assert_int_equal(fp_view_setup(&c, &p, &info, v), FP_OK);
    fp_options_free(&p);
}

static fp_buffers_params_t blur_params(int radius, double sigma, int iterations, int separable)
{
    fp_buffers_params_t b;
    memset(&b, 0, sizeof b);
    b.blur = FP_BLUR_BILATERAL;
    b.radius = radius;
    b.sigma = sigma;
    b.range = 0.05;
    b.iterations = iterations;
    b.separable = separable;
    b.resolution = 1;
    return b;
}

static float *noise_fog(size_t n)
{
    float *f = malloc(n * 4 * sizeof(float));
    assert_non_null(f);
    for (size_t i = 0; i < 4 * n; i++)
        f[i] = (float)urand();
    return f;
}

/* The fog layer at the samples (f i, f j), as the fog stage computes it
 * on the strided view. */
static float *subsample_fog(const float *fog, int w, int h, int f)
{
    int lw = (w + f - 1) / f, lh = (h + f - 1) / f;
    float *lo = malloc((size_t)lw * lh * 4 * sizeof(float));
    assert_non_null(lo);
    for (int j = 0; j < lh; j++)
        for (int i = 0; i < lw; i++)
            memcpy(lo + 4 * ((size_t)j * lw + i), fog + 4 * ((size_t)(f * j) * w + f * i),
                   4 * sizeof(float));
    return lo;
}

/* ---------------------------------------------------------------- 1 */

/* Independent plain Gaussian: the (2r+1)^2 square, renormalised where it
 * leaves the frame, in double, stored as float between iterations. */
static void gaussian(int radius, double sigma, int iterations, int w, int h, float *fog)
{
    size_t n = (size_t)w * h;
    float *tmp = malloc(n * 4 * sizeof(float));
    assert_non_null(tmp);
    for (int it = 0; it < iterations; it++) {
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                double s[4] = { 0, 0, 0, 0 }, ws = 0;
                for (int dy = -radius; dy <= radius; dy++)
                    for (int dx = -radius; dx <= radius; dx++) {
                        int xx = x + dx, yy = y + dy;
                        if (xx < 0 || yy < 0 || xx >= w || yy >= h)
                            continue;
                        double g = exp(-(dx * dx + dy * dy) / (2 * sigma * sigma));
                        for (int c = 0; c < 4; c++)
                            s[c] += g * fog[4 * ((size_t)yy * w + xx) + c];
                        ws += g;
                    }
                for (int c = 0; c < 4; c++)
                    tmp[4 * ((size_t)y * w + x) + c] = (float)(s[c] / ws);
            }
        memcpy(fog, tmp, n * 4 * sizeof(float));
    }
    free(tmp);
}

static void test_flat_is_gaussian(void **state)
{
    (void)state;
    const int w = 97, h = 61;
    size_t n = (size_t)w * h;
    float *dist = malloc(n * sizeof(float));
    assert_non_null(dist);
    for (size_t i = 0; i < n; i++)
        dist[i] = 12.5f;
    float *src = noise_fog(n);
    float *got = malloc(n * 4 * sizeof(float)), *ref = malloc(n * 4 * sizeof(float));
    const struct { int radius; double sigma; int iterations; } cases[] = {
        { 4, 0, 1 }, { 6, 2.5, 2 }, { 1, 0, 1 }, { 12, 7, 1 }
    };
    for (size_t k = 0; k < FP_ARRAY_LEN(cases); k++)
        for (int sep = 0; sep <= 1; sep++) {
            fp_buffers_params_t b = blur_params(cases[k].radius, cases[k].sigma,
                                                cases[k].iterations, sep);
            memcpy(got, src, n * 4 * sizeof(float));
            memcpy(ref, src, n * 4 * sizeof(float));
            assert_int_equal(fp_buffers_blur(&b, w, h, dist, got), FP_OK);
            gaussian(b.radius, fp_buffers_sigma(&b), b.iterations, w, h, ref);
            double worst = 0, moved = 0;
            for (size_t i = 0; i < 4 * n; i++) {
                worst = fmax(worst, fabs((double)got[i] - ref[i]));
                moved = fmax(moved, fabs((double)got[i] - src[i]));
            }
            print_message("flat depth, radius %d sigma %g, %d iteration(s), %s: max |bilateral - "
                          "Gaussian| %.2e (bound 1e-6; the blur moved values by up to %.2f)\n",
                          b.radius, fp_buffers_sigma(&b), b.iterations,
                          sep ? "separable" : "full 2D", worst, moved);
            assert_true(worst <= 1e-6);
            assert_true(moved > 0.1);
        }
    free(dist);
    free(src);
    free(got);
    free(ref);
}

/* ---------------------------------------------------------------- 2 */

#define STEP_W 128
#define STEP_H 96
/* Near plane: x < 61 or y < 37 (an L with a corner, edges on no sample
 * grid); far plane elsewhere. */
static int step_near(int x, int y) { return x < 61 || y < 37; }

static const float near_fog[4] = { 0.05f, 0.06f, 0.07f, 0.95f };
static const float far_fog[4] = { 0.6f, 0.65f, 0.7f, 0.2f };

/* Worst movement of any pixel toward the other side's fog, as a share of
 * the difference between the two. */
static double bleeding(const float *fog, int w, int h)
{
    double worst = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const float *own = step_near(x, y) ? near_fog : far_fog;
            const float *other = step_near(x, y) ? far_fog : near_fog;
            for (int c = 0; c < 4; c++) {
                double toward = ((double)fog[4 * ((size_t)y * w + x) + c] - own[c]) /
                                ((double)other[c] - own[c]);
                worst = fmax(worst, toward);
            }
        }
    return worst;
}

static void test_step_no_bleeding(void **state)
{
    (void)state;
    const int w = STEP_W, h = STEP_H;
    size_t n = (size_t)w * h;
    fp_view_t v;
    view_fov(&v, w, h, "40");
    float *depth = malloc(n * sizeof(float)), *dist = malloc(n * sizeof(float));
    float *fog = malloc(n * 4 * sizeof(float)), *src = malloc(n * 4 * sizeof(float));
    assert_non_null(depth);
    const double bound = 1e-3;
    /* A large step, and one of 30% (6 range sigmas at --blur-range 0.05). */
    const float fars[] = { 20.0f, 13.0f };
    for (size_t k = 0; k < FP_ARRAY_LEN(fars); k++) {
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                size_t i = (size_t)y * w + x;
                depth[i] = step_near(x, y) ? 10.0f : fars[k];
                memcpy(src + 4 * i, step_near(x, y) ? near_fog : far_fog, sizeof near_fog);
            }
        fp_buffers_guide(&v, depth, dist);
        for (int sep = 0; sep <= 1; sep++) {
            fp_buffers_params_t b = blur_params(8, 0, 2, sep);
            memcpy(fog, src, n * 4 * sizeof(float));
            assert_int_equal(fp_buffers_blur(&b, w, h, dist, fog), FP_OK);
            double bl = bleeding(fog, w, h);
            /* The same blur without the range weight, to show what is at stake. */
            b.range = 1e6;
            memcpy(fog, src, n * 4 * sizeof(float));
            assert_int_equal(fp_buffers_blur(&b, w, h, dist, fog), FP_OK);
            double plain = bleeding(fog, w, h);
            print_message("step 10 -> %g in depth, blur radius 8, 2 iterations, %s: bleeding "
                          "%.2e of the difference (bound %g; a plain Gaussian: %.2f)\n",
                          fars[k], sep ? "separable" : "full 2D", bl, bound, plain);
            assert_true(bl <= bound);
            assert_true(plain > 0.2);
        }
        for (int f = 2; f <= 4; f *= 2) {
            float *lo = subsample_fog(src, w, h, f);
            assert_int_equal(fp_upsample(f, 0.05, w, h, dist, lo, fog), FP_OK);
            double bl = bleeding(fog, w, h);
            /* Without the range weight, for comparison. */
            assert_int_equal(fp_upsample(f, 1e6, w, h, dist, lo, fog), FP_OK);
            double plain = bleeding(fog, w, h);
            print_message("step 10 -> %g in depth, upsampled from 1/%d: bleeding %.2e of the "
                          "difference (bound %g; without the range weight: %.2f)\n", fars[k], f,
                          bl, bound, plain);
            assert_true(bl <= bound);
            assert_true(plain > 0.1);
            free(lo);
        }
    }
    free(depth);
    free(dist);
    free(fog);
    free(src);
}

/* ---------------------------------------------------------------- 3 */

/* Depth with edges: a sloping ground, boxes and a disc in front, sky above
 * the horizon band; a 40-degree camera. */
static void scene_depth(int w, int h, float *depth, int with_sky)
{
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float d = 8.0f + 40.0f * (float)(h - y) / h;   /* ground receding upward */
            if (with_sky && y < h / 5 && !(x > w / 2 && x < w / 2 + 9))
                d = INFINITY;
            if (x > w / 6 && x < w / 3 && y > h / 4 && y < 3 * h / 4)
                d = 6.0f;                                  /* a box */
            if (x > w / 2 && x < 3 * w / 4 && y > h / 3 && y < h / 2)
                d = 14.0f + 0.05f * x;                     /* a slanted box */
            double cx = x - 0.8 * w, cy = y - 0.7 * h;
            if (cx * cx + cy * cy < (h / 6.0) * (h / 6.0))
                d = 3.0f;                                  /* a disc close by */
            if (x == w / 8)
                d = 4.0f;                                  /* a one-pixel pole */
            depth[(size_t)y * w + x] = d;
        }
}

static void test_separable_vs_full(void **state)
{
    (void)state;
    const int w = 160, h = 112;
    size_t n = (size_t)w * h;
    fp_view_t v;
    view_fov(&v, w, h, "40");
    float *depth = malloc(n * sizeof(float)), *dist = malloc(n * sizeof(float));
    assert_non_null(depth);
    scene_depth(w, h, depth, 1);
    fp_buffers_guide(&v, depth, dist);
    /* Noisy fog around a smooth one: noise amplitude 0.2, values in [0, 1]. */
    float *src = malloc(n * 4 * sizeof(float));
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            for (int c = 0; c < 4; c++)
                src[4 * ((size_t)y * w + x) + c] =
                    (float)(0.4 + 0.3 * sin(x / 13.0 + c) * cos(y / 9.0) + 0.2 * (urand() - 0.5));
    float *sep = malloc(n * 4 * sizeof(float)), *full = malloc(n * 4 * sizeof(float));
    const int radii[] = { 4, 8 };
    for (size_t k = 0; k < FP_ARRAY_LEN(radii); k++) {
        fp_buffers_params_t b = blur_params(radii[k], 0, 1, 1);
        memcpy(sep, src, n * 4 * sizeof(float));
        assert_int_equal(fp_buffers_blur(&b, w, h, dist, sep), FP_OK);
        b.separable = 0;
        memcpy(full, src, n * 4 * sizeof(float));
        assert_int_equal(fp_buffers_blur(&b, w, h, dist, full), FP_OK);
        double worst = 0, sum = 0;
        long over = 0;
        for (size_t i = 0; i < 4 * n; i++) {
            double e = fabs((double)sep[i] - full[i]);
            worst = fmax(worst, e);
            sum += e;
            over += e > 0.01;
        }
        double mean = sum / (4.0 * n);
        print_message("separable vs full 2D kernel, radius %d, noisy fog (amplitude 0.2) over "
                      "depth edges: max |difference| %.4f, mean %.2e, %.2f%% of values off by "
                      "more than 0.01 (bounds 0.1, 2e-3, 2%%)\n",
                      b.radius, worst, mean, 100.0 * over / (4.0 * n));
        assert_true(worst <= 0.1);
        assert_true(mean <= 2e-3);
        assert_true(over <= 0.02 * 4.0 * n);
    }
    free(depth);
    free(dist);
    free(src);
    free(sep);
    free(full);
}

/* ---------------------------------------------------------------- 4, 5 */

/* Smooth planar depth: a wavy wall receding to the right. */
static void smooth_depth(int w, int h, float *depth)
{
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            depth[(size_t)y * w + x] = (float)(15 + 0.1 * x + 5 * sin(y / 20.0));
}

static fp_integrate_data_t default_fog(void)
{
    fp_params_t p;
    assert_int_equal(fp_options_defaults(&p), FP_OK);
    fp_integrate_data_t d;
    assert_int_equal(fp_integrate_commit(&p, &d), FP_OK);
    fp_options_free(&p);
    return d;
}

static void test_upsample_smooth(void **state)
{
    (void)state;
    const int w = 193, h = 129;   /* not multiples of 4: partial last samples */
    size_t n = (size_t)w * h;
    fp_view_t v;
    view_fov(&v, w, h, "50");
    float *depth = malloc(n * sizeof(float)), *dist = malloc(n * sizeof(float));
    float *full = malloc(n * 4 * sizeof(float)), *up = malloc(n * 4 * sizeof(float));
    float *ldepth = malloc(n * sizeof(float)), *lo = malloc(n * 4 * sizeof(float));
    assert_non_null(lo);
    smooth_depth(w, h, depth);
    fp_buffers_guide(&v, depth, dist);
    fp_integrate_data_t d = default_fog();
    assert_int_equal(fp_integrate_process(&d, &v, depth, full, NULL), FP_OK);
    double range = 0;   /* of tau over the frame */
    float tmin = 1, tmax = 0;
    for (size_t i = 0; i < n; i++) {
        tmin = fminf(tmin, full[4 * i + 3]);
        tmax = fmaxf(tmax, full[4 * i + 3]);
    }
    range = tmax - tmin;
    for (int f = 2; f <= 4; f *= 2) {
        fp_view_t sv;
        fp_view_subsample(&v, f, &sv);
        fp_depth_subsample(depth, w, h, f, ldepth);
        assert_int_equal(fp_integrate_process(&d, &sv, ldepth, lo, NULL), FP_OK);
        assert_int_equal(fp_upsample(f, 0.05, w, h, dist, lo, up), FP_OK);
        double worst = 0, se = 0;
        for (size_t i = 0; i < 4 * n; i++) {
            double e = (double)up[i] - full[i];
            worst = fmax(worst, fabs(e));
            se += e * e;
        }
        double psnr = 10 * log10(1.0 / (se / (4.0 * n)));
        print_message("upsampling smooth fog from 1/%d (tau %.3f..%.3f): max |error| %.2e, "
                      "PSNR %.1f dB (bounds 3e-3, 65 dB)\n", f, tmin, tmax, worst, psnr);
        assert_true(worst <= 3e-3);
        assert_true(psnr >= 65);
    }
    assert_true(range > 0.1);
    free(depth);
    free(dist);
    free(full);
    free(up);
    free(ldepth);
    free(lo);
}

static void test_subsampled_view(void **state)
{
    (void)state;
    const int w = 203, h = 117;
    size_t n = (size_t)w * h;
    float *depth = malloc(n * sizeof(float)), *ldepth = malloc(n * sizeof(float));
    float *full = malloc(n * 4 * sizeof(float)), *lo = malloc(n * 4 * sizeof(float));
    assert_non_null(lo);
    for (size_t i = 0; i < n; i++)
        depth[i] = urand() < 0.1 ? INFINITY : (float)(1 + 100 * urand());
    fp_integrate_data_t d = default_fog();
    const double pitches[] = { -3, -30, 20 };
    for (size_t pi = 0; pi < FP_ARRAY_LEN(pitches); pi++) {
        fp_view_t v;
        assert_int_equal(make_view(&v, w, h, 2, pitches[pi]), 0);
        assert_int_equal(fp_integrate_process(&d, &v, depth, full, NULL), FP_OK);
        for (int f = 1; f <= 4; f *= 2) {
            fp_view_t sv;
            fp_view_subsample(&v, f, &sv);
            assert_int_equal(sv.width, (w + f - 1) / f);
            assert_int_equal(sv.height, (h + f - 1) / f);
            fp_depth_subsample(depth, w, h, f, ldepth);
            double worst = 0, fog_worst = 0;
            assert_int_equal(fp_integrate_process(&d, &sv, ldepth, lo, NULL), FP_OK);
            for (int y = 0; y < sv.height; y++)
                for (int x = 0; x < sv.width; x++) {
                    size_t i = (size_t)(f * y) * w + (size_t)f * x, s = (size_t)y * sv.width + x;
                    assert_true(ldepth[s] == depth[i] || (isinf(ldepth[s]) && isinf(depth[i])));
                    double d1[3], d2[3], l1, l2;
                    fp_view_ray(&v, f * x, f * y, depth[i], d1, &l1);
                    fp_view_ray(&sv, x, y, ldepth[s], d2, &l2);
                    for (int k = 0; k < 3; k++)
                        worst = fmax(worst, fabs(d1[k] - d2[k]));
                    if (isinf(l1))
                        assert_true(isinf(l2));
                    else
                        worst = fmax(worst, fabs(l1 - l2) / l1);
                    for (int c = 0; c < 4; c++)
                        fog_worst = fmax(fog_worst, fabs((double)lo[4 * s + c] - full[4 * i + c]));
                }
            print_message("pitch %g, 1/%d: strided view rays vs full view rays: max difference "
                          "%.2e (bound 1e-12); fog on it vs full fog: %.2e (bound 1e-6)\n",
                          pitches[pi], f, worst, fog_worst);
            assert_true(worst <= 1e-12);
            assert_true(fog_worst <= 1e-6);
        }
    }
    free(depth);
    free(ldepth);
    free(full);
    free(lo);
}

/* ---------------------------------------------------------------- 6 */

static void test_falloff(void **state)
{
    (void)state;
    const int w = 120, h = 80;
    size_t n = (size_t)w * h;
    fp_view_t v;
    view_fov(&v, w, h, "40");
    float *depth = malloc(n * sizeof(float)), *dist = malloc(n * sizeof(float));
    assert_non_null(depth);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            depth[(size_t)y * w + x] = y < 6 ? INFINITY : (float)(2 + 0.25 * x);   /* 2..32 */
    fp_buffers_guide(&v, depth, dist);
    float *src = noise_fog(n);
    float *plain = malloc(n * 4 * sizeof(float)), *fall = malloc(n * 4 * sizeof(float));
    for (int sep = 0; sep <= 1; sep++) {
        fp_buffers_params_t b = blur_params(3, 0, 2, sep);
        memcpy(plain, src, n * 4 * sizeof(float));
        assert_int_equal(fp_buffers_blur(&b, w, h, dist, plain), FP_OK);
        b.falloff = 8;
        memcpy(fall, src, n * 4 * sizeof(float));
        assert_int_equal(fp_buffers_blur(&b, w, h, dist, fall), FP_OK);
        long nnear = 0, nfar = 0, nmid = 0;
        double near_diff = 0, far_diff = 0, mid_out = 0;
        for (size_t i = 0; i < n; i++) {
            double dd = dist[i];
            for (int c = 0; c < 4; c++) {
                double g = fall[4 * i + c], o = src[4 * i + c], p = plain[4 * i + c];
                if (dd < b.falloff)
                    near_diff = fmax(near_diff, fabs(g - o));
                else if (dd >= 2 * b.falloff)
                    far_diff = fmax(far_diff, fabs(g - p));
                else   /* between the unblurred and the blurred value */
                    mid_out = fmax(mid_out, fmin(fabs(g - o), fabs(g - p)) *
                                                (((g - o) * (g - p) > 0) ? 1 : 0));
            }
            nnear += dd < b.falloff;
            nfar += dd >= 2 * b.falloff;
            nmid += dd >= b.falloff && dd < 2 * b.falloff;
        }
        print_message("falloff D = 8, %s: %ld pixels within D changed by %.2e, %ld from 2 D on "
                      "differ from the plain blur by %.2e (bounds 0), %ld between: %.2e outside "
                      "[unblurred, blurred]\n", sep ? "separable" : "full 2D", nnear, near_diff,
                      nfar, far_diff, nmid, mid_out);
        assert_true(nnear > 500 && nfar > 500 && nmid > 500);
        assert_true(near_diff == 0);
        assert_true(far_diff == 0);
        assert_true(mid_out <= 1e-6);
    }
    free(depth);
    free(dist);
    free(src);
    free(plain);
    free(fall);
}

/* ---------------------------------------------------------------- 7 */

static void test_opencl_parity(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    if (fp_cl_open(NULL, &cl) != FP_OK)
        skip();
    fp_buffers_cl_t s;
    assert_int_equal(fp_buffers_cl_init(cl, &s), FP_OK);
    const int w = 150, h = 98;
    size_t n = (size_t)w * h;
    fp_view_t v;
    view_fov(&v, w, h, "40");
    float *depth = malloc(n * sizeof(float)), *dist = malloc(n * sizeof(float));
    assert_non_null(depth);
    scene_depth(w, h, depth, 1);
    fp_buffers_guide(&v, depth, dist);
    float *src = noise_fog(n);
    float *ref = malloc(n * 4 * sizeof(float)), *got = malloc(n * 4 * sizeof(float));
    const struct { int radius, separable; double falloff; } cases[] = {
        { 4, 1, 0 }, { 4, 0, 0 }, { 7, 1, 9 }, { 3, 0, 9 }
    };
    for (size_t k = 0; k < FP_ARRAY_LEN(cases); k++) {
        fp_buffers_params_t b = blur_params(cases[k].radius, 0, 2, cases[k].separable);
        b.falloff = cases[k].falloff;
        memcpy(ref, src, n * 4 * sizeof(float));
        memcpy(got, src, n * 4 * sizeof(float));
        assert_int_equal(fp_buffers_blur(&b, w, h, dist, ref), FP_OK);
        assert_int_equal(fp_buffers_blur_cl(&s, &b, w, h, dist, got), FP_OK);
        double worst = 0;
        for (size_t i = 0; i < 4 * n; i++)
            worst = fmax(worst, fabs((double)got[i] - ref[i]));
        print_message("OpenCL vs C blur, radius %d, %s, 2 iterations, falloff %g: max "
                      "|difference| %.2e (bound 1e-5)\n", b.radius,
                      b.separable ? "separable" : "full 2D", b.falloff, worst);
        assert_true(worst <= 1e-5);
    }
    for (int f = 2; f <= 4; f *= 2) {
        float *lo = subsample_fog(src, w, h, f);
        assert_int_equal(fp_upsample(f, 0.05, w, h, dist, lo, ref), FP_OK);
        assert_int_equal(fp_upsample_cl(&s, f, 0.05, w, h, dist, lo, got), FP_OK);
        double worst = 0;
        for (size_t i = 0; i < 4 * n; i++)
            worst = fmax(worst, fabs((double)got[i] - ref[i]));
        print_message("OpenCL vs C upsampling from 1/%d: max |difference| %.2e (bound 1e-5)\n",
                      f, worst);
        assert_true(worst <= 1e-5);
        free(lo);
    }
    free(depth);
    free(dist);
    free(src);
    free(ref);
    free(got);
    fp_buffers_cl_release(&s);
    fp_cl_close(cl);
}

/* ---------------------------------------------------------------- 8 */

static const float sky_fog[4] = { 0.8f, 0.85f, 0.9f, 0.0f };
static const float geo_fog[4] = { 0.1f, 0.12f, 0.15f, 0.7f };

/* Worst departure of sky pixels from the sky's fog and of geometry pixels
 * from the geometry's (each side is uniform, so any blending shows). */
static void sky_check(const float *fog, const float *dist, size_t n, double *sky_err,
                      double *geo_err)
{
    *sky_err = *geo_err = 0;
    for (size_t i = 0; i < n; i++)
        for (int c = 0; c < 4; c++) {
            if (isinf(dist[i]))
                *sky_err = fmax(*sky_err, fabs((double)fog[4 * i + c] - sky_fog[c]));
            else
                *geo_err = fmax(*geo_err, fabs((double)fog[4 * i + c] - geo_fog[c]));
        }
}

static void test_sky(void **state)
{
    (void)state;
    const int w = 144, h = 100;
    size_t n = (size_t)w * h;
    fp_view_t v;
    view_fov(&v, w, h, "40");
    float *depth = malloc(n * sizeof(float)), *dist = malloc(n * sizeof(float));
    float *src = malloc(n * 4 * sizeof(float)), *fog = malloc(n * 4 * sizeof(float));
    assert_non_null(fog);
    /* Sky above a ragged horizon and through a window; sky written as inf,
     * NaN and Cycles' 1e10; geometry at all distances, very far included. */
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            int sky = y < 30 + 10 * sin(x / 7.0) || (x > 90 && x < 110 && y > 60 && y < 80);
            double u = urand();
            depth[i] = sky ? (u < 0.3 ? INFINITY : u < 0.6 ? NAN : 1e10f)
                           : (float)(5 + 1e5 * (y > 50 && x > 40 && x < 60) + 0.2 * x);
            memcpy(src + 4 * i, sky ? sky_fog : geo_fog, sizeof sky_fog);
        }
    fp_buffers_guide(&v, depth, dist);
    long nsky = 0;
    for (size_t i = 0; i < n; i++)
        nsky += isinf(dist[i]) != 0;
    assert_true(nsky > 1000 && nsky < (long)n - 1000);
    double se, ge;
    for (int sep = 0; sep <= 1; sep++) {
        /* A range sigma wide enough to blend any two distances of geometry. */
        fp_buffers_params_t b = blur_params(10, 0, 3, sep);
        b.range = 1e6;
        memcpy(fog, src, n * 4 * sizeof(float));
        assert_int_equal(fp_buffers_blur(&b, w, h, dist, fog), FP_OK);
        sky_check(fog, dist, n, &se, &ge);
        print_message("sky, blur %s (range sigma 1e6): sky pixels moved by %.2e, geometry by "
                      "%.2e (bound 1e-6)\n", sep ? "separable" : "full 2D", se, ge);
        assert_true(se <= 1e-6 && ge <= 1e-6);
    }
    for (int f = 2; f <= 4; f *= 2) {
        float *lo = subsample_fog(src, w, h, f);
        assert_int_equal(fp_upsample(f, 1e6, w, h, dist, lo, fog), FP_OK);
        sky_check(fog, dist, n, &se, &ge);
        print_message("sky, upsampled from 1/%d: sky pixels off by %.2e, geometry by %.2e "
                      "(bound 1e-6)\n", f, se, ge);
        assert_true(se <= 1e-6 && ge <= 1e-6);
        free(lo);
    }
    free(depth);
    free(dist);
    free(src);
    free(fog);
}

/* ---------------------------------------------------------------- 9 */

static void test_options(void **state)
{
    (void)state;
    fp_params_t p;
    assert_int_equal(fp_options_defaults(&p), FP_OK);
    assert_int_equal(p.buffers.blur, FP_BLUR_OFF);
    assert_int_equal(p.buffers.radius, 4);
    assert_true(p.buffers.sigma == 0 && fp_buffers_sigma(&p.buffers) == 2);
    assert_true(p.buffers.range == 0.05);
    assert_int_equal(p.buffers.iterations, 1);
    assert_true(p.buffers.falloff == 0);
    assert_int_equal(p.buffers.separable, 1);
    assert_int_equal(p.buffers.resolution, 1);
    assert_false(fp_buffers_active(&p));
    assert_int_equal(fp_options_apply(&p, "fog-resolution", "1/4", "test"), FP_OK);
    assert_int_equal(p.buffers.resolution, 4);
    assert_true(fp_buffers_active(&p));
    assert_int_equal(fp_options_apply(&p, "fog-resolution", "1/2", "test"), FP_OK);
    assert_int_equal(p.buffers.resolution, 2);
    assert_int_equal(fp_options_apply(&p, "fog-resolution", "1/3", "test"), FP_EUSAGE);
    assert_int_equal(fp_options_apply(&p, "fog-resolution", "1", "test"), FP_OK);
    assert_false(fp_buffers_active(&p));
    assert_int_equal(fp_options_apply(&p, "blur", "bilateral", "test"), FP_OK);
    assert_true(fp_buffers_active(&p));
    assert_int_equal(fp_options_apply(&p, "blur-separable", "off", "test"), FP_OK);
    assert_int_equal(p.buffers.separable, 0);
    assert_int_equal(fp_options_apply(&p, "blur-radius", "33", "test"), FP_EUSAGE);
    assert_int_equal(fp_options_apply(&p, "blur-iterations", "9", "test"), FP_EUSAGE);
    assert_int_equal(fp_options_apply(&p, "blur-range", "0", "test"), FP_EUSAGE);
    assert_int_equal(fp_options_apply(&p, "blur-falloff", "2.5", "test"), FP_OK);
    assert_true(p.buffers.falloff == 2.5);
    fp_options_free(&p);
}

/* ---------------------------------------------------------------- 10 */

static double rel_of(double a, double b)
{
    if (isinf(a) || isinf(b))
        return isinf(a) && isinf(b) ? 0 : INFINITY;
    return fabs(a - b) / fmin(a, b);
}

static void test_edges_list(void **state)
{
    (void)state;
    const int w = 171, h = 114;   /* partial last cells at 1/2 and 1/4; the pole at x = 21 */
    size_t n = (size_t)w * h;
    fp_view_t v;
    view_fov(&v, w, h, "40");
    float *depth = malloc(n * sizeof(float)), *dist = malloc(n * sizeof(float));
    int *pix = malloc(n * sizeof(int));
    unsigned char *listed = malloc(n);
    assert_non_null(listed);
    const double t = 0.1;
    smooth_depth(w, h, depth);
    fp_buffers_guide(&v, depth, dist);
    for (int f = 2; f <= 4; f *= 2) {
        /* Only the columns and rows past the last sample: x, y > f (lw - 1). */
        int lw = (w + f - 1) / f, lh = (h + f - 1) / f;
        size_t border = (size_t)(w - f * (lw - 1) - 1) * h + (size_t)(h - f * (lh - 1) - 1) * w -
                        (size_t)(w - f * (lw - 1) - 1) * (h - f * (lh - 1) - 1);
        assert_int_equal(fp_upsample_edges(f, t, w, h, dist, pix), border);
    }
    assert_int_equal(fp_upsample_edges(1, t, w, h, dist, pix), 0);
    scene_depth(w, h, depth, 1);
    fp_buffers_guide(&v, depth, dist);
    for (int f = 2; f <= 4; f *= 2) {
        size_t m = fp_upsample_edges(f, t, w, h, dist, pix);
        memset(listed, 0, n);
        for (size_t k = 0; k < m; k++) {
            assert_true(pix[k] >= 0 && (size_t)pix[k] < n);
            if (k)
                assert_true(pix[k] > pix[k - 1]);
            listed[pix[k]] = 1;
        }
        /* The definition, pixel by pixel: not a sample, and a corner
         * sample of its cell farther than t in relative distance. */
        int lw = (w + f - 1) / f, lh = (h + f - 1) / f;
        long wrong = 0, pole = 0, pole_listed = 0, horizon = 0, horizon_listed = 0;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                size_t p = (size_t)y * w + x;
                int want = (x % f && x / f + 1 >= lw) || (y % f && y / f + 1 >= lh);
                if (x % f || y % f)
                    for (int j = y / f; j <= y / f + 1 && j < lh; j++)
                        for (int i = x / f; i <= x / f + 1 && i < lw; i++)
                            want |= rel_of(dist[p], dist[(size_t)(f * j) * w + f * i]) > t;
                wrong += want != listed[p];
                if (x == w / 8 && x % f && y > h / 5 && !(x > w / 6 && x < w / 3)) {
                    pole++;
                    pole_listed += listed[p];
                }
                if (y == h / 5 - 1 && y % f && !(x > w / 2 - 2 && x < w / 2 + 10)) {
                    horizon++;
                    horizon_listed += listed[p];
                }
            }
        print_message("depth-edge pixels at 1/%d (threshold %g): %zu of %zu (%.1f%%), %ld against "
                      "the definition (bound 0); the one-pixel pole %ld/%ld, the row above the "
                      "horizon %ld/%ld\n", f, t, m, n, 100.0 * m / n, wrong, pole_listed, pole,
                      horizon_listed, horizon);
        assert_int_equal(wrong, 0);
        assert_true(pole > 0 && pole_listed == pole);
        assert_true(horizon > 0 && horizon_listed == horizon);
        assert_true(m < n / 4);
    }
    free(depth);
    free(dist);
    free(pix);
    free(listed);
}

/* ---------------------------------------------------------------- 11 */

static void test_edges_exact(void **state)
{
    (void)state;
    const int w = 160, h = 112;
    size_t n = (size_t)w * h;
    fp_view_t v;
    view_fov(&v, w, h, "40");
    float *depth = malloc(n * sizeof(float)), *dist = malloc(n * sizeof(float));
    float *full = malloc(n * 4 * sizeof(float)), *up = malloc(n * 4 * sizeof(float));
    float *ldepth = malloc(n * sizeof(float)), *lo = malloc(n * 4 * sizeof(float));
    float *edge_fog = malloc(n * 4 * sizeof(float));
    int *pix = malloc(n * sizeof(int));
    assert_non_null(pix);
    scene_depth(w, h, depth, 1);
    fp_buffers_guide(&v, depth, dist);
    fp_params_t p;
    assert_int_equal(fp_options_defaults(&p), FP_OK);
    assert_int_equal(fp_options_apply(&p, "density", "0.05", "test"), FP_OK);
    assert_int_equal(fp_options_apply(&p, "fog-color", "0.8,0.85,0.9", "test"), FP_OK);
    fp_integrate_data_t d;
    assert_int_equal(fp_integrate_commit(&p, &d), FP_OK);
    assert_int_equal(fp_integrate_process(&d, &v, depth, full, NULL), FP_OK);
    for (int f = 2; f <= 4; f *= 2) {
        fp_view_t sv;
        fp_view_subsample(&v, f, &sv);
        fp_depth_subsample(depth, w, h, f, ldepth);
        assert_int_equal(fp_integrate_process(&d, &sv, ldepth, lo, NULL), FP_OK);
        assert_int_equal(fp_upsample(f, p.buffers.range, w, h, dist, lo, up), FP_OK);
        double before = 0, after = 0;
        for (size_t i = 0; i < 4 * n; i++)
            before = fmax(before, fabs((double)up[i] - full[i]));
        size_t m = fp_upsample_edges(f, p.buffers.edge_threshold, w, h, dist, pix);
        assert_int_equal(fp_integrate_pixels(&d, &v, depth, pix, m, edge_fog), FP_OK);
        for (size_t k = 0; k < m; k++)
            memcpy(up + 4 * (size_t)pix[k], edge_fog + 4 * k, 4 * sizeof(float));
        for (size_t i = 0; i < 4 * n; i++)
            after = fmax(after, fabs((double)up[i] - full[i]));

        print_message("1/%d against full resolution: upsampled alone max |error| %.4f, with the "
                      "%zu depth-edge pixels (%.1f%%) computed again %.4f (bound 0.01)\n", f,
                      before, m, 100.0 * m / n, after);
        assert_true(after <= 0.01);
        assert_true(after < 0.5 * before);
    }
    fp_options_free(&p);
    free(depth);
    free(dist);
    free(full);
    free(up);
    free(ldepth);
    free(lo);
    free(edge_fog);
    free(pix);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_flat_is_gaussian),
        cmocka_unit_test(test_step_no_bleeding),
        cmocka_unit_test(test_separable_vs_full),
        cmocka_unit_test(test_upsample_smooth),
        cmocka_unit_test(test_subsampled_view),
        cmocka_unit_test(test_falloff),
        cmocka_unit_test(test_opencl_parity),
        cmocka_unit_test(test_sky),
        cmocka_unit_test(test_options),
        cmocka_unit_test(test_edges_list),
        cmocka_unit_test(test_edges_exact),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

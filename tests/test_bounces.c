/* The Monte Carlo reference with bounces (filters/reference.c): the
 * closed form of an infinite medium, more bounces never less light; and
 * the deterministic integrator against the reference on the sample scene
 * (split from tests/test_reference.c; helpers in
 * tests/reference_testutil.h). */
#include "reference_testutil.h"

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
        cmocka_unit_test(test_bounces_closed_form),
        cmocka_unit_test(test_bounces_monotone),
        cmocka_unit_test(test_deterministic_vs_reference),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* The scatter stage's fast light paths (the segments along the view ray,
 * the SIMD lanes) against the exact integrator, in C and OpenCL (split
 * from tests/test_scatter.c; helpers in tests/scatter_testutil.h). */
#include "scatter_testutil.h"

/* --light-quad fast (the default without a fogmap: 4 pieces of
 * FP_LIGHT_NODES nodes, the phase peak and the spot's cone taken out in
 * closed form) against brute force (light_gen) and, for the figure, the
 * panels path with 64 panels of 4 nodes (256 nodes per light; its camera
 * optical depth is interpolated between segment ends).  Rays from a
 * camera in several fogs, phase functions and lights, to geometry and to
 * the sky; the error of S.r relative to the ray's own (floor: 1e-3 of the
 * largest of the configuration).  Bound: 2e-3 (measured 1.02e-3, at a fog
 * top with a mixed phase function; the panels path is off by 4e-3 in height
 * fog, where its camera optical depth is interpolated). */
static void test_light_fast(void **state)
{
    (void)state;
    static const char *const fogs[][6] = {
        { "density", "0.05", "height", "0,8", "haze", "0" },          /* night-street-lamps */
        { "density", "0.2", "height", "0,inf", "haze", "0.01" },
        { "density", "0.02", "height", "1,4,12", "haze", "0" },
    };
    static const char *const phases[] = { "hg:0.8", "iso", "cs:0.6", "mix:0.2,0.75", "hg:-0.5",
                                          "rayleigh", "hg:0.95" };
    static const char *const lights[] = {
        "point:-4,3.5,6:1,0.55,0.2:30",
        "spot:0,7,26:0.75,0.85,1:200:0,-1,-0.15:15,30",
        "point:0.3,1.8,12:1,1,1:5",
        "spot:2,2,10:1,1,1:50:0,0,-1:0,60",
        "spot:-3,5,-4:1,1,1:50:0.2,-0.3,1:30,80",
    };
    double worst = 0, worst_p = 0;
    int bad = 0;
    for (size_t fi = 0; fi < FP_ARRAY_LEN(fogs); fi++)
        for (size_t pi = 0; pi < FP_ARRAY_LEN(phases); pi++)
            for (size_t li = 0; li < FP_ARRAY_LEN(lights); li++) {
                double S[2][40][3], B[40];
                for (int exact = 0; exact < 2; exact++) {
                    const char *opts[] = { fogs[fi][0], fogs[fi][1], fogs[fi][2], fogs[fi][3],
                                           fogs[fi][4], fogs[fi][5], "fog-color", "0,0,0",
                                           "phase", phases[pi], "light", lights[li],
                                           "light-quad", exact ? "panels" : "fast",
                                           "light-panels", "64", "scatter-steps", "128",
                                           "light-cull", "0", NULL };
                    rig_t r;
                    rig_open(&r, opts);
                    fp_test_rng = 88172645463325252ull;
                    for (int k = 0; k < 40; k++) {
                        double o[3] = { 0, 1.7, 0 };
                        double d[3] = { 2 * urand() - 1, 0.6 * urand() - 0.2, 2 * urand() - 0.3 };
                        unit(d);
                        double len = k % 4 == 0 ? INFINITY : 2 + 60 * urand();
                        ray(&r, o, d, len, S[exact][k]);
                        if (!exact)
                            B[k] = light_gen(&r, o, d, len);
                    }
                    rig_close(&r);
                }
                double smax = 0, e = 0, ep = 0;
                for (int k = 0; k < 40; k++)
                    smax = fmax(smax, B[k]);
                for (int k = 0; k < 40; k++) {
                    double fl = fmax(B[k], 1e-3 * smax);
                    e = fmax(e, fabs(S[0][k][0] - B[k]) / fl);
                    ep = fmax(ep, fabs(S[1][k][0] - B[k]) / fl);
                }
                worst = fmax(worst, e);
                worst_p = fmax(worst_p, ep);
                if (getenv("FP_TEST_VERBOSE"))
                    print_message("fast light %s %s %s %s: %.3g (64 panels %.3g)\n",
                                  fogs[fi][1], fogs[fi][3], phases[pi], lights[li], e, ep);
                if (!(e <= 2e-3) && bad++ < 5)
                    print_message("fast local light, %s %s %s, phase %s, light %s: relative "
                                  "error %.3g against brute force (bound 2e-3)\n", fogs[fi][1],
                                  fogs[fi][3], fogs[fi][5], phases[pi], lights[li], e);
            }
    print_message("fast local lights (--light-quad fast, 4 x %d nodes) vs brute force: max "
                  "relative error of S %.3g (--light-quad panels, 64 panels: %.3g) over %zu fogs "
                  "x %zu phase functions x %zu lights x 40 rays (bound 2e-3)\n", FP_LIGHT_NODES,
                  worst, worst_p, FP_ARRAY_LEN(fogs), FP_ARRAY_LEN(phases),
                  FP_ARRAY_LEN(lights));
    assert_int_equal(bad, 0);
}

/* The lanes of the fast local lights' kernel (kernels/scatter_lanes.h,
 * float16 in scatter_lights) compiled in double against fp_light_ray, the
 * C reference: the same formulas written with selects, so they agree to
 * rounding.  Fogs with haze, a top, a turned box; every phase function;
 * points and spots (narrow, wide, a cone up to 90 degrees); rays from the
 * camera and from elsewhere (an orthographic camera's plane), to geometry
 * and to the sky, some from inside the box, some missing the fog.  Bound:
 * 1e-9 of the configuration's largest S. */
static void test_light_lanes(void **state)
{
    (void)state;
    static const char *const fogs[][10] = {
        { "density", "0.05", "height", "0,8", "haze", "0", "fog-rotate", "0", NULL },
        { "density", "0.2", "height", "0,inf", "haze", "0.01", "fog-rotate", "0", NULL },
        { "density", "0.02", "height", "1,4,12", "haze", "0.004", "haze-height", "0,20,30",
          NULL },
        { "density", "0.08", "height", "0,3", "fog-box", "-10,-1,0,12,6,40", "fog-rotate",
          "25", NULL },
        { "density", "0", "height", "0,8", "haze", "0.03", "haze-height", "1,10,25", NULL },
    };
    static const char *const phases[] = { "hg:0.8", "iso", "cs:0.6", "mix:0.2,0.75",
                                          "mixhg:0.3,0.7", "hg:-0.5", "rayleigh", "hg:0.1" };
    static const char *const lights[] = {
        "point:-4,3.5,6:1,0.55,0.2:30",
        "spot:0,7,26:0.75,0.85,1:200:0,-1,-0.15:15,30",
        "spot:2,2,10:1,1,1:50:0,0,-1:0,60",
        "spot:-3,5,-4:1,1,1:50:0.2,-0.3,1:30,80",
        "point:0.3,1.8,12:1,1,1:5",
    };
    double worst = 0;
    int bad = 0, lit = 0;
    long rays = 0;
    for (size_t fi = 0; fi < FP_ARRAY_LEN(fogs); fi++)
        for (size_t pi = 0; pi < FP_ARRAY_LEN(phases); pi++)
            for (size_t li = 0; li < FP_ARRAY_LEN(lights); li++) {
                const char *opts[24];
                size_t n = 0;
                for (size_t i = 0; fogs[fi][i]; i++)
                    opts[n++] = fogs[fi][i];
                const char *rest[] = { "fog-color", "0,0,0", "phase", phases[pi], "light",
                                       lights[li], NULL };
                for (size_t i = 0; rest[i]; i++)
                    opts[n++] = rest[i];
                opts[n] = NULL;
                rig_t r;
                rig_open(&r, opts);
                fp_test_rng = 0x9e3779b97f4a7c15ull + fi * 131 + pi * 17 + li;
                double ref[48][3], got[48][3], smax = 0;
                for (int k = 0; k < 48; k++) {
                    /* Every third ray starts away from the camera (an
                     * orthographic view's plane, or inside the fog). */
                    double o[3] = { 0, 1.7, 0 };
                    if (k % 3 == 1) {
                        o[0] = 20 * urand() - 10;
                        o[1] = 10 * urand() - 1;
                        o[2] = 30 * urand() - 5;
                    }
                    double d[3] = { 2 * urand() - 1, 1.2 * urand() - 0.5, 2 * urand() - 0.3 };
                    unit(d);
                    double len = k % 4 == 0 ? INFINITY : 0.5 + 60 * urand();
                    fp_light_ray(r.fog.fp, r.sd.lt, r.sd.lights, 0, o[0], o[1], o[2], d[0], d[1], d[2], len,
                                 ref[k]);
                    fp_ln_light_ray(r.fog.fp, r.sd.lt, r.sd.lights, 0, o[0], o[1], o[2], d[0], d[1], d[2],
                                    len, got[k]);
                    for (int c = 0; c < 3; c++)
                        smax = fmax(smax, fabs(ref[k][c]));
                    rays++;
                }
                double e = 0;
                for (int k = 0; k < 48; k++)
                    for (int c = 0; c < 3; c++) {
                        double dk = fabs(got[k][c] - ref[k][c]);
                        e = fmax(e, isnan(dk) ? INFINITY : dk / fmax(smax, 1e-300));
                    }
                worst = fmax(worst, e);
                lit += smax > 0;
                if (!(e <= 1e-9) && bad++ < 5)
                    print_message("light lanes in double vs fp_light_ray, fog %zu, phase %s, "
                                  "light %s: %.3g of the largest S (bound 1e-9)\n", fi,
                                  phases[pi], lights[li], e);
                rig_close(&r);
            }
    print_message("fast local lights, lanes (scatter_lanes.h) in double vs fp_light_ray: max "
                  "|dS| %.3g of the largest S over %ld rays, %d of %zu configurations lit (bound "
                  "1e-9)\n", worst, rays, lit,
                  FP_ARRAY_LEN(fogs) * FP_ARRAY_LEN(phases) * FP_ARRAY_LEN(lights));
    assert_int_equal(bad, 0);
    /* (A few spots light none of their rays: the haze alone, cones away.) */
    assert_true((size_t)lit * 10 >= FP_ARRAY_LEN(fogs) * FP_ARRAY_LEN(phases) *
                                         FP_ARRAY_LEN(lights) * 9);
}

/* The fast local lights' kernel (scatter_lights: all lights in one
 * launch, 16 pixels per work-item as float16 lanes) against the C
 * reference on the sample frame with the night-street-lamps look (no
 * fogmap): the whole frame (perspective and orthographic), the frame cut
 * to 53x37 (rows not a multiple of the lanes: the last work-item of a row
 * holds 5 pixels) with planar, radial and inverse depth and sky pixels,
 * and pixel lists of 1024 and 1019 entries against the whole frame and
 * against the C reference. */
static void test_light_fast_opencl(void **state)
{
    (void)state;
    static const char *const opts[] = {
        "density", "0.05", "height", "0,8", "fog-color", "0.004,0.006,0.012", "phase", "hg:0.8",
        "light", "point:-4,3.5,6:1.0,0.55,0.2:30", "light", "point:3,3.5,14:1.0,0.55,0.2:30",
        "light", "spot:0,7,26:0.75,0.85,1.0:200:0,-1,-0.15:15,30", NULL };
    if (!sample_scene())
        skip();
    cl_rig_t cr;
    cl_rig_open(&cr);
    scene_t sc;
    assert_int_equal(scene_open(&sc, opts, 0), 0);
    size_t npx = (size_t)sc.w * sc.h;
    float *ref = malloc(npx * 4 * sizeof *ref), *got = malloc(npx * 4 * sizeof *got);
    /* Perspective, then the same projection read as orthographic (rays
     * from the camera's plane: scatter_lights' own origin and direction). */
    for (int ortho = 1; ortho >= 0; ortho--) {
        sc.v.ortho = ortho;
        assert_int_equal(fp_scatter_process(&sc.r.sd, &sc.r.fog, &sc.v, sc.depth, ref), FP_OK);
        assert_int_equal(fp_scatter_process_cl(&cr.scl, &cr.icl, &sc.r.sd, &sc.r.fog, &sc.v, sc.depth,
                                               got), FP_OK);
        double max_ds = 0, max_rel = 0, smax = 0;
        long failures = 0;
        for (size_t i = 0; i < npx; i++)
            for (int c = 0; c < 4; c++) {
                double a = ref[4 * i + c], b = got[4 * i + c], e = fabs(b - a);
                if (c < 3)
                    max_ds = fmax(max_ds, e);
                smax = fmax(smax, c < 3 ? a : 0);
                if (fabs(a) > 1e-3)
                    max_rel = fmax(max_rel, e / fabs(a));
                failures += !(e <= fmax(2e-3 * fabs(a), 1e-4));
            }
        print_message("OpenCL vs C, fast local lights (night street lamps, no fogmap, %dx%d%s): "
                      "max |dS| %.3g (S up to %.3g), max relative (values > 1e-3) %.3g; "
                      "tolerance 2e-3 relative or 1e-4\n", sc.w, sc.h,
                      ortho ? ", orthographic" : "", max_ds, smax, max_rel);
        assert_int_equal(failures, 0);
        assert_true(smax > 0.01);
    }
    int *pix = malloc((npx / 3 + 1) * sizeof *pix);
    float *lst = malloc((npx / 3 + 1) * 4 * sizeof *lst), *lref = malloc((npx / 3 + 1) * 4 * sizeof *lref);
    size_t m = test_pixel_list(npx, pix);
    /* 1024 entries (64 work-items of 16 lanes), then 1019 (the last
     * work-item holds 11). */
    for (size_t mm = m; mm + 5 >= m; mm -= 5) {
        assert_int_equal(fp_scatter_pixels_cl(&cr.scl, &cr.icl, &sc.r.sd, &sc.r.fog, &sc.v, sc.depth,
                                              pix, mm, lst), FP_OK);
        double cl_list = test_list_diff(got, pix, mm, lst);
        assert_int_equal(fp_scatter_pixels(&sc.r.sd, &sc.r.fog, &sc.v, sc.depth, pix, mm, lref),
                         FP_OK);
        long lfail = 0;
        double lmax = 0;
        for (size_t i = 0; i < 4 * mm; i++) {
            double e = fabs((double)lst[i] - lref[i]);
            lmax = fmax(lmax, isnan(e) ? INFINITY : e);
            lfail += !(e <= fmax(2e-3 * fabs(lref[i]), 1e-4));
        }
        print_message("fast local lights, pixel list of %zu: vs the whole frame (OpenCL) %.3g "
                      "(bound 1e-6), vs the C reference max |d| %.3g (tolerance 2e-3 relative or "
                      "1e-4)\n", mm, cl_list, lmax);
        assert_true(cl_list <= 1e-6);
        assert_int_equal(lfail, 0);
    }
    /* The frame cut to 53x37, the same camera (pixel (x, y) keeps its
     * ray), with the depth read as planar, radial and inverse (1/z), and
     * a NaN, a negative and an infinite depth among the pixels (sky). */
    for (int kind = FP_DEPTH_PLANAR; kind <= FP_DEPTH_INVERSE; kind++) {
        int cw = 53, ch = 37;
        float *cd = malloc((size_t)cw * ch * sizeof *cd);
        for (int y = 0; y < ch; y++)
            for (int x = 0; x < cw; x++) {
                float z = sc.depth[(size_t)y * sc.w + x];
                cd[(size_t)y * cw + x] =
                    kind != FP_DEPTH_INVERSE ? z : isfinite(z) && z > 0 && z < 1e10f ? 1 / z : 0;
            }
        cd[3] = NAN;
        cd[cw + 7] = -1;
        cd[2 * cw + 40] = INFINITY;
        fp_view_t cv = sc.v;
        cv.width = cw;
        cv.height = ch;
        cv.depth_kind = kind;
        assert_int_equal(fp_scatter_process(&sc.r.sd, &sc.r.fog, &cv, cd, ref), FP_OK);
        assert_int_equal(fp_scatter_process_cl(&cr.scl, &cr.icl, &sc.r.sd, &sc.r.fog, &cv, cd, got),
                         FP_OK);
        long cfail = 0;
        double cmax = 0, csmax = 0;
        for (size_t i = 0; i < (size_t)cw * ch * 4; i++) {
            double e = fabs((double)got[i] - ref[i]);
            cmax = fmax(cmax, isnan(e) ? INFINITY : e);
            csmax = fmax(csmax, i % 4 < 3 ? ref[i] : 0);
            cfail += !(e <= fmax(2e-3 * fabs(ref[i]), 1e-4));
        }
        static const char *const kinds[] = { "planar", "radial", "inverse" };
        print_message("OpenCL vs C, fast local lights, the frame cut to %dx%d, %s depth: max |d| "
                      "%.3g (S up to %.3g; tolerance 2e-3 relative or 1e-4)\n", cw, ch,
                      kinds[kind], cmax, csmax);
        assert_int_equal(cfail, 0);
        assert_true(csmax > 0.01);
        free(cd);
    }
    free(pix);
    free(lst);
    free(lref);
    free(ref);
    free(got);
    scene_close(&sc);
    cl_rig_close(&cr);
}

int main(int argc, char **argv)
{
    test_argv0 = argv[0];
    /* tests/test_lightfast PATTERN (or FP_TEST_FILTER=PATTERN): only the
     * tests whose names match (cmocka's pattern). */
    if (argc > 1)
        cmocka_set_test_filter(argv[1]);
    else if (getenv("FP_TEST_FILTER"))
        cmocka_set_test_filter(getenv("FP_TEST_FILTER"));
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_light_fast),
        cmocka_unit_test(test_light_lanes),
        cmocka_unit_test(test_light_fast_opencl),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    remove_scene();
    return rc;
}

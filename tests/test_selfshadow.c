/* Fog self-shadowing in the scatter stage (exact, and the per-frame grid)
 * against brute-force quadrature of sigma_t along the sun ray, fogmaps
 * included; one ray before any frame fills the grid (split from
 * tests/test_scatter.c; helpers in tests/scatter_testutil.h). */
#include "scatter_testutil.h"

static void test_self_shadow_exact(void **state)
{
    (void)state;
    static const struct {
        const char *basis, *wrap, *height, *box;
        int w, h;
    } cases[] = {
        { "cubic", "zero", "1,6,14", NULL, 13, 9 },
        { "quadratic", "repeat", "1,6", NULL, 16, 8 },
        { "cubic", "clamp", "1,6,14", "-8,-1,-4,14,9,12", 13, 9 },
        { "linear", "zero", "1,4", "-6,-2,-3,12,7,10", 12, 10 },
    };
    double worst_all = 0;
    for (size_t ci = 0; ci < FP_ARRAY_LEN(cases); ci++) {
        rig_t r;
        float *img;
        self_rig(&r, &img, cases[ci].w, cases[ci].h, "0.2", cases[ci].basis, cases[ci].wrap,
                 cases[ci].height, cases[ci].box, "exact", NULL);
        const double *l = r.sd.lt + FP_LT_SUN_DIR;
        double worst = 0, span = 0;
        /* fp_sigma_t is the fogmap's B-spline surface (checked against its
         * definition where no box or clipping intervenes). */
        if (!cases[ci].box && strcmp(cases[ci].wrap, "zero") != 0)
            for (int k = 0; k < 200; k++) {
                double x = MA0 + 2.0 * cases[ci].w * urand(), y = -1 + 12 * urand(),
                       z = MB0 + 1.5 * cases[ci].h * urand();
                const fp_fog_tables_t *t = r.fog.tables;
                double got = fp_sigma_t(r.fog.fp, t->lvi, t->lvf, t->coef, x, y, z);
                double want = 0.2 * (y < 1 ? 1 : exp(-(y - 1) / 6)) *
                              fmax(fp_fogmap_eval_direct(img, cases[ci].w, cases[ci].h,
                                                         r.p.fogmap.basis, r.p.fogmap.wrap,
                                                         (x - MA0) / 2, (z - MB0) / 1.5), 0);
                if (!(fabs(got - want) <= 1e-6 * 0.2 * 2))
                    fail_msg("case %zu: fp_sigma_t(%g,%g,%g) %.9g, the B-spline surface %.9g", ci,
                             x, y, z, got, want);
            }
        for (int k = 0; k < 60; k++) {
            double p[3] = { MA0 - 4 + (2.0 * cases[ci].w + 8) * urand(), -1.5 + 13 * urand(),
                            MB0 - 4 + (1.5 * cases[ci].h + 8) * urand() };
            double od = sun_od_brute(&r, p, l, 0.004);
            double tb = exp(-od), te = tau_of(&r, p);
            double e = fabs(te - tb) / tb;
            worst = fmax(worst, e);
            span = fmax(span, od);
            if (!(e <= 1e-3))
                fail_msg("case %zu (%s, %s) point (%g,%g,%g): fp_sun_tau %.10g, brute force "
                         "%.10g (relative %.3g, tolerance 1e-3)", ci, cases[ci].basis,
                         cases[ci].wrap, p[0], p[1], p[2], te, tb, e);
        }
        print_message("self-shadow exact, %s %s%s: max relative error of tau_sun %.3g "
                      "(optical depths up to %.2f; tolerance 1e-3)\n", cases[ci].basis,
                      cases[ci].wrap, cases[ci].box ? " in a box" : "", worst, span);
        worst_all = fmax(worst_all, worst);
        rig_close(&r);
        free(img);
    }
    print_message("self-shadowing (exact) vs brute force: max relative error %.3g (tolerance "
                  "1e-3)\n", worst_all);
}

static void test_self_shadow_grid(void **state)
{
    (void)state;
    double cell[3], e[2];
    /* A fog with bounds (a fogmap that does not wrap, a top), on a frame of
     * 16 x 12 pixels.  The grid's error grows with the optical depth
     * across a cell: with 128 x 128 x 64 nodes per cascade, at density
     * 0.06 within 1e-3, at 0.2 within 3e-3 (the tolerances of the
     * world-aligned grid of 96 x 48 x 96 nodes before; its error was
     * 2.8e-4 and 1.5e-3).  The default sizes the grid by the frame: at
     * this frame's 192 pixels its smallest, 64 x 64 x 32, measured and
     * printed. */
    static const struct { const char *density, *grid; double tol; } dens[] = {
        { "0.06", "128,128,64", 1e-3 }, { "0.2", "128,128,64", 3e-3 },
        { "0.06", NULL, 0 }, { "0.2", NULL, 0 } };
    for (size_t i = 0; i < FP_ARRAY_LEN(dens); i++) {
        grid_error(dens[i].density, "1,6,14", "zero", dens[i].grid, 150, cell, e);
        print_message("self-shadow map, grid %s, bounded fog of density %s (finest cells %.3g x "
                      "%.3g across the sun, %.3g in height): max relative error of tau_sun %.3g "
                      "over the cascades, %.3g along the view rays", dens[i].grid ? dens[i].grid
                      : "0,0,32 (default)", dens[i].density, cell[0], cell[1], cell[2], e[0],
                      e[1]);
        if (dens[i].tol > 0)
            print_message(" (tolerance %g)", dens[i].tol);
        print_message("\n");
        if (dens[i].tol > 0 && !(e[0] <= dens[i].tol && e[1] <= dens[i].tol))
            fail_msg("self-shadow grid, density %s: relative error %.3g / %.3g above %g",
                     dens[i].density, e[0], e[1], dens[i].tol);
    }
    /* Without bounds (a repeating fogmap under a height profile without a
     * top) the sky rays reach to where their optical depth passes the
     * integrator's stop (filters/scatter.c grid_bounds), hundreds of units
     * down into the fog below its base; the cascades keep the nodes dense
     * near the camera and the weight follows the height profile (a
     * world-aligned grid over the whole reach had cells of 4.86 x 5.3 x
     * 2.22 and an error of 0.398; the cascades: from 0.03 to 0.9 over
     * random frames, where the coarse cascades reach hundreds of units
     * below the base, and the sun's optical depth is large): measured and
     * printed, not bounded. */
    for (int run = 0; run < 4; run++) {
        grid_error("0.06", "1,6", "repeat", NULL, 150, cell, e);
        print_message("self-shadow map, default grid, unbounded repeating fogmap with sky in "
                      "view, random frame %d: finest cells %.3g x %.3g x %.3g, max relative "
                      "error of tau_sun %.3g over the cascades, %.3g along the view rays up to 60 "
                      "units (not bounded; the world-aligned grid before: 0.398 and 0.355)\n",
                      run + 1, cell[0], cell[1], cell[2], e[0], e[1]);
    }
    /* Without a fogmap the exact optical depth toward the sun is a closed
     * form, so --self-shadow map uses it instead of a grid. */
    {
        rig_t r;
        const char *opts[] = { "density", "0.06", "height", "1,6", "sun", "0.3,0.5,-0.4",
                               "self-shadow", "map", NULL };
        rig_open(&r, opts);
        fp_view_t v;
        assert_int_equal(make_view(&v, 8, 6, 3, -20), 0);
        float depth[48], out[48 * 4];
        for (int i = 0; i < 48; i++)
            depth[i] = (float)(1 + i);
        assert_int_equal(fp_scatter_frame(&r.p, &r.sd, &r.fog, &v, depth, 1), FP_OK);
        assert_int_equal(fp_scatter_process(&r.sd, &r.fog, &v, depth, out), FP_OK);
        assert_int_equal((int)r.sd.lt[FP_LT_SELF], FP_SELF_EXACT);
        assert_null(r.sd.grid);
        rig_close(&r);
    }
}

/* The default self-shadowing (the grid) on the look of make bench's
 * "low-sun-shafts + fogmap" row: the preset's fog (density 0.03 to a top
 * at 15) times the sample fogmap, linear, 3 levels, frame 1 of the sample
 * scene.  tau_sun of the grid against exact along the view rays. */
static void test_self_shadow_grid_scene(void **state)
{
    (void)state;
    /* The default at this 64 x 48 frame is its smallest grid (64 x 64 x
     * 32 nodes per cascade); 256 x 256 x 64 is what it becomes at 512 x
     * 512 pixels and above. */
    static const struct { const char *grid, *cascades; double tol; } runs[] = {
        { NULL, NULL, 1e-2 }, { "256,256,64", "3", 1e-3 }, { "128,128,32", "3", 0 },
    };
    for (size_t k = 0; k < FP_ARRAY_LEN(runs); k++) {
        const char *opts[24] = { "density", "0.03", "height", "0,inf,15", "sun", "-0.4,0.35,0.6",
                                 "basis", "linear", "self-shadow", "auto", NULL };
        int n = 10;
        if (runs[k].grid) {
            opts[n++] = "self-shadow-grid";
            opts[n++] = runs[k].grid;
            opts[n++] = "self-shadow-cascades";
            opts[n++] = runs[k].cascades;
        }
        opts[n] = NULL;
        scene_t sc;
        if (scene_open(&sc, opts, 1))
            skip();
        float *out = malloc((size_t)sc.w * sc.h * 4 * sizeof *out);
        assert_non_null(out);
        assert_int_equal(fp_scatter_process(&sc.r.sd, &sc.r.fog, &sc.v, sc.depth, out), FP_OK);
        assert_int_equal((int)sc.r.sd.lt[FP_LT_SELF], FP_SELF_MAP);
        assert_non_null(sc.r.sd.grid);
        double outside, e = grid_view_error(&sc.r, &sc.v, sc.depth, INFINITY, 4000, &outside);
        const double *c0 = sc.r.sd.lt + FP_LT_CASCADE;
        print_message("self-shadow map%s%s%s%s, low-sun-shafts + sample fogmap (linear, 3 "
                      "levels): finest cells %.3g x %.3g x %.3g, max relative error of tau_sun "
                      "%.3g along the view rays (%.2f%% of the points outside the cascades, "
                      "exact)%s\n", runs[k].grid ? " " : " (defaults 0,0,32 x 3)",
                      runs[k].grid ? runs[k].grid : "", runs[k].grid ? " x " : "",
                      runs[k].grid ? runs[k].cascades : "", c0[3], c0[4], c0[5], e,
                      100 * outside, runs[k].tol >= 1e-2 ? " (tolerance 1e-2)"
                                     : runs[k].tol > 0 ? " (tolerance 1e-3)" : "");
        if (runs[k].tol > 0 && !(e <= runs[k].tol))
            fail_msg("self-shadow grid on the low-sun-shafts look: %.3g above %g", e,
                     runs[k].tol);
        free(out);
        scene_close(&sc);
    }
}

/* One ray through fp_scatter_ray_at before any frame: it fills the
 * self-shadow grid it looks up (it read past an empty grid before), and
 * gives the frame's values. */
static void test_ray_fills_grid(void **state)
{
    (void)state;
    static const char *const opts[] = { "density", "0.03", "sun", "-0.4,0.35,0.6",
                                        "shadow-map", "-", "self-shadow", "map", NULL };
    scene_t sc;
    if (scene_open(&sc, opts, 1))
        skip();
    assert_int_equal((int)sc.r.sd.lt[FP_LT_SELF], FP_SELF_MAP);
    assert_null(sc.r.sd.grid);
    float view[FP_VIEW_FLOATS], px[4];
    fp_view_pack(&sc.v, view);
    double worst = 0;
    for (int k = 0; k < 16; k++) {
        int i = (k * 797) % (sc.w * sc.h);
        double d[3], len, o[3], S[3];
        fp_view_ray(&sc.v, i % sc.w, i / sc.w, sc.depth[i], d, &len);
        fp_view_origin_at(&sc.v, i % sc.w, i / sc.w, o);
        double tau = fp_scatter_ray_at(&sc.r.sd, &sc.r.fog, &sc.v, view, sc.depth, o, d, len, 0, S);
        assert_non_null(sc.r.sd.grid);
        assert_int_equal(fp_scatter_pixels(&sc.r.sd, &sc.r.fog, &sc.v, sc.depth, &i, 1, px), FP_OK);
        for (int c = 0; c < 3; c++)
            worst = fmax(worst, fabs(S[c] - px[c]) / fmax(fabs(px[c]), 1e-6));
        worst = fmax(worst, fabs(tau - px[3]));
    }
    print_message("a ray on its own fills the self-shadow grid: against the frame's pixels max "
                  "relative %.3g (float rounding)\n", worst);
    assert_true(worst <= 1e-6);
    scene_close(&sc);
}

int main(int argc, char **argv)
{
    test_argv0 = argv[0];
    /* tests/test_selfshadow PATTERN (or FP_TEST_FILTER=PATTERN): only the
     * tests whose names match (cmocka's pattern). */
    if (argc > 1)
        cmocka_set_test_filter(argv[1]);
    else if (getenv("FP_TEST_FILTER"))
        cmocka_set_test_filter(getenv("FP_TEST_FILTER"));
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_self_shadow_exact),
        cmocka_unit_test(test_self_shadow_grid),
        cmocka_unit_test(test_self_shadow_grid_scene),
        cmocka_unit_test(test_ray_fills_grid),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    remove_scene();
    return rc;
}

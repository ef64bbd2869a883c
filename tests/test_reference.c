/* The Monte Carlo reference (filters/reference.c, kernels/reference_core.h):
 * delta and ratio tracking against the closed-form transmittance of a
 * homogeneous slab and through a random fogmap with the majorant grid;
 * the majorant grid's bounds; single scattering of the sun, point, spot
 * and area lights against the test's own quadrature; a light close to
 * the ray; OpenCL against C; determinism.  Multiple bounces and the
 * deterministic integrator against the reference are
 * tests/test_bounces.c (helpers shared in tests/reference_testutil.h). */
#include "reference_testutil.h"

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
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

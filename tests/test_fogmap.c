/* The wavelet fogmap in the integrator: the exact integration (the C
 * reference, double) against brute-force quadrature of the fog's definition
 * for every basis and wrap mode over random rays; a constant fogmap equals
 * homogeneous fog; sparse skipping changes nothing; OpenCL against the C
 * reference on whole frames (|dtau| <= 1e-5); the error of level of detail,
 * early termination and marching, printed. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "clrt.h"
#include "fogmap.h"
#include "fp.h"
#include "integrate.h"
#include "options.h"
#include "testutil.h"
#include "wavelet.h"

#include "fog_core.h"   /* FP_F_* parameter slots */

/* The rectangle: fogmap pixels of 2 x 1.5 fog units. */
#define A0 (-10.0)
#define B0 (-5.0)
#define US 0.5
#define VS (1 / 1.5)
#define FY0 1.0
#define FH 6.0

typedef struct setup_t {
    fp_params_t p;
    fp_fogmap_stage_t s;
    fp_integrate_data_t d;
    float *img;
    int w, h;
} setup_t;

static void make(setup_t *st, int w, int h, int degree, int wrap, int levels, double top,
                 int zero_blocks)
{
    memset(st, 0, sizeof *st);
    fp_options_defaults(&st->p);
    fp_params_t *p = &st->p;
    p->fog.density = 0.05;
    p->fog.height[0] = FY0;
    p->fog.height[1] = FH;
    p->fog.height[2] = top;
    p->fogmap.basis = degree;
    p->fogmap.wrap = wrap;
    p->fogmap.levels = levels;
    p->fogmap.rect[0] = A0;
    p->fogmap.rect[1] = B0;
    p->fogmap.rect[2] = A0 + w / US;
    p->fogmap.rect[3] = B0 + h / VS;
    st->w = w;
    st->h = h;
    st->img = malloc((size_t)w * h * sizeof(float));
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            double v = urand() * 2;
            /* Whole empty blocks, for sparse skipping. */
            if (zero_blocks && ((i / 4 + j / 4) % 3 == 0))
                v = 0;
            st->img[j * w + i] = (float)v;
        }
    assert_int_equal(fp_integrate_commit(p, &st->d), FP_OK);
    assert_int_equal(fp_fogmap_setup(p, NULL, st->img, w, h, &st->s, &st->d), FP_OK);
}

static void unmake(setup_t *st)
{
    fp_fogmap_release(&st->s);
    fp_options_free(&st->p);
    free(st->img);
}

static double hprof(double y, double top)
{
    if (y >= top)
        return 0;
    return y < FY0 ? 1 : exp(-(y - FY0) / FH);
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Brute force: Gauss-Legendre (8 nodes) between every crossing of a
 * half-pixel line and of the height planes, where the integrand is smooth,
 * subdivided so the exponential changes little; F from its definition. */
static double brute(const setup_t *st, const double o[3], const double dir[3], double len,
                    double top)
{
    static const double x8[8] = { -0.9602898564975363, -0.7966664774136267, -0.5255324099163290,
                                  -0.1834346424956498, 0.1834346424956498, 0.5255324099163290,
                                  0.7966664774136267, 0.9602898564975363 };
    static const double w8[8] = { 0.1012285362903763, 0.2223810344533745, 0.3137066458778873,
                                  0.3626837833783620, 0.3626837833783620, 0.3137066458778873,
                                  0.2223810344533745, 0.1012285362903763 };
    double u0 = (o[0] - A0) * US, du = dir[0] * US, v0 = (o[2] - B0) * VS, dv = dir[2] * VS;
    size_t cap = 4096, n = 0;
    double *cut = malloc(cap * sizeof *cut);
    cut[n++] = 0;
    cut[n++] = len;
    const double sc[2][2] = { { u0, du }, { v0, dv } };
    for (int ax = 0; ax < 2; ax++) {
        double a = sc[ax][0], b = sc[ax][0] + len * sc[ax][1];
        if (sc[ax][1] == 0)
            continue;
        double lo = fmin(a, b), hi = fmax(a, b);
        for (double k = ceil(lo * 2) / 2; k <= hi; k += 0.5) {
            double t = (k - sc[ax][0]) / sc[ax][1];
            if (t > 0 && t < len) {
                if (n == cap)
                    cut = realloc(cut, (cap *= 2) * sizeof *cut);
                cut[n++] = t;
            }
        }
    }
    double planes[2] = { FY0, top };
    for (int i = 0; i < 2; i++)
        if (dir[1] != 0 && isfinite(planes[i])) {
            double t = (planes[i] - o[1]) / dir[1];
            if (t > 0 && t < len) {
                if (n == cap)
                    cut = realloc(cut, (cap *= 2) * sizeof *cut);
                cut[n++] = t;
            }
        }
    qsort(cut, n, sizeof *cut, cmp_d);
    double sum = 0;
    for (size_t i = 0; i + 1 < n; i++) {
        double a = cut[i], b = cut[i + 1];
        if (!(b > a))
            continue;
        int pieces = 1 + (int)(fabs(dir[1]) * (b - a) / FH / 0.05);
        double step = (b - a) / pieces;
        for (int q = 0; q < pieces; q++) {
            double c = a + (q + 0.5) * step;
            for (int g = 0; g < 8; g++) {
                double t = c + 0.5 * step * x8[g];
                double f = fp_fogmap_eval_direct(st->img, st->w, st->h, st->p.fogmap.basis,
                                                 st->p.fogmap.wrap, u0 + t * du, v0 + t * dv);
                sum += w8[g] * 0.5 * step * f * hprof(o[1] + t * dir[1], top);
            }
        }
    }
    free(cut);
    return st->p.fog.density * sum;
}

/* A random ray of one of the hard classes. */
static void random_ray(int k, double o[3], double dir[3], double *len)
{
    o[0] = -20 + 50 * urand();
    o[1] = -3 + 20 * urand();
    o[2] = -12 + 30 * urand();
    double d[3] = { urand() - 0.5, urand() - 0.5, urand() - 0.5 };
    switch (k % 6) {
    case 0: d[1] = 0; break;                           /* level */
    case 1: d[1] = (urand() - 0.5) * 1e-4; break;      /* grazing */
    case 2: d[0] = 0; break;                           /* along the grid's v */
    case 3: d[2] = 0; break;                           /* along the grid's u */
    case 4:                                            /* through a pixel corner */
        o[0] = A0 + 2.0 * (int)(urand() * 10);
        o[2] = B0 + 1.5 * (int)(urand() * 8);
        d[0] = 2.0;
        d[2] = 1.5;
        d[1] = urand() - 0.5;
        break;
    default: break;
    }
    double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int i = 0; i < 3; i++)
        dir[i] = d[i] / l;
    *len = 0.5 + 60 * urand();
}

static void test_exact_vs_brute_force(void **state)
{
    (void)state;
    double worst = 0;
    for (int degree = 0; degree <= 3; degree++)
        for (int wrap = 0; wrap <= 2; wrap++) {
            setup_t st;
            int w = wrap == FP_WRAP_REPEAT ? 16 : 13, h = wrap == FP_WRAP_REPEAT ? 8 : 9;
            make(&st, w, h, degree, wrap, 2, degree == 2 ? 14.0 : INFINITY, 0);
            double worst_here = 0;
            for (int k = 0; k < 120; k++) {
                double o[3], dir[3], len;
                random_ray(k, o, dir, &len);
                double a = fp_integrate_optical_depth(&st.d, o, dir, len, 0);
                double b = brute(&st, o, dir, len, st.p.fog.height[2]);
                /* Coefficients are floats: allow their rounding (1e-7 of the
                 * fogmap's scale) besides the relative bound. */
                double err = fabs(a - b) / (fabs(b) + 1e-2 * st.p.fog.density * len);
                worst_here = fmax(worst_here, err);
                if (!(err < 1e-6))
                    fail_msg("degree %d wrap %d ray %d o (%g,%g,%g) dir (%g,%g,%g) len %g: "
                             "exact %.12g brute force %.12g", degree, wrap, k, o[0], o[1], o[2],
                             dir[0], dir[1], dir[2], len, a, b);
            }
            print_message("degree %d wrap %d: max relative error %.2e\n", degree, wrap, worst_here);
            worst = fmax(worst, worst_here);
            unmake(&st);
        }
    print_message("exact integration vs brute force: max relative error %.2e (bound 1e-6)\n", worst);
}

/* --fog-offset, --fog-rotate and --fog-box, cameras inside and outside
 * the box: the exact integral equals brute force over the clipped ray in
 * the fog's own frame. */
static void test_moved_fog_in_a_box(void **state)
{
    (void)state;
    for (int degree = 0; degree <= 3; degree++) {
        setup_t st;
        make(&st, 13, 9, degree, FP_WRAP_CLAMP, 2, INFINITY, 0);
        const double off[3] = { 3.5, -0.5, -2 }, ang = 0.7;
        const double box[6] = { -8, -1, -4, 14, 9, 12 };
        for (int i = 0; i < 3; i++)
            st.d.fp[FP_F_OFF + i] = off[i];
        st.d.fp[FP_F_COS] = cos(ang);
        st.d.fp[FP_F_SIN] = sin(ang);
        for (int i = 0; i < 6; i++)
            st.d.fp[FP_F_BOX + i] = box[i];
        int outside = 0;
        for (int k = 0; k < 120; k++) {
            double o[3], dir[3], len;
            random_ray(k, o, dir, &len);
            /* The fog's frame: undo the offset, turn by -angle. */
            double p[3] = { o[0] - off[0], o[1] - off[1], o[2] - off[2] };
            double q[3] = { cos(ang) * p[0] - sin(ang) * p[2], p[1], sin(ang) * p[0] + cos(ang) * p[2] };
            double e[3] = { cos(ang) * dir[0] - sin(ang) * dir[2], dir[1],
                            sin(ang) * dir[0] + cos(ang) * dir[2] };
            double a = 0, b = len;
            int in = 1;
            for (int ax = 0; ax < 3; ax++) {
                in &= q[ax] >= box[ax] && q[ax] <= box[ax + 3];
                if (e[ax] == 0) {
                    if (q[ax] < box[ax] || q[ax] > box[ax + 3])
                        b = a;
                    continue;
                }
                double t0 = (box[ax] - q[ax]) / e[ax], t1 = (box[ax + 3] - q[ax]) / e[ax];
                a = fmax(a, fmin(t0, t1));
                b = fmin(b, fmax(t0, t1));
            }
            outside += !in;
            double want = 0;
            if (b > a) {
                double q0[3] = { q[0] + a * e[0], q[1] + a * e[1], q[2] + a * e[2] };
                want = brute(&st, q0, e, b - a, INFINITY);
            }
            double got = fp_integrate_optical_depth(&st.d, o, dir, len, 0);
            double err = fabs(got - want) / (fabs(want) + 1e-2 * st.p.fog.density * len);
            if (!(err < 1e-6))
                fail_msg("degree %d ray %d (camera %s the box): exact %.12g brute force %.12g",
                         degree, k, in ? "inside" : "outside", got, want);
        }
        assert_true(outside > 10);
        unmake(&st);
    }
}

/* --fog-offset and --fog-box are on the world's axes: with --up z they
 * land in fog space (x, z, -y). */
static void test_offset_and_box_world_axes(void **state)
{
    (void)state;
    fp_params_t p;
    fp_integrate_data_t d;
    fp_options_defaults(&p);
    assert_int_equal(fp_options_apply(&p, "up", "z", "test"), FP_OK);
    assert_int_equal(fp_options_apply(&p, "fog-offset", "1,2,3", "test"), FP_OK);
    assert_int_equal(fp_options_apply(&p, "fog-box", "-1,-2,-3,4,5,6", "test"), FP_OK);
    assert_int_equal(fp_integrate_commit(&p, &d), FP_OK);
    const double off[3] = { 1, 3, -2 }, box[6] = { -1, -3, -5, 4, 6, 2 };
    for (int i = 0; i < 3; i++)
        assert_double_equal(d.fp[FP_F_OFF + i], off[i], 0);
    for (int i = 0; i < 6; i++)
        assert_double_equal(d.fp[FP_F_BOX + i], box[i], 0);
    fp_options_free(&p);
}

static void test_constant_is_homogeneous(void **state)
{
    (void)state;
    for (int degree = 0; degree <= 3; degree++) {
        setup_t st;
        make(&st, 16, 8, degree, FP_WRAP_REPEAT, 2, INFINITY, 0);
        for (int i = 0; i < 16 * 8; i++)
            st.img[i] = 1;
        fp_fogmap_release(&st.s);
        assert_int_equal(fp_fogmap_setup(&st.p, NULL, st.img, 16, 8, &st.s, &st.d), FP_OK);
        fp_integrate_data_t plain;
        assert_int_equal(fp_integrate_commit(&st.p, &plain), FP_OK);
        for (int k = 0; k < 200; k++) {
            double o[3], dir[3], len;
            random_ray(k, o, dir, &len);
            double a = fp_integrate_optical_depth(&st.d, o, dir, len, 0);
            double b = fp_integrate_optical_depth(&plain, o, dir, len, 0);
            assert_double_equal(a, b, 1e-9 * (1 + b));
        }
        unmake(&st);
    }
}

static void test_sparse_exact(void **state)
{
    (void)state;
    for (int degree = 0; degree <= 3; degree++) {
        setup_t st;
        make(&st, 48, 32, degree, FP_WRAP_ZERO, 2, INFINITY, 1);
        fp_integrate_data_t off = st.d;
        off.fp[FP_F_SPARSE] = 0;
        assert_true(st.d.fp[FP_F_SPARSE] != 0);
        for (int k = 0; k < 300; k++) {
            double o[3], dir[3], len;
            random_ray(k, o, dir, &len);
            len *= 3;
            double a = fp_integrate_optical_depth(&st.d, o, dir, len, 0);
            double b = fp_integrate_optical_depth(&off, o, dir, len, 0);
            assert_double_equal(a, b, 1e-12 * (1 + b));
        }
        unmake(&st);
    }
}

static void test_opencl_parity(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    if (fp_cl_open(NULL, &cl) != FP_OK)
        skip();
    fp_integrate_cl_t s;
    assert_int_equal(fp_integrate_cl_init(cl, &s), FP_OK);
    const int w = 160, h = 96;
    size_t n = (size_t)w * h;
    float *depth = malloc(n * sizeof(float)), *ref = malloc(n * 4 * sizeof(float)),
          *got = malloc(n * 4 * sizeof(float));
    for (int degree = 0; degree <= 3; degree++) {
        setup_t st;
        make(&st, 40, 24, degree, degree % 3, 3, degree == 1 ? 12.0 : INFINITY, 1);
        if (degree & 1) {
            /* A moved, turned fog in a box the camera is outside of. */
            const double box[6] = { -5, -1, -5, 20, 8, 15 };
            for (int i = 0; i < 6; i++)
                st.d.fp[FP_F_BOX + i] = box[i];
            st.d.fp[FP_F_OFF] = 1.5;
            st.d.fp[FP_F_COS] = cos(0.3);
            st.d.fp[FP_F_SIN] = sin(0.3);
        }
        fp_view_t v;
        assert_int_equal(make_view(&v, w, h, 2 + 4 * degree, -20), 0);
        for (size_t i = 0; i < n; i++) {
            double u = urand();
            depth[i] = u < 0.05 ? INFINITY : (float)pow(10, -1 + 2.5 * urand());
        }
        assert_int_equal(fp_integrate_process(&st.d, &v, depth, ref, NULL), FP_OK);
        assert_int_equal(fp_integrate_process_cl(&s, &st.d, &v, depth, got), FP_OK);
        double worst = 0;
        for (size_t i = 0; i < n; i++) {
            double e = fabs((double)got[4 * i + 3] - ref[4 * i + 3]);
            worst = fmax(worst, e);
            if (!(e <= 1e-5))
                fail_msg("degree %d pixel %zu depth %g: cl %.9g ref %.9g", degree, i, depth[i],
                         got[4 * i + 3], ref[4 * i + 3]);
        }
        print_message("degree %d: OpenCL vs C reference max |dtau| %.2e (tolerance 1e-5)\n",
                      degree, worst);
        unmake(&st);
    }
    free(depth);
    free(ref);
    free(got);
    fp_integrate_cl_release(&s);
    fp_cl_close(cl);
}

/* Rendering the raw bands (no deconstruction) integrates the same fog. */
static void test_without_deconstruction(void **state)
{
    (void)state;
    for (int degree = 0; degree <= 3; degree++) {
        setup_t st, raw;
        make(&st, 24, 16, degree, degree % 3, 2, INFINITY, 0);
        /* Same parameters (strings shared, freed once with st). */
        memset(&raw, 0, sizeof raw);
        raw.p = st.p;
        raw.p.fogmap.deconstruct = 0;
        assert_int_equal(fp_integrate_commit(&raw.p, &raw.d), FP_OK);
        assert_int_equal(fp_fogmap_setup(&raw.p, NULL, st.img, 24, 16, &raw.s, &raw.d), FP_OK);
        for (int k = 0; k < 100; k++) {
            double o[3], dir[3], len;
            random_ray(k, o, dir, &len);
            double a = fp_integrate_optical_depth(&st.d, o, dir, len, 0);
            double b = fp_integrate_optical_depth(&raw.d, o, dir, len, 0);
            assert_double_equal(b, a, 1e-6 * (1 + a));
        }
        fp_fogmap_release(&raw.s);
        unmake(&st);
    }
}

/* Fast paths are measured against the exact answer; their errors printed,
 * and bounded where a bound is known. */
static void test_fast_path_errors(void **state)
{
    (void)state;
    setup_t st;
    make(&st, 64, 64, 1, FP_WRAP_ZERO, 4, INFINITY, 0);
    fp_integrate_data_t lod = st.d, term = st.d, march = st.d;
    lod.fp[FP_F_LOD_MU] = 0.5;
    term.fp[FP_F_OD_MAX] = -log(0.01);   /* --min-transmittance 0.01 */
    march.fp[FP_F_MODE] = 1;            /* --integrator march */
    march.fp[FP_F_STEPS] = 1024;
    double e_lod = 0, e_term = 0, e_march = 0;
    for (int k = 0; k < 300; k++) {
        double o[3], dir[3], len;
        random_ray(k, o, dir, &len);
        len *= 4;
        double t = exp(-fp_integrate_optical_depth(&st.d, o, dir, len, 0));
        e_lod = fmax(e_lod, fabs(exp(-fp_integrate_optical_depth(&lod, o, dir, len, 0)) - t));
        e_term = fmax(e_term, fabs(exp(-fp_integrate_optical_depth(&term, o, dir, len, 0)) - t));
        e_march = fmax(e_march, fabs(exp(-fp_integrate_optical_depth(&march, o, dir, len, 0)) - t));
    }
    print_message("max |dtau| against exact: lod-mu 0.5 %.2e, min-transmittance 0.01 %.2e, "
                  "march 1024 steps %.2e\n", e_lod, e_term, e_march);
    /* Stopping below T = 0.01 can only leave tau in [0, 0.01]. */
    assert_true(e_term <= 0.01);
    assert_true(e_march < 1e-3);
    unmake(&st);
}


/* The one walk per ray over the sum surfaces A_l (kernels/fog_core.h,
 * fp_grid_walk) against the walk of every level on its own grid (the
 * path of raw bands, run here on the deconstructed levels): the same
 * integral, with all levels and with levels dropped by --lod-mu and
 * --lod-footprint (A_l refined from the coarser levels, filters/fogmap.c). */
static void test_walk_matches_levels(void **state)
{
    (void)state;
    double worst = 0;
    for (int degree = 0; degree <= 3; degree++)
        for (int wrap = 0; wrap <= 2; wrap++) {
            setup_t st;
            int w = wrap == FP_WRAP_REPEAT ? 32 : 27, h = wrap == FP_WRAP_REPEAT ? 16 : 19;
            make(&st, w, h, degree, wrap, 3, INFINITY, 0);
            fp_fog_tables_t levels = *st.d.tables;
            levels.lvi[FP_LI_APPROX] = -1;          /* no sum surfaces: level by level */
            for (int lod = 0; lod < 3; lod++) {
                fp_integrate_data_t a = st.d, b = st.d;
                b.tables = &levels;
                if (lod == 1)
                    a.fp[FP_F_LOD_MU] = b.fp[FP_F_LOD_MU] = 0.6;
                if (lod == 2)
                    a.fp[FP_F_FOOTPRINT] = b.fp[FP_F_FOOTPRINT] = 0.05;
                for (int k = 0; k < 90; k++) {
                    double o[3], dir[3], len;
                    random_ray(k, o, dir, &len);
                    double x = fp_integrate_optical_depth(&a, o, dir, len, 0);
                    double y = fp_integrate_optical_depth(&b, o, dir, len, 0);
                    /* The sums are rounded to float like the levels. */
                    double err = fabs(x - y) / (fabs(y) + 1e-2 * st.p.fog.density * len);
                    worst = fmax(worst, err);
                    if (!(err < 1e-6))
                        fail_msg("degree %d wrap %d lod %d ray %d: one walk %.12g, level by "
                                 "level %.12g", degree, wrap, lod, k, x, y);
                }
            }
            unmake(&st);
        }
    print_message("one walk over the sum surfaces vs level by level: max relative difference "
                  "%.2e (bound 1e-6)\n", worst);
}

/* The fog of the resumable walk's tests: 3 levels, a top for the
 * quadratic basis, empty blocks for the cubic. */
static void make_walk_case(setup_t *st, int degree, int wrap)
{
    int w = wrap == FP_WRAP_REPEAT ? 32 : 27, h = wrap == FP_WRAP_REPEAT ? 16 : 19;
    make(st, w, h, degree, wrap, 3, degree == 2 ? 14.0 : INFINITY, degree == 3);
}

/* The resumable walk (fp_fog_cur_t): the optical depth over increasing
 * cut points of one ray, one cursor, equals fp_fog_od over each stretch
 * from its start (what the callers computed before) to 1e-12 relative, for
 * every basis and wrap, a fog box, a top, the haze, infinite rays, and the
 * fallbacks (lod, early termination, march), and the stretches of a ray
 * add up to fp_fog_od of the whole ray (the walk's cases, 1e-10); relative to the stretch's
 * optical depth, or to 1e-3 of the one it would have at F = 1 where it has
 * next to no fog. */
static void test_cursor_matches_fog_od(void **state)
{
    (void)state;
    double worst = 0, worst_sum = 0;
    int stretches = 0;
    for (int degree = 0; degree <= 3; degree++)
        for (int wrap = 0; wrap <= 2; wrap++) {
            setup_t st;
            make_walk_case(&st, degree, wrap);
            for (int variant = 0; variant < 6; variant++) {
                fp_integrate_data_t dd = st.d;
                if (variant == 1) {
                    /* A moved, turned fog in a box, with haze. */
                    const double box[6] = { -5, -1, -5, 20, 8, 15 };
                    for (int i = 0; i < 6; i++)
                        dd.fp[FP_F_BOX + i] = box[i];
                    dd.fp[FP_F_OFF] = 1.5;
                    dd.fp[FP_F_COS] = cos(0.3);
                    dd.fp[FP_F_SIN] = sin(0.3);
                    dd.fp[FP_F_HAZE] = 0.02;
                    dd.fp[FP_F_HAZE + 1] = 0.5;
                    dd.fp[FP_F_HAZE + 2] = 3;
                    dd.fp[FP_F_HAZE + 3] = 9;
                }
                /* The fallbacks to fp_fog_od per stretch. */
                if (variant == 2)
                    dd.fp[FP_F_LOD_MU] = 0.6;
                if (variant == 3)
                    dd.fp[FP_F_OD_MAX] = 0.3;
                if (variant == 4) {
                    dd.fp[FP_F_MODE] = 1;
                    dd.fp[FP_F_STEPS] = 16;
                }
                if (variant == 5)
                    dd.fp[FP_F_LOD_BOUND] = 1e-4;
                const fp_fog_tables_t *t = dd.tables;
                for (int k = 0; k < 60; k++) {
                    double o[3], dir[3], len;
                    random_ray(k, o, dir, &len);
                    if (k % 5 == 0)
                        len = INFINITY;
                    double span = isinf(len) ? 80 : len;
                    /* Sorted cut points, some repeated, some past len. */
                    double cut[24];
                    int n = 1 + (int)(urand() * 22);
                    for (int i = 0; i < n; i++)
                        cut[i] = urand() * span * 1.1;
                    if (n > 3)
                        cut[2] = cut[1];
                    qsort(cut, (size_t)n, sizeof cut[0], cmp_d);
                    cut[n++] = len;
                    fp_fog_cur_t cur;
                    fp_fog_cur_init(&cur, dd.fp, t->lvi, o[0], o[1], o[2], dir[0], dir[1],
                                    dir[2], len);
                    /* The walk itself where it applies, else the fallback. */
                    assert_int_equal(cur.walk, variant < 2);
                    double t0 = 0, total = 0;
                    for (int i = 0; i < n; i++) {
                        double t1 = fmin(cut[i], len);
                        double got = fp_fog_cur_advance(&cur, dd.fp, FP_TABLES(t), t1);
                        double ref = 0;
                        total += got;
                        /* An infinite end: the whole ray's sum, below. */
                        if (isinf(t1))
                            continue;
                        if (t1 > t0) {
                            double p[3] = { o[0] + t0 * dir[0], o[1] + t0 * dir[1],
                                            o[2] + t0 * dir[2] };
                            ref = fp_integrate_optical_depth(&dd, p, dir, t1 - t0, 0);
                        }
                        /* Relative; a stretch with next to no fog (below 1e-3 of the
                         * optical depth it would have at F = 1) absolutely. */
                        double floor_od = 1e-3 * dd.fp[FP_F_SIGMA] * (t1 - t0);
                        double err = got == ref ? 0 : fabs(got - ref) / fmax(fabs(ref), floor_od);
                        worst = fmax(worst, err);
                        stretches++;
                        if (!(err <= 1e-12))
                            fail_msg("degree %d wrap %d variant %d ray %d stretch %d [%g, %g]: "
                                     "cursor %.17g, fp_fog_od %.17g", degree, wrap, variant, k,
                                     i, t0, t1, got, ref);
                        t0 = fmax(t0, t1);
                    }
                    /* The stretches add up to the whole ray's optical depth (to
                     * 1e-10: each stretch's haze starts at o + t dir rounded,
                     * which moves a grazing ray's crossing of the haze's base
                     * by that rounding over its slope). */
                    double whole = fp_integrate_optical_depth(&dd, o, dir, len, 0);
                    double floor_od = 1e-3 * dd.fp[FP_F_SIGMA] * fmin(span, 50);
                    double err = total == whole ? 0
                                 : fabs(total - whole) / fmax(fabs(whole), floor_od);
                    if (variant >= 2)
                        continue;   /* per stretch by design (early termination) */
                    worst_sum = fmax(worst_sum, err);
                    if (!(err <= 1e-10))
                        fail_msg("degree %d wrap %d variant %d ray %d: stretches add up to %.17g, "
                                 "fp_fog_od of the ray %.17g", degree, wrap, variant, k, total,
                                 whole);
                }
            }
            unmake(&st);
        }
    print_message("resumable walk vs fp_fog_od per stretch: max relative difference %.2e over "
                  "%d stretches; their sums vs fp_fog_od of the whole ray %.2e (bounds 1e-12, 1e-10)\n",
                  worst, stretches, worst_sum);
}

/* The resumable walk in single precision (the OpenCL compilation of
 * fog_core.h, in a test kernel built from the integrate program's source)
 * against the C reference, fp_fog_od in double over each stretch: every
 * basis and wrap, random rays and cut points; |d| <= 1e-5 + 1e-4 |od|. */
static const char cursor_kernel[] =
    "\n__kernel void cursor_test(__global const float *ray, __global const float *cut,\n"
    "    __global float *out, __constant const float *fp, __constant const int *lvi,\n"
    "    __constant const float *lvf, __global const float *coef, __global const uchar *occ)\n"
    "{\n"
    "    int r = get_global_id(0);\n"
    "    __global const float *q = ray + 8 * r;\n"
    "    fp_fog_cur_t cur;\n"
    "    fp_fog_cur_init(&cur, fp, lvi, q[0], q[1], q[2], q[3], q[4], q[5], q[6]);\n"
    "    for (int i = 0; i < (int)q[7]; i++)\n"
    "        out[24 * r + i] = fp_fog_cur_advance(&cur, fp, lvi, lvf, coef, occ, cut[24 * r + i]);\n"
    "}\n";

static void test_cursor_opencl(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    if (fp_cl_open(NULL, &cl) != FP_OK)
        skip();
    const char *base = NULL;
    for (int i = 0; i < fp_kernel_source_count; i++)
        if (strcmp(fp_kernel_sources[i].name, "integrate") == 0)
            base = fp_kernel_sources[i].source;
    assert_non_null(base);
    size_t nb = strlen(base);
    char *src = malloc(nb + sizeof cursor_kernel);
    memcpy(src, base, nb);
    memcpy(src + nb, cursor_kernel, sizeof cursor_kernel);
    cl_int err;
    const char *srcs[1] = { src };
    cl_device_id dev = fp_cl_device(cl);
    cl_program prog = clCreateProgramWithSource(fp_cl_context(cl), 1, srcs, NULL, &err);
    assert_int_equal(err, CL_SUCCESS);
    assert_int_equal(clBuildProgram(prog, 1, &dev, "-cl-std=CL1.2", NULL, NULL), CL_SUCCESS);
    cl_kernel k;
    assert_int_equal(fp_cl_kernel(prog, "cursor_test", &k), FP_OK);
    fp_integrate_cl_t s;
    assert_int_equal(fp_integrate_cl_init(cl, &s), FP_OK);
    enum { NR = 64, NC = 24 };
    float ray[NR * 8], cut[NR * NC], got[NR * NC];
    double cutd[NR * NC], worst = 0;
    int stretches = 0;
    for (int degree = 0; degree <= 3; degree++)
        for (int wrap = 0; wrap <= 2; wrap++) {
            setup_t st;
            make_walk_case(&st, degree, wrap);
            fp_view_t v;
            assert_int_equal(make_view(&v, 16, 16, 2, -20), 0);
            assert_int_equal(fp_integrate_cl_prepare(&s, &st.d, &v, NULL), FP_OK);
            double o[NR][3], dir[NR][3];
            int n[NR];
            for (int r = 0; r < NR; r++) {
                double len;
                random_ray(r, o[r], dir[r], &len);
                /* Float origins and directions, as the kernel sees them. */
                for (int i = 0; i < 3; i++) {
                    o[r][i] = (float)o[r][i];
                    dir[r][i] = (float)dir[r][i];
                    ray[8 * r + i] = (float)o[r][i];
                    ray[8 * r + 3 + i] = (float)dir[r][i];
                }
                len = (float)len;
                ray[8 * r + 6] = (float)len;
                n[r] = 1 + (int)(urand() * (NC - 1));
                for (int i = 0; i < n[r]; i++)
                    cutd[NC * r + i] = (float)(urand() * len);
                qsort(cutd + NC * r, (size_t)n[r], sizeof(double), cmp_d);
                cutd[NC * r + n[r] - 1] = len;
                for (int i = 0; i < n[r]; i++)
                    cut[NC * r + i] = (float)cutd[NC * r + i];
                ray[8 * r + 7] = (float)n[r];
            }
            cl_context ctx = fp_cl_context(cl);
            cl_mem bray = clCreateBuffer(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof ray,
                                         ray, &err);
            assert_int_equal(err, CL_SUCCESS);
            cl_mem bcut = clCreateBuffer(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof cut,
                                         cut, &err);
            assert_int_equal(err, CL_SUCCESS);
            cl_mem bout = clCreateBuffer(ctx, CL_MEM_WRITE_ONLY, sizeof got, NULL, &err);
            assert_int_equal(err, CL_SUCCESS);
            assert_int_equal(FP_CL_ARG(k, 0, bray) || FP_CL_ARG(k, 1, bcut) ||
                             FP_CL_ARG(k, 2, bout) || FP_CL_ARG(k, 3, s.params) ||
                             FP_CL_ARG(k, 4, s.lvi) || FP_CL_ARG(k, 5, s.lvf) ||
                             FP_CL_ARG(k, 6, s.coef) || FP_CL_ARG(k, 7, s.occ), FP_OK);
            size_t global = NR;
            cl_command_queue q = fp_cl_queue(cl);
            assert_int_equal(clEnqueueNDRangeKernel(q, k, 1, NULL, &global, NULL, 0, NULL, NULL),
                             CL_SUCCESS);
            assert_int_equal(clEnqueueReadBuffer(q, bout, CL_TRUE, 0, sizeof got, got, 0, NULL,
                                                 NULL), CL_SUCCESS);
            clReleaseMemObject(bray);
            clReleaseMemObject(bcut);
            clReleaseMemObject(bout);
            for (int r = 0; r < NR; r++) {
                double t0 = 0;
                for (int i = 0; i < n[r]; i++) {
                    double t1 = cutd[NC * r + i], ref = 0;
                    if (t1 > t0) {
                        double p[3] = { o[r][0] + t0 * dir[r][0], o[r][1] + t0 * dir[r][1],
                                        o[r][2] + t0 * dir[r][2] };
                        ref = fp_integrate_optical_depth(&st.d, p, dir[r], t1 - t0, 0);
                    }
                    double e = fabs(got[NC * r + i] - ref);
                    worst = fmax(worst, e / (1e-5 + 1e-4 * fabs(ref)));
                    stretches++;
                    if (!(e <= 1e-5 + 1e-4 * fabs(ref)))
                        fail_msg("degree %d wrap %d ray %d stretch %d [%g, %g]: OpenCL %.9g, C %.9g",
                                 degree, wrap, r, i, t0, t1, got[NC * r + i], ref);
                    t0 = fmax(t0, t1);
                }
            }
            unmake(&st);
        }
    print_message("resumable walk, OpenCL (float) vs C reference per stretch: max |d| %.2f of the "
                  "tolerance 1e-5 + 1e-4 |od| over %d stretches\n", worst, stretches);
    clReleaseKernel(k);
    clReleaseProgram(prog);
    free(src);
    fp_integrate_cl_release(&s);
    fp_cl_close(cl);
}

/* --lod-bound: the levels it drops change tau by at most the bound, on
 * rays long and dense enough that it drops some (else the test could not
 * fail). */
static void test_lod_bound(void **state)
{
    (void)state;
    setup_t st;
    make(&st, 64, 64, 1, FP_WRAP_REPEAT, 4, INFINITY, 0);
    /* A smooth fogmap with fine ripples: small detail levels. */
    for (int j = 0; j < 64; j++)
        for (int i = 0; i < 64; i++)
            st.img[j * 64 + i] = (float)(1 + 0.5 * sin(i * 0.2) * cos(j * 0.15) +
                                         2e-3 * (urand() - 0.5));
    fp_fogmap_release(&st.s);
    st.p.fog.density = 0.2;
    assert_int_equal(fp_integrate_commit(&st.p, &st.d), FP_OK);
    assert_int_equal(fp_fogmap_setup(&st.p, NULL, st.img, 64, 64, &st.s, &st.d), FP_OK);
    const double bounds[] = { 1e-3, 1e-4, 1e-5 };
    for (size_t b = 0; b < 3; b++) {
        fp_integrate_data_t lod = st.d;
        lod.fp[FP_F_LOD_BOUND] = bounds[b];
        double worst = 0;
        int changed = 0;
        for (int k = 0; k < 400; k++) {
            double o[3], dir[3], len;
            random_ray(k, o, dir, &len);
            len = k % 4 == 0 ? INFINITY : len * 4;
            double t = exp(-fp_integrate_optical_depth(&st.d, o, dir, len, 0));
            double e = fabs(exp(-fp_integrate_optical_depth(&lod, o, dir, len, 0)) - t);
            worst = fmax(worst, e);
            changed += e > 0;
        }
        print_message("--lod-bound %g: max |dtau| against exact %.2e over 400 rays, %d changed\n",
                      bounds[b], worst, changed);
        if (!(worst <= bounds[b]))
            fail_msg("--lod-bound %g: max |dtau| %.3e", bounds[b], worst);
        assert_true(changed > 20);
    }
    unmake(&st);
}

/* --lod-bound on large maps, the C reference and OpenCL against the exact C
 * reference: never past the bound.  A 4096x4096 map made as bench_looks.c
 * makes its own (a 64x64 map's bilinear surface at the 4096 map's pixel
 * centers: kinks between the nodes of every finer level, detail in bands
 * along them), and a 256x256 map of white noise (detail everywhere, on a
 * smooth swell so that coarser levels can take some of it), both over a
 * 120 x 120 fog-unit rectangle so that a ray crosses many cells. */
static void lod_large_map(setup_t *st, int size, int levels, int smooth)
{
    memset(st, 0, sizeof *st);
    fp_options_defaults(&st->p);
    fp_params_t *p = &st->p;
    p->fog.density = 0.05;
    p->fog.height[0] = FY0;
    p->fog.height[1] = FH;
    p->fog.height[2] = INFINITY;
    p->fogmap.basis = 1;
    p->fogmap.levels = levels;
    p->fogmap.rect[0] = -30;
    p->fogmap.rect[1] = -20;
    p->fogmap.rect[2] = 90;
    p->fogmap.rect[3] = 100;
    st->w = st->h = size;
    st->img = malloc((size_t)size * size * sizeof(float));
    if (smooth) {
        float m64[64 * 64];
        for (int i = 0; i < 64 * 64; i++)
            m64[i] = (float)(2 * urand());
        double r = size / 64.0;
        for (int j = 0; j < size; j++) {
            double y = fmin(fmax((j + 0.5) / r - 0.5, 0), 63);
            int j0 = (int)fmin(floor(y), 62);
            for (int i = 0; i < size; i++) {
                double x = fmin(fmax((i + 0.5) / r - 0.5, 0), 63);
                int i0 = (int)fmin(floor(x), 62);
                double fx = x - i0, fy = y - j0;
                const float *c = m64 + j0 * 64 + i0;
                st->img[(size_t)j * size + i] =
                    (float)((1 - fy) * ((1 - fx) * c[0] + fx * c[1]) +
                            fy * ((1 - fx) * c[64] + fx * c[65]));
            }
        }
    } else {
        for (int j = 0; j < size; j++)
            for (int i = 0; i < size; i++)
                st->img[(size_t)j * size + i] =
                    (float)(1 + 0.8 * sin(i * 0.05) * cos(j * 0.04) + 0.01 * urand());
    }
    assert_int_equal(fp_integrate_commit(p, &st->d), FP_OK);
    assert_int_equal(fp_fogmap_setup(p, NULL, st->img, size, size, &st->s, &st->d), FP_OK);
}

static void test_lod_bound_large(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    fp_integrate_cl_t s;
    int have_cl = fp_cl_open(NULL, &cl) == FP_OK;
    if (have_cl)
        assert_int_equal(fp_integrate_cl_init(cl, &s), FP_OK);
    const int vw = 48, vh = 32;
    size_t n = (size_t)vw * vh;
    float *depth = malloc(n * sizeof(float)), *ref = malloc(n * 4 * sizeof(float)),
          *got = malloc(n * 4 * sizeof(float));
    fp_view_t v;
    assert_int_equal(make_view(&v, vw, vh, 6, -12), 0);
    for (size_t i = 0; i < n; i++)
        depth[i] = urand() < 0.1 ? INFINITY : (float)pow(10, 0.5 + 1.5 * urand());
    for (int map = 0; map < 2; map++) {
        setup_t st;
        lod_large_map(&st, map == 0 ? 4096 : 256, map == 0 ? 9 : 6, map == 0);
        const char *name = map == 0 ? "4096x4096 (kinks)" : "256x256 noise";
        if (have_cl)
            assert_int_equal(fp_integrate_process(&st.d, &v, depth, ref, NULL), FP_OK);
        /* The kinks' map has a tensor grid (tests/test_tensor.c), which
         * takes most of its rays: the dyadic levels alone too, on a copy
         * of its tables without it (a serial of its own for the device). */
        fp_fog_tables_t nt = *st.d.tables;
        nt.lvi[FP_TG_ROW * FP_LI_STRIDE + FP_TI_NX] = 0;
        nt.serial = ~nt.serial;
        const double bounds[] = { 1e-3, 1e-4, 1e-3, 1e-4 };
        for (size_t b = 0; b < (map == 0 ? 4 : 2); b++) {
            fp_integrate_data_t lod = st.d;
            lod.fp[FP_F_LOD_BOUND] = bounds[b];
            if (b >= 2) {
                lod.tables = &nt;
                name = "4096x4096 (kinks), no tensor grid";
            }
            double worst = 0;
            int changed = 0;
            for (int k = 0; k < 150; k++) {
                double o[3], dir[3], len;
                random_ray(k, o, dir, &len);
                len = k % 5 == 0 ? INFINITY : len * 3;
                double t = exp(-fp_integrate_optical_depth(&st.d, o, dir, len, 0));
                double e = fabs(exp(-fp_integrate_optical_depth(&lod, o, dir, len, 0)) - t);
                worst = fmax(worst, e);
                changed += e > 1e-9;
            }
            print_message("%s --lod-bound %g: C max |dtau| against exact %.2e over 150 rays, "
                          "%d changed\n", name, bounds[b], worst, changed);
            if (!(worst <= bounds[b]))
                fail_msg("%s --lod-bound %g: C max |dtau| %.3e", name, bounds[b], worst);
            /* The bound is used, not only kept (on the noise, whose every
             * level carries detail, only the larger one drops much). */
            if (map == 0 || bounds[b] >= 1e-3)
                assert_true(changed >= 10);
            if (!have_cl)
                continue;
            /* OpenCL (single precision) against the exact C reference: the
             * bound plus test_opencl_parity's tolerance of the exact walk. */
            assert_int_equal(fp_integrate_process_cl(&s, &lod, &v, depth, got), FP_OK);
            double cw = 0;
            for (size_t i = 0; i < n; i++) {
                double e = fabs((double)got[4 * i + 3] - ref[4 * i + 3]);
                cw = fmax(cw, isnan(e) ? INFINITY : e);
            }
            print_message("%s --lod-bound %g: OpenCL max |dtau| against the exact C reference "
                          "%.2e over %zu pixels (tolerance the bound + 1e-5)\n", name, bounds[b],
                          cw, n);
            if (!(cw <= bounds[b] + 1e-5))
                fail_msg("%s --lod-bound %g: OpenCL max |dtau| %.3e", name, bounds[b], cw);
        }
        unmake(&st);
    }
    free(depth);
    free(ref);
    free(got);
    if (have_cl) {
        fp_integrate_cl_release(&s);
        fp_cl_close(cl);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_exact_vs_brute_force),
        cmocka_unit_test(test_moved_fog_in_a_box),
        cmocka_unit_test(test_offset_and_box_world_axes),
        cmocka_unit_test(test_constant_is_homogeneous),
        cmocka_unit_test(test_sparse_exact),
        cmocka_unit_test(test_opencl_parity),
        cmocka_unit_test(test_without_deconstruction),
        cmocka_unit_test(test_fast_path_errors),
        cmocka_unit_test(test_walk_matches_levels),
        cmocka_unit_test(test_cursor_matches_fog_od),
        cmocka_unit_test(test_lod_bound),
        cmocka_unit_test(test_lod_bound_large),
        /* Last: the random numbers it draws leave the others' as they were. */
        cmocka_unit_test(test_cursor_opencl),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* The wavelet stage: B-spline evaluation against independent formulas,
 * lossless decomposition, synthesis = uniform B-spline refinement, the
 * deconstructed levels (and the raw bands with the synthesis filters)
 * summing to F from its definition, constants, and the OpenCL path
 * against the C reference. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bspline.h"
#include "clrt.h"
#include "fp.h"
#include "wavelet.h"

static uint64_t rng = 88172645463325252ull;
static double urand(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (double)(rng >> 11) / 9007199254740992.0;
}

static float *random_map(int w, int h)
{
    float *img = malloc((size_t)w * h * sizeof *img);
    assert_non_null(img);
    for (int i = 0; i < w * h; i++)
        img[i] = (float)urand();
    return img;
}

static const char *const wrap_name[3] = { "zero", "clamp", "repeat" };

/* ---- B-splines ---- */

/* Truncated-power form: b_d(x) = 1/d! sum_k (-1)^k C(d+1,k) (x + (d+1)/2 - k)_+^d. */
static double bspline_truncated(int d, double x)
{
    double sum = 0, binom = 1, fact = 1;
    for (int i = 2; i <= d; i++)
        fact *= i;
    for (int k = 0; k <= d + 1; k++) {
        double t = x + 0.5 * (d + 1) - k;
        if (t > 0)
            sum += (k & 1 ? -1 : 1) * binom * pow(t, d);
        binom = binom * (d + 1 - k) / (k + 1);
    }
    return sum / fact;
}

/* Piecewise definitions written out. */
static double bspline_piecewise(int d, double x)
{
    double a = fabs(x);
    switch (d) {
    case 0:
        return x >= -0.5 && x < 0.5;
    case 1:
        return a <= 1 ? 1 - a : 0;
    case 2:
        return a <= 0.5 ? 0.75 - x * x : a <= 1.5 ? 0.5 * (a - 1.5) * (a - 1.5) : 0;
    default:
        return a <= 1 ? (4 - 6 * a * a + 3 * a * a * a) / 6
                      : a <= 2 ? (2 - a) * (2 - a) * (2 - a) / 6 : 0;
    }
}

static void test_bspline_values(void **state)
{
    (void)state;
    for (int d = 0; d <= 3; d++)
        for (int t = 0; t < 2000; t++) {
            double x = -3 + 6 * urand();
            double v = fp_bspline(d, x);
            assert_true(fabs(v - bspline_piecewise(d, x)) < 1e-14);
            if (d > 0)
                assert_true(fabs(v - bspline_truncated(d, x)) < 1e-12);
            /* partition of unity */
            double sum = 0;
            for (int i = -4; i <= 4; i++)
                sum += fp_bspline(d, x - i);
            assert_true(fabs(sum - 1) < 1e-14);
        }
    /* exact values at knots and centers */
    assert_true(fp_bspline(0, -0.5) == 1 && fp_bspline(0, 0.5) == 0);
    assert_true(fp_bspline(1, 0) == 1 && fp_bspline(1, 1) == 0);
    assert_true(fp_bspline(2, 0) == 0.75 && fp_bspline(2, 0.5) == 0.5);
    assert_true(fp_bspline(2, 1) == 0.125);
    assert_true(fabs(fp_bspline(3, 0) - 2.0 / 3) < 1e-15 && fabs(fp_bspline(3, 1) - 1.0 / 6) < 1e-15);
    assert_true(fp_bspline(3, 2) == 0 && fp_bspline(2, 1.5) == 0 && fp_bspline(4, 0) == 0);
}

static void test_bspline_weights(void **state)
{
    (void)state;
    for (int d = 0; d <= 3; d++)
        for (int t = 0; t < 1000; t++) {
            double s = t == 0 ? 0 : urand(), w[4], sum = 0;
            fp_bspline_weights(d, s, w);
            for (int j = 0; j < 4; j++) {
                double a[4];
                if (j > d) {
                    assert_true(w[j] == 0);
                    continue;
                }
                sum += w[j];
                assert_true(w[j] >= 0);
                /* w_j(s) = b_d(s - SHIFT + FIRST - j) */
                double ref = fp_bspline(d, s - FP_BSPLINE_SHIFT(d) + FP_BSPLINE_FIRST(d) - j);
                assert_true(fabs(w[j] - ref) < 1e-14);
                fp_bspline_poly(d, j, a);
                assert_true(fabs(((a[3] * s + a[2]) * s + a[1]) * s + a[0] - w[j]) < 1e-14);
            }
            assert_true(fabs(sum - 1) < 1e-14);
        }
    /* A surface through the cells equals the sum over basis functions. */
    double c[16];
    for (int i = 0; i < 16; i++)
        c[i] = urand();
    for (int d = 0; d <= 3; d++)
        for (int t = 0; t < 500; t++) {
            double x = 4 + 8 * urand(), w[4], s, ref = 0, v = 0;
            int k;
            for (int i = 0; i < 16; i++)
                ref += c[i] * fp_bspline(d, x - i);
            fp_bspline_cell(d, x, &k, &s);
            assert_true(s >= 0 && s < 1);
            fp_bspline_weights(d, s, w);
            for (int j = 0; j <= d; j++)
                v += w[j] * c[k - FP_BSPLINE_FIRST(d) + j];
            assert_true(fabs(v - ref) < 1e-13);
        }
}

/* ---- lossless ---- */

static void test_lossless(void **state)
{
    (void)state;
    static const int sizes[][2] = { { 1, 1 }, { 7, 5 }, { 33, 17 }, { 100, 60 }, { 64, 64 } };
    for (size_t si = 0; si < FP_ARRAY_LEN(sizes); si++) {
        int w = sizes[si][0], h = sizes[si][1];
        float *img = random_map(w, h), *back = malloc((size_t)w * h * sizeof *back);
        assert_non_null(back);
        for (int d = 0; d <= 3; d++)
            for (int wrap = 0; wrap < 3; wrap++)
                for (int L = 0; L <= 5; L++) {
                    fp_fogmap_t m;
                    assert_int_equal(fp_wavelet_decompose(img, w, h, d, L, wrap, &m), FP_OK);
                    assert_int_equal(m.num_levels, m.levels + 1);
                    assert_true(m.dom_w % (1 << m.levels) == 0 && m.dom_h % (1 << m.levels) == 0);
                    if (wrap == FP_WRAP_REPEAT) {
                        assert_true(m.dom_w == w && m.dom_h == h && m.pad_x0 == 0);
                        assert_true(m.levels <= L);
                    } else {
                        int margin = wrap == FP_WRAP_ZERO ? d + 2 : 2 * (d + 2);
                        assert_int_equal(m.levels, L);
                        assert_true(m.pad_x0 >= margin && m.dom_w - w - m.pad_x0 >= margin);
                        assert_true(m.pad_y0 >= margin && m.dom_h - h - m.pad_y0 >= margin);
                    }
                    assert_int_equal(fp_wavelet_reconstruct(&m, back), FP_OK);
                    double err = 0;
                    for (int i = 0; i < w * h; i++)
                        err = fmax(err, fabs(back[i] - img[i]));
                    if (err > 1e-6)
                        fail_msg("%dx%d d=%d %s L=%d: error %g", w, h, d, wrap_name[wrap], L, err);
                    fp_fogmap_free(&m);
                }
        free(img);
        free(back);
    }
}

/* ---- synthesis = uniform B-spline refinement ---- */

/* Refinement masks (2^-d binomial), coarse l -> fine 2l + k, k from lo. */
static const double mask[4][5] = {
    { 1, 1 }, { 0.5, 1, 0.5 }, { 0.25, 0.75, 0.75, 0.25 }, { 0.125, 0.5, 0.75, 0.5, 0.125 }
};
static const int mask_lo[4] = { 0, -1, -1, -2 };

static void test_refinement(void **state)
{
    (void)state;
    for (int d = 0; d <= 3; d++) {
        /* The filters from the lifting steps: the scaling one is the mask. */
        float one = 1;
        fp_fogmap_t m;
        assert_int_equal(fp_wavelet_decompose(&one, 1, 1, d, 1, FP_WRAP_ZERO, &m), FP_OK);
        const fp_wavelet_filter_t *f = &m.synth[0];
        assert_int_equal(f->lo, mask_lo[d]);
        assert_int_equal(f->hi, mask_lo[d] + d + 1);
        for (int k = 0; k <= d + 1; k++)
            assert_true(fabs(f->tap[k] - mask[d][k]) < 1e-15);
        for (int which = 0; which < 2; which++) {
            f = &m.synth[which];
            int count = 0;
            for (int p = 0; p < 2; p++)
                for (int i = 0; i < f->phase_n[p]; i++) {
                    int k = 2 * (f->phase_lo[p] + i) + p;
                    assert_true(k >= f->lo && k <= f->hi);
                    assert_true(f->phase[p][i] == f->tap[k - f->lo]);
                    count++;
                }
            assert_int_equal(count, f->hi - f->lo + 1);
        }
        /* The detail synthesis has no constant part: its taps sum to 0
         * (a constant analyses to zero details and back). */
        double sum = 0;
        for (int k = m.synth[1].lo; k <= m.synth[1].hi; k++)
            sum += m.synth[1].tap[k - m.synth[1].lo];
        assert_true(fabs(sum) < 1e-15);
        fp_fogmap_free(&m);

        /* 2D: a fine map that is the refinement of a coarse one (periodic)
         * analyses to that coarse map and zero details, i.e. synthesis
         * with zero details is the refinement, centering included. */
        enum { CW = 8, CH = 6 };
        double c[CH][CW], r[CH][2 * CW];
        float fine[2 * CH][2 * CW];
        for (int j = 0; j < CH; j++)
            for (int i = 0; i < CW; i++)
                c[j][i] = urand();
        memset(r, 0, sizeof r);
        for (int j = 0; j < CH; j++)
            for (int i = 0; i < CW; i++)
                for (int k = 0; k <= d + 1; k++)
                    r[j][(2 * i + mask_lo[d] + k + 2 * CW) % (2 * CW)] += mask[d][k] * c[j][i];
        for (int y = 0; y < 2 * CH; y++)
            for (int x = 0; x < 2 * CW; x++) {
                double v = 0;
                for (int j = 0; j < CH; j++)
                    for (int k = 0; k <= d + 1; k++)
                        if ((2 * j + mask_lo[d] + k + 2 * CH) % (2 * CH) == y)
                            v += mask[d][k] * r[j][x];
                fine[y][x] = (float)v;
            }
        assert_int_equal(fp_wavelet_decompose(&fine[0][0], 2 * CW, 2 * CH, d, 1, FP_WRAP_REPEAT,
                                              &m), FP_OK);
        assert_int_equal(m.levels, 1);
        for (int j = 0; j < CH; j++)
            for (int i = 0; i < CW; i++)
                assert_true(fabs(m.level[0].coef[j * CW + i] - c[j][i]) < 1e-6);
        for (int b = 0; b < 3; b++)
            assert_true(m.band[1][b].amax < 1e-6);
        assert_true(m.level[1].amax < 1e-6);
        /* And the centering: level 0 evaluated as a surface is F. */
        for (int t = 0; t < 50; t++) {
            double U = 2 * CW * urand(), V = 2 * CH * urand();
            double direct = fp_fogmap_eval_direct(&fine[0][0], 2 * CW, 2 * CH, d, FP_WRAP_REPEAT,
                                                  U, V);
            assert_true(fabs(fp_fogmap_eval_level(&m, 0, U, V) - direct) < 1e-6);
        }
        fp_fogmap_free(&m);
    }
}

/* ---- deconstruction: sum of level surfaces == F ---- */

static void check_eval(const float *img, int w, int h, int d, int L, int wrap)
{
    fp_fogmap_t m;
    assert_int_equal(fp_wavelet_decompose(img, w, h, d, L, wrap, &m), FP_OK);
    double r = 0.5 * (d + 1), maxc = 0;
    for (int i = 0; i < w * h; i++)
        maxc = fmax(maxc, fabs(img[i]));
    double tol = 1e-5 * fmax(1, maxc);
    for (int t = 0; t < 400; t++) {
        double U, V;
        int kind = t % 4;
        if (wrap == FP_WRAP_CLAMP) {
            U = r + (m.dom_w - 2 * r) * urand();
            V = r + (m.dom_h - 2 * r) * urand();
        } else if (wrap == FP_WRAP_REPEAT) {
            U = m.dom_w * (3 * urand() - 1);
            V = m.dom_h * (3 * urand() - 1);
        } else {
            U = m.dom_w * urand();
            V = m.dom_h * urand();
        }
        if (kind == 0) {        /* inside the fogmap */
            U = m.pad_x0 + w * urand();
            V = m.pad_y0 + h * urand();
        } else if (kind == 1) { /* near its edges */
            U = m.pad_x0 + (urand() < 0.5 ? 0 : w) + 2 * r * (2 * urand() - 1);
            V = m.pad_y0 + h * urand();
        } else if (kind == 2) {
            U = m.pad_x0 + w * urand();
            V = m.pad_y0 + (urand() < 0.5 ? 0 : h) + 2 * r * (2 * urand() - 1);
        }
        double direct = fp_fogmap_eval_direct(img, w, h, d, wrap, U - m.pad_x0, V - m.pad_y0);
        double sum = fp_fogmap_eval(&m, U, V, FP_MAX_LEVELS);
        double bands = fp_fogmap_eval_bands(&m, U, V, FP_MAX_LEVELS);
        if (fabs(sum - direct) > tol || fabs(bands - direct) > tol)
            fail_msg("%dx%d d=%d %s L=%d at (%g, %g): levels %.9g bands %.9g direct %.9g", w, h,
                     d, wrap_name[wrap], L, U, V, sum, bands, direct);
    }
    /* Partial sums: dropping levels is the same in both representations. */
    for (int t = 0; t < 50; t++) {
        double U = m.dom_w * urand(), V = m.dom_h * urand();
        for (int l = 0; l < m.num_levels; l++)
            assert_true(fabs(fp_fogmap_eval(&m, U, V, l) - fp_fogmap_eval_bands(&m, U, V, l)) <
                        tol);
    }
    fp_fogmap_free(&m);
}

static void test_deconstruction(void **state)
{
    (void)state;
    static const int sizes[][3] = { { 7, 5, 2 }, { 33, 17, 3 }, { 32, 16, 4 }, { 20, 12, 6 } };
    for (size_t si = 0; si < FP_ARRAY_LEN(sizes); si++) {
        int w = sizes[si][0], h = sizes[si][1];
        float *img = random_map(w, h);
        for (int i = 0; i < w * h; i++)
            img[i] *= 5;
        for (int d = 0; d <= 3; d++)
            for (int wrap = 0; wrap < 3; wrap++) {
                check_eval(img, w, h, d, sizes[si][2], wrap);
                check_eval(img, w, h, d, 1, wrap);
            }
        free(img);
    }
}

/* ---- constants ---- */

static void test_constant(void **state)
{
    (void)state;
    enum { W = 32, H = 16 };
    float img[W * H];
    for (int i = 0; i < W * H; i++)
        img[i] = 0.7f;
    for (int d = 0; d <= 3; d++) {
        fp_fogmap_t m;
        assert_int_equal(fp_wavelet_decompose(img, W, H, d, 3, FP_WRAP_REPEAT, &m), FP_OK);
        assert_int_equal(m.levels, 3);
        const fp_fog_level_t *c = &m.level[0];
        assert_true(c->nx == 4 && c->ny == 2 && c->cell == 8);
        for (int i = 0; i < c->nx * c->ny; i++)
            assert_true(fabs(c->coef[i] - 0.7) < 1e-6);
        for (int l = 1; l <= 3; l++) {
            assert_true(m.level[l].amax < 1e-6);
            for (int b = 0; b < 3; b++)
                assert_true(m.band[l][b].amax < 1e-6);
        }
        fp_fogmap_free(&m);

        /* ZERO: the constant inside, away from the edges; 0 beyond the support. */
        assert_int_equal(fp_wavelet_decompose(img, W, H, d, 4, FP_WRAP_ZERO, &m), FP_OK);
        double r = 0.5 * (d + 1);
        for (int t = 0; t < 300; t++) {
            double u = r + (W - 2 * r) * urand(), v = r + (H - 2 * r) * urand();
            assert_true(fabs(fp_fogmap_eval(&m, u + m.pad_x0, v + m.pad_y0, 99) - 0.7) < 1e-6);
            double U = m.dom_w * urand(), V = m.dom_h * urand();
            u = U - m.pad_x0;
            v = V - m.pad_y0;
            if (u < -r || u > W + r || v < -r || v > H + r)
                assert_true(fabs(fp_fogmap_eval(&m, U, V, 99)) < 1e-6);
        }
        fp_fogmap_free(&m);
    }
}

/* ---- geometry, arguments ---- */

static void test_layout(void **state)
{
    (void)state;
    float img[12 * 20] = { 0 };
    fp_fogmap_t m;
    int q = fp_quiet;
    /* REPEAT reduces the levels to what divides the size: 12 = 4*3, 20 = 4*5. */
    assert_int_equal(fp_wavelet_decompose(img, 12, 20, 1, 5, FP_WRAP_REPEAT, &m), FP_OK);
    assert_int_equal(m.levels, 2);
    assert_int_equal(m.num_levels, 3);
    fp_fogmap_free(&m);
    for (int d = 0; d <= 3; d++) {
        assert_int_equal(fp_wavelet_decompose(img, 12, 20, d, 3, FP_WRAP_ZERO, &m), FP_OK);
        for (int l = 0; l <= 3; l++) {
            const fp_fog_level_t *lv = &m.level[l];
            double cell = 1 << (3 - l);
            assert_true(lv->cell == cell);
            assert_true(lv->nx * cell == m.dom_w && lv->ny * cell == m.dom_h);
            assert_true(lv->origin_u == ((d & 1) ? 0.5 : cell / 2));
            if (l > 0) {
                assert_true(m.band[l][0].cell == 2 * cell && m.band[l][2].nx * 2 == lv->nx);
                assert_true(m.band[l][1].origin_v == ((d & 1) ? 0.5 : cell));
            }
        }
        assert_null(m.band[0][0].coef);
        fp_fogmap_free(&m);
    }
    fp_quiet = 1;
    assert_int_equal(fp_wavelet_decompose(img, 12, 20, 4, 1, FP_WRAP_ZERO, &m), FP_EUSAGE);
    assert_int_equal(fp_wavelet_decompose(img, 12, 20, 1, FP_MAX_LEVELS + 1, 0, &m), FP_EUSAGE);
    assert_int_equal(fp_wavelet_decompose(img, 12, 20, 1, 1, 3, &m), FP_EUSAGE);
    assert_int_equal(fp_wavelet_decompose(img, 0, 20, 1, 1, 0, &m), FP_EUSAGE);
    img[5] = NAN;
    assert_int_equal(fp_wavelet_decompose(img, 12, 20, 1, 1, 0, &m), FP_ERR);
    fp_quiet = q;
    fp_fogmap_free(&m);
}

/* ---- OpenCL against the C reference ---- */

static void compare_level(const fp_fog_level_t *a, const fp_fog_level_t *b, const char *what,
                          int l, int d, int wrap)
{
    assert_int_equal(a->nx, b->nx);
    assert_int_equal(a->ny, b->ny);
    assert_true(a->cell == b->cell && a->origin_u == b->origin_u && a->origin_v == b->origin_v);
    double tol = 1e-5 * fmax(1, a->amax), err = 0;
    for (int i = 0; i < a->nx * a->ny; i++)
        err = fmax(err, fabs(a->coef[i] - b->coef[i]));
    if (err > tol)
        fail_msg("OpenCL %s %d (d=%d %s): max difference %g", what, l, d, wrap_name[wrap], err);
}

static void test_opencl(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    int q = fp_quiet;
    fp_quiet = 1;
    int rc = fp_cl_open(NULL, &cl);
    fp_quiet = q;
    if (rc != FP_OK)
        skip();
    static const int cases[][3] = { { 7, 5, 2 }, { 33, 17, 3 }, { 64, 64, 5 }, { 100, 60, 0 },
                                    { 1, 1, 4 } };
    for (size_t ci = 0; ci < FP_ARRAY_LEN(cases); ci++) {
        int w = cases[ci][0], h = cases[ci][1], L = cases[ci][2];
        float *img = random_map(w, h);
        for (int d = 0; d <= 3; d++)
            for (int wrap = 0; wrap < 3; wrap++) {
                fp_fogmap_t a, b;
                assert_int_equal(fp_wavelet_decompose(img, w, h, d, L, wrap, &a), FP_OK);
                assert_int_equal(fp_wavelet_decompose_cl(cl, img, w, h, d, L, wrap, &b), FP_OK);
                assert_int_equal(a.levels, b.levels);
                assert_true(a.dom_w == b.dom_w && a.dom_h == b.dom_h && a.pad_x0 == b.pad_x0 &&
                            a.pad_y0 == b.pad_y0);
                for (int l = 0; l <= a.levels; l++) {
                    compare_level(&a.level[l], &b.level[l], "level", l, d, wrap);
                    for (int k = 0; l > 0 && k < 3; k++)
                        compare_level(&a.band[l][k], &b.band[l][k], "band", l, d, wrap);
                    assert_true(fabs(a.level[l].amax - b.level[l].amax) <=
                                1e-5 * fmax(1, a.level[l].amax));
                }
                assert_memory_equal(&a.synth, &b.synth, sizeof a.synth);
                fp_fogmap_free(&a);
                fp_fogmap_free(&b);
            }
        free(img);
    }
    fp_cl_close(cl);
}

/* kernels/bspline.h compiled as OpenCL C (float) against its C version. */
static void test_opencl_bspline(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    int q = fp_quiet;
    fp_quiet = 1;
    int rc = fp_cl_open(NULL, &cl);
    fp_quiet = q;
    if (rc != FP_OK)
        skip();
    enum { N = 1000 };
    float x[N], out[7 * N];
    for (int i = 0; i < N; i++)
        x[i] = (float)(-6 + 12 * urand());
    x[0] = 0;
    x[1] = 0.5f;
    x[2] = -1.5f;
    cl_program prog;
    cl_kernel k = NULL;
    cl_int err, n = N;
    assert_int_equal(fp_cl_program(cl, "wavelet", "-cl-std=CL1.2", &prog), FP_OK);
    assert_int_equal(fp_cl_kernel(prog, "wavelet_bspline_check", &k), FP_OK);
    cl_mem bx = clCreateBuffer(fp_cl_context(cl), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                               sizeof x, x, &err);
    assert_int_equal(err, CL_SUCCESS);
    cl_mem bo = clCreateBuffer(fp_cl_context(cl), CL_MEM_WRITE_ONLY, sizeof out, NULL, &err);
    assert_int_equal(err, CL_SUCCESS);
    for (cl_int d = 0; d <= 3; d++) {
        size_t global = N;
        assert_int_equal(FP_CL_ARG(k, 0, bx) || FP_CL_ARG(k, 1, n) || FP_CL_ARG(k, 2, d) ||
                         FP_CL_ARG(k, 3, bo), FP_OK);
        assert_int_equal(clEnqueueNDRangeKernel(fp_cl_queue(cl), k, 1, NULL, &global, NULL, 0,
                                                NULL, NULL), CL_SUCCESS);
        assert_int_equal(clEnqueueReadBuffer(fp_cl_queue(cl), bo, CL_TRUE, 0, sizeof out, out, 0,
                                             NULL, NULL), CL_SUCCESS);
        for (int i = 0; i < N; i++) {
            const float *o = out + 7 * i;
            double w[4], s;
            int kk;
            fp_bspline_cell(d, x[i], &kk, &s);
            fp_bspline_weights(d, s, w);
            assert_true(fabs(o[0] - fp_bspline(d, x[i])) < 1e-6);
            assert_true(o[1] == kk && fabs(o[2] - s) < 1e-6);
            for (int j = 0; j < 4; j++)
                assert_true(fabs(o[3 + j] - w[j]) < 1e-6);
        }
    }
    clReleaseMemObject(bx);
    clReleaseMemObject(bo);
    clReleaseKernel(k);
    fp_cl_close(cl);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bspline_values),
        cmocka_unit_test(test_bspline_weights),
        cmocka_unit_test(test_lossless),
        cmocka_unit_test(test_refinement),
        cmocka_unit_test(test_deconstruction),
        cmocka_unit_test(test_constant),
        cmocka_unit_test(test_layout),
        cmocka_unit_test(test_opencl),
        cmocka_unit_test(test_opencl_bspline),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

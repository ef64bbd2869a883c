/* The tensor grid of the linear basis (filters/fogmap.c tensor_grid,
 * kernels/fog_core.h fp_tensor_walk), the walk --lod-bound takes on a
 * fogmap that is bilinear on rectangles larger than its cells (a smaller
 * map resized with the triangle filter): its breaks are the resize's kinks
 * and its error eps is rounding; its optical depth is the exact walk's
 * within sigma eps times the ray's weight (the bound it is used under),
 * for every wrap mode; with --lod-bound the transmittance stays within the
 * bound, also where the grid does not fit and the dyadic levels take
 * over; a map with fine detail builds none; OpenCL against the C
 * reference. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

/* The segments of the C copies of the walks compiled into this program
 * (fp_fog_od below): the tensor walk's must be the fewer, else the test
 * did not walk it. */
static long seg_count;
#define FP_SEG_COUNT() (seg_count++)

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

#include "fog_core.h"

#define SMALL 8
#define SCALE 32
#define SIZE (SMALL * SCALE)
#define FY0 1.0
#define FH 6.0

typedef struct setup_t {
    fp_params_t p;
    fp_fogmap_stage_t s;
    fp_integrate_data_t d;
    float *img;
} setup_t;

/* A SMALL x SMALL random map's bilinear surface at the pixel centres of a
 * map SCALE times larger (edges clamped, as oiiotool's --resize:filter=
 * triangle): bilinear on rectangles whose sides lie between the large
 * map's pixels SCALE k + SCALE/2 - 1 and SCALE k + SCALE/2.  noise_v: rows
 * of noise instead (fine detail along V). */
static void make(setup_t *st, int wrap, int noise_v)
{
    memset(st, 0, sizeof *st);
    fp_options_defaults(&st->p);
    fp_params_t *p = &st->p;
    p->fog.density = 0.05;
    p->fog.height[0] = FY0;
    p->fog.height[1] = FH;
    p->fog.height[2] = INFINITY;
    p->fogmap.basis = 1;
    p->fogmap.wrap = wrap;
    p->fogmap.levels = 4;
    p->fogmap.rect[0] = -30;
    p->fogmap.rect[1] = -20;
    p->fogmap.rect[2] = 90;
    p->fogmap.rect[3] = 100;
    float m[SMALL * SMALL];
    for (int i = 0; i < SMALL * SMALL; i++)
        m[i] = (float)(0.2 + 2 * urand());
    st->img = malloc((size_t)SIZE * SIZE * sizeof(float));
    for (int j = 0; j < SIZE; j++) {
        double y = fmin(fmax((j + 0.5) / SCALE - 0.5, 0), SMALL - 1);
        int j0 = (int)fmin(floor(y), SMALL - 2);
        for (int i = 0; i < SIZE; i++) {
            double x = fmin(fmax((i + 0.5) / SCALE - 0.5, 0), SMALL - 1);
            int i0 = (int)fmin(floor(x), SMALL - 2);
            double fx = x - i0, fy = y - j0;
            const float *c = m + j0 * SMALL + i0;
            double v = (1 - fy) * ((1 - fx) * c[0] + fx * c[1]) +
                       fy * ((1 - fx) * c[SMALL] + fx * c[SMALL + 1]);
            st->img[(size_t)j * SIZE + i] = (float)(noise_v && j % 2 ? v * (0.9 + 0.2 * urand())
                                                                     : v);
        }
    }
    assert_int_equal(fp_integrate_commit(p, &st->d), FP_OK);
    assert_int_equal(fp_fogmap_setup(p, NULL, st->img, SIZE, SIZE, &st->s, &st->d), FP_OK);
}

static void unmake(setup_t *st)
{
    fp_fogmap_release(&st->s);
    fp_options_free(&st->p);
    free(st->img);
}

static const int *tensor_row(const setup_t *st)
{
    return st->d.tables->lvi + FP_TG_ROW * FP_LI_STRIDE;
}

static double tensor_eps(const setup_t *st)
{
    return st->d.tables->lvf[FP_TG_ROW * FP_LR_STRIDE + FP_TR_EPS];
}

/* The breaks along one axis: every resize kink's pair of nodes, and
 * nothing else but the nodes where the padding or the domain's seam meets
 * the map (a kink too, or a jump across the seam, which the walk of a
 * non-repeating map never crosses). */
static void check_breaks(const setup_t *st, int axis)
{
    const fp_fogmap_t *m = &st->s.map;
    const int *ti = tensor_row(st);
    int nb = ti[axis ? FP_TI_NY : FP_TI_NX], n = axis ? m->dom_h : m->dom_w;
    int pad = axis ? m->pad_y0 : m->pad_x0;
    const float *br = st->d.tables->coef + ti[axis ? FP_TI_BY : FP_TI_BX];
    char *is = calloc((size_t)n, 1);
    for (int r = 0; r < nb; r++) {
        int b = (int)br[r];
        assert_true(b >= 0 && b < n && (float)b == br[r]);
        assert_true(r == 0 || br[r] > br[r - 1]);
        /* 1 / width as the walk reads it. */
        int w = (r + 1 < nb ? (int)br[r + 1] : (int)br[0] + n) - b;
        assert_true(br[nb + r] == 1.0f / w);
        is[b] = 1;
    }
    int kinks = 0;
    for (int k = 0; k < SMALL; k++)
        for (int e = 0; e < 2; e++) {
            int node = pad + SCALE * k + SCALE / 2 - 1 + e;
            if (!is[node])
                fail_msg("axis %d: no break at node %d (the kink %d of the resize)", axis, node,
                         k);
            is[node] = 0;
            kinks++;
        }
    const int edge[6] = { pad - 1, pad, pad + SIZE - 1, pad + SIZE, 0, n - 1 };
    for (int e = 0; e < 6; e++)
        if (edge[e] >= 0 && edge[e] < n)
            is[edge[e]] = 0;
    for (int i = 0; i < n; i++)
        if (is[i])
            fail_msg("axis %d: a break at node %d, where the map is linear", axis, i);
    free(is);
    print_message("wrap %d axis %d: %d breaks (%d at the resize's kinks) over %d nodes\n",
                  st->p.fogmap.wrap, axis, nb, kinks, n);
}

/* A random ray: the classes of test_fogmap.c's, and rays that start on a
 * break node and move down across it. */
static void random_ray(const setup_t *st, int k, double o[3], double dir[3], double *len)
{
    o[0] = -40 + 140 * urand();
    o[1] = -3 + 20 * urand();
    o[2] = -30 + 140 * urand();
    double d[3] = { urand() - 0.5, urand() - 0.5, urand() - 0.5 };
    switch (k % 6) {
    case 0: d[1] = 0; break;
    case 1: d[1] = (urand() - 0.5) * 1e-4; break;
    case 2: d[0] = 0; break;
    case 3: d[2] = 0; break;
    case 4: {
        /* On a break node (domain node i sits at U = i + 0.5). */
        const fp_fogmap_t *m = &st->s.map;
        const int *ti = tensor_row(st);
        const float *bx = st->d.tables->coef + ti[FP_TI_BX];
        const float *by = st->d.tables->coef + ti[FP_TI_BY];
        double u = bx[(int)(urand() * ti[FP_TI_NX])] + 0.5, v = by[(int)(urand() * ti[FP_TI_NY])] + 0.5;
        o[0] = st->p.fogmap.rect[0] + (u - m->pad_x0) / st->d.fp[FP_F_USCALE];
        o[2] = st->p.fogmap.rect[1] + (v - m->pad_y0) / st->d.fp[FP_F_VSCALE];
        d[0] = -fabs(d[0]);
        d[2] = k % 12 == 4 ? -fabs(d[2]) : 0;
        break;
    }
    default: break;
    }
    double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int i = 0; i < 3; i++)
        dir[i] = d[i] / l;
    *len = k % 7 == 0 ? INFINITY : 1 + 200 * urand();
}

/* The tensor grid of the resized map in every wrap mode: its breaks, eps
 * at rounding, and the walk against the exact one (fp_fog_od without a
 * bound): |d od| <= sigma eps wtot, the bound under which it is used, plus
 * double rounding (1e-12 of od); with --lod-bound |dtau| within the bound,
 * the tensor walk taken (fewer segments) where sigma eps wtot fits. */
static void test_tensor_resized(void **state)
{
    (void)state;
    for (int wrap = 0; wrap < 3; wrap++) {
        setup_t st;
        make(&st, wrap, 0);
        const int *ti = tensor_row(&st);
        assert_true(ti[FP_TI_NX] > 0 && ti[FP_TI_NY] > 0);
        check_breaks(&st, 0);
        check_breaks(&st, 1);
        double fmaxv = 0;
        for (size_t i = 0; i < (size_t)SIZE * SIZE; i++)
            fmaxv = fmax(fmaxv, st.img[i]);
        double eps = tensor_eps(&st);
        print_message("wrap %d: eps = max |F - G| = %.2e (%.2e of max F; tolerance 1e-6)\n", wrap,
                      eps, eps / fmaxv);
        assert_true(eps > 0 && eps <= 1e-6 * fmaxv);
        const fp_fog_tables_t *t = st.d.tables;
        double sigma = st.d.fp[FP_F_SIGMA], worst = 0, worst_tau = 0;
        long seg_exact = 0, seg_tensor = 0;
        int used = 0;
        for (int k = 0; k < 300; k++) {
            double o[3], dir[3], len;
            random_ray(&st, k, o, dir, &len);
            fp_integrate_data_t lod = st.d;
            lod.fp[FP_F_LOD_BOUND] = 1e-4;
            seg_count = 0;
            double exact = fp_fog_od(st.d.fp, FP_TABLES(t), o[0], o[1], o[2], dir[0], dir[1],
                                     dir[2], len, 0);
            long se = seg_count;
            seg_count = 0;
            double got = fp_fog_od(lod.fp, FP_TABLES(t), o[0], o[1], o[2], dir[0], dir[1],
                                   dir[2], len, 0);
            long sg = seg_count;
            /* The ray's weight as fp_fogmap_od computes it. */
            fp_path_t p;
            double a, b;
            fp_fogmap_path(st.d.fp, o[0], o[1], o[2], dir[0], dir[1], dir[2], len, &p, &a, &b);
            if (isinf(b))
                b = fp_fogmap_cap(st.d.fp, &p, a);
            double wtot = b > a ? fp_rest_weight(FY0, FH, &p, a, b) : 0;
            worst_tau = fmax(worst_tau, fabs(exp(-got) - exp(-exact)));
            /* The rest (long rays whose sigma eps wtot passes the bound)
             * take the dyadic levels: only |dtau| is bounded there. */
            if (sigma * eps * wtot <= 1e-4 && b > a) {
                double tol = sigma * eps * wtot + 1e-12 * exact;
                if (!(fabs(got - exact) <= tol))
                    fail_msg("wrap %d ray %d: tensor od %.15g, exact %.15g (tolerance %.3g)",
                             wrap, k, got, exact, tol);
                if (tol > 0)
                    worst = fmax(worst, fabs(got - exact) / tol);
                used++;
                seg_exact += se;
                seg_tensor += sg;
            }
        }
        print_message("wrap %d: tensor walk vs exact over 300 rays: max |d od| %.2f of sigma eps "
                      "wtot, max |dtau| %.2e (--lod-bound 1e-4); %d rays, %.1f segments per ray "
                      "against the exact walk's %.1f\n", wrap, worst, worst_tau, used,
                      (double)seg_tensor / used, (double)seg_exact / used);
        assert_true(worst_tau <= 1e-4);
        assert_true(used > 150);
        /* About 20 rectangles per axis against 272 cells: far fewer segments
         * (fewer still but for the cuts of h, the same in both walks). */
        assert_true(seg_tensor * 2 < seg_exact);
        unmake(&st);
    }
}

/* A bound below what the tensor grid can promise on the longer rays (the
 * median of sigma eps wtot over the rays): the dyadic levels take those,
 * the bound still holds. */
static void test_tensor_tight_bound(void **state)
{
    (void)state;
    setup_t st;
    make(&st, FP_WRAP_ZERO, 0);
    const fp_fog_tables_t *t = st.d.tables;
    double eps = tensor_eps(&st), sigma = st.d.fp[FP_F_SIGMA];
    enum { NR = 120 };
    double o[NR][3], dir[NR][3], len[NR], need[NR], sorted[NR];
    int nr = 0;
    for (int k = 0; nr < NR; k++) {
        random_ray(&st, k, o[nr], dir[nr], &len[nr]);
        fp_path_t p;
        double a, b;
        fp_fogmap_path(st.d.fp, o[nr][0], o[nr][1], o[nr][2], dir[nr][0], dir[nr][1],
                       dir[nr][2], len[nr], &p, &a, &b);
        if (isinf(b))
            b = fp_fogmap_cap(st.d.fp, &p, a);
        if (!(b > a))
            continue;
        need[nr] = sorted[nr] = sigma * eps * fp_rest_weight(FY0, FH, &p, a, b);
        nr++;
    }
    for (int i = 1; i < NR; i++)
        for (int j = i; j > 0 && sorted[j - 1] > sorted[j]; j--) {
            double x = sorted[j];
            sorted[j] = sorted[j - 1];
            sorted[j - 1] = x;
        }
    const double bound = sorted[NR / 2];
    fp_integrate_data_t lod = st.d;
    lod.fp[FP_F_LOD_BOUND] = bound;
    double worst = 0;
    int tensor = 0, dyadic = 0;
    for (int k = 0; k < NR; k++) {
        double exact = fp_fog_od(st.d.fp, FP_TABLES(t), o[k][0], o[k][1], o[k][2], dir[k][0],
                                 dir[k][1], dir[k][2], len[k], 0);
        double got = fp_fog_od(lod.fp, FP_TABLES(t), o[k][0], o[k][1], o[k][2], dir[k][0],
                               dir[k][1], dir[k][2], len[k], 0);
        double e = fabs(exp(-got) - exp(-exact));
        worst = fmax(worst, e);
        if (!(e <= bound))
            fail_msg("ray %d: |dtau| %.3e past --lod-bound %g", k, e, bound);
        tensor += need[k] <= bound;
        dyadic += need[k] > bound;
    }
    print_message("--lod-bound %.2e (eps %.2e): max |dtau| %.2e over %d rays (%d on the tensor "
                  "grid, %d on the dyadic levels)\n", bound, eps, worst, NR, tensor, dyadic);
    assert_true(tensor >= NR / 4 && dyadic >= NR / 4);
    unmake(&st);
}

/* Fine detail: no tensor grid (noise on every other row: breaks along V
 * at every node), and --lod-bound works as before. */
static void test_tensor_none_on_detail(void **state)
{
    (void)state;
    setup_t st;
    make(&st, FP_WRAP_ZERO, 1);
    assert_int_equal(tensor_row(&st)[FP_TI_NX], 0);
    unmake(&st);
    /* White noise. */
    fp_params_t p;
    fp_options_defaults(&p);
    p.fogmap.basis = 1;
    p.fogmap.levels = 3;
    float img[64 * 64];
    for (int i = 0; i < 64 * 64; i++)
        img[i] = (float)urand();
    fp_integrate_data_t d;
    fp_fogmap_stage_t s;
    assert_int_equal(fp_integrate_commit(&p, &d), FP_OK);
    assert_int_equal(fp_fogmap_setup(&p, NULL, img, 64, 64, &s, &d), FP_OK);
    assert_int_equal(d.tables->lvi[FP_TG_ROW * FP_LI_STRIDE + FP_TI_NX], 0);
    fp_fogmap_release(&s);
    fp_options_free(&p);
}

/* OpenCL (single precision) with --lod-bound on the tensor grid against
 * the C reference of the same (test_opencl_parity's tolerance, 1e-5) and
 * against the exact C reference (the bound plus that tolerance). */
static void test_tensor_opencl(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    if (fp_cl_open(NULL, &cl) != FP_OK)
        skip();
    fp_integrate_cl_t s;
    assert_int_equal(fp_integrate_cl_init(cl, &s), FP_OK);
    const int w = 96, h = 64;
    size_t n = (size_t)w * h;
    float *depth = malloc(n * sizeof(float)), *ref = malloc(n * 4 * sizeof(float)),
          *cref = malloc(n * 4 * sizeof(float)), *got = malloc(n * 4 * sizeof(float));
    for (int wrap = 0; wrap < 3; wrap++) {
        setup_t st;
        make(&st, wrap, 0);
        fp_view_t v;
        assert_int_equal(make_view(&v, w, h, 4 + 3 * wrap, -15), 0);
        for (size_t i = 0; i < n; i++)
            depth[i] = urand() < 0.1 ? INFINITY : (float)pow(10, 0.5 + 1.8 * urand());
        fp_integrate_data_t lod = st.d;
        lod.fp[FP_F_LOD_BOUND] = 1e-4;
        assert_int_equal(fp_integrate_process(&st.d, &v, depth, ref, NULL), FP_OK);
        assert_int_equal(fp_integrate_process(&lod, &v, depth, cref, NULL), FP_OK);
        assert_int_equal(fp_integrate_process_cl(&s, &lod, &v, depth, got), FP_OK);
        double wc = 0, we = 0;
        for (size_t i = 0; i < n; i++) {
            double ec = fabs((double)got[4 * i + 3] - cref[4 * i + 3]);
            double ee = fabs((double)got[4 * i + 3] - ref[4 * i + 3]);
            wc = fmax(wc, isnan(ec) ? INFINITY : ec);
            we = fmax(we, isnan(ee) ? INFINITY : ee);
            if (!(ec <= 1e-5) || !(ee <= 1e-4 + 1e-5))
                fail_msg("wrap %d pixel %zu depth %g: OpenCL %.9g, C (tensor) %.9g, exact %.9g",
                         wrap, i, depth[i], got[4 * i + 3], cref[4 * i + 3], ref[4 * i + 3]);
        }
        print_message("wrap %d --lod-bound 1e-4 (tensor grid): OpenCL vs C max |dtau| %.2e "
                      "(tolerance 1e-5), vs exact C %.2e (tolerance 1e-4 + 1e-5)\n", wrap, wc,
                      we);
        unmake(&st);
    }
    free(depth);
    free(ref);
    free(cref);
    free(got);
    fp_integrate_cl_release(&s);
    fp_cl_close(cl);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_tensor_resized),
        cmocka_unit_test(test_tensor_tight_bound),
        cmocka_unit_test(test_tensor_none_on_detail),
        cmocka_unit_test(test_tensor_opencl),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

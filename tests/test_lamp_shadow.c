/* The local lights' screen-space shadows (--lamp-shadows screen,
 * kernels/lamp_shadow_core.h) on a synthetic depth buffer: a wall at
 * planar z = 10 over the left half of the frame (x < 0), sky elsewhere, a
 * point lamp behind it at (-3, 0, 14) and a spot in front of it.
 *
 *  1. the walk's intervals along each view ray against the same rule
 *     point by point (fp_ls_visible), and both against the geometry: a
 *     point is shadowed when its segment to the lamp meets the wall's
 *     slab (z in [10, 11], x < 0: THICK 1);
 *  2. the fog's light (C, double) against quadrature of the single-
 *     scattering integral with that geometric visibility, per pixel,
 *     within 5e-4 of the lamp's largest in-scatter (--light-quad panels,
 *     whose nodes point-sample the shadow's edges: the light the shadow
 *     takes away within 5e-3); --lamp-shadows none fails the same check
 *     (measured, printed);
 *  3. OpenCL against the C reference on the frame (pixels and a pixel
 *     list), within 5e-4 of the largest in-scatter;
 *  4. --shadows map+screen: an extra directional light's screen shadows,
 *     as under --shadows screen.
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

#define W 64
#define H 48

typedef struct scene_t {
    fp_params_t p;
    fp_integrate_data_t fog;
    fp_scatter_data_t sd;
    fp_view_t v;
    float depth[W * H];
    float view[FP_VIEW_FLOATS];
} scene_t;

static void scene_open(scene_t *s, const char *const *opts)
{
    memset(s, 0, sizeof *s);
    fp_params_t cp;
    fp_options_defaults(&cp);
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.width = info.disp_w = W;
    info.height = info.disp_h = H;
    info.pixel_aspect = 1;
    assert_int_equal(fp_options_apply(&cp, "camera-pos", "0,0,0", "test"), FP_OK);
    assert_int_equal(fp_options_apply(&cp, "camera-target", "0,0,10", "test"), FP_OK);
    assert_int_equal(fp_options_apply(&cp, "vfov", "60", "test"), FP_OK);
    fp_camera_t c;
    assert_int_equal(fp_camera_resolve(&cp, &info, "synthetic", 1, &c), FP_OK);
    assert_int_equal(fp_view_setup(&c, &cp, &info, &s->v), FP_OK);
    fp_options_free(&cp);
    for (int j = 0; j < H; j++)
        for (int i = 0; i < W; i++) {
            double dir[3], len;
            fp_view_ray(&s->v, i, j, 1, dir, &len);
            s->depth[j * W + i] = dir[0] < 0 ? 10.0f : INFINITY;
        }
    fp_view_pack(&s->v, s->view);
    fp_options_defaults(&s->p);
    for (int i = 0; opts[i]; i += 2)
        assert_int_equal(fp_options_apply(&s->p, opts[i], opts[i + 1], "test"), FP_OK);
    assert_int_equal(fp_integrate_commit(&s->p, &s->fog), FP_OK);
    assert_int_equal(fp_scatter_commit(&s->p, &s->sd), FP_OK);
    assert_int_equal(fp_scatter_frame(&s->p, &s->sd, &s->fog, &s->v, s->depth, 1), FP_OK);
}

static void scene_close(scene_t *s)
{
    fp_scatter_release(&s->sd);
    fp_options_free(&s->p);
}

static const double lamp[3] = { -3, 0, 14 };

/* The geometry's answer: P's segment to the lamp meets the wall's slab
 * (z in [10, 11] on the pixels with x < 0; x falls monotonically toward
 * the lamp's -3, so at z = 11 it is smallest over the slab).  *margin: how
 * far that is from the slab's edges (points too near them are not judged). */
static int wall_shadows(const double P[3], double *margin)
{
    if (P[2] >= 11) {
        *margin = P[2] - 11;
        return 0;
    }
    double f = (11 - P[2]) / (lamp[2] - P[2]);
    double x = P[0] + f * (lamp[0] - P[0]);
    *margin = fmin(fabs(x), fabs(P[2] - 10));
    return x < 0;
}

static const char *const base_opts[] = {
    "density", "0.05", "fog-color", "0,0,0", "phase", "hg:0.3",
    "light", "point:-3,0,14:1,0.8,0.6:40",
    "light", "spot:2,1,4:0.6,0.8,1:30:0,0,1:25,40", NULL
};

/* ------------------------------------------------------------ 1. the walk */

static void test_walk(void **state)
{
    (void)state;
    scene_t s;
    scene_open(&s, base_opts);
    const double *lt = s.sd.lt;
    assert_int_equal((int)lt[FP_LT_LS_ON], 1);
    const double *row = s.sd.lights;
    int rays = 0, shadowed_rays = 0, pts = 0, judged = 0, mismatch = 0;
    for (int j = 0; j < H; j += 3)
        for (int i = 0; i < W; i += 2) {
            double dir[3], len, o[3];
            fp_view_ray(&s.v, i, j, s.depth[j * W + i], dir, &len);
            fp_view_origin_at(&s.v, i, j, o);
            double tb = fmin(len, 60), iv[2 * FP_SS_MAX_IV];
            int n = fp_ls_ray_iv(lt, row, s.view, s.sd.smap, o[0], o[1], o[2], dir[0], dir[1],
                                 dir[2], 0, tb, iv);
            rays++;
            shadowed_rays += n > 0;
            for (int k = 0; k < 400; k++) {
                double t = (k + 0.5) / 400 * tb;
                double P[3] = { o[0] + t * dir[0], o[1] + t * dir[1], o[2] + t * dir[2] };
                int in = fp_ls_in(iv, n, t);
                double vis = fp_ls_visible(lt, row, s.view, s.sd.smap, P[0], P[1], P[2]);
                pts++;
                if (in != (vis == 0))
                    fail_msg("pixel (%d, %d) t %g: the walk's intervals say %s, the point %s", i,
                             j, t, in ? "shadowed" : "lit", vis == 0 ? "shadowed" : "lit");
                double margin;
                int geo = wall_shadows(P, &margin);
                /* Half a pixel at the point's depth: the cells are pixels. */
                if (margin < 0.02 * P[2])
                    continue;
                judged++;
                mismatch += geo != in;
                if (geo != in)
                    print_message("pixel (%d, %d) P (%g, %g, %g): geometry %d, walk %d\n", i, j,
                                  P[0], P[1], P[2], geo, in);
            }
        }
    print_message("lamp walk: %d rays (%d with shadow), %d points: intervals = point rule at "
                  "all; %d judged against the wall's geometry, %d differ (tolerance 0)\n", rays,
                  shadowed_rays, pts, judged, mismatch);
    assert_true(shadowed_rays > rays / 8);
    assert_int_equal(mismatch, 0);
    /* The spot (in front of the wall, x > 0) is nowhere shadowed. */
    int spot_hits = 0;
    for (int j = 0; j < H; j += 4)
        for (int i = 0; i < W; i += 4) {
            double dir[3], len, o[3], iv[2 * FP_SS_MAX_IV];
            fp_view_ray(&s.v, i, j, s.depth[j * W + i], dir, &len);
            fp_view_origin_at(&s.v, i, j, o);
            double P[3] = { 5 * dir[0], 5 * dir[1], 5 * dir[2] };
            spot_hits += fp_ls_visible(lt, row + FP_LL_STRIDE, s.view, s.sd.smap, P[0], P[1],
                                       P[2]) == 0;
            spot_hits += fp_ls_ray_iv(lt, row + FP_LL_STRIDE, s.view, s.sd.smap, o[0], o[1],
                                      o[2], dir[0], dir[1], dir[2], 0, fmin(len, 9), iv) > 0;
        }
    assert_int_equal(spot_hits, 0);
    scene_close(&s);
}

/* ------------------------------------------------------------ 2. the fog's light */

/* The lamps' in-scatter along a view ray by the midpoint rule in the
 * angle seen from each lamp (t = t_c + D tan(theta): the 1/r^2 peak
 * flattened), n steps over [0, min(len, T)], visibility from the wall's
 * geometry for the point lamp (the spot: lit): the fast rule's closed
 * forms for the optical depths, fp_light_gain and fp_phase for the rest. */
static void brute(const scene_t *s, const double o[3], const double d[3], double len, int geo,
                  double S[3])
{
    const double *fp = s->fog.fp, *lt = s->sd.lt;
    S[0] = S[1] = S[2] = 0;
    double T = fmin(len, 250);
    const int n = 6000;
    for (int L = 0; L < 2; L++) {
        const double *row = s->sd.lights + L * FP_LL_STRIDE;
        double q[3] = { row[FP_LL_POS] - o[0], row[FP_LL_POS + 1] - o[1], row[FP_LL_POS + 2] - o[2] };
        double tc = q[0] * d[0] + q[1] * d[1] + q[2] * d[2];
        double r2[3] = { q[0] - tc * d[0], q[1] - tc * d[1], q[2] - tc * d[2] };
        double D = sqrt(r2[0] * r2[0] + r2[1] * r2[1] + r2[2] * r2[2]);
        double th0 = atan((0 - tc) / D), th1 = atan((T - tc) / D), hth = (th1 - th0) / n;
        for (int k = 0; k < n; k++) {
            double th = th0 + (k + 0.5) * hth, t = tc + D * tan(th);
            double dt = D / (cos(th) * cos(th)) * hth;
            double P[3] = { o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2] };
            double sig = fp_light_plain_sigma(fp, P[0], P[1], P[2]);
            double margin;
            if (!(sig > 0) || (L == 0 && geo && wall_shadows(P, &margin)))
                continue;
            double odc = fp_light_plain_od(fp, o[0], o[1], o[2], d[0], d[1], d[2], t);
            double v[3] = { row[FP_LL_POS] - P[0], row[FP_LL_POS + 1] - P[1],
                            row[FP_LL_POS + 2] - P[2] };
            double r = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            for (int c = 0; c < 3; c++)
                v[c] /= r;
            double g = fp_light_gain(row, -v[0], -v[1], -v[2], r);
            if (!(g > 0))
                continue;
            double odl = fp_light_plain_od(fp, P[0], P[1], P[2], v[0], v[1], v[2], r);
            double f = dt * lt[FP_LT_ALBEDO] * sig * exp(-odc - odl) * g / (r * r) *
                       fp_phase((int)lt[FP_LT_PHASE], lt[FP_LT_PHASE + 1], lt[FP_LT_PHASE + 2],
                                v[0] * d[0] + v[1] * d[1] + v[2] * d[2]);
            for (int c = 0; c < 3; c++)
                S[c] += f * row[FP_LL_I + c];
        }
    }
}

/* Largest difference over the sampled pixels between out (the frame's
 * fog layer) and the quadrature, relative to the quadrature's largest. */
static double fog_error(const scene_t *s, const float *out, int geo, double *smax_out)
{
    double e = 0, smax = 0;
    for (int j = 1; j < H; j += 6)
        for (int i = 1; i < W; i += 5) {
            double dir[3], len, o[3], S[3];
            fp_view_ray(&s->v, i, j, s->depth[j * W + i], dir, &len);
            fp_view_origin_at(&s->v, i, j, o);
            brute(s, o, dir, len, geo, S);
            for (int c = 0; c < 3; c++) {
                smax = fmax(smax, S[c]);
                e = fmax(e, fabs(out[4 * (j * W + i) + c] - S[c]));
            }
        }
    *smax_out = smax;
    return e / smax;
}

/* The light the shadow takes away (sh - open per pixel) against the
 * quadrature's, relative to the quadrature's largest in-scatter. */
static double shadow_error(const scene_t *s, const float *sh, const float *open)
{
    double e = 0, smax = 0;
    for (int j = 1; j < H; j += 6)
        for (int i = 1; i < W; i += 5) {
            double dir[3], len, o[3], S1[3], S0[3];
            fp_view_ray(&s->v, i, j, s->depth[j * W + i], dir, &len);
            fp_view_origin_at(&s->v, i, j, o);
            brute(s, o, dir, len, 1, S1);
            brute(s, o, dir, len, 0, S0);
            for (int c = 0; c < 3; c++) {
                size_t at = 4 * (size_t)(j * W + i) + c;
                smax = fmax(smax, S0[c]);
                e = fmax(e, fabs((sh[at] - open[at]) - (S1[c] - S0[c])));
            }
        }
    return e / smax;
}

static void test_fog(void **state)
{
    (void)state;
    scene_t s;
    scene_open(&s, base_opts);
    float *out = malloc(4 * sizeof *out * W * H);
    assert_int_equal(fp_scatter_process(&s.sd, &s.fog, &s.v, s.depth, out), FP_OK);
    double smax, e = fog_error(&s, out, 1, &smax);
    /* The same frame unshadowed, judged against the shadowed quadrature
     * (must fail) and the unshadowed one (must pass). */
    scene_t u;
    const char *nopts[32];
    int k = 0;
    for (; base_opts[k]; k++)
        nopts[k] = base_opts[k];
    nopts[k++] = "lamp-shadows";
    nopts[k++] = "none";
    nopts[k] = NULL;
    scene_open(&u, nopts);
    assert_int_equal((int)u.sd.lt[FP_LT_LS_ON], 0);
    float *uout = malloc(4 * sizeof *uout * W * H);
    assert_int_equal(fp_scatter_process(&u.sd, &u.fog, &u.v, u.depth, uout), FP_OK);
    double smax_u, e_none = fog_error(&u, uout, 1, &smax_u), e_open = fog_error(&u, uout, 0, &smax_u);
    print_message("lamp shadows, C: largest error against quadrature %.2e of the largest "
                  "in-scatter %.3g (tolerance 5e-4); --lamp-shadows none: %.2e against the "
                  "shadowed fog, %.2e against unshadowed quadrature\n", e, smax, e_none, e_open);
    assert_true(e <= 5e-4);
    assert_true(e_open <= 5e-4);
    assert_true(e_none > 2e-2);
    /* --light-quad panels (the path with a fogmap): nodes in the shadow
     * left out, the shadow's edges point-sampled by the panels' nodes.
     * Judged by the light the shadow takes away (the panels' own error
     * apart). */
    scene_t pn, p0;
    nopts[k - 2] = "light-quad";
    nopts[k - 1] = "panels";
    scene_open(&pn, nopts);
    assert_int_equal((int)pn.sd.lt[FP_LT_LS_ON], 1);
    nopts[k++] = "lamp-shadows";
    nopts[k++] = "none";
    nopts[k] = NULL;
    scene_open(&p0, nopts);
    float *pout = malloc(4 * sizeof *pout * W * H);
    assert_int_equal(fp_scatter_process(&pn.sd, &pn.fog, &pn.v, pn.depth, uout), FP_OK);
    assert_int_equal(fp_scatter_process(&p0.sd, &p0.fog, &p0.v, p0.depth, pout), FP_OK);
    double e_pan = shadow_error(&pn, uout, pout);
    print_message("lamp shadows, C, --light-quad panels: the light the shadow takes away within "
                  "%.2e of the largest in-scatter (tolerance 5e-3)\n", e_pan);
    assert_true(e_pan <= 5e-3);
    free(pout);
    scene_close(&pn);
    scene_close(&p0);
    free(out);
    free(uout);
    scene_close(&s);
    scene_close(&u);
}

/* ------------------------------------------------------------ 3. OpenCL */

static void test_opencl(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    if (fp_cl_open(NULL, &cl) != FP_OK) {
        print_message("no OpenCL device: skipped\n");
        skip();
    }
    fp_integrate_cl_t icl;
    fp_scatter_cl_t scl;
    assert_int_equal(fp_integrate_cl_init(cl, &icl), FP_OK);
    assert_int_equal(fp_scatter_cl_init(cl, &scl), FP_OK);
    scene_t s;
    scene_open(&s, base_opts);
    size_t n = (size_t)W * H;
    float *ref = malloc(4 * n * sizeof *ref), *got = malloc(4 * n * sizeof *got);
    assert_int_equal(fp_scatter_process(&s.sd, &s.fog, &s.v, s.depth, ref), FP_OK);
    assert_int_equal(fp_scatter_process_cl(&scl, &icl, &s.sd, &s.fog, &s.v, s.depth, got), FP_OK);
    double smax = 0, e = 0;
    for (size_t i = 0; i < 4 * n; i++)
        if (i % 4 != 3)
            smax = fmax(smax, ref[i]);
    for (size_t i = 0; i < 4 * n; i++)
        e = fmax(e, fabs(got[i] - ref[i]) / (i % 4 == 3 ? 1 : smax));
    /* A pixel list: the same values, list order. */
    int pix[97];
    for (int k = 0; k < 97; k++)
        pix[k] = (int)((k * 1237u) % n);
    float *lst = malloc(4 * 97 * sizeof *lst);
    assert_int_equal(fp_scatter_pixels_cl(&scl, &icl, &s.sd, &s.fog, &s.v, s.depth, pix, 97, lst),
                     FP_OK);
    double el = 0;
    for (int k = 0; k < 97; k++)
        for (int c = 0; c < 4; c++)
            el = fmax(el, fabs(lst[4 * k + c] - got[4 * pix[k] + c]) / (c == 3 ? 1 : smax));
    print_message("lamp shadows, OpenCL against C: largest difference %.2e (pixel list %.2e) of "
                  "the largest in-scatter %.3g (tolerance 5e-4)\n", e, el, smax);
    assert_true(e <= 5e-4);
    assert_true(el <= 5e-4);
    free(ref);
    free(got);
    free(lst);
    scene_close(&s);
    fp_scatter_cl_release(&scl);
    fp_integrate_cl_release(&icl);
    fp_cl_close(cl);
}

/* ------------------------------------------------------------ 4. map+screen */

/* An extra directional light behind the wall (toward +z, up a little):
 * under --shadows map+screen its screen shadows are those of --shadows
 * screen (the map is the sun's only).  The map here sees nothing (one
 * texel at +inf), the depth buffer's pyramid after it, as
 * fp_scatter_screen lays them out. */
static void test_dir_map_screen(void **state)
{
    (void)state;
    static const char *const opts[] = { "density", "0.05", "fog-color", "0,0,0",
                                        "shadows", "screen", "light", "dir:-0.2,0.1,1:1,1,1:2",
                                        "lamp-shadows", "none", "self-shadow", "off", NULL };
    scene_t s;
    scene_open(&s, opts);
    double *lt = s.sd.lt;
    assert_int_equal((int)lt[FP_LT_SHADOWS], FP_SHADOWS_SCREEN);
    size_t nz = s.sd.smap_n;
    float *both = malloc((nz + 1) * sizeof *both);
    both[0] = INFINITY;
    memcpy(both + 1, s.sd.smap, nz * sizeof *both);
    double lt2[FP_LT_COUNT];
    memcpy(lt2, lt, sizeof lt2);
    lt2[FP_LT_SHADOWS] = FP_SHADOWS_MAP_SCREEN;
    lt2[FP_LT_SM_W] = lt2[FP_LT_SM_H] = 1;
    lt2[FP_LT_SM_LEVELS] = 0;
    for (int i = 0; i < 16; i++)
        lt2[FP_LT_SM_NDC + i] = 0;
    for (int i = 0; i < 4; i++)
        lt2[FP_LT_SM_Z + i] = 0;
    int shadowed = 0, pts = 0;
    for (int k = 0; k < 200; k++) {
        double P[3] = { -4 + 3.5 * urand(), -2 + 4 * urand(), 2 + 7.5 * urand() };
        double J1[3], J2[3];
        fp_scatter_source(s.fog.fp, NULL, NULL, NULL, NULL, lt, s.sd.lights, s.sd.smap, NULL,
                          s.view, s.depth, W, H, 0, 0, 0, 1, P[0], P[1], P[2], J1);
        fp_scatter_source(s.fog.fp, NULL, NULL, NULL, NULL, lt2, s.sd.lights, both, NULL,
                          s.view, s.depth, W, H, 0, 0, 0, 1, P[0], P[1], P[2], J2);
        pts++;
        shadowed += J1[0] == 0;
        if (J1[0] != J2[0])
            fail_msg("(%g, %g, %g): the directional light %g under screen, %g under map+screen",
                     P[0], P[1], P[2], J1[0], J2[0]);
    }
    print_message("map+screen: an extra directional light's screen shadows at %d points (%d "
                  "shadowed) as under --shadows screen\n", pts, shadowed);
    assert_true(shadowed > 10);
    free(both);
    scene_close(&s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_walk),
        cmocka_unit_test(test_fog),
        cmocka_unit_test(test_opencl),
        cmocka_unit_test(test_dir_map_screen),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

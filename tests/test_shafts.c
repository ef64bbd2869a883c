/* Shadows in the fog: the sun's shadow map, screen-space shadows and the
 * shafts along the map against brute force, thin casters, convergence,
 * OpenCL, map+screen, the sky seam (split from tests/test_scatter.c; helpers in
 * tests/scatter_testutil.h). */
#include "scatter_testutil.h"

/* ------------------------------------------------------------ 7. shafts (issue 13) */

/* A thin-caster scene for the exact shadow-map walk (kernels/shafts_core.h):
 * level ground, a wall at z 40..40.45 (6 m high, x -18..18) with gaps,
 * pillars at z 20..20.3 (4 m high), the sun 20 degrees up toward +z, so
 * the map's x axis is the world's and a gap or pillar whose edges sit on
 * texel boundaries is exactly whole texels wide in the map. */
typedef struct {
    double box[32][6];
    int n;
} caster_scene_t;

static void caster_add(caster_scene_t *s, double x0, double y0, double z0, double x1, double y1,
                       double z1)
{
    double b[6] = { x0, y0, z0, x1, y1, z1 };
    memcpy(s->box[s->n++], b, sizeof b);
}

/* The wall's gaps [gx, gx + gw] and the pillars [px, px + pw]. */
static void caster_scene(caster_scene_t *s, const double *gx, int ng, double gw, const double *px,
                         const double *pw, int np)
{
    s->n = 0;
    caster_add(s, -200, -1, -200, 200, 0, 200);   /* the ground */
    double x = -18;
    for (int i = 0; i < ng; i++) {
        caster_add(s, x, 0, 40, gx[i], 6, 40.45);
        x = gx[i] + gw;
    }
    caster_add(s, x, 0, 40, 18, 6, 40.45);
    for (int i = 0; i < np; i++)
        caster_add(s, px[i], 0, 20, px[i] + pw[i], 4, 20.3);
}

/* Nearest hit along o + t d (t > 0), +inf when none. */
static double caster_hit(const caster_scene_t *s, const double o[3], const double d[3])
{
    double best = INFINITY;
    for (int i = 0; i < s->n; i++) {
        double a = 1e-9, b = INFINITY;
        for (int k = 0; k < 3; k++)
            fp_clip(o[k], d[k], s->box[i][k], s->box[i][k + 3], &a, &b);
        if (b > a)
            best = fmin(best, a);
    }
    return best;
}

#define SH_ELEV (20 * M_PI / 180)
#define SH_SIZE 51.2   /* the map's side, m */

/* Set: caster_map packs without the ground plane (ga = gb = 0: the plain
 * min-max of zb, the walk as it was before the plane). */
static int caster_plain;

/* The sun's map of the scene at `texel` m (SH_SIZE / texel texels each
 * way), packed as fp_scatter_frame packs a file's, into r's light data. */
static void caster_map(rig_t *r, const caster_scene_t *s, double texel)
{
    double *lt = r->sd.lt;
    const double l[3] = { 0, sin(SH_ELEV), cos(SH_ELEV) };
    const double f[3] = { 0, -l[1], -l[2] };            /* the map camera's +z */
    const double rx[3] = { 1, 0, 0 };                   /* its +x */
    const double uy[3] = { 0, l[2], -l[1] };            /* its +y: up, away from the sun */
    const double c[3] = { 0, 50 * l[1], 25 + 50 * l[2] };
    int n = (int)lround(SH_SIZE / texel);
    for (int i = 0; i < 16; i++)
        lt[FP_LT_SM_NDC + i] = 0;
    for (int k = 0; k < 3; k++) {
        lt[FP_LT_SM_NDC + 4 * k] = rx[k] / SH_SIZE;
        lt[FP_LT_SM_NDC + 4 * k + 1] = -uy[k] / SH_SIZE;
        lt[FP_LT_SM_Z + k] = f[k];
    }
    lt[FP_LT_SM_NDC + 12] = 0.5 - dot3(c, rx) / SH_SIZE;
    lt[FP_LT_SM_NDC + 13] = 0.5 + dot3(c, uy) / SH_SIZE;
    lt[FP_LT_SM_NDC + 15] = 1;
    lt[FP_LT_SM_Z + 3] = -dot3(c, f);
    lt[FP_LT_SM_W] = lt[FP_LT_SM_H] = n;
    float *z = malloc((size_t)n * n * sizeof *z);
    assert_non_null(z);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double a = (i + 0.5) * texel - 0.5 * SH_SIZE, b = 0.5 * SH_SIZE - (j + 0.5) * texel;
            double o[3];
            for (int k = 0; k < 3; k++)
                o[k] = c[k] + a * rx[k] + b * uy[k];
            z[(size_t)j * n + i] = (float)caster_hit(s, o, f);
        }
    float *packed;
    size_t np;
    int levels;
    double slope = l[2] / l[1];
    fp_shafts_plane(lt + FP_LT_SM_NDC, lt + FP_LT_SM_Z, n, n, lt + FP_LT_SM_GA, lt + FP_LT_SM_GB);
    if (caster_plain)
        lt[FP_LT_SM_GA] = lt[FP_LT_SM_GB] = 0;
    assert_int_equal(fp_shafts_build(z, n, n, texel * fmax(1, slope), r->p.light.shadow_bias,
                                     lt[FP_LT_SM_GA], lt[FP_LT_SM_GB], &packed, &np, &levels),
                     0);
    free(z);
    free(r->sd.smap);
    r->sd.smap = packed;
    r->sd.smap_n = np;
    r->sd.smap_w = r->sd.smap_h = n;
    lt[FP_LT_SM_LEVELS] = levels;
    static unsigned long serial = 1000000;
    r->sd.serial = ++serial;
}

/* The scene's own visibility of the sun from p (the map's is the
 * default of fp_scatter_sun_brute). */
static double caster_vis(void *ctx, const double p[3])
{
    const caster_scene_t *s = ctx;
    const double l[3] = { 0, sin(SH_ELEV), cos(SH_ELEV) };
    return caster_hit(s, p, l) < INFINITY ? 0 : 1;
}

/* fogpipe's sun share of the same ray: S.r over albedo E p (the options
 * below: no ambient, albedo 1, sun color 1 intensity 1, isotropic). */
static double shafts_fast(const rig_t *r, const double o[3], const double d[3], double len)
{
    double S[3];
    ray(r, o, d, len, S);
    return S[0] * 4 * M_PI;
}

static const double sh_gaps[] = { -12, -7.5, -3, 0.5, 4, 8.5, 13 };   /* on 0.05 m texel edges */
static const double sh_pillars[] = { -10, -4, 2, 9 };
static const double sh_pillar_w1[] = { 0.05, 0.1, 0.05, 0.1 };        /* one and two texels */

/* Camera rays of the thin-caster scene: a fan from (0, 1.7, 0) toward
 * the wall, some grazing, some to the sky (the fog's top ends them). */
static void sh_ray(const caster_scene_t *s, int k, int nk, double o[3], double d[3], double *len)
{
    o[0] = -1 + 0.37 * (k % 7);
    o[1] = 1.7;
    o[2] = 5 + 2.1 * (k % 5);
    double az = -0.55 + 1.1 * k / (nk - 1.0), el = -0.12 + 0.22 * ((k * 7) % 11) / 10.0;
    d[0] = sin(az) * cos(el);
    d[1] = sin(el);
    d[2] = cos(az) * cos(el);
    double t = caster_hit(s, o, d);
    *len = isfinite(t) ? t : INFINITY;
}

static const char *const sh_opts_base[] = {
    "density", "0.05", "height", "0,30,15", "fog-color", "0,0,0", "sun", "0,0.3420201,0.9396926",
    "sun-color", "1,1,1", "sun-intensity", "1", "phase", "iso", "shadow-map", "unused.####.exr",
    "shadow-filter", "0", NULL };

static void sh_rig(rig_t *r, const char *const *extra, const float *map, int mw, int mh)
{
    const char *opts[64];
    int n = 0;
    for (int i = 0; sh_opts_base[i]; i++)
        opts[n++] = sh_opts_base[i];
    for (int i = 0; extra && extra[i]; i++)
        opts[n++] = extra[i];
    opts[n] = NULL;
    if (map)
        rig_open_map(r, opts, map, mw, mh);
    else
        rig_open(r, opts);
}
/* In homogeneous fog at one height: int over the stretches [a_i, b_i] of
 * sigma e^{-sigma t} dt. */
static double lit_sum(double sigma, double x0, const double *a, const double *bb, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++)
        s += exp(-sigma * (a[i] - x0)) - exp(-sigma * (bb[i] - x0));
    return s;
}
/* A w x h view from (0, 1.7, 0) toward the wall and its planar depth
 * traced in the scene (malloc'd). */
static float *caster_view(const caster_scene_t *s, int w, int h, fp_view_t *v)
{
    make_view_at(v, w, h, "0,1.7,0", "0,2.5,40", "50");
    float *depth = malloc((size_t)w * h * sizeof *depth);
    assert_non_null(depth);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double d[3], len1, o[3];
            fp_view_ray(v, x, y, 1, d, &len1);
            fp_view_origin_at(v, x, y, o);
            double t = caster_hit(s, o, d);
            depth[y * w + x] = isfinite(t) ? (float)(t / len1) : INFINITY;
        }
    return depth;
}
/* --shadows screen by the same walk over the depth buffer: against brute
 * force with the point visibility of the same rule (fp_shadow_screen), on
 * the thin-caster scene seen from before the wall (its face and its gaps
 * are in the depth buffer; the sun ahead, above the wall). */
typedef struct {
    const double *lt;
    const float *view, *zpyr;   /* the frame's scene z and its pyramid */
    int w, h;
} screen_vis_t;

static double screen_vis(void *ctx, const double p[3])
{
    const screen_vis_t *c = ctx;
    return fp_shadow_screen(c->lt, c->view, c->zpyr, c->w, c->h, p[0], p[1], p[2]);
}
/* --shadows map+screen: the map's exact walk with the depth buffer's
 * shadowed stretches taken out of its lit runs, against brute force with
 * the product of the two point rules (fp_sun_visibility), on the
 * thin-caster scene with a 0.4 m map (the 5 and 10 cm pillars fall
 * between its texels; the camera sees them); the combined light is below
 * both the map's and the walk's alone on some rays (each adds shadow the
 * other lacks) and closer to the scene's own visibility than either, and
 * the OpenCL kernel gives the same. */
static double both_vis(void *ctx, const double p[3])
{
    const screen_vis_t *c = ctx;
    return fp_shadow_map(c->lt, c->zpyr, p[0], p[1], p[2]) *
           fp_shadow_screen(c->lt, c->view, fp_ss_zpyr(c->lt, c->zpyr), c->w, c->h, p[0], p[1],
                            p[2]);
}

static double map_vis(void *ctx, const double p[3])
{
    const screen_vis_t *c = ctx;
    return fp_shadow_map(c->lt, c->zpyr, p[0], p[1], p[2]);
}

static double walk_vis(void *ctx, const double p[3])
{
    const screen_vis_t *c = ctx;
    return fp_shadow_screen(c->lt, c->view, fp_ss_zpyr(c->lt, c->zpyr), c->w, c->h, p[0], p[1],
                            p[2]);
}

static void test_shadow_map(void **state)
{
    (void)state;
    static const char *const opts[] = { "density", "0.03", "sun", "-0.4,0.35,0.6",
                                        "shadow-map", "-", NULL };
    scene_t sc;
    if (scene_open(&sc, opts, 0))
        skip();
    const double *lt = sc.r.sd.lt, *l = lt + FP_LT_SUN_DIR;
    assert_non_null(sc.r.sd.smap);
    assert_int_equal(sc.r.sd.smap_w, 512);
    /* In the blue box's shadow: the ground point whose sun ray passes
     * through the box's center, 2 cm up.  Lit: near the camera path. */
    const double C[3] = { 7.5, 2.5, 16.5 };
    double s = (C[1] - 0.02) / l[1];
    double shadowed[3] = { C[0] - s * l[0], 0.02, C[2] - s * l[2] };
    double lit[3] = { 0, 0.02, -5 };
    assert_true(scene_occluded(shadowed, l));
    assert_false(scene_occluded(lit, l));
    /* Point-sampled, the bias each texel's own (filters/shafts.c). */
    double vs = fp_sun_visibility(lt, sc.r.sd.smap, NULL, NULL, 0, 0, shadowed[0], shadowed[1],
                                  shadowed[2]);
    double vl = fp_sun_visibility(lt, sc.r.sd.smap, NULL, NULL, 0, 0, lit[0], lit[1], lit[2]);
    double vl_up = fp_sun_visibility(lt, sc.r.sd.smap, NULL, NULL, 0, 0, lit[0], 1, lit[2]);
    print_message("shadow map (%d texels, %d pyramid levels): at (%.2f, %.2f, %.2f) in the box's "
                  "shadow visibility %.3g; at (%.2f, %.2f, %.2f) lit %.3g (1 m up: %.3g)\n",
                  sc.r.sd.smap_w, (int)lt[FP_LT_SM_LEVELS], shadowed[0], shadowed[1],
                  shadowed[2], vs, lit[0], lit[1], lit[2], vl, vl_up);
    assert_double_equal(vs, 0, 0);
    /* 2 cm above level ground under this low sun: no acne (the old
     * filtered lookup with a fixed bias gave 0.67 here). */
    assert_double_equal(vl, 1, 0);
    assert_double_equal(vl_up, 1, 0);
    /* The shadow's edge along +x, 1.5 m up, from the point whose sun ray
     * passes through the box's center, by bisection on the geometry: the
     * map's visibility goes 0 -> 1 once across it, within two texels of
     * the true edge (a texel: the map's 167 m over 512). */
    const double ys = 1.5;
    s = (C[1] - ys) / l[1];
    const double base[3] = { C[0] - s * l[0], ys, C[2] - s * l[2] };
    double lo = base[0], hi = base[0] + 6;
    assert_true(scene_occluded(base, l));
    assert_false(scene_occluded((double[]){ hi, ys, base[2] }, l));
    for (int k = 0; k < 60; k++) {
        double mid = 0.5 * (lo + hi);
        if (scene_occluded((double[]){ mid, ys, base[2] }, l))
            lo = mid;
        else
            hi = mid;
    }
    double edge = 0.5 * (lo + hi), texel = 167.0 / 512, prev = 0, first_lit = NAN;
    int changes = 0;
    for (int k = -200; k <= 200; k++) {
        double x = edge + 0.01 * k;
        double v = fp_shadow_map(lt, sc.r.sd.smap, x, ys, base[2]);
        if (k == -200)
            assert_double_equal(v, 0, 0);
        if (k == 200)
            assert_double_equal(v, 1, 0);
        if (v != prev) {
            changes++;
            first_lit = x;
        }
        prev = v;
    }
    print_message("shadow map: visibility 0 -> 1 across the box's shadow edge at x = %.3f, the "
                  "map's at %.3f (%.2f texels off), %d change(s)\n", edge, first_lit,
                  fabs(first_lit - edge) / texel, changes);
    assert_int_equal(changes, 1);
    assert_true(fabs(first_lit - edge) <= 2 * texel);
    scene_close(&sc);
}

static void test_shafts_build_definition(void **state)
{
    (void)state;
    int texels = 0;
    for (int k = 0; k < 30; k++) {
        int w = 1 + (int)(urand() * 90), h = 1 + (int)(urand() * 70);
        float *z = malloc((size_t)w * h * sizeof *z);
        for (int i = 0; i < w * h; i++) {
            int r = (int)(urand() * 20);
            z[i] = r == 0 ? NAN : r == 1 ? INFINITY : r == 2 ? -INFINITY : r == 3 ? 0.0f
                 : (float)((urand() - 0.3) * (k % 3 ? 50 : 1e-30));
        }
        double msb = 0.01 * (k % 5), ub = k % 2 ? 1e-3 : 0;
        /* The ground plane: none, or a float's slope of either sign. */
        double ga = k % 4 ? (float)(0.4 * (urand() - 0.5)) : 0;
        double gb = k % 4 ? (float)(0.4 * (urand() - 0.5)) : 0;
        float *p;
        size_t n;
        int levels;
        assert_int_equal(fp_shafts_build(z, w, h, msb, ub, ga, gb, &p, &n, &levels), 0);
        for (int j = 0; j < h; j++)
            for (int i = 0; i < w; i++) {
                double c = z[(size_t)j * w + i];
                float want = INFINITY;
                if (isfinite(c)) {
                    double slope = 0.5 * (shafts_one_sided(z, w, h, i, j, 1, 0) +
                                          shafts_one_sided(z, w, h, i, j, 0, 1));
                    double b = fmin(slope, msb) + ub + 4e-7 * (fabs(c) + 1);
                    want = nextafterf((float)(c + b), INFINITY);
                }
                float got = p[(size_t)j * w + i];
                if (memcmp(&got, &want, sizeof got))
                    fail_msg("map %d (%dx%d) texel %d,%d: %.9g, by definition %.9g", k, w, h, i,
                             j, got, want);
                texels++;
            }
        /* Level 1 of the pyramid: bounds of the residual zb - ga U - gb V
         * over each 2 x 2 block's points (a texel's center less and plus
         * half the plane's fall across it), outward to float. */
        int lw = (w + 1) / 2, lh = (h + 1) / 2;
        double half = 0.5 * (fabs(ga) + fabs(gb));
        for (int j = 0; j < lh && levels > 0; j++)
            for (int i = 0; i < lw; i++) {
                float mn = INFINITY, mx = -INFINITY;
                for (int q = 0; q < 4; q++) {
                    int a = 2 * i + (q & 1), b = 2 * j + (q >> 1);
                    if (a < w && b < h) {
                        double r = p[(size_t)b * w + a] - ga * (a + 0.5) - gb * (b + 0.5);
                        float lo = (float)(r - half), hi = (float)(r + half);
                        if ((double)lo > r - half)
                            lo = nextafterf(lo, -INFINITY);
                        if ((double)hi < r + half)
                            hi = nextafterf(hi, INFINITY);
                        mn = fminf(mn, lo);
                        mx = fmaxf(mx, hi);
                    }
                }
                assert_true(p[(size_t)w * h + 2 * ((size_t)j * lw + i)] == mn);
                assert_true(p[(size_t)w * h + 2 * ((size_t)j * lw + i) + 1] == mx);
            }
        free(p);
        free(z);
    }
    print_message("fp_shafts_build vs its definition (fmin, nextafterf): %d texels bit for bit\n",
                  texels);
}

static void test_screen_shadows(void **state)
{
    (void)state;
    const int w = 64, h = 48;
    fp_view_t v;
    make_view_at(&v, w, h, "0,0,0", "0,0,10", "60");
    float *depth = malloc((size_t)w * h * sizeof *depth), packed[FP_VIEW_FLOATS];
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            double dir[3], len;
            fp_view_ray(&v, i, j, 1, dir, &len);
            assert_true(dir[2] > 0.5);
            depth[j * w + i] = dir[0] < 0 ? 10.0f : INFINITY;
        }
    fp_view_pack(&v, packed);
    static const char *const opts[] = { "density", "0.03", "sun", "0,0.3,1", "shadows",
                                        "screen", "screen-shadow", "20,1", NULL };
    rig_t r;
    rig_open(&r, opts);
    assert_int_equal(fp_scatter_frame(&r.p, &r.sd, &r.fog, &v, depth, 1), FP_OK);
    const double *lt = r.sd.lt;
    assert_int_equal((int)lt[FP_LT_SHADOWS], FP_SHADOWS_SCREEN);
    int n[3] = { 0, 0, 0 };
    for (int k = 0; k < 600; k++) {
        /* Points the camera sees (on a pixel's ray): in front of the wall
         * (2 < z < 9.5 on a wall pixel), beside it (2 < z < 14 on a sky
         * pixel), and, hidden, behind it (11.5 < z < 14.5 on a wall pixel). */
        int kind = k % 3, i, j;
        do {
            i = (int)(urand() * w);
            j = (int)(urand() * h);
        } while ((kind == 1) != isinf(depth[j * w + i]));
        double dir[3], len;
        fp_view_ray(&v, i, j, 1, dir, &len);
        double z = kind == 0 ? 2 + 7.5 * urand() : kind == 1 ? 2 + 12 * urand()
                                                             : 11.5 + 3 * urand();
        double t = z / dir[2], x = t * dir[0], y = t * dir[1];
        double vis = fp_sun_visibility(lt, r.sd.smap, packed, depth, w, h, x, y, z);
        double want = kind == 0 ? 0 : 1;
        if (vis != want)
            fail_msg("screen-space shadow at (%g, %g, %g) (%s): %g, expected %g", x, y, z,
                     kind == 0 ? "in front of the wall" : kind == 1 ? "beside it" : "behind it",
                     vis, want);
        n[kind]++;
    }
    /* On the wall's edge column (whose march converges on the sun's
     * vanishing point, half a pixel away): pixel lookups must round to
     * the nearest pixel center. */
    int edge_pts = 0;
    for (int j = 0; j < h; j++)
        for (int i = 1; i + 1 < w; i++) {
            if (isinf(depth[j * w + i]) || !(isinf(depth[j * w + i - 1]) ||
                                              isinf(depth[j * w + i + 1])))
                continue;
            double dir[3], len;
            fp_view_ray(&v, i, j, 1, dir, &len);
            for (double z = 3; z <= 9; z += 1.5) {
                double t = z / dir[2];
                double vis = fp_sun_visibility(lt, r.sd.smap, packed, depth, w, h, t * dir[0],
                                               t * dir[1], z);
                if (vis != 0)
                    fail_msg("screen-space shadow on the wall's edge pixel (%d, %d) at z %g: %g, "
                             "expected 0", i, j, z, vis);
                edge_pts++;
            }
        }
    assert_true(edge_pts >= 4 * h);
    /* Beyond the march's reach (20 units toward the sun) the wall casts
     * nothing: the documented limit. */
    assert_double_equal(fp_sun_visibility(lt, r.sd.smap, packed, depth, w, h, -2, 0, -12), 1, 0);
    print_message("screen-space shadows: %d points in front of the wall in its shadow all 0, %d "
                  "beside it and %d behind it all 1\n", n[0], n[1], n[2]);
    rig_close(&r);
    free(depth);
}

/* The sky meets the horizon without a seam: a sky ray's fog equals the
 * fog of geometry far along the same ray (rays level, rising and
 * falling, height fog with and without a top, a haze). */
static void test_sky_seam(void **state)
{
    (void)state;
    static const char *const heights[] = { "0,3", "0,3,15", "0,20" };
    double worst = 0;
    for (size_t hi = 0; hi < FP_ARRAY_LEN(heights); hi++) {
        const char *opts[] = { "density", "0.05", "height", heights[hi], "haze", "0.001",
                               "haze-height", "0,50", "sun", "-0.4,0.35,0.6", "phase", "hg:0.6",
                               "fog-color", "0.2,0.25,0.3", NULL };
        rig_t r;
        rig_open(&r, opts);
        static const double dys[] = { 0, 0.02, 0.3, -0.01 };
        for (size_t k = 0; k < FP_ARRAY_LEN(dys); k++) {
            double o[3] = { 0, 1.5, 0 }, d[3] = { 0.3, dys[k], 1 }, Ss[3], Sg[3];
            unit(d);
            double ts = ray(&r, o, d, INFINITY, Ss);
            /* Geometry far away (for a falling ray: where it meets y = -1e4,
             * deep in fog of optical depth far past the stop). */
            double far = dys[k] < 0 ? 1e4 / -d[1] : 1e7;
            double tg = ray(&r, o, d, far, Sg);
            for (int c = 0; c < 3; c++) {
                double e = fabs(Ss[c] - Sg[c]) / fmax(Ss[c], 1e-3);
                worst = fmax(worst, e);
                if (!(e <= 1e-3))
                    fail_msg("height %s, dy %g: sky S %.8g, far geometry S %.8g", heights[hi],
                             dys[k], Ss[c], Sg[c]);
            }
            assert_true(fabs(ts - tg) <= 1e-6);
        }
        rig_close(&r);
    }
    print_message("sky against geometry far along the same ray: max relative difference of S "
                  "%.3g (tolerance 1e-3)\n", worst);
}

/* Against brute force with the same map: relative error <= 1e-4, with
 * and without a fogmap and self-shadowing. */
static void test_shafts_brute(void **state)
{
    (void)state;
    caster_scene_t s;
    caster_scene(&s, sh_gaps, FP_ARRAY_LEN(sh_gaps), 0.05, sh_pillars, sh_pillar_w1,
                 FP_ARRAY_LEN(sh_pillars));
    static float fmap[24 * 24];
    for (int i = 0; i < 24 * 24; i++)
        fmap[i] = (float)(0.3 + 1.7 * urand());
    static const char *const fm_opts[] = { "fog-rect", "-20,-5,20,60", "basis", "linear",
                                           "levels", "2", NULL };
    struct {
        const char *name, *self;
        int fogmap, rays;
        long steps;
        double tol;
    } cases[] = {
        { "height fog, self-shadowing (closed form)", "exact", 0, 60, 1000000, 1e-4 },
        { "height fog, no self-shadowing", "off", 0, 30, 1000000, 1e-4 },
        { "fogmap, no self-shadowing", "off", 1, 16, 200000, 1e-4 },
        { "fogmap, self-shadowing (carried, the sun's optical depth linear per step)", "exact",
          1, 6, 100000, 1e-4 },
    };
    for (size_t ci = 0; ci < FP_ARRAY_LEN(cases); ci++) {
        const char *extra[16];
        int n = 0;
        extra[n++] = "self-shadow";
        extra[n++] = cases[ci].self;
        for (int i = 0; cases[ci].fogmap && fm_opts[i]; i++)
            extra[n++] = fm_opts[i];
        extra[n] = NULL;
        rig_t r;
        sh_rig(&r, extra, cases[ci].fogmap ? fmap : NULL, 24, 24);
        caster_map(&r, &s, 0.05);
        double worst = 0, smax = 0, got[64], want[64];
        int nr = cases[ci].rays;
        for (int k = 0; k < nr; k++) {
            double o[3], d[3], len;
            sh_ray(&s, k * (60 / nr), 60, o, d, &len);
            want[k] = fp_scatter_sun_brute(&r.sd, &r.fog, o, d, len, cases[ci].steps, NULL, NULL);
            got[k] = shafts_fast(&r, o, d, len);
            smax = fmax(smax, want[k]);
        }
        for (int k = 0; k < nr; k++) {
            double e = fabs(got[k] - want[k]) / fmax(want[k], 1e-2 * smax);
            worst = fmax(worst, e);
            if (!(e <= cases[ci].tol))
                fail_msg("%s, ray %d: %.9g, brute force (%ld steps) %.9g: relative %.3g above %g",
                         cases[ci].name, k, got[k], cases[ci].steps, want[k], e, cases[ci].tol);
        }
        print_message("shafts vs brute force (%ld steps, the same 0.05 m map, %d levels), %s: "
                      "max relative error %.3g over %d rays (tolerance %g)\n", cases[ci].steps,
                      (int)r.sd.lt[FP_LT_SM_LEVELS], cases[ci].name, worst, nr, cases[ci].tol);
        rig_close(&r);
    }
}

/* The ground plane only speeds the walk up (issue 26): with it and without
 * it (the plain min-max of zb) the walk finds the same lit and shadowed
 * runs, so every ray's sun share is the same bit for bit: fans of rays
 * over the thin-caster scene and a 96x48 view toward the wall, maps at
 * 0.05 and 0.2 m, filtered and hard, with and without self-shadowing. */
static void test_shafts_plane(void **state)
{
    (void)state;
    caster_scene_t s;
    caster_scene(&s, sh_gaps, FP_ARRAY_LEN(sh_gaps), 0.05, sh_pillars, sh_pillar_w1,
                 FP_ARRAY_LEN(sh_pillars));
    const int w = 96, h = 48;
    fp_view_t v;
    float *depth = caster_view(&s, w, h, &v);
    long rays = 0;
    double ga = 0, gb = 0;
    for (int ci = 0; ci < 4; ci++) {
        const char *extra[] = { "self-shadow", ci & 1 ? "exact" : "off", "shadow-filter",
                                ci & 2 ? "1" : "0", NULL };
        rig_t r;
        sh_rig(&r, extra, NULL, 0, 0);
        caster_plain = 1;
        caster_map(&r, &s, ci & 2 ? 0.2 : 0.05);
        float *plain = r.sd.smap;
        r.sd.smap = NULL;
        caster_plain = 0;
        caster_map(&r, &s, ci & 2 ? 0.2 : 0.05);
        ga = r.sd.lt[FP_LT_SM_GA];
        gb = r.sd.lt[FP_LT_SM_GB];
        assert_true(fabs(ga) + fabs(gb) > 0);
        for (int k = 0; k < 60 + w * h; k++) {
            double o[3], d[3], len;
            if (k < 60) {
                sh_ray(&s, k, 60, o, d, &len);
            } else {
                int x = (k - 60) % w, y = (k - 60) / w;
                fp_view_ray(&v, x, y, depth[y * w + x], d, &len);
                fp_view_origin_at(&v, x, y, o);
            }
            double with = shafts_fast(&r, o, d, len);
            float *kept = r.sd.smap;
            r.sd.smap = plain;
            r.sd.lt[FP_LT_SM_GA] = r.sd.lt[FP_LT_SM_GB] = 0;
            double without = shafts_fast(&r, o, d, len);
            r.sd.smap = kept;
            r.sd.lt[FP_LT_SM_GA] = ga;
            r.sd.lt[FP_LT_SM_GB] = gb;
            if (memcmp(&with, &without, sizeof with))
                fail_msg("case %d, ray %d: %.17g with the ground plane, %.17g without", ci, k,
                         with, without);
            rays++;
        }
        free(plain);
        rig_close(&r);
    }
    print_message("the walk with the ground plane (ga %.4g, gb %.4g per texel) and without: the "
                  "same sun share bit for bit on %ld rays\n", ga, gb, rays);
    free(depth);
}

/* No lost shaft, no leak: a level ray behind the wall crosses each
 * one-texel gap's shaft, lit over exactly that texel; a level ray behind
 * the pillars is dark over exactly each pillar's texels (one and two
 * wide), lit elsewhere.  Closed forms (height fog at one height is
 * homogeneous), no self-shadowing. */
static void test_shafts_thin(void **state)
{
    (void)state;
    caster_scene_t s;
    caster_scene(&s, sh_gaps, FP_ARRAY_LEN(sh_gaps), 0.05, sh_pillars, sh_pillar_w1,
                 FP_ARRAY_LEN(sh_pillars));
    for (int R = 0; R <= 2; R += 2) {
        char rs[8];
        snprintf(rs, sizeof rs, "%d", R);
        const char *extra[] = { "self-shadow", "off", "height", "0,inf", "shadow-filter", rs,
                                NULL };
        rig_t r;
        sh_rig(&r, extra, NULL, 0, 0);
        caster_map(&r, &s, 0.05);
        double sigma = 0.05, x0 = -17.5, len = 35;
        /* Behind the wall (in its shadow at 1 m): the gaps' shafts. */
        double o[3] = { x0, 1, 35 }, d[3] = { 1, 0, 0 };
        double a[16], bb[16];
        int ng = FP_ARRAY_LEN(sh_gaps);
        for (int i = 0; i < ng; i++) {
            a[i] = sh_gaps[i] - x0;
            bb[i] = a[i] + 0.05;
        }
        double want = lit_sum(sigma, 0, a, bb, ng), got = shafts_fast(&r, o, d, len);
        double e_gap = fabs(got - want) / want;
        /* Behind the pillars: lit but over each pillar's texels. */
        double o2[3] = { x0, 1, 18 };
        int np = FP_ARRAY_LEN(sh_pillars);
        double prev = 0;
        for (int i = 0; i < np; i++) {
            a[i] = prev;
            bb[i] = sh_pillars[i] - x0;
            prev = bb[i] + sh_pillar_w1[i];
        }
        a[np] = prev;
        bb[np] = len;
        double want2 = lit_sum(sigma, 0, a, bb, np + 1), got2 = shafts_fast(&r, o2, d, len);
        double e_pil = fabs(got2 - want2) / want2;
        /* Up through a two-texel pillar's shadow, 1 cm inside its edges:
         * dark all the way, whatever the filter. */
        double o3[3] = { sh_pillars[1] + 0.01, 0.2, 18 }, d3[3] = { 0, 1, 0 };
        double dark = shafts_fast(&r, o3, d3, 1.2);
        double all = lit_sum(sigma, 0, (double[]){ 0 }, (double[]){ 1.2 }, 1);
        print_message("thin casters, --shadow-filter %d: one-texel gaps' shafts %.9g (exact %.9g, "
                      "relative %.2g); behind one- and two-texel pillars %.9g (exact %.9g, "
                      "relative %.2g); up through a two-texel pillar's shadow %.3g of the "
                      "unshadowed %.3g\n", R, got, want, e_gap, got2, want2, e_pil, dark, all);
        double tol = R == 0 ? 1e-6 : 2e-2;
        if (!(e_gap <= tol && e_pil <= tol))
            fail_msg("--shadow-filter %d: relative errors %.3g (gaps), %.3g (pillars) above %g",
                     R, e_gap, e_pil, tol);
        assert_true(dark == 0);
        rig_close(&r);
    }
}

/* The same scene at 0.025, 0.05, 0.1 and 0.2 m texels against the
 * geometry's own visibility: the error shrinks with the texels, and no
 * light leaks behind the wall (0.45 m: more than two texels but at 0.2). */
static void test_shafts_converge(void **state)
{
    (void)state;
    /* The scene: 1.2 m gaps, 0.8 m pillars, off the texel grid. */
    static const double gx[] = { -10.37, -4.63, 1.21, 7.09 };
    static const double px[] = { -8.13, -1.91, 4.33 };
    static const double pw[] = { 0.8, 0.8, 0.8 };
    caster_scene_t s;
    caster_scene(&s, gx, FP_ARRAY_LEN(gx), 1.2, px, pw, FP_ARRAY_LEN(px));
    const double texels[4] = { 0.025, 0.05, 0.1, 0.2 };
    double err[4], leak[4];
    const int nr = 24;
    double want[24];
    rig_t r;
    const char *extra[] = { "self-shadow", "exact", NULL };
    sh_rig(&r, extra, NULL, 0, 0);
    double smax = 0;
    for (int k = 0; k < nr; k++) {
        double o[3], d[3], len;
        sh_ray(&s, k * 2 + 1, 2 * nr, o, d, &len);
        want[k] = fp_scatter_sun_brute(&r.sd, &r.fog, o, d, len, 20000, caster_vis, &s);
        smax = fmax(smax, want[k]);
    }
    for (int ti = 0; ti < 4; ti++) {
        caster_map(&r, &s, texels[ti]);
        double sum = 0, tot = 0;
        for (int k = 0; k < nr; k++) {
            double o[3], d[3], len;
            sh_ray(&s, k * 2 + 1, 2 * nr, o, d, &len);
            sum += fabs(shafts_fast(&r, o, d, len) - want[k]);
            tot += want[k];
        }
        err[ti] = sum / tot;
        /* Behind the wall, between its gaps, 0.1 m and more behind its
         * back: dark. */
        double o[3] = { -2.5, 0.5, 39.6 }, d[3] = { 0, 0.3, -1 };
        unit(d);
        leak[ti] = shafts_fast(&r, o, d, 3);
    }
    print_message("thin casters vs the geometry (24 rays, brute force 20000 steps): mean relative "
                  "error %.3g, %.3g, %.3g, %.3g at 0.025, 0.05, 0.1, 0.2 m texels; behind the "
                  "wall %.3g %.3g %.3g %.3g\n", err[0], err[1], err[2], err[3], leak[0], leak[1],
                  leak[2], leak[3]);
    assert_true(err[0] < err[2] && err[1] < err[3] && err[0] < err[3]);
    assert_true(err[0] < 0.01);
    for (int ti = 0; ti < 4; ti++)
        assert_true(leak[ti] == 0);
    rig_close(&r);
}

/* OpenCL against the C reference on the thin-caster scene: a 96x48 view
 * toward the wall, its depth traced; height fog and a fogmap, filtered
 * and hard, self-shadowing on. */
static void test_shafts_opencl(void **state)
{
    (void)state;
    cl_rig_t cr;
    cl_rig_open(&cr);
    caster_scene_t s;
    caster_scene(&s, sh_gaps, FP_ARRAY_LEN(sh_gaps), 0.05, sh_pillars, sh_pillar_w1,
                 FP_ARRAY_LEN(sh_pillars));
    const int w = 96, h = 48;
    fp_view_t v;
    float *depth = caster_view(&s, w, h, &v);
    float *ref = malloc((size_t)w * h * 4 * sizeof *ref);
    float *got = malloc((size_t)w * h * 4 * sizeof *got);
    static float fmap[24 * 24];
    for (int i = 0; i < 24 * 24; i++)
        fmap[i] = (float)(0.3 + 1.7 * urand());
    static const char *const extra[3][16] = {
        { "self-shadow", "exact", "shadow-filter", "1", "fog-color", "0.1,0.1,0.1", NULL },
        { "self-shadow", "exact", "shadow-filter", "0", "haze", "0.002", "haze-height", "0,40",
          NULL },
        { "self-shadow", "exact", "shadow-filter", "1", "fog-rect", "-20,-5,20,60", "basis",
          "linear", "levels", "2", NULL },
    };
    static const char *const names[3] = { "height fog, filter 1", "height fog and haze, hard",
                                          "fogmap, filter 1" };
    for (int ci = 0; ci < 3; ci++) {
        rig_t r;
        sh_rig(&r, extra[ci], ci == 2 ? fmap : NULL, 24, 24);
        caster_map(&r, &s, 0.05);
        if (ci == 2)
            assert_int_equal(fp_fogmap_frame(&r.p, NULL, &r.fm, 1, &v, &r.fog), FP_OK);
        assert_int_equal(fp_scatter_process(&r.sd, &r.fog, &v, depth, ref), FP_OK);
        assert_int_equal(fp_scatter_process_cl(&cr.scl, &cr.icl, &r.sd, &r.fog, &v, depth, got), FP_OK);
        double max_rel = 0, smax = 0;
        long failures = 0;
        for (int i = 0; i < w * h; i++)
            smax = fmax(smax, ref[4 * i]);
        for (int i = 0; i < w * h * 4; i++) {
            double a = ref[i], b = got[i], e = fabs(b - a);
            max_rel = fmax(max_rel, e / fmax(fabs(a), 1e-2 * smax));
            if (!(e <= fmax(2e-3 * fabs(a), 1e-4)) && failures++ < 5)
                print_message("%s: pixel (%d,%d) ch %d: OpenCL %.7g, C %.7g\n", names[ci],
                              i / 4 % w, i / 4 / w, i % 4, b, a);
        }
        print_message("OpenCL vs C, thin casters, %s (%dx%d): max relative %.3g (S.r up to "
                      "%.3g); tolerance 2e-3 relative or 1e-4\n", names[ci], w, h, max_rel, smax);
        if (failures)
            fail_msg("%s: %ld values outside 2e-3 relative / 1e-4 absolute", names[ci], failures);
        rig_close(&r);
    }
    free(depth);
    free(ref);
    free(got);
    cl_rig_close(&cr);
}

static void test_shafts_screen(void **state)
{
    (void)state;
    caster_scene_t s;
    caster_scene(&s, sh_gaps, FP_ARRAY_LEN(sh_gaps), 0.3, sh_pillars, sh_pillar_w1,
                 FP_ARRAY_LEN(sh_pillars));
    const int w = 160, h = 90;
    fp_view_t v;
    float *depth = caster_view(&s, w, h, &v);
    const char *extra[] = { "shadows", "screen", "screen-shadow", "25,1", "self-shadow",
                            "exact", NULL };
    rig_t r;
    sh_rig(&r, extra, NULL, 0, 0);
    assert_int_equal(fp_scatter_frame(&r.p, &r.sd, &r.fog, &v, depth, 1), FP_OK);
    float view[FP_VIEW_FLOATS];
    fp_view_pack(&v, view);
    screen_vis_t sv = { r.sd.lt, view, r.sd.smap, w, h };
    double worst = 0, smax = 0, got[16], want[16], lit_frac = 0;
    const int nr = 10;
    for (int k = 0; k < nr; k++) {
        /* rows about the horizon: the ground and fog in the wall's shadow */
        int x = 8 + (k * 37) % (w - 16), y = h / 2 - 2 + (k * 3) % 8;
        double d[3], len, o[3], S[3];
        fp_view_ray(&v, x, y, depth[y * w + x], d, &len);
        fp_view_origin_at(&v, x, y, o);
        fp_scatter_ray_at(&r.sd, &r.fog, &v, view, depth, o, d, len, 0, S);
        got[k] = S[0] * 4 * M_PI;
        want[k] = fp_scatter_sun_brute(&r.sd, &r.fog, o, d, len, 20000, screen_vis, &sv);
        /* the same ray without shadows: how much of it the walk darkened */
        double all = fp_scatter_sun_brute(&r.sd, &r.fog, o, d, len, 2000, NULL, NULL);
        lit_frac += want[k] / fmax(all, 1e-30) / nr;
        smax = fmax(smax, want[k]);
    }
    for (int k = 0; k < nr; k++) {
        double e = fabs(got[k] - want[k]) / fmax(want[k], 1e-2 * smax);
        worst = fmax(worst, e);
        if (!(e <= 2e-4))
            fail_msg("--shadows screen, ray %d: %.9g, brute force %.9g: relative %.3g above 2e-4",
                     k, got[k], want[k], e);
    }
    print_message("--shadows screen (the walk over a 160x90 depth buffer) vs brute force (20000 "
                  "steps, the same rule per point): max relative error %.3g over %d rays "
                  "(tolerance 2e-4); the rays keep %.0f%% of their unshadowed light\n", worst,
                  nr, 100 * lit_frac);
    assert_true(lit_frac < 0.95 && lit_frac > 0.05);
    rig_close(&r);
    free(depth);
}

static void test_shafts_map_screen(void **state)
{
    (void)state;
    caster_scene_t s;
    caster_scene(&s, sh_gaps, FP_ARRAY_LEN(sh_gaps), 0.3, sh_pillars, sh_pillar_w1,
                 FP_ARRAY_LEN(sh_pillars));
    const int w = 160, h = 90;
    fp_view_t v;
    float *depth = caster_view(&s, w, h, &v);
    const char *extra[] = { "shadows", "screen", "screen-shadow", "25,1", "self-shadow",
                            "exact", NULL };
    rig_t r;
    sh_rig(&r, extra, NULL, 0, 0);
    assert_int_equal(fp_scatter_frame(&r.p, &r.sd, &r.fog, &v, depth, 1), FP_OK);
    /* The map in place of the depth buffer's pyramid, then both in one
     * buffer as fp_scatter_frame makes them for map+screen. */
    caster_map(&r, &s, 0.4);
    r.sd.lt[FP_LT_SHADOWS] = FP_SHADOWS_MAP_SCREEN;
    assert_int_equal(fp_scatter_screen(&r.sd, &v, depth, 1), FP_OK);
    float view[FP_VIEW_FLOATS];
    fp_view_pack(&v, view);
    screen_vis_t sv = { r.sd.lt, view, r.sd.smap, w, h };
    double worst = 0, smax = 0, got[16], want[16];
    int darker = 0;
    double err_map = 0, err_walk = 0, err_both = 0, sum_ex = 0;
    const int nr = 12;
    for (int k = 0; k < nr; k++) {
        int x = 8 + (k * 37) % (w - 16), y = h / 2 - 2 + (k * 3) % 8;
        double d[3], len, o[3], S[3];
        fp_view_ray(&v, x, y, depth[y * w + x], d, &len);
        fp_view_origin_at(&v, x, y, o);
        fp_scatter_ray_at(&r.sd, &r.fog, &v, view, depth, o, d, len, 0, S);
        got[k] = S[0] * 4 * M_PI;
        want[k] = fp_scatter_sun_brute(&r.sd, &r.fog, o, d, len, 50000, both_vis, &sv);
        double m = fp_scatter_sun_brute(&r.sd, &r.fog, o, d, len, 50000, map_vis, &sv);
        double ss = fp_scatter_sun_brute(&r.sd, &r.fog, o, d, len, 50000, walk_vis, &sv);
        darker += want[k] < (1 - 1e-3) * fmin(m, ss);
        double ex = fp_scatter_sun_brute(&r.sd, &r.fog, o, d, len, 50000, caster_vis, &s);
        err_map += fabs(m - ex);
        err_walk += fabs(ss - ex);
        err_both += fabs(want[k] - ex);
        sum_ex += ex;
        assert_true(want[k] <= fmin(m, ss) * (1 + 1e-9) + 1e-12);
        smax = fmax(smax, want[k]);
    }
    for (int k = 0; k < nr; k++) {
        double e = fabs(got[k] - want[k]) / fmax(want[k], 1e-2 * smax);
        worst = fmax(worst, e);
        if (!(e <= 2e-4))
            fail_msg("--shadows map+screen, ray %d: %.9g, brute force %.9g: relative %.3g above "
                     "2e-4", k, got[k], want[k], e);
    }
    print_message("--shadows map+screen (a 0.4 m map and the walk over a 160x90 depth buffer) vs "
                  "brute force (50000 steps, the product of the point rules): max relative error "
                  "%.3g over %d rays (tolerance 2e-4); %d rays darker than both alone\n", worst,
                  nr, darker);
    assert_true(darker >= 2);
    print_message("against the scene's own visibility (the exact answer, 50000 steps), mean "
                  "|error| over the rays relative to their mean light: map %.4f, walk %.4f, "
                  "map+screen %.4f\n", err_map / sum_ex, err_walk / sum_ex, err_both / sum_ex);
    /* The map loses the thin pillars, the walk what the camera cannot
     * see (measured: 0.0048, 0.0040, 0.0034). */
    assert_true(err_both < err_map && err_both < err_walk);
    /* The kernel: the same buffer on the device. */
    cl_rig_t cr;
    cl_rig_open(&cr);
    float *dev = malloc((size_t)w * h * 4 * sizeof *dev);
    float *ref = malloc((size_t)w * h * 4 * sizeof *ref);
    assert_non_null(dev);
    assert_non_null(ref);
    assert_int_equal(fp_scatter_process(&r.sd, &r.fog, &v, depth, ref), FP_OK);
    assert_int_equal(fp_scatter_process_cl(&cr.scl, &cr.icl, &r.sd, &r.fog, &v, depth, dev),
                     FP_OK);
    double peak = 0, dmax = 0;
    for (int i = 0; i < w * h * 4; i++)
        peak = fmax(peak, fabs(ref[i]));
    for (int i = 0; i < w * h * 4; i++)
        dmax = fmax(dmax, fabs(dev[i] - ref[i]));
    print_message("--shadows map+screen, OpenCL vs the C reference: max difference %.3g of a "
                  "peak %.3g\n", dmax, peak);
    assert_true(dmax <= 1e-3 * peak);
    free(dev);
    free(ref);
    cl_rig_close(&cr);
    rig_close(&r);
    free(depth);
}

int main(int argc, char **argv)
{
    test_argv0 = argv[0];
    /* tests/test_shafts PATTERN (or FP_TEST_FILTER=PATTERN): only the
     * tests whose names match (cmocka's pattern). */
    if (argc > 1)
        cmocka_set_test_filter(argv[1]);
    else if (getenv("FP_TEST_FILTER"))
        cmocka_set_test_filter(getenv("FP_TEST_FILTER"));
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_shadow_map),
        cmocka_unit_test(test_screen_shadows),
        cmocka_unit_test(test_sky_seam),
        cmocka_unit_test(test_shafts_brute),
        cmocka_unit_test(test_shafts_thin),
        cmocka_unit_test(test_shafts_plane),
        cmocka_unit_test(test_shafts_converge),
        cmocka_unit_test(test_shafts_opencl),
        cmocka_unit_test(test_shafts_screen),
        cmocka_unit_test(test_shafts_map_screen),
        /* Last: the random numbers it draws leave the others' as they were. */
        cmocka_unit_test(test_shafts_build_definition),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    remove_scene();
    return rc;
}

/* Every combination of the building blocks a user composes agrees with the
 * exact path: --shadows none / screen / map (and map+screen: plain, and
 * with the fogmap and the lamps) x a fogmap or not x local
 * lamps or not x --fog-resolution 1, 1/2, 1/4 x --blur off / bilateral x
 * OpenCL / the C reference (--cpu), on one small frame of the sample scene
 * (128x72) with a sun, through the pipeline's own frame path (the
 * session of fogpipe_apply: frame_fog, as the command line runs it).
 *
 * Each combination's composite is measured against the exact one of its
 * group (OpenCL, full resolution, no blur) as the reduced-resolution
 * figures are stated (tests/bench_light.c, BENCHMARKS.md): RGB clamped to
 * [0, 1], PSNR (peak 1), and the share of depth-edge pixels (the distance
 * from the camera differs by over 5% from a 4-neighbour's, or sky meets
 * geometry) off by more than 2/255 in some channel.  A blurred reduced
 * frame is also measured against the blurred full-resolution frame (the
 * reduction's own error, which the blur's change of look would hide).
 *
 * The bounds, per what is reduced, over the figures measured on PoCL's CPU
 * device (lowest PSNR, highest edge share over the 12 groups, both
 * devices):
 *   C reference, full resolution:   122.9 dB, 0%     -> >= 100 dB, 0%
 *   1/2 (--fog-edges exact):         63.3 dB, 0.07%  -> >= 55 dB, <= 0.5%
 *   1/4:                             58.9 dB, 0.27%  -> >= 52 dB, <= 1%
 *   1/2, 1/4 blurred, against the blurred full-resolution frame:
 *                                    62.9 dB, 0%     -> the bounds of 1/2, 1/4
 *   --blur bilateral (radius 4) against the exact frame, a change of look:
 *                                    47.2 dB, 11.4%  -> >= 42 dB, <= 15%
 * From 9951d3e until its fix, --shadows screen at reduced resolution
 * walked the half-resolution depth buffer as if it were the frame's at the
 * edge pixels: its rows here were at 1/2 27.8-38.1 dB with 42-53% of the
 * edge pixels off, at 1/4 33.4-46.2 dB, 13-86% (47 of the 4 screen
 * groups' 60 rows out of bounds; every other group within). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "camera.h"
#include "clrt.h"
#include "exrio.h"
#include "fp.h"
#include "options_all.h"
#include "pipeline.h"
#include "session.h"

#include "buffers.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum { W = 128, H = 72 };

typedef struct {
    char dir[4096];
    fp_frame_t *frame;
    float *dist;          /* distance from the camera per pixel (+inf: sky) */
    unsigned char *edge;  /* depth-edge pixels */
    long nedge;
    int have_cl;
} world_t;

static world_t world;

/* A bound: lowest PSNR, highest share of edge pixels off (percent). */
typedef struct {
    const char *what;
    double psnr, edge;
} bound_t;

static const bound_t B_EXACT_C = { "C reference", 100, 0 };
static const bound_t B_HALF = { "1/2", 55, 0.5 };
static const bound_t B_QUARTER = { "1/4", 52, 1.0 };
static const bound_t B_BLUR = { "blur", 42, 15 };

static int make_scene(char *dir, size_t size)
{
    const char *tmp = getenv("FP_TMP");
    snprintf(dir, size, "%s/test_combos", tmp ? tmp : "tests/tmp");
    const char *gen = getenv("FP_SCENE");
    gen = gen ? gen : "samples/fp-scene";
    char cmd[9000];
    snprintf(cmd, sizeof cmd,
             "mkdir -p '%s' && '%s' -o '%s' --width %d --height %d --frames 1-1 "
             "--shadow-size 512 >/dev/null",
             dir, gen, dir, W, H);
    return system(cmd);
}

static int world_setup(void **state)
{
    (void)state;
    if (make_scene(world.dir, sizeof world.dir) != 0) {
        fprintf(stderr, "test_combos: fp-scene did not run (set FP_SCENE)\n");
        return -1;
    }
    char path[4200];
    snprintf(path, sizeof path, "%s/scene.0001.exr", world.dir);
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    if (fp_exr_read_file(path, 1, &sel, &world.frame))
        return -1;
    const fp_frame_info_t *info = fp_frame_info(world.frame);
    if (info->width != W || info->height != H)
        return -1;
    fp_params_t p;
    fp_camera_t cam;
    fp_view_t v;
    if (fp_options_defaults(&p) || fp_camera_resolve(&p, info, path, 1, &cam) ||
        fp_view_setup(&cam, &p, info, &v))
        return -1;
    fp_options_free(&p);
    world.dist = malloc(W * H * sizeof *world.dist);
    world.edge = calloc(W * H, 1);
    if (!world.dist || !world.edge)
        return -1;
    fp_buffers_guide(&v, fp_frame_depth(world.frame), world.dist);
    static const int nb[4][2] = { { 1, 0 }, { -1, 0 }, { 0, 1 }, { 0, -1 } };
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            double d0 = world.dist[y * W + x];
            for (int k = 0; k < 4; k++) {
                int xx = x + nb[k][0], yy = y + nb[k][1];
                if (xx < 0 || yy < 0 || xx >= W || yy >= H)
                    continue;
                double d1 = world.dist[yy * W + xx];
                if (isinf(d0) != isinf(d1) ||
                    (!isinf(d0) && fabs(d0 - d1) > 0.05 * fmin(d0, d1)))
                    world.edge[y * W + x] = 1;
            }
            world.nedge += world.edge[y * W + x];
        }
    fp_cl_t *cl = NULL;
    world.have_cl = fp_cl_open(NULL, &cl) == FP_OK;
    fp_cl_close(cl);
    return 0;
}

static int world_teardown(void **state)
{
    (void)state;
    if (world.frame)
        fp_frame_free(world.frame);
    free(world.dist);
    free(world.edge);
    return 0;
}

/* One group of the matrix: what the frame is made of. */
typedef struct {
    const char *shadows;
    int fogmap, lamps;
} group_t;

/* The composite of the group's look with one combination (cpu, 1/res,
 * blur) into out (W*H*4). */
static int render(const group_t *g, int cpu, int res, int blur, float *out)
{
    char smap[4200], fogmap[4200], resv[8];
    snprintf(smap, sizeof smap, "%s/shadow.%%04d.exr", world.dir);
    snprintf(fogmap, sizeof fogmap, "%s/fogmap.exr", world.dir);
    snprintf(resv, sizeof resv, res > 1 ? "1/%d" : "1", res);
    /* The sun of the half-resolution test (tests/cli.sh) and the shafts'
     * look of bench_light; 16 segments for the sun without shadows (a
     * quarter of the default's time: the path is the same). */
    const char *opts[40] = { "sun", "-0.4,0.35,0.6", "phase", "hg:0.6", "density", "0.05",
                             "height", "0,3,15", "fog-color", "0.03,0.04,0.06",
                             "scatter-steps", "16", "shadows", g->shadows,
                             "fog-resolution", resv };
    int n = 16;
    if (strncmp(g->shadows, "map", 3) == 0) {
        opts[n++] = "shadow-map";
        opts[n++] = smap;
    }
    if (g->fogmap) {
        opts[n++] = "fogmap";
        opts[n++] = fogmap;
        opts[n++] = "fog-rect";
        opts[n++] = "-60,-20,60,160";
    }
    if (g->lamps) {
        /* night-street-lamps' spot light, in view */
        opts[n++] = "light";
        opts[n++] = "spot:0,7,26:0.75,0.85,1.0:200:0,-1,-0.15:15,30";
    }
    if (blur) {
        opts[n++] = "blur";
        opts[n++] = "bilateral";
    }
    if (cpu) {
        opts[n++] = "cpu";
        opts[n++] = "1";
    }
    fp_params_t p;
    int rc = fp_options_defaults(&p);
    for (int k = 0; rc == FP_OK && k < n; k += 2)
        rc = fp_options_apply(&p, opts[k], opts[k + 1], "test_combos");
    fp_session_t *s = NULL;
    if (rc == FP_OK)
        rc = fp_session_open(&p, &s);
    if (rc == FP_OK) {
        memcpy(out, fp_frame_rgba(world.frame), W * H * 4 * sizeof *out);
        rc = fp_session_frame(s, fp_frame_info(world.frame), out, fp_frame_depth(world.frame),
                              "test_combos", 1, NULL, NULL);
    }
    fp_session_close(s);
    fp_options_free(&p);
    return rc;
}

static double clamp01(float v)
{
    return isnan(v) ? 0 : fmin(fmax((double)v, 0), 1);
}

/* got against ref under bound b: one line of figures; returns 1 when out
 * of bounds. */
static int measure(const char *label, const float *ref, const float *got, const bound_t *b)
{
    double se = 0, worst = 0;
    long bad = 0, bad_edge = 0;
    for (int i = 0; i < W * H; i++) {
        double e = 0;
        for (int c = 0; c < 3; c++) {
            double d = fabs(clamp01(got[4 * i + c]) - clamp01(ref[4 * i + c]));
            se += d * d;
            e = fmax(e, d);
        }
        worst = fmax(worst, e);
        bad += e > 2.0 / 255;
        bad_edge += world.edge[i] && e > 2.0 / 255;
    }
    double mse = se / (3.0 * W * H);
    double psnr = mse > 0 ? 10 * log10(1 / mse) : INFINITY;
    double edge = world.nedge ? 100.0 * (double)bad_edge / (double)world.nedge : 0;
    int fail = !(psnr >= b->psnr) || !(edge <= b->edge);
    print_message("%-44s PSNR %6.1f dB (>= %g), edge pixels > 2/255 %5.2f%% (<= %g%%, %s), "
                  "max %.4f, all > 2/255 %.2f%%%s\n",
                  label, psnr, b->psnr, edge, b->edge, b->what, worst,
                  100.0 * (double)bad / (W * H), fail ? "  FAIL" : "");
    return fail;
}

static void run_group(const group_t *g)
{
    float *exact = malloc(W * H * 4 * sizeof *exact);
    float *got = malloc(W * H * 4 * sizeof *got);
    float *blur_full = malloc(W * H * 4 * sizeof *blur_full);
    assert_non_null(exact);
    assert_non_null(got);
    assert_non_null(blur_full);
    char name[64];
    snprintf(name, sizeof name, "shadows %s, %s, %s", g->shadows,
             g->fogmap ? "fogmap" : "no fogmap", g->lamps ? "lamps" : "no lamps");
    clock_t t0 = clock();
    /* The exact path: OpenCL at full resolution (the C reference where no
     * device is). */
    int ref_cpu = !world.have_cl;
    assert_int_equal(render(g, ref_cpu, 1, 0, exact), FP_OK);
    int failures = 0, rows = 0;
    for (int cpu = ref_cpu; cpu <= 1; cpu++)
        for (int blur = 0; blur <= 1; blur++)
            for (int res = 1; res <= 4; res *= 2) {
                if (cpu == ref_cpu && res == 1 && !blur)
                    continue;
                char label[160];
                snprintf(label, sizeof label, "%s | %s %s%s:", name, cpu ? "C" : "OpenCL",
                         res == 1 ? "1" : res == 2 ? "1/2" : "1/4", blur ? " blur" : "");
                assert_int_equal(render(g, cpu, res, blur, got), FP_OK);
                const bound_t *b = blur ? &B_BLUR : res == 2 ? &B_HALF : res == 4 ? &B_QUARTER
                                                                        : &B_EXACT_C;
                failures += measure(label, exact, got, b);
                rows++;
                if (blur && res == 1)
                    memcpy(blur_full, got, W * H * 4 * sizeof *got);
                if (blur && res > 1) {
                    /* The reduction under the blur: against the blurred
                     * full-resolution frame, at the reduction's bound. */
                    snprintf(label, sizeof label, "%s | %s %s blur vs 1 blur:", name,
                             cpu ? "C" : "OpenCL", res == 2 ? "1/2" : "1/4");
                    failures += measure(label, blur_full, got, res == 2 ? &B_HALF : &B_QUARTER);
                    rows++;
                }
            }
    print_message("%s: %d of %d rows out of bounds (%.1f s CPU)\n", name, failures, rows,
                  (double)(clock() - t0) / CLOCKS_PER_SEC);
    free(exact);
    free(got);
    free(blur_full);
    assert_int_equal(failures, 0);
}

#define GROUP(fn, sh, fm, lp)                                                                    \
    static void fn(void **state)                                                                 \
    {                                                                                            \
        (void)state;                                                                             \
        const group_t g = { sh, fm, lp };                                                        \
        run_group(&g);                                                                           \
    }

GROUP(test_none, "none", 0, 0)
GROUP(test_none_lamps, "none", 0, 1)
GROUP(test_none_fogmap, "none", 1, 0)
GROUP(test_none_fogmap_lamps, "none", 1, 1)
GROUP(test_screen, "screen", 0, 0)
GROUP(test_screen_lamps, "screen", 0, 1)
GROUP(test_screen_fogmap, "screen", 1, 0)
GROUP(test_screen_fogmap_lamps, "screen", 1, 1)
GROUP(test_map, "map", 0, 0)
GROUP(test_map_lamps, "map", 0, 1)
GROUP(test_map_fogmap, "map", 1, 0)
GROUP(test_map_fogmap_lamps, "map", 1, 1)
GROUP(test_map_screen, "map+screen", 0, 0)
GROUP(test_map_screen_fogmap_lamps, "map+screen", 1, 1)

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_none),          cmocka_unit_test(test_none_lamps),
        cmocka_unit_test(test_none_fogmap),   cmocka_unit_test(test_none_fogmap_lamps),
        cmocka_unit_test(test_screen),        cmocka_unit_test(test_screen_lamps),
        cmocka_unit_test(test_screen_fogmap), cmocka_unit_test(test_screen_fogmap_lamps),
        cmocka_unit_test(test_map),           cmocka_unit_test(test_map_lamps),
        cmocka_unit_test(test_map_fogmap),    cmocka_unit_test(test_map_fogmap_lamps),
        cmocka_unit_test(test_map_screen),    cmocka_unit_test(test_map_screen_fogmap_lamps),
    };
    return cmocka_run_group_tests(tests, world_setup, world_teardown);
}

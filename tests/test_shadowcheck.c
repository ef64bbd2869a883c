/* The shadow map's check (filters/shadowcheck.h) on synthetic sun depth
 * maps: level ground falling away from the sun down the map (its depth
 * grows 2 texels' worth a row, a sun about 27 degrees up), pillars and
 * walls standing on it in front (toward the sun), slits in a wall, the
 * sky around.  A caster or gap narrower than 8 texels is found with its
 * width, place and length; 8 texels and wider is silent, and so are the
 * tip of a wide object (rows cross it narrowly for a few texels) and a
 * surface seen at a grazing angle (its depth falls fast, but evenly). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "shadowcheck.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { W = 160, H = 120 };
#define TEXEL 0.05
#define SLOPE 2.0                      /* ground depth per texel down the map, texels */
#define STEP (2 * TEXEL * SLOPE)       /* as fp_scatter_frame asks: two texels of ground */

static float map[W * H];

static double ground(int j)
{
    return 50 + j * TEXEL * SLOPE;
}

static void flat(void)
{
    for (int j = 0; j < H; j++)
        for (int i = 0; i < W; i++)
            map[j * W + i] = (float)ground(j);
}

/* A caster toward the sun: texels [x0, x1) x [y0, y1) at `front` scene
 * units before the ground at its top row (so before all the ground it
 * covers). */
static void box(int x0, int x1, int y0, int y1, double front)
{
    for (int j = y0; j < y1; j++)
        for (int i = x0; i < x1; i++)
            map[j * W + i] = (float)(ground(y0) - front);
}

static fp_smap_report_t check(void)
{
    fp_smap_report_t r;
    assert_int_equal(fp_shadowcheck(map, W, H, TEXEL, TEXEL, STEP, &r), 0);
    return r;
}

static void test_thin_pillar(void **state)
{
    (void)state;
    flat();
    box(70, 72, 20, 80, 5);   /* 2 texels (0.1) across, 60 long */
    fp_smap_report_t r = check();
    assert_true(r.caster.found);
    assert_int_equal(r.caster.width, 2);
    assert_true(fabs(r.caster.width_units - 0.1) < 1e-12);
    assert_int_equal(r.caster.axis, 0);
    assert_true(fabs(r.caster.x - 70.5) < 0.5 && fabs(r.caster.y - 50) < 2);
    assert_true(r.caster.length >= 59);
    assert_int_equal(r.caster.count, 1);
    assert_false(r.gap.found);
    /* 8 texels across it: 0.1 / 8 a texel, 4 times the map each way. */
    long nw, nh;
    double need = fp_shadowcheck_needed(&r, &r.caster, &nw, &nh);
    assert_true(fabs(need - 0.0125) < 1e-12);
    assert_int_equal(nw, 4 * W);
    assert_int_equal(nh, 4 * H);
}

static void test_wide_pillar(void **state)
{
    (void)state;
    flat();
    box(70, 82, 20, 80, 5);   /* 12 texels */
    fp_smap_report_t r = check();
    assert_false(r.caster.found);
    assert_false(r.gap.found);
    flat();
    box(70, 78, 20, 80, 5);   /* 8: the width that holds */
    r = check();
    assert_false(r.caster.found);
    flat();
    box(70, 77, 20, 80, 5);   /* 7: under */
    r = check();
    assert_true(r.caster.found);
    assert_int_equal(r.caster.width, 7);
}

/* The thinnest of several, each counted; a pillar before a wall that ends
 * on the wall's own edge is still its own caster. */
static void test_thinnest_of_many(void **state)
{
    (void)state;
    flat();
    box(10, 15, 20, 80, 5);    /* 5 */
    box(30, 33, 20, 80, 5);    /* 3 */
    box(50, 100, 40, 70, 3);   /* a wall */
    box(96, 100, 30, 69, 6);   /* 4, in front of it, its right edge the wall's */
    box(120, 140, 20, 80, 5);  /* 20 */
    fp_smap_report_t r = check();
    assert_true(r.caster.found);
    assert_int_equal(r.caster.width, 3);
    assert_true(fabs(r.caster.x - 31) < 0.5);
    assert_int_equal(r.caster.count, 3);
}

/* Slits in a wall: the sun's light comes through them (a gap), seen as
 * the ground far behind or as nothing (sky). */
static void test_slits(void **state)
{
    (void)state;
    for (int sky = 0; sky < 2; sky++) {
        flat();
        box(10, 150, 20, 80, 8);
        for (int j = 20; j < 80; j++)
            for (int i = 60; i < 62; i++)
                map[j * W + i] = sky ? INFINITY : (float)ground(j);
        fp_smap_report_t r = check();
        assert_false(r.caster.found);
        assert_true(r.gap.found);
        assert_int_equal(r.gap.width, 2);
        assert_true(fabs(r.gap.x - 60.5) < 0.5);
        /* a 10-texel slit: silent */
        for (int j = 20; j < 80; j++)
            for (int i = 62; i < 70; i++)
                map[j * W + i] = sky ? NAN : (float)ground(j);
        r = check();
        assert_false(r.gap.found);
    }
}

/* A pillar against the sky (nothing behind it in the map), 1 texel. */
static void test_sky(void **state)
{
    (void)state;
    for (int k = 0; k < W * H; k++)
        map[k] = INFINITY;
    for (int j = 10; j < 110; j++)
        map[j * W + 40] = 20;
    fp_smap_report_t r = check();
    assert_true(r.caster.found);
    assert_int_equal(r.caster.width, 1);
    /* the sky between pillars is no gap: it is nothing (both sides of
     * the map are open) */
    assert_false(r.gap.found);
}

/* Not casters: the tip of a wide object (a diamond: its rows near the
 * tips are narrow for a few texels) and a surface the sun sees at a
 * grazing angle (its depth changes by 3 steps a texel, evenly). */
static void test_not_thin(void **state)
{
    (void)state;
    flat();
    for (int j = 10; j < 110; j++)
        for (int i = 30; i < 130; i++)
            if (abs(i - 80) + abs(j - 60) <= 45)
                map[j * W + i] = (float)(ground(105) - 6);
    fp_smap_report_t r = check();
    assert_false(r.caster.found);
    assert_false(r.gap.found);
    flat();
    for (int j = 20; j < 100; j++)
        for (int i = 40; i < 52; i++)
            map[j * W + i] = (float)(ground(100) - 10 - 3 * STEP * (i - 40));
    r = check();
    assert_false(r.caster.found);
    assert_false(r.gap.found);
}

/* Along the map's y: a beam across the map, 2 texels tall. */
static void test_axis_y(void **state)
{
    (void)state;
    flat();
    for (int i = 20; i < 140; i++)
        for (int j = 50; j < 52; j++)
            map[j * W + i] = (float)(ground(52) - 6);
    fp_smap_report_t r;
    assert_int_equal(fp_shadowcheck(map, W, H, TEXEL, 2 * TEXEL, STEP, &r), 0);
    assert_true(r.caster.found);
    assert_int_equal(r.caster.width, 2);
    assert_int_equal(r.caster.axis, 1);
    assert_true(fabs(r.caster.width_units - 0.2) < 1e-12);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_thin_pillar),      cmocka_unit_test(test_wide_pillar),
        cmocka_unit_test(test_thinnest_of_many), cmocka_unit_test(test_slits),
        cmocka_unit_test(test_sky),              cmocka_unit_test(test_not_thin),
        cmocka_unit_test(test_axis_y),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

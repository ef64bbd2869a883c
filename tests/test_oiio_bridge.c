/* The OpenImageIO bridge: images are read as data (no color conversion,
 * 8/16-bit integers mapped exactly and linearly to [0,1]), channels by
 * name, rows top to bottom as displayed; previews are written atomically,
 * dithered without banding and byte for byte repeatably; contact sheets
 * tile previews.  Reference images come from oiiotool ($OIIOTOOL, else the
 * one on $PATH); the cases that need it are skipped without it.  Files go
 * to a directory under $FP_TMP (or /tmp) that is removed at the end. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fp.h"
#include "oiio_bridge.h"

static char dir[4096];
static const char *oiiotool_cmd;

/* Exact float comparison that says what differed. */
#define assert_float_same(a, b)                                                         \
    do {                                                                                \
        float a_ = (a), b_ = (b);                                                       \
        if (!(a_ == b_))                                                                \
            fail_msg("%s = %.9g, expected %.9g", #a, (double)a_, (double)b_);           \
    } while (0)

static const char *tpath(const char *name)
{
    /* A few rotating buffers, so that one call can use several paths. */
    static char buf[8][4200];
    static int next;
    char *p = buf[next++ % 8];
    snprintf(p, sizeof buf[0], "%s/%s", dir, name);
    return p;
}

/* Runs oiiotool with `args` (file names relative to the test directory);
 * skips the test when there is no oiiotool. */
static void oiiotool(const char *args)
{
    if (!oiiotool_cmd)
        skip();
    char cmd[4096 * 2];
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s' %s", dir, oiiotool_cmd, args);
    if (system(cmd) != 0)
        fail_msg("failed: %s", cmd);
}

/* Number of entries in the test directory whose name contains ".tmp.". */
static int temporaries(void)
{
    int n = 0;
    DIR *d = opendir(dir);
    struct dirent *e;
    while (d && (e = readdir(d)))
        n += strstr(e->d_name, ".tmp.") != NULL;
    if (d)
        closedir(d);
    return n;
}

static int same_bytes(const char *a, const char *b)
{
    char cmd[9000];
    snprintf(cmd, sizeof cmd, "cmp -s '%s' '%s'", a, b);
    return system(cmd) == 0;
}

static void read_ok(const char *p, const char *ch, float **px, int *w, int *h)
{
    *px = NULL;
    assert_int_equal(fp_oiio_read_channel(p, ch, px, w, h), FP_OK);
    assert_non_null(*px);
}

/* Every 8-bit code written reads back as exactly code / 255.0f (OpenImageIO's
 * own conversion misses half of them), row 0 is the top row, and an RGBA
 * PNG's colour is neither premultiplied on read nor divided on write. */
static void test_png8_is_data(void **state)
{
    (void)state;
    const char *p = tpath("ramp8.png");
    const int w = 256, h = 4;
    float img[256 * 4];
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++)
            img[j * w + i] = (float)i / 255.0f * (j == 0 ? 1.0f : 0.5f);
    assert_int_equal(fp_oiio_write_preview(p, img, w, h, 1, 8, 0), FP_OK);
    assert_int_equal(temporaries(), 0);
    float *got;
    int gw, gh;
    read_ok(p, NULL, &got, &gw, &gh);
    assert_int_equal(gw, w);
    assert_int_equal(gh, h);
    for (int i = 0; i < w; i++)
        assert_float_same(got[i], (float)i / 255.0f);
    assert_float_same(got[128], 128.0f / 255.0f);
    assert_float_same(got[w + 128], 64.0f / 255.0f);   /* 0.5 * 128/255 rounds to 64 */
    free(got);

    /* RGBA with straight alpha 0.25: R 0.8 is stored and read as 204. */
    const char *q = tpath("rgba.png");
    float rgba[4 * 4];
    for (int k = 0; k < 4; k++) {
        rgba[4 * k + 0] = 0.8f;
        rgba[4 * k + 1] = 0.4f;
        rgba[4 * k + 2] = 0.2f;
        rgba[4 * k + 3] = 0.25f;
    }
    assert_int_equal(fp_oiio_write_preview(q, rgba, 2, 2, 4, 8, 0), FP_OK);
    read_ok(q, "R", &got, &gw, &gh);
    assert_float_same(got[3], 204.0f / 255.0f);
    free(got);
    read_ok(q, "A", &got, &gw, &gh);
    assert_float_same(got[0], 64.0f / 255.0f);
    free(got);
}

/* PNGs written by oiiotool (tagged sRGB): 8-bit 128 is 128/255, not
 * linearized; a 16-bit top-to-bottom ramp reads 0 in row 0 and 65535 = 1.0
 * in the last row, every value an exact code / 65535. */
static void test_png_from_oiiotool(void **state)
{
    (void)state;
    oiiotool("--pattern constant:color=0.5 4x2 1 -d uint8 -o half8.png");
    oiiotool("--pattern fill:top=0:bottom=1 64x32 1 -d uint16 -o ramp16.png");
    float *got;
    int w, h;
    read_ok(tpath("half8.png"), "", &got, &w, &h);
    assert_int_equal(w, 4);
    assert_int_equal(h, 2);
    for (int i = 0; i < w * h; i++)
        assert_float_same(got[i], 128.0f / 255.0f);
    free(got);

    read_ok(tpath("ramp16.png"), NULL, &got, &w, &h);
    assert_int_equal(w, 64);
    assert_int_equal(h, 32);
    for (int x = 0; x < w; x++) {
        assert_float_same(got[x], 0.0f);
        assert_float_same(got[(h - 1) * w + x], 1.0f);
    }
    for (int y = 1; y < h; y++) {
        float v = got[y * w], code = roundf(v * 65535.0f);
        assert_true(v > got[(y - 1) * w]);
        assert_float_same(v, code / 65535.0f);
        assert_float_same(got[y * w + w - 1], v);   /* rows are constant */
    }
    free(got);

    /* Our 16-bit writer: 1.0 is 65535, 0.5 rounds to 32768. */
    const char *p = tpath("w16.png");
    float px[3] = { 1.0f, 0.5f, 1000.0f / 65535.0f };
    assert_int_equal(fp_oiio_write_preview(p, px, 3, 1, 1, 16, 0), FP_OK);
    read_ok(p, NULL, &got, &w, &h);
    assert_float_same(got[0], 1.0f);
    assert_float_same(got[1], 32768.0f / 65535.0f);
    assert_float_same(got[2], 1000.0f / 65535.0f);
    free(got);
}

/* Float TIFF: values outside [0,1] come back unclamped, channels by name,
 * rows top to bottom. */
static void test_float_tiff(void **state)
{
    (void)state;
    oiiotool("--pattern fill:top=2.5,-0.75,0.125:bottom=0.5,0.5,0.5 8x4 3 -d float "
             "-o float.tif");
    float *got;
    int w, h;
    read_ok(tpath("float.tif"), NULL, &got, &w, &h);
    assert_int_equal(w, 8);
    assert_int_equal(h, 4);
    assert_float_same(got[0], 2.5f);
    assert_float_same(got[3 * w + 7], 0.5f);
    free(got);
    read_ok(tpath("float.tif"), "G", &got, &w, &h);
    assert_float_same(got[1], -0.75f);
    assert_float_same(got[3 * w], 0.5f);
    free(got);
    read_ok(tpath("float.tif"), "B", &got, &w, &h);
    assert_float_same(got[0], 0.125f);
    assert_float_same(got[2 * w + 3], 0.375f);
    free(got);
}

/* EXR: an RGB half image by channel name, a "density" channel, and a data
 * window smaller than the display window (its pixels are returned). */
static void test_exr(void **state)
{
    (void)state;
    oiiotool("--pattern fill:top=0.25,0.5,0.75:bottom=1,2,4 6x5 3 -d half -o rgb.exr");
    oiiotool("--pattern constant:color=0.1,0.2,0.375 4x2 3 --chnames R,G,density -d float "
             "-o density.exr");
    oiiotool("--pattern constant:color=0.1,0.2,0.3 8x4 3 -d half --origin +2+1 "
             "--fullsize 12x8+0+0 -o window.exr");
    float *got;
    int w, h;
    read_ok(tpath("rgb.exr"), "G", &got, &w, &h);
    assert_int_equal(w, 6);
    assert_int_equal(h, 5);
    assert_float_same(got[0], 0.5f);
    assert_float_same(got[4 * w + 5], 2.0f);
    free(got);
    read_ok(tpath("rgb.exr"), "B", &got, &w, &h);
    assert_float_same(got[4 * w], 4.0f);
    free(got);
    read_ok(tpath("density.exr"), "density", &got, &w, &h);
    assert_float_same(got[7], 0.375f);
    free(got);
    read_ok(tpath("window.exr"), "R", &got, &w, &h);
    assert_int_equal(w, 8);
    assert_int_equal(h, 4);
    assert_float_same(got[31], (float)0x1.998p-4);   /* 0.1 as a half */
    free(got);
}

/* A TIFF's Orientation is applied, for each of the eight: our read of the
 * file equals oiiotool's --autoorient of it.  Orientation 4 (rows stored
 * bottom up) is also checked by hand. */
static void test_orientation(void **state)
{
    (void)state;
    oiiotool("--pattern fill:topleft=0:topright=0.25:bottomleft=0.5:bottomright=1 6x4 1 "
             "-d uint16 -o corner.tif");
    float *ref, *got;
    int rw, rh, w, h;
    read_ok(tpath("corner.tif"), NULL, &ref, &rw, &rh);
    for (int o = 1; o <= 8; o++) {
        char args[512], stored[64], shown[64];
        snprintf(stored, sizeof stored, "orient%d.tif", o);
        snprintf(shown, sizeof shown, "shown%d.tif", o);
        snprintf(args, sizeof args, "corner.tif --orientation %d -o %s", o, stored);
        oiiotool(args);
        snprintf(args, sizeof args, "%s --autoorient -o %s", stored, shown);
        oiiotool(args);
        float *want;
        int ww, wh;
        read_ok(tpath(shown), NULL, &want, &ww, &wh);
        read_ok(tpath(stored), NULL, &got, &w, &h);
        assert_int_equal(w, ww);
        assert_int_equal(h, wh);
        assert_int_equal(w, o <= 4 ? 6 : 4);
        for (int i = 0; i < w * h; i++)
            assert_float_same(got[i], want[i]);
        if (o == 4)
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++)
                    assert_float_same(got[y * w + x], ref[(h - 1 - y) * w + x]);
        free(want);
        free(got);
    }
    free(ref);
}

static void test_read_errors(void **state)
{
    (void)state;
    float *got = (float *)&got;   /* a sentinel: outputs are untouched on failure */
    int w = -7, h = -7;
    assert_int_not_equal(fp_oiio_read_channel(tpath("missing.png"), NULL, &got, &w, &h), FP_OK);
    FILE *f = fopen(tpath("text.png"), "w");
    assert_non_null(f);
    fputs("not an image\n", f);
    fclose(f);
    assert_int_not_equal(fp_oiio_read_channel(tpath("text.png"), NULL, &got, &w, &h), FP_OK);
    f = fopen(tpath("text.dat"), "w");
    assert_non_null(f);
    fputs("not an image either\n", f);
    fclose(f);
    assert_int_not_equal(fp_oiio_read_channel(tpath("text.dat"), NULL, &got, &w, &h), FP_OK);
    assert_int_not_equal(fp_oiio_read_channel(dir, NULL, &got, &w, &h), FP_OK);
    assert_int_not_equal(fp_oiio_read_channel(NULL, NULL, &got, &w, &h), FP_OK);
    float px[3] = { 0.1f, 0.2f, 0.3f };
    assert_int_equal(fp_oiio_write_preview(tpath("rgb.png"), px, 1, 1, 3, 8, 0), FP_OK);
    assert_int_not_equal(fp_oiio_read_channel(tpath("rgb.png"), "density", &got, &w, &h),
                         FP_OK);
    assert_true(got == (float *)&got);
    assert_int_equal(w, -7);
    assert_int_equal(h, -7);
}

static void test_write_errors(void **state)
{
    (void)state;
    float px[4 * 4] = { 0.5f };
    assert_int_not_equal(fp_oiio_write_preview("/nonexistent/dir/x.png", px, 1, 1, 1, 8, 0),
                         FP_OK);
    assert_int_not_equal(fp_oiio_write_preview(tpath("x.nosuchformat"), px, 1, 1, 1, 8, 0),
                         FP_OK);
    assert_int_not_equal(fp_oiio_write_preview(tpath("noextension"), px, 1, 1, 1, 8, 0), FP_OK);
    assert_int_not_equal(fp_oiio_write_preview(tpath("x.png"), px, 1, 1, 2, 8, 0), FP_OK);
    assert_int_not_equal(fp_oiio_write_preview(tpath("x.png"), px, 1, 1, 1, 12, 0), FP_OK);
    assert_int_not_equal(fp_oiio_write_preview(tpath("x.png"), px, 0, 1, 1, 8, 0), FP_OK);
    assert_int_not_equal(fp_oiio_write_preview(tpath("x.png"), NULL, 1, 1, 1, 8, 0), FP_OK);
    /* JPEG holds neither 16 bits nor alpha: said, not silently dropped. */
    assert_int_not_equal(fp_oiio_write_preview(tpath("x.jpg"), px, 1, 1, 1, 16, 0), FP_OK);
    assert_int_not_equal(fp_oiio_write_preview(tpath("x.jpg"), px, 2, 2, 4, 8, 0), FP_OK);
    assert_int_equal(temporaries(), 0);
    assert_int_equal(access(tpath("x.jpg"), F_OK), -1);

    /* A failed write leaves the old file in place. */
    assert_int_equal(fp_oiio_write_preview(tpath("keep.png"), px, 1, 1, 1, 8, 0), FP_OK);
    assert_int_not_equal(fp_oiio_write_preview(tpath("keep.png"), px, 1, 1, 5, 8, 0), FP_OK);
    float *got;
    int w, h;
    read_ok(tpath("keep.png"), NULL, &got, &w, &h);
    assert_float_same(got[0], 128.0f / 255.0f);
    free(got);

    /* JPEG, 8-bit gray: lossy, but close. */
    float gray[16 * 16];
    for (int i = 0; i < 16 * 16; i++)
        gray[i] = 0.25f;
    assert_int_equal(fp_oiio_write_preview(tpath("gray.jpg"), gray, 16, 16, 1, 8, 1), FP_OK);
    read_ok(tpath("gray.jpg"), NULL, &got, &w, &h);
    assert_int_equal(w, 16);
    assert_true(fabsf(got[100] - 0.25f) < 2.5f / 255);
    free(got);
}

/* A ramp too gentle for 8 bits (0.2 to 0.21 over 256 pixels, under three
 * codes): dithered, every pixel is the code just below or just above its
 * value, both codes are used wherever the value lies between them, and each
 * column's mean follows the ramp (no bands), which rounding alone does not
 * do.  Same input, same bytes; 0 and 1 stay exact. */
static void test_dither(void **state)
{
    (void)state;
    const int w = 256, h = 64;
    float *img = malloc(sizeof(float) * w * h);
    assert_non_null(img);
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++)
            img[j * w + i] = 0.2f + 0.01f * i / (w - 1);
    const char *p = tpath("dither.png"), *flat = tpath("flat.png");
    assert_int_equal(fp_oiio_write_preview(p, img, w, h, 1, 8, 1), FP_OK);
    assert_int_equal(fp_oiio_write_preview(flat, img, w, h, 1, 8, 0), FP_OK);
    float *got, *rounded;
    int gw, gh;
    read_ok(p, NULL, &got, &gw, &gh);
    read_ok(flat, NULL, &rounded, &gw, &gh);
    double worst_dithered = 0, worst_rounded = 0;
    for (int i = 0; i < w; i++) {
        double want = img[i] * 255.0, mean = 0, mean_rounded = 0;
        int below = 0, above = 0;
        for (int j = 0; j < h; j++) {
            double code = rint(got[j * w + i] * 255.0);
            assert_true(code == floor(want) || code == ceil(want));
            below += code < want;
            above += code > want;
            mean += code / h;
            mean_rounded += rint(rounded[j * w + i] * 255.0) / h;
        }
        double frac = want - floor(want);
        if (frac > 0.1 && frac < 0.9) {
            assert_true(below > 0);
            assert_true(above > 0);
        }
        worst_dithered = fmax(worst_dithered, fabs(mean - want));
        worst_rounded = fmax(worst_rounded, fabs(mean_rounded - want));
    }
    assert_true(worst_dithered < 0.2);
    assert_true(worst_rounded > 0.4);
    free(rounded);

    /* Deterministic, PNG and TIFF (whose writer would stamp the time). */
    assert_int_equal(fp_oiio_write_preview(tpath("dither2.png"), img, w, h, 1, 8, 1), FP_OK);
    assert_true(same_bytes(p, tpath("dither2.png")));
    assert_int_equal(fp_oiio_write_preview(tpath("d1.tif"), img, w, h, 1, 16, 1), FP_OK);
    sleep(1);
    assert_int_equal(fp_oiio_write_preview(tpath("d2.tif"), img, w, h, 1, 16, 1), FP_OK);
    assert_true(same_bytes(tpath("d1.tif"), tpath("d2.tif")));
    free(got);

    /* 16 bits: within one step.  Black, white and out-of-range stay exact. */
    read_ok(tpath("d1.tif"), NULL, &got, &gw, &gh);
    for (int k = 0; k < w * h; k++)
        assert_true(fabs(got[k] * 65535.0 - img[k] * 65535.0) < 1.0);
    free(got);
    for (int k = 0; k < w * h; k++)
        img[k] = (k % 4 == 0) ? 0.0f : (k % 4 == 1) ? 1.0f : (k % 4 == 2) ? -3.0f : 7.0f;
    assert_int_equal(fp_oiio_write_preview(p, img, w, h, 1, 8, 1), FP_OK);
    read_ok(p, NULL, &got, &gw, &gh);
    for (int k = 0; k < w * h; k++)
        assert_float_same(got[k], (k % 4 == 1 || k % 4 == 3) ? 1.0f : 0.0f);
    free(got);
    free(img);
}

/* Five 6x4 RGB previews in 2 columns: a 12x12 sheet, cells left to right,
 * top to bottom, codes carried exactly, the empty cell black. */
static void test_contact_sheet(void **state)
{
    (void)state;
    const int cw = 6, ch = 4, n = 5;
    char names[5][64];
    const char *paths[5];
    float cell[6 * 4 * 3];
    for (int k = 0; k < n; k++) {
        for (int i = 0; i < cw * ch; i++) {
            cell[3 * i + 0] = (float)(10 * k + 1) / 255.0f;
            cell[3 * i + 1] = (float)(i) / 255.0f;   /* position inside the cell */
            cell[3 * i + 2] = (float)(200 + k) / 255.0f;
        }
        snprintf(names[k], sizeof names[k], "cell%d.png", k);
        paths[k] = strdup(tpath(names[k]));
        assert_int_equal(fp_oiio_write_preview(paths[k], cell, cw, ch, 3, 8, 0), FP_OK);
    }
    const char *sheet = tpath("sheet.png");
    assert_int_equal(fp_oiio_tile_sheet(paths, n, 2, 4096, sheet), FP_OK);
    assert_int_equal(temporaries(), 0);
    float *r, *g;
    int w, h;
    read_ok(sheet, "R", &r, &w, &h);
    read_ok(sheet, "G", &g, &w, &h);
    assert_int_equal(w, 2 * cw);
    assert_int_equal(h, 3 * ch);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            int k = (y / ch) * 2 + x / cw, i = (y % ch) * cw + x % cw;
            float want_r = k < n ? (float)(10 * k + 1) / 255.0f : 0.0f;
            float want_g = k < n ? (float)i / 255.0f : 0.0f;
            assert_float_same(r[y * w + x], want_r);
            assert_float_same(g[y * w + x], want_g);
        }
    free(r);
    free(g);

    /* One column: a tall strip. */
    assert_int_equal(fp_oiio_tile_sheet(paths, 3, 1, 4096, sheet), FP_OK);
    read_ok(sheet, NULL, &r, &w, &h);
    assert_int_equal(w, cw);
    assert_int_equal(h, 3 * ch);
    assert_float_same(r[2 * ch * cw], 21.0f / 255.0f);
    free(r);

    /* 16-bit cells give a 16-bit sheet. */
    float deep[6 * 4];
    for (int i = 0; i < cw * ch; i++)
        deep[i] = 1000.0f / 65535.0f;
    const char *d[2] = { strdup(tpath("deep0.png")), strdup(tpath("deep1.tif")) };
    assert_int_equal(fp_oiio_write_preview(d[0], deep, cw, ch, 1, 16, 0), FP_OK);
    assert_int_equal(fp_oiio_write_preview(d[1], deep, cw, ch, 1, 16, 0), FP_OK);
    assert_int_equal(fp_oiio_tile_sheet(d, 2, 2, 4096, sheet), FP_OK);
    read_ok(sheet, NULL, &r, &w, &h);
    assert_int_equal(w, 2 * cw);
    assert_float_same(r[w * h - 1], 1000.0f / 65535.0f);
    free(r);

    /* A bounded sheet: five 6x4 cells in 2 columns (12x12) at most 6 pixels
     * a side are scaled by 1/2 to 3x2, and a flat cell stays flat. */
    assert_int_equal(fp_oiio_tile_sheet(paths, n, 2, 6, sheet), FP_OK);
    read_ok(sheet, "R", &r, &w, &h);
    assert_int_equal(w, 6);
    assert_int_equal(h, 6);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            int k = (y / 2) * 2 + x / 3;
            assert_float_same(r[y * w + x], k < n ? (float)(10 * k + 1) / 255.0f : 0.0f);
        }
    free(r);
    assert_int_not_equal(fp_oiio_tile_sheet(paths, n, 2, 0, tpath("sheet3.png")), FP_OK);

    /* A cell of another size, or other channels, is named; nothing written. */
    float odd[7 * 4 * 3] = { 0 };
    const char *oddp = strdup(tpath("odd.png"));
    assert_int_equal(fp_oiio_write_preview(oddp, odd, 7, 4, 3, 8, 0), FP_OK);
    const char *mixed[3] = { paths[0], paths[1], oddp };
    const char *out2 = tpath("sheet2.png");
    assert_int_not_equal(fp_oiio_tile_sheet(mixed, 3, 2, 4096, out2), FP_OK);
    const char *gray_rgb[2] = { d[0], paths[0] };
    assert_int_not_equal(fp_oiio_tile_sheet(gray_rgb, 2, 2, 4096, out2), FP_OK);
    const char *missing[2] = { paths[0], tpath("nothere.png") };
    assert_int_not_equal(fp_oiio_tile_sheet(missing, 2, 2, 4096, out2), FP_OK);
    assert_int_not_equal(fp_oiio_tile_sheet(paths, 0, 2, 4096, out2), FP_OK);
    assert_int_not_equal(fp_oiio_tile_sheet(paths, 2, 0, 4096, out2), FP_OK);
    assert_int_equal(access(out2, F_OK), -1);
    assert_int_equal(temporaries(), 0);

    free((void *)oddp);
    free((void *)d[0]);
    free((void *)d[1]);
    for (int k = 0; k < n; k++)
        free((void *)paths[k]);
}

static int setup_group(void **state)
{
    (void)state;
    const char *base = getenv("FP_TMP");
    if (!base || !*base)
        base = "/tmp";
    if (mkdir(base, 0777) != 0 && errno != EEXIST)
        return -1;
    snprintf(dir, sizeof dir, "%s/test_oiio_bridge.XXXXXX", base);
    if (!mkdtemp(dir))
        return -1;
    const char *tool = getenv("OIIOTOOL");
    if (tool && *tool)
        oiiotool_cmd = tool;
    else if (system("command -v oiiotool >/dev/null 2>&1") == 0)
        oiiotool_cmd = "oiiotool";
    return 0;
}

static int teardown_group(void **state)
{
    (void)state;
    char cmd[4200];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_png8_is_data),
        cmocka_unit_test(test_png_from_oiiotool),
        cmocka_unit_test(test_float_tiff),
        cmocka_unit_test(test_exr),
        cmocka_unit_test(test_orientation),
        cmocka_unit_test(test_read_errors),
        cmocka_unit_test(test_write_errors),
        cmocka_unit_test(test_dither),
        cmocka_unit_test(test_contact_sheet),
    };
    return cmocka_run_group_tests(tests, setup_group, teardown_group);
}

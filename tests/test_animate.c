/* Animated fog (filters/animate.c): wind moves a feature of the fog by
 * wind t (both up axes, and the turning rate); still fog costs nothing per
 * frame; the frame-to-frame change under wind is the motion itself
 * (figure printed); fogmap sequences held or blended on the wavelet
 * coefficients; turbulence deterministic, continuous, Kolmogorov-scaled and
 * never negative; advection exact for whole-pixel shifts, MacCormack
 * bounded, and frame N the same whichever frame a run starts at, with or
 * without --cache-dir; per-frame decomposition in OpenCL against C. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "animate.h"
#include "clrt.h"
#include "fogmap.h"
#include "fp.h"
#include "integrate.h"
#include "oiio_bridge.h"
#include "options.h"
#include "testutil.h"
#include "wavelet.h"

#include "fog_core.h"   /* FP_F_* parameter slots */

typedef struct stage_t {
    fp_params_t p;
    fp_fogmap_stage_t s;
    fp_integrate_data_t d;
    fp_view_t view;
    float *img;
    int w, h;
} stage_t;

static char tmpdir[4096];

static void set(fp_params_t *p, const char *name, const char *value)
{
    assert_int_equal(fp_options_apply(p, name, value, "test"), FP_OK);
}

/* A smooth random fogmap >= 0: a few blobs over a floor. */
static float *blobs(int w, int h, double floor_value)
{
    float *img = malloc((size_t)w * h * sizeof *img);
    double cx[5], cy[5], r[5];
    for (int b = 0; b < 5; b++) {
        cx[b] = urand() * w;
        cy[b] = urand() * h;
        r[b] = 2 + urand() * 0.3 * w;
    }
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            double v = floor_value;
            for (int b = 0; b < 5; b++) {
                double dx = i + 0.5 - cx[b], dy = j + 0.5 - cy[b];
                v += exp(-(dx * dx + dy * dy) / (r[b] * r[b]));
            }
            img[(size_t)j * w + i] = (float)v;
        }
    return img;
}

/* Parameters: a 2 x 2 unit pixel fogmap from (-16, -8), a 4-unit layer. */
static void params(fp_params_t *p, int w, int h)
{
    fp_options_defaults(p);
    char rect[128];
    snprintf(rect, sizeof rect, "-16,-8,%g,%g", -16 + 2.0 * w, -8 + 2.0 * h);
    set(p, "fog-rect", rect);
    set(p, "height", "0,inf,4");
    set(p, "density", "0.1");
    set(p, "fogmap", "in-memory");
}

/* Set up (and animate when the options say so) a stage from `img`. */
static void stage_open(stage_t *st, const float *img, int w, int h)
{
    st->w = w;
    st->h = h;
    st->img = malloc((size_t)w * h * sizeof(float));
    memcpy(st->img, img, (size_t)w * h * sizeof(float));
    assert_int_equal(fp_animate_check(&st->p), FP_OK);
    assert_int_equal(fp_integrate_commit(&st->p, &st->d), FP_OK);
    assert_int_equal(fp_fogmap_setup(&st->p, NULL, img, w, h, &st->s, &st->d), FP_OK);
    if (fp_animate_fogmap_animated(&st->p))
        assert_int_equal(fp_fogmap_animate(&st->p, img, w, h, &st->s, &st->d), FP_OK);
    assert_int_equal(make_view(&st->view, 8, 8, 3, -20), 0);
}

static void stage_close(stage_t *st)
{
    fp_fogmap_release(&st->s);
    fp_options_free(&st->p);
    free(st->img);
}

static void frame(stage_t *st, fp_cl_t *cl, long f)
{
    assert_int_equal(fp_fogmap_frame(&st->p, cl, &st->s, f, &st->view, &st->d), FP_OK);
}

/* Optical depth straight down through the layer at fog-space (x, z). */
static double od_down(const stage_t *st, double x, double z)
{
    const double o[3] = { x, 10, z }, dir[3] = { 0, -1, 0 };
    return fp_integrate_optical_depth(&st->d, o, dir, 20, 0);
}

static int same_tables(const fp_fog_tables_t *a, const fp_fog_tables_t *b)
{
    return a->ncoef == b->ncoef && a->nocc == b->nocc &&
           memcmp(a->coef, b->coef, a->ncoef * sizeof(float)) == 0 &&
           memcmp(a->occ, b->occ, a->nocc - 1) == 0;   /* the last byte is padding */
}

static double tables_diff(const fp_fog_tables_t *a, const fp_fog_tables_t *b)
{
    assert_int_equal(a->ncoef, b->ncoef);
    double m = 0;
    for (size_t i = 0; i < a->ncoef; i++)
        m = fmax(m, fabs((double)a->coef[i] - b->coef[i]));
    return m;
}

/* ------------------------------------------------------------ wind */

/* A feature of the fog at world (x, z) at t = 0 is at (x, z) + wind t. */
static void test_wind_moves_the_fog(void **state)
{
    (void)state;
    for (int up = 0; up < 2; up++) {
        stage_t st;
        memset(&st, 0, sizeof st);
        params(&st.p, 24, 16);
        set(&st.p, "up", up ? "z" : "y");
        set(&st.p, "wind", "3,-2");
        set(&st.p, "fps", "25");
        set(&st.p, "fog-offset", "1,0,-2");
        float *img = blobs(24, 16, 0.1);
        stage_open(&st, img, 24, 16);
        const long f = 37;
        const double t = f / 25.0;
        double worst = 0, moved = 0;
        for (int k = 0; k < 60; k++) {
            /* World points (horizontal axes a, b) and their fog coordinates. */
            double a = -14 + 40 * urand(), b = -6 + 24 * urand();
            double w0[3] = { a, 0, b }, w1[3] = { a + 3 * t, 0, b - 2 * t }, f0[3], f1[3];
            if (up) {
                double z0[3] = { a, b, 0 }, z1[3] = { a + 3 * t, b - 2 * t, 0 };
                fp_world_to_fog(FP_UP_Z, z0, f0);
                fp_world_to_fog(FP_UP_Z, z1, f1);
            } else {
                memcpy(f0, w0, sizeof f0);
                memcpy(f1, w1, sizeof f1);
            }
            frame(&st, NULL, 0);
            double before = od_down(&st, f0[0], f0[2]);
            double here = od_down(&st, f1[0], f1[2]);
            frame(&st, NULL, f);
            double after = od_down(&st, f1[0], f1[2]);
            worst = fmax(worst, fabs(after - before) / (before + 1e-3));
            moved = fmax(moved, fabs(here - before));
        }
        print_message("--up %s: a feature moved by wind t: max relative difference %.2e\n",
                      up ? "z" : "y", worst);
        assert_true(worst < 1e-9);
        assert_true(moved > 1e-2);   /* the fog did change where it was */
        free(img);
        stage_close(&st);
    }
}

/* The turning rate: fog-local q is at world offset(t) + R(t) q, R turning
 * counterclockwise seen from above (x towards -z with --up y). */
static void test_wind_turns_the_fog(void **state)
{
    (void)state;
    stage_t st;
    memset(&st, 0, sizeof st);
    params(&st.p, 24, 16);
    set(&st.p, "wind", "2,1,90");
    set(&st.p, "fps", "24");
    set(&st.p, "fog-rotate", "10");
    float *img = blobs(24, 16, 0.1);
    stage_open(&st, img, 24, 16);
    double worst = 0;
    for (int k = 0; k < 40; k++) {
        double qx = -14 + 40 * urand(), qz = -6 + 24 * urand();
        /* At t = 0 the fog is turned by 10 degrees, at t = 1 by 100. */
        double a0 = 10 * M_PI / 180, a1 = 100 * M_PI / 180;
        frame(&st, NULL, 0);
        double before = od_down(&st, cos(a0) * qx + sin(a0) * qz, -sin(a0) * qx + cos(a0) * qz);
        frame(&st, NULL, 24);
        double after = od_down(&st, 2 + cos(a1) * qx + sin(a1) * qz,
                               1 - sin(a1) * qx + cos(a1) * qz);
        worst = fmax(worst, fabs(after - before) / (before + 1e-3));
    }
    print_message("turning wind: max relative difference %.2e\n", worst);
    assert_true(worst < 1e-9);
    free(img);
    stage_close(&st);
}

/* Still fog: nothing changes from frame to frame, not even the tables'
 * serial (no upload, no work); with wind only, the tables stay too. */
static void test_still_costs_nothing(void **state)
{
    (void)state;
    for (int wind = 0; wind < 2; wind++) {
        stage_t st;
        memset(&st, 0, sizeof st);
        params(&st.p, 16, 16);
        if (wind)
            set(&st.p, "wind", "1,1");
        float *img = blobs(16, 16, 0);
        stage_open(&st, img, 16, 16);
        assert_null(st.s.anim);
        unsigned long serial = st.s.tables.serial;
        frame(&st, NULL, 1);
        double fp1[FP_F_COUNT_];
        memcpy(fp1, st.d.fp, sizeof fp1);
        for (long f = 2; f < 6; f++) {
            frame(&st, NULL, f);
            assert_int_equal(st.s.tables.serial, serial);
            assert_true(st.s.animate_ms == 0 && st.s.decompose_ms == 0);
            assert_int_equal(st.s.decompositions, 0);
            if (!wind)
                assert_memory_equal(fp1, st.d.fp, sizeof fp1);
        }
        free(img);
        stage_close(&st);
    }
}

/* Quality: between consecutive frames under wind, the fog seen from above
 * changes by the motion only.  Mean |difference| of the optical depth on a
 * grid, as it is and after undoing the shift (printed). */
static void test_wind_change_is_the_motion(void **state)
{
    (void)state;
    stage_t st;
    memset(&st, 0, sizeof st);
    params(&st.p, 32, 32);
    set(&st.p, "wind", "1.3,0.7");
    set(&st.p, "basis", "cubic");
    float *img = blobs(32, 32, 0.05);
    stage_open(&st, img, 32, 32);
    double raw = 0, undone = 0, mean = 0;
    int n = 0;
    const long f = 100;
    const double dt = 1 / 24.0;
    for (int j = 0; j < 48; j++)
        for (int i = 0; i < 48; i++) {
            double x = -14 + 60.0 * i / 48, z = -6 + 60.0 * j / 48;
            frame(&st, NULL, f);
            double a = od_down(&st, x, z);
            frame(&st, NULL, f + 1);
            double b = od_down(&st, x, z), c = od_down(&st, x + 1.3 * dt, z + 0.7 * dt);
            raw += fabs(b - a);
            undone += fabs(c - a);
            mean += a;
            n++;
        }
    raw /= n;
    undone /= n;
    mean /= n;
    print_message("wind, consecutive frames (optical depth seen from above, mean %.4f): mean "
                  "|diff| %.3e as is, %.3e after undoing the shift\n", mean, raw, undone);
    assert_true(undone < 1e-9 * mean);
    assert_true(raw > 1e-4 * mean);
    free(img);
    stage_close(&st);
}

/* ------------------------------------------------------------ sequences */

static void write_key(const char *dir, long f, const float *img, int w, int h)
{
    char path[4300];
    snprintf(path, sizeof path, "%s/key.%04ld.png", dir, f);
    assert_int_equal(fp_oiio_write_preview(path, img, w, h, 1, 16, 0), FP_OK);
}

static float *read_key(const char *dir, long f, int *w, int *h)
{
    char path[4300];
    float *img;
    snprintf(path, sizeof path, "%s/key.%04ld.png", dir, f);
    assert_int_equal(fp_oiio_read_channel(path, NULL, &img, w, h), FP_OK);
    return img;
}

/* The reference tables of one fogmap image (a still stage). */
static void reference(const char *interp, const float *img, int w, int h, stage_t *ref)
{
    memset(ref, 0, sizeof *ref);
    params(&ref->p, w, h);
    set(&ref->p, "fogmap-interp", interp);
    stage_open(ref, img, w, h);
}

static void test_sequence_keys(void **state)
{
    (void)state;
    char dir[4200];
    snprintf(dir, sizeof dir, "%s/seq", tmpdir);
    mkdir(dir, 0777);
    const int w = 24, h = 16;
    const long keys[3] = { 1, 5, 9 };
    float *k[3];
    for (int i = 0; i < 3; i++) {
        float *img = blobs(w, h, 0.02);
        for (int p = 0; p < w * h; p++)
            img[p] *= 0.4f;   /* within [0, 1] for the 16-bit PNG */
        write_key(dir, keys[i], img, w, h);
        free(img);
        int kw, kh;
        k[i] = read_key(dir, keys[i], &kw, &kh);
    }
    const char *modes[3] = { "hold", "linear", "smooth" };
    for (int m = 0; m < 3; m++) {
        stage_t st;
        memset(&st, 0, sizeof st);
        params(&st.p, w, h);
        char pattern[4300];
        snprintf(pattern, sizeof pattern, "%s/key.####.png", dir);
        set(&st.p, "fogmap", pattern);
        set(&st.p, "fogmap-interp", modes[m]);
        int active;
        assert_int_equal(fp_integrate_commit(&st.p, &st.d), FP_OK);
        assert_int_equal(fp_fogmap_commit(&st.p, NULL, &st.s, &st.d, &active), FP_OK);
        assert_true(active && st.s.anim);
        assert_int_equal(make_view(&st.view, 8, 8, 3, -20), 0);
        for (long f = -2; f <= 12; f++) {
            frame(&st, NULL, f);
            /* The keys around f and the weight the mode gives. */
            int i0 = f < 5 ? 0 : f < 9 ? 1 : 2, i1 = i0;
            double wgt = 0;
            if (m > 0 && f > keys[i0] && i0 < 2) {
                i1 = i0 + 1;
                wgt = (double)(f - keys[i0]) / (keys[i1] - keys[i0]);
                if (m == 2)
                    wgt = wgt * wgt * (3 - 2 * wgt);
            }
            stage_t ref;
            if (wgt == 0) {
                /* A key (or a held one): exactly its own decomposition. */
                reference("linear", k[i0], w, h, &ref);
                if (!same_tables(&st.s.tables, &ref.s.tables))
                    fail_msg("%s, frame %ld: not key %ld's decomposition", modes[m], f,
                             keys[i0]);
            } else {
                /* Blended coefficients = the blended fogmap decomposed
                 * (the decomposition is linear), within float rounding. */
                float *mix = malloc((size_t)w * h * sizeof *mix);
                for (int p = 0; p < w * h; p++)
                    mix[p] = (float)((1 - wgt) * k[i0][p] + wgt * k[i1][p]);
                reference("linear", mix, w, h, &ref);
                double e = tables_diff(&st.s.tables, &ref.s.tables);
                if (!(e < 2e-6))
                    fail_msg("%s, frame %ld: blended coefficients differ by %g", modes[m], f, e);
                free(mix);
            }
            stage_close(&ref);
        }
        /* Held frames reuse the tables: no rebuild between keys. */
        if (m == 0) {
            frame(&st, NULL, 5);
            unsigned long serial = st.s.tables.serial;
            frame(&st, NULL, 6);
            frame(&st, NULL, 8);
            assert_int_equal(st.s.tables.serial, serial);
            assert_int_equal(st.s.decompositions, 0);
        }
        fp_fogmap_release(&st.s);
        fp_options_free(&st.p);
    }
    /* A key of another size is refused, naming it. */
    float *odd = blobs(10, 10, 0);
    for (int p = 0; p < 100; p++)
        odd[p] *= 0.3f;
    write_key(dir, 7, odd, 10, 10);
    free(odd);
    stage_t st;
    memset(&st, 0, sizeof st);
    params(&st.p, w, h);
    char pattern[4300];
    snprintf(pattern, sizeof pattern, "%s/key.%%04d.png", dir);
    set(&st.p, "fogmap", pattern);
    int active;
    assert_int_equal(fp_integrate_commit(&st.p, &st.d), FP_OK);
    assert_int_equal(fp_fogmap_commit(&st.p, NULL, &st.s, &st.d, &active), FP_OK);
    assert_int_equal(make_view(&st.view, 8, 8, 3, -20), 0);
    assert_int_not_equal(fp_fogmap_frame(&st.p, NULL, &st.s, 7, &st.view, &st.d), FP_OK);
    fp_fogmap_release(&st.s);
    fp_options_free(&st.p);
    for (int i = 0; i < 3; i++)
        free(k[i]);
}

/* ------------------------------------------------------------ turbulence */

static void test_turbulence_deterministic_and_continuous(void **state)
{
    (void)state;
    const int w = 32, h = 32;
    float *img = blobs(w, h, 0.05);
    stage_t a, b;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    params(&a.p, w, h);
    params(&b.p, w, h);
    set(&a.p, "turbulence", "0.8");
    set(&b.p, "turbulence", "0.8");
    stage_open(&a, img, w, h);
    stage_open(&b, img, w, h);
    /* Frame 7 directly, or after other frames: the same bits. */
    frame(&a, NULL, 7);
    frame(&b, NULL, 3);
    frame(&b, NULL, 12);
    frame(&b, NULL, 7);
    assert_true(same_tables(&a.s.tables, &b.s.tables));
    assert_true(a.s.decompose_ms > 0 && a.s.animate_ms >= a.s.decompose_ms);
    assert_int_equal(a.s.decompositions, 1);
    /* Another frame, another fog; another seed, another fog. */
    frame(&b, NULL, 8);
    assert_false(same_tables(&a.s.tables, &b.s.tables));
    stage_close(&b);
    memset(&b, 0, sizeof b);
    params(&b.p, w, h);
    set(&b.p, "turbulence", "0.8");
    set(&b.p, "seed", "7");
    stage_open(&b, img, w, h);
    frame(&b, NULL, 7);
    assert_false(same_tables(&a.s.tables, &b.s.tables));
    stage_close(&a);
    stage_close(&b);
    free(img);

    /* Continuous in t: the field's change over dt shrinks with dt (C2 in
     * time, so about linearly). */
    fp_fogmap_t g;
    float *flat = blobs(w, h, 0);
    assert_int_equal(fp_wavelet_decompose(flat, w, h, 1, 3, FP_WRAP_ZERO, &g), FP_OK);
    size_t n = (size_t)g.dom_w * g.dom_h;
    double *f0 = malloc(n * sizeof *f0), *f1 = malloc(n * sizeof *f1);
    double prev = 0;
    for (int e = 0; e < 4; e++) {
        double dt = pow(10, -e);
        assert_int_equal(fp_turbulence_field(&g, 3, 1.0, 2.37, ~0u, f0), FP_OK);
        assert_int_equal(fp_turbulence_field(&g, 3, 1.0, 2.37 + dt, ~0u, f1), FP_OK);
        double m = 0;
        for (size_t i = 0; i < n; i++)
            m = fmax(m, fabs(f1[i] - f0[i]));
        print_message("turbulence: max change over dt = %g s: %.3e\n", dt, m);
        if (e > 0)
            assert_true(m < prev * 0.2);
        prev = m;
    }
    free(f0);
    free(f1);
    free(flat);
    fp_fogmap_free(&g);
}

/* Kolmogorov: with Haar refinement (which keeps every coefficient's
 * value) the RMS of level l is 2^(-5/6 (l-1)) of level 1's, and finer
 * levels change faster, by 2^(2/3) per level. */
static void test_turbulence_spectrum(void **state)
{
    (void)state;
    fp_fogmap_t g;
    float *img = blobs(64, 64, 0);
    assert_int_equal(fp_wavelet_decompose(img, 64, 64, 0, 4, FP_WRAP_REPEAT, &g), FP_OK);
    size_t n = (size_t)g.dom_w * g.dom_h;
    double *f0 = malloc(n * sizeof *f0), *f1 = malloc(n * sizeof *f1);
    double rms[5] = { 0 }, rate[5] = { 0 };
    const double dt = 1e-3;
    for (int l = 1; l <= 4; l++) {
        double s2 = 0, ds = 0;
        int cnt = 0;
        for (int k = 0; k < 40; k++) {
            double t = 0.731 * k;
            assert_int_equal(fp_turbulence_field(&g, 11, 1.0, t, 1u << l, f0), FP_OK);
            assert_int_equal(fp_turbulence_field(&g, 11, 1.0, t + dt, 1u << l, f1), FP_OK);
            for (size_t i = 0; i < n; i++) {
                s2 += f0[i] * f0[i];
                ds += fabs(f1[i] - f0[i]) / dt;
                cnt++;
            }
        }
        rms[l] = sqrt(s2 / cnt);
        rate[l] = ds / cnt / rms[l];
    }
    for (int l = 2; l <= 4; l++) {
        double ra = rms[l] / rms[l - 1], rr = rate[l] / rate[l - 1];
        print_message("turbulence level %d: RMS ratio to level %d %.3f (2^(-5/6) = %.3f), rate "
                      "ratio %.3f (2^(2/3) = %.3f)\n", l, l - 1, ra, pow(2, -5.0 / 6), rr,
                      pow(2, 2.0 / 3));
        assert_true(fabs(ra / pow(2, -5.0 / 6) - 1) < 0.1);
        assert_true(fabs(rr / pow(2, 2.0 / 3) - 1) < 0.15);
    }
    free(f0);
    free(f1);
    free(img);
    fp_fogmap_free(&g);
}

/* Strong turbulence would drive thin fog negative; the clamp on the fine
 * coefficients keeps the density >= 0 everywhere (B-splines are >= 0). */
static void test_turbulence_never_negative(void **state)
{
    (void)state;
    const int w = 32, h = 24;
    for (int degree = 0; degree <= 3; degree++) {
        float *img = blobs(w, h, 0);
        stage_t st;
        memset(&st, 0, sizeof st);
        params(&st.p, w, h);
        set(&st.p, "turbulence", "3");
        st.p.fogmap.basis = degree;
        stage_open(&st, img, w, h);
        fp_animate_frame_t af;
        assert_int_equal(fp_animate_fogmap(st.s.anim, NULL, 5, &af), FP_OK);
        const fp_fogmap_t *m = af.map;
        int clamped = 0;
        for (int i = 0; i < w * h; i++) {
            assert_true(af.img[i] >= 0);
            clamped += af.img[i] == 0 && img[i] > 0;
        }
        double lo = INFINITY, hi = 0;
        for (int k = 0; k < 4000; k++) {
            double U = m->pad_x0 - 2 + (w + 4) * urand(), V = m->pad_y0 - 2 + (h + 4) * urand();
            double f = fp_fogmap_eval(m, U, V, m->levels);
            lo = fmin(lo, f);
            hi = fmax(hi, f);
        }
        print_message("degree %d: turbulent fogmap in [%.3g, %.3g], %d pixels clamped to 0\n",
                      degree, lo, hi, clamped);
        assert_true(clamped > 0);             /* the noise did reach below 0 */
        assert_true(lo > -1e-5 * hi);         /* float rounding of the levels' sum only */
        /* And along rays: no negative optical depth. */
        frame(&st, NULL, 5);
        for (int k = 0; k < 200; k++)
            assert_true(od_down(&st, -16 + 64 * urand(), -8 + 48 * urand()) >= -1e-9);
        free(img);
        stage_close(&st);
    }
}

/* ------------------------------------------------------------ advection */

static void test_advect_steps(void **state)
{
    (void)state;
    const int w = 20, h = 12;
    float *img = blobs(w, h, 0), *out = malloc(w * h * sizeof *out);
    float *tmp = malloc(2 * w * h * sizeof *tmp);
    /* Whole pixels on a periodic map: an exact shift, either scheme. */
    for (int mode = FP_ADVECT_SL; mode <= FP_ADVECT_MACCORMACK; mode++) {
        fp_advect_step(img, w, h, FP_WRAP_REPEAT, mode, 2, -1, out, tmp);
        for (int j = 0; j < h; j++)
            for (int i = 0; i < w; i++)
                assert_true(out[j * w + i] == img[((j + 1) % h) * w + (i + w - 2) % w]);
    }
    /* Fractional steps: MacCormack stays in range and keeps the mass (a
     * periodic map) and is sharper than semi-Lagrangian against the exact
     * shift of a smooth periodic pattern. */
    const double du = 0.37, dv = 0.21;
    const int steps = 20;
    float *a = malloc(w * h * sizeof *a), *b = malloc(w * h * sizeof *b);
    double err[2] = { 0, 0 };
    for (int mode = FP_ADVECT_SL; mode <= FP_ADVECT_MACCORMACK; mode++) {
        for (int j = 0; j < h; j++)
            for (int i = 0; i < w; i++)
                a[j * w + i] = (float)(1 + sin(2 * M_PI * i / w) * cos(2 * M_PI * j / h));
        double mass0 = 0, mass = 0;
        for (int i = 0; i < w * h; i++)
            mass0 += a[i];
        for (int s = 0; s < steps; s++) {
            fp_advect_step(a, w, h, FP_WRAP_REPEAT, mode, du, dv, b, tmp);
            memcpy(a, b, w * h * sizeof *a);
        }
        double e = 0;
        for (int j = 0; j < h; j++)
            for (int i = 0; i < w; i++) {
                double x = i - steps * du, y = j - steps * dv;
                double want = 1 + sin(2 * M_PI * x / w) * cos(2 * M_PI * y / h);
                e = fmax(e, fabs(a[j * w + i] - want));
                mass += a[j * w + i];
                assert_true(a[j * w + i] >= 0 && a[j * w + i] <= 2.0f);
            }
        err[mode - 1] = e;
        print_message("%s: %d steps of (%.2f, %.2f) px: max error %.3f, mass change %.1e\n",
                      mode == FP_ADVECT_SL ? "semi-Lagrangian" : "MacCormack", steps, du, dv, e,
                      fabs(mass - mass0) / mass0);
        if (mode == FP_ADVECT_SL)
            assert_true(fabs(mass - mass0) / mass0 < 1e-5);
    }
    assert_true(err[1] < 0.5 * err[0]);
    /* Zero wrap: the fog leaves and nothing comes in. */
    fp_advect_step(img, w, h, FP_WRAP_ZERO, FP_ADVECT_SL, 3, 0, out, tmp);
    for (int j = 0; j < h; j++)
        for (int i = 0; i < 3; i++)
            assert_true(out[j * w + i] == 0);
    free(img);
    free(out);
    free(tmp);
    free(a);
    free(b);
}

/* Advection by whole pixels through a repeating fogmap is the same fog as
 * the wind moving it: two routes, one fog. */
static void test_advect_matches_wind(void **state)
{
    (void)state;
    const int w = 16, h = 16;
    float *img = blobs(w, h, 0.1);
    stage_t a, b;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    /* 2 units per pixel, 24 fps: 48 units/s is 1 pixel per frame. */
    for (int k = 0; k < 2; k++) {
        stage_t *st = k ? &b : &a;
        params(&st->p, w, h);
        set(&st->p, "fog-wrap", "repeat");
        set(&st->p, "wind", "48,-96");
        set(&st->p, "advect-start", "0");
        if (k)
            set(&st->p, "advect", "semi-lagrangian");
        stage_open(st, img, w, h);
    }
    double worst = 0;
    for (long f = 0; f < 6; f++) {
        frame(&a, NULL, f);
        frame(&b, NULL, f);
        for (int k = 0; k < 50; k++) {
            double x = -30 + 80 * urand(), z = -30 + 80 * urand();
            double oa = od_down(&a, x, z), ob = od_down(&b, x, z);
            worst = fmax(worst, fabs(oa - ob) / (oa + 1e-3));
        }
    }
    print_message("advection by whole pixels vs the wind's offset: max relative difference "
                  "%.2e\n", worst);
    assert_true(worst < 1e-5);
    stage_close(&a);
    stage_close(&b);
    free(img);
}

static int count_states(const char *dir)
{
    DIR *d = opendir(dir);
    int n = 0;
    struct dirent *e;
    while (d && (e = readdir(d)))
        n += strstr(e->d_name, ".state") && !strstr(e->d_name, ".tmp.");
    if (d)
        closedir(d);
    return n;
}

/* Frame N is the same whether the run starts at 1 or at N, with or
 * without the cache, and whatever order frames come in. */
static void test_advect_start_independent(void **state)
{
    (void)state;
    const int w = 24, h = 20;
    float *img = blobs(w, h, 0.02);
    char cache[4200];
    snprintf(cache, sizeof cache, "%s/advect-cache", tmpdir);
    const char *modes[2] = { "semi-lagrangian", "maccormack" };
    for (int m = 0; m < 2; m++) {
        stage_t run[4];
        for (int r = 0; r < 4; r++) {
            memset(&run[r], 0, sizeof run[r]);
            params(&run[r].p, w, h);
            set(&run[r].p, "wind", "5.5,-3.25");
            set(&run[r].p, "fog-rotate", "20");
            set(&run[r].p, "advect", modes[m]);
            set(&run[r].p, "fog-wrap", m ? "clamp" : "zero");
            if (r >= 2)
                set(&run[r].p, "cache-dir", cache);
            stage_open(&run[r], img, w, h);
        }
        /* Run 0 from frame 1 to 21; run 1 starts at 21; run 2 fills the
         * cache on the way to 21, run 3 starts at 21 from it. */
        for (long f = 1; f <= 21; f++)
            frame(&run[0], NULL, f);
        frame(&run[1], NULL, 21);
        assert_true(same_tables(&run[0].s.tables, &run[1].s.tables));
        for (long f = 1; f <= 21; f += 4)
            frame(&run[2], NULL, f);
        assert_true(same_tables(&run[0].s.tables, &run[2].s.tables));
        assert_true(count_states(cache) >= 2 * (m + 1));
        frame(&run[3], NULL, 21);
        assert_true(same_tables(&run[0].s.tables, &run[3].s.tables));
        /* Backwards in a run, and before the start: the fogmap itself. */
        frame(&run[1], NULL, 4);
        frame(&run[0], NULL, 4);
        assert_true(same_tables(&run[0].s.tables, &run[1].s.tables));
        frame(&run[1], NULL, -5);
        stage_t ref;
        reference("linear", img, w, h, &ref);
        ref.p.fogmap.wrap = run[1].p.fogmap.wrap;
        fp_fogmap_release(&ref.s);
        assert_int_equal(fp_fogmap_setup(&ref.p, NULL, img, w, h, &ref.s, &ref.d), FP_OK);
        assert_true(same_tables(&run[1].s.tables, &ref.s.tables));
        stage_close(&ref);
        for (int r = 0; r < 4; r++)
            stage_close(&run[r]);
    }
    /* A damaged cache file is ignored, not trusted. */
    DIR *d = opendir(cache);
    struct dirent *e;
    while (d && (e = readdir(d)))
        if (strstr(e->d_name, ".state")) {
            char path[4500];
            snprintf(path, sizeof path, "%s/%s", cache, e->d_name);
            FILE *f = fopen(path, "r+b");
            fseek(f, 200, SEEK_SET);
            fputc(0x55, f);
            fclose(f);
        }
    if (d)
        closedir(d);
    stage_t a, b;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    for (int k = 0; k < 2; k++) {
        stage_t *st = k ? &b : &a;
        params(&st->p, w, h);
        set(&st->p, "wind", "5.5,-3.25");
        set(&st->p, "fog-rotate", "20");
        set(&st->p, "advect", "semi-lagrangian");
        if (k)
            set(&st->p, "cache-dir", cache);
        stage_open(st, img, w, h);
    }
    frame(&a, NULL, 18);
    frame(&b, NULL, 18);
    assert_true(same_tables(&a.s.tables, &b.s.tables));
    stage_close(&a);
    stage_close(&b);
    free(img);
}

/* ------------------------------------------------------------ OpenCL, checks */

static void test_opencl_per_frame(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    if (fp_cl_open(NULL, &cl) != FP_OK) {
        print_message("no OpenCL device: skipped\n");
        skip();
    }
    const int w = 48, h = 40;
    float *img = blobs(w, h, 0.05);
    stage_t a, b;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    for (int k = 0; k < 2; k++) {
        stage_t *st = k ? &b : &a;
        params(&st->p, w, h);
        set(&st->p, "turbulence", "0.5");
        set(&st->p, "basis", "quadratic");
        stage_open(st, img, w, h);
    }
    for (long f = 1; f <= 3; f++) {
        frame(&a, cl, f);
        frame(&b, NULL, f);
        assert_true(a.s.used_cl);
        double e = tables_diff(&a.s.tables, &b.s.tables);
        print_message("frame %ld: decomposed in %.2f ms (OpenCL) / %.2f ms (C), max |coef "
                      "difference| %.1e\n", f, a.s.decompose_ms, b.s.decompose_ms, e);
        assert_true(e < 1e-5);
    }
    stage_close(&a);
    stage_close(&b);
    free(img);
    fp_cl_close(cl);
}

static void test_usage(void **state)
{
    (void)state;
    fp_params_t p;
    fp_options_defaults(&p);
    set(&p, "turbulence", "1");
    fp_quiet = 1;
    assert_int_equal(fp_animate_check(&p), FP_EUSAGE);
    fp_options_free(&p);
    fp_options_defaults(&p);
    set(&p, "advect", "maccormack");
    assert_int_equal(fp_animate_check(&p), FP_EUSAGE);
    set(&p, "fogmap", "fog.####.png");
    assert_int_equal(fp_animate_check(&p), FP_EUSAGE);
    set(&p, "fogmap", "fog.png");
    assert_int_equal(fp_animate_check(&p), FP_OK);
    assert_true(fp_animate_fogmap_animated(&p));
    fp_options_free(&p);
    fp_options_defaults(&p);
    assert_int_not_equal(fp_options_apply(&p, "wind", "1", "test"), FP_OK);
    assert_int_not_equal(fp_options_apply(&p, "fps", "0", "test"), FP_OK);
    assert_int_not_equal(fp_options_apply(&p, "fogmap-interp", "cubic", "test"), FP_OK);
    fp_quiet = 0;
    fp_options_free(&p);
}

int main(void)
{
    const char *t = getenv("FP_TMP");
    snprintf(tmpdir, sizeof tmpdir, "%s/test_animate", t ? t : "tests/tmp");
    mkdir(t ? t : "tests/tmp", 0777);
    mkdir(tmpdir, 0777);
    char cmd[4300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'/*", tmpdir);
    if (system(cmd) != 0)
        return 1;
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_wind_moves_the_fog),
        cmocka_unit_test(test_wind_turns_the_fog),
        cmocka_unit_test(test_still_costs_nothing),
        cmocka_unit_test(test_wind_change_is_the_motion),
        cmocka_unit_test(test_sequence_keys),
        cmocka_unit_test(test_turbulence_deterministic_and_continuous),
        cmocka_unit_test(test_turbulence_spectrum),
        cmocka_unit_test(test_turbulence_never_negative),
        cmocka_unit_test(test_advect_steps),
        cmocka_unit_test(test_advect_matches_wind),
        cmocka_unit_test(test_advect_start_independent),
        cmocka_unit_test(test_opencl_per_frame),
        cmocka_unit_test(test_usage),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

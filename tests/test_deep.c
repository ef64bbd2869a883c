/* Unit tests of the deep stage (filters/deep.h) and the deep EXR codec
 * (src/exr/exr_deep.h): the split rule, tidying, the fog's samples against the
 * fog of a ray ending at any depth (the bound), and deep images written
 * and read back in every codec deep files allow. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "deep.h"
#include "exr_deep.h"
#include "fp.h"
#include "options.h"
#include "testutil.h"

#include <openexr.h>

static fp_dsample_t vol(double z, double zb, double a, double c)
{
    fp_dsample_t s = { z, zb, { c, 0.5 * c, 0.25 * c }, a, FP_DEEP_SRC_FOG };
    return s;
}

/* OpenEXR's split rule: the front part of a homogeneous sample, and the
 * two parts composited give the whole sample back. */
static void test_split(void **state)
{
    (void)state;
    fp_dsample_t s = vol(10, 20, 0.6, 0.3), f;
    fp_deep_split_front(&s, 12.5, &f);
    assert_double_equal(f.a, 1 - pow(0.4, 0.25), 1e-12);
    assert_double_equal(f.c[0], 0.3 * f.a / 0.6, 1e-12);
    assert_double_equal(f.zb, 12.5, 0);
    /* front then back (the same rule for the rest) == the whole */
    fp_dlist_t l = { NULL, 0, 0 };
    fp_dsample_t cut = { 12.5, 12.5, { 0, 0, 0 }, 0, FP_DEEP_SRC_PLATE };
    assert_int_equal(fp_dlist_push(&l, &s), FP_OK);
    assert_int_equal(fp_dlist_push(&l, &cut), FP_OK);
    assert_int_equal(fp_deep_tidy(&l), FP_OK);
    assert_int_equal(l.n, 3);
    double whole[4], parts[4];
    fp_deep_flatten(&s, 1, INFINITY, whole);
    fp_deep_flatten(l.s, l.n, INFINITY, parts);
    for (int c = 0; c < 4; c++)
        assert_double_equal(whole[c], parts[c], 1e-12);
    /* alpha 0: colour in proportion to the range */
    fp_dsample_t e = vol(0, 4, 0, 1);
    fp_deep_split_front(&e, 1, &f);
    assert_double_equal(f.c[0], 0.25, 1e-12);
    fp_dlist_free(&l);
}

/* Tidy: overlapping volumes split at each other's boundaries and the
 * coincident pieces combined (optical depths add): sorted, apart, and the
 * transmittance of the whole is the product. */
static void test_tidy(void **state)
{
    (void)state;
    fp_dlist_t l = { NULL, 0, 0 };
    fp_dsample_t a = vol(5, 15, 0.5, 0.2), b = vol(10, 30, 0.3, 0.1), p = vol(12, 12, 0.2, 0.05);
    assert_int_equal(fp_dlist_push(&l, &b), FP_OK);
    assert_int_equal(fp_dlist_push(&l, &a), FP_OK);
    assert_int_equal(fp_dlist_push(&l, &p), FP_OK);
    assert_int_equal(fp_deep_tidy(&l), FP_OK);
    for (size_t k = 1; k < l.n; k++) {
        assert_true(l.s[k - 1].z <= l.s[k].z);
        assert_true(l.s[k - 1].zb <= l.s[k].z || l.s[k - 1].z == l.s[k - 1].zb);
    }
    double rgba[4];
    fp_deep_flatten(l.s, l.n, INFINITY, rgba);
    assert_double_equal(1 - rgba[3], 0.5 * 0.7 * 0.8, 1e-12);
    fp_dlist_free(&l);
}

static fp_integrate_data_t height_fog(double sigma, double y0, double H, double top)
{
    fp_params_t p;
    fp_integrate_data_t d;
    fp_options_defaults(&p);
    p.fog.density = sigma;
    p.fog.height[0] = y0;
    p.fog.height[1] = H;
    p.fog.height[2] = top;
    p.fog.color[0] = 0.7;
    p.fog.color[1] = 0.8;
    p.fog.color[2] = 0.9;
    assert_int_equal(fp_integrate_commit(&p, &d), FP_OK);
    fp_options_free(&p);
    return d;
}

/* The bound: for rays of a wide view through height fog (thick, thin,
 * with a top), an opaque element of colour E merged at any depth z into
 * the pixel's fog samples gives S(z) + tau(z) E of the ray ending at z
 * within --deep-bound times max(1, S); and the samples to the end give the
 * whole ray exactly.  The bound is not met by the samples of a ray cut
 * to a few samples (so the check can fail). */
static void test_bound(void **state)
{
    (void)state;
    const double fogs[3][4] = { { 0.05, 0, 8, INFINITY }, { 0.3, 2, INFINITY, 6 },
                                { 0.01, -1, 3, 40 } };
    fp_params_t p;
    fp_options_defaults(&p);
    p.deep.deep = 1;
    fp_deep_data_t dd;
    assert_int_equal(fp_deep_commit(&p, &dd), FP_OK);
    fp_options_free(&p);
    double worst = 0, worst_capped = 0;
    long samples = 0, rays = 0;
    for (int fi = 0; fi < 3; fi++) {
        fp_view_t v;
        assert_int_equal(make_view(&v, 9, 7, 1.5, -8), 0);
        fp_integrate_data_t fog = height_fog(fogs[fi][0], fogs[fi][1], fogs[fi][2], fogs[fi][3]);
        for (int cap = 0; cap < 2; cap++) {
            fp_deep_data_t d2 = dd;
            if (cap)
                d2.max_samples = 2;
            fp_deep_fog_t f = { &d2, &fog, NULL, &v, NULL };
            for (int y = 0; y < v.height; y++)
                for (int x = 0; x < v.width; x++) {
                    fp_dlist_t l = { NULL, 0, 0 };
                    fp_deep_stats_t st;
                    memset(&st, 0, sizeof st);
                    assert_int_equal(fp_deep_fog_pixel(&f, x, y, INFINITY, NULL, 0, &l, &st),
                                     FP_OK);
                    double k = fp_deep_ray_scale(&v, x, y), dir[3], o[3], len;
                    fp_view_ray(&v, x, y, 1.0f, dir, &len);
                    fp_view_origin_at(&v, x, y, o);
                    double all[4];
                    fp_deep_flatten(l.s, l.n, INFINITY, all);
                    double tau_inf = exp(-fp_integrate_optical_depth(&fog, o, dir, INFINITY, 0));
                    if (!cap)
                        assert_double_equal(1 - all[3], tau_inf, 1e-9);
                    double smax = fmax(1, fog.fog_color[2] * (1 - tau_inf));
                    for (double z = 0.05; z < 2000; z *= 1.13) {
                        double cut[4];
                        fp_deep_flatten(l.s, l.n, z, cut);
                        double tau = exp(-fp_integrate_optical_depth(&fog, o, dir, z * k, 0));
                        for (int c = 0; c < 3; c++) {
                            double S = (1 - tau) * fog.fog_color[c], E = 0.2 + 0.3 * c;
                            double e = fabs(cut[c] + (1 - cut[3]) * E - (S + tau * E)) / smax;
                            if (cap)
                                worst_capped = fmax(worst_capped, e);
                            else
                                worst = fmax(worst, e);
                        }
                    }
                    if (!cap) {
                        samples += (long)l.n;
                        rays++;
                    }
                    fp_dlist_free(&l);
                }
        }
    }
    print_message("# deep bound: worst %.3g (bound %g), %.2f samples a ray; 2 samples: %.3g\n",
                  worst, dd.bound, (double)samples / rays, worst_capped);
    assert_true(worst <= dd.bound);
    assert_true(worst_capped > dd.bound);
}

/* A deep image with a HALF, a FLOAT and a UINT channel, written in each
 * codec deep files allow and read back value for value. */
static void test_codec(void **state)
{
    (void)state;
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.width = info.disp_w = 37;
    info.height = info.disp_h = 5;
    info.pixel_aspect = 1;
    fp_deep_chan_t ch[7] = { { "R", 2 }, { "G", 2 }, { "B", 2 }, { "A", 2 },
                             { "Z", 2 }, { "ZBack", 2 }, { "id", 0 } };
    fp_deep_image_t *d = NULL;
    assert_int_equal(fp_deep_alloc(&info, ch, 7, &d), FP_OK);
    uint32_t counts[37 * 5];
    for (int i = 0; i < 37 * 5; i++)
        counts[i] = (uint32_t)(i % 7 == 3 ? 40 : i % 5);   /* runs for RLE, empty pixels */
    assert_int_equal(fp_deep_alloc_samples(d, counts), FP_OK);
    for (uint64_t k = 0; k < d->total; k++)
        for (int c = 0; c < 7; c++) {
            float v = c == 4 ? (float)k : c == 5 ? (float)k + 0.5f : (float)(k % 13) * 0.125f;
            if (c == 6)
                d->data[c][k] = (uint32_t)(k * 2654435761u);
            else
                memcpy(&d->data[c][k], &v, 4);
        }
    const int comps[3] = { EXR_COMPRESSION_NONE, EXR_COMPRESSION_RLE, EXR_COMPRESSION_ZIPS };
    for (int ci = 0; ci < 3; ci++) {
        fp_exr_write_opts_t o = FP_EXR_WRITE_OPTS_INITIALIZER;
        o.compression = comps[ci];
        void *buf = NULL;
        size_t size = 0;
        assert_int_equal(fp_deep_encode(d, NULL, &o, "codec.exr", 1, &buf, &size), FP_OK);
        assert_true(fp_exr_is_deep(buf, size));
        fp_deep_image_t *r = NULL;
        assert_int_equal(fp_deep_read_memory(buf, size, "codec.exr", 1, &r), FP_OK);
        assert_int_equal(r->info.compression, comps[ci]);
        assert_int_equal(r->total, d->total);
        for (size_t i = 0; i < d->npix; i++)
            assert_int_equal(r->counts[i], d->counts[i]);
        for (int c = 0; c < 7; c++) {
            int rc = -1;
            for (int e = 0; e < r->nchan; e++)
                if (strcmp(r->chans[e].name, ch[c].name) == 0)
                    rc = e;
            assert_true(rc >= 0);
            assert_memory_equal(r->data[rc], d->data[c], d->total * 4);
        }
        fp_deep_free(r);
    }
    /* codecs deep files do not allow are refused */
    fp_exr_write_opts_t o = FP_EXR_WRITE_OPTS_INITIALIZER;
    o.compression = EXR_COMPRESSION_PIZ;
    void *buf = NULL;
    size_t size = 0;
    assert_int_not_equal(fp_deep_encode(d, NULL, &o, "codec.exr", 1, &buf, &size), FP_OK);
    fp_deep_free(d);
}

int main(void)
{
    fp_quiet = 1;
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_split),
        cmocka_unit_test(test_tidy),
        cmocka_unit_test(test_bound),
        cmocka_unit_test(test_codec),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* Color management and fog layers: fogpipe's OpenColorIO config validates
 * and has what the README promises; round trips between every pair of its
 * color spaces within 1e-4; a grey stays grey in every space and on the
 * display; alpha is never touched; chromaticities identify the spaces and
 * the spaces give back their chromaticities; the stage's checks of names;
 * the fog layers merged "over" the plate equal the composite, with and
 * without conversions. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "aov.h"
#include "color.h"
#include "composite.h"
#include "fp.h"
#include "ocio_bridge.h"
#include "options.h"
#include "preview.h"
#include "testutil.h"

static char config_path[4096];

static const char *config(void)
{
    const char *src = getenv("FP_SRCDIR");
    snprintf(config_path, sizeof config_path, "%s/samples/ocio/config.ocio", src ? src : ".");
    return config_path;
}

static fp_ocio_t *open_config(void)
{
    fp_ocio_t *c = NULL;
    assert_int_equal(fp_ocio_open(config(), &c), FP_OK);
    assert_non_null(c);
    return c;
}

/* The scene-referred color spaces of the config, linear ones first. */
static const char *const linear_spaces[] = { "lin_rec709", "ACEScg", "ACES2065-1" };
#define NLIN 3

static void test_config_validates(void **state)
{
    fp_ocio_t *c = open_config();
    char name[256], d[256], v[256];
    /* What the README and the issue promise. */
    static const char *const want[][2] = {
        { "lin_rec709", "Linear Rec.709 (sRGB)" }, { "acescg", "ACEScg" },
        { "ACES2065-1", "ACES2065-1" }, { "scene_linear", "Linear Rec.709 (sRGB)" },
        { "data", "Raw" }, { "aces_interchange", "ACES2065-1" },
    };
    for (size_t i = 0; i < FP_ARRAY_LEN(want); i++) {
        assert_int_equal(fp_ocio_space(c, want[i][0], "test", name, sizeof name), FP_OK);
        assert_string_equal(name, want[i][1]);
    }
    assert_int_equal(fp_ocio_is_data(c, "Raw"), 1);
    assert_int_equal(fp_ocio_is_data(c, "ACEScg"), 0);
    assert_int_equal(fp_ocio_display_view(c, NULL, NULL, d, sizeof d, v, sizeof v), FP_OK);
    assert_string_equal(d, "sRGB");
    assert_string_equal(v, "Standard");
    assert_int_equal(fp_ocio_display_view(c, "srgb", "aces 1.0 - sdr video", d, sizeof d, v,
                                          sizeof v), FP_OK);
    assert_string_equal(v, "ACES 1.0 - SDR Video");
    assert_int_equal(fp_ocio_space(c, "no such space", "test", name, sizeof name), FP_EUSAGE);
    assert_int_equal(fp_ocio_display_view(c, "P3", NULL, d, sizeof d, v, sizeof v), FP_EUSAGE);
    assert_int_equal(fp_ocio_display_view(c, NULL, "Filmic", d, sizeof d, v, sizeof v),
                     FP_EUSAGE);
    /* Every space of the config makes a processor to every other. */
    int n = fp_ocio_num_spaces(c);
    assert_true(n >= 6);
    for (int i = 0; i < n; i++)
        for (int k = 0; k < n; k++) {
            fp_ocio_proc_t *p = NULL;
            assert_int_equal(fp_ocio_processor(c, fp_ocio_space_name(c, i),
                                               fp_ocio_space_name(c, k), &p), FP_OK);
            fp_ocio_proc_free(p);
        }
    fp_ocio_close(c);
}

static void test_config_errors(void **state)
{
    fp_ocio_t *c = NULL;
    assert_int_not_equal(fp_ocio_open("/nonexistent/config.ocio", &c), FP_OK);
    assert_null(c);
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s/fp_test_color.%ld.ocio",
             getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp", (long)getpid());
    FILE *f = fopen(tmp, "w");
    assert_non_null(f);
    fputs("ocio_profile_version: 2\nroles: {scene_linear: nothing}\ncolorspaces: [oops\n", f);
    fclose(f);
    assert_int_not_equal(fp_ocio_open(tmp, &c), FP_OK);
    assert_null(c);
    remove(tmp);
}

static void test_find_config(void **state)
{
    char path[4096];
    const char *origin = NULL;
    char *saved = getenv("OCIO") ? strdup(getenv("OCIO")) : NULL;
    unsetenv("OCIO");
    /* fogpipe's own: this test runs from the build tree. */
    assert_int_equal(fp_ocio_find_config(NULL, path, sizeof path, &origin), FP_OK);
    assert_string_equal(origin, "fogpipe's config");
    assert_non_null(strstr(path, "config.ocio"));
    fp_ocio_t *c = NULL;
    assert_int_equal(fp_ocio_open(path, &c), FP_OK);
    fp_ocio_close(c);
    /* $OCIO over fogpipe's own, --ocio over $OCIO. */
    setenv("OCIO", "/from/env.ocio", 1);
    assert_int_equal(fp_ocio_find_config(NULL, path, sizeof path, &origin), FP_OK);
    assert_string_equal(path, "/from/env.ocio");
    assert_string_equal(origin, "$OCIO");
    assert_int_equal(fp_ocio_find_config("/given.ocio", path, sizeof path, &origin), FP_OK);
    assert_string_equal(path, "/given.ocio");
    assert_string_equal(origin, "--ocio");
    if (saved)
        setenv("OCIO", saved, 1);
    else
        unsetenv("OCIO");
    free(saved);
}

/* Random colors, from deep shadow to highlights well above 1. */
static void random_rgba(float *px, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        for (int c = 0; c < 3; c++)
            px[4 * i + c] = (float)(urand() < 0.5 ? urand() : exp(8 * urand() - 4));
        px[4 * i + 3] = (float)urand();
    }
}

static void convert(fp_ocio_t *c, const char *a, const char *b, float *px, size_t n)
{
    fp_ocio_proc_t *p = NULL;
    assert_int_equal(fp_ocio_processor(c, a, b, &p), FP_OK);
    fp_ocio_apply(p, px, n, 4);
    fp_ocio_proc_free(p);
}

static void test_round_trips(void **state)
{
    fp_ocio_t *c = open_config();
    enum { N = 4096 };
    float *orig = malloc(N * 4 * sizeof(float)), *px = malloc(N * 4 * sizeof(float));
    assert_non_null(orig);
    assert_non_null(px);
    random_rgba(orig, N);
    double worst = 0;
    for (int i = 0; i < NLIN; i++)
        for (int k = 0; k < NLIN; k++) {
            memcpy(px, orig, N * 4 * sizeof(float));
            convert(c, linear_spaces[i], linear_spaces[k], px, N);
            convert(c, linear_spaces[k], linear_spaces[i], px, N);
            for (size_t j = 0; j < 4 * N; j++) {
                double e = fabs(px[j] - orig[j]) / fmax(1.0, fabs(orig[j]));
                worst = fmax(worst, e);
                if (!(e <= 1e-4))
                    fail_msg("%s -> %s -> %s: %g became %g", linear_spaces[i], linear_spaces[k],
                             linear_spaces[i], orig[j], px[j]);
            }
        }
    /* The sRGB-encoded space, inside its [0, 1] range. */
    for (size_t j = 0; j < N; j++)
        for (int ch = 0; ch < 3; ch++)
            orig[4 * j + ch] = (float)urand();
    memcpy(px, orig, N * 4 * sizeof(float));
    convert(c, "lin_rec709", "srgb_tx", px, N);
    convert(c, "srgb_tx", "ACEScg", px, N);
    convert(c, "ACEScg", "lin_rec709", px, N);
    for (size_t j = 0; j < 4 * N; j++)
        assert_double_equal(px[j], orig[j], 1e-4);
    print_message("worst relative round-trip error between linear spaces: %.2e\n", worst);
    free(orig);
    free(px);
    fp_ocio_close(c);
}

static void test_grey_stays_grey(void **state)
{
    fp_ocio_t *c = open_config();
    static const float greys[] = { 0.001f, 0.18f, 0.5f, 1.0f, 16.0f };
    for (int i = 0; i < NLIN; i++)
        for (int k = 0; k < NLIN; k++)
            for (size_t g = 0; g < FP_ARRAY_LEN(greys); g++) {
                float px[4] = { greys[g], greys[g], greys[g], 0.25f };
                convert(c, linear_spaces[i], linear_spaces[k], px, 1);
                /* Same primaries' white: the grey itself comes back. */
                for (int ch = 0; ch < 3; ch++)
                    assert_double_equal(px[ch], greys[g], 1e-4 * greys[g]);
            }
    /* And on the display: R = G = B. */
    fp_ocio_proc_t *d = NULL;
    for (int i = 0; i < NLIN; i++) {
        assert_int_equal(fp_ocio_display_processor(c, linear_spaces[i], "sRGB", "Standard", &d),
                         FP_OK);
        float px[3] = { 0.18f, 0.18f, 0.18f };
        fp_ocio_apply(d, px, 1, 3);
        assert_double_equal(px[0], px[1], 1e-5);
        assert_double_equal(px[1], px[2], 1e-5);
        /* sRGB of 0.18 is 0.4614 */
        assert_double_equal(px[0], 0.46136, 1e-4);
        fp_ocio_proc_free(d);
    }
    fp_ocio_close(c);
}

static void test_alpha_untouched(void **state)
{
    fp_ocio_t *c = open_config();
    enum { N = 1000 };
    float px[N * 4], alpha[N];
    random_rgba(px, N);
    px[4 * 7 + 3] = -0.0f;
    px[4 * 9 + 3] = 1e30f;
    for (int i = 0; i < N; i++)
        alpha[i] = px[4 * i + 3];
    convert(c, "lin_rec709", "srgb_tx", px, N);
    convert(c, "srgb_tx", "ACES2065-1", px, N);
    for (int i = 0; i < N; i++)
        assert_memory_equal(&px[4 * i + 3], &alpha[i], sizeof(float));
    fp_ocio_close(c);
}

static void make_params(fp_params_t *p, const char *const *kv)
{
    assert_int_equal(fp_options_defaults(p), FP_OK);
    assert_int_equal(fp_options_apply(p, "ocio", config(), "test"), FP_OK);
    for (; kv && kv[0]; kv += 2)
        assert_int_equal(fp_options_apply(p, kv[0], kv[1], "test"), FP_OK);
}

static const double rec709[8] = { 0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290 };
static const double ap1[8] = { 0.713, 0.293, 0.165, 0.830, 0.128, 0.044, 0.32168, 0.33767 };
static const double ap0[8] = { 0.7347, 0.2653, 0.0, 1.0, 0.0001, -0.0770, 0.32168, 0.33767 };
static const double p3[8] = { 0.680, 0.320, 0.265, 0.690, 0.150, 0.060, 0.3127, 0.3290 };

static void test_chromaticities(void **state)
{
    /* Our matrices against OpenColorIO's built-in transforms. */
    fp_ocio_t *c = open_config();
    const double *chr[3] = { rec709, ap1, ap0 };
    for (int i = 0; i < 3; i++) {
        double ours[9], theirs[9];
        assert_int_equal(fp_color_chromaticities_to_ap0(chr[i], ours), FP_OK);
        assert_int_equal(fp_ocio_matrix(c, linear_spaces[i], "ACES2065-1", theirs), 0);
        for (int k = 0; k < 9; k++)
            assert_double_equal(ours[k], theirs[k], 1e-4);
    }
    double m[9];
    assert_int_equal(fp_ocio_matrix(c, "srgb_tx", "ACES2065-1", m), 1);
    assert_int_equal(fp_ocio_matrix(c, "ACEScg", "lin_rec709", m), 0);
    const double degenerate[8] = { 0.3, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3127, 0.329 };
    assert_int_not_equal(fp_color_chromaticities_to_ap0(degenerate, m), FP_OK);
    fp_ocio_close(c);

    /* Chromaticities -> space, as stored (floats, rounded). */
    fp_params_t p;
    fp_color_t col;
    const char *kv[] = { "output-space", "acescg", NULL };
    make_params(&p, kv);
    assert_int_equal(fp_color_commit(&p, &col), FP_OK);
    float f[8];
    for (int k = 0; k < 8; k++)
        f[k] = (float)rec709[k];
    assert_string_equal(fp_color_identify(&col, f), "Linear Rec.709 (sRGB)");
    for (int k = 0; k < 8; k++)
        f[k] = (float)ap1[k];
    assert_string_equal(fp_color_identify(&col, f), "ACEScg");
    for (int k = 0; k < 8; k++)
        f[k] = (float)ap0[k];
    assert_string_equal(fp_color_identify(&col, f), "ACES2065-1");
    for (int k = 0; k < 8; k++)
        f[k] = (float)p3[k];
    assert_null(fp_color_identify(&col, f));
    /* Space -> chromaticities, for the output's attribute. */
    assert_int_equal(fp_color_space_chromaticities(&col, "ACEScg", f), FP_OK);
    for (int k = 0; k < 8; k++)
        assert_double_equal(f[k], ap1[k], 1e-6);
    assert_int_equal(fp_color_space_chromaticities(&col, "Linear Rec.709 (sRGB)", f), FP_OK);
    assert_double_equal(f[0], 0.64, 1e-6);
    assert_int_not_equal(fp_color_space_chromaticities(&col, "sRGB Encoded Rec.709 (sRGB)", f),
                         FP_OK);
    fp_color_release(&col);
    fp_options_free(&p);
}

static void test_commit_checks(void **state)
{
    fp_params_t p;
    fp_color_t col;
    /* No color option: OpenColorIO is not even loaded, nothing converts. */
    assert_int_equal(fp_options_defaults(&p), FP_OK);
    assert_int_equal(fp_color_commit(&p, &col), FP_OK);
    assert_int_equal(col.active, 0);
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    fp_color_frame_t cf;
    assert_int_equal(fp_color_frame(&col, &info, "x.exr", 1, &cf), FP_OK);
    assert_null(cf.to_work);
    assert_null(cf.to_out);
    assert_null(cf.to_display);
    assert_int_equal(cf.set_chromaticities, 0);
    fp_color_release(&col);
    fp_options_free(&p);

    static const struct {
        const char *kv[7];
        int rc;
    } cases[] = {
        { { "input-space", "nope", NULL }, FP_EUSAGE },
        { { "working-space", "Raw", NULL }, FP_EUSAGE },
        { { "output-space", "data", NULL }, FP_EUSAGE },
        { { "working-space", "srgb_tx", NULL }, FP_EUSAGE },
        { { "input-space", "srgb_tx", NULL }, FP_EUSAGE },
        { { "input-space", "srgb_tx", "working-space", "acescg", NULL }, FP_OK },
        { { "output-space", "srgb_tx", NULL }, FP_OK },
        { { "output-space", "srgb_tx", "aov", "1", NULL }, FP_EUSAGE },
        { { "output-space", "ACES2065-1", "aov", "1", NULL }, FP_OK },
        { { "display", "nope", NULL }, FP_EUSAGE },
        { { "view", "nope", NULL }, FP_EUSAGE },
        { { "view", "Raw", NULL }, FP_OK },
    };
    for (size_t i = 0; i < FP_ARRAY_LEN(cases); i++) {
        make_params(&p, cases[i].kv);
        int rc = fp_color_commit(&p, &col);
        if (rc != cases[i].rc)
            fail_msg("case %zu (--%s %s): status %d, expected %d", i, cases[i].kv[0],
                     cases[i].kv[1], rc, cases[i].rc);
        fp_color_release(&col);
        fp_options_free(&p);
    }
}

static void test_frame_spaces(void **state)
{
    fp_params_t p;
    fp_color_t col;
    fp_frame_info_t info;
    fp_color_frame_t cf;
    memset(&info, 0, sizeof info);

    /* All spaces the same: nothing to apply, the attribute passes. */
    const char *same[] = { "input-space", "lin_rec709", "working-space", "linear",
                           "output-space", "Linear Rec.709 (sRGB)", NULL };
    make_params(&p, same);
    assert_int_equal(fp_color_commit(&p, &col), FP_OK);
    assert_int_equal(fp_color_frame(&col, &info, "x.exr", 1, &cf), FP_OK);
    assert_null(cf.to_work);
    assert_null(cf.to_out);
    assert_int_equal(cf.set_chromaticities, 0);
    fp_color_release(&col);
    fp_options_free(&p);

    /* An ACEScg plate (by its chromaticities) written as linear Rec.709. */
    const char *out709[] = { "output-space", "lin_rec709", NULL };
    make_params(&p, out709);
    assert_int_equal(fp_color_commit(&p, &col), FP_OK);
    info.has_chromaticities = 1;
    for (int k = 0; k < 8; k++)
        info.chromaticities[k] = (float)ap1[k];
    assert_int_equal(fp_color_frame(&col, &info, "x.exr", 1, &cf), FP_OK);
    assert_string_equal(cf.in, "ACEScg");
    assert_string_equal(cf.work, "ACEScg");
    assert_string_equal(cf.out, "Linear Rec.709 (sRGB)");
    assert_null(cf.to_work);
    assert_non_null(cf.to_out);
    assert_int_equal(cf.set_chromaticities, 1);
    assert_double_equal(cf.chromaticities[0], 0.64, 1e-6);
    fp_exr_write_opts_t w = FP_EXR_WRITE_OPTS_INITIALIZER;
    fp_color_write_opts(&cf, &w);
    assert_int_equal(w.set_chromaticities, 1);
    assert_double_equal(w.chromaticities[7], 0.329, 1e-6);
    /* Unknown primaries: scene_linear (a warning), the attribute dropped. */
    for (int k = 0; k < 8; k++)
        info.chromaticities[k] = (float)p3[k];
    assert_int_equal(fp_color_frame(&col, &info, "x.exr", 2, &cf), FP_OK);
    assert_string_equal(cf.in, "Linear Rec.709 (sRGB)");
    assert_null(cf.to_out);
    fp_color_release(&col);
    fp_options_free(&p);

    /* Non-linear output: the attribute is left out. */
    const char *tx[] = { "input-space", "acescg", "output-space", "srgb_tx", NULL };
    make_params(&p, tx);
    assert_int_equal(fp_color_commit(&p, &col), FP_OK);
    assert_int_equal(fp_color_frame(&col, &info, "x.exr", 1, &cf), FP_OK);
    assert_int_equal(cf.set_chromaticities, -1);
    fp_color_release(&col);
    fp_options_free(&p);
}

/* A config without the aces_interchange role: chromaticities cannot be
 * matched (scene_linear, attribute dropped), linearity is judged against
 * scene_linear. */
static void test_config_without_interchange(void **state)
{
    char tmp[4096], line[1024];
    snprintf(tmp, sizeof tmp, "%s/fp_test_color_noref.%ld.ocio",
             getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp", (long)getpid());
    FILE *in = fopen(config(), "r"), *out = fopen(tmp, "w");
    assert_non_null(in);
    assert_non_null(out);
    while (fgets(line, sizeof line, in))
        if (!strstr(line, "aces_interchange:"))
            fputs(line, out);
    fclose(in);
    fclose(out);
    fp_params_t p;
    fp_color_t col;
    assert_int_equal(fp_options_defaults(&p), FP_OK);
    assert_int_equal(fp_options_apply(&p, "ocio", tmp, "test"), FP_OK);
    assert_int_equal(fp_options_apply(&p, "output-space", "acescg", "test"), FP_OK);
    assert_int_equal(fp_color_commit(&p, &col), FP_OK);
    float f[8];
    for (int k = 0; k < 8; k++)
        f[k] = (float)ap1[k];
    assert_null(fp_color_identify(&col, f));
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.has_chromaticities = 1;
    memcpy(info.chromaticities, f, sizeof f);
    fp_color_frame_t cf;
    assert_int_equal(fp_color_frame(&col, &info, "x.exr", 1, &cf), FP_OK);
    assert_string_equal(cf.in, "Linear Rec.709 (sRGB)");
    assert_non_null(cf.to_out);
    assert_int_equal(cf.set_chromaticities, -1);
    fp_color_release(&col);
    assert_int_equal(fp_options_apply(&p, "working-space", "srgb_tx", "test"), FP_OK);
    assert_int_equal(fp_color_commit(&p, &col), FP_EUSAGE);
    fp_color_release(&col);
    fp_options_free(&p);
    remove(tmp);
}

/* A fog layer: S >= 0 and tau in [0, 1], some pixels clear, some opaque. */
static void random_fog(float *fog, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        double tau = i % 17 == 0 ? 1.0 : i % 19 == 0 ? 0.0 : urand();
        fog[4 * i + 3] = (float)tau;
        for (int c = 0; c < 3; c++)
            fog[4 * i + c] = (float)((1 - tau) * (0.5 + urand()));
    }
}

static void test_aov_over_is_composite(void **state)
{
    enum { N = 5000 };
    float *plate = malloc(N * 4 * sizeof(float)), *fog = malloc(N * 4 * sizeof(float));
    float *comp = malloc(N * 4 * sizeof(float)), *merged = malloc(N * 4 * sizeof(float));
    assert_non_null(plate);
    assert_non_null(fog);
    assert_non_null(comp);
    assert_non_null(merged);
    fp_params_t p;
    fp_color_t col;
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    const char *const *looks[] = {
        (const char *const[]){ "aov", "1", NULL },
        (const char *const[]){ "aov-only", "1", "input-space", "lin_rec709", "working-space",
                               "acescg", "output-space", "ACES2065-1", NULL },
    };
    for (size_t l = 0; l < FP_ARRAY_LEN(looks); l++) {
        const char *kv[16];
        int k = 0;
        for (; looks[l][k]; k++)
            kv[k] = looks[l][k];
        kv[k] = NULL;
        make_params(&p, kv);
        assert_int_equal(fp_color_commit(&p, &col), FP_OK);
        fp_color_frame_t cf;
        assert_int_equal(fp_color_frame(&col, &info, "x.exr", 1, &cf), FP_OK);
        random_rgba(plate, N);
        random_fog(fog, N);
        /* The pipeline: plate -> working, composite, layers, -> output. */
        memcpy(comp, plate, N * 4 * sizeof(float));
        fp_color_to_working(&cf, comp, N);
        fp_composite_process(comp, fog, N, comp);
        fp_aov_frame_t a;
        assert_int_equal(fp_aov_make(&p, &cf, fog, N, "x.exr", 1, &a), FP_OK);
        fp_color_to_output(&cf, comp, N);
        assert_int_equal(a.num, 7);
        assert_string_equal(a.extra[3].name, "fog.A");
        assert_string_equal(a.extra[6].name, "transmittance.B");
        for (size_t i = 0; i < N; i++) {
            assert_double_equal(a.planes[3 * N + i], 1.0 - fog[4 * i + 3], 1e-7);
            assert_double_equal(a.planes[4 * N + i], fog[4 * i + 3], 0);
        }
        /* The plate as a compositor has it: in the output space. */
        fp_color_to_working(&cf, plate, N);
        fp_color_to_output(&cf, plate, N);
        fp_aov_over(&a, plate, N, merged);
        double worst = 0;
        for (size_t i = 0; i < 4 * N; i++) {
            double e = fabs(merged[i] - comp[i]) / fmax(1.0, fabs(comp[i]));
            worst = fmax(worst, e);
        }
        print_message("%s: fog over plate vs composite, worst relative difference %.2e\n",
                      l ? "ACEScg working, ACES2065-1 output" : "no conversion", worst);
        /* Without conversion the same float operations up to one rounding;
         * with two matrices in between, float rounding. */
        assert_true(worst <= (l ? 1e-5 : 1e-6));
        fp_exr_write_opts_t w = FP_EXR_WRITE_OPTS_INITIALIZER;
        fp_aov_write_opts(&p, &a, &w);
        assert_int_equal(w.num_extra, 7);
        assert_int_equal(w.drop_color, l == 1);
        assert_int_equal(w.color_only, l == 1);
        fp_aov_free(&a);
        fp_color_release(&col);
        fp_options_free(&p);
    }
    /* No --aov: no layers, write options untouched. */
    assert_int_equal(fp_options_defaults(&p), FP_OK);
    fp_color_frame_t none = FP_COLOR_FRAME_INITIALIZER;
    fp_aov_frame_t a;
    assert_int_equal(fp_aov_make(&p, &none, fog, N, "x.exr", 1, &a), FP_OK);
    assert_int_equal(a.num, 0);
    fp_exr_write_opts_t w = FP_EXR_WRITE_OPTS_INITIALIZER;
    fp_aov_write_opts(&p, &a, &w);
    assert_int_equal(w.num_extra, 0);
    fp_aov_free(&a);
    fp_options_free(&p);
    free(plate);
    free(fog);
    free(comp);
    free(merged);
}

static void test_sheet_columns(void **state)
{
    assert_int_equal(fp_preview_columns(0, 1), 1);
    assert_int_equal(fp_preview_columns(0, 3), 2);
    assert_int_equal(fp_preview_columns(0, 4), 2);
    assert_int_equal(fp_preview_columns(0, 5), 3);
    assert_int_equal(fp_preview_columns(0, 100), 10);
    assert_int_equal(fp_preview_columns(0, 101), 11);
    assert_int_equal(fp_preview_columns(4, 100), 4);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_config_validates),
        cmocka_unit_test(test_config_errors),
        cmocka_unit_test(test_find_config),
        cmocka_unit_test(test_round_trips),
        cmocka_unit_test(test_grey_stays_grey),
        cmocka_unit_test(test_alpha_untouched),
        cmocka_unit_test(test_chromaticities),
        cmocka_unit_test(test_commit_checks),
        cmocka_unit_test(test_frame_spaces),
        cmocka_unit_test(test_config_without_interchange),
        cmocka_unit_test(test_aov_over_is_composite),
        cmocka_unit_test(test_sheet_columns),
    };
    fp_quiet = 1;
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* Option tables: defaults, parsing, ranges, aliases, presets, --help. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fp.h"
#include "options.h"
#include "testutil.h"

static int parse(fp_params_t *p, int argc, const char **argv)
{
    fp_options_defaults(p);
    return fp_options_parse(argc, (char **)argv, p);
}

static void test_defaults(void **state)
{
    (void)state;
    fp_params_t p;
    assert_int_equal(fp_options_defaults(&p), FP_OK);
    assert_double_equal(p.fog.density, 0.02, 0);
    assert_double_equal(p.fog.height[0], 0, 0);
    assert_double_equal(p.fog.height[1], 20, 0);
    assert_true(isinf(p.fog.height[2]));
    assert_string_equal(p.io.input, "-");
    assert_int_equal(p.camera.depth_kind, FP_DEPTH_PLANAR);
    assert_int_equal(p.num_given, 0);
    fp_options_free(&p);
}

static void test_parse(void **state)
{
    (void)state;
    fp_params_t p;
    const char *argv[] = { "fogpipe", "-i", "a.####.exr", "--output=b.####.exr", "--height", "1,5",
                           "--depth-kind", "radial", "--float", "--fog-color", "1,0.5,0.25",
                           "--visibility", "100" };
    assert_int_equal(parse(&p, 13, argv), FP_OK);
    assert_string_equal(p.io.input, "a.####.exr");
    assert_string_equal(p.io.output, "b.####.exr");
    assert_double_equal(p.fog.height[0], 1, 0);
    assert_double_equal(p.fog.height[1], 5, 0);
    assert_true(isinf(p.fog.height[2]));   /* optional component keeps its default */
    assert_int_equal(p.camera.depth_kind, FP_DEPTH_RADIAL);
    assert_int_equal(p.io.use_float, 1);
    assert_double_equal(p.fog.color[2], 0.25, 0);
    assert_double_equal(p.fog.density, log(10.0) / 100, 1e-15);
    assert_true(fp_options_given(&p, "height"));
    assert_false(fp_options_given(&p, "camera-pos"));
    fp_options_free(&p);
}

static void test_errors(void **state)
{
    (void)state;
    fp_params_t p;
    const char *cases[][3] = {
        { "fogpipe", "--nope", "1" },       { "fogpipe", "--density", "-1" },
        { "fogpipe", "--density", "abc" },  { "fogpipe", "--height", "1" },
        { "fogpipe", "--height", "1,2,3,4" }, { "fogpipe", "--depth-kind", "banana" },
        { "fogpipe", "--fog-color", "1,,2" }, { "fogpipe", "--visibility", "0" },
        { "fogpipe", "--vfov", "180" },     { "fogpipe", "stray", "x" },
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        assert_int_equal(parse(&p, 3, cases[i]), FP_EUSAGE);
        fp_options_free(&p);
    }
    const char *missing[] = { "fogpipe", "--density" };
    assert_int_equal(parse(&p, 2, missing), FP_EUSAGE);
    fp_options_free(&p);
}

static void test_preset(void **state)
{
    (void)state;
    char path[] = "/tmp/fp-preset-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    const char *text = "# a look\n  density = 0.5\nheight=2, 10\n\nfog-color = 0.1,0.2,0.3\n";
    assert_int_equal(write(fd, text, strlen(text)), (ssize_t)strlen(text));
    close(fd);
    fp_params_t p;
    const char *argv[] = { "fogpipe", "--density", "0.25", "--preset", path };
    assert_int_equal(parse(&p, 5, argv), FP_OK);
    assert_double_equal(p.fog.density, 0.25, 0);   /* the command line wins */
    assert_double_equal(p.fog.height[1], 10, 0);
    assert_double_equal(p.fog.color[1], 0.2, 0);
    fp_options_free(&p);
    /* Bad lines name the file and line. */
    FILE *f = fopen(path, "w");
    fputs("density = 0.1\nbogus line\n", f);
    fclose(f);
    const char *argv2[] = { "fogpipe", "--preset", path };
    assert_int_equal(parse(&p, 3, argv2), FP_EUSAGE);
    fp_options_free(&p);
    f = fopen(path, "w");
    fputs("help = 1\n", f);
    fclose(f);
    assert_int_equal(parse(&p, 3, argv2), FP_EUSAGE);
    fp_options_free(&p);
    unlink(path);
}

/* Short options bundle as getopt's: flags together, an option that takes
 * a value ending the bundle with the rest of the word or the next word. */
static void test_bundled_short_options(void **state)
{
    (void)state;
    fp_params_t p;
    const char *argv[] = { "fogpipe", "-qv", "-qoout.exr", "-vf", "1-3", "-i-" };
    assert_int_equal(parse(&p, 6, argv), FP_OK);
    assert_int_equal(p.io.quiet, 1);
    assert_int_equal(p.io.verbose, 1);
    assert_string_equal(p.io.output, "out.exr");
    assert_string_equal(p.io.frames, "1-3");
    assert_string_equal(p.io.input, "-");
    fp_options_free(&p);
    const char *bad[][3] = { { "fogpipe", "-qx", NULL }, { "fogpipe", "-qo", NULL },
                             { "fogpipe", "-vV", "-z" } };
    const int argc[] = { 2, 2, 3 };
    for (int i = 0; i < 3; i++) {
        assert_int_equal(parse(&p, argc[i], bad[i]), FP_EUSAGE);
        fp_options_free(&p);
    }
}

static void test_help_lists_everything(void **state)
{
    (void)state;
    char *buf = NULL;
    size_t size = 0;
    FILE *f = open_memstream(&buf, &size);
    fp_options_print_help(f, 0);
    fclose(f);
    for (const fp_option_group_t *g = fp_option_groups; g->title; g++)
        for (const fp_option_t *o = g->options; o->name; o++) {
            char want[128];
            snprintf(want, sizeof want, "--%s", o->name);
            if (!(o->flags & FP_OPTF_HIDDEN) && !strstr(buf, want))
                fail_msg("--help lacks %s", want);
            /* Every default parses (fp_options_defaults succeeded) and
             * numeric options print their range. */
            if ((o->type == FP_OPT_REAL || o->type == FP_OPT_INT) && !(o->flags & FP_OPTF_HIDDEN))
                assert_non_null(strstr(strstr(buf, want), "range"));
        }
    free(buf);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_defaults),
        cmocka_unit_test(test_parse),
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_preset),
        cmocka_unit_test(test_bundled_short_options),
        cmocka_unit_test(test_help_lists_everything),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

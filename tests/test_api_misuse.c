/* libfogpipe's public API (src/fogpipe.h) misused by a host: what a call
 * keeps is the library's own copy, a context freed while another thread
 * is in a call on it or from inside one of its callbacks is safe, a
 * message handler that calls back into the library gets an error instead
 * of a deadlock, and degenerate or huge camera matrices are normalized or
 * refused.  Each case is a function of its own (listed in main) that the
 * fuzz harness calls too. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "fogpipe.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* A hang is a failure, not a stuck `make check`. */
enum { HANG_S = 60 };

static char tmpdir[] = "/tmp/fp-api-misuse-XXXXXX";

static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    char *s = calloc(1, 1 << 20);
    size_t n = s ? fread(s, 1, (1 << 20) - 1, f) : 0;
    (void)n;
    fclose(f);
    return s;
}

/* fogpipe_parse_args keeps a copy of argv (fogpipe.h: arrays are not
 * kept): a host that frees its argv before fogpipe_run gets --stats with
 * the command line it gave, not freed memory. */
static void test_parse_args_copies_argv(void **state)
{
    (void)state;
    const char *samples = getenv("FP_SAMPLES");
    if (!samples) {
        printf("# no FP_SAMPLES (run through make check)\n");
        skip();
    }
    char in[4096], outp[4200], stats[4200];
    snprintf(in, sizeof in, "%s/scene.0003.exr", samples);
    snprintf(outp, sizeof outp, "%s/argv.exr", tmpdir);
    snprintf(stats, sizeof stats, "%s/argv.json", tmpdir);
    const char *args[] = { "host", "--cpu", "--quiet", "-i", in, "-o", outp, "--stats", stats };
    int argc = (int)(sizeof args / sizeof args[0]);
    char **argv = calloc((size_t)argc + 1, sizeof *argv);
    assert_non_null(argv);
    for (int i = 0; i < argc; i++)
        assert_non_null(argv[i] = strdup(args[i]));
    fogpipe_t *fp;
    assert_int_equal(fogpipe_new(&fp), FOGPIPE_OK);
    assert_int_equal(fogpipe_parse_args(fp, argc, argv), FOGPIPE_OK);
    /* The host reuses and frees its strings and array. */
    for (int i = 0; i < argc; i++) {
        memset(argv[i], 'Z', strlen(argv[i]));
        free(argv[i]);
    }
    free(argv);
    assert_int_equal(fogpipe_run(fp, 0), FOGPIPE_OK);
    fogpipe_free(fp);
    char *json = slurp(stats);
    assert_non_null(json);
    char want[16384];
    snprintf(want, sizeof want, "\"argv\": [\"host\", \"--cpu\", \"--quiet\", \"-i\", \"%s\", "
             "\"-o\", \"%s\", \"--stats\", \"%s\"]", in, outp, stats);
    if (!strstr(json, want))
        printf("# stats: %.400s\n# expected %s\n", json, want);
    assert_non_null(strstr(json, want));
    free(json);
    unlink(stats);
    unlink(outp);
}

/* argv with a NULL inside argc, or a negative argc: an error, not a crash. */
static void test_parse_args_null_entry(void **state)
{
    (void)state;
    fogpipe_t *fp;
    assert_int_equal(fogpipe_new(&fp), FOGPIPE_OK);
    char *argv[] = { "host", "--density", NULL, "0.1", NULL };
    assert_int_equal(fogpipe_parse_args(fp, 4, argv), FOGPIPE_EUSAGE);
    assert_non_null(strstr(fogpipe_error(fp), "argv[2] is NULL"));
    assert_int_equal(fogpipe_parse_args(fp, -1, argv), FOGPIPE_EUSAGE);
    assert_int_equal(fogpipe_parse_args(fp, 0, argv), FOGPIPE_EUSAGE);
    /* A good call after them still works. */
    char *good[] = { "host", "--density", "0.1", NULL };
    assert_int_equal(fogpipe_parse_args(fp, 3, good), FOGPIPE_OK);
    fogpipe_free(fp);
}

int main(void)
{
    if (!mkdtemp(tmpdir)) {
        perror(tmpdir);
        return 1;
    }
    alarm(HANG_S);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_parse_args_copies_argv),
        cmocka_unit_test(test_parse_args_null_entry),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    rmdir(tmpdir);
    return rc;
}

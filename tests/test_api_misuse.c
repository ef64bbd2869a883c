/* libfogpipe's public API (lib/fogpipe.h) misused by a host: what a call
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

/* ------------------------------------------------------------ a frame */

enum { W = 64, H = 48 };
static float rgba[W * H * 4], depth[W * H], out[W * H * 4];

static fogpipe_frame_t frame(void)
{
    for (int i = 0; i < W * H; i++) {
        for (int k = 0; k < 4; k++)
            rgba[4 * i + k] = k == 3 ? 1.0f : 0.25f * (float)(k + 1);
        depth[i] = 5.0f + (float)(i % W) * 0.1f;
    }
    /* A negative depth: the apply warns (a message handler runs inside the
     * call). */
    depth[7] = -1;
    fogpipe_frame_t in = FOGPIPE_FRAME_INITIALIZER;
    in.width = W;
    in.height = H;
    in.rgba = rgba;
    in.depth = depth;
    in.name = "misuse-frame";
    return in;
}

static fogpipe_t *make(void)
{
    fogpipe_t *fp = NULL;
    assert_int_equal(fogpipe_new(&fp), FOGPIPE_OK);
    assert_int_equal(fogpipe_set(fp, "camera-pos", "0,1,0", NULL), FOGPIPE_OK);
    assert_int_equal(fogpipe_set(fp, "camera-target", "0,1,-1", NULL), FOGPIPE_OK);
    assert_int_equal(fogpipe_set(fp, "vfov", "40", NULL), FOGPIPE_OK);
    assert_int_equal(fogpipe_set(fp, "density", "0.05", NULL), FOGPIPE_OK);
    return fp;
}

/* ------------------------------------------------------------ re-entry */

/* What a handler that calls back into the library saw. */
typedef struct reenter_t {
    fogpipe_t *fp, *other;
    int calls;
    int set_rc, apply_rc, parse_rc, run_rc, new_rc, other_set_rc;
    fogpipe_t *made;
    char set_msg[600];
    int free_self, free_other;
} reenter_t;

static void reenter(void *user, int kind, const char *text)
{
    reenter_t *r = user;
    (void)text;
    if (kind != FOGPIPE_MSG_WARNING || r->calls++)
        return;
    r->set_rc = fogpipe_set(r->fp, "density", "0.02", NULL);
    snprintf(r->set_msg, sizeof r->set_msg, "%s", fogpipe_error(r->fp));
    fogpipe_frame_t in = frame();
    r->apply_rc = fogpipe_apply(r->fp, &in, out, NULL, NULL);
    char *argv[] = { "host", "--density", "0.1", NULL };
    r->parse_rc = fogpipe_parse_args(r->fp, 3, argv);
    r->run_rc = fogpipe_run(r->fp, 0);
    r->new_rc = fogpipe_new(&r->made);
    if (r->other)
        r->other_set_rc = fogpipe_set(r->other, "density", "0.02", NULL);
    /* These work from a handler. */
    assert_non_null(fogpipe_version());
    fogpipe_set_message_handler(r->fp, reenter, r);
    if (r->free_other)
        fogpipe_free(r->other);
    if (r->free_self)
        fogpipe_free(r->fp);
}

/* A message handler that calls back into the library: an error naming
 * the handler (the library lock is the caller's), never a deadlock; the
 * call in progress goes on. */
static void test_handler_reenters(void **state)
{
    (void)state;
    reenter_t r;
    memset(&r, 0, sizeof r);
    r.fp = make();
    assert_int_equal(fogpipe_new(&r.other), FOGPIPE_OK);
    fogpipe_set_message_handler(r.fp, reenter, &r);
    fogpipe_frame_t in = frame();
    assert_int_equal(fogpipe_apply(r.fp, &in, out, NULL, NULL), FOGPIPE_OK);
    assert_int_equal(r.calls, 1);
    assert_int_equal(r.set_rc, FOGPIPE_ERROR);
    printf("# %s\n", r.set_msg);
    assert_non_null(strstr(r.set_msg, "fogpipe_set: called from a message handler"));
    assert_int_equal(r.apply_rc, FOGPIPE_ERROR);
    assert_int_equal(r.parse_rc, FOGPIPE_ERROR);
    assert_int_equal(r.run_rc, FOGPIPE_ERROR);
    assert_int_equal(r.new_rc, FOGPIPE_ERROR);
    assert_null(r.made);
    assert_int_equal(r.other_set_rc, FOGPIPE_ERROR);
    assert_non_null(strstr(fogpipe_error(r.other), "called from a message handler"));
    /* The refused calls changed nothing: the next apply is the same. */
    float first[W * H * 4];
    memcpy(first, out, sizeof out);
    r.calls = 0;
    assert_int_equal(fogpipe_apply(r.fp, &in, out, NULL, NULL), FOGPIPE_OK);
    assert_memory_equal(first, out, sizeof out);
    /* Outside a handler the same calls work. */
    assert_int_equal(fogpipe_set(r.other, "density", "0.02", NULL), FOGPIPE_OK);
    fogpipe_free(r.other);
    fogpipe_free(r.fp);
}

/* fogpipe_free from a handler: its own context is freed when the call in
 * progress returns (which still succeeds), another one at once. */
static void test_free_from_handler(void **state)
{
    (void)state;
    reenter_t r;
    memset(&r, 0, sizeof r);
    r.fp = make();
    assert_int_equal(fogpipe_new(&r.other), FOGPIPE_OK);
    r.free_self = r.free_other = 1;
    fogpipe_set_message_handler(r.fp, reenter, &r);
    fogpipe_frame_t in = frame();
    assert_int_equal(fogpipe_apply(r.fp, &in, out, NULL, NULL), FOGPIPE_OK);
    assert_int_equal(r.calls, 1);
    for (int i = 0; i < W * H * 4; i++)
        assert_true(isfinite(out[i]));
    /* Both are gone: a call on either is refused without touching it. */
    assert_int_equal(fogpipe_set(r.fp, "density", "0.1", NULL), FOGPIPE_EUSAGE);
    assert_int_equal(fogpipe_set(r.other, "density", "0.1", NULL), FOGPIPE_EUSAGE);
    assert_non_null(strstr(fogpipe_error(r.fp), "not a live context"));
}

/* Every message of a fogpipe_run (progress, info, the frame loop's kept
 * lines, from whichever thread the loop hands them on) calls back into the
 * library: each call refused, the run goes on to the end. */
typedef struct run_reenter_t {
    fogpipe_t *fp;
    pthread_mutex_t m;
    int messages, refused, other;
} run_reenter_t;

static void run_reenter(void *user, int kind, const char *text)
{
    run_reenter_t *r = user;
    (void)kind;
    (void)text;
    int rc = fogpipe_set(r->fp, "density", "0.02", NULL);
    fogpipe_set_message_handler(r->fp, run_reenter, r);
    pthread_mutex_lock(&r->m);
    r->messages++;
    if (rc == FOGPIPE_ERROR)
        r->refused++;
    else
        r->other++;
    pthread_mutex_unlock(&r->m);
}

static void test_handler_reenters_run(void **state)
{
    (void)state;
    const char *samples = getenv("FP_SAMPLES");
    if (!samples) {
        printf("# no FP_SAMPLES (run through make check)\n");
        skip();
    }
    char in[4096], outp[4200];
    snprintf(in, sizeof in, "%s/scene.####.exr", samples);
    snprintf(outp, sizeof outp, "%s/run.####.exr", tmpdir);
    run_reenter_t r;
    memset(&r, 0, sizeof r);
    pthread_mutex_init(&r.m, NULL);
    assert_int_equal(fogpipe_new(&r.fp), FOGPIPE_OK);
    const char *const opts[][2] = { { "input", in }, { "output", outp }, { "frames", "1-3" },
                                    { "progress", "lines" }, { "verbose", NULL },
                                    { "cpu", NULL } };
    for (size_t i = 0; i < sizeof opts / sizeof opts[0]; i++)
        assert_int_equal(fogpipe_set(r.fp, opts[i][0], opts[i][1], NULL), FOGPIPE_OK);
    fogpipe_set_message_handler(r.fp, run_reenter, &r);
    assert_int_equal(fogpipe_run(r.fp, 0), FOGPIPE_OK);
    printf("# %d messages, %d calls refused, %d not\n", r.messages, r.refused, r.other);
    assert_true(r.messages >= 3);
    assert_int_equal(r.refused, r.messages);
    fogpipe_free(r.fp);
    for (int f = 1; f <= 3; f++) {
        char path[4300];
        snprintf(path, sizeof path, "%s/run.%04d.exr", tmpdir, f);
        assert_int_equal(unlink(path), 0);
    }
    pthread_mutex_destroy(&r.m);
}

/* ------------------------------------------------------------ free during a call */

typedef struct race_t {
    fogpipe_t *fp;
    pthread_mutex_t m;
    pthread_cond_t cv;
    int inside, freed;
} race_t;

/* Inside thread A's apply: let thread B free the context, and give it time
 * to reach the library while this call is still in progress. */
static void inside(void *user, int kind, const char *text)
{
    race_t *r = user;
    (void)text;
    if (kind != FOGPIPE_MSG_WARNING)
        return;
    pthread_mutex_lock(&r->m);
    r->inside = 1;
    pthread_cond_broadcast(&r->cv);
    pthread_mutex_unlock(&r->m);
    usleep(200 * 1000);
}

static void *freer(void *arg)
{
    race_t *r = arg;
    pthread_mutex_lock(&r->m);
    while (!r->inside)
        pthread_cond_wait(&r->cv, &r->m);
    pthread_mutex_unlock(&r->m);
    fogpipe_free(r->fp);
    pthread_mutex_lock(&r->m);
    r->freed = 1;
    pthread_mutex_unlock(&r->m);
    return NULL;
}

/* fogpipe_free on one thread while another is inside fogpipe_apply on the
 * same context: the free waits for the call, which finishes with its
 * frame; the context's later calls are refused, not run on freed memory. */
static void test_free_during_apply(void **state)
{
    (void)state;
    race_t r;
    memset(&r, 0, sizeof r);
    pthread_mutex_init(&r.m, NULL);
    pthread_cond_init(&r.cv, NULL);
    r.fp = make();
    fogpipe_set_message_handler(r.fp, inside, &r);
    pthread_t t;
    assert_int_equal(pthread_create(&t, NULL, freer, &r), 0);
    fogpipe_frame_t in = frame();
    int rc = fogpipe_apply(r.fp, &in, out, NULL, NULL);
    pthread_join(t, NULL);
    assert_int_equal(rc, FOGPIPE_OK);
    assert_int_equal(r.freed, 1);
    assert_int_equal(fogpipe_apply(r.fp, &in, out, NULL, NULL), FOGPIPE_EUSAGE);
    assert_non_null(strstr(fogpipe_error(r.fp), "not a live context"));
    fogpipe_free(r.fp);   /* a second free is refused too */
    pthread_mutex_destroy(&r.m);
    pthread_cond_destroy(&r.cv);
}

/* ------------------------------------------------------------ cameras */

/* A camera at (0.5, 1, 2) looking down world -z, 40 deg vertical: OpenEXR's
 * worldToCamera and worldToNDC, each times its scale. */
static void camera(double s_w2c, double s_w2n, double w2c[16], double w2n[16])
{
    const double m[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -1, 0, -0.5, -1, 2, 1 };
    double sy = 1 / (2 * tan(40 * M_PI / 360)), sx = sy * H / W;
    const double pr[16] = { sx, 0, 0, 0, 0, -sy, 0, 0, 0.5, 0.5, 1, 1, 0, 0, 0, 0 };
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double t = 0;
            for (int k = 0; k < 4; k++)
                t += m[i * 4 + k] * pr[k * 4 + j];
            w2n[i * 4 + j] = t * s_w2n;
            w2c[i * 4 + j] = m[i * 4 + j] * s_w2c;
        }
}

/* worldToCamera / worldToNDC scaled by 1e300, 1e-300 or -1 are the same
 * projective camera: the same frame, finite, on the device and on the C
 * path (before, the device's frame was all NaN with FOGPIPE_OK). */
static void test_camera_scaled(void **state)
{
    (void)state;
    static const double sc[][2] = { { 1e300, 1 }, { 1, 1e300 }, { 1e-300, 1e-300 },
                                    { 1e300, 1e-300 }, { -1, 1e-200 } };
    static float ref[W * H * 4];
    for (int cpu = 0; cpu < 2; cpu++) {
        fogpipe_t *fp;
        assert_int_equal(fogpipe_new(&fp), FOGPIPE_OK);
        assert_int_equal(fogpipe_set(fp, "density", "0.08", NULL), FOGPIPE_OK);
        assert_int_equal(fogpipe_set(fp, "cpu", cpu ? "1" : "0", NULL), FOGPIPE_OK);
        double w2c[16], w2n[16];
        fogpipe_frame_t in = frame();
        in.world_to_camera = w2c;
        in.world_to_ndc = w2n;
        camera(1, 1, w2c, w2n);
        assert_int_equal(fogpipe_apply(fp, &in, ref, NULL, NULL), FOGPIPE_OK);
        assert_true(fabsf(ref[4 * 100] - rgba[4 * 100]) > 1e-3f);   /* fogged */
        for (size_t k = 0; k < sizeof sc / sizeof sc[0]; k++) {
            camera(sc[k][0], sc[k][1], w2c, w2n);
            assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_OK);
            double d = 0;
            for (int i = 0; i < W * H * 4; i++) {
                assert_true(isfinite(out[i]));
                d = fmax(d, fabs(out[i] - ref[i]));
            }
            printf("# %s, scales %g, %g: max |d| %.3g\n", cpu ? "--cpu" : "device", sc[k][0],
                   sc[k][1], d);
            assert_true(d <= 1e-5);
        }
        fogpipe_free(fp);
    }
}

/* A matrix that is no projection: refused, its name in the message. */
static void test_camera_degenerate(void **state)
{
    (void)state;
    fogpipe_t *fp;
    assert_int_equal(fogpipe_new(&fp), FOGPIPE_OK);
    double w2c[16], w2n[16];
    fogpipe_frame_t in = frame();
    in.world_to_camera = w2c;
    in.world_to_ndc = w2n;
    camera(1, 1, w2c, w2n);
    w2n[6] = NAN;
    assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_ERROR);
    assert_non_null(strstr(fogpipe_error(fp), "misuse-frame: frame 1: worldToNDC has a "
                                              "non-finite element"));
    camera(1, 1, w2c, w2n);
    memset(w2c, 0, sizeof w2c);
    assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_ERROR);
    assert_non_null(strstr(fogpipe_error(fp), "worldToCamera is all zeros"));
    camera(1, 1e-320, w2c, w2n);   /* subnormal: still the camera */
    assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_OK);
    camera(1, 0, w2c, w2n);
    assert_int_equal(fogpipe_apply(fp, &in, out, NULL, NULL), FOGPIPE_ERROR);
    assert_non_null(strstr(fogpipe_error(fp), "worldToNDC is all zeros"));
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
        cmocka_unit_test(test_free_during_apply),
        cmocka_unit_test(test_handler_reenters),
        cmocka_unit_test(test_free_from_handler),
        cmocka_unit_test(test_handler_reenters_run),
        cmocka_unit_test(test_camera_scaled),
        cmocka_unit_test(test_camera_degenerate),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    rmdir(tmpdir);
    return rc;
}

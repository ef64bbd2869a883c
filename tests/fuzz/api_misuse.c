/* fogpipe fuzz harness: libfogpipe's public API (fogpipe.h) misused as a
 * host might, one case a process (tests/fuzz/fuzz.py --mode api):
 *
 *   api_misuse CASE      exit 0: the library coped (an error code and a
 *                        one-line message, or the work done); 1: it did
 *                        not (the reason on stderr).  A crash, a sanitizer
 *                        report or a hang (SIGALRM after 20 s) fails too.
 *
 * FP_FIXTURES names the harness's fixtures folder (scene.0001.exr). */
#define _GNU_SOURCE
#include "fogpipe.h"

#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

static int failed;

#define EXPECT(cond, ...)                                    \
    do {                                                     \
        if (!(cond)) {                                       \
            fprintf(stderr, "api_misuse: %s:%d: ", __func__, __LINE__); \
            fprintf(stderr, __VA_ARGS__);                    \
            fputc('\n', stderr);                             \
            failed = 1;                                      \
        }                                                    \
    } while (0)

/* A one-line, non-empty message. */
static void one_line(fogpipe_t *fp, const char *what)
{
    const char *m = fogpipe_error(fp);
    EXPECT(m && *m && !strchr(m, '\n'), "%s: message %s", what, m ? m : "(NULL)");
}

/* A small frame: grey plate, depth 10, camera from the options. */
typedef struct {
    int w, h;
    float *rgba, *depth, *out;
    fogpipe_frame_t f;
} frame_t;

static void frame_make(frame_t *fr, int w, int h)
{
    fr->w = w;
    fr->h = h;
    size_t n = (size_t)w * h;
    fr->rgba = malloc(n * 4 * sizeof(float));
    fr->depth = malloc(n * sizeof(float));
    fr->out = malloc(n * 4 * sizeof(float));
    if (!fr->rgba || !fr->depth || !fr->out)
        abort();
    for (size_t i = 0; i < n; i++) {
        fr->rgba[4 * i] = fr->rgba[4 * i + 1] = fr->rgba[4 * i + 2] = 0.5f;
        fr->rgba[4 * i + 3] = 1;
        fr->depth[i] = 5 + (float)(i % 17);
    }
    fogpipe_frame_t init = FOGPIPE_FRAME_INITIALIZER;
    fr->f = init;
    fr->f.width = w;
    fr->f.height = h;
    fr->f.rgba = fr->rgba;
    fr->f.depth = fr->depth;
}

static void frame_free(frame_t *fr)
{
    free(fr->rgba);
    free(fr->depth);
    free(fr->out);
}

static fogpipe_t *context(void)
{
    fogpipe_t *fp = NULL;
    if (fogpipe_new(&fp) != FOGPIPE_OK || !fp) {
        fprintf(stderr, "api_misuse: fogpipe_new failed\n");
        exit(1);
    }
    fogpipe_set(fp, "cpu", NULL, NULL); /* the C reference: no device needed, fast */
    fogpipe_set(fp, "camera-pos", "0,2,10", NULL);
    fogpipe_set(fp, "vfov", "40", NULL);
    return fp;
}

static int null_args(void)
{
    EXPECT(fogpipe_new(NULL) != FOGPIPE_OK, "fogpipe_new(NULL) succeeded");
    fogpipe_free(NULL);
    EXPECT(fogpipe_error(NULL) && *fogpipe_error(NULL), "fogpipe_error(NULL)");
    EXPECT(fogpipe_set(NULL, "density", "1", NULL) != FOGPIPE_OK, "set on NULL");
    EXPECT(fogpipe_parse_args(NULL, 0, NULL) != FOGPIPE_OK, "parse_args on NULL");
    EXPECT(fogpipe_apply(NULL, NULL, NULL, NULL, NULL) != FOGPIPE_OK, "apply on NULL");
    EXPECT(fogpipe_run(NULL, 0) != FOGPIPE_OK, "run on NULL");
    fogpipe_set_message_handler(NULL, NULL, NULL);
    fogpipe_t *fp = context();
    EXPECT(fogpipe_set(fp, NULL, "1", NULL) != FOGPIPE_OK, "set(NULL name)");
    one_line(fp, "set(NULL name)");
    EXPECT(fogpipe_set(fp, "", "1", NULL) != FOGPIPE_OK, "set(\"\")");
    EXPECT(fogpipe_set(fp, "density", NULL, NULL) != FOGPIPE_OK, "set(density, NULL)");
    one_line(fp, "set(density, NULL)");
    EXPECT(fogpipe_set(fp, "--", "1", NULL) != FOGPIPE_OK, "set(\"--\")");
    EXPECT(fogpipe_parse_args(fp, 0, NULL) != FOGPIPE_OK, "parse_args(0, NULL)");
    char *argv1[] = { "fogpipe", NULL };
    EXPECT(fogpipe_parse_args(fp, -5, argv1) != FOGPIPE_OK, "parse_args(-5)");
    EXPECT(fogpipe_apply(fp, NULL, NULL, NULL, NULL) != FOGPIPE_OK, "apply(NULL frame)");
    one_line(fp, "apply(NULL frame)");
    frame_t fr;
    frame_make(&fr, 8, 8);
    fr.f.rgba = NULL;
    EXPECT(fogpipe_apply(fp, &fr.f, fr.out, NULL, NULL) != FOGPIPE_OK, "apply(rgba NULL)");
    fr.f.rgba = fr.rgba;
    fr.f.depth = NULL;
    EXPECT(fogpipe_apply(fp, &fr.f, fr.out, NULL, NULL) != FOGPIPE_OK, "apply(depth NULL)");
    fr.f.depth = fr.depth;
    EXPECT(fogpipe_apply(fp, &fr.f, NULL, NULL, NULL) != FOGPIPE_OK, "apply(out NULL)");
    one_line(fp, "apply(out NULL)");
    EXPECT(fogpipe_apply(fp, &fr.f, fr.out, NULL, NULL) == FOGPIPE_OK, "a good frame after: %s",
           fogpipe_error(fp));
    frame_free(&fr);
    fogpipe_free(fp);
    return failed;
}

static int wrong_sizes(void)
{
    fogpipe_t *fp = context();
    frame_t fr;
    frame_make(&fr, 8, 8);
    static const int dims[][2] = { { 0, 8 }, { 8, 0 }, { -1, 8 }, { 8, -8 }, { INT_MAX, INT_MAX },
                                   { 65536, 65536 }, { INT_MIN, INT_MIN }, { 1 << 30, 4 } };
    for (size_t i = 0; i < sizeof dims / sizeof dims[0]; i++) {
        fr.f.width = dims[i][0];
        fr.f.height = dims[i][1];
        EXPECT(fogpipe_apply(fp, &fr.f, fr.out, NULL, NULL) != FOGPIPE_OK, "%dx%d accepted",
               dims[i][0], dims[i][1]);
        one_line(fp, "wrong size");
    }
    fr.f.width = fr.f.height = 8;
    EXPECT(fogpipe_apply(fp, &fr.f, fr.out, NULL, NULL) == FOGPIPE_OK, "8x8: %s",
           fogpipe_error(fp));
    frame_free(&fr);
    fogpipe_free(fp);
    return failed;
}

/* fogpipe.h: "arrays passed in stay the caller's and are not kept after
 * the call returns".  argv's strings are unmapped after parse_args, so a
 * later read of them is a SIGSEGV even without AddressSanitizer. */
static int freed_argv(void)
{
    const char *fx = getenv("FP_FIXTURES");
    if (!fx) {
        fprintf(stderr, "FP_FIXTURES is not set\n");
        return 77;
    }
    char in[4096], out[4096], stats[4096];
    snprintf(in, sizeof in, "%s/scene.0001.exr", fx);
    snprintf(out, sizeof out, "api_freed_argv.exr");
    snprintf(stats, sizeof stats, "api_freed_argv.json");
    unlink(out);
    unlink(stats);
    const char *args[] = { "fogpipe", "-q", "--cpu", "-i", in, "-o", out, "--stats", stats };
    int argc = (int)(sizeof args / sizeof args[0]);
    size_t page = (size_t)sysconf(_SC_PAGESIZE);
    size_t len = 0;
    for (int i = 0; i < argc; i++)
        len += strlen(args[i]) + 1;
    len = (len + page - 1) / page * page;
    char *mem = mmap(NULL, len, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    char **argv = mmap(NULL, page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (mem == MAP_FAILED || argv == MAP_FAILED)
        return 77;
    char *p = mem;
    for (int i = 0; i < argc; i++) {
        argv[i] = p;
        p = stpcpy(p, args[i]) + 1;
    }
    argv[argc] = NULL;
    fogpipe_t *fp = NULL;
    if (fogpipe_new(&fp) != FOGPIPE_OK)
        return 1;
    EXPECT(fogpipe_parse_args(fp, argc, argv) == FOGPIPE_OK, "parse_args: %s", fogpipe_error(fp));
    munmap(mem, len);
    munmap(argv, page);
    EXPECT(fogpipe_run(fp, 0) == FOGPIPE_OK, "run: %s", fogpipe_error(fp));
    EXPECT(access(out, F_OK) == 0, "no output %s", out);
    EXPECT(access(stats, F_OK) == 0, "no stats file %s", stats);
    fogpipe_free(fp);
    return failed;
}

struct applier {
    fogpipe_t *fp;
    frame_t *fr;
    int rc;
};

static void *apply_thread(void *arg)
{
    struct applier *a = arg;
    a->rc = fogpipe_apply(a->fp, &a->fr->f, a->fr->out, NULL, NULL);
    return NULL;
}

/* fogpipe_free while another thread is inside fogpipe_apply on the same
 * context: the free must wait for the call or the call must fail cleanly
 * (fogpipe.h states which); the applying thread never touches the context
 * again. */
static int free_during_apply(void)
{
    fogpipe_t *fp = context();
    frame_t fr;
    frame_make(&fr, 256, 256);
    fogpipe_set(fp, "scatter-steps", "128", NULL);
    fogpipe_set(fp, "sun", "0,1,0.3", NULL);
    struct applier a = { fp, &fr, -1 };
    pthread_t t;
    pthread_create(&t, NULL, apply_thread, &a);
    usleep(20000);
    fogpipe_free(fp);
    pthread_join(t, NULL);
    for (size_t i = 0; a.rc == FOGPIPE_OK && i < (size_t)256 * 256 * 4; i++)
        EXPECT(isfinite(fr.out[i]), "pixel %zu not finite", i);
    frame_free(&fr);
    return failed;
}

struct reentry {
    fogpipe_t *fp;
    int calls, inner_rc, mode;
};

static void handler(void *user, int kind, const char *text)
{
    struct reentry *r = user;
    (void)kind;
    (void)text;
    if (r->calls++)
        return;
    if (r->mode == 0) {
        r->inner_rc = fogpipe_set(r->fp, "density", "0.03", NULL);
    } else {
        fogpipe_t *other = NULL;
        r->inner_rc = fogpipe_new(&other);
        fogpipe_free(other);
    }
}

/* A message handler that calls back into the library: an error code or
 * the call done, never a deadlock on the library's lock. */
static int reentry(int mode)
{
    fogpipe_t *fp = context();
    struct reentry r = { fp, 0, -1, mode };
    fogpipe_set_message_handler(fp, handler, &r);
    fogpipe_set(fp, "verbose", NULL, NULL);
    frame_t fr;
    frame_make(&fr, 16, 16);
    int rc = fogpipe_apply(fp, &fr.f, fr.out, NULL, NULL);
    /* verbose output or not, a bad option's message reaches the handler */
    if (!r.calls)
        fogpipe_set(fp, "no-such-option", "1", NULL);
    EXPECT(rc == FOGPIPE_OK || *fogpipe_error(fp), "apply failed without a message");
    frame_free(&fr);
    fogpipe_free(fp);
    return failed;
}

static int new_free_cycles(void)
{
    frame_t fr;
    frame_make(&fr, 8, 8);
    for (int i = 0; i < 20; i++) {
        fogpipe_t *fp = context();
        EXPECT(fogpipe_set(fp, "density", i % 2 ? "0.5" : "abc", NULL) == (i % 2 ? 0 : 2),
               "density");
        EXPECT(fogpipe_apply(fp, &fr.f, fr.out, NULL, NULL) == FOGPIPE_OK, "cycle %d: %s", i,
               fogpipe_error(fp));
        char *bad[] = { "fogpipe", "--density", "1e999", "--nope", NULL };
        EXPECT(fogpipe_parse_args(fp, 4, bad) != FOGPIPE_OK, "bad args accepted");
        one_line(fp, "bad args");
        fogpipe_free(fp);
    }
    frame_free(&fr);
    return failed;
}

/* Degenerate and non-finite camera matrices: refused with a message, or
 * a finite frame. */
static int bad_matrices(void)
{
    fogpipe_t *fp = context();
    frame_t fr;
    frame_make(&fr, 16, 16);
    double zero[16] = { 0 }, nan16[16], id[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 };
    for (int i = 0; i < 16; i++)
        nan16[i] = NAN;
    const double *sets[][2] = { { zero, zero }, { nan16, id }, { id, nan16 }, { id, zero },
                                { zero, id } };
    for (size_t s = 0; s < sizeof sets / sizeof sets[0]; s++) {
        fr.f.world_to_camera = sets[s][0];
        fr.f.world_to_ndc = sets[s][1];
        int rc = fogpipe_apply(fp, &fr.f, fr.out, NULL, NULL);
        if (rc != FOGPIPE_OK) {
            one_line(fp, "bad matrix");
            continue;
        }
        size_t bad = 0;
        for (size_t i = 0; i < (size_t)16 * 16 * 4; i++)
            bad += !isfinite(fr.out[i]);
        EXPECT(!bad, "matrix set %zu: accepted with %zu non-finite values", s, bad);
    }
    frame_free(&fr);
    fogpipe_free(fp);
    return failed;
}

int main(int argc, char **argv)
{
    alarm(20);
    if (argc != 2) {
        fprintf(stderr, "usage: api_misuse CASE\n");
        return 2;
    }
    const char *c = argv[1];
    if (!strcmp(c, "null_args"))
        return null_args();
    if (!strcmp(c, "wrong_sizes"))
        return wrong_sizes();
    if (!strcmp(c, "freed_argv"))
        return freed_argv();
    if (!strcmp(c, "free_during_apply"))
        return free_during_apply();
    if (!strcmp(c, "reentrant_handler"))
        return reentry(0);
    if (!strcmp(c, "handler_new_context"))
        return reentry(1);
    if (!strcmp(c, "new_free_cycles"))
        return new_free_cycles();
    if (!strcmp(c, "bad_matrices"))
        return bad_matrices();
    fprintf(stderr, "api_misuse: unknown case %s\n", c);
    return 2;
}

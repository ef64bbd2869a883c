/* Contexts on two threads at once (issue 27: no process-wide state in the
 * library).  Two contexts with different looks fog frames in memory, each
 * on its own thread: each one's pixels equal those of the same context run
 * alone, and the two calls were in progress at the same time: each
 * context's message handler, on the first message of its call, waits for
 * the other call to have sent one too.  Under a process-wide lock the
 * second call could not start while the first waits, and the wait gives up
 * (after FP_MEET_S seconds: a bound on a hang, not a measure of speed). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "fogpipe.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum { W = 96, H = 54, FRAMES = 3 };
#define FP_MEET_S 30

static float rgba[W * H * 4], depth[W * H];

static void fill(void)
{
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            int i = y * W + x;
            rgba[4 * i] = 0.1f + 0.8f * (float)x / W;
            rgba[4 * i + 1] = 0.3f;
            rgba[4 * i + 2] = 0.2f + 0.6f * (float)y / H;
            rgba[4 * i + 3] = 1.0f;
            depth[i] = 2.0f + 40.0f * (float)(x + y) / (W + H);
        }
}

/* Two looks, so that a context answering with the other's settings shows. */
static const char *const looks[2][4][2] = {
    { { "density", "0.05" }, { "fog-color", "0.7,0.72,0.75" }, { "height", "0,4" }, { NULL, NULL } },
    { { "visibility", "30" }, { "fog-color", "0.9,0.6,0.4" }, { "sun", "0.3,1,0.2" }, { NULL, NULL } },
};

static fogpipe_t *make(int look, int verbose)
{
    fogpipe_t *fp = NULL;
    assert_int_equal(fogpipe_new(&fp), FOGPIPE_OK);
    assert_int_equal(fogpipe_set(fp, "camera-pos", "0,1.5,0", NULL), FOGPIPE_OK);
    assert_int_equal(fogpipe_set(fp, "camera-target", "0,1.5,-1", NULL), FOGPIPE_OK);
    assert_int_equal(fogpipe_set(fp, "vfov", "40", NULL), FOGPIPE_OK);
    for (int i = 0; looks[look][i][0]; i++)
        assert_int_equal(fogpipe_set(fp, looks[look][i][0], looks[look][i][1], NULL),
                         FOGPIPE_OK);
    if (verbose)
        assert_int_equal(fogpipe_set(fp, "verbose", NULL, NULL), FOGPIPE_OK);
    return fp;
}

static fogpipe_frame_t frame(long n)
{
    fogpipe_frame_t in = FOGPIPE_FRAME_INITIALIZER;
    in.width = W;
    in.height = H;
    in.rgba = rgba;
    in.depth = depth;
    in.name = "threads";
    in.frame = n;
    return in;
}

/* ------------------------------------------------------------ meeting */

static pthread_mutex_t mu = PTHREAD_MUTEX_INITIALIZER;
static pthread_cond_t cv = PTHREAD_COND_INITIALIZER;
static int arrived, met, gave_up;   /* gave_up: a side stopped waiting */

typedef struct side_t {
    int look;
    int armed;        /* meet on the next message */
    int waited;       /* met or gave up */
    int rc;
    float out[FRAMES][W * H * 4];
} side_t;

static void meet(void *user, int kind, const char *text)
{
    (void)kind;
    (void)text;
    side_t *s = user;
    if (!s->armed || s->waited)
        return;
    s->waited = 1;
    struct timespec until;
    clock_gettime(CLOCK_REALTIME, &until);
    until.tv_sec += FP_MEET_S;
    pthread_mutex_lock(&mu);
    arrived++;
    pthread_cond_broadcast(&cv);
    while (arrived < 2 && !gave_up)
        if (pthread_cond_timedwait(&cv, &mu, &until) == ETIMEDOUT)
            gave_up = 1;
    /* Met only while the other still waited inside its call. */
    if (arrived >= 2 && !gave_up)
        met = 1;
    pthread_mutex_unlock(&mu);
}

static void *side_main(void *v)
{
    side_t *s = v;
    fogpipe_t *fp = NULL;
    s->rc = fogpipe_new(&fp);
    if (s->rc)
        return NULL;
    fogpipe_set_message_handler(fp, meet, s);
    for (int i = 0; looks[s->look][i][0] && !s->rc; i++)
        s->rc = fogpipe_set(fp, looks[s->look][i][0], looks[s->look][i][1], NULL);
    const char *cam[3][2] = { { "camera-pos", "0,1.5,0" }, { "camera-target", "0,1.5,-1" },
                              { "vfov", "40" } };
    for (int i = 0; i < 3 && !s->rc; i++)
        s->rc = fogpipe_set(fp, cam[i][0], cam[i][1], NULL);
    if (!s->rc)
        s->rc = fogpipe_set(fp, "verbose", NULL, NULL);
    s->armed = 1;
    for (int f = 0; f < FRAMES && !s->rc; f++) {
        fogpipe_frame_t in = frame(f + 1);
        s->rc = fogpipe_apply(fp, &in, s->out[f], NULL, NULL);
    }
    s->armed = 0;
    if (s->rc)
        fprintf(stderr, "# look %d: %s\n", s->look, fogpipe_error(fp));
    fogpipe_free(fp);
    return NULL;
}

static void test_two_threads(void **state)
{
    (void)state;
    fill();
    static float serial[2][FRAMES][W * H * 4];
    for (int look = 0; look < 2; look++) {
        fogpipe_t *fp = make(look, 0);
        for (int f = 0; f < FRAMES; f++) {
            fogpipe_frame_t in = frame(f + 1);
            assert_int_equal(fogpipe_apply(fp, &in, serial[look][f], NULL, NULL), FOGPIPE_OK);
        }
        fogpipe_free(fp);
    }
    /* The looks differ: a mix-up between the contexts would show. */
    assert_true(memcmp(serial[0][0], serial[1][0], sizeof serial[0][0]) != 0);

    static side_t sides[2];
    pthread_t th[2];
    for (int i = 0; i < 2; i++) {
        sides[i].look = i;
        assert_int_equal(pthread_create(&th[i], NULL, side_main, &sides[i]), 0);
    }
    for (int i = 0; i < 2; i++)
        pthread_join(th[i], NULL);
    for (int i = 0; i < 2; i++) {
        assert_int_equal(sides[i].rc, FOGPIPE_OK);
        assert_int_equal(sides[i].waited, 1);
        for (int f = 0; f < FRAMES; f++)
            assert_memory_equal(sides[i].out[f], serial[i][f], sizeof serial[i][f]);
    }
    if (!met)
        fail_msg("the two contexts' calls were never in progress at once (each handler "
                 "waited %d s for the other's call)", FP_MEET_S);
}

/* Verbosity is the context's: a verbose context's messages go to its
 * handler, and a context that is not verbose says nothing, whichever ran
 * last. */
static int counts[2];
static void counter(void *user, int kind, const char *text)
{
    (void)kind;
    (void)text;
    counts[*(int *)user]++;
}

static void test_verbosity_is_the_contexts(void **state)
{
    (void)state;
    fill();
    static int ids[2] = { 0, 1 };
    fogpipe_t *loud = make(0, 1), *quiet = make(1, 0);
    fogpipe_set_message_handler(loud, counter, &ids[0]);
    fogpipe_set_message_handler(quiet, counter, &ids[1]);
    static float out[W * H * 4];
    fogpipe_frame_t in = frame(1);
    assert_int_equal(fogpipe_apply(loud, &in, out, NULL, NULL), FOGPIPE_OK);
    assert_int_equal(fogpipe_apply(quiet, &in, out, NULL, NULL), FOGPIPE_OK);
    assert_true(counts[0] > 0);
    assert_int_equal(counts[1], 0);
    fogpipe_free(loud);
    fogpipe_free(quiet);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_two_threads),
        cmocka_unit_test(test_verbosity_is_the_contexts),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

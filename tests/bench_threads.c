/* fogpipe benchmark: contexts on two threads at once (issue 27).  Two
 * contexts fog frames in memory through the public API: one thread doing
 * both contexts' frames one after the other, against two threads each
 * doing its own context's.  Prints the wall times, their ratio (0.5: the
 * two ran fully at once on two free cores; 1: one at a time) and the CPU
 * time, for the OpenCL device and for the C reference (--cpu).  A figure,
 * never a pass/fail. */
#include "fogpipe.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

enum { W = 320, H = 180, FRAMES = 4 };

static float rgba[W * H * 4], depth[W * H];

typedef struct side_t {
    fogpipe_t *fp;
    float *out;
    int rc;
} side_t;

static double wall_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
}

static double cpu_s(void)
{
    struct rusage u;
    getrusage(RUSAGE_SELF, &u);
    return u.ru_utime.tv_sec + u.ru_stime.tv_sec + (u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-6;
}

static int frames(side_t *s)
{
    for (int f = 0; f < FRAMES; f++) {
        fogpipe_frame_t in = FOGPIPE_FRAME_INITIALIZER;
        in.width = W;
        in.height = H;
        in.rgba = rgba;
        in.depth = depth;
        in.name = "bench";
        in.frame = f + 1;
        int rc = fogpipe_apply(s->fp, &in, s->out, NULL, NULL);
        if (rc) {
            fprintf(stderr, "bench_threads: %s\n", fogpipe_error(s->fp));
            return rc;
        }
    }
    return 0;
}

static void *side_main(void *v)
{
    side_t *s = v;
    s->rc = frames(s);
    return NULL;
}

static fogpipe_t *make(int look, int cpu)
{
    static const char *const looks[2][3][2] = {
        { { "density", "0.05" }, { "height", "0,4" }, { "sun", "0.3,1,0.2" } },
        { { "visibility", "30" }, { "sun", "-0.5,0.8,0.1" }, { "fog-color", "0.9,0.6,0.4" } },
    };
    fogpipe_t *fp = NULL;
    if (fogpipe_new(&fp))
        return NULL;
    int rc = fogpipe_set(fp, "camera-pos", "0,1.5,0", NULL) ||
             fogpipe_set(fp, "camera-target", "0,1.5,-1", NULL) ||
             fogpipe_set(fp, "vfov", "40", NULL) || (cpu && fogpipe_set(fp, "cpu", NULL, NULL));
    for (int i = 0; i < 3 && !rc; i++)
        rc = fogpipe_set(fp, looks[look][i][0], looks[look][i][1], NULL);
    if (rc) {
        fprintf(stderr, "bench_threads: %s\n", fogpipe_error(fp));
        fogpipe_free(fp);
        return NULL;
    }
    return fp;
}

static int measure(int cpu, const char *label)
{
    side_t s[2];
    static float out[2][W * H * 4];
    for (int i = 0; i < 2; i++) {
        s[i].fp = make(i, cpu);
        s[i].out = out[i];
        if (!s[i].fp)
            return 1;
        /* Warm: the session, the device and its programs made once. */
        if (frames(&s[i]))
            return 1;
    }
    double w0 = wall_s(), c0 = cpu_s();
    int rc = frames(&s[0]) || frames(&s[1]);
    double w1 = wall_s(), c1 = cpu_s();
    pthread_t th[2];
    for (int i = 0; i < 2 && !rc; i++)
        rc = pthread_create(&th[i], NULL, side_main, &s[i]);
    for (int i = 0; i < 2 && !rc; i++)
        pthread_join(th[i], NULL);
    double w2 = wall_s(), c2 = cpu_s();
    rc = rc || s[0].rc || s[1].rc;
    for (int i = 0; i < 2; i++)
        fogpipe_free(s[i].fp);
    if (rc)
        return 1;
    printf("| %s | %.2f s | %.2f s | %.2f | %.2f s | %.2f s |\n", label, w1 - w0, w2 - w1,
           (w2 - w1) / (w1 - w0), c1 - c0, c2 - c1);
    return 0;
}

int main(void)
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
    printf("### Contexts on two threads (issue 27)\n\n");
    printf("Two contexts (two fogs, each with a sun), %d frames of %dx%d each in memory through the "
           "public API: one thread doing both contexts' frames in turn, against two threads "
           "each doing its own context's. Ratio = two threads / one thread (0.5: fully at once "
           "on two free cores; 1: one at a time, as under the old process-wide lock). PoCL "
           "spreads one kernel over the cores already, so on the OpenCL device the ratio says "
           "how much the host-side work between kernels overlaps.\n\n",
           FRAMES, W, H);
    printf("| path | one thread, both contexts | two threads | ratio | CPU, one thread | CPU, two threads |\n");
    printf("|---|---|---|---|---|---|\n");
    if (measure(0, "OpenCL (default device)") || measure(1, "C reference (--cpu)"))
        return 1;
    printf("\n");
    return 0;
}

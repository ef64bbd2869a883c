/* make bench: the local lights' screen-space shadows (--lamp-shadows
 * screen, kernels/lamp_shadow_core.h) on one frame of the sample scene
 * (Markdown on stdout).  Timings are figures, never pass/fail.
 *   bench_lamp_shadow FRAME.exr
 * The street of N lamps of bench_light's "Many lamps" (points with a soft
 * radius, Cycles spots and fogpipe spots shining down, area lights facing
 * down, 1.5 apart along z on both sides) in the frame's ground fog, on
 * OpenCL with the default culling: CPU ns per pixel (getrusage, user +
 * sys: PoCL's threads are the process's) and wall ms, the least of 5
 * runs, with the lamps' shadows and without (--lamp-shadows none); the
 * share of the pixels whose fog the shadows change by more than 1e-4 of
 * the frame's largest in-scatter, and the light they take away. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "camera.h"
#include "clrt.h"
#include "exrio.h"
#include "fogmap.h"
#include "fp.h"
#include "integrate.h"
#include "options.h"
#include "scatter.h"

#include "bench_util.h"

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

/* The lamps' options ("name=value"), n lamps, shadows on or off. */
static int street(look_t *l, int n, int shadows, fp_cl_t *cl, const fp_view_t *v,
                  const float *depth)
{
    memset(l, 0, sizeof *l);
    fp_options_defaults(&l->p);
    int rc = fp_options_apply(&l->p, "density", "0.05", "bench") ||
             fp_options_apply(&l->p, "height", "0,3,15", "bench") ||
             fp_options_apply(&l->p, "fog-color", "0.002,0.003,0.006", "bench") ||
             fp_options_apply(&l->p, "phase", "hg:0.6", "bench") ||
             fp_options_apply(&l->p, "lamp-shadows", shadows ? "screen" : "none", "bench");
    for (int k = 0; k < n && !rc; k++) {
        char spec[256];
        double x = (k % 2 ? -4 : 4) + 0.5 * sin(k), z = 2 + 1.5 * (k / 2) + 0.75 * (k % 2);
        switch (k % 4) {
        case 0:
            snprintf(spec, sizeof spec, "point:%g,3.5,%g:1,0.6,0.3:8:0.1", x, z);
            break;
        case 1:
            snprintf(spec, sizeof spec, "spot:%g,4,%g:0.8,0.9,1:30:%g,-1,0.1:cycles:60,0.2:0.05",
                     x, z, -0.1 * x);
            break;
        case 2:
            snprintf(spec, sizeof spec, "spot:%g,4,%g:1,1,0.8:30:0,-1,0:20,35", x, z);
            break;
        default:
            snprintf(spec, sizeof spec, "area:%g,3,%g:1,0.9,0.7:6:0,-1,0:1,0,0:0.6,0.3", x, z);
        }
        rc = fp_options_apply(&l->p, "light", spec, "bench");
    }
    return rc || look_commit(l, cl, v, depth);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: bench_lamp_shadow FRAME.exr\n");
        return 2;
    }
    fp_params_t p0;
    fp_options_defaults(&p0);
    fp_frame_t *frame = NULL;
    fp_view_t view;
    fp_cl_t *cl = NULL;
    fp_integrate_cl_t icl;
    fp_scatter_cl_t scl;
    if (bench_frame_view(argv[1], &p0, &frame, &view) || fp_cl_open(NULL, &cl) ||
        fp_integrate_cl_init(cl, &icl) || fp_scatter_cl_init(cl, &scl))
        return 1;
    const fp_frame_info_t *info = fp_frame_info(frame);
    size_t n = (size_t)info->width * info->height;
    const float *depth = fp_frame_depth(frame);
    float *out[2] = { malloc(n * 4 * sizeof(float)), malloc(n * 4 * sizeof(float)) };
    if (!out[0] || !out[1])
        return 1;
    static const int counts[] = { 1, 8, 64 };
    const int reps = 5;
    printf("\n### Lamps' screen-space shadows (issue 23, --lamp-shadows)\n\n"
           "The street of N lamps of \"Many lamps\" in the sample frame (%dx%d), OpenCL, the "
           "default --light-cull 1e-4: CPU ns per pixel (user + sys) and wall ms per frame, "
           "the least of %d runs, with the lamps' shadows (screen, the default) and without "
           "(none); the pixels whose fog the shadows change by more than 1e-4 of the largest "
           "in-scatter, and the largest share of a pixel's in-scatter they take away.\n\n",
           info->width, info->height, reps);
    printf("| lamps | CPU ns/px (shadows) | wall ms (shadows) | CPU ns/px (none) | wall ms (none) "
           "| shadows' CPU, ns/px | pixels changed | most taken away |\n"
           "|---|---|---|---|---|---|---|---|\n");
    for (size_t ci = 0; ci < FP_ARRAY_LEN(counts); ci++) {
        double cpu[2], wall[2];
        for (int sh = 1; sh >= 0; sh--) {
            look_t l;
            if (street(&l, counts[ci], sh, cl, &view, depth))
                return 1;
            fp_scatter_process_cl(&scl, &icl, &l.light, &l.fog, &view, depth, out[sh]);
            cpu[sh] = wall[sh] = INFINITY;
            for (int r = 0; r < reps; r++) {
                double c0 = cpu_s(), t0 = now_ms();
                if (fp_scatter_process_cl(&scl, &icl, &l.light, &l.fog, &view, depth, out[sh]))
                    return 1;
                wall[sh] = fmin(wall[sh], now_ms() - t0);
                cpu[sh] = fmin(cpu[sh], (cpu_s() - c0) * 1e9 / (double)n);
            }
            look_release(&l);
        }
        double smax = 1e-30, most = 0;
        size_t changed = 0;
        for (size_t i = 0; i < n; i++)
            for (int c = 0; c < 3; c++)
                smax = fmax(smax, out[0][4 * i + c]);
        for (size_t i = 0; i < n; i++) {
            int ch = 0;
            for (int c = 0; c < 3; c++) {
                double d = (double)out[0][4 * i + c] - out[1][4 * i + c];
                ch |= d > 1e-4 * smax;
                if (out[0][4 * i + c] > 1e-3 * smax)
                    most = fmax(most, d / out[0][4 * i + c]);
            }
            changed += ch;
        }
        printf("| %d | %.0f | %.1f | %.0f | %.1f | %.0f | %.1f%% | %.0f%% |\n", counts[ci], cpu[1],
               wall[1], cpu[0], wall[0], cpu[1] - cpu[0], 100.0 * changed / n, 100 * most);
        fflush(stdout);
    }
    free(out[0]);
    free(out[1]);
    fp_scatter_cl_release(&scl);
    fp_integrate_cl_release(&icl);
    fp_cl_close(cl);
    fp_frame_free(frame);
    fp_options_free(&p0);
    return 0;
}

/* Benchmark of the fog stage on one frame: OpenCL time per frame, Mpixel/s,
 * and the error of the float kernel against the C double reference.
 *   bench_fog FRAME.exr [repeats] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "camera.h"
#include "clrt.h"
#include "exrio.h"
#include "fp.h"
#include "integrate.h"
#include "options.h"

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: bench_fog FRAME.exr [repeats]\n");
        return 2;
    }
    int reps = argc > 2 ? atoi(argv[2]) : 10;
    fp_params_t p;
    fp_options_defaults(&p);
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    fp_frame_t *f;
    if (fp_exr_read_file(argv[1], 1, &sel, &f))
        return 1;
    const fp_frame_info_t *info = fp_frame_info(f);
    fp_camera_t cam;
    fp_view_t v;
    fp_integrate_data_t d;
    if (fp_camera_resolve(&p, info, argv[1], 1, &cam) || fp_view_setup(&cam, &p, info, &v) ||
        fp_integrate_commit(&p, &d))
        return 1;
    size_t n = (size_t)info->width * info->height;
    float *ref = malloc(n * 4 * sizeof(float)), *got = malloc(n * 4 * sizeof(float));
    double t0 = now_ms();
    fp_integrate_process(&d, &v, fp_frame_depth(f), ref, NULL);
    double t_ref = now_ms() - t0;
    fp_cl_t *cl;
    fp_integrate_cl_t s;
    if (fp_cl_open(NULL, &cl) || fp_integrate_cl_init(cl, &s))
        return 1;
    fp_integrate_process_cl(&s, &d, &v, fp_frame_depth(f), got);   /* warm-up */
    t0 = now_ms();
    for (int r = 0; r < reps; r++)
        fp_integrate_process_cl(&s, &d, &v, fp_frame_depth(f), got);
    double t_cl = (now_ms() - t0) / reps;
    double maxe = 0, sum2 = 0;
    for (size_t i = 0; i < n; i++) {
        double e = fabs((double)got[4 * i + 3] - ref[4 * i + 3]);
        maxe = fmax(maxe, e);
        sum2 += e * e;
    }
    printf("| %s | %dx%d | %.2f | %.1f | %.1f | %.2e | %.2e |\n", fp_cl_device_label(cl),
           info->width, info->height, t_cl, n / t_cl / 1e3, t_ref, maxe, sqrt(sum2 / n));
    fp_integrate_cl_release(&s);
    fp_cl_close(cl);
    free(ref);
    free(got);
    fp_frame_free(f);
    fp_options_free(&p);
    return 0;
}

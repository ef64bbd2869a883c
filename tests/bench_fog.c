/* make bench: figures for the fog stages on one frame of the sample scene
 * (Markdown on stdout).  Timings are figures, never pass/fail.
 *   bench_fog FRAME.exr
 * Every fast path is printed with its error against the exact answer. */
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
#include "options_all.h"

#include "fog_core.h"

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

typedef struct bench_t {
    fp_params_t p;
    fp_frame_t *frame;
    fp_view_t view;
    size_t n;
    const float *depth;
    fp_cl_t *cl;
    fp_integrate_cl_t icl;
    float *exact, *got;
} bench_t;

/* A smooth, patchy fogmap: sums of blobs, zero in places (so sparse
 * skipping has work), deterministic. */
static float *make_fogmap(int size)
{
    float *img = calloc((size_t)size * size, sizeof *img);
    unsigned s = 12345;
    for (int b = 0; b < 24; b++) {
        s = s * 1103515245u + 12345u;
        double cx = (s >> 8) % 1000 / 1000.0;
        s = s * 1103515245u + 12345u;
        double cy = (s >> 8) % 1000 / 1000.0;
        s = s * 1103515245u + 12345u;
        double r = 0.04 + (s >> 8) % 1000 / 1000.0 * 0.12;
        for (int j = 0; j < size; j++)
            for (int i = 0; i < size; i++) {
                double dx = (i + 0.5) / size - cx, dy = (j + 0.5) / size - cy;
                double q = 1 - (dx * dx + dy * dy) / (r * r);
                if (q > 0)
                    img[(size_t)j * size + i] += (float)(q * q);
            }
    }
    return img;
}

/* Run the OpenCL fog for the current parameters: best-of time in ms. */
static double run(bench_t *b, fp_fogmap_stage_t *st, fp_integrate_data_t *d, int reps)
{
    double best = INFINITY;
    fp_fogmap_frame(&b->p, b->cl, st, 1, &b->view, d);
    fp_integrate_process_cl(&b->icl, d, &b->view, b->depth, b->got);   /* upload, warm-up */
    for (int r = 0; r < reps; r++) {
        double t0 = now_ms();
        fp_integrate_process_cl(&b->icl, d, &b->view, b->depth, b->got);
        best = fmin(best, now_ms() - t0);
    }
    (void)st;
    return best;
}

static void tau_error(const bench_t *b, const float *ref, double *maxe, double *rms)
{
    double m = 0, s2 = 0;
    for (size_t i = 0; i < b->n; i++) {
        double e = fabs((double)b->got[4 * i + 3] - ref[4 * i + 3]);
        m = fmax(m, e);
        s2 += e * e;
    }
    *maxe = m;
    *rms = sqrt(s2 / b->n);
}

static int setup_fog(bench_t *b, const float *img, int size, fp_fogmap_stage_t *st,
                     fp_integrate_data_t *d)
{
    if (fp_integrate_commit(&b->p, d))
        return FP_ERR;
    if (!img)
        return FP_OK;
    return fp_fogmap_setup(&b->p, b->cl, img, size, size, st, d);
}

static const char *basis_name[] = { "Haar", "linear", "quadratic", "cubic" };

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: bench_fog FRAME.exr\n");
        return 2;
    }
    bench_t b;
    memset(&b, 0, sizeof b);
    fp_options_defaults(&b.p);
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    fp_camera_t cam;
    if (fp_exr_read_file(argv[1], 1, &sel, &b.frame))
        return 1;
    const fp_frame_info_t *info = fp_frame_info(b.frame);
    if (fp_camera_resolve(&b.p, info, argv[1], 1, &cam) ||
        fp_view_setup(&cam, &b.p, info, &b.view) || fp_cl_open(NULL, &b.cl) ||
        fp_integrate_cl_init(b.cl, &b.icl))
        return 1;
    b.n = (size_t)info->width * info->height;
    b.depth = fp_frame_depth(b.frame);
    b.exact = malloc(b.n * 4 * sizeof(float));
    b.got = malloc(b.n * 4 * sizeof(float));
    double mpx = b.n / 1e6;
    /* The look: the fogmap over the scene, density for visible fog. */
    fp_options_apply(&b.p, "fog-rect", "-60,-20,60,100", "bench");
    fp_options_apply(&b.p, "density", "0.08", "bench");
    fp_options_apply(&b.p, "height", "0,6", "bench");
    printf("Frame: %s, %dx%d; device: %s.\n\n", argv[1], info->width, info->height,
           fp_cl_device_label(b.cl));

    /* Height fog, exact closed form, and the device's error against the C
     * double reference on the whole frame. */
    {
        fp_integrate_data_t d;
        fp_fogmap_stage_t st;
        memset(&st, 0, sizeof st);
        setup_fog(&b, NULL, 0, &st, &d);
        double ms = run(&b, &st, &d, 5);
        double t0 = now_ms();
        fp_integrate_process(&d, &b.view, b.depth, b.exact, NULL);
        double ref_ms = now_ms() - t0;
        double me, rms;
        tau_error(&b, b.exact, &me, &rms);
        printf("## Height fog (no fogmap)\n\n| OpenCL ms/frame | Mpixel/s | C reference ms | max "
               "abs error tau | RMS error tau |\n|---|---|---|---|---|\n| %.2f | %.1f | %.0f | "
               "%.2e | %.2e |\n\n", ms, mpx / ms * 1e3, ref_ms, me, rms);
    }

    /* Table 1 of seed 000: raw fogmaps (no decomposition), per basis and size. */
    printf("## Raw fogmaps, no decomposition (seed 000 Table 1)\n\nms per frame (Mpixel/s).\n\n"
           "| basis | 16x16 | 32x32 | 64x64 |\n|---|---|---|---|\n");
    for (int basis = 0; basis <= 2; basis++) {
        printf("| %s |", basis_name[basis]);
        for (int size = 16; size <= 64; size *= 2) {
            float *img = make_fogmap(size);
            b.p.fogmap.basis = basis;
            b.p.fogmap.levels = 0;
            fp_integrate_data_t d;
            fp_fogmap_stage_t st;
            setup_fog(&b, img, size, &st, &d);
            double ms = run(&b, &st, &d, 3);
            printf(" %.1f (%.1f) |", ms, mpx / ms * 1e3);
            fp_fogmap_release(&st);
            free(img);
        }
        printf("\n");
    }

    /* Table 2: levels x mu on a 64x64 linear fogmap; error against mu = 1. */
    printf("\n## Levels and level of detail mu, 64x64 linear (seed 000 Table 2)\n\n"
           "ms per frame; max |dtau| against mu = 1 (exact) in brackets.\n\n"
           "| levels | mu 1 | mu 0.9 | mu 0.75 | mu 0.5 | mu 0.25 | mu 0 |\n|---|---|---|---|---|---|---|\n");
    {
        float *img = make_fogmap(64);
        const double mus[] = { 1, 0.9, 0.75, 0.5, 0.25, 0 };
        for (int levels = 1; levels <= 4; levels++) {
            printf("| %d |", levels);
            b.p.fogmap.basis = 1;
            b.p.fogmap.levels = levels;
            for (size_t k = 0; k < FP_ARRAY_LEN(mus); k++) {
                b.p.fogmap.lod_mu = mus[k];
                fp_integrate_data_t d;
                fp_fogmap_stage_t st;
                setup_fog(&b, img, 64, &st, &d);
                double ms = run(&b, &st, &d, 3);
                double me, rms;
                if (k == 0)
                    memcpy(b.exact, b.got, b.n * 4 * sizeof(float));
                tau_error(&b, b.exact, &me, &rms);
                printf(" %.1f (%.1e) |", ms, me);
                fp_fogmap_release(&st);
            }
            printf("\n");
        }
        b.p.fogmap.lod_mu = 1;
        free(img);
    }

    /* Table 3: with and without deconstruction, 3 levels. */
    printf("\n## With and without deconstruction, 64x64, 3 levels (seed 000 Table 3)\n\n"
           "ms per frame; max |dtau| between the two in the last column.\n\n"
           "| basis | deconstructed | raw bands | max abs difference |\n|---|---|---|---|\n");
    {
        float *img = make_fogmap(64);
        for (int basis = 0; basis <= 3; basis++) {
            b.p.fogmap.basis = basis;
            b.p.fogmap.levels = 3;
            double ms[2];
            for (int dec = 1; dec >= 0; dec--) {
                b.p.fogmap.deconstruct = dec;
                fp_integrate_data_t d;
                fp_fogmap_stage_t st;
                setup_fog(&b, img, 64, &st, &d);
                ms[dec] = run(&b, &st, &d, 2);
                if (dec)
                    memcpy(b.exact, b.got, b.n * 4 * sizeof(float));
                fp_fogmap_release(&st);
            }
            double me, rms;
            tau_error(&b, b.exact, &me, &rms);
            printf("| %s | %.1f | %.1f | %.1e |\n", basis_name[basis], ms[1], ms[0], me);
        }
        b.p.fogmap.deconstruct = 1;
        free(img);
    }

    /* Cost against fogmap size; the fast paths and their errors. */
    printf("\n## Fogmap size (linear, 4 levels)\n\nDecomposition time (OpenCL), render time with "
           "and without sparse skipping (exact either way), with --lod-footprint 1 and "
           "--min-transmittance 0.01 and their max |dtau| against exact.\n\n"
           "| size | decompose ms | render ms | no sparse ms | footprint 1 ms (error) | "
           "min-transmittance 0.01 ms (error) |\n|---|---|---|---|---|---|\n");
    for (int size = 256; size <= 4096; size *= 4) {
        float *img = make_fogmap(size);
        b.p.fogmap.basis = 1;
        b.p.fogmap.levels = 4;
        fp_integrate_data_t d;
        fp_fogmap_stage_t st;
        setup_fog(&b, img, size, &st, &d);
        double ms = run(&b, &st, &d, 1);
        memcpy(b.exact, b.got, b.n * 4 * sizeof(float));
        d.fp[FP_F_SPARSE] = 0;
        double ms_dense = run(&b, &st, &d, 1);
        d.fp[FP_F_SPARSE] = 1;
        b.p.fogmap.lod_footprint = 1;
        double ms_foot = run(&b, &st, &d, 1), e_foot, r;
        tau_error(&b, b.exact, &e_foot, &r);
        b.p.fogmap.lod_footprint = 0;
        d.fp[FP_F_OD_MAX] = -log(0.01);
        double ms_term = run(&b, &st, &d, 1), e_term;
        tau_error(&b, b.exact, &e_term, &r);
        printf("| %dx%d | %.0f | %.1f | %.1f | %.1f (%.1e) | %.1f (%.1e) |\n", size, size,
               st.decompose_ms, ms, ms_dense, ms_foot, e_foot, ms_term, e_term);
        fp_fogmap_release(&st);
        free(img);
    }

    /* Exact against marching, same run. */
    printf("\n## Exact integration against uniform raymarching (64x64 linear, 3 levels)\n\n"
           "| integrator | ms per frame | RMS error tau | max error tau |\n|---|---|---|---|\n");
    {
        float *img = make_fogmap(64);
        b.p.fogmap.basis = 1;
        b.p.fogmap.levels = 3;
        fp_integrate_data_t d;
        fp_fogmap_stage_t st;
        setup_fog(&b, img, 64, &st, &d);
        double ms = run(&b, &st, &d, 3);
        memcpy(b.exact, b.got, b.n * 4 * sizeof(float));
        printf("| exact | %.1f | - | - |\n", ms);
        for (int steps = 16; steps <= 1024; steps *= 4) {
            d.fp[FP_F_MODE] = 1;
            d.fp[FP_F_STEPS] = steps;
            double msm = run(&b, &st, &d, 1), me, rms;
            tau_error(&b, b.exact, &me, &rms);
            printf("| march %d steps | %.1f | %.2e | %.2e |\n", steps, msm, rms, me);
        }
        d.fp[FP_F_MODE] = 0;

        /* The device's exact mode against the C double reference, on every
         * 16th pixel (the reference is slow). */
        run(&b, &st, &d, 1);
        double me = 0, s2 = 0;
        size_t cnt = 0;
        for (size_t i = 0; i < b.n; i += 16) {
            int x = (int)(i % info->width), y = (int)(i / info->width);
            double dir[3], len;
            fp_view_ray(&b.view, x, y, b.depth[i], dir, &len);
            double tau = exp(-fp_integrate_optical_depth(&d, b.view.origin, dir, len, 0));
            double e = fabs(tau - b.got[4 * i + 3]);
            me = fmax(me, e);
            s2 += e * e;
            cnt++;
        }
        printf("\nOpenCL exact mode against the C double-precision reference (every 16th pixel): "
               "max |dtau| %.2e, RMS %.2e; %.1f Mpixel/s.\n", me, sqrt(s2 / cnt), mpx / ms * 1e3);
        fp_fogmap_release(&st);
        free(img);
    }
    free(b.exact);
    free(b.got);
    fp_integrate_cl_release(&b.icl);
    fp_cl_close(b.cl);
    fp_frame_free(b.frame);
    fp_options_free(&b.p);
    return 0;
}

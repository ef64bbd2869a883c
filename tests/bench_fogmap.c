/* make bench: the fogmap integrator's cost per pixel and its error against
 * the exact C double reference (Markdown on stdout).  Figures, never
 * pass/fail.
 *   bench_fogmap HD.exr SEED.exr [what]
 * HD.exr: a 1920x1080 frame of the sample scene; SEED.exr: the 800x600 one.
 * what: all (default), exact, march, large.
 * Cost is CPU time (getrusage user+sys of this process: PoCL's threads are
 * in it) per pixel of one fog layer, upload and read-back included, the
 * minimum of several runs, so that a loaded machine shows less. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "camera.h"
#include "clrt.h"
#include "exrio.h"
#include "fogmap.h"
#include "fp.h"
#include "integrate.h"
#include "options_all.h"
#include "scatter.h"

#include "bench_util.h"

#include "fog_core.h"

typedef struct frame_t {
    fp_params_t p;
    fp_frame_t *frame;
    fp_view_t view;
    size_t n;
    const float *depth;
    float *got, *keep;
} frame_t;

static fp_cl_t *cl;
static fp_integrate_cl_t icl;

/* The bench fogmap of bench_fog.c: smooth blobs, zero in places. */
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

static int open_frame(const char *path, frame_t *f)
{
    memset(f, 0, sizeof *f);
    fp_options_defaults(&f->p);
    if (bench_frame_view(path, &f->p, &f->frame, &f->view))
        return FP_ERR;
    f->n = (size_t)f->view.width * f->view.height;
    f->depth = fp_frame_depth(f->frame);
    f->got = malloc(f->n * 4 * sizeof(float));
    f->keep = malloc(f->n * 4 * sizeof(float));
    /* The look of bench_fog.c. */
    fp_options_apply(&f->p, "fog-rect", "-60,-20,60,100", "bench");
    fp_options_apply(&f->p, "density", "0.08", "bench");
    fp_options_apply(&f->p, "height", "0,6", "bench");
    return f->got && f->keep ? FP_OK : FP_ERR;
}

static int setup(frame_t *f, const float *img, int size, int basis, int levels,
                 fp_fogmap_stage_t *st, fp_integrate_data_t *d)
{
    f->p.fogmap.basis = basis;
    f->p.fogmap.levels = levels;
    if (fp_integrate_commit(&f->p, d) || fp_fogmap_setup(&f->p, cl, img, size, size, st, d))
        return FP_ERR;
    return fp_fogmap_frame(&f->p, cl, st, 1, &f->view, d);
}

/* OpenCL fog layer into f->got: CPU ns per pixel, minimum of reps runs
 * after one warm-up. */
static double run(frame_t *f, const fp_integrate_data_t *d, int reps)
{
    double best = INFINITY;
    fp_integrate_process_cl(&icl, d, &f->view, f->depth, f->got);
    for (int r = 0; r < reps; r++) {
        double t0 = cpu_s();
        fp_integrate_process_cl(&icl, d, &f->view, f->depth, f->got);
        best = fmin(best, cpu_s() - t0);
    }
    return best * 1e9 / f->n;
}

/* max |tau - exact| of f->got on every step-th pixel, exact = the C double
 * reference with the parameters of `d` but levels all kept, exact rule. */
static double ref_error(frame_t *f, const fp_integrate_data_t *d, size_t step, double *rms)
{
    fp_integrate_data_t e = *d;
#ifdef FP_F_LOD_BOUND
    e.fp[FP_F_LOD_BOUND] = 0;
#endif
    e.fp[FP_F_LOD_MU] = 1;
    e.fp[FP_F_FOOTPRINT] = 0;
    e.fp[FP_F_OD_MAX] = INFINITY;
    e.fp[FP_F_MODE] = 0;
    int w = f->view.width;
    double me = 0, s2 = 0;
    size_t cnt = 0;
    for (size_t i = step / 2; i < f->n; i += step) {
        double dir[3], len;
        fp_view_ray(&f->view, (int)(i % w), (int)(i / w), f->depth[i], dir, &len);
        double tau = exp(-fp_integrate_optical_depth(&e, f->view.origin, dir, len, 0));
        double err = fabs(tau - f->got[4 * i + 3]);
        me = fmax(me, err);
        s2 += err * err;
        cnt++;
    }
    if (rms)
        *rms = sqrt(s2 / cnt);
    return me;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: bench_fogmap HD.exr SEED.exr [all|exact|march|large]\n");
        return 2;
    }
    const char *what = argc > 3 ? argv[3] : "all";
    setvbuf(stdout, NULL, _IOLBF, 0);   /* figures as they come */
    int all = !strcmp(what, "all");
    frame_t hd, seed;
    if (open_frame(argv[1], &hd) || open_frame(argv[2], &seed) || fp_cl_open(NULL, &cl) ||
        fp_integrate_cl_init(cl, &icl))
        return 1;
    printf("## Fogmap integration: one walk per ray (CPU ns per pixel)\n\n");
    printf("Device: %s. CPU time (user+sys, getrusage, PoCL's threads included) per pixel of "
           "one fog layer with its upload and read-back, minimum of 3 runs (one for 4096x4096); "
           "errors of tau "
           "against the exact C double-precision reference (every 16th pixel; 64th for "
           "4096x4096). The look of bench_fog.c: fog rectangle -60,-20,60,100, density 0.08, "
           "height 0,6, the patchy bench fogmap.\n\n", fp_cl_device_label(cl));
    float *img64 = make_fogmap(64);
    double ns64 = 0;
    if (all || !strcmp(what, "exact") || !strcmp(what, "large")) {
        printf("| case | frame | ns/px | goal | max abs dtau | RMS dtau |\n"
               "|---|---|---|---|---|---|\n");
        fp_integrate_data_t d;
        fp_fogmap_stage_t st;
        if (setup(&hd, img64, 64, 1, 3, &st, &d))
            return 1;
        ns64 = run(&hd, &d, 3);
        double rms, me = ref_error(&hd, &d, 16, &rms);
        printf("| 64x64 linear, 3 levels, exact | 1920x1080 | %.0f | <= 1000 | %.2e | %.2e |\n",
               ns64, me, rms);
        /* The same on one ray a work-item (integrate_fog), the kernel
         * integrate_fogmap's lanes replace for this look. */
        icl.no_lanes = 1;
        double ns1 = run(&hd, &d, 3), rms1, me1 = ref_error(&hd, &d, 16, &rms1);
        icl.no_lanes = 0;
        printf("| the same, one ray a work-item (integrate_fog; above: 16, integrate_fogmap) | "
               "1920x1080 | %.0f (%.1fx) | - | %.2e | %.2e |\n", ns1, ns1 / ns64, me1, rms1);
        fp_fogmap_release(&st);
    }
#ifdef FP_F_LOD_BOUND   /* (the bench also builds on the tree before --lod-bound) */
    if (all || !strcmp(what, "large")) {
        /* On the 800x600 frame (the exact C reference of 4096x4096 is slow),
         * against 64x64 on the same frame. */
        fp_integrate_data_t d;
        fp_fogmap_stage_t st;
        if (setup(&seed, img64, 64, 1, 3, &st, &d))
            return 1;
        double ns64s = run(&seed, &d, 3), rms64, me64 = ref_error(&seed, &d, 16, &rms64);
        printf("| 64x64 linear, 3 levels, exact | 800x600 | %.0f | - | %.2e | %.2e |\n", ns64s,
               me64, rms64);
        fp_fogmap_release(&st);
        float *img = make_fogmap(4096);
        const int levels = 6;
        if (setup(&seed, img, 4096, 1, levels, &st, &d))
            return 1;
        double ns, me, rms;
        {
            /* Exact: every fine cell crossed (64x as many per unit of length
             * as 64x64), so on every 16th pixel only (a pixel list). */
            size_t np = seed.n / 16;
            int *pix = malloc(np * sizeof *pix);
            float *out = malloc(np * 4 * sizeof *out);
            for (size_t i = 0; i < np; i++)
                pix[i] = (int)(i * 16);   /* holds the pixels ref_error(64) checks */
            fp_integrate_pixels_cl(&icl, &d, &seed.view, seed.depth, pix, np, out);
            double t0 = cpu_s();
            fp_integrate_pixels_cl(&icl, &d, &seed.view, seed.depth, pix, np, out);
            ns = (cpu_s() - t0) * 1e9 / np;
            for (size_t i = 0; i < np; i++)
                seed.got[4 * pix[i] + 3] = out[4 * i + 3];
            me = ref_error(&seed, &d, 64, &rms);
            printf("| 4096x4096 linear, %d levels, exact (every 16th pixel) | 800x600 | %.0f "
                   "(%.1fx 64x64) | - | %.2e | %.2e |\n", levels, ns, ns / ns64s, me, rms);
            free(pix);
            free(out);
        }
        printf("| 4096x4096 linear, %d levels: max coefficient of the levels finer than 0..%d: ",
               levels, levels);
        for (int l = 0; l <= levels; l++)
            printf("%s%.1e", l ? ", " : "", st.tables.lvf[l * FP_LR_STRIDE + FP_LR_TAIL]);
        printf(" | | | | | |\n");
        const double bounds[] = { 1e-4, 1e-3 };
        for (size_t k = 0; k < FP_ARRAY_LEN(bounds); k++) {
            d.fp[FP_F_LOD_BOUND] = bounds[k];
            ns = run(&seed, &d, 1);
            me = ref_error(&seed, &d, 64, &rms);
            printf("| 4096x4096 linear, %d levels, --lod-bound %g | 800x600 | %.0f (%.1fx "
                   "64x64) | <= 2x | %.2e (bound %g) | %.2e |\n", levels, bounds[k], ns,
                   ns / ns64s, me, bounds[k], rms);
        }
        fp_fogmap_release(&st);
        free(img);
    }
#endif
    if (all || !strcmp(what, "march")) {
        /* Exact against marching at the same error, on the frame of seed 000. */
        printf("\n### Exact integration against uniform raymarching (800x600, 64x64 linear, 3 "
               "levels)\n\nErrors of tau against the exact C double reference, every 16th "
               "pixel.\n\n| integrator | ns/px | max abs dtau | RMS dtau |\n|---|---|---|---|\n");
        fp_integrate_data_t d;
        fp_fogmap_stage_t st;
        if (setup(&seed, img64, 64, 1, 3, &st, &d))
            return 1;
        double ns_exact = run(&seed, &d, 3), rms;
        double e_exact = ref_error(&seed, &d, 16, &rms);
        printf("| exact | %.0f | %.2e | %.2e |\n", ns_exact, e_exact, rms);
        double ns_same = 0, e_same = 0;
        int n_same = 0;
        for (int steps = 256; steps <= 4096 && !n_same; steps *= 2) {
            d.fp[FP_F_MODE] = 1;
            d.fp[FP_F_STEPS] = steps;
            double ns = run(&seed, &d, 1);
            double me = ref_error(&seed, &d, 16, &rms);
            printf("| march %d steps | %.0f | %.2e | %.2e |\n", steps, ns, me, rms);
            if (!n_same && me <= fmax(e_exact, 1e-5)) {
                n_same = steps;
                ns_same = ns;
                e_same = me;
            }
        }
        if (n_same)
            printf("\nThe first march within max(exact's error, 1e-5) of the reference: %d steps "
                   "(%.2e), %.1fx the exact integrator's time (goal >= 10x).\n", n_same, e_same,
                   ns_same / ns_exact);
        else
            printf("\nNo march up to 4096 steps comes within max(exact's error, 1e-5) of the "
                   "reference.\n");
        fp_fogmap_release(&st);
    }
    free(img64);
    fp_integrate_cl_release(&icl);
    fp_cl_close(cl);
    return 0;
}

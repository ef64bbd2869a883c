/* make bench (issue 12 (b)): the bounded level of detail of the one walk
 * per ray (--lod-bound) on a 4096x4096 fogmap against the 64x64 one it
 * was made from, on the look of bench_looks.c's fogmap rows (fog rectangle
 * -60,-20,60,160, density 0.1, height 0,5, linear).  Markdown on stdout;
 * figures, never pass/fail.
 *   bench_lod FRAME.exr FOG64.exr FOG4096.exr [triangle|dyadic]
 * FRAME.exr: a frame of the sample scene (bench_looks: 480x270); FOG64.exr:
 * the sample's 64x64 fogmap; FOG4096.exr: it resized to 4096x4096 with
 * oiiotool's triangle filter (bench_looks.c's map).  A third map is made
 * here: the 64x64 map refined onto the 4096 map's dyadic grid (pixel 64 i
 * of the 4096 map holds pixel i, bilinear between, zero past the last),
 * the surface the linear synthesis of fogpipe's own decomposition gives,
 * so that its levels finer than the 64-grid hold nothing but rounding.
 * Cost: CPU time (getrusage user+sys, PoCL's threads included) per pixel of
 * one fog layer, upload and read-back included, minimum of 3 runs after a
 * warm-up (BENCH_LOD_QUICK set: the exact 4096 runs left out).  Error: max
 * |dtau| of the OpenCL layer against the exact C double reference (every
 * level, no early exit) on every 16th pixel. */
/* The segments the C copies of the walks (fog_core.h, compiled into this
 * program) integrate, for the segments per ray. */
static long seg_count;
#define FP_SEG_COUNT() (seg_count++)

#include <limits.h>
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
#include "oiio_bridge.h"
#include "options_all.h"
#include "scatter.h"

#include "bench_util.h"

#include "fog_core.h"

#define STEP 16

static fp_cl_t *cl;
static fp_integrate_cl_t icl;

typedef struct frame_t {
    fp_params_t p;
    fp_frame_t *frame;
    fp_view_t view;
    size_t n;
    const float *depth;
    float *got;
    double *ref;   /* exact tau on every STEP-th pixel */
} frame_t;

static int open_frame(const char *path, frame_t *f)
{
    memset(f, 0, sizeof *f);
    fp_options_defaults(&f->p);
    if (bench_frame_view(path, &f->p, &f->frame, &f->view))
        return FP_ERR;
    f->n = (size_t)f->view.width * f->view.height;
    f->depth = fp_frame_depth(f->frame);
    f->got = malloc(f->n * 4 * sizeof(float));
    f->ref = malloc((f->n / STEP + 1) * sizeof(double));
    /* bench_looks.c's fogmap look. */
    if (fp_options_apply(&f->p, "fog-rect", "-60,-20,60,160", "bench") ||
        fp_options_apply(&f->p, "density", "0.1", "bench") ||
        fp_options_apply(&f->p, "height", "0,5", "bench") ||
        fp_options_apply(&f->p, "basis", "linear", "bench"))
        return FP_ERR;
    return f->got && f->ref ? FP_OK : FP_ERR;
}

static int setup(frame_t *f, const float *img, int size, int levels, fp_fogmap_stage_t *st,
                 fp_integrate_data_t *d)
{
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
    if (fp_integrate_process_cl(&icl, d, &f->view, f->depth, f->got))
        return NAN;
    for (int r = 0; r < reps; r++) {
        double t0 = cpu_s();
        if (fp_integrate_process_cl(&icl, d, &f->view, f->depth, f->got))
            return NAN;
        best = fmin(best, cpu_s() - t0);
    }
    return best * 1e9 / f->n;
}

/* The exact C reference of `d` (every level, no early exit) into f->ref. */
static void reference(frame_t *f, const fp_integrate_data_t *d)
{
    fp_integrate_data_t e = *d;
    e.fp[FP_F_LOD_BOUND] = 0;
    e.fp[FP_F_LOD_MU] = 1;
    e.fp[FP_F_FOOTPRINT] = 0;
    e.fp[FP_F_OD_MAX] = INFINITY;
    e.fp[FP_F_MODE] = 0;
    int w = f->view.width;
    for (size_t i = STEP / 2, k = 0; i < f->n; i += STEP, k++) {
        double dir[3], len;
        fp_view_ray(&f->view, (int)(i % w), (int)(i / w), f->depth[i], dir, &len);
        f->ref[k] = exp(-fp_integrate_optical_depth(&e, f->view.origin, dir, len, 0));
    }
}

/* Segments per ray of `d`'s walk, the C copy (double; the OpenCL walk
 * cuts the same segments up to rounding), on every STEP-th pixel. */
static double segments(const frame_t *f, const fp_integrate_data_t *d)
{
    const fp_fog_tables_t *t = fp_fog_tables_or_empty(d->tables);
    int w = f->view.width;
    size_t rays = 0;
    seg_count = 0;
    for (size_t i = STEP / 2; i < f->n; i += STEP, rays++) {
        double dir[3], len, o[3];
        fp_view_ray(&f->view, (int)(i % w), (int)(i / w), f->depth[i], dir, &len);
        fp_view_origin_at(&f->view, (int)(i % w), (int)(i / w), o);
        fp_fog_od(d->fp, FP_TABLES(t), o[0], o[1], o[2], dir[0], dir[1], dir[2], len, 0);
    }
    return (double)seg_count / rays;
}

static double max_error(const frame_t *f)
{
    double me = 0;
    for (size_t i = STEP / 2, k = 0; i < f->n; i += STEP, k++)
        me = fmax(me, fabs(f->ref[k] - f->got[4 * i + 3]));
    return me;
}

/* The 64x64 map on the 4096 map's dyadic grid: the 4096 map decomposed
 * into 9 levels sits in a domain padded by 256 = 4 x 64 pixels, so the
 * nodes of its level of cell 64 are its pixels 64 i.  Pixel i of the
 * 64x64 goes to node i + 1, bilinear between (the linear synthesis), with
 * node 0 zero and the 64x64's last row and column left out, so that the
 * map rises from zero at its edges as the zero padding does beyond them
 * (an edge with fog on it would be a step at the finest level). */
static float *dyadic(const float *m64, int n64, int scale)
{
    int n = n64 * scale;
    float *img = malloc((size_t)n * n * sizeof *img);
    if (!img)
        return NULL;
    for (int y = 0; y < n; y++) {
        int j = y / scale - 1;
        double fy = (double)(y % scale) / scale;
        for (int x = 0; x < n; x++) {
            int i = x / scale - 1;
            double fx = (double)(x % scale) / scale, c[2][2];
            for (int b = 0; b < 2; b++)
                for (int a = 0; a < 2; a++)
                    c[b][a] = i + a >= 0 && j + b >= 0 && i + a < n64 - 1 && j + b < n64 - 1
                                  ? m64[(size_t)(j + b) * n64 + i + a]
                                  : 0;
            img[(size_t)y * n + x] = (float)((1 - fy) * ((1 - fx) * c[0][0] + fx * c[0][1]) +
                                             fy * ((1 - fx) * c[1][0] + fx * c[1][1]));
        }
    }
    return img;
}

/* What the tensor grids were, printed under the table. */
static char notes[2][256];

/* One 4096x4096 map: exact (on every STEP-th pixel, a pixel list) and
 * the bounds, with the tensor grid (where its error fits the ray: what
 * --lod-bound does) and without it (the dyadic levels alone), against the
 * 64x64 (d64), whose cost *ns64 is measured again before each bound (the
 * least of all its runs: a loaded machine's noise counts against the
 * ratios less). */
static int large(frame_t *f, const char *name, const float *img, const fp_integrate_data_t *d64,
                 double *ns64, char *note)
{
    fp_integrate_data_t d;
    fp_fogmap_stage_t st;
    if (setup(f, img, 4096, 9, &st, &d))
        return FP_ERR;
    /* The same tables without the tensor grid (a serial of their own, so
     * that the device copy is told apart). */
    fp_fog_tables_t nt = *d.tables;
    nt.lvi[FP_TG_ROW * FP_LI_STRIDE + FP_TI_NX] = 0;
    nt.serial = ULONG_MAX - nt.serial;
    const int *ti = d.tables->lvi + FP_TG_ROW * FP_LI_STRIDE;
    double fm = 0;
    for (size_t i = 0; i < (size_t)4096 * 4096; i++)
        fm = fmax(fm, img[i]);
    snprintf(note, 256, "%s: tensor grid %dx%d rectangles%s, eps = max |F - G| = %.2e "
             "(max F %.3g)", name, ti[FP_TI_NX], ti[FP_TI_NY],
             ti[FP_TI_NX] ? "" : " (none: the dyadic levels alone)",
             d.tables->lvf[FP_TG_ROW * FP_LR_STRIDE + FP_TR_EPS], fm);
    reference(f, &d);
    size_t np = f->n / STEP;
    int *pix = malloc(np * sizeof *pix);
    float *out = malloc(np * 4 * sizeof *out);
    if (!pix || !out) {
        free(pix);
        free(out);
        return FP_ERR;
    }
    for (size_t i = 0; i < np; i++)
        pix[i] = (int)(STEP / 2 + i * STEP);
    int quick = getenv("BENCH_LOD_QUICK") != NULL;
    double best = INFINITY;
    for (int r = 0; r < (quick ? 0 : 2); r++) {
        double t0 = cpu_s();
        if (fp_integrate_pixels_cl(&icl, &d, &f->view, f->depth, pix, np, out))
            return FP_ERR;
        best = fmin(best, cpu_s() - t0);
    }
    double ns = best * 1e9 / np;
    for (size_t i = 0; i < np; i++)
        f->got[4 * pix[i] + 3] = out[4 * i + 3];
    if (quick)
        printf("| %s | exact | (BENCH_LOD_QUICK: left out) | | | |\n", name);
    else
        printf("| %s | exact (pixel list: every %dth pixel) | %.0f | %.1fx | %.1e | %.0f |\n",
               name, STEP, ns, ns / *ns64, max_error(f), segments(f, &d));
    free(pix);
    free(out);
    const double bounds[] = { 1e-4, 1e-3 };
    for (size_t k = 0; k < FP_ARRAY_LEN(bounds); k++) {
        for (int tensor = 1; tensor >= 0; tensor--) {
            fp_integrate_data_t db = d;
            db.tables = tensor ? d.tables : &nt;
            db.fp[FP_F_LOD_BOUND] = bounds[k];
            *ns64 = fmin(*ns64, run(f, d64, 3));
            ns = run(f, &db, 3);
            printf("| %s | --lod-bound %g%s | %.0f | %.2fx | %.1e | %.0f |\n", name, bounds[k],
                   tensor ? "" : ", no tensor grid (the dyadic levels alone)", ns, ns / *ns64,
                   max_error(f), segments(f, &db));
        }
    }
    fp_fogmap_release(&st);
    return FP_OK;
}

int main(int argc, char **argv)
{
    if (argc < 4) {
        fprintf(stderr, "usage: bench_lod FRAME.exr FOG64.exr FOG4096.exr [triangle|dyadic]\n");
        return 2;
    }
    setvbuf(stdout, NULL, _IOLBF, 0);
    frame_t f;
    float *m64 = NULL, *m4096 = NULL;
    int w64, h64, w4096, h4096;
    if (open_frame(argv[1], &f) || fp_oiio_read_channel(argv[2], NULL, &m64, &w64, &h64) ||
        fp_oiio_read_channel(argv[3], NULL, &m4096, &w4096, &h4096))
        return 1;   /* (the library printed why) */
    if (w64 != 64 || h64 != 64 || w4096 != 4096 || h4096 != 4096) {
        fprintf(stderr, "bench_lod: expected a 64x64 and a 4096x4096 fogmap (got %dx%d, %dx%d)\n",
                w64, h64, w4096, h4096);
        return 1;
    }
    float *mdy = dyadic(m64, 64, 64);
    if (!mdy || fp_cl_open(NULL, &cl) || fp_integrate_cl_init(cl, &icl))
        return 1;
    const fp_frame_info_t *info = fp_frame_info(f.frame);
    printf("## Bounded level of detail: 4096x4096 against 64x64 (issue 12 (b))\n\n");
    printf("Device: %s. Frame %dx%d; the look of bench_looks.c's fogmap rows. CPU time "
           "(user+sys, getrusage, PoCL's threads included) per pixel of one fog layer, minimum "
           "of 3 runs; max |dtau| against the exact C double reference on every %dth pixel. "
           "4096 (triangle): the 64x64 resized by oiiotool --resize:filter=triangle (kinks "
           "between the 4096 map's dyadic nodes); 4096 (dyadic): the 64x64 on the 4096 map's "
           "grid of cell 64 (finer levels zero up to rounding).\n\n",
           fp_cl_device_label(cl), info->width, info->height, STEP);
    printf("| map | mode | ns/px | x 64x64 | max \\|dtau\\| | segments/ray |\n"
           "|---|---|---|---|---|---|\n");
    fp_integrate_data_t d;
    fp_fogmap_stage_t st;
    if (setup(&f, m64, 64, 3, &st, &d))
        return 1;
    double ns64 = run(&f, &d, 5);
    reference(&f, &d);
    printf("| 64x64, 3 levels | exact | %.0f | 1.0x | %.1e | %.0f |\n", ns64, max_error(&f),
           segments(&f, &d));
    const char *only = argc > 4 ? argv[4] : "";
    if ((strcmp(only, "dyadic") &&
         large(&f, "4096 (triangle), 9 levels", m4096, &d, &ns64, notes[0])) ||
        (strcmp(only, "triangle") &&
         large(&f, "4096 (dyadic), 9 levels", mdy, &d, &ns64, notes[1])))
        return 1;
    printf("\nThe 64x64's least cost over all its runs: %.0f ns/px (the ratios above use the "
           "least up to their row).  Segments per ray: of the C copy of each walk (double) on "
           "the same pixels.  --lod-bound walks the tensor grid (the linear basis' fogmap on "
           "the rectangles between its break nodes, filters/fogmap.c) wherever sigma eps times "
           "the ray's weight fits the bound, else the dyadic levels.\n", ns64);
    for (int i = 0; i < 2; i++)
        if (notes[i][0])
            printf("- %s\n", notes[i]);
    fp_fogmap_release(&st);
    free(mdy);
    free(m64);
    free(m4096);
    free(f.got);
    free(f.ref);
    fp_frame_free(f.frame);
    fp_integrate_cl_release(&icl);
    fp_cl_close(cl);
    return 0;
}

/* make bench: fog self-shadowing (issue 12), the default's cost and error
 * (Markdown on stdout).  Figures, never pass/fail.
 *   bench_selfshadow DIR [DIR...]
 * Each DIR holds frame 1 of the sample scene (scene.0001.exr,
 * shadow.0001.exr, fogmap.exr, as samples/fogpipe-scene writes them).  The look
 * is make bench's "low-sun-shafts + fogmap 64x64, 3 levels" (the preset's
 * options written out, the fogmap linear, 3 levels).
 *
 * Per --self-shadow mode: CPU time (getrusage user+sys, the PoCL threads
 * included) of the OpenCL fog layer of the frame, the self-shadow grid
 * filled again each time as for a frame of a moving camera, minimum of
 * REPS; per pixel beyond --self-shadow off.  Error: the grid's tau_sun
 * against the exact optical depth toward the sun (C, double) at points
 * along the view rays; and the OpenCL fog layer against the exact C
 * reference (--self-shadow exact), max |dS| relative to the largest S. */
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
#include "light_core.h"
#include "scatter_core.h"

#define REPS 3

typedef struct frame_t {
    fp_frame_t *frame;
    fp_view_t view;
    const float *depth;
    size_t n;
    char shadow[4200], fogmap[4200];
} frame_t;

static fp_cl_t *cl;
static fp_integrate_cl_t icl;
static fp_scatter_cl_t scl;

static int look_open(const frame_t *f, look_t *l, const char *self, const char *grid)
{
    static const char *const opts[] = {
        "density", "0.03", "height", "0,inf,15", "fog-color", "0.02,0.025,0.035",
        "sun", "-0.4,0.35,0.6", "sun-color", "1.0,0.9,0.75", "sun-intensity", "5",
        "phase", "mix:0.2,0.75", "shadow-filter", "1", "fog-rect", "-60,-20,60,160",
        "basis", "linear", "levels", "3", NULL };
    memset(l, 0, sizeof *l);
    fp_options_defaults(&l->p);
    for (const char *const *o = opts; *o; o += 2)
        if (fp_options_apply(&l->p, o[0], o[1], "bench"))
            return FP_ERR;
    if (fp_options_apply(&l->p, "shadow-map", f->shadow, "bench") ||
        fp_options_apply(&l->p, "fogmap", f->fogmap, "bench") ||
        fp_options_apply(&l->p, "self-shadow", self, "bench") ||
        (grid && fp_options_apply(&l->p, "self-shadow-grid", grid, "bench")))
        return FP_ERR;
    return look_commit(l, cl, &f->view, f->depth);
}

/* CPU seconds of the OpenCL fog layer (the grid filled again when
 * `refill`, else kept), min of REPS. */
static double run_cl(const frame_t *f, look_t *l, float *out, int refill)
{
    double best = INFINITY;
    if (fp_scatter_process_cl(&scl, &icl, &l->light, &l->fog, &f->view, f->depth, out))
        return NAN;
    for (int r = 0; r < REPS; r++) {
        if (refill)
            scl.grid_key.valid = 0;
        double t0 = cpu_s();
        if (fp_scatter_process_cl(&scl, &icl, &l->light, &l->fog, &f->view, f->depth, out))
            return NAN;
        best = fmin(best, cpu_s() - t0);
    }
    return best;
}

/* The grid's tau_sun against exact at up to npts points along the view
 * rays, uniform in distance over each ray's fog: max relative error; the
 * share of points outside the cascades (exact there). */
static double grid_error(const frame_t *f, look_t *l, int npts, double *outside, double *per)
{
    if (fp_scatter_pixels(&l->light, &l->fog, &f->view, f->depth, NULL, 0, NULL))
        return NAN;
    const double *lt = l->light.lt, *s = lt + FP_LT_SUN_DIR;
    const fp_fog_tables_t *t = fp_fog_tables_or_empty(l->fog.tables);
    double worst = 0;
    int out = 0, n = 0;
    unsigned long long rng = 12345;
    for (int tries = 0; n < npts && tries < 100 * npts; tries++) {
        rng = rng * 6364136223846793005ULL + 1442695040888963407ULL;
        size_t i = (size_t)((rng >> 33) % f->n);
        double u = (double)((rng >> 11) & 0xfffff) / 0x100000;
        int x = (int)(i % (size_t)f->view.width), y = (int)(i / (size_t)f->view.width);
        double dir[3], len, o[3], ta, tb;
        fp_view_ray(&f->view, x, y, f->depth[i], dir, &len);
        fp_view_origin_at(&f->view, x, y, o);
        if (!fp_fog_span(l->fog.fp, o[0], o[1], o[2], dir[0], dir[1], dir[2], len, &ta, &tb) ||
            !isfinite(tb))
            continue;
        double tt = ta + u * (tb - ta), p[3];
        for (int k = 0; k < 3; k++)
            p[k] = o[k] + tt * dir[k];
        double og = fp_sun_od_grid(lt, l->light.grid, p[0], p[1], p[2]);
        n++;
        if (og < -0.5) {
            out++;
            continue;
        }
        double oe = fp_fog_od(l->fog.fp, FP_TABLES(t), p[0], p[1], p[2], s[0], s[1], s[2],
                              INFINITY, 0);
        worst = fmax(worst, fabs(expm1(oe - og)));
        int c;
        double g[3];
        if (fp_sun_od_cell(lt, p[0], p[1], p[2], &c, g))
            per[c] = fmax(per[c], fabs(expm1(oe - og)));
    }
    *outside = n ? (double)out / n : NAN;
    return worst;
}

/* The C reference (exact self-shadowing) on every stride-th pixel against
 * the OpenCL layer: max |dS| relative to the reference's largest S. */
static double layer_error(const frame_t *f, look_t *exact, const float *got, size_t stride)
{
    float view[FP_VIEW_FLOATS];
    fp_view_pack(&f->view, view);
    double smax = 1e-30, m = 0;
    double *ref = malloc(f->n * 3 * sizeof *ref);
    if (!ref)
        return NAN;
    for (size_t i = 0; i < f->n; i += stride) {
        int x = (int)(i % (size_t)f->view.width), y = (int)(i / (size_t)f->view.width);
        double dir[3], len, o[3];
        fp_view_ray(&f->view, x, y, f->depth[i], dir, &len);
        fp_view_origin_at(&f->view, x, y, o);
        fp_scatter_ray(&exact->light, &exact->fog, &f->view, view, f->depth, o, dir, len,
                       ref + 3 * i);
        for (int c = 0; c < 3; c++)
            smax = fmax(smax, fabs(ref[3 * i + c]));
    }
    for (size_t i = 0; i < f->n; i += stride)
        for (int c = 0; c < 3; c++)
            m = fmax(m, fabs(got[4 * i + c] - ref[3 * i + c]) / smax);
    free(ref);
    return m;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: bench_selfshadow DIR [DIR...]\n");
        return 2;
    }
    if (fp_cl_open(NULL, &cl) || fp_integrate_cl_init(cl, &icl) || fp_scatter_cl_init(cl, &scl)) {
        fprintf(stderr, "bench_selfshadow: failed (the message above)\n");
        return 1;
    }
    printf("### Fog self-shadowing: the default (the sun-aligned grid) against exact\n\n"
           "The low-sun-shafts + fogmap 64x64 look (3 levels, linear) on frame 1 of the sample "
           "scene. OpenCL fog layer, CPU time (user+sys) with the grid filled again as for a "
           "moving camera, minimum of %d, and the part of it that filling the grid takes (the "
           "same run with the grid kept, as for a still camera over still fog, subtracted); per "
           "pixel beyond `--self-shadow off` (this includes the segments that the view ray "
           "halves where the sunlight changes fast, which self-shadowing adds). tau_sun: the "
           "grid against the exact optical depth toward the sun (C, double) at 20000 points "
           "along the view rays, max relative error (points outside the cascades are exact). "
           "dS: the OpenCL layer against the exact C reference, max |dS| relative to the "
           "largest S. Device: %s.\n\n",
           REPS, fp_cl_device_label(cl));
    printf("| frame | --self-shadow | grid | CPU ms | of which the grid's fill | "
           "self-shadowing us/px | max rel. err. tau_sun | outside | max dS |\n"
           "|---|---|---|---|---|---|---|---|---|\n");
    int rc = 0;
    for (int a = 1; a < argc; a++) {
        frame_t f;
        memset(&f, 0, sizeof f);
        char path[4200];
        snprintf(path, sizeof path, "%s/scene.0001.exr", argv[a]);
        snprintf(f.shadow, sizeof f.shadow, "%s/shadow.####.exr", argv[a]);
        snprintf(f.fogmap, sizeof f.fogmap, "%s/fogmap.exr", argv[a]);
        fp_params_t p0;
        fp_options_defaults(&p0);
        int r = bench_frame_view(path, &p0, &f.frame, &f.view);
        fp_options_free(&p0);
        if (r) {
            fprintf(stderr, "bench_selfshadow: failed (the message above)\n");
            rc = 1;
            continue;
        }
        f.depth = fp_frame_depth(f.frame);
        f.n = (size_t)f.view.width * f.view.height;
        float *out = malloc(f.n * 4 * sizeof *out);
        static const struct { const char *self, *grid; } modes[] = {
            { "off", NULL }, { "exact", NULL }, { "auto", NULL }, { "auto", "128,128,32" },
            { "auto", "256,256,64" },
        };
        double off = NAN;
        look_t exact;
        int have_exact = look_open(&f, &exact, "exact", NULL) == FP_OK;
        for (size_t k = 0; k < sizeof modes / sizeof *modes && out; k++) {
            look_t l;
            if (look_open(&f, &l, modes[k].self, modes[k].grid)) {
                fprintf(stderr, "bench_selfshadow: failed (the message above)\n");
                rc = 1;
                continue;
            }
            double s = run_cl(&f, &l, out, 1);
            int map = (int)l.light.lt[FP_LT_SELF] == FP_SELF_MAP;
            double kept = map ? run_cl(&f, &l, out, 0) : s;
            if (k == 0)
                off = s;
            double outside = NAN, et = NAN, es = NAN;
            double per[FP_LT_MAX_CASCADES] = { 0, 0, 0, 0 };
            if (map)
                et = grid_error(&f, &l, 20000, &outside, per);
            if (have_exact && k > 0)
                es = layer_error(&f, &exact, out, f.n > 4000 ? f.n / 4000 : 1);
            char g[96];
            if (!map)
                snprintf(g, sizeof g, "-");
            else if (modes[k].grid)
                snprintf(g, sizeof g, "%s", modes[k].grid);
            else
                snprintf(g, sizeof g, "0,0,32 (default: %g,%g,%g)", l.light.lt[FP_LT_GRID_N],
                         l.light.lt[FP_LT_GRID_N + 1], l.light.lt[FP_LT_GRID_N + 2]);
            printf("| %dx%d | %s | %s | %.1f | %.1f | %.2f | %.1e | %.2f%% | %.1e |\n",
                   f.view.width, f.view.height, modes[k].self, g, s * 1e3, (s - kept) * 1e3,
                   (s - off) / f.n * 1e6, et, 100 * outside, es);
            if (map) {
                printf("| | per cascade, finest first: |");
                for (int c = 0; c < (int)l.light.lt[FP_LT_GRID_K]; c++) {
                    const double *box = l.light.lt + FP_LT_CASCADE + 6 * c;
                    printf(" %.2g (cells %.2g x %.2g x %.2g);", per[c], box[3], box[4], box[5]);
                }
                printf(" | | | | | | |\n");
            }
            look_release(&l);
        }
        if (have_exact)
            look_release(&exact);
        free(out);
        fp_frame_free(f.frame);
    }
    printf("\n");
    fp_scatter_cl_release(&scl);
    fp_integrate_cl_release(&icl);
    fp_cl_close(cl);
    return rc;
}

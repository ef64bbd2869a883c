/* make bench: the looks of issue 12, each as the marginal fog cost of a
 * fogpipe run (CPU ns per pixel, getrusage user+sys of the run minus the
 * same run with --no-fog) with its error against the exact C reference and
 * the goal beside it (Markdown on stdout).  Figures, never
 * pass/fail.
 *   bench_looks HD_DIR SCRATCH_DIR [shafts|light]
 * HD_DIR: scene.0001.exr .. scene.0024.exr at 1920x1080 (tests/bench.sh's);
 * SCRATCH_DIR is made here: smaller frames of the sample scene (FP_SCENE),
 * the fogmaps, the outputs.  Environment: FOGPIPE, FP_SCENE, OIIOTOOL
 * (default oiiotool), FP_SRCDIR (the presets; default .).
 *
 * Marginal cost: the one-time set-up of a run (loading the OpenCL driver,
 * the programs, the fogmap's decomposition) is left out, as a long shot
 * amortises it: cost = [fog(N frames) - fog(1 frame)] - [no-fog(N) -
 * no-fog(1)], over the pixels of frames 2..N, each run the minimum CPU time
 * of 3. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "camera.h"
#include "clrt.h"
#include "exrio.h"
#include "fogmap.h"
#include "fp.h"
#include "integrate.h"
#include "options_all.h"
#include "scatter.h"

#include "bench_util.h"

/* The shared ray code in double (fp_phase, the light layout). */
#include "fog_core.h"
#include "light_core.h"

extern char **environ;

#define REPS 3
#define MAX_ARGS 64

static const char *fogpipe_bin, *scene_bin, *oiiotool_bin, *scratch;

/* Run argv (stdout and stderr to /dev/null); CPU seconds (user + sys of
 * the process and its threads), or NAN when it failed. */
static double run_cpu(char *const *argv)
{
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
    pid_t pid;
    int err = posix_spawnp(&pid, argv[0], &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (err) {
        fprintf(stderr, "bench_looks: %s: cannot start (%s)\n", argv[0], strerror(err));
        return NAN;
    }
    int status;
    struct rusage ru;
    if (wait4(pid, &status, 0, &ru) != pid || !WIFEXITED(status) || WEXITSTATUS(status)) {
        fprintf(stderr, "bench_looks: failed:");
        for (char *const *a = argv; *a; a++)
            fprintf(stderr, " %s", *a);
        fprintf(stderr, "\n");
        return NAN;
    }
    return ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + ru.ru_stime.tv_sec +
           ru.ru_stime.tv_usec * 1e-6;
}

/* A set of frames: DIR/scene.####.exr (and shadow.####.exr), N frames. */
typedef struct set_t {
    const char *name;
    char dir[4096];
    int width, height, frames;
} set_t;

/* fogpipe's argv over frames 1..nframes of a set, with the look's options
 * and any extra ones (NULL-terminated lists); --stats to stats if given. */
static int build_argv(char **argv, char *buf, size_t bufsz, const set_t *s, int nframes,
                      const char *const *opts, const char *const *extra, const char *stats)
{
    int n = 0;
    size_t used = 0;
#define PUT(str)                                                             \
    do {                                                                     \
        size_t len_ = strlen(str) + 1;                                       \
        if (n + 1 >= MAX_ARGS || used + len_ > bufsz)                        \
            return -1;                                                       \
        memcpy(buf + used, str, len_);                                       \
        argv[n++] = buf + used;                                              \
        used += len_;                                                        \
    } while (0)
    char tmp[4200];
    PUT(fogpipe_bin);
    PUT("-q");
    snprintf(tmp, sizeof tmp, "%s/scene.####.exr", s->dir);
    PUT("-i");
    PUT(tmp);
    snprintf(tmp, sizeof tmp, "%s/out-%s/out.####.exr", scratch, s->name);
    PUT("-o");
    PUT(tmp);
    snprintf(tmp, sizeof tmp, "1-%d", nframes);
    PUT("--frames");
    PUT(tmp);
    if (stats) {
        PUT("--stats");
        PUT(stats);
    }
    for (const char *const *o = opts; o && *o; o++) {
        if (strstr(*o, "{dir}")) {
            const char *at = strstr(*o, "{dir}");
            snprintf(tmp, sizeof tmp, "%.*s%s%s", (int)(at - *o), *o, s->dir, at + 5);
            PUT(tmp);
        } else if (strstr(*o, "{scratch}")) {
            const char *at = strstr(*o, "{scratch}");
            snprintf(tmp, sizeof tmp, "%.*s%s%s", (int)(at - *o), *o, scratch, at + 9);
            PUT(tmp);
        } else if (strstr(*o, "{src}")) {
            const char *at = strstr(*o, "{src}");
            const char *src = getenv("FP_SRCDIR") ? getenv("FP_SRCDIR") : ".";
            snprintf(tmp, sizeof tmp, "%.*s%s%s", (int)(at - *o), *o, src, at + 5);
            PUT(tmp);
        } else {
            PUT(*o);
        }
    }
    for (const char *const *o = extra; o && *o; o++)
        PUT(*o);
#undef PUT
    argv[n] = NULL;
    return n;
}

static double fps_of(const char *stats)
{
    FILE *f = fopen(stats, "r");
    char line[512];
    double fps = NAN;
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, " \"fps\": %lf", &fps) == 1)
            break;
    if (f)
        fclose(f);
    return fps;
}

/* Runs of fogpipe on set s interleaved (run k: nframes[k] frames, opts[k]
 * and extra[k] as min_cpu): reps rounds of one run of each, so that a load
 * drifting on the shared machine weighs on all of them alike; each run's
 * least CPU seconds into cpu[k] and (fps not NULL) best frames/s into
 * fps[k].  0, or -1 if a run failed. */
#define SEQ_REPS 5
static int rounds(const set_t *s, int nruns, const int *nframes, const char *const *const *opts,
                  const char *const *const *extra, int reps, double *cpu, double *fps)
{
    static char *argv[4][MAX_ARGS], buf[4][32768];
    char stats[4200];
    snprintf(stats, sizeof stats, "%s/stats.json", scratch);
    if (nruns > 4)
        return -1;
    for (int k = 0; k < nruns; k++) {
        if (build_argv(argv[k], buf[k], sizeof buf[k], s, nframes[k], opts[k], extra[k],
                       fps ? stats : NULL) < 0)
            return -1;
        cpu[k] = INFINITY;
        if (fps)
            fps[k] = 0;
    }
    for (int r = 0; r < reps; r++)
        for (int k = 0; k < nruns; k++) {
            double t = run_cpu(argv[k]);
            if (isnan(t))
                return -1;
            cpu[k] = fmin(cpu[k], t);
            if (fps)
                fps[k] = fmax(fps[k], fps_of(stats));
        }
    return 0;
}

static double px_per_frame(const set_t *s) { return (double)s->width * s->height; }

/* Marginal ns per pixel of a look over frames 2..N of its set; io: options
 * of both runs (NULL: none; the set's --no-fog runs are then shared).
 * io_ns (when not NULL): the I/O cost of the same frames, the --no-fog
 * run's own marginal CPU per pixel (reading, decoding, encoding and
 * writing a frame), the yardstick of issue 26's goals. */
static double marginal_ns_io(set_t *s, const char *const *opts, const char *const *io,
                             double *io_ns)
{
    const char *nofog[8] = { "--no-fog" };
    for (int i = 0; io && io[i] && i < 6; i++)
        nofog[i + 1] = io[i];
    /* The four runs interleaved, REPS rounds. */
    const int nframes[4] = { 1, s->frames, 1, s->frames };
    const char *const *o[4] = { NULL, NULL, opts, opts };
    const char *const *e[4] = { nofog, nofog, io, io };
    double cpu[4];
    if (rounds(s, 4, nframes, o, e, REPS, cpu, NULL))
        return NAN;
    double fog = (cpu[3] - cpu[2]) - (cpu[1] - cpu[0]);
    if (io_ns)
        *io_ns = (cpu[1] - cpu[0]) / ((s->frames - 1) * px_per_frame(s)) * 1e9;
    return fog / ((s->frames - 1) * px_per_frame(s)) * 1e9;
}

static double marginal_ns(set_t *s, const char *const *opts, const char *const *io)
{
    return marginal_ns_io(s, opts, io, NULL);
}

/* Error of a look's OpenCL fog layer against the exact C reference (the
 * look's options with every fast path turned off) on every stride-th
 * pixel of frame 1 of its set: max |dtau| and max |dS| relative to the
 * reference's largest S. */
static fp_cl_t *cl;
static fp_integrate_cl_t icl;
static fp_scatter_cl_t scl;

static const char *const exact_opts[] = { "--integrator", "exact", "--self-shadow", "exact",
                                          "--lod-mu", "1", "--lod-footprint", "0",
                                          "--min-transmittance", "0", "--fog-resolution", "1",
                                          NULL };

typedef struct frame1_t {
    fp_frame_t *frame;
    fp_view_t view;
    const float *depth;
    int *pix;
    size_t npix;
} frame1_t;

static int frame1_open(const set_t *s, size_t target, frame1_t *f)
{
    memset(f, 0, sizeof *f);
    char path[4200];
    snprintf(path, sizeof path, "%s/scene.0001.exr", s->dir);
    fp_params_t p0;
    fp_options_defaults(&p0);
    int rc = bench_frame_view(path, &p0, &f->frame, &f->view);
    fp_options_free(&p0);
    if (rc)
        return rc;
    f->depth = fp_frame_depth(f->frame);
    size_t n = (size_t)f->view.width * f->view.height;
    size_t stride = n / target > 1 ? n / target : 1;
    if (stride > 1 && stride % 2 == 0)
        stride++; /* odd: not one column of the frame */
    f->npix = (n + stride - 1) / stride;
    f->pix = malloc(f->npix * sizeof *f->pix);
    if (!f->pix)
        return fp_error("out of memory");
    for (size_t k = 0; k < f->npix; k++)
        f->pix[k] = (int)(k * stride);
    return FP_OK;
}

static void frame1_close(frame1_t *f)
{
    if (f->frame)
        fp_frame_free(f->frame);
    free(f->pix);
}

static int look_open(const set_t *s, const frame1_t *f, const char *const *opts,
                     const char *const *extra, look_t *l)
{
    char *argv[MAX_ARGS], buf[32768];
    memset(l, 0, sizeof *l);
    fp_options_defaults(&l->p);
    int argc = build_argv(argv, buf, sizeof buf, s, 1, opts, extra, NULL);
    if (argc < 0 || fp_options_parse(argc, argv, &l->p))
        return FP_ERR;
    return look_commit(l, cl, &f->view, f->depth);
}

static int look_layer(look_t *l, const frame1_t *f, int use_cl, float *out)
{
    if (l->light.active)
        return use_cl ? fp_scatter_pixels_cl(&scl, &icl, &l->light, &l->fog, &f->view, f->depth,
                                             f->pix, f->npix, out)
                      : fp_scatter_pixels(&l->light, &l->fog, &f->view, f->depth, f->pix,
                                          f->npix, out);
    return use_cl ? fp_integrate_pixels_cl(&icl, &l->fog, &f->view, f->depth, f->pix, f->npix, out)
                  : fp_integrate_pixels(&l->fog, &f->view, f->depth, f->pix, f->npix, out);
}

typedef struct err_t {
    double tau, s;
} err_t;

static err_t compare(const float *a, const float *ref, size_t n)
{
    double smax = 1e-30;
    err_t e = { 0, 0 };
    for (size_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++)
            smax = fmax(smax, fabs((double)ref[4 * i + c]));
    for (size_t i = 0; i < n; i++) {
        for (int c = 0; c < 3; c++)
            e.s = fmax(e.s, fabs((double)a[4 * i + c] - ref[4 * i + c]) / smax);
        e.tau = fmax(e.tau, fabs((double)a[4 * i + 3] - ref[4 * i + 3]));
    }
    return e;
}

/* The look's layer (OpenCL, its own options) against the exact C
 * reference; the reference's layer into ref when given. */
static int look_error(const set_t *s, const frame1_t *f, const char *const *opts,
                      const char *const *extra, err_t *e, float *ref_out)
{
    look_t l, r;
    size_t n = f->npix;
    float *got = malloc(n * 4 * sizeof *got), *ref = malloc(n * 4 * sizeof *ref);
    int rc = !got || !ref ? fp_error("out of memory") : FP_OK;
    if (rc == FP_OK && (rc = look_open(s, f, opts, extra, &l)) == FP_OK) {
        rc = look_layer(&l, f, 1, got);
        look_release(&l);
    }
    if (rc == FP_OK && (rc = look_open(s, f, opts, exact_opts, &r)) == FP_OK) {
        rc = look_layer(&r, f, 0, ref);
        look_release(&r);
    }
    if (rc == FP_OK) {
        *e = compare(got, ref, n);
        if (ref_out)
            memcpy(ref_out, ref, n * 4 * sizeof *ref);
    }
    free(got);
    free(ref);
    return rc;
}

static int spawn_ok(char *const *argv) { return !isnan(run_cpu(argv)); }

static void fmt_ns(char *buf, size_t n, double ns)
{
    if (isnan(ns))
        snprintf(buf, n, "failed");
    else if (ns >= 1000)
        snprintf(buf, n, "%.2f us/px", ns / 1000);
    else
        snprintf(buf, n, "%.1f ns/px", ns);
}

/* Issue 13: the low-sun-shafts preset with a 2048x2048 sun map at 1080p,
 * its marginal cost and its error against brute force (the sun's share
 * of about 200 pixels of frame 1: fp_scatter_sun_brute, 1e5 steps per
 * ray, point-sampled visibility, times albedo E p(mu); the look run with
 * --fog-color 0 so that S is the sun's share alone). */
static void shafts_section(const char *scratch_dir)
{
    set_t sh = { "shafts", "", 1920, 1080, 3 };
    snprintf(sh.dir, sizeof sh.dir, "%s/shafts", scratch_dir);
    char out[4200];
    snprintf(out, sizeof out, "%s/out-shafts", scratch_dir);
    char *a[] = { (char *)scene_bin, "-o", sh.dir, "--width", "1920", "--height", "1080",
                  "--frames", "1-3", "--shadow-size", "2048", NULL };
    if ((mkdir(out, 0777) && errno != EEXIST) || !spawn_ok(a)) {
        fprintf(stderr, "bench_looks: no frames for the shafts\n");
        return;
    }
    const char *const look[] = { "--preset", "{src}/samples/presets/low-sun-shafts.preset",
                                 "--shadow-map", "{dir}/shadow.####.exr", NULL };
    double io_ns = NAN;
    double ns = marginal_ns_io(&sh, look, NULL, &io_ns);
    frame1_t f;
    look_t l;
    static const char *const dark[] = { "--fog-color", "0,0,0", NULL };
    double max_c = NAN, max_cl = NAN, mean_c = 0;
    size_t counted = 0;
    if (frame1_open(&sh, 200, &f) == FP_OK && look_open(&sh, &f, look, dark, &l) == FP_OK) {
        size_t n = f.npix;
        float *got = malloc(n * 4 * sizeof *got), *ref = malloc(n * 4 * sizeof *ref);
        double *want = malloc(n * 3 * sizeof *want), smax = 0;
        if (got && ref && want &&
            fp_scatter_pixels_cl(&scl, &icl, &l.light, &l.fog, &f.view, f.depth, f.pix, n,
                                 got) == FP_OK &&
            fp_scatter_pixels(&l.light, &l.fog, &f.view, f.depth, f.pix, n, ref) == FP_OK) {
            const double *lt = l.light.lt, *sun = lt + FP_LT_SUN_DIR;
            for (size_t k = 0; k < n; k++) {
                int x = f.pix[k] % f.view.width, y = f.pix[k] / f.view.width;
                double o[3], d[3], len;
                fp_view_ray(&f.view, x, y, f.depth[f.pix[k]], d, &len);
                fp_view_origin_at(&f.view, x, y, o);
                double b = fp_scatter_sun_brute(&l.light, &l.fog, o, d, len, 100000, NULL, NULL);
                double ph = fp_phase((int)lt[FP_LT_PHASE], lt[FP_LT_PHASE + 1],
                                     lt[FP_LT_PHASE + 2], d[0] * sun[0] + d[1] * sun[1] +
                                     d[2] * sun[2]);
                for (int c = 0; c < 3; c++) {
                    want[3 * k + c] = lt[FP_LT_ALBEDO] * lt[FP_LT_SUN_E + c] * ph * b;
                    smax = fmax(smax, want[3 * k + c]);
                }
            }
            max_c = max_cl = 0;
            for (size_t k = 0; k < n; k++)
                for (int c = 0; c < 3; c++) {
                    double w = want[3 * k + c], floor_ = fmax(w, 1e-2 * smax);
                    double ec = fabs(ref[4 * k + c] - w) / floor_;
                    max_c = fmax(max_c, ec);
                    max_cl = fmax(max_cl, fabs(got[4 * k + c] - w) / floor_);
                    mean_c += ec;
                    counted++;
                }
        }
        free(got);
        free(ref);
        free(want);
        look_release(&l);
    }
    frame1_close(&f);
    char nss[64];
    fmt_ns(nss, sizeof nss, ns);
    printf("\n## Issue 13: shafts along the shadow map\n\n"
           "The low-sun-shafts preset with the sample scene's 2048x2048 sun map at 1920x1080 "
           "(marginal CPU as above, frames 2-3): **%s**, %.1fx the I/O cost of the same frames "
           "(%.1f ns/px; issue 26's goal <= 5x: %s; issue 13's <= 1.5 us/px, 16.2 us/px before). "
           "Against brute force (1e5 midpoint steps per ray, point-sampled map, exact "
           "self-shadowing per point) on %zu pixels of frame 1, the sun's share relative to "
           "itself (at least 1%% of the largest): C reference max %.1e (mean %.1e), OpenCL "
           "(float) max %.1e; the issue's bound 1e-4 (its test: tests/test_shafts, "
           "test_shafts_brute).\n",
           nss, ns / io_ns, io_ns, ns <= 5 * io_ns ? "met" : "not met", f.npix, max_c,
           counted ? mean_c / counted : NAN, max_cl);
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: bench_looks HD_DIR SCRATCH_DIR [shafts|light]\n");
        return 2;
    }
    setvbuf(stdout, NULL, _IOLBF, 0);
    fogpipe_bin = getenv("FOGPIPE") ? getenv("FOGPIPE") : "./fogpipe";
    scene_bin = getenv("FP_SCENE") ? getenv("FP_SCENE") : "./samples/fogpipe-scene";
    oiiotool_bin = getenv("OIIOTOOL") && *getenv("OIIOTOOL") ? getenv("OIIOTOOL") : "oiiotool";
    scratch = argv[2];
    if (mkdir(scratch, 0777) && errno != EEXIST) {
        fprintf(stderr, "bench_looks: %s: cannot make the directory (%s)\n", scratch,
                strerror(errno));
        return 1;
    }
    /* 24 frames: the height fog's marginal (~20 ms a frame) stands well
     * above the runs' start-up noise (+-0.1 s), and the pipeline's first
     * frames (its buffers' first pages) weigh less. */
    set_t hd = { "hd", "", 1920, 1080, 24 };
    /* Several frames each, so that the marginal cost stands well above a
     * run's start-up noise on a shared machine. */
    set_t mid = { "mid", "", 480, 270, 4 };
    set_t small = { "small", "", 160, 90, 8 };
    /* The issue's own frame for the sun's shafts with a fogmap, with the
     * scene's shadow maps (the per-frame costs, the self-shadow grid's fill
     * and the map's pyramid, weigh ~2x more per pixel at 160x90). */
    set_t hds = { "hds", "", 1920, 1080, 3 };
    snprintf(hd.dir, sizeof hd.dir, "%s", argv[1]);
    snprintf(mid.dir, sizeof mid.dir, "%s/mid", scratch);
    snprintf(small.dir, sizeof small.dir, "%s/small", scratch);
    snprintf(hds.dir, sizeof hds.dir, "%s/hds", scratch);
    set_t *sets[] = { &hd, &mid, &small, &hds };
    for (size_t k = 0; k < FP_ARRAY_LEN(sets); k++) {
        char d[4200];
        snprintf(d, sizeof d, "%s/out-%s", scratch, sets[k]->name);
        if (mkdir(d, 0777) && errno != EEXIST) {
            fprintf(stderr, "bench_looks: %s: cannot make the directory (%s)\n", d,
                    strerror(errno));
            return 1;
        }
    }
    /* The smaller frames, with the sun's shadow maps. */
    for (int k = 1; k < 4; k++) {
        set_t *s = sets[k];
        char w[16], h[16], fr[32];
        snprintf(w, sizeof w, "%d", s->width);
        snprintf(h, sizeof h, "%d", s->height);
        snprintf(fr, sizeof fr, "1-%d", s->frames);
        char *a[] = { (char *)scene_bin, "-o", s->dir, "--width", w, "--height", h, "--frames",
                      fr, NULL };
        if (!spawn_ok(a))
            return 1;
    }
    /* The fogmaps: the sample's 64x64, and the same fog at 4096x4096
     * (bilinear upsampling, the surface the linear basis makes of the
     * 64x64 map), decomposed into 9 levels so that its coarsest level is
     * the 64x64 map's with 3 (8x8). */
    char fog64[4200], fog4096[4200];
    snprintf(fog64, sizeof fog64, "%s/fogmap.exr", mid.dir);
    snprintf(fog4096, sizeof fog4096, "%s/fog4096.exr", scratch);
    {
        char *a[] = { (char *)oiiotool_bin, fog64, "--resize:filter=triangle", "4096x4096",
                      "-d", "float", "-o", fog4096, NULL };
        if (!spawn_ok(a))
            return 1;
    }
    if (fp_cl_open(NULL, &cl) || fp_integrate_cl_init(cl, &icl) || fp_scatter_cl_init(cl, &scl))
        return 1;
    /* bench_looks HD_DIR SCRATCH_DIR shafts: issue 13's section alone. */
    if (argc > 3 && strcmp(argv[3], "shafts") == 0) {
        shafts_section(scratch);
        fp_scatter_cl_release(&scl);
        fp_integrate_cl_release(&icl);
        fp_cl_close(cl);
        return 0;
    }

    /* bench_looks HD_DIR SCRATCH_DIR light: the light half's rows of issue
     * 26 (height fog, the lamps, the shafts) and issue 13's section. */
    int light_only = argc > 3 && strcmp(argv[3], "light") == 0;
    const char *const height_fog[] = { NULL };
    const char *const uncompressed[] = { "--compression", "none", NULL };
    const char *const fogmap64[] = { "--fogmap", "{scratch}/mid/fogmap.exr", "--fog-rect",
                                     "-60,-20,60,160", "--density", "0.1", "--height", "0,5",
                                     "--basis", "linear", "--levels", "3", NULL };
    const char *const lamps[] = { "--preset", "{src}/samples/presets/night-street-lamps.preset",
                                  NULL };
    const char *const shafts[] = { "--preset", "{src}/samples/presets/low-sun-shafts.preset",
                                   "--shadow-map", "{dir}/shadow.####.exr", "--fogmap",
                                   "{scratch}/mid/fogmap.exr", "--fog-rect", "-60,-20,60,160",
                                   "--basis", "linear", "--levels", "3", NULL };
    const char *const fogmap4096[] = { "--fogmap", "{scratch}/fog4096.exr", "--fog-rect",
                                       "-60,-20,60,160", "--density", "0.1", "--height", "0,5",
                                       "--basis", "linear", "--levels", "9", NULL };

    printf("## Issue 12: the looks, marginal fog cost against the goals\n\n");
    printf("Marginal CPU time per pixel (getrusage user+sys of a fogpipe run minus the same run "
           "with `--no-fog`, minimum of %d runs each, the four runs interleaved round by round), "
           "the run's one-time set-up (OpenCL driver, programs, fogmap decomposition) left out: "
           "[fog(N frames) - fog(1)] - [no-fog(N) - "
           "no-fog(1)] over the pixels of frames 2..N. Error: the OpenCL fog layer against the "
           "exact C double reference (every fast path off) on about 4000 pixels of frame 1: max "
           "|dtau| and max |dS| relative to the largest S. Device: %s.\n\n",
           REPS, fp_cl_device_label(cl));
    printf("I/O cost: the `--no-fog` run's own marginal CPU per pixel over the same frames "
           "(read, decode, encode, write); ratio: the look's marginal fog cost over it, against "
           "issue 26's goal.\n\n");
    printf("| look | frames | marginal CPU | I/O cost | ratio | goal (issue 26) | "
           "max \\|dtau\\| | max dS | goal (issue 12) |\n"
           "|---|---|---|---|---|---|---|---|---|\n");
    struct {
        const char *name;
        set_t *set;
        const char *const *opts;
        const char *goal;
        const char *const *io;
        double ns;
        double goal_x;    /* issue 26: at most this many times the I/O cost (0: none) */
        int light;        /* one of the light half's rows (bench_looks ... light) */
    } looks[] = {
        { "height fog (closed form)", &hd, height_fog, "<= 20 ns/px", NULL, NAN, 0.25, 1 },
        { "height fog, both runs writing uncompressed EXRs (the fog without the encoder's "
          "data-dependent cost)", &hd, height_fog, "-", uncompressed, NAN, 0, 0 },
        { "fogmap 64x64 linear, 3 levels, exact", &mid, fogmap64, "<= 1 us/px", NULL, NAN, 5, 0 },
        { "night-street-lamps preset (2 points + spot)", &mid, lamps, "<= 3 us/px", NULL, NAN,
          5, 1 },
        { "night-street-lamps preset at 1920x1080", &hds, lamps, "-", NULL, NAN, 5, 1 },
        { "low-sun-shafts + fogmap 64x64, 3 levels (default self-shadowing)", &hds, shafts,
          "<= 5 us/px", NULL, NAN, 10, 1 },
        { "the same at 160x90 (the grid's fill and the map's pyramid per frame weigh more)",
          &small, shafts, "-", NULL, NAN, 0, 0 },
        { "fogmap 64x64 linear, 3 levels (at 160x90, for the ratio below)", &small, fogmap64,
          "-", NULL, NAN, 0, 0 },
        { "fogmap 4096x4096 linear, 9 levels (the same fog)", &small, fogmap4096,
          "<= 2x the 64x64 at max \\|dtau\\| <= 1e-4", NULL, NAN, 0, 0 },
    };
    for (size_t k = 0; k < FP_ARRAY_LEN(looks); k++) {
        set_t *s = looks[k].set;
        if (light_only && !looks[k].light)
            continue;
        double io_ns = NAN;
        looks[k].ns = marginal_ns_io(s, looks[k].opts, looks[k].io, &io_ns);
        frame1_t f;
        err_t e = { NAN, NAN };
        if (frame1_open(s, 4000, &f) || look_error(s, &f, looks[k].opts, NULL, &e, NULL))
            fprintf(stderr, "bench_looks: %s: no error figure\n", looks[k].name);
        frame1_close(&f);
        char ns[64];
        fmt_ns(ns, sizeof ns, looks[k].ns);
        char io[64], goal_x[64];
        fmt_ns(io, sizeof io, io_ns);
        if (looks[k].goal_x > 0)
            snprintf(goal_x, sizeof goal_x, "<= %gx (%s)", looks[k].goal_x,
                     looks[k].ns <= looks[k].goal_x * io_ns ? "met" : "not met");
        else
            snprintf(goal_x, sizeof goal_x, "-");
        printf("| %s | %dx%d, %d | %s | %s | %.2fx | %s | %.1e | %.1e | %s |\n", looks[k].name,
               s->width, s->height, s->frames, ns, io, looks[k].ns / io_ns, goal_x, e.tau, e.s,
               looks[k].goal);
    }
    if (light_only) {
        shafts_section(scratch);
        fp_scatter_cl_release(&scl);
        fp_integrate_cl_release(&icl);
        fp_cl_close(cl);
        return 0;
    }
    printf("\n4096x4096 against 64x64 (160x90): %.1fx the cost (exact; `--lod-bound` on this "
           "map and on one whose finer levels vanish: tests/bench_lod below).\n",
           looks[8].ns / looks[7].ns);

    /* Exact against the uniform march at the same max error: the march
     * with the fewest steps (powers of two) whose max |dtau| against the
     * exact C reference is within 1e-5, as exact's own is. */
    {
        frame1_t f;
        if (frame1_open(&mid, 4000, &f) == FP_OK) {
            err_t ee = { NAN, NAN };
            look_error(&mid, &f, fogmap64, NULL, &ee, NULL);
            int steps = 0;
            err_t em = { NAN, NAN };
            char steps_s[16];
            const char *march[] = { "--integrator", "march", "--steps", steps_s, NULL };
            for (int n = 64; n <= 16384; n *= 2) {
                snprintf(steps_s, sizeof steps_s, "%d", n);
                if (look_error(&mid, &f, fogmap64, march, &em, NULL))
                    break;
                if (em.tau <= 1e-5) {
                    steps = n;
                    break;
                }
            }
            frame1_close(&f);
            const char *opts[32];
            size_t m = 0;
            for (const char *const *o = fogmap64; *o; o++)
                opts[m++] = *o;
            for (const char *const *o = march; *o; o++)
                opts[m++] = *o;
            opts[m] = NULL;
            double mns = steps ? marginal_ns(&mid, opts, NULL) : NAN;
            printf("\nExact against the uniform march at the same max error (fogmap 64x64 linear, "
                   "3 levels, %dx%d): exact %.2f us/px, max |dtau| %.1e; march %d steps %.2f "
                   "us/px, max |dtau| %.1e: **exact %.1fx faster** (goal >= 10x).\n",
                   mid.width, mid.height, looks[2].ns / 1000, ee.tau, steps, mns / 1000, em.tau,
                   mns / looks[2].ns);
        }
    }

    /* Whole sequence: frames/s (--stats) and CPU, the runs interleaved. */
    {
        static const char *const nofog[] = { "--no-fog", NULL };
        static const char *const nofog_off[] = { "--no-fog", "--pipeline", "off", NULL };
        const char *const *opts[3] = { NULL, NULL, height_fog };
        const char *const *extra[3] = { nofog, nofog_off, NULL };
        double cpu[3], fps[3];
        const int nframes[3] = { hd.frames, hd.frames, hd.frames };
        if (rounds(&hd, 3, nframes, opts, extra, SEQ_REPS, cpu, fps))
            return 1;
        printf("\n1920x1080, %d frames (the three runs interleaved, best of %d rounds): "
               "`--no-fog` %.2f frames/s pipelined, %.2f with `--pipeline off`: **%.2fx** (goal "
               ">= 1.7x). Height fog %.2f frames/s: --no-fog is **%.2fx** faster (goal <= 1.2x); "
               "CPU %.2f s against %.2f s (%.2fx). Frames/s are wall time (other work on the "
               "machine lowers them).\n",
               hd.frames, SEQ_REPS, fps[0], fps[1], fps[0] / fps[1], fps[2], fps[0] / fps[2],
               cpu[2], cpu[0], cpu[2] / cpu[0]);
    }
    shafts_section(scratch);
    fp_scatter_cl_release(&scl);
    fp_integrate_cl_release(&icl);
    fp_cl_close(cl);
    return 0;
}

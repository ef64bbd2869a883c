/* fogpipe stage "reference": the Monte Carlo reference of the light in the
 * fog (--integrator reference, seed 004).  It estimates the same fog layer
 * (S.rgb, tau) as the deterministic integrator (filters/scatter.h) from
 * the fog's point extinction only: free flights by delta tracking
 * (decomposition tracking: the part of sigma_t that the height profiles
 * give is inverted exactly, the fogmap's residual tracked against a
 * majorant grid), transmittances by residual ratio tracking, next-event
 * estimation to the sun and the local lights at every real collision,
 * phase-function sampling for --bounces N further scattering events.
 * Deterministic for a given --seed: the random numbers of pixel i, sample
 * s come from (seed, i, s) (kernels/rng.h), the first free flight's from
 * a rotated (0,2)-sequence over s.  The estimator is
 * kernels/reference_core.h (its comment has the details); the C version
 * here (double) is what the tests drive, the OpenCL one (float,
 * kernels/reference.cl) agrees with it statistically. */
#ifndef FP_REFERENCE_H
#define FP_REFERENCE_H

#include <stdint.h>

#include "camera.h"
#include "clrt.h"
#include "integrate.h"
#include "options.h"
#include "params.h"
#include "scatter.h"

#define FP_RP_COUNT_ 40       /* kernels/reference_core.h FP_RP_COUNT */
#define FP_REFERENCE_GRID 32  /* grid columns along each axis of a square box */

extern const fp_option_t fp_reference_options[];

/* The majorant grid: per cell of an axis-aligned box in fog space, the
 * bounds Fmin <= F <= Fmax of the fogmap surface over the cell (2 floats
 * per cell, x fastest), and the parameter array the estimator reads
 * (FP_RP_*).  Without a fogmap F = 1 and there are no cells. */
typedef struct fp_reference_grid_t {
    double rp[FP_RP_COUNT_];
    int n[3];
    float *cells;
} fp_reference_grid_t;

/* The bounds over the box lo..hi cut into n[0] x n[1] x n[2] cells (fills
 * g->rp's grid and fogmap entries; bounces 0, control and stratification
 * on). */
int fp_reference_grid_fill(const fp_integrate_data_t *fog, const double lo[3], const double hi[3],
                           const int n[3], fp_reference_grid_t *g);

/* The box that matters for one frame: the camera, the visible stretch of
 * every view ray (sky rays to where their fog ends, within twice the
 * farthest surface or light), the local lights, and the box swept toward
 * the sun; cut into about cells^2 columns shaped after the box, one cell
 * high (F does not vary along y; the height profiles are bounded per
 * segment exactly).  `cells` < 1: FP_REFERENCE_GRID.  Without a fogmap,
 * no cells. */
int fp_reference_grid_build(const fp_integrate_data_t *fog, const fp_scatter_data_t *sd,
                            const fp_view_t *v, const float *depth, int cells,
                            fp_reference_grid_t *g);

void fp_reference_grid_release(fp_reference_grid_t *g);

/* The pieces of the estimator, in double precision, for the tests.
 * `rng` is a kernels/rng.h state (fp_rng_t's one word). */
double fp_reference_sigma_t(const fp_integrate_data_t *fog, const double x[3]);
/* Where the fog ends along o + t d within [0, len] (-INFINITY: none). */
double fp_reference_fog_end(const fp_integrate_data_t *fog, const double o[3], const double d[3],
                            double len);
/* The walk's segments along o + t d over [0, tend], as the trackers cut
 * them (with the control or plain, per g->rp): seg[FP_REFERENCE_SEG k ..]
 * = s0, s1, the majorant mu, the residual's bound r, and the control's
 * factors (fp_reference_control); returns their number (at most max). */
#define FP_REFERENCE_SEG 6
int fp_reference_segments(const fp_integrate_data_t *fog, const fp_reference_grid_t *g,
                          const double o[3], const double d[3], double tend, double *seg,
                          int max);
/* The control c at height y on a segment, and its integral over the
 * segment (closed form). */
double fp_reference_control(const fp_integrate_data_t *fog, const double *seg, double y);
double fp_reference_control_od(const fp_integrate_data_t *fog, const double o[3],
                               const double d[3], const double *seg);
/* One free flight (decomposition tracking, or plain delta tracking when
 * g->rp[FP_RP_CONTROL] is 0): the distance of the first real collision,
 * INFINITY when it passes tend. */
double fp_reference_free_flight(const fp_integrate_data_t *fog, const fp_reference_grid_t *g,
                                const double o[3], const double d[3], double tend,
                                uint32_t *rng);
/* One ratio-tracking estimate of the transmittance over [0, tend]
 * (residual, or plain when g->rp[FP_RP_CONTROL] is 0). */
double fp_reference_ratio(const fp_integrate_data_t *fog, const fp_reference_grid_t *g,
                          const double o[3], const double d[3], double tend, uint32_t *rng);

/* Options of one run beyond fp_params_t (tests). */
typedef struct fp_reference_opts_t {
    int control;     /* decomposition and residual ratio tracking (1, default), or
                        plain delta and ratio tracking (0) */
    int stratify;    /* stratified first free flight (1, default) */
    int cells;       /* grid columns per axis (0: FP_REFERENCE_GRID) */
} fp_reference_opts_t;

/* The C version for a whole frame: out[4 i ..] = (S.r, S.g, S.b, tau),
 * the means over p->reference.spp samples; --bounces from
 * p->reference.bounces, the seed from --seed (p->anim.seed).  `sd` may be
 * NULL (ambient fog, albedo 1). */
int fp_reference_process(const fp_params_t *p, const fp_scatter_data_t *sd,
                         const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                         float *out);
/* The same with each pixel's standard errors (4 per pixel, from the
 * samples' variance as if they were independent, which overstates the
 * error of the stratified first flight; NULL: none) and options (NULL:
 * defaults). */
int fp_reference_process_se(const fp_params_t *p, const fp_scatter_data_t *sd,
                            const fp_integrate_data_t *fog, const fp_view_t *v,
                            const float *depth, const fp_reference_opts_t *o, float *out,
                            float *se);
/* The npix pixels pix[] of the frame (indices y * width + x; depth is the
 * whole frame's) into out[4*k], list order: the same values
 * fp_reference_process gives them.  pix NULL: all pixels in order. */
int fp_reference_pixels(const fp_params_t *p, const fp_scatter_data_t *sd,
                        const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                        const int *pix, size_t npix, float *out);

/* OpenCL state kept across frames. */
typedef struct fp_reference_cl_t {
    fp_cl_t *cl;
    cl_kernel kernel;
    cl_mem depth, acc, view, fp, lvi, lvf, coef, lt, smap, rp, grid, pix, lights;
    size_t capacity;          /* pixels the depth buffer holds */
    size_t band;              /* entries of a band: acc, sum, part */
    size_t coef_n, smap_n, grid_n, pix_n, lights_n;
    unsigned long tables;     /* serial of the fogmap tables on the device (0: none) */
    double *sum;              /* per pixel of the band: sums of S.rgb, tau and of their
                                 squares */
    float *part;              /* one launch's sums */
} fp_reference_cl_t;

int fp_reference_cl_init(fp_cl_t *cl, fp_reference_cl_t *s);
int fp_reference_process_cl(fp_reference_cl_t *s, const fp_params_t *p,
                            const fp_scatter_data_t *sd, const fp_integrate_data_t *fog,
                            const fp_view_t *v, const float *depth, float *out);
int fp_reference_process_cl_se(fp_reference_cl_t *s, const fp_params_t *p,
                               const fp_scatter_data_t *sd, const fp_integrate_data_t *fog,
                               const fp_view_t *v, const float *depth,
                               const fp_reference_opts_t *o, float *out, float *se);
/* As fp_reference_pixels, on the device. */
int fp_reference_pixels_cl(fp_reference_cl_t *s, const fp_params_t *p,
                           const fp_scatter_data_t *sd, const fp_integrate_data_t *fog,
                           const fp_view_t *v, const float *depth, const int *pix, size_t npix,
                           float *out);
void fp_reference_cl_release(fp_reference_cl_t *s);

#endif

/* fogpipe stage "animate": the fog at time t = frame / --fps (seed 000's
 * future work: "the decomposition is cheap enough to redo every frame").
 *
 *  - Wind (--wind VX,VZ[,DEG]): the fog drifts, its offset growing with t,
 *    and turns about the vertical through its (moving) offset at DEG/s;
 *    no redecomposition.  Fog-local = R(t)^T (p - offset(t)) as in
 *    kernels/fog_core.h, offset(t) = --fog-offset + wind t, R(t) the turn
 *    by --fog-rotate + DEG t.  A feature of the fog moves by wind t.
 *  - Fogmap sequences (--fogmap fog.####.png): the keys are the frames on
 *    disk; between two keys the fogmap is held or interpolated on the
 *    wavelet coefficients of the two keys (each key decomposed once).
 *  - Turbulence (--turbulence AMOUNT): per wavelet detail level l = 1..L
 *    (coarse to fine), a B-spline surface on that level's grid whose
 *    coefficients are value noise in time, amplitude AMOUNT * mean(fogmap)
 *    * 2^(-5/6 (l-1)) (Kolmogorov's k^(-5/3) energy spectrum, as in Kim et
 *    al. 2008, Wavelet Turbulence, sec. 4) and rate --turbulence-speed *
 *    2^(2/3 (l-1)) steps per second (eddy turnover time ~ k^(-2/3)).
 *  - Advection (--advect): the fogmap image carried by the wind through its
 *    fixed rectangle, one semi-Lagrangian (or MacCormack) step per frame
 *    from --advect-start; frame N is the same whichever frame a run starts
 *    at (states recomputed, or read from --cache-dir).
 *
 * Everything is a function of the frame number and the inputs: no state of
 * a run changes what a frame looks like (caches only save time).
 *
 * Thread safety: an fp_animate_t is used by one thread at a time. */
#ifndef FP_ANIMATE_H
#define FP_ANIMATE_H

#include "clrt.h"
#include "integrate.h"
#include "params.h"
#include "wavelet.h"

#define FP_ADVECT_CHECKPOINT 8   /* --cache-dir keeps every 8th advection state */

typedef struct fp_animate_t fp_animate_t;

/* Usage checks of the animation options against the rest (FP_EUSAGE with a
 * message). */
int fp_animate_check(const fp_params_t *p);

/* 1 when the fogmap itself changes from frame to frame (a sequence,
 * turbulence, advection), so that it is decomposed per frame. */
int fp_animate_fogmap_animated(const fp_params_t *p);

/* Time of a frame: frame / --fps, seconds. */
double fp_animate_time(const fp_params_t *p, long frame);

/* The wind in fog space (x, y = up, z), scene units per second: --wind
 * VX,VZ with --up y, VX,VY with --up z (fog z = -world y). */
void fp_animate_wind(const fp_params_t *p, double w[3]);

/* The fog's placement at `frame`: FP_F_OFF and FP_F_COS/SIN from
 * --fog-offset, --fog-rotate and --wind (the offset stays put under
 * --advect, which moves the fog through its rectangle instead).  Nothing
 * is touched when there is no wind. */
void fp_animate_transform(const fp_params_t *p, long frame, fp_integrate_data_t *d);

/* Start animating a fogmap.  `base` (w x h, row 0 first; copied) is the
 * still fogmap or the first key of a sequence, `geom` its decomposition
 * (domain, levels and filters; not kept), uscale/vscale fogmap pixels per
 * fog unit (FP_F_USCALE/VSCALE).  A sequence's keys are scanned here. */
int fp_animate_open(const fp_params_t *p, const float *base, int w, int h,
                    const fp_fogmap_t *geom, double uscale, double vscale,
                    fp_animate_t **out);

typedef struct fp_animate_frame_t {
    const fp_fogmap_t *map;   /* the frame's decomposition: owned by the fp_animate_t, */
    const float *img;         /* and its w x h image: valid until the next call */
    int changed;              /* 0: the same as the previous call gave */
    int decompositions;       /* done for this frame (0 when cached or unchanged) */
    double decompose_ms;      /* their time */
    int used_cl;              /* they ran in OpenCL */
} fp_animate_frame_t;

/* The fogmap at `frame`.  `cl` may be NULL (C reference). */
int fp_animate_fogmap(fp_animate_t *a, fp_cl_t *cl, long frame, fp_animate_frame_t *out);

void fp_animate_close(fp_animate_t *a);

/* ---- building blocks, for the tests ---- */

/* One advection step of the w x h image `src` by (du, dv) pixels (content
 * moves by +du along the columns, +dv along the rows): semi-Lagrangian
 * with bilinear sampling (mode FP_ADVECT_SL), or MacCormack with the
 * result clamped to the four samples the forward step read (Selle et al.
 * 2008), so it stays within the local range and >= 0.  The boundary
 * follows FP_WRAP_*.  `tmp` holds 2 w h floats (MacCormack). */
void fp_advect_step(const float *src, int w, int h, int wrap, int mode, double du, double dv,
                    float *dst, float *tmp);

/* The turbulence at time t (seconds) as fine coefficients on the padded
 * domain of `g` (dom_w x dom_h, row-major), for unit AMOUNT * mean: the sum
 * over the detail levels l in `level_mask` (bit l; ~0u: all) of
 * 2^(-5/6 (l-1)) times the level's noise surface refined to the fine grid
 * (exactly the same surface).  Each noise coefficient is a uniform cubic
 * B-spline in time through independent values in [-1,1] at integer steps
 * of t * speed * 2^(2/3 (l-1)) (C2 in time), keyed by (seed, l, i, j,
 * step).  out: dom_w * dom_h doubles. */
int fp_turbulence_field(const fp_fogmap_t *g, unsigned seed, double speed, double t,
                        unsigned level_mask, double *out);

#endif

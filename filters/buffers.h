/* fogpipe stage "buffers": what is done to the fog layer (S.r, S.g, S.b,
 * tau) between the fog stages and the composite, never to the plate.
 *
 * - A depth-aware bilateral blur (seed 002 section 4.4): a Gaussian in
 *   pixels times a range weight on the guide distance, so fog never smears
 *   across a depth edge; optional near-camera falloff (seed 002 "Blur Depth
 *   Falloff"); separable (horizontal, then vertical pass) or the full 2D
 *   kernel.
 * - Reduced-resolution fog: the fog computed at the full-resolution pixels
 *   (f i, f j) only, through a strided view (fp_view_subsample), and brought
 *   back by joint bilateral upsampling guided by the full-resolution guide
 *   distance (Kopf et al. 2007), falling back to the sample of nearest
 *   distance where no sample matches the pixel's (an edge); the pixels at
 *   depth edges computed again at full resolution (fp_upsample_edges,
 *   --fog-edges exact).
 *
 * The guide is the distance along each pixel's view ray (fp_buffers_guide),
 * +inf for sky: sky blends only with sky, geometry never with sky.  The
 * range weight of two guide distances d1, d2 is exp(-r^2 / (2 range^2))
 * with r = |d1 - d2| / min(d1, d2).
 *
 * The per-pixel code is written once (kernels/buffers_core.h): the C
 * reference in double (accumulation and weights; layers stored as float
 * between passes, as on the device), OpenCL in single precision
 * (kernels/buffers.cl). */
#ifndef FP_BUFFERS_H
#define FP_BUFFERS_H

#include "camera.h"
#include "clrt.h"
#include "params.h"

#define FP_BLUR_MAX_RADIUS 32

/* 1 when the buffers stage changes anything (--blur bilateral or
 * --fog-resolution below 1). */
int fp_buffers_active(const fp_params_t *p);

/* The spatial sigma in pixels (--blur-sigma, or radius / 2 when 0). */
double fp_buffers_sigma(const fp_buffers_params_t *b);

/* Guide distance of every pixel of the view: the length of its view ray
 * (fp_view_ray), +inf for sky.  dist has width * height entries. */
void fp_buffers_guide(const fp_view_t *v, const float *depth, float *dist);

/* The view whose pixel (x', y') is pixel (f x', f y') of v: width
 * ceil(w / f), height ceil(h / f). */
void fp_view_subsample(const fp_view_t *v, int f, fp_view_t *out);

/* depth[f j][f i] for the ceil(w / f) x ceil(h / f) samples. */
void fp_depth_subsample(const float *depth, int w, int h, int f, float *out);

/* Range weight of two guide distances (1 for two sky pixels, 0 for sky and
 * geometry); `range` > 0. */
double fp_buffers_range_weight(double d1, double d2, double range);

/* C reference: the bilateral blur of a whole w x h fog layer in place
 * (b->iterations times, then the near-camera falloff), guided by dist.
 * Does nothing when b->blur is off.  FP_ERR (with a message) for
 * parameters outside the option ranges or out of memory. */
int fp_buffers_blur(const fp_buffers_params_t *b, int w, int h, const float *dist, float *fog);

/* C reference: joint bilateral upsampling of the low-resolution layer lo
 * (ceil(w / f) x ceil(h / f), sample (i, j) at full-resolution pixel
 * (f i, f j)) to the w x h layer fog, guided by the full-resolution dist:
 * over the 4 x 4 samples around each pixel, a Gaussian in full-resolution
 * pixels (sigma f / 2) times the range weight; where that sums to less
 * than 1e-3 of the Gaussian alone (no sample at the pixel's distance: an
 * edge), the sample of nearest distance (for sky, the farthest).  `range`
 * is the range sigma (--blur-range).  f = 1 copies lo. */
int fp_upsample(int f, double range, int w, int h, const float *dist, const float *lo,
                float *fog);

/* The depth-edge pixels of joint bilateral upsampling by f (> 1): those
 * that are not samples and whose guide distance differs from that of one
 * of the (up to 4) samples at the corners of the low-resolution cell that
 * holds them by more than `threshold` (relative, as the range weight's r;
 * sky against geometry always), and those past the last sample column or
 * row (sizes not a multiple of f), where the upsampling would
 * extrapolate.  Their fog is computed again at full
 * resolution (--fog-edges exact): there the upsampling has no sample on
 * the pixel's own surface or mixes in the fog beside a silhouette (light
 * shafts start at the occluder's edge).  Writes their indices y * w + x,
 * ascending, to pix (room for w * h) and returns how many; 0 for f <= 1. */
size_t fp_upsample_edges(int f, double threshold, int w, int h, const float *dist, int *pix);

/* OpenCL state kept across frames (program, kernels, buffers). */
typedef struct fp_buffers_cl_t {
    fp_cl_t *cl;
    cl_kernel blur, falloff, upsample;
    cl_mem dist, fog, tmp, orig, lo;
    size_t capacity;      /* pixels the full-resolution buffers hold */
    size_t lo_capacity;   /* pixels the low-resolution buffer holds */
} fp_buffers_cl_t;

int fp_buffers_cl_init(fp_cl_t *cl, fp_buffers_cl_t *s);
/* As fp_buffers_blur, on the device; host pointers in and out. */
int fp_buffers_blur_cl(fp_buffers_cl_t *s, const fp_buffers_params_t *b, int w, int h,
                       const float *dist, float *fog);
/* As fp_upsample, on the device; host pointers in and out. */
int fp_upsample_cl(fp_buffers_cl_t *s, int f, double range, int w, int h, const float *dist,
                   const float *lo, float *fog);
void fp_buffers_cl_release(fp_buffers_cl_t *s);

#endif

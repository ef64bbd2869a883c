/* fogpipe stage "wavelet": multi-level B-spline wavelet decomposition of a
 * fogmap (seed 000 sec. 3.2 "Decomposition and multiresolution", 4.2
 * "Preparing data for rendering", 4.4 "deconstruction").  C reference in
 * double precision (fp_wavelet_decompose), OpenCL (fp_wavelet_decompose_cl,
 * kernels/wavelet.cl); both fill the same fp_fogmap_t.
 *
 * The fog function (DESIGN, Conventions), in fogmap pixel units:
 *     F(u,v) = sum_ij c_ij b_d(u - i - 1/2) b_d(v - j - 1/2)
 * u along the columns i, v along the rows j, pixel (i,j) covering
 * [i,i+1] x [j,j+1], b_d the centered uniform B-spline of degree d
 * (kernels/bspline.h), c_ij the fogmap's pixels.
 *
 * Domain.  The transform works on a periodic domain of dom_w x dom_h fine
 * pixels, each a multiple of 2^levels.  Domain coordinates (U,V) are in
 * fine pixels; fogmap pixel (i,j) covers [pad_x0+i, pad_x0+i+1] x
 * [pad_y0+j, pad_y0+j+1], i.e. U = u + pad_x0, V = v + pad_y0.
 *   FP_WRAP_ZERO:   zeros around the fogmap, margin >= d + 2 on every side.
 *                   The sum of the level surfaces equals F on the whole
 *                   domain; F is 0 outside [pad_x0 - (d+1)/2, pad_x0 + w +
 *                   (d+1)/2] (same in V), in particular near the domain's
 *                   border, so a renderer clips rays to the domain (or to
 *                   that rectangle) and takes 0 outside.
 *   FP_WRAP_CLAMP:  edge-replicated margin >= 2 (d + 2).  The sum equals F
 *                   for U in [(d+1)/2, dom_w - (d+1)/2] (same in V): only
 *                   the outermost (d+1)/2 pixels see the periodic wrap.
 *                   F does not depend on u for u <= -d/2 or u >= w + d/2
 *                   (same in v), so a renderer clamps (U,V) into
 *                   [pad_x0 - d/2, pad_x0 + w + d/2] x (same in V), which
 *                   lies inside the exact region (margin >= 2 (d + 2)).
 *   FP_WRAP_REPEAT: the domain is the fogmap itself (pad 0); F is periodic
 *                   and the sum equals it everywhere.  levels is reduced to
 *                   the largest value whose 2^levels divides both w and h
 *                   (the caller warns when out->levels < the request).
 *
 * Levels (seed 000 sec. 4.4).  level[0] is the coarse approximation with
 * cell size 2^levels; level[l], l = 1..levels, holds the detail bands of
 * the l-th coarsest decomposition step synthesized back ("deconstructed")
 * into scaling coefficients of cell size 2^(levels - l); level[levels] has
 * cell size 1.  Every level is one periodic B-spline surface
 *     S_l(U,V) = sum_{i,j} coef[(j mod ny) * nx + (i mod nx)]
 *                          b_d((U - origin_u)/cell - i) b_d((V - origin_v)/cell - j)
 * and sum_l S_l = F (within float rounding).  Basis (i,j) of a level of
 * cell size s is centered at (origin_u + s i, origin_v + s j) with
 * origin = s/2 for even d (a coarse cell covers the 2x2 finer cells under
 * it) and 1/2 for odd d (coarse centers on the fine centers of even index).
 * The surface is one polynomial per cell between knots at U = origin_u +
 * cell * (k - FP_BSPLINE_SHIFT(d)): multiples of cell for even d, cell * k
 * + 1/2 for odd d (same in V); kernels/bspline.h tells which coefficients
 * overlap a cell and gives their weights as polynomials.
 *
 * Raw bands (rendering without deconstruction).  band[l][b], l = 1..levels,
 * are the detail coefficients of the same step at its coarse resolution
 * (cell size 2^(levels - l + 1), the same grid and origin as the
 * approximation there); b = FP_BAND_LH (low-pass along u, high-pass along
 * v), FP_BAND_HL (high along u, low along v), FP_BAND_HH.  With phi_i the
 * coarse 1D basis function i (a B-spline) and psi_i the coarse wavelet i,
 *     S_l = sum_ij LH_ij phi_i(U) psi_j(V) + HL_ij psi_i(U) phi_j(V)
 *                  + HH_ij psi_i(U) psi_j(V)
 * and in terms of the finer grid's basis functions f_n (cell size / 2):
 *     phi_i = sum_k synth[0].tap[k - lo] f_{2i+k},
 *     psi_i = sum_k synth[1].tap[k - lo] f_{2i+k}     (lo <= k <= hi)
 * (synth[0] is the uniform B-spline refinement mask, 2^-d binomial).
 *
 * Memory: every coef array is float, contiguous, row-major (rows along V),
 * owned by the fp_fogmap_t; fp_fogmap_free releases them.  An fp_fogmap_t
 * is read-only after it is filled and may be shared between threads. */
#ifndef FP_WAVELET_H
#define FP_WAVELET_H

#include "clrt.h"

#define FP_MAX_LEVELS 12
#define FP_MAX_DEGREE 3
#define FP_FILTER_MAX_TAPS 16

enum { FP_WRAP_ZERO = 0, FP_WRAP_CLAMP = 1, FP_WRAP_REPEAT = 2 };
enum { FP_BAND_LH = 0, FP_BAND_HL = 1, FP_BAND_HH = 2 };

/* One periodic B-spline surface (or one raw band). */
typedef struct fp_fog_level_t {
    int nx, ny;                 /* coefficients along U and V */
    double cell;                /* cell size in fine (domain) pixels: a power of 2 */
    double origin_u, origin_v;  /* basis (i,j) centered at (origin_u + cell*i, origin_v + cell*j) */
    float amax;                 /* max |coef|: bounds |surface| (B-splines >= 0, sum to 1) */
    float *coef;                /* nx * ny, coef[j * nx + i] */
} fp_fog_level_t;

/* Impulse response of one 1D synthesis step (computed from the lifting
 * steps by synthesizing a unit impulse): coarse coefficient l of value 1,
 * everything else 0, gives fine coefficients x_{2l+k} = tap[k - lo] for
 * lo <= k <= hi, 0 elsewhere.  Split by parity: fine 2(l + m) + p receives
 * phase[p][m - phase_lo[p]] for 0 <= m - phase_lo[p] < phase_n[p]. */
typedef struct fp_wavelet_filter_t {
    int lo, hi;
    double tap[FP_FILTER_MAX_TAPS];
    int phase_lo[2], phase_n[2];
    double phase[2][FP_FILTER_MAX_TAPS];
} fp_wavelet_filter_t;

typedef struct fp_fogmap_t {
    int degree;                 /* d, 0..3 */
    int wrap;                   /* FP_WRAP_* */
    int levels;                 /* decomposition steps done (maybe < requested for REPEAT) */
    int width, height;          /* the fogmap, pixels */
    int dom_w, dom_h;           /* padded periodic domain, fine pixels (multiples of 2^levels) */
    int pad_x0, pad_y0;         /* domain position of fogmap pixel (0,0)'s corner */
    int num_levels;             /* levels + 1 */
    fp_fog_level_t level[FP_MAX_LEVELS + 1];    /* deconstructed surfaces, coarse to fine */
    fp_fog_level_t band[FP_MAX_LEVELS + 1][3];  /* raw LH, HL, HH; band[0] unused (zeroed) */
    fp_wavelet_filter_t synth[2];               /* [0]: scaling (phi), [1]: wavelet (psi) */
} fp_fogmap_t;

/* Decompose the w x h fogmap `img` (row-major, img[j * w + i] = c_ij,
 * finite) with B-spline wavelets of degree 0..3, `levels` (0..FP_MAX_LEVELS)
 * steps, wrap mode FP_WRAP_*.  C reference, double precision inside.
 * `out` is overwritten (not freed first); on failure it is left empty
 * (safe to free).  FP_EUSAGE for out-of-range arguments. */
int fp_wavelet_decompose(const float *img, int w, int h, int degree, int levels, int wrap,
                         fp_fogmap_t *out);

/* The same with kernels/wavelet.cl on `cl` (lifting in float); the result
 * matches the C reference within float rounding.  On failure `out` is left
 * empty and the caller may fall back to fp_wavelet_decompose. */
int fp_wavelet_decompose_cl(fp_cl_t *cl, const float *img, int w, int h, int degree,
                            int levels, int wrap, fp_fogmap_t *out);

/* Release every array of `m` and zero it. */
void fp_fogmap_free(fp_fogmap_t *m);

/* Full inverse transform (from level[0] and the raw bands) back to the
 * w x h fogmap: out[j * w + i].  For the lossless test. */
int fp_wavelet_reconstruct(const fp_fogmap_t *m, float *out);

/* One level's surface S_l at domain point (U,V), periodic. */
double fp_fogmap_eval_level(const fp_fogmap_t *m, int l, double U, double V);

/* sum_{l=0..max_level} S_l(U,V) (max_level clipped to levels): F at the
 * domain point (U,V) when max_level >= levels. */
double fp_fogmap_eval(const fp_fogmap_t *m, double U, double V, int max_level);

/* The same sum from level[0] and the raw bands expanded with synth[] (the
 * renderer's path without deconstruction); equal to fp_fogmap_eval. */
double fp_fogmap_eval_bands(const fp_fogmap_t *m, double U, double V, int max_level);

/* F(u,v) straight from its definition (u,v in fogmap pixels): c = 0 outside
 * the fogmap for ZERO, clamped indices for CLAMP, periodic for REPEAT.
 * The judge of the decomposition. */
double fp_fogmap_eval_direct(const float *img, int w, int h, int degree, int wrap, double u,
                             double v);

#endif

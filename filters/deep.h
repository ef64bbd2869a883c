/* fogpipe stage "deep": the fog as OpenEXR deep samples (--deep).
 *
 * Along each pixel's ray the fog is a list of volumetric samples [Z, ZBack]
 * whose boundaries are chosen so that OpenEXR's rule for splitting a sample
 * ("Interpreting OpenEXR Deep Pixels": the part f of a sample's range has
 * alpha 1 - (1 - a)^f and its colour in proportion, a' / a) reproduces
 * fogpipe's own fog for a surface at any depth within a stated bound:
 *
 *   for every depth z, |S'(z) - S(z)| + |tau'(z) - tau(z)| <= bound * max(1, S_max)
 *
 * per channel, where S, tau are the in-scatter and transmittance of the ray
 * ending at z (fp_scatter_ray / fp_integrate_optical_depth, the --cpu
 * reference in double precision) and S', tau' those of the samples in
 * front of z composited front to back with the last one split at z.  At
 * the boundaries the samples are exact: a segment [t0, t1] holds
 * alpha = 1 - tau(t1) / tau(t0) and colour (S(t1) - S(t0)) / tau(t0), so
 * compositing the samples in front of t1 gives tau(t1) and S(t1).
 *
 * Boundaries: the fog's span along the ray (its box, its top, the haze),
 * the input's own sample depths (deep input), then bisection of the
 * segment whose probes (1/4, 1/2, 3/4 of it) are furthest off, until every
 * probe is within the bound or the pixel has --deep-max-samples samples;
 * then neighbours are merged again where every point evaluated between
 * them stays within the bound (as few samples as the bound allows).
 *
 * A deep input (a deep render) is fogged sample by sample: the fog's
 * samples and the input's are made tidy together (split at each other's
 * boundaries, coincident pieces combined by OpenEXR's rule for two
 * volumes over the same range), so the fog lies between and inside the
 * input's samples and the flattened result of an opaque surface is the
 * flat path's tau * C + S. */
#ifndef FP_DEEP_H
#define FP_DEEP_H

#include "camera.h"
#include "integrate.h"
#include "params.h"
#include "scatter.h"

#include <stddef.h>
#include <stdint.h>

/* One deep sample in double precision while it is built.  `src` is the
 * input sample it came from (a deep input's, or the plate's surface:
 * FP_DEEP_SRC_PLATE), or FP_DEEP_SRC_FOG. */
typedef struct fp_dsample_t {
    double z, zb;
    double c[3], a;
    long src;
} fp_dsample_t;
#define FP_DEEP_SRC_FOG (-1L)
#define FP_DEEP_SRC_PLATE (-2L)

/* Derived once per run from the options (commit). */
typedef struct fp_deep_data_t {
    int on;                   /* --deep */
    double bound;             /* --deep-bound */
    int max_samples;          /* --deep-max-samples (fog samples per pixel) */
    double max_alpha;         /* --deep-max-alpha (1: none) */
    int sky_keep;             /* --sky keep */
} fp_deep_data_t;

int fp_deep_commit(const fp_params_t *p, fp_deep_data_t *d);

/* What the fog of one frame is computed from (the pipeline's run data). */
typedef struct fp_deep_fog_t {
    const fp_deep_data_t *deep;
    const fp_integrate_data_t *fog;
    const fp_scatter_data_t *light;  /* NULL or !active: extinction with ambient fog */
    const fp_view_t *view;
    const float *depth;              /* the frame's depth (screen-space shadows), or NULL */
} fp_deep_fog_t;

/* Report per run: samples written and pixels (for samples per pixel). */
typedef struct fp_deep_stats_t {
    long pixels, samples, fog_samples, evals, capped;
} fp_deep_stats_t;

/* A pixel's samples: a growable list. */
typedef struct fp_dlist_t {
    fp_dsample_t *s;
    size_t n, cap;
} fp_dlist_t;
int fp_dlist_push(fp_dlist_t *l, const fp_dsample_t *s);
void fp_dlist_free(fp_dlist_t *l);

/* Deep Z -> distance along the ray of pixel (x, y): t = z * k. */
double fp_deep_ray_scale(const fp_view_t *v, int x, int y);

/* The fog samples of pixel (x, y) from the camera to deep depth z_end
 * (INFINITY: to where the fog ends), with boundaries at the `nforced`
 * depths forced[] among them (a deep input's sample depths), appended to
 * *out.  st->evals counts the fog evaluations, st->capped the pixels that
 * reached --deep-max-samples before the bound.  FP_ERR: out of memory (no
 * message: it runs on worker threads). */
int fp_deep_fog_pixel(const fp_deep_fog_t *f, int x, int y, double z_end, const double *forced,
                      size_t nforced, fp_dlist_t *out, fp_deep_stats_t *st);

/* Make a sample list tidy (OpenEXR): sorted by Z then ZBack, no two
 * overlapping: volumes split at every other sample's boundaries (the
 * split rule), coincident pieces combined (alpha 1 - prod(1 - a_i), colour
 * by the rule for volumes over the same range; the first's src kept). */
int fp_deep_tidy(fp_dlist_t *l);

/* Split one sample at deep depth z: the part in front of z. */
void fp_deep_split_front(const fp_dsample_t *s, double z, fp_dsample_t *front);

/* Composite a tidy list front to back (premultiplied): rgba out; only
 * what lies in front of z_cut (samples straddling it split), INFINITY:
 * all. */
void fp_deep_flatten(const fp_dsample_t *s, size_t n, double z_cut, double rgba[4]);


#endif
